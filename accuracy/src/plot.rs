//! The Pareto plot (time against error) of one scene, drawn with `plotters`' bitmap
//! backend. Text needs a TrueType font: DejaVu Sans is loaded from [`FONT_PATH`] at run
//! time (Debian package `fonts-dejavu-core`) and registered with plotters' `ab_glyph`
//! renderer, so the build needs no fontconfig or freetype.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

/// Where the plot font is read from.
pub const FONT_PATH: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Family name the font is registered under.
const FONT_FAMILY: &str = "sans-serif";

/// Errors on a log axis cannot be 0: values below this are drawn at it (the axis label
/// says so). Below one mismatch in 10^7 pairs, or a FLIP of 10^-7, nothing is visible.
pub const ERROR_FLOOR: f64 = 1e-7;

/// Why a plot was not written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("{path}: cannot load the plot font ({message}); install the Debian package fonts-dejavu-core")]
    Font { path: PathBuf, message: String },
    #[error("{path}: cannot draw the plot: {message}")]
    Draw { path: PathBuf, message: String },
}

/// Load and register the font once per process.
fn ensure_font() -> Result<(), PlotError> {
    static FONT: OnceLock<Result<(), String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let bytes = std::fs::read(FONT_PATH).map_err(|e| e.to_string())?;
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        register_font(FONT_FAMILY, FontStyle::Normal, bytes).map_err(|_| "not a TrueType font".to_string())
    })
    .clone()
    .map_err(|message| PlotError::Font { path: PathBuf::from(FONT_PATH), message })
}

/// One configuration in a panel.
#[derive(Clone, Debug)]
pub struct PlotPoint {
    pub group: String,
    pub label: String,
    pub time_ms: f64,
    pub error: f64,
}

/// One panel: an error measure (y) against time (x), both logarithmic.
#[derive(Clone, Debug)]
pub struct Panel {
    pub y_label: String,
    pub points: Vec<PlotPoint>,
}

/// The Pareto front of `points`: those no other point beats in both time and error,
/// by increasing time.
pub fn pareto_front(points: &[PlotPoint]) -> Vec<(f64, f64)> {
    let mut p: Vec<(f64, f64)> = points.iter().map(|p| (p.time_ms, p.error.max(ERROR_FLOOR))).collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut front: Vec<(f64, f64)> = Vec::new();
    for q in p {
        if front.last().is_none_or(|l| q.1 < l.1) {
            front.push(q);
        }
    }
    front
}

/// Log-axis range around `values`, half a decade of margin.
fn log_range(values: impl Iterator<Item = f64>, floor: f64) -> std::ops::Range<f64> {
    let (mut lo, mut hi) = (f64::INFINITY, 0f64);
    for v in values {
        let v = v.max(floor);
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return floor..floor * 10.0;
    }
    lo / 3.0..hi * 3.0
}

/// Which points get a text label: a point close to an already labelled one (in the
/// plot's log coordinates, under 12% of the x range and 4% of the y range) stays
/// unlabelled, so clusters of equal configurations do not overprint. The table has them all.
fn label_positions(points: &[PlotPoint], x: &std::ops::Range<f64>, y: &std::ops::Range<f64>) -> Vec<bool> {
    let norm = |v: f64, r: &std::ops::Range<f64>| (v.log10() - r.start.log10()) / (r.end.log10() - r.start.log10());
    let mut placed: Vec<(f64, f64)> = Vec::new();
    points
        .iter()
        .map(|p| {
            let q = (norm(p.time_ms.max(1e-3), x), norm(p.error.max(ERROR_FLOOR), y));
            let free = placed.iter().all(|o| (o.0 - q.0).abs() >= 0.12 || (o.1 - q.1).abs() >= 0.04);
            if free {
                placed.push(q);
            }
            free
        })
        .collect()
}

/// Draw `panels` side by side into the PNG at `path`.
pub fn pareto_plot(path: &Path, title: &str, panels: &[Panel]) -> Result<(), PlotError> {
    ensure_font()?;
    let draw_err = |e: &dyn std::fmt::Display| PlotError::Draw { path: path.to_path_buf(), message: e.to_string() };
    let width = 700 * panels.len().max(1) as u32;
    let root = BitMapBackend::new(path, (width, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| draw_err(&e))?;
    let root = root.titled(title, (FONT_FAMILY, 22)).map_err(|e| draw_err(&e))?;
    let areas = root.split_evenly((1, panels.len().max(1)));
    let mut groups: Vec<&str> = Vec::new();
    for p in panels.iter().flat_map(|p| &p.points) {
        if !groups.contains(&p.group.as_str()) {
            groups.push(&p.group);
        }
    }
    for (panel, area) in panels.iter().zip(&areas) {
        let x = log_range(panel.points.iter().map(|p| p.time_ms), 1e-3);
        let y = log_range(panel.points.iter().map(|p| p.error), ERROR_FLOOR);
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x.clone().log_scale(), y.clone().log_scale())
            .map_err(|e| draw_err(&e))?;
        chart
            .configure_mesh()
            .x_desc("frame time (ms, median)")
            .y_desc(format!("{} (0 drawn at {ERROR_FLOOR:e})", panel.y_label))
            .label_style((FONT_FAMILY, 13))
            .draw()
            .map_err(|e| draw_err(&e))?;
        let front = pareto_front(&panel.points);
        chart
            .draw_series(LineSeries::new(front, BLACK.mix(0.4).stroke_width(1)))
            .map_err(|e| draw_err(&e))?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLACK.mix(0.4)));
        let labelled = label_positions(&panel.points, &x, &y);
        for (gi, group) in groups.iter().enumerate() {
            let color = Palette99::pick(gi).to_rgba();
            let pts: Vec<(&PlotPoint, bool)> =
                panel.points.iter().zip(&labelled).filter(|(p, _)| p.group == *group).map(|(p, &l)| (p, l)).collect();
            chart
                .draw_series(pts.iter().map(|(p, l)| {
                    let label = if *l { p.label.clone() } else { String::new() };
                    EmptyElement::at((p.time_ms, p.error.max(ERROR_FLOOR)))
                        + Circle::new((0, 0), 5, color.filled())
                        + Text::new(label, (7, -6), (FONT_FAMILY, 12))
                }))
                .map_err(|e| draw_err(&e))?
                .label(*group)
                .legend(move |(x, y)| Circle::new((x + 8, y), 5, color.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT_FAMILY, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| draw_err(&e))?;
    }
    root.present().map_err(|e| draw_err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(t: f64, e: f64) -> PlotPoint {
        PlotPoint { group: "g".into(), label: format!("{t}"), time_ms: t, error: e }
    }

    #[test]
    fn pareto_front_keeps_only_non_dominated_points() {
        let pts = [pt(3.0, 0.1), pt(1.0, 0.5), pt(2.0, 0.6), pt(4.0, 0.01), pt(5.0, 0.01)];
        assert_eq!(pareto_front(&pts), vec![(1.0, 0.5), (3.0, 0.1), (4.0, 0.01)]);
    }
}
