//! The viewer's stage views: which buffer of the frame each shows, and how its values
//! become colours (8-bit sRGB RGBA, row 0 on top, one texel per pixel).

use hyrt::formats::{GBufferTexel, INVALID_ID, SHADOW_LIT, SHADOW_OCCLUDED};
use hyrt::{BounceBuffer, BufferView, Frame, FrameBuffer};
use hyrt_core::kernels::shading::rgba_to_srgb8;

/// One RGBA8 texel.
pub type Rgba8 = [u8; 4];

/// What the window shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    Final,
    Raster,
    RayTraced,
    Barycentrics,
    Depth,
    Normals,
    TriangleIds,
    ObjectIds,
    RayTracedFlag,
    /// One light's shadow mask (the viewer's current light).
    Shadow,
    /// The ray list (compaction's shadow rays) as a count per pixel.
    RayCount,
    /// The deepest reflection or refraction bounce that leaves each pixel.
    BounceDepth,
}

impl View {
    /// Every view, in the order of their keys (1, 2, ..., 9, 0, -, =).
    pub const ALL: [View; 12] = [
        View::Final,
        View::Raster,
        View::RayTraced,
        View::Barycentrics,
        View::Depth,
        View::Normals,
        View::TriangleIds,
        View::ObjectIds,
        View::RayTracedFlag,
        View::Shadow,
        View::RayCount,
        View::BounceDepth,
    ];

    /// The key that selects it, as the legend writes it.
    pub const KEYS: [&'static str; 12] = ["1", "2", "3", "4", "5", "6", "7", "8", "9", "0", "-", "="];

    /// Its name on screen.
    pub fn name(self) -> &'static str {
        match self {
            View::Final => "final image",
            View::Raster => "raster image",
            View::RayTraced => "ray-traced image",
            View::Barycentrics => "barycentrics (u, v, w)",
            View::Depth => "depth (near white)",
            View::Normals => "normals",
            View::TriangleIds => "triangle ids",
            View::ObjectIds => "object ids",
            View::RayTracedFlag => "ray traced (orange) / rasterized (blue)",
            View::Shadow => "shadow mask (white lit, red occluded)",
            View::RayCount => "ray list: rays per pixel",
            View::BounceDepth => "bounce depth",
        }
    }

    /// The buffers it reads; the first must be held for the view to show anything.
    pub fn buffer(self) -> FrameBuffer {
        match self {
            View::Final => FrameBuffer::Final,
            View::Raster => FrameBuffer::Raster,
            View::RayTraced => FrameBuffer::Rt,
            View::Barycentrics | View::Depth | View::TriangleIds | View::ObjectIds | View::RayTracedFlag => {
                FrameBuffer::GBuffer
            }
            View::Normals => FrameBuffer::Surfaces,
            View::Shadow => FrameBuffer::Shadow,
            View::RayCount => FrameBuffer::Rays,
            View::BounceDepth => FrameBuffer::Bounce { buffer: BounceBuffer::Rays, depth: 1 },
        }
    }

    /// True if the frame must hold every stage's output for this view
    /// ([`hyrt::FrameOptions::stage_outputs`]): the viewer's frames keep the G-buffer
    /// ([`hyrt::FrameOptions::keep_gbuffer`], for picking), so its views need no more.
    pub fn needs_stage_outputs(self) -> bool {
        !hyrt::FrameOptions { keep_gbuffer: true, ..Default::default() }.returns(self.buffer())
    }
}

/// Why a view shows nothing for `frame`, if it does not.
pub fn missing(view: View, frame: &Frame) -> Option<String> {
    let buffer = view.buffer();
    if frame.holds(buffer) {
        return None;
    }
    let stage = buffer.writer();
    let reason = frame.stats.skipped.iter().find(|k| k.stage == stage).map(|k| k.reason.describe());
    Some(match reason {
        Some(r) => format!("{} skipped by this frame's plan: {r}", stage.name()),
        None => format!("{} did not run in this frame", stage.name()),
    })
}

/// A colour per id, far apart for neighbouring ids.
fn id_colour(id: u32) -> Rgba8 {
    if id == INVALID_ID {
        return [0, 0, 0, 255];
    }
    // A 32-bit mix (the murmur3 finaliser) spreads consecutive ids over the colours.
    let mut h = id.wrapping_add(0x9e37_79b9);
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^= h >> 16;
    let c = |shift: u32| 64 + ((h >> shift) & 0xff) as u8 / 4 * 3;
    [c(0), c(8), c(16), 255]
}

/// A unit value to 8 bits (clamped).
fn unorm(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// A count on a blue-to-yellow ramp, 0 black, `max` and above yellow.
fn heat(count: u32, max: u32) -> Rgba8 {
    if count == 0 {
        return [0, 0, 0, 255];
    }
    let t = count as f32 / max.max(1) as f32;
    [unorm(t * 1.5 - 0.25), unorm(t), unorm(1.0 - t * 0.8), 255]
}

fn gbuffer_view(g: &[GBufferTexel], f: impl Fn(&GBufferTexel) -> Rgba8) -> Vec<Rgba8> {
    g.iter().map(|t| if t.is_hit() { f(t) } else { [0, 0, 0, 255] }).collect()
}

/// The colours of `view` for `frame` (black where the frame does not hold its buffer);
/// `light` picks the shadow mask's light; the images (final, raster, rt) are displayed
/// through `display`, an exposure scale and a tone-mapping operator (core's
/// `tone_map::display`, as `hyrt render` writes PNGs).
pub fn colours(view: View, frame: &Frame, light: usize, lights: usize, display: (f32, hyrt::ToneMap)) -> Vec<Rgba8> {
    let pixels = frame.width as usize * frame.height as usize;
    let black = || vec![[0, 0, 0, 255]; pixels];
    let Some(buffer) = frame.holds(view.buffer()).then(|| frame.buffer(view.buffer())).flatten() else {
        return black();
    };
    match (view, buffer) {
        (View::Final | View::Raster | View::RayTraced, BufferView::Image(img)) => {
            let (scale, op) = display;
            img.iter()
                .map(|&p| rgba_to_srgb8(hyrt_core::kernels::tone_map::display(p, scale, op)))
                .map(|[r, g, b, _]| [r, g, b, 255])
                .collect()
        }
        (View::Barycentrics, BufferView::GBuffer(g)) => {
            gbuffer_view(g, |t| [unorm(1.0 - t.bary_u - t.bary_v), unorm(t.bary_u), unorm(t.bary_v), 255])
        }
        (View::Depth, BufferView::GBuffer(g)) => {
            // Window depth crowds near 1: stretch the range the hits span.
            let (lo, hi) = g
                .iter()
                .filter(|t| t.is_hit())
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), t| (lo.min(t.depth), hi.max(t.depth)));
            let span = (hi - lo).max(f32::MIN_POSITIVE);
            gbuffer_view(g, |t| {
                let v = unorm(1.0 - (t.depth - lo) / span * 0.9);
                [v, v, v, 255]
            })
        }
        (View::TriangleIds, BufferView::GBuffer(g)) => gbuffer_view(g, |t| id_colour(t.triangle)),
        (View::ObjectIds, BufferView::GBuffer(g)) => gbuffer_view(g, |t| id_colour(t.object)),
        (View::RayTracedFlag, BufferView::GBuffer(g)) => {
            gbuffer_view(g, |t| if t.is_ray_traced() { [255, 140, 0, 255] } else { [40, 90, 220, 255] })
        }
        (View::Normals, BufferView::Surfaces(s)) => s
            .iter()
            .map(|s| {
                if s.normal == [0.0; 3] {
                    [0, 0, 0, 255]
                } else {
                    let [x, y, z] = s.normal.map(|n| unorm(n * 0.5 + 0.5));
                    [x, y, z, 255]
                }
            })
            .collect(),
        (View::Shadow, BufferView::Codes(codes)) => {
            let lights = lights.max(1);
            (0..pixels)
                .map(|p| match codes.get(p * lights + light.min(lights - 1)).copied() {
                    Some(SHADOW_LIT) => [255, 255, 255, 255],
                    Some(SHADOW_OCCLUDED) => [170, 30, 30, 255],
                    _ => [0, 0, 0, 255],
                })
                .collect()
        }
        (View::RayCount, BufferView::Rays(rays)) => {
            let mut count = vec![0u32; pixels];
            for r in rays {
                if let Some(c) = count.get_mut(r.pixel as usize) {
                    *c += 1;
                }
            }
            count.iter().map(|&c| heat(c, lights as u32)).collect()
        }
        (View::BounceDepth, _) => bounce_depth(frame, pixels),
        _ => black(),
    }
}

/// Per pixel, the deepest bounce a reflection or refraction ray of it reached: a ray of
/// depth 1 names its pixel, a deeper one the ray of the depth above it.
fn bounce_depth(frame: &Frame, pixels: usize) -> Vec<Rgba8> {
    let mut deepest = vec![0u32; pixels];
    let mut pixel_of: Vec<u32> = Vec::new();
    for depth in 1..=frame.stats.bounces.len() as u32 {
        let buffer = FrameBuffer::Bounce { buffer: BounceBuffer::Rays, depth };
        let Some(BufferView::Rays(rays)) = frame.holds(buffer).then(|| frame.buffer(buffer)).flatten() else {
            break;
        };
        let parents = std::mem::take(&mut pixel_of);
        pixel_of = rays
            .iter()
            .map(|r| if depth == 1 { r.pixel } else { parents.get(r.pixel as usize).copied().unwrap_or(INVALID_ID) })
            .collect();
        for &p in &pixel_of {
            if let Some(d) = deepest.get_mut(p as usize) {
                *d = depth;
            }
        }
    }
    let max = frame.stats.bounces.len() as u32;
    deepest.iter().map(|&d| heat(d, max)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_view_has_a_key_and_ids_get_distinct_colours() {
        assert_eq!(View::ALL.len(), View::KEYS.len());
        assert_ne!(id_colour(0), id_colour(1));
        assert_eq!(id_colour(INVALID_ID), [0, 0, 0, 255]);
    }

    #[test]
    fn the_final_view_is_the_final_image_in_srgb() {
        let mut scene = hyrt::Scene::default_scene();
        scene.ensure_camera_and_lights();
        let mut renderer = hyrt::Renderer::cpu(Some(1));
        let prepared = renderer.prepare(&scene);
        let options = hyrt::FrameOptions { stage_outputs: true, ..Default::default() };
        let frame = renderer.render(&prepared, &scene.camera.unwrap(), 32, 18, &options).unwrap();
        let srgb = frame.final_srgb8();
        let plain = (1.0, hyrt::ToneMap::None);
        let view = colours(View::Final, &frame, 0, 1, plain);
        assert!(view.iter().zip(srgb.chunks(4)).all(|(v, s)| v[..3] == s[..3]));
        for v in View::ALL {
            assert_eq!(colours(v, &frame, 0, prepared.geometry.lights.len(), plain).len(), 32 * 18, "{v:?}");
        }
        // An exposure of one stop brightens the image, as hyrt render's PNG does.
        let brighter = colours(View::Final, &frame, 0, 1, (2.0, hyrt::ToneMap::None));
        assert!(brighter.iter().zip(&view).all(|(b, v)| b[0] >= v[0]) && brighter != view);
    }
}
