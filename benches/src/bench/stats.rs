//! Statistics of repeated measurements: medians over frames or repetitions.

use hyrt_core::frame::FrameStats;
use hyrt_core::stage::Stage;

/// The median of `values` (the mean of the two middle values for an even count);
/// `None` for an empty slice or when any value is NaN.
pub fn median(values: &[f64]) -> Option<f64> {
    if values.is_empty() || values.iter().any(|v| v.is_nan()) {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) })
}

/// Per-stage and per-frame medians over several frames of the same scene and size.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSummary {
    /// Frames measured.
    pub frames: usize,
    /// Median milliseconds of each per-frame stage, in execution order (stages that
    /// did not run in every frame are left out).
    pub stage_ms: Vec<(Stage, f64)>,
    /// Median of the per-frame sums of the stages (without `bvh_build`): the frame time.
    pub frame_ms: f64,
}

impl FrameSummary {
    /// Summarize the statistics of `frames` (at least one).
    pub fn from_frames(frames: &[FrameStats]) -> Option<FrameSummary> {
        let frame_ms = median(&frames.iter().map(FrameStats::frame_ms).collect::<Vec<_>>())?;
        let stage_ms = Stage::ALL
            .into_iter()
            .filter(|&s| s != Stage::BvhBuild)
            .filter_map(|s| {
                let v: Option<Vec<f64>> = frames.iter().map(|f| f.ms(s)).collect();
                Some((s, median(&v?)?))
            })
            .collect();
        Some(FrameSummary { frames: frames.len(), stage_ms, frame_ms })
    }

    /// Median milliseconds of one stage, if it ran in every frame.
    pub fn ms(&self, stage: Stage) -> Option<f64> {
        self.stage_ms.iter().find(|(s, _)| *s == stage).map(|(_, ms)| *ms)
    }

    /// Frames per second at the median frame time.
    pub fn fps(&self) -> f64 {
        1e3 / self.frame_ms
    }
}

/// Million rays per second for `rays` rays traced in `ms` milliseconds.
pub fn mrays_per_s(rays: usize, ms: f64) -> f64 {
    rays as f64 / (ms * 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hyrt_core::frame::StageTime;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&[]), None);
        assert_eq!(median(&[3.0]), Some(3.0));
        assert_eq!(median(&[5.0, 1.0, 3.0]), Some(3.0));
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median(&[1.0, f64::NAN]), None);
    }

    proptest::proptest! {
        #[test]
        fn median_splits_the_values_in_halves(v in proptest::collection::vec(-1e6f64..1e6, 1..50)) {
            let m = median(&v).unwrap();
            let below = v.iter().filter(|&&x| x < m).count();
            let above = v.iter().filter(|&&x| x > m).count();
            proptest::prop_assert!(below <= v.len() / 2 && above <= v.len() / 2, "{m} of {v:?}");
        }
    }

    fn stats(times: &[(Stage, f64)]) -> FrameStats {
        FrameStats {
            stage_ms: times
                .iter()
                .map(|&(stage, ms)| StageTime { stage, depth: 0, ms, work: Default::default() })
                .collect(),
            ..Default::default()
        }
    }

    #[test]
    fn frame_summary_takes_medians_per_stage_and_of_the_frame_sums() {
        let frames = [
            stats(&[(Stage::VisibilityRaster, 1.0), (Stage::ShadowRays, 10.0)]),
            stats(&[(Stage::VisibilityRaster, 3.0), (Stage::ShadowRays, 2.0)]),
            stats(&[(Stage::VisibilityRaster, 2.0), (Stage::ShadowRays, 4.0), (Stage::Composition, 1.0)]),
        ];
        let s = FrameSummary::from_frames(&frames).unwrap();
        assert_eq!(s.ms(Stage::VisibilityRaster), Some(2.0));
        assert_eq!(s.ms(Stage::ShadowRays), Some(4.0));
        // Composition ran in one frame only: no median.
        assert_eq!(s.ms(Stage::Composition), None);
        // Frame sums 11, 5, 7: median 7 (not the sum of the stage medians, 6).
        assert_eq!(s.frame_ms, 7.0);
        assert_eq!(s.fps(), 1e3 / 7.0);
        assert_eq!(FrameSummary::from_frames(&[]), None);
    }

    #[test]
    fn mrays_per_second() {
        assert_eq!(mrays_per_s(2_000_000, 1000.0), 2.0);
    }
}

/// Time contenders in interleaved rounds, so that a noisy machine slows them alike: each
/// runs once untimed (warm-up), then `rounds` rounds run every contender once, in an order
/// rotated by one each round (no contender always runs first). Milliseconds per
/// contender, per round (`[contender][round]`).
pub fn interleaved_ms(rounds: usize, contenders: &mut [&mut dyn FnMut()]) -> Vec<Vec<f64>> {
    interleaved_rounds_ms(rounds, &mut |_| {}, contenders)
}

/// [`interleaved_ms`] with an untimed `setup` before every round: `setup(0)` before the
/// warm-up, `setup(r)` before round `r` (1-based), e.g. moving an object to frame `r`'s
/// place before every contender updates its scene for it.
pub fn interleaved_rounds_ms(
    rounds: usize,
    setup: &mut dyn FnMut(usize),
    contenders: &mut [&mut dyn FnMut()],
) -> Vec<Vec<f64>> {
    interleaved_turns_ms(rounds, setup, &mut || {}, contenders)
}

/// [`interleaved_rounds_ms`] with `before_turn` also run untimed right before every
/// timed turn, e.g. evicting the caches so that no contender starts from what the one
/// before it left there (`ray_contest --cold`).
pub fn interleaved_turns_ms(
    rounds: usize,
    setup: &mut dyn FnMut(usize),
    before_turn: &mut dyn FnMut(),
    contenders: &mut [&mut dyn FnMut()],
) -> Vec<Vec<f64>> {
    setup(0);
    contenders.iter_mut().for_each(|c| c());
    let n = contenders.len();
    let mut ms = vec![Vec::with_capacity(rounds); n];
    for r in 0..rounds.max(1) {
        setup(r + 1);
        for j in 0..n {
            let i = (j + r) % n;
            before_turn();
            let t = std::time::Instant::now();
            contenders[i]();
            ms[i].push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    ms
}

/// The least and greatest of `values` (`None` when empty).
pub fn range(values: &[f64]) -> Option<(f64, f64)> {
    let lo = values.iter().copied().min_by(f64::total_cmp)?;
    let hi = values.iter().copied().max_by(f64::total_cmp)?;
    Some((lo, hi))
}

/// The ratio `peer / hyrt` of two contenders' times round by round (`peer[r]` the
/// peer's time in round `r`): its median, least and greatest. `None` without rounds.
pub fn round_ratios(peer: &[f64], hyrt: &[f64]) -> Option<(f64, f64, f64)> {
    let ratios: Vec<f64> = peer.iter().zip(hyrt).map(|(p, h)| p / h).collect();
    let (lo, hi) = range(&ratios)?;
    Some((median(&ratios)?, lo, hi))
}

#[cfg(test)]
mod interleaving_tests {
    use super::*;

    #[test]
    fn interleaved_rounds_time_every_contender_once_per_round_in_rotated_order() {
        let order = std::cell::RefCell::new(Vec::new());
        let (mut a, mut b, mut c) =
            (|| order.borrow_mut().push('a'), || order.borrow_mut().push('b'), || order.borrow_mut().push('c'));
        let ms = interleaved_ms(3, &mut [&mut a, &mut b, &mut c]);
        assert!(ms.iter().all(|m| m.len() == 3));
        // Warm-up, then rounds starting at a, b, c.
        assert_eq!(order.into_inner().iter().collect::<String>(), "abc".to_string() + "abc" + "bca" + "cab");
    }

    #[test]
    fn interleaved_rounds_set_up_each_round_untimed_before_its_contenders() {
        let order = std::cell::RefCell::new(String::new());
        let mut setup = |r: usize| order.borrow_mut().push_str(&r.to_string());
        let (mut a, mut b) = (|| order.borrow_mut().push('a'), || order.borrow_mut().push('b'));
        let ms = interleaved_rounds_ms(2, &mut setup, &mut [&mut a, &mut b]);
        assert!(ms.iter().all(|m| m.len() == 2));
        assert_eq!(order.into_inner(), "0ab1ab2ba");
        assert_eq!(range(&[3.0, 1.0, 2.0]), Some((1.0, 3.0)));
        assert_eq!(range(&[]), None);
    }

    #[test]
    fn interleaved_turns_run_the_hook_before_every_timed_turn_only() {
        let order = std::cell::RefCell::new(String::new());
        let mut setup = |r: usize| order.borrow_mut().push_str(&r.to_string());
        let mut flush = || order.borrow_mut().push('.');
        let (mut a, mut b) = (|| order.borrow_mut().push('a'), || order.borrow_mut().push('b'));
        let ms = interleaved_turns_ms(2, &mut setup, &mut flush, &mut [&mut a, &mut b]);
        assert!(ms.iter().all(|m| m.len() == 2));
        // Not before the untimed warm-up.
        assert_eq!(order.into_inner(), "0ab1.a.b2.b.a");
    }

    #[test]
    fn round_ratios_are_per_round() {
        // The peer twice as slow in every round, whatever the machine did to both.
        let (m, lo, hi) = round_ratios(&[2.0, 8.0, 4.0], &[1.0, 4.0, 2.0]).unwrap();
        assert_eq!((m, lo, hi), (2.0, 2.0, 2.0));
        let (m, lo, hi) = round_ratios(&[3.0, 1.0, 2.0], &[1.0, 1.0, 1.0]).unwrap();
        assert_eq!((m, lo, hi), (2.0, 1.0, 3.0));
        assert!(round_ratios(&[], &[]).is_none());
    }
}
