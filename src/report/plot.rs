//! SVG charts for the report, drawn with plotters' SVG backend (text is written as `<text>`
//! elements in a generic font family: no font files, nothing fetched), and the min/max
//! decimation that keeps long traces small without hiding their peaks.

use std::ops::Range;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::error::{Error, Result};

/// Width of every chart in pixels (the page scales it down on narrow screens).
pub const WIDTH: u32 = 1000;

/// Points kept per series: two per pixel column (its minimum and maximum).
pub const COLUMNS: usize = WIDTH as usize;

/// Colours, chosen to stay apart for colour-blind readers (Okabe-Ito).
pub mod colour {
    use plotters::style::RGBColor;
    /// The reference `u`.
    pub const REFERENCE: RGBColor = RGBColor(40, 40, 40);
    /// The measured probe `y`.
    pub const PROBE: RGBColor = RGBColor(0, 114, 178);
    /// The model.
    pub const MODEL: RGBColor = RGBColor(230, 159, 0);
    /// The residual.
    pub const RESIDUAL: RGBColor = RGBColor(213, 94, 0);
    /// The compensated signal, the compensator.
    pub const COMPENSATED: RGBColor = RGBColor(0, 158, 115);
    /// The corrected response (model times compensator).
    pub const PRODUCT: RGBColor = RGBColor(40, 40, 40);
    /// The physical prediction.
    pub const PHYSICS: RGBColor = RGBColor(204, 121, 167);
    /// Bands, floors, guides.
    pub const GUIDE: RGBColor = RGBColor(120, 120, 120);
}

/// Min/max decimation: at most two points per column, the smallest and the largest of the
/// samples that fall in it, in their original order, so a one-sample spike survives. `points`
/// are ordered by `x` and evenly spaced (a trace, a spectrum); traces with at most
/// `2 columns` points are returned whole.
#[must_use]
pub fn decimate(points: &[(f64, f64)], columns: usize) -> Vec<(f64, f64)> {
    decimated_indices(points.len(), columns, |i| {
        points.get(i).map_or(0.0, |p| p.1)
    })
    .into_iter()
    .filter_map(|i| points.get(i).copied())
    .collect()
}

/// The indices [`decimate`] keeps of `n` evenly spaced samples whose values `y(i)` gives, so
/// that a long trace is decimated without first being copied whole.
#[must_use]
pub fn decimated_indices(n: usize, columns: usize, y: impl Fn(usize) -> f64) -> Vec<usize> {
    if columns == 0 || n <= 2 * columns {
        return (0..n).collect();
    }
    let mut out = Vec::with_capacity(2 * columns);
    for c in 0..columns {
        let (lo, hi) = (c * n / columns, (c + 1) * n / columns);
        if lo >= hi {
            continue;
        }
        let (mut min_i, mut max_i) = (lo, lo);
        let (mut min_v, mut max_v) = (y(lo), y(lo));
        for i in lo + 1..hi {
            let v = y(i);
            if v < min_v {
                (min_i, min_v) = (i, v);
            }
            if v > max_v {
                (max_i, max_v) = (i, v);
            }
        }
        let (a, b) = (min_i.min(max_i), min_i.max(max_i));
        out.push(a);
        if b != a {
            out.push(b);
        }
    }
    out
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// A solid line of this width.
    Line(u32),
    /// A dashed line.
    Dashed,
    /// Vertical stems from zero (correlations).
    Stems,
    /// Crosses (poles).
    Crosses,
    /// Open circles (zeros).
    Circles,
}

/// One series of a chart.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text (empty: no legend entry).
    pub label: String,
    /// The points, already decimated when long.
    pub points: Vec<(f64, f64)>,
    /// Colour.
    pub colour: RGBColor,
    /// How to draw it.
    pub style: Style,
}

impl Series {
    /// A line series, decimated to [`COLUMNS`].
    #[must_use]
    pub fn line(label: &str, points: &[(f64, f64)], colour: RGBColor, width: u32) -> Self {
        Self {
            label: label.to_string(),
            points: decimate(points, COLUMNS),
            colour,
            style: Style::Line(width),
        }
    }

    /// A series drawn with `style`, not decimated.
    #[must_use]
    pub fn with(label: &str, points: Vec<(f64, f64)>, colour: RGBColor, style: Style) -> Self {
        Self {
            label: label.to_string(),
            points,
            colour,
            style,
        }
    }
}

/// A labelled marker (a spectral peak and its diagnosis).
#[derive(Debug, Clone)]
pub struct Marker {
    /// Where.
    pub at: (f64, f64),
    /// Text beside it.
    pub label: String,
}

/// One panel: axes, series, horizontal guides and markers.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Caption above the panel.
    pub title: String,
    /// X axis label, with its unit.
    pub x_label: String,
    /// Y axis label, with its unit.
    pub y_label: String,
    /// X range.
    pub x: Range<f64>,
    /// Y range.
    pub y: Range<f64>,
    /// Logarithmic x axis (Bode plots).
    pub log_x: bool,
    /// The data.
    pub series: Vec<Series>,
    /// Horizontal guides `(y, label)` (confidence bands, floors), thin grey lines.
    pub guides: Vec<(f64, String)>,
    /// Labelled markers.
    pub markers: Vec<Marker>,
    /// Where the legend goes.
    pub legend: SeriesLabelPosition,
    /// Names for the integer x positions `1, 2, ...` (the error history's fits), instead of
    /// numbers.
    pub x_names: Vec<String>,
}

impl Panel {
    /// A linear panel with the y range fitted to its series and guides (5 % margin).
    #[must_use]
    pub fn new(title: &str, x_label: &str, y_label: &str, series: Vec<Series>) -> Self {
        let (mut x0, mut x1, mut y0, mut y1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for p in series.iter().flat_map(|s| s.points.iter()) {
            if p.0.is_finite() && p.1.is_finite() {
                x0 = x0.min(p.0);
                x1 = x1.max(p.0);
                y0 = y0.min(p.1);
                y1 = y1.max(p.1);
            }
        }
        if series.iter().any(|s| s.style == Style::Stems) {
            y0 = y0.min(0.0);
            y1 = y1.max(0.0);
        }
        Self {
            title: title.to_string(),
            x_label: x_label.to_string(),
            y_label: y_label.to_string(),
            x: padded(x0, x1, 0.0),
            y: padded(y0, y1, 0.05),
            log_x: false,
            series,
            guides: Vec::new(),
            markers: Vec::new(),
            legend: SeriesLabelPosition::UpperRight,
            x_names: Vec::new(),
        }
    }

    /// Adds horizontal guides and widens the y range to show them.
    #[must_use]
    pub fn guides(mut self, guides: Vec<(f64, String)>) -> Self {
        for (g, _) in &guides {
            let (lo, hi) = (self.y.start.min(*g), self.y.end.max(*g));
            if g.is_finite() && (lo < self.y.start || hi > self.y.end) {
                self.y = padded(lo, hi, 0.05);
            }
        }
        self.guides = guides;
        self
    }
}

/// A finite, non-empty range around `[lo, hi]` with a relative margin.
fn padded(lo: f64, hi: f64, margin: f64) -> Range<f64> {
    if !(lo.is_finite() && hi.is_finite()) {
        return 0.0..1.0;
    }
    let span = hi - lo;
    if span <= 1e-300 * lo.abs().max(1.0) {
        let d = (lo.abs() * 0.05).max(1e-12);
        return (lo - d)..(hi + d);
    }
    (lo - margin * span)..(hi + margin * span)
}

/// Draws panels stacked vertically (each `height` pixels) into one SVG, or side by side when
/// `columns` is 2. Returns the SVG text.
///
/// # Errors
/// [`Error::Plot`] naming `name` when plotters fails.
pub fn figure(name: &str, panels: &[Panel], height: u32, columns: usize) -> Result<String> {
    figure_sized(name, panels, (WIDTH, height), columns)
}

/// As [`figure`], `size.0` pixels wide.
///
/// # Errors
/// As [`figure`].
pub fn figure_sized(
    name: &str,
    panels: &[Panel],
    size: (u32, u32),
    columns: usize,
) -> Result<String> {
    let (width, height) = size;
    let columns = columns.clamp(1, 2);
    let rows = panels.len().div_ceil(columns).max(1);
    let total = (width, height * u32::try_from(rows).unwrap_or(1));
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, total).into_drawing_area();
        root.fill(&WHITE).map_err(|e| Error::plot(name, e))?;
        let areas = root.split_evenly((rows, columns));
        for (panel, area) in panels.iter().zip(&areas) {
            draw_panel(area, panel).map_err(|e| Error::plot(name, e))?;
        }
        root.present().map_err(|e| Error::plot(name, e))?;
    }
    // The SVG goes inline into HTML: no XML declaration, and it scales with the page.
    let start = svg.find("<svg").unwrap_or(0);
    Ok(svg.split_off(start))
}

type DrawResult = std::result::Result<(), String>;

fn draw_panel(area: &DrawingArea<SVGBackend<'_>, Shift>, p: &Panel) -> DrawResult {
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&p.title, ("sans-serif", 15))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70);
    if p.log_x {
        let x = p.x.start.max(1e-12)..p.x.end.max(p.x.start.max(1e-12) * 10.0);
        let mut chart = builder
            .build_cartesian_2d(x.log_scale(), p.y.clone())
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc(&p.x_label)
            .y_desc(&p.y_label)
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 13))
            .light_line_style(RGBColor(238, 238, 238))
            .bold_line_style(RGBColor(215, 215, 215))
            .x_label_formatter(&|v| si(*v))
            .draw()
            .map_err(|e| e.to_string())?;
        draw_content(&mut chart, p)
    } else {
        let mut chart = builder
            .build_cartesian_2d(p.x.clone(), p.y.clone())
            .map_err(|e| e.to_string())?;
        let named = |v: &f64| {
            let i = v.round();
            if (v - i).abs() < 1e-6 && i >= 1.0 {
                p.x_names.get(i as usize - 1).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        };
        let numbered = |v: &f64| si(*v);
        let x_format: &dyn Fn(&f64) -> String = if p.x_names.is_empty() {
            &numbered
        } else {
            &named
        };
        let x_labels = if p.x_names.is_empty() {
            10
        } else {
            2 * p.x_names.len() + 1
        };
        chart
            .configure_mesh()
            .x_labels(x_labels)
            .x_desc(&p.x_label)
            .y_desc(&p.y_label)
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 13))
            .light_line_style(RGBColor(238, 238, 238))
            .bold_line_style(RGBColor(215, 215, 215))
            .x_label_formatter(x_format)
            .y_label_formatter(&|v| si(*v))
            .draw()
            .map_err(|e| e.to_string())?;
        draw_content(&mut chart, p)
    }
}

/// A tick label: short, without trailing noise.
fn si(v: f64) -> String {
    let a = v.abs();
    // Ticks at zero come out of the axis arithmetic as 1e-17 and the like.
    if a < 1e-12 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.1e}")
    } else {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    }
}

fn draw_content<'a, X, Y>(
    chart: &mut ChartContext<'a, SVGBackend<'a>, Cartesian2d<X, Y>>,
    p: &Panel,
) -> DrawResult
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let (x0, x1) = (p.x.start, p.x.end);
    for (y, label) in &p.guides {
        let s = chart
            .draw_series(LineSeries::new(
                vec![(x0, *y), (x1, *y)],
                colour::GUIDE.stroke_width(1),
            ))
            .map_err(|e| e.to_string())?;
        if !label.is_empty() {
            s.label(label.clone()).legend(|(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour::GUIDE.stroke_width(1))
            });
        }
    }
    let mut legend = false;
    for s in &p.series {
        let c = s.colour;
        let drawn = match s.style {
            Style::Line(w) => {
                chart.draw_series(LineSeries::new(s.points.iter().copied(), c.stroke_width(w)))
            }
            Style::Dashed => chart.draw_series(DashedLineSeries::new(
                s.points.iter().copied(),
                8,
                5,
                c.stroke_width(2),
            )),
            Style::Stems => {
                let w = if s.points.len() > 100 { 1 } else { 3 };
                chart.draw_series(s.points.iter().map(move |&(x, y)| {
                    PathElement::new(vec![(x, 0.0), (x, y)], c.stroke_width(w))
                }))
            }
            Style::Crosses => chart.draw_series(
                s.points
                    .iter()
                    .map(|&(x, y)| Cross::new((x, y), 6, c.stroke_width(2))),
            ),
            Style::Circles => chart.draw_series(
                s.points
                    .iter()
                    .map(|&(x, y)| Circle::new((x, y), 6, c.stroke_width(2))),
            ),
        }
        .map_err(|e| e.to_string())?;
        if !s.label.is_empty() {
            legend = true;
            let style = s.style;
            let drawn = drawn.label(s.label.clone());
            match style {
                Style::Crosses => drawn.legend(move |(x, y)| {
                    EmptyElement::at((x + 10, y)) + Cross::new((0, 0), 5, c.stroke_width(2))
                }),
                Style::Circles => drawn.legend(move |(x, y)| {
                    EmptyElement::at((x + 10, y)) + Circle::new((0, 0), 5, c.stroke_width(2))
                }),
                _ => drawn.legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(3))
                }),
            };
        }
    }
    for m in &p.markers {
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(m.at)
                    + Circle::new((0, 0), 7, colour::RESIDUAL.stroke_width(2))
                    + Text::new(
                        m.label.clone(),
                        (9, -16),
                        ("sans-serif", 13).into_font().color(&colour::RESIDUAL),
                    ),
            ))
            .map_err(|e| e.to_string())?;
    }
    if legend || p.guides.iter().any(|g| !g.1.is_empty()) {
        chart
            .configure_series_labels()
            .position(p.legend.clone())
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(200, 200, 200))
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimated_indices_are_the_points_decimate_keeps() {
        let pts: Vec<(f64, f64)> = (0..10_007)
            .map(|k| (k as f64, ((k * 7919) % 1013) as f64 - 500.0))
            .collect();
        for columns in [1, 3, 800, 5000, 6000] {
            let kept: Vec<(f64, f64)> = decimated_indices(pts.len(), columns, |i| pts[i].1)
                .into_iter()
                .map(|i| pts[i])
                .collect();
            let mut want = Vec::new();
            // The buckets by hand: smallest and largest of each, in their order.
            if pts.len() <= 2 * columns {
                want.clone_from(&pts);
            } else {
                for c in 0..columns {
                    let (lo, hi) = (c * pts.len() / columns, (c + 1) * pts.len() / columns);
                    let b = &pts[lo..hi];
                    let min = (0..b.len()).fold(0, |m, i| if b[i].1 < b[m].1 { i } else { m });
                    let max = (0..b.len()).fold(0, |m, i| if b[i].1 > b[m].1 { i } else { m });
                    want.push(b[min.min(max)]);
                    if min != max {
                        want.push(b[min.max(max)]);
                    }
                }
            }
            assert_eq!(kept, want, "{columns} columns");
            assert_eq!(decimate(&pts, columns), want);
        }
    }

    #[test]
    fn a_one_sample_spike_survives_decimation() {
        for at in [0usize, 1, 4_999, 77_777, 99_999] {
            let mut pts: Vec<(f64, f64)> = (0..100_000)
                .map(|k| (k as f64, (k as f64 * 0.01).sin() * 0.1))
                .collect();
            pts[at].1 = 5.0;
            pts[(at + 50_000) % 100_000].1 = -4.0;
            let d = decimate(&pts, 800);
            assert!(d.len() <= 1600, "{}", d.len());
            assert!(d.contains(&(at as f64, 5.0)), "spike at {at} lost");
            let dip = ((at + 50_000) % 100_000) as f64;
            assert!(d.contains(&(dip, -4.0)), "dip at {dip} lost");
            // Still in time order.
            assert!(d.windows(2).all(|w| w[0].0 < w[1].0));
        }
    }

    #[test]
    fn short_traces_are_kept_whole() {
        let pts: Vec<(f64, f64)> = (0..100).map(|k| (k as f64, k as f64)).collect();
        assert_eq!(decimate(&pts, 800), pts);
    }

    #[test]
    fn a_figure_is_svg_with_text_and_lines() {
        let s = Series::line(
            "probe",
            &[(0.0, 0.0), (1.0, 1.0), (2.0, 0.5)],
            colour::PROBE,
            2,
        );
        let p = Panel::new("title here", "time (s)", "pressure", vec![s])
            .guides(vec![(0.8, "band".into())]);
        let svg = figure("test", &[p], 300, 1).unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..50.min(svg.len())]);
        assert!(svg.contains("<polyline"), "{svg}");
        assert!(svg.contains("title here") && svg.contains("time (s)"));
        assert!(svg.contains("sans-serif"));
        assert!(svg.contains("band"), "the guide's legend entry is missing");
    }

    #[test]
    fn guides_widen_the_range_to_show_themselves() {
        let s = Series::line("r", &[(0.0, -0.1), (1.0, 0.1)], colour::PROBE, 1);
        let p = Panel::new("t", "x", "y", vec![s]).guides(vec![(0.5, String::new())]);
        assert!(p.y.end > 0.5 && p.y.start <= -0.1, "{:?}", p.y);
    }
}
