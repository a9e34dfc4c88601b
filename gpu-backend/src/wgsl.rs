//! Rust values spelled as WGSL literals, for the constants the shaders' preludes are
//! generated with ([`crate::shader`], [`crate::texture`]).

/// An f32 as a WGSL literal with exactly its value: the f32 widened to f64 and
/// printed shortest-round-trip, so naga's f64 parse and f32 conversion are exact.
pub(crate) fn f32_literal(x: f32) -> String {
    format!("{:?}", x as f64)
}
