//! Line and point plots of the experiments, as SVG and PNG, with `plotters`.
//!
//! No system font library is used: the text of both formats is laid out with the DejaVu Sans
//! embedded in the binary (`host/assets/DejaVuSans.ttf`, registered with `ab_glyph`), so the
//! plots look the same on every machine and the build needs no fontconfig/freetype headers.
//! A figure is a grid of panels; each panel has labelled axes (with units), an optional
//! logarithmic y axis, and a legend. Non-finite values (and negative ones on a log axis) are
//! left out of the drawing; the CSV next to each plot keeps them. On a log axis, values under
//! its bottom (exact estimates, 0 %, among them) are drawn on the bottom edge, and the panel
//! says so.

use anyhow::{anyhow, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::series::DashedLineSeries;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};
use std::sync::Once;

/// The embedded font (DejaVu Sans, see `host/assets/DejaVuSans-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
/// The family name the plots use.
const FAMILY: &str = "sans-serif";

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// Solid line with a marker at each point.
    LinePoints,
    /// Dashed line, no markers (reference curves: the optimal-triangulation floor, true values).
    Dashed,
    /// Markers only.
    Points,
}

/// One curve of a panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// `(x, y)` points.
    pub points: Vec<(f64, f64)>,
    /// Drawing style.
    pub style: Style,
    /// Index into the palette.
    pub color: usize,
}

impl Series {
    /// A series from x and y values.
    pub fn new(name: impl Into<String>, x: &[f64], y: &[f64], style: Style, color: usize) -> Self {
        Series {
            name: name.into(),
            points: x.iter().copied().zip(y.iter().copied()).collect(),
            style,
            color,
        }
    }

    /// A dashed horizontal line at `y` from `x0` to `x1` (a reference level).
    pub fn level(name: impl Into<String>, [x0, x1]: [f64; 2], y: f64, color: usize) -> Self {
        Series::new(name, &[x0, x1], &[y, y], Style::Dashed, color)
    }
}

/// Where the legend goes (`UpperLeft`, `UpperRight`, `LowerRight`, `LowerLeft`, ...).
pub use plotters::chart::SeriesLabelPosition as Legend;

/// One chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// Caption above the chart.
    pub title: String,
    /// X axis label, with unit.
    pub x_label: String,
    /// Y axis label, with unit.
    pub y_label: String,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// Curves.
    pub series: Vec<Series>,
    /// Legend position.
    pub legend: Legend,
    /// Label only whole numbers on the x axis (e.g. case numbers, neuron counts).
    pub integer_x: bool,
}

impl Panel {
    /// A panel with a linear y axis, the legend upper left and any x ticks (set the fields
    /// for others).
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
        series: Vec<Series>,
    ) -> Self {
        let (title, x_label, y_label) = (title.into(), x_label.into(), y_label.into());
        let (log_y, legend, integer_x) = (false, Legend::UpperLeft, false);
        Panel { title, x_label, y_label, log_y, series, legend, integer_x }
    }
}

/// A grid of panels with a common title.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title over the whole figure.
    pub title: String,
    /// Panels, row by row.
    pub panels: Vec<Panel>,
    /// Panels per row.
    pub cols: usize,
}

impl Figure {
    /// A figure of one panel.
    pub fn single(title: impl Into<String>, panel: Panel) -> Self {
        Figure { title: title.into(), panels: vec![panel], cols: 1 }
    }

    fn size(&self) -> (u32, u32) {
        let cols = self.cols.max(1);
        let rows = self.panels.len().div_ceil(cols).max(1);
        ((if cols == 1 { 900 } else { 640 * cols }) as u32, (40 + 460 * rows) as u32)
    }
}

const PALETTE: [RGBColor; 7] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(40, 40, 40),
    RGBColor(140, 86, 75),
];

/// The colour of palette entry `i`.
fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Writes `fig` as `dir/stem.svg` and `dir/stem.png` (atomically, as every output) and
/// returns the two file names.
pub fn write_figure(dir: &std::path::Path, stem: &str, fig: &Figure) -> Result<[String; 2]> {
    use anyhow::Context;
    let names = [format!("{stem}.svg"), format!("{stem}.png")];
    let svg = svg(fig).with_context(|| names[0].clone())?;
    crate::data::output::write_bytes(&dir.join(&names[0]), svg.as_bytes())?;
    let png = png(fig).with_context(|| names[1].clone())?;
    crate::data::output::write_bytes(&dir.join(&names[1]), &png)?;
    Ok(names)
}

/// Lowest value of a logarithmic axis; smaller positive values are drawn on it.
const LOG_MIN: f64 = 1e-2;

/// Palette index of the optimal-triangulation floor (dark grey, dashed).
pub const FLOOR_COLOR: usize = 5;

fn register() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is compiled in and known to parse (tested); a failure here would only
        // leave the text out of the plots.
        let _ = register_font(FAMILY, FontStyle::Normal, FONT);
    });
}

/// The figure as an SVG document.
pub fn svg(fig: &Figure) -> Result<String> {
    register();
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, fig.size()).into_drawing_area();
        draw(&root, fig).map_err(|e| anyhow!("cannot draw \"{}\": {e}", fig.title))?;
        root.present().map_err(|e| anyhow!("cannot draw \"{}\": {e}", fig.title))?;
    }
    Ok(out)
}

/// The figure as a PNG file's bytes.
pub fn png(fig: &Figure) -> Result<Vec<u8>> {
    register();
    let (w, h) = fig.size();
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        draw(&root, fig).map_err(|e| anyhow!("cannot draw \"{}\": {e}", fig.title))?;
        root.present().map_err(|e| anyhow!("cannot draw \"{}\": {e}", fig.title))?;
    }
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Best);
        enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        let mut wr = enc.write_header()?;
        wr.write_image_data(&rgb)?;
        wr.finish()?;
    }
    Ok(bytes)
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, fig: &Figure) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let root = root.titled(&fig.title, (FAMILY, 24))?;
    let cols = fig.cols.max(1);
    let rows = fig.panels.len().div_ceil(cols).max(1);
    let areas = root.split_evenly((rows, cols));
    for (panel, area) in fig.panels.iter().zip(areas.iter()) {
        draw_panel(area, panel)?;
    }
    Ok(())
}

/// Data range of the drawable points: x over all, y over the finite (and, on a log axis,
/// positive) values.
fn ranges(p: &Panel) -> ((f64, f64), (f64, f64)) {
    let mut x = (f64::INFINITY, f64::NEG_INFINITY);
    let mut y = (f64::INFINITY, f64::NEG_INFINITY);
    for s in &p.series {
        for &(a, b) in &s.points {
            if !(a.is_finite() && b.is_finite()) || (p.log_y && b <= 0.0) {
                continue;
            }
            x = (x.0.min(a), x.1.max(a));
            y = (y.0.min(b), y.1.max(b));
        }
    }
    if !x.0.is_finite() {
        x = (0.0, 1.0);
        y = (1.0, 10.0);
    }
    if x.1 - x.0 <= 0.0 {
        x = (x.0 - 1.0, x.1 + 1.0);
    }
    let pad = (x.1 - x.0) * 0.04;
    let x = (x.0 - pad, x.1 + pad);
    let y = if p.log_y {
        // One decade of headroom above the data for the legend; nothing below 1e-2 (an
        // exact estimate, 0 %, is drawn on the bottom edge instead of stretching the axis).
        let lo = libm::pow(10.0, libm::floor(libm::log10(y.0))).max(LOG_MIN);
        let hi = libm::pow(10.0, libm::ceil(libm::log10(y.1 * 10.0)));
        (lo, if hi > lo { hi } else { lo * 10.0 })
    } else {
        let span = if y.1 > y.0 { y.1 - y.0 } else { y.1.abs().max(1.0) };
        // Start at zero when the data are not far from it: errors read best from zero.
        let lo = if y.0 >= 0.0 && y.0 < span { 0.0 } else { y.0 - 0.1 * span };
        // Headroom above the data for the legend.
        (lo, y.1 + 0.5 * (y.1 - lo).max(span))
    };
    (x, y)
}

fn tick_label(v: f64) -> String {
    let a = v.abs();
    // Ticks computed as sums of steps come out as 1e-17 or so where they mean zero.
    if a < 1e-9 {
        "0".to_string()
    } else if !(0.01..1000.0).contains(&a) {
        format!("{v:.0e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else {
        // Enough decimals for ticks 0.05 apart, without trailing zeros.
        let t = format!("{v:.3}");
        t.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

fn x_tick(v: f64, integer: bool) -> String {
    match integer {
        false => tick_label(v),
        true if (v - v.round()).abs() < 1e-6 => format!("{}", v.round()),
        true => String::new(),
    }
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> DrawResult<DB> {
    let ((x0, x1), (y0, y1)) = ranges(p);
    let mut b = ChartBuilder::on(area);
    b.caption(&p.title, (FAMILY, 18)).margin(12).x_label_area_size(48).y_label_area_size(70);
    // The same mesh, series and legend on either y axis (the two chart types differ).
    macro_rules! draw {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc(&p.x_label)
                .y_desc(&p.y_label)
                .axis_desc_style((FAMILY, 16))
                .label_style((FAMILY, 14))
                .x_label_formatter(&|v| x_tick(*v, p.integer_x))
                .y_label_formatter(&|v| tick_label(*v))
                .light_line_style(RGBColor(235, 235, 235))
                .max_light_lines(2)
                .draw()?;
            for s in &p.series {
                series(&mut chart, s, drawable(s, p.log_y, y0))?;
            }
            if let Some(note) = edge_note(p, y0) {
                let style = TextStyle::from((FAMILY, 13))
                    .color(&RGBColor(90, 90, 90))
                    .pos(Pos::new(HPos::Right, VPos::Bottom));
                // Just above the bottom edge, at the right end.
                let at = (x1 - 0.01 * (x1 - x0), y0 * libm::pow(y1 / y0, 0.02));
                chart.draw_series(std::iter::once(Text::new(note, at, style)))?;
            }
            legend(&mut chart, &p.legend)
        }};
    }
    if p.log_y {
        draw!(b.build_cartesian_2d(x0..x1, (y0..y1).log_scale())?)
    } else {
        draw!(b.build_cartesian_2d(x0..x1, y0..y1)?)
    }
}

/// The points of `s` a chart can draw: finite ones; on a log axis no negative values, and
/// none below the axis' bottom `y0` (they, zeros too, are drawn on it).
fn drawable(s: &Series, log_y: bool, y0: f64) -> Vec<(f64, f64)> {
    s.points
        .iter()
        .copied()
        .filter(|(a, b)| a.is_finite() && b.is_finite() && (!log_y || *b >= 0.0))
        .map(|(a, b)| if log_y { (a, b.max(y0)) } else { (a, b) })
        .collect()
}

/// On a log axis whose bottom is `y0`, the note that some values lie under it (drawn on the
/// edge), or `None` when none do.
fn edge_note(p: &Panel, y0: f64) -> Option<String> {
    let under = |s: &Series| s.points.iter().any(|(a, b)| a.is_finite() && (0.0..y0).contains(b));
    (p.log_y && p.series.iter().any(under))
        .then(|| format!("values under {} drawn on the bottom edge", tick_label(y0)))
}

fn series<'a, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    s: &Series,
    pts: Vec<(f64, f64)>,
) -> DrawResult<DB>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let c = color(s.color);
    let line = ShapeStyle::from(c).stroke_width(2);
    let anno = match s.style {
        Style::LinePoints => {
            chart.draw_series(LineSeries::new(pts.clone(), line))?;
            chart.draw_series(pts.iter().map(|p| Circle::new(*p, 4, c.filled())))?
        }
        Style::Points => chart.draw_series(pts.iter().map(|p| Circle::new(*p, 5, c.filled())))?,
        Style::Dashed => chart.draw_series(DashedLineSeries::new(pts, 8, 5, line))?,
    };
    anno.label(s.name.clone()).legend(move |(x, y)| {
        PathElement::new(vec![(x, y), (x + 24, y)], ShapeStyle::from(c).stroke_width(2))
    });
    Ok(())
}

fn legend<'a, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    at: &Legend,
) -> DrawResult<DB>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    chart
        .configure_series_labels()
        .position(at.clone())
        .label_font((FAMILY, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .draw()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fig(log_y: bool) -> Figure {
        Figure::single(
            "test figure",
            Panel {
                title: "panel".into(),
                x_label: "depth Z (cm)".into(),
                y_label: "e_ma (%)".into(),
                log_y,
                series: vec![
                    Series::new(
                        "a",
                        &[65.0, 75.0, 85.0],
                        &[1.0, f64::INFINITY, 3.0],
                        Style::LinePoints,
                        0,
                    ),
                    Series::new("floor", &[65.0, 85.0], &[0.5, 0.0], Style::Dashed, FLOOR_COLOR),
                ],
                legend: Legend::UpperRight,
                integer_x: false,
            },
        )
    }

    #[test]
    fn embedded_font_parses() {
        assert!(register_font("embedded-test", FontStyle::Normal, FONT).is_ok());
    }

    #[test]
    fn svg_and_png_are_drawn_with_text_and_are_deterministic() {
        for log_y in [false, true] {
            let f = fig(log_y);
            let s = svg(&f).unwrap();
            assert!(s.starts_with("<svg"), "{}", &s[..40]);
            for text in ["test figure", "depth Z (cm)", "e_ma (%)", "floor"] {
                assert!(s.contains(text), "{text} missing");
            }
            let p = png(&f).unwrap();
            assert_eq!(&p[1..4], b"PNG");
            assert_eq!(p, png(&f).unwrap());
            // Text is rendered: the PNG has dark pixels of glyphs besides the lines.
            assert!(p.len() > 5000);
        }
    }

    #[test]
    fn ranges_skip_what_cannot_be_drawn() {
        let f = fig(true);
        let ((x0, x1), (y0, y1)) = ranges(&f.panels[0]);
        assert!(x0 < 65.0 && x1 > 85.0);
        assert_eq!((y0, y1), (0.1, 100.0));
        let ((_, _), (y0, y1)) = ranges(&fig(false).panels[0]);
        assert_eq!(y0, 0.0);
        assert!(y1 > 3.0);
        assert_eq!(tick_label(1000.0), "1e3");
        assert_eq!(tick_label(2.5), "2.5");
        assert_eq!(tick_label(1.55), "1.55");
        assert_eq!(tick_label(4.0), "4");
        assert_eq!(tick_label(0.25), "0.25");
        assert_eq!(tick_label(-5.551115123125783e-17), "0");
    }

    #[test]
    fn values_under_a_log_axis_are_drawn_on_its_edge_and_said_to_be() {
        // The floor's 0.0 lies under the log axis' bottom (0.1): drawn there, and noted.
        let f = fig(true);
        let floor = &f.panels[0].series[1];
        assert_eq!(drawable(floor, true, 0.1), vec![(65.0, 0.5), (85.0, 0.1)]);
        assert!(svg(&f).unwrap().contains("values under 0.1 drawn on the bottom edge"));
        // A linear axis draws 0 where it is; no note.
        assert_eq!(drawable(floor, false, 0.0), vec![(65.0, 0.5), (85.0, 0.0)]);
        assert!(!svg(&fig(false)).unwrap().contains("bottom edge"));
        // Negative values have no place on a log axis.
        let neg = Series::new("n", &[1.0, 2.0], &[-1.0, 2.0], Style::Points, 0);
        assert_eq!(drawable(&neg, true, 0.1), vec![(2.0, 2.0)]);
    }
}
