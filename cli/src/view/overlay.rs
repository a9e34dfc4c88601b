//! The viewer's overlay: lines of text (frame rate, stage times, counts, legend) and the
//! composition-weight slider, rasterized on the CPU into a small premultiplied RGBA
//! image that either presenter lays over the frame's top-left corner.

use ab_glyph::{point, Font, FontVec, PxScale, ScaleFont};

use super::stages::Rgba8;

/// Where the overlay's font is looked for (DejaVu Sans: Debian's fonts-dejavu-core).
pub const FONT_PATHS: [&str; 3] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
];

/// Pixels between the overlay's edge and its text.
const MARGIN: u32 = 8;
/// Height of the weight slider's track.
const SLIDER_HEIGHT: u32 = 16;

/// A rectangle in overlay pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rect {
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

impl Rect {
    /// True if the point lies inside.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        x >= self.x as f64 && y >= self.y as f64 && x < (self.x + self.w) as f64 && y < (self.y + self.h) as f64
    }
}

/// The overlay's pixels, premultiplied RGBA, row 0 on top.
#[derive(Clone, Debug, Default)]
pub struct OverlayImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgba8>,
    /// The weight slider's track: a click or drag at x sets the weight to
    /// `(x - slider.x) / slider.w`.
    pub slider: Rect,
}

/// The font and size the overlay writes with.
pub struct Overlay {
    font: FontVec,
    scale: PxScale,
}

impl Overlay {
    /// The overlay with the first of [`FONT_PATHS`] that loads.
    pub fn load() -> Result<Overlay, String> {
        for path in FONT_PATHS {
            if let Ok(bytes) = std::fs::read(path) {
                let font = FontVec::try_from_vec(bytes).map_err(|e| format!("{path}: {e}"))?;
                return Ok(Overlay { font, scale: PxScale::from(12.0) });
            }
        }
        Err(format!("no overlay font (DejaVu Sans) at {}", FONT_PATHS.join(", ")))
    }

    /// `lines` on a translucent dark panel, then the slider at `weight` in [0, 1].
    pub fn draw(&self, lines: &[String], weight: f32) -> OverlayImage {
        let font = self.font.as_scaled(self.scale);
        let line_h = font.height().ceil() as u32 + 1;
        let text_w = lines.iter().map(|l| self.width_of(l)).fold(0.0f32, f32::max).ceil() as u32;
        let width = text_w.max(200) + 2 * MARGIN;
        let text_h = line_h * lines.len() as u32;
        let height = text_h + SLIDER_HEIGHT + 3 * MARGIN;
        let mut pixels = vec![[0, 0, 0, 150]; (width * height) as usize];
        for (i, line) in lines.iter().enumerate() {
            let baseline = (MARGIN + line_h * i as u32) as f32 + font.ascent();
            let mut x = MARGIN as f32;
            let mut last = None;
            for ch in line.chars() {
                let id = font.glyph_id(ch);
                if let Some(prev) = last {
                    x += font.kern(prev, id);
                }
                last = Some(id);
                let glyph = id.with_scale_and_position(self.scale, point(x, baseline));
                x += font.h_advance(id);
                let Some(outline) = self.font.outline_glyph(glyph) else { continue };
                let b = outline.px_bounds();
                outline.draw(|gx, gy, c| {
                    let (px, py) = (b.min.x as i64 + gx as i64, b.min.y as i64 + gy as i64);
                    if px >= 0 && py >= 0 && (px as u32) < width && (py as u32) < height {
                        let p = &mut pixels[(py as u32 * width + px as u32) as usize];
                        // White text over the panel, premultiplied.
                        let c = c.clamp(0.0, 1.0);
                        for ch in &mut p[..3] {
                            *ch = (*ch as f32 * (1.0 - c) + 255.0 * c) as u8;
                        }
                        p[3] = (p[3] as f32 * (1.0 - c) + 255.0 * c) as u8;
                    }
                });
            }
        }
        let slider = Rect { x: MARGIN, y: MARGIN * 2 + text_h, w: width - 2 * MARGIN, h: SLIDER_HEIGHT };
        let filled = (weight.clamp(0.0, 1.0) * slider.w as f32).round() as u32;
        for y in slider.y..slider.y + slider.h {
            for x in slider.x..slider.x + slider.w {
                let inside = x < slider.x + filled;
                pixels[(y * width + x) as usize] = if inside { [255, 140, 0, 255] } else { [70, 70, 70, 255] };
            }
        }
        OverlayImage { width, height, pixels, slider }
    }

    fn width_of(&self, line: &str) -> f32 {
        let font = self.font.as_scaled(self.scale);
        line.chars().map(|c| font.h_advance(font.glyph_id(c))).sum()
    }
}

/// Lay `overlay` (premultiplied) over the top-left corner of an opaque `width`-wide image.
pub fn compose(image: &mut [Rgba8], width: u32, overlay: &OverlayImage) {
    let height = image.len() as u32 / width.max(1);
    for y in 0..overlay.height.min(height) {
        for x in 0..overlay.width.min(width) {
            let o = overlay.pixels[(y * overlay.width + x) as usize];
            let p = &mut image[(y * width + x) as usize];
            let keep = 255 - o[3] as u32;
            for c in 0..3 {
                p[c] = (o[c] as u32 + (p[c] as u32 * keep + 127) / 255).min(255) as u8;
            }
        }
    }
}
