//! # hyrt-conformance
//!
//! The judge of hyrt's promise that backends (and runs, and thread counts) agree.
//!
//! - [`corpus`]: the scene corpus, built by code, each case named for what it stresses
//!   (paper scenes, raster, ray and degenerate hard cases, image sizes).
//! - [`compare`]: stage-by-stage comparison of two frames. Integer words (ids, flags,
//!   counts, ray-list keys, shadow visibility) must be identical; float words are
//!   compared in ulp with a histogram and the worst case; a pixel whose primary
//!   visibility differs is reported once, in `visibility_raster`.
//! - [`leak`]: the leak corpus: closed shells with lights sealed inside (nothing outside
//!   may be lit) or outside, from the origin to 1e6, and the leak count.
//! - [`report`]: running the corpus on two backends, the report (`report.md`, difference
//!   images; also `hyrt conformance --out DIR`), and the recorded deviations.
//!
//! ## Budgets
//!
//! The budget of every stage is 0: identical integers, 0 ulp, and it is met.
//! - Determinism: every stage's output is bit-identical run to run on each backend, and
//!   on 1 or 2 CPU threads (`tests/corpus.rs`).
//! - The GPU backend on Mesa lavapipe against the CPU reference: every stage, every
//!   word, on the whole corpus (`tests/corpus.rs`, also `hyrt conformance`). What makes it
//!   so:
//!   - `visibility_raster`: the fragment shader evaluates the reference kernels itself
//!     (exact 64-bit edge functions of the snapped positions, f32 barycentrics and
//!     depth) and writes the reference depth; vertices reach the hardware pre-snapped or
//!     as grown cover triangles, so the hardware proposes every pixel the reference
//!     covers (gpu-backend's `visibility_raster.wgsl`);
//!   - in every shader, products that feed a sum go through an OR with an always-zero
//!     uniform, so the compiler cannot fuse them into multiply-adds (lavapipe does fuse
//!     plain vector expressions: measured);
//!   - `pow` is a core kernel built from correctly rounded operations
//!     (`hyrt_core::kernels::shading::pow_portable`), mirrored in WGSL, instead of
//!     `powf` and WGSL `pow`, whose approximations differ;
//!   - it relies on the device computing f32 division, `sqrt`, conversions and `round`
//!     correctly rounded (lavapipe does; WGSL allows 2.5 ulp division and flushed
//!     subnormals, so another driver may not) and on the device's rasterizer using 8
//!     subpixel bits and the top-left rule (Vulkan's `subPixelPrecisionBits`).
//!
//! Should a deviation appear (another driver, a change), `known_deviations.toml` records
//! it per case and buffer as a ratchet (a run may improve on it, never exceed it, and a
//! case or buffer not listed must be exact) and [`report::CAUSES`] must name its cause.
//! The file is empty today.
//!
//! ```
//! use hyrt_conformance::ulp_distance;
//! assert_eq!(ulp_distance(1.0, 1.0), 0);
//! assert_eq!(ulp_distance(1.0, f32::from_bits(1.0f32.to_bits() + 3)), 3);
//! assert_eq!(ulp_distance(0.0, -0.0), 0);
//! ```

pub mod compare;
pub mod corpus;
pub mod leak;
pub mod report;

/// Map f32 bits to integers ordered like the floats (+0 and -0 both map to 0).
#[inline]
pub fn ordered_bits(x: f32) -> i64 {
    let b = x.to_bits() as i32;
    if b < 0 {
        -((b & 0x7fff_ffff) as i64)
    } else {
        b as i64
    }
}

/// Distance in units in the last place between two floats; `u64::MAX` if either is NaN
/// (unless both are NaN with the same bits).
#[inline]
pub fn ulp_distance(a: f32, b: f32) -> u64 {
    if a.is_nan() || b.is_nan() {
        return if a.to_bits() == b.to_bits() { 0 } else { u64::MAX };
    }
    (ordered_bits(a) - ordered_bits(b)).unsigned_abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ulp_distance_crosses_zero_and_handles_nan() {
        let tiny = f32::from_bits(1);
        assert_eq!(ulp_distance(tiny, -tiny), 2);
        assert_eq!(ulp_distance(f32::NAN, 1.0), u64::MAX);
        assert_eq!(ulp_distance(f32::NAN, f32::NAN), 0);
        assert_eq!(ulp_distance(f32::MAX, f32::INFINITY), 1);
    }
}
