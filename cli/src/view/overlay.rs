//! The viewer's overlay: lines of text (frame rate, stage times, counts, legend), the
//! composition-weight slider and the exposure slider, rasterized on the CPU into a small
//! premultiplied RGBA image that either presenter lays over the frame's top-left corner.

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
/// Height of a slider's track.
const SLIDER_HEIGHT: u32 = 16;
/// The sliders, top to bottom.
pub const SLIDERS: [Slider; 2] = [Slider::Weight, Slider::Exposure];

/// The exposure slider's range either way, in stops: ±8 stops span a factor of 65,536,
/// every exposure a display needs (Page Up and Page Down reach
/// `hyrt render --exposure`'s ±64).
pub const EXPOSURE_SLIDER_STOPS: f32 = 8.0;

/// What a slider sets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slider {
    /// The composition weight, 0 at the left end, 1 at the right.
    Weight,
    /// The display's exposure, -[`EXPOSURE_SLIDER_STOPS`] at the left end, 0 in the middle,
    /// +[`EXPOSURE_SLIDER_STOPS`] at the right.
    Exposure,
}

impl Slider {
    /// The value at `fraction` (0 at the left end, 1 at the right; clamped).
    pub fn value(self, fraction: f32) -> f32 {
        let f = fraction.clamp(0.0, 1.0);
        match self {
            Slider::Weight => f,
            Slider::Exposure => (2.0 * f - 1.0) * EXPOSURE_SLIDER_STOPS,
        }
    }

    /// Where `value` sits on the track, in [0, 1] (values past the ends at the ends).
    pub fn fraction(self, value: f32) -> f32 {
        match self {
            Slider::Weight => value,
            Slider::Exposure => (value / EXPOSURE_SLIDER_STOPS + 1.0) * 0.5,
        }
        .clamp(0.0, 1.0)
    }
}

/// A slider's filled part and the rest of its track.
const FILLED: Rgba8 = [255, 140, 0, 255];
const EMPTY: Rgba8 = [70, 70, 70, 255];

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
    /// The tracks of [`SLIDERS`], in order: a click or drag at x sets the slider's value at
    /// the fraction `(x - track.x) / track.w` ([`Slider::value`]).
    pub sliders: [Rect; SLIDERS.len()],
}

impl OverlayImage {
    /// The slider whose track holds the point, and that track.
    pub fn slider_at(&self, x: f64, y: f64) -> Option<(Slider, Rect)> {
        SLIDERS.into_iter().zip(self.sliders).find(|(_, r)| r.contains(x, y))
    }

    /// The value `slider` takes at overlay x (past its track's ends: the end's value).
    pub fn value_at(&self, slider: Slider, x: f64) -> f32 {
        let i = SLIDERS.iter().position(|&s| s == slider).expect("every slider is drawn");
        let track = self.sliders[i];
        slider.value(((x - track.x as f64) / track.w.max(1) as f64) as f32)
    }
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

    /// `lines` on a translucent dark panel, then the tracks of [`SLIDERS`] filled to
    /// `fractions` (each in [0, 1], [`Slider::fraction`]).
    pub fn draw(&self, lines: &[String], fractions: [f32; SLIDERS.len()]) -> OverlayImage {
        let font = self.font.as_scaled(self.scale);
        let line_h = font.height().ceil() as u32 + 1;
        let text_w = lines.iter().map(|l| self.width_of(l)).fold(0.0f32, f32::max).ceil() as u32;
        let width = text_w.max(200) + 2 * MARGIN;
        let text_h = line_h * lines.len() as u32;
        let n = SLIDERS.len() as u32;
        let height = text_h + n * (SLIDER_HEIGHT + MARGIN) + 2 * MARGIN;
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
        let sliders: [Rect; SLIDERS.len()] = std::array::from_fn(|i| Rect {
            x: MARGIN,
            y: MARGIN * 2 + text_h + i as u32 * (SLIDER_HEIGHT + MARGIN),
            w: width - 2 * MARGIN,
            h: SLIDER_HEIGHT,
        });
        for (track, fraction) in sliders.iter().zip(fractions) {
            let filled = (fraction.clamp(0.0, 1.0) * track.w as f32).round() as u32;
            for y in track.y..track.y + track.h {
                for x in track.x..track.x + track.w {
                    let inside = x < track.x + filled;
                    pixels[(y * width + x) as usize] = if inside { FILLED } else { EMPTY };
                }
            }
        }
        OverlayImage { width, height, pixels, sliders }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sliders_map_their_ends_and_middle() {
        assert_eq!((Slider::Weight.value(0.0), Slider::Weight.value(1.0)), (0.0, 1.0));
        let e = Slider::Exposure;
        assert_eq!((e.value(0.0), e.value(0.5), e.value(1.0)), (-EXPOSURE_SLIDER_STOPS, 0.0, EXPOSURE_SLIDER_STOPS));
        // Past the ends: clamped both ways (Page Up can go further than the track shows).
        assert_eq!((e.value(-1.0), e.fraction(64.0), e.fraction(-64.0)), (-EXPOSURE_SLIDER_STOPS, 1.0, 0.0));
        for s in SLIDERS {
            for f in [0.0, 0.25, 0.5, 0.75, 1.0] {
                assert_eq!(s.fraction(s.value(f)), f, "{s:?} at {f}");
            }
        }
    }

    #[test]
    fn the_overlay_draws_each_slider_filled_to_its_fraction() {
        let overlay = match Overlay::load() {
            Ok(o) => o,
            // CI installs the font (.ci/run): there this test must run.
            Err(e) if std::env::var_os("CI").is_none() => return eprintln!("skipped: {e}"),
            Err(e) => panic!("{e}"),
        };
        let image = overlay.draw(&["a line".into()], [0.25, 0.75]);
        let [weight, exposure] = image.sliders;
        assert!(exposure.y >= weight.y + weight.h, "the exposure track lies below the weight's");
        assert!(exposure.y + exposure.h <= image.height);
        for (track, fraction) in image.sliders.iter().zip([0.25f32, 0.75]) {
            let y = track.y + track.h / 2;
            let at = |x: u32| image.pixels[(y * image.width + x) as usize];
            let edge = track.x + (fraction * track.w as f32).round() as u32;
            assert_eq!(
                (at(track.x), at(edge - 1), at(edge), at(track.x + track.w - 1)),
                (FILLED, FILLED, EMPTY, EMPTY)
            );
            let mid = (track.x + track.w / 2) as f64;
            assert_eq!(image.slider_at(mid, y as f64).map(|(_, r)| r), Some(*track));
        }
        // A drag across the tracks: ends, middle, beyond.
        let (w, e) = (Slider::Weight, Slider::Exposure);
        let (left, right) = (exposure.x as f64, (exposure.x + exposure.w) as f64);
        assert_eq!(
            (image.value_at(w, left), image.value_at(w, right), image.value_at(w, right + 50.0)),
            (0.0, 1.0, 1.0)
        );
        assert_eq!(image.value_at(e, (left + right) / 2.0), 0.0);
        assert_eq!(
            (image.value_at(e, left - 50.0), image.value_at(e, right)),
            (-EXPOSURE_SLIDER_STOPS, EXPOSURE_SLIDER_STOPS)
        );
        assert_eq!(image.slider_at(0.0, 0.0), None);
    }
}
