//! The SIMD level of each kind of walk, measured interleaved while the stages run.
//!
//! Every level gives the same answers bit for bit (the traversals are exact), so the level
//! is only a question of speed, and the answer differs by CPU and by kind of walk. Measured
//! with `ray_contest --with-avx2` (interleaved rounds, 2 threads, Embree's best / hyrt,
//! AVX-512 against the same code compiled for AVX2 alone) on a 2-core Intel Xeon:
//!
//! | walk | teaser | Sponza | horse near | bunny near | dragon |
//! |---|---:|---:|---:|---:|---:|
//! | any hit, packets, AVX-512 / AVX2 | 0.95 / 0.86 | 0.93 / 0.87 | 1.00 / 0.99 | 0.88 / 0.70 | 0.80 / 0.76 |
//! | closest hit, packets, AVX-512 / AVX2 | 0.77 / 0.93 | 0.87 / 1.15 | 0.95 / 1.02 | 1.02 / 0.99 | 0.84 / 0.97 |
//! | closest hit, single rays (teaser's bounces) | 0.78 / 0.78 | | | | |
//!
//! So on that Xeon any hit is faster at AVX-512 and closest-hit packets at AVX2; on the
//! project's AMD EPYC AVX-512 was the faster for both. No fixed rule fits both, so the
//! stages measure: [`Traversal::PacketAuto`] and [`Traversal::SingleAuto`] (the stages'
//! defaults where this CPU has AVX-512 and no level is forced) hand each chunk of rays to
//! [`timed`], which runs the chunks of one kind of walk at AVX-512 and AVX2 in turn
//! (whichever thread takes the next chunk takes the next level), timing each, until both
//! levels have traced [`MIN_CHUNKS`] chunks and [`MIN_RAYS`] rays; from then on the kind
//! runs at the level with fewer nanoseconds per ray ([`AVX2_MARGIN`]). Chunks of both levels
//! alternate through the same frames, so a noisy neighbour slows both alike. The choice
//! is per process: what the kind of walk costs on this CPU, not on one scene.
//!
//! [`levels`] says what each kind runs at and what was measured (`hyrt render` and
//! `hyrt bench` print it).
//!
//! [`Traversal::PacketAuto`]: super::Traversal::PacketAuto
//! [`Traversal::SingleAuto`]: super::Traversal::SingleAuto

use std::sync::atomic::{AtomicU64, AtomicU8, AtomicUsize, Ordering};
use std::time::Instant;

use super::SimdLevel;

/// The levels measured against each other, the default first (the one run until a kind
/// is decided, and kept on a tie).
pub const CANDIDATES: [SimdLevel; 2] = [SimdLevel::Avx512, SimdLevel::Avx2];

/// Chunks each level traces before a kind is decided: enough that one preempted chunk
/// cannot decide (a frame's shadow rays are hundreds of chunks; a fused frame's tiles,
/// one chunk per tile and light, as many).
pub const MIN_CHUNKS: u64 = 64;

/// Rays each level traces before a kind is decided (a 720p frame's shadow rays are about
/// a million; a frame with few rays decides over several frames).
pub const MIN_RAYS: u64 = 1 << 17;

/// AVX2 replaces the default only when it takes less than this fraction of the default's
/// time per ray: a difference within the measurement's noise (a few percent between
/// interleaved runs of the same code) keeps the default.
pub const AVX2_MARGIN: f64 = 0.97;

/// A kind of walk: what is traced (any hit or closest hit) and how (packets or single
/// rays through the wide tree). Each is measured and decided on its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Walk {
    AnyHitPackets,
    ClosestHitPackets,
    AnyHitSingle,
    ClosestHitSingle,
}

impl Walk {
    /// Every kind, in [`levels`]' order.
    pub const ALL: [Walk; 4] =
        [Walk::AnyHitPackets, Walk::ClosestHitPackets, Walk::AnyHitSingle, Walk::ClosestHitSingle];

    /// The kind of a walk: any hit or closest hit, single rays or packets.
    pub fn of(any_hit: bool, single: bool) -> Walk {
        match (any_hit, single) {
            (true, false) => Walk::AnyHitPackets,
            (false, false) => Walk::ClosestHitPackets,
            (true, true) => Walk::AnyHitSingle,
            (false, true) => Walk::ClosestHitSingle,
        }
    }

    /// Name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Walk::AnyHitPackets => "any hit, packets",
            Walk::ClosestHitPackets => "closest hit, packets",
            Walk::AnyHitSingle => "any hit, single rays",
            Walk::ClosestHitSingle => "closest hit, single rays",
        }
    }
}

/// One kind's measurement: time and rays per candidate, and the decision.
pub struct Trial {
    /// 0 while measuring, else 1 + the index in [`CANDIDATES`] of the level chosen.
    decided: AtomicU8,
    /// Chunks handed out so far: chunk `n` runs candidate [`candidate`]`(n)`.
    next: AtomicUsize,
    ns: [AtomicU64; 2],
    rays: [AtomicU64; 2],
    chunks: [AtomicU64; 2],
}

/// The candidate of the `n`-th chunk handed out while measuring: the top bit of a
/// multiplicative hash of `n` (Fibonacci hashing), so that the candidates take turns
/// without a period. A plain `n % 2` would pair them with whatever alternates in the
/// callers: the fused frame traces each tile's lights in turn, so with two lights every
/// tile would give one light's rays to one level and the other's to the other.
#[inline]
fn candidate(n: usize) -> usize {
    ((n as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 63) as usize
}

/// What [`levels`] reports of one kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkLevel {
    pub walk: Walk,
    /// The level chosen; `None` while both are still measured.
    pub level: Option<SimdLevel>,
    /// Nanoseconds per ray measured at each of [`CANDIDATES`] (NaN where none ran).
    pub ns_per_ray: [f64; 2],
    /// Rays traced at each while measuring.
    pub rays: [u64; 2],
}

impl Default for Trial {
    fn default() -> Self {
        Trial::new()
    }
}

impl Trial {
    /// Nothing measured yet.
    pub const fn new() -> Trial {
        Trial {
            decided: AtomicU8::new(0),
            next: AtomicUsize::new(0),
            ns: [AtomicU64::new(0), AtomicU64::new(0)],
            rays: [AtomicU64::new(0), AtomicU64::new(0)],
            chunks: [AtomicU64::new(0), AtomicU64::new(0)],
        }
    }

    /// The level chosen, if any.
    pub fn decided(&self) -> Option<SimdLevel> {
        match self.decided.load(Ordering::Relaxed) {
            0 => None,
            k => Some(CANDIDATES[k as usize - 1]),
        }
    }

    /// Run `trace` on a chunk of `rays` rays at the chosen level, or while measuring at the
    /// next candidate, timed and counted.
    #[inline]
    pub fn timed<R>(&self, rays: usize, trace: impl FnOnce(SimdLevel) -> R) -> R {
        if let Some(level) = self.decided() {
            return trace(level);
        }
        let k = candidate(self.next.fetch_add(1, Ordering::Relaxed));
        let start = Instant::now();
        let r = trace(CANDIDATES[k]);
        self.record(k, start.elapsed().as_nanos() as u64, rays as u64);
        r
    }

    /// Count a chunk of candidate `k`: `ns` nanoseconds for `rays` rays; decide once both
    /// candidates have enough.
    pub fn record(&self, k: usize, ns: u64, rays: u64) {
        self.ns[k].fetch_add(ns, Ordering::Relaxed);
        self.rays[k].fetch_add(rays, Ordering::Relaxed);
        self.chunks[k].fetch_add(1, Ordering::Relaxed);
        let enough = |k: usize| {
            self.chunks[k].load(Ordering::Relaxed) >= MIN_CHUNKS && self.rays[k].load(Ordering::Relaxed) >= MIN_RAYS
        };
        if enough(0) && enough(1) {
            let [a, b] = self.ns_per_ray();
            let choice = if b < a * AVX2_MARGIN { 1 } else { 0 };
            // The first thread to see both complete decides; later counts change nothing.
            let _ = self.decided.compare_exchange(0, choice + 1, Ordering::Relaxed, Ordering::Relaxed);
        }
    }

    /// Nanoseconds per ray of each candidate so far (NaN where none ran).
    pub fn ns_per_ray(&self) -> [f64; 2] {
        std::array::from_fn(|k| {
            let rays = self.rays[k].load(Ordering::Relaxed);
            if rays == 0 {
                f64::NAN
            } else {
                self.ns[k].load(Ordering::Relaxed) as f64 / rays as f64
            }
        })
    }

    /// Forget everything: measure again.
    pub fn reset(&self) {
        self.decided.store(0, Ordering::Relaxed);
        self.next.store(0, Ordering::Relaxed);
        for k in 0..2 {
            self.ns[k].store(0, Ordering::Relaxed);
            self.rays[k].store(0, Ordering::Relaxed);
            self.chunks[k].store(0, Ordering::Relaxed);
        }
    }

    fn report(&self, walk: Walk) -> WalkLevel {
        WalkLevel {
            walk,
            level: self.decided(),
            ns_per_ray: self.ns_per_ray(),
            rays: std::array::from_fn(|k| self.rays[k].load(Ordering::Relaxed)),
        }
    }
}

/// The process's trials, one per [`Walk`] in [`Walk::ALL`]'s order.
static TRIALS: [Trial; 4] = [const { Trial::new() }; 4];

/// Whether the stages measure their level on this CPU: it runs both [`CANDIDATES`] and no
/// level is forced ([`super::force_simd_level`], [`super::SIMD_ENV`]).
pub fn applies() -> bool {
    SimdLevel::forced().is_none() && CANDIDATES.iter().all(|l| l.is_available())
}

/// [`Trial::timed`] of the process's trial of `walk`.
#[inline]
pub fn timed<R>(walk: Walk, rays: usize, trace: impl FnOnce(SimdLevel) -> R) -> R {
    TRIALS[walk as usize].timed(rays, trace)
}

/// The level `walk` runs at now: the chosen one, else the default.
pub fn current(walk: Walk) -> SimdLevel {
    TRIALS[walk as usize].decided().unwrap_or(CANDIDATES[0])
}

/// What each kind of walk runs at, and what was measured.
pub fn levels() -> [WalkLevel; 4] {
    std::array::from_fn(|i| TRIALS[i].report(Walk::ALL[i]))
}

/// One line per kind of walk that ran while measured (empty where tuning does not apply or
/// nothing was traced): its level and the two levels' nanoseconds per ray.
pub fn summary() -> Vec<String> {
    if !applies() {
        return Vec::new();
    }
    levels()
        .iter()
        .filter(|l| l.rays.iter().any(|&r| r > 0))
        .map(|l| {
            let [a, b] = l.ns_per_ray;
            let (na, nb) = (CANDIDATES[0].name(), CANDIDATES[1].name());
            let level = l.level.map_or(format!("{na} (still measuring)"), |v| v.name().to_string());
            format!(
                "{}: {level} (measured interleaved: {na} {a:.1} ns, {nb} {b:.1} ns a ray on one thread)",
                l.walk.name()
            )
        })
        .collect()
}

/// Forget every measurement (each kind measures again): for benchmarks that compare
/// levels from a clean start.
pub fn reset() {
    TRIALS.iter().for_each(Trial::reset);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feed `chunks` chunks of `rays` rays to the candidates in turn, candidate `k` taking
    /// `ns[k]` per ray.
    fn feed(t: &Trial, chunks: usize, rays: usize, ns: [u64; 2]) {
        for i in 0..chunks {
            t.record(i % 2, ns[i % 2] * rays as u64, rays as u64);
        }
    }

    #[test]
    fn a_kind_is_decided_only_once_both_levels_traced_enough() {
        let t = Trial::default();
        // Many rays in few chunks: not enough chunks.
        feed(&t, 2 * MIN_CHUNKS as usize - 2, 1 << 16, [10, 5]);
        assert_eq!(t.decided(), None);
        feed(&t, 2, 1 << 16, [10, 5]);
        assert_eq!(t.decided(), Some(SimdLevel::Avx2), "AVX2 took half the time");
        let t = Trial::default();
        // Many chunks of few rays: not enough rays.
        feed(&t, 4 * MIN_CHUNKS as usize, 8, [10, 5]);
        assert_eq!(t.decided(), None);
    }

    #[test]
    fn the_default_stays_unless_the_other_is_faster_by_the_margin() {
        for (ns, expect) in
            [([100, 99], SimdLevel::Avx512), ([100, 96], SimdLevel::Avx2), ([90, 100], SimdLevel::Avx512)]
        {
            let t = Trial::default();
            feed(&t, 2 * MIN_CHUNKS as usize, MIN_RAYS as usize, ns);
            assert_eq!(t.decided(), Some(expect), "{ns:?}");
            assert_eq!(t.ns_per_ray(), [ns[0] as f64, ns[1] as f64]);
        }
    }

    #[test]
    fn decided_kinds_run_their_level_and_measuring_kinds_alternate() {
        let t = Trial::default();
        let ran: Vec<SimdLevel> = (0..1000).map(|_| t.timed(10, |l| l)).collect();
        let avx2 = ran.iter().filter(|&&l| l == CANDIDATES[1]).count();
        assert!((450..=550).contains(&avx2), "{avx2} of 1000 chunks at AVX2");
        assert_eq!(t.report(Walk::AnyHitPackets).rays, [10 * (1000 - avx2 as u64), 10 * avx2 as u64]);
        // Every other chunk (one light of two in the fused tiles) is not one level's.
        let even = ran.iter().step_by(2).filter(|&&l| l == CANDIDATES[1]).count();
        assert!((200..=300).contains(&even), "{even} of the 500 even chunks at AVX2");
        feed(&t, 2 * MIN_CHUNKS as usize, MIN_RAYS as usize, [100, 50]);
        assert!((0..5).all(|_| t.timed(10, |l| l) == SimdLevel::Avx2));
        t.reset();
        assert_eq!((t.decided(), t.ns_per_ray()[0].is_nan()), (None, true));
    }
}
