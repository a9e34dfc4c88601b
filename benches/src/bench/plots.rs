//! PNG line plots with plotters (bitmap backend, text through ab_glyph).
//!
//! plotters is built without its font-kit/fontconfig backend, so text needs a font
//! registered at run time: DejaVu Sans from Debian's `fonts-dejavu-core`
//! ([`FONT_PATH`]). Without it, plotting fails with a message saying what to install.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;
use plotters::style::FontStyle;

use super::BenchError;

/// DejaVu Sans as Debian's `fonts-dejavu-core` installs it.
pub const FONT_PATH: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Plot size in pixels (small PNGs for the repository).
pub const PLOT_SIZE: (u32, u32) = (720, 450);

/// One line of points, drawn with markers.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

/// A line plot.
#[derive(Clone, Debug)]
pub struct Plot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// Logarithmic x axis (base 10).
    pub log_x: bool,
    /// Logarithmic y axis (base 10).
    pub log_y: bool,
    /// Tick label of an x value.
    pub x_format: fn(f64) -> String,
    pub series: Vec<Series>,
}

/// Register DejaVu Sans as plotters' "sans-serif" family (once per process).
pub fn load_font() -> Result<(), BenchError> {
    static FONT: OnceLock<Result<(), String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let bytes = std::fs::read(FONT_PATH).map_err(|e| format!("cannot read: {e}"))?;
        // plotters keeps fonts for the whole process: leak the bytes once.
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
            .map_err(|_| "not a font plotters can read".to_string())
    })
    .clone()
    .map_err(|message| BenchError::Font { path: PathBuf::from(FONT_PATH), message })
}

/// A range around `values` with 5% room on each side (a unit range around a single value).
fn padded(values: impl Iterator<Item = f64>, from_zero: bool) -> std::ops::Range<f64> {
    let (mut lo, mut hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() || !hi.is_finite() {
        return 0.0..1.0;
    }
    if from_zero {
        lo = lo.min(0.0);
    }
    if hi - lo <= f64::EPSILON * hi.abs().max(1.0) {
        lo -= 0.5;
        hi += 0.5;
    }
    let pad = 0.05 * (hi - lo);
    (if from_zero && lo >= 0.0 { lo } else { lo - pad })..hi + pad
}

/// Draw `plot` into a PNG at `path`.
pub fn draw(plot: &Plot, path: &Path) -> Result<(), BenchError> {
    load_font()?;
    let err = |e: &dyn std::fmt::Display| BenchError::Plot { path: path.to_path_buf(), message: e.to_string() };
    let (log_x, log_y) = (plot.log_x, plot.log_y);
    let tx = |x: f64| if log_x { x.log10() } else { x };
    let ty = |y: f64| if log_y { y.log10() } else { y };
    // Points that can be drawn: finite, and positive on a log axis.
    let pts: Vec<Vec<(f64, f64)>> = plot
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .copied()
                .filter(|(x, y)| x.is_finite() && y.is_finite() && (!log_x || *x > 0.0) && (!log_y || *y > 0.0))
                .collect()
        })
        .collect();
    // Ranges padded in axis space (log10 on a log axis), then back to values.
    let back = |r: std::ops::Range<f64>, log: bool| if log { 10f64.powf(r.start)..10f64.powf(r.end) } else { r };
    let x_range = back(padded(pts.iter().flatten().map(|p| tx(p.0)), false), log_x);
    let y_range = back(padded(pts.iter().flatten().map(|p| ty(p.1)), !log_y), log_y);

    let (w, h) = PLOT_SIZE;
    let mut rgb = vec![0u8; w as usize * h as usize * 3];
    let drawn = match (log_x, log_y) {
        (false, false) => draw_into(plot, &mut rgb, &pts, x_range, y_range),
        (true, false) => draw_into(plot, &mut rgb, &pts, x_range.log_scale(), y_range),
        (false, true) => draw_into(plot, &mut rgb, &pts, x_range, y_range.log_scale()),
        (true, true) => draw_into(plot, &mut rgb, &pts, x_range.log_scale(), y_range.log_scale()),
    };
    drawn.map_err(|e| err(&e))?;
    // Encoded here rather than by plotters' image 0.24 encoder: the best PNG compression
    // keeps the plots small enough to commit.
    let file = std::fs::File::create(path).map_err(|source| BenchError::Write { path: path.to_path_buf(), source })?;
    let enc = image::codecs::png::PngEncoder::new_with_quality(
        std::io::BufWriter::new(file),
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    );
    image::ImageEncoder::write_image(enc, &rgb, w, h, image::ExtendedColorType::Rgb8).map_err(|e| err(&e))
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

/// Draw into an RGB buffer with axes `x` and `y` (linear or logarithmic coordinates).
fn draw_into<X, Y>(plot: &Plot, rgb: &mut [u8], pts: &[Vec<(f64, f64)>], x: X, y: Y) -> DrawResult
where
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let err = |e: &dyn std::fmt::Display| -> Box<dyn std::error::Error> { e.to_string().into() };
    let root = BitMapBackend::with_buffer(rgb, PLOT_SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(&plot.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(x, y)
        .map_err(|e| err(&e))?;
    let x_format = plot.x_format;
    let x_label = move |v: &f64| x_format(*v);
    let y_label = |v: &f64| plain(*v);
    chart
        .configure_mesh()
        .x_desc(&plot.x_label)
        .y_desc(&plot.y_label)
        .x_labels(6)
        .y_labels(8)
        .x_label_formatter(&x_label)
        .y_label_formatter(&y_label)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()
        .map_err(|e| err(&e))?;
    let colors = [BLUE, RED, GREEN, MAGENTA, CYAN, BLACK];
    for (i, (s, p)) in plot.series.iter().zip(pts.iter().cloned()).enumerate() {
        let c = colors[i % colors.len()];
        chart
            .draw_series(LineSeries::new(p.clone(), c.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label(&s.label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        chart.draw_series(p.into_iter().map(|xy| Circle::new(xy, 4, c.filled()))).map_err(|e| err(&e))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Thousands and millions, trailing zeros trimmed: `1234567` -> "1.23M", `25820` -> "25.8k",
/// `100000` -> "100k".
pub fn si(x: f64) -> String {
    let a = x.abs();
    if a >= 1e6 {
        format!("{}M", plain_digits(x / 1e6, 2))
    } else if a >= 1e3 {
        format!("{}k", plain_digits(x / 1e3, 1))
    } else {
        plain_digits(x, 0)
    }
}

/// `x` with at most `digits` decimals, trailing zeros and point trimmed.
fn plain_digits(x: f64, digits: usize) -> String {
    let s = format!("{x:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// A plain number with up to three decimals.
pub fn plain(x: f64) -> String {
    plain_digits(x, 3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn padded_ranges() {
        assert_eq!(padded([1.0, 3.0].into_iter(), false), 0.9..3.1);
        assert_eq!(padded([1.0, 3.0].into_iter(), true), 0.0..3.15);
        assert_eq!(padded([2.0].into_iter(), false), 1.45..2.55);
        assert_eq!(padded(std::iter::empty(), false), 0.0..1.0);
    }

    #[test]
    fn tick_labels() {
        assert_eq!(si(25_820.0), "25.8k");
        assert_eq!(si(871_414.0), "871.4k");
        assert_eq!(si(100_000.0), "100k");
        assert_eq!(si(1_234_567.0), "1.23M");
        assert_eq!(si(1_000_000.0), "1M");
        assert_eq!(si(500.0), "500");
        assert_eq!(plain(0.92), "0.92");
        assert_eq!(plain(2.0), "2");
    }

    #[test]
    fn draws_a_png_when_the_font_is_installed() {
        if !Path::new(FONT_PATH).is_file() {
            eprintln!("{FONT_PATH} missing (Debian fonts-dejavu-core); skipping");
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        let plot = Plot {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            log_x: true,
            log_y: true,
            x_format: si,
            series: vec![Series { label: "a".into(), points: vec![(10.0, 1.0), (1000.0, 3.0)] }],
        };
        draw(&plot, &path).unwrap();
        let img = image::open(&path).unwrap();
        assert_eq!((img.width(), img.height()), PLOT_SIZE);
    }
}
