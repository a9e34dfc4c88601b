//! Forcing the SIMD level of the traversals (`force_simd_level`, `HYRT_SIMD`): one test in
//! its own binary, since the override is process-wide.

use hyrt_cpu::traversal::{force_simd_level, simd_level_forced, tuning, SimdLevel, Traversal};

#[test]
fn a_forced_level_is_what_traversals_use_until_released() {
    for l in SimdLevel::ALL {
        assert_eq!(SimdLevel::from_name(l.name()), Some(l));
    }
    assert_eq!(SimdLevel::from_name("avx1024"), None);
    let best = SimdLevel::best();
    assert_eq!(SimdLevel::detect(), best, "no override at start (HYRT_SIMD unset in tests)");
    for l in SimdLevel::available() {
        force_simd_level(Some(l)).unwrap();
        assert_eq!(SimdLevel::detect(), l);
        assert_eq!(Traversal::simd(), Traversal::Packet(l));
        assert_eq!(Traversal::for_bounces(), Traversal::Single(l));
        assert_eq!(simd_level_forced(), l != best);
    }
    for l in SimdLevel::ALL.into_iter().filter(|l| !l.is_available()) {
        let before = SimdLevel::detect();
        assert!(force_simd_level(Some(l)).is_err(), "{l:?} is not on this CPU");
        assert_eq!(SimdLevel::detect(), before, "a refused level changes nothing");
    }
    force_simd_level(None).unwrap();
    assert_eq!(SimdLevel::detect(), best);
    assert!(!simd_level_forced());
    // Unforced on a CPU with AVX-512, the stages measure it against AVX2 per kind of walk.
    let measured = SimdLevel::Avx512.is_available();
    assert_eq!(tuning::applies(), measured);
    let expect = if measured { Traversal::PacketAuto } else { Traversal::Packet(best) };
    assert_eq!(Traversal::simd(), expect);
    let expect = if measured { Traversal::SingleAuto } else { Traversal::Single(best) };
    assert_eq!(Traversal::for_bounces(), expect);
}
