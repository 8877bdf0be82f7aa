//! Plots as SVG and PNG: line and scatter series with labels on linear or logarithmic axes
//! (`Figure`), and heat maps of a value over a two-parameter grid (`HeatMap`). Drawn with
//! `plotters`, twice from the same drawing calls: into SVG, and into a bitmap encoded as PNG
//! (text rasterized by `ab_glyph` from the DejaVu Sans font compiled in, assets/fonts), so
//! both look alike and need no system fonts. The font also gives the SVG's text its widths.
//!
//! Small on purpose: a study's output-against-parameter plots, the accuracy study's Pareto
//! plot, a run's time histories and a sweep's frequency-response curves all use it. A curve
//! drawn in pieces (solid where stable, dashed where not) is several series in one colour
//! (`colour`), only one of them labelled (an empty label has no legend entry); `mark` puts a
//! labelled marker on a point (a fold). `equal_aspect` gives both (linear) axes the same
//! data units per pixel, widening the shorter one's range about its centre (a body's
//! picture: a thin beam stays thin); `grey` draws a series in light grey (a reference
//! shape behind the data).
//!
//! ```no_run
//! use hbcontact::output::plot::{Axis, Figure};
//! let fig = Figure::new("probe amplitude", Axis::linear("gap [m]"), Axis::log("amplitude [m]"))
//!     .line("H = 10", vec![(1e-7, 2e-6), (2e-7, 1.5e-6)])
//!     .dashed("reference", vec![(1e-7, 2.1e-6), (2e-7, 1.6e-6)]);
//! fig.save(std::path::Path::new("out/amplitude")).unwrap(); // amplitude.svg, amplitude.png
//! ```

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::{Error, Result};

const WIDTH: u32 = 720;
const HEIGHT: u32 = 480;
const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
];

/// One axis: its label (with the unit, e.g. `gap [m]`), whether it is logarithmic, and its
/// categories when it is categorical (then value i is drawn at i, ticked with category i).
#[derive(Clone, Debug)]
pub struct Axis {
    pub label: String,
    pub log: bool,
    pub categories: Vec<String>,
}

impl Axis {
    pub fn linear(label: impl Into<String>) -> Self {
        Axis {
            label: label.into(),
            log: false,
            categories: Vec::new(),
        }
    }
    pub fn log(label: impl Into<String>) -> Self {
        Axis {
            label: label.into(),
            log: true,
            categories: Vec::new(),
        }
    }
    /// A categorical axis: x = i for `categories[i]` (e.g. a study's string parameter).
    pub fn categorical(label: impl Into<String>, categories: Vec<String>) -> Self {
        Axis {
            label: label.into(),
            log: false,
            categories,
        }
    }

    /// The tick label at `v`: the category at a whole index, nothing between; the number
    /// otherwise.
    fn tick(&self, v: f64) -> String {
        if self.categories.is_empty() {
            return tick(v);
        }
        let i = v.round();
        match self.categories.get(i as usize) {
            Some(c) if (v - i).abs() < 1e-6 && i >= 0.0 => c.clone(),
            _ => String::new(),
        }
    }
}

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// Solid line through the points, with markers.
    Line,
    /// Markers only.
    Scatter,
    /// Dashed line without markers (references, asymptotes).
    Dashed,
    /// Solid line without markers (densely sampled time histories).
    Curve,
}

#[derive(Clone, Debug)]
pub struct Series {
    /// The legend text; empty: no legend entry.
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub style: Style,
    /// The palette index; `None`: the series' own position.
    pub colour: Option<usize>,
}

/// A marked point: a black glyph with its label beside it.
#[derive(Clone, Debug)]
pub struct Mark {
    pub label: String,
    pub point: (f64, f64),
    pub shape: Shape,
}

/// The glyph of a mark (folds and the kinds of bifurcation each have one).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    Triangle,
    Disc,
    Square,
    Cross,
    Ring,
    Diamond,
}

/// A 2-D plot of labelled series; the legend sits inside the frame.
#[derive(Clone, Debug)]
pub struct Figure {
    pub title: String,
    pub x: Axis,
    pub y: Axis,
    pub series: Vec<Series>,
    /// Stretch a linear y axis to include 0 (profiles whose variation is small next to
    /// their level).
    pub y_from_zero: bool,
    pub marks: Vec<Mark>,
    /// Both axes at the same data units per pixel (linear, non-categorical axes only).
    pub equal_aspect: bool,
}

/// The `colour` index of light grey (`Figure::grey`), outside the palette.
pub const GREY: usize = usize::MAX;

/// The drawing colour of palette index `index` (`GREY`: light grey).
fn series_colour(index: usize) -> RGBColor {
    if index == GREY {
        RGBColor(175, 175, 175)
    } else {
        PALETTE[index % PALETTE.len()]
    }
}

fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::Model(format!("internal: plot: {e}"))
}

/// The compiled-in font registered, once, as the `sans-serif` the plots ask for.
fn font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = REGISTERED.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok()
    });
    if *ok {
        Ok(())
    } else {
        Err(plot_error(
            "the compiled-in font assets/fonts/DejaVuSans.ttf does not load",
        ))
    }
}

/// A drawing area of the plot size on `backend`, white, with the font registered.
fn canvas<DB: DrawingBackend>(backend: DB) -> Result<DrawingArea<DB, Shift>> {
    font()?;
    let root = backend.into_drawing_area();
    root.fill(&WHITE).map_err(plot_error)?;
    Ok(root)
}

/// The SVG document `paint` draws.
fn svg_of(paint: impl FnOnce(DrawingArea<SVGBackend, Shift>) -> Result<()>) -> Result<String> {
    let mut text = String::new();
    paint(canvas(SVGBackend::with_string(&mut text, (WIDTH, HEIGHT)))?)?;
    Ok(text)
}

/// The PNG image (RGB, 8 bits) `paint` draws.
fn png_of(paint: impl FnOnce(DrawingArea<BitMapBackend, Shift>) -> Result<()>) -> Result<Vec<u8>> {
    let mut rgb = vec![0; 3 * (WIDTH * HEIGHT) as usize];
    paint(canvas(BitMapBackend::with_buffer(
        &mut rgb,
        (WIDTH, HEIGHT),
    ))?)?;
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, WIDTH, HEIGHT);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(plot_error)?;
    writer.write_image_data(&rgb).map_err(plot_error)?;
    writer.finish().map_err(plot_error)?;
    Ok(bytes)
}

impl Figure {
    pub fn new(title: impl Into<String>, x: Axis, y: Axis) -> Self {
        Figure {
            title: title.into(),
            x,
            y,
            series: Vec::new(),
            y_from_zero: false,
            marks: Vec::new(),
            equal_aspect: false,
        }
    }

    /// See `equal_aspect`: 1 unit on x as long as 1 unit on y (axes with the same unit).
    pub fn equal_aspect(mut self) -> Self {
        self.equal_aspect = true;
        self
    }

    /// Draw the last added series in light grey.
    pub fn grey(self) -> Self {
        self.colour(GREY)
    }

    /// Draw the last added series in palette colour `index` (pieces of one curve).
    pub fn colour(mut self, index: usize) -> Self {
        if let Some(s) = self.series.last_mut() {
            s.colour = Some(index);
        }
        self
    }

    /// A labelled triangle at `point`.
    pub fn mark(self, label: impl Into<String>, point: (f64, f64)) -> Self {
        self.mark_as(label, point, Shape::Triangle)
    }

    /// A labelled marker of `shape` at `point`.
    pub fn mark_as(mut self, label: impl Into<String>, point: (f64, f64), shape: Shape) -> Self {
        self.marks.push(Mark {
            label: label.into(),
            point,
            shape,
        });
        self
    }

    /// See `y_from_zero`.
    pub fn from_zero(mut self) -> Self {
        self.y_from_zero = true;
        self
    }

    pub fn add(mut self, label: impl Into<String>, points: Vec<(f64, f64)>, style: Style) -> Self {
        self.series.push(Series {
            label: label.into(),
            points,
            style,
            colour: None,
        });
        self
    }
    pub fn line(self, label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        self.add(label, points, Style::Line)
    }
    pub fn scatter(self, label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        self.add(label, points, Style::Scatter)
    }
    pub fn dashed(self, label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        self.add(label, points, Style::Dashed)
    }
    pub fn curve(self, label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        self.add(label, points, Style::Curve)
    }

    /// The points that can be drawn: finite, and positive on a log axis.
    fn drawable(&self, s: &Series) -> Vec<(f64, f64)> {
        let ok = |v: f64, log: bool| v.is_finite() && (!log || v > 0.0);
        s.points
            .iter()
            .copied()
            .filter(|&(x, y)| ok(x, self.x.log) && ok(y, self.y.log))
            .collect()
    }

    /// Every drawable point of the series and the marks.
    fn all_drawable(&self) -> Vec<(f64, f64)> {
        let marks = Series {
            label: String::new(),
            points: self.marks.iter().map(|m| m.point).collect(),
            style: Style::Scatter,
            colour: None,
        };
        self.series
            .iter()
            .chain(std::iter::once(&marks))
            .flat_map(|s| self.drawable(s))
            .collect()
    }

    /// The figure as an SVG document.
    pub fn svg(&self) -> Result<String> {
        svg_of(|root| self.paint(root))
    }

    /// The figure as a PNG image.
    pub fn png(&self) -> Result<Vec<u8>> {
        png_of(|root| self.paint(root))
    }

    fn paint<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<()> {
        let (xr, yr) = self.ranges();
        match (self.x.log, self.y.log) {
            (false, false) => self.draw(&root, xr.0..xr.1, yr.0..yr.1)?,
            (true, false) => self.draw(&root, (xr.0..xr.1).log_scale(), yr.0..yr.1)?,
            (false, true) => self.draw(&root, xr.0..xr.1, (yr.0..yr.1).log_scale())?,
            (true, true) => self.draw(&root, (xr.0..xr.1).log_scale(), (yr.0..yr.1).log_scale())?,
        }
        root.present().map_err(plot_error)
    }

    /// The x and y axis ranges of the drawable points (see `range`).
    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let all = self.all_drawable();
        let zero = (self.y_from_zero && !self.y.log).then_some(0.0);
        let n = self.x.categories.len() as f64;
        let (xr, yr) = (
            if n > 0.0 {
                (-0.5, n - 0.5)
            } else {
                range(all.iter().map(|p| p.0), self.x.log)
            },
            range(all.iter().map(|p| p.1).chain(zero), self.y.log),
        );
        let linear = !self.x.log && !self.y.log && n == 0.0;
        if !(self.equal_aspect && linear) {
            return (xr, yr);
        }
        // A canvas that fails here fails the drawing too, with its error.
        match self.plot_area() {
            Ok(pixels) => equal_aspect_ranges(xr, yr, pixels),
            Err(_) => (xr, yr),
        }
    }

    /// The plotting area's size in pixels (x, y) between the first and last pixel the axis
    /// ranges map to: the chart built on a scratch canvas, as `draw` builds it.
    fn plot_area(&self) -> Result<(f64, f64)> {
        let mut scratch = String::new();
        let root = canvas(SVGBackend::with_string(&mut scratch, (WIDTH, HEIGHT)))?;
        let chart = chart_builder(&root, &self.title)
            .build_cartesian_2d(0.0..1.0, 0.0..1.0)
            .map_err(plot_error)?;
        let (x, y) = chart.plotting_area().get_pixel_range();
        // Cartesian2d maps a range onto pixels start..=end - 1.
        Ok(((x.end - x.start - 1) as f64, (y.end - y.start - 1) as f64))
    }

    /// The magnitudes below which a tick on x and on y is 0 up to a rounding error (1e-9 of
    /// the axis range; none on a log axis): plotters may place the tick at 0 at -2.2e-16.
    fn zero_ticks(&self) -> (f64, f64) {
        let (xr, yr) = self.ranges();
        let zero = |(lo, hi): (f64, f64), log: bool| if log { 0.0 } else { 1e-9 * (hi - lo) };
        (zero(xr, self.x.log), zero(yr, self.y.log))
    }

    fn draw<DB, X, Y>(&self, root: &DrawingArea<DB, Shift>, x: X, y: Y) -> Result<()>
    where
        DB: DrawingBackend,
        X: AsRangedCoord<Value = f64>,
        Y: AsRangedCoord<Value = f64>,
        X::CoordDescType: Ranged<ValueType = f64> + ValueFormatter<f64>,
        Y::CoordDescType: Ranged<ValueType = f64> + ValueFormatter<f64>,
    {
        let mut chart = chart_builder(root, &self.title)
            .build_cartesian_2d(x, y)
            .map_err(plot_error)?;
        let mut mesh = chart.configure_mesh();
        if !self.x.categories.is_empty() {
            // Unit steps over [-0.5, n - 0.5]: a tick at every category.
            mesh.x_labels(self.x.categories.len() + 1);
        }
        let (zero_x, zero_y) = self.zero_ticks();
        mesh.x_desc(self.x.label.as_str())
            .y_desc(self.y.label.as_str())
            .x_label_formatter(&|v| self.x.tick(snap(*v, zero_x)))
            .y_label_formatter(&|v| tick(snap(*v, zero_y)))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(plot_error)?;
        for (i, s) in self.series.iter().enumerate() {
            let colour = series_colour(s.colour.unwrap_or(i));
            let pts = self.drawable(s);
            let entry = match s.style {
                Style::Line => {
                    chart
                        .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))
                        .map_err(plot_error)?;
                    chart
                        .draw_series(pts.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                        .map_err(plot_error)?
                }
                Style::Scatter => chart
                    .draw_series(pts.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                    .map_err(plot_error)?,
                Style::Dashed => chart
                    .draw_series(DashedLineSeries::new(pts, 8, 5, colour.stroke_width(2)))
                    .map_err(plot_error)?,
                Style::Curve => chart
                    .draw_series(LineSeries::new(pts, colour.stroke_width(2)))
                    .map_err(plot_error)?,
            };
            let style = s.style;
            if s.label.is_empty() {
                continue;
            }
            entry
                .label(s.label.as_str())
                .legend(move |(x, y)| match style {
                    Style::Scatter => Circle::new((x + 8, y), 4, colour.filled()).into_dyn(),
                    Style::Dashed => {
                        PathElement::new(vec![(x, y), (x + 8, y)], colour.stroke_width(2))
                            .into_dyn()
                    }
                    Style::Line | Style::Curve => {
                        PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(2))
                            .into_dyn()
                    }
                });
        }
        self.draw_marks(&mut chart)?;
        if self.series.iter().any(|s| !s.label.is_empty()) {
            chart
                .configure_series_labels()
                .position(self.legend_corner())
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 13))
                .draw()
                .map_err(plot_error)?;
        }
        Ok(())
    }

    /// The marks: a black glyph on the point, its label placed where it overlaps no label
    /// placed before it and stays inside the frame (`label_box`).
    fn draw_marks<DB, X, Y>(&self, chart: &mut ChartContext<DB, Cartesian2d<X, Y>>) -> Result<()>
    where
        DB: DrawingBackend,
        X: Ranged<ValueType = f64>,
        Y: Ranged<ValueType = f64>,
    {
        let log_ok = |v: f64, log: bool| v.is_finite() && (!log || v > 0.0);
        let area = chart.plotting_area().get_pixel_range();
        let frame = ((area.0.start, area.1.start), (area.0.end, area.1.end));
        let shown: Vec<&Mark> = self
            .marks
            .iter()
            .filter(|m| log_ok(m.point.0, self.x.log) && log_ok(m.point.1, self.y.log))
            .collect();
        // The glyphs first, so no label covers one.
        let mut placed: Vec<LabelBox> = shown
            .iter()
            .map(|m| {
                let (x, y) = chart.backend_coord(&m.point);
                (x - GLYPH, y - GLYPH, x + GLYPH, y + GLYPH)
            })
            .collect();
        for m in shown {
            let at = chart.backend_coord(&m.point);
            let (dx, dy) = if m.label.is_empty() {
                (0, 0)
            } else {
                label_box(at, m.label.chars().count(), frame, &mut placed)
            };
            let glyph = EmptyElement::at(m.point)
                + glyph(m.shape)
                + Text::new(m.label.clone(), (dx, dy), ("sans-serif", 12));
            chart
                .draw_series(std::iter::once(glyph))
                .map_err(plot_error)?;
        }
        Ok(())
    }

    /// Write `<stem>.svg` and `<stem>.png`.
    pub fn save(&self, stem: &Path) -> Result<()> {
        save_both(stem, &self.svg()?, &self.png()?)
    }

    /// The frame corner whose quarter-width, quarter-height box holds the fewest points (on
    /// the axes' own scales), so the legend covers as little data as it can; upper right on
    /// a tie.
    fn legend_corner(&self) -> SeriesLabelPosition {
        let all = self.all_drawable();
        let scale = |v: f64, log: bool| if log { v.log10() } else { v };
        let unit = |(lo, hi): (f64, f64), log: bool| {
            let (lo, hi) = (scale(lo, log), scale(hi, log));
            move |v: f64| (scale(v, log) - lo) / (hi - lo)
        };
        let (xr, yr) = self.ranges();
        let (ux, uy) = (unit(xr, self.x.log), unit(yr, self.y.log));
        let corners = [
            (SeriesLabelPosition::UpperRight, true, true),
            (SeriesLabelPosition::UpperLeft, false, true),
            (SeriesLabelPosition::LowerRight, true, false),
            (SeriesLabelPosition::LowerLeft, false, false),
        ];
        let inside = |&(x, y): &(f64, f64), right: bool, top: bool| {
            let (u, v) = (ux(x), uy(y));
            (if right { u > 0.65 } else { u < 0.35 }) && (if top { v > 0.7 } else { v < 0.3 })
        };
        corners
            .into_iter()
            .min_by_key(|&(_, right, top)| all.iter().filter(|p| inside(p, right, top)).count())
            .map_or(SeriesLabelPosition::UpperRight, |c| c.0)
    }
}

/// `v`, or 0 when it is smaller than `zero` in magnitude (a tick at 0 up to rounding).
fn snap(v: f64, zero: f64) -> f64 {
    if v.abs() < zero {
        0.0
    } else {
        v
    }
}

/// A `Figure`'s chart layout on `root`: its title, margin and label areas.
fn chart_builder<'a, 'b, DB: DrawingBackend>(
    root: &'a DrawingArea<DB, Shift>,
    title: &'b str,
) -> ChartBuilder<'a, 'b, DB> {
    let mut builder = ChartBuilder::on(root);
    builder
        .caption(title, ("sans-serif", title_size(root, title)))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(78);
    builder
}

/// The largest title font size from `TITLE_SIZES` at which `title` fits the canvas' width
/// within its margins (the glyphs measured; where they cannot be, half the size per
/// character), the smallest otherwise.
fn title_size<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, title: &str) -> f64 {
    let room = f64::from(root.dim_in_pixel().0) - 2.0 * TITLE_MARGIN;
    let width = |size: f64| {
        let style = TextStyle::from(("sans-serif", size).into_font());
        root.estimate_text_size(title, &style)
            .map_or(0.5 * size * title.chars().count() as f64, |(w, _)| {
                f64::from(w)
            })
    };
    let [largest, smallest] = TITLE_SIZES;
    let mut size = largest;
    while size > smallest && width(size) > room {
        size -= 1.0;
    }
    size
}

/// The title's font size [px]: the usual, and the least a long title shrinks to.
const TITLE_SIZES: [f64; 2] = [18.0, 11.0];
/// The room kept on each side of the title [px].
const TITLE_MARGIN: f64 = 12.0;

/// The axis ranges `x` and `y` with the shorter one (in data units per pixel, on a plotting
/// area of `pixels` = (width, height)) widened about its centre until both axes have the
/// same units per pixel; unchanged when a range or the area is empty.
pub fn equal_aspect_ranges(
    x: (f64, f64),
    y: (f64, f64),
    pixels: (f64, f64),
) -> ((f64, f64), (f64, f64)) {
    let (w, h) = pixels;
    let (sx, sy) = ((x.1 - x.0) / w, (y.1 - y.0) / h);
    let ok = |v: f64| v.is_finite() && v > 0.0;
    if !(ok(sx) && ok(sy)) {
        return (x, y);
    }
    let s = sx.max(sy);
    let about = |(lo, hi): (f64, f64), own: f64, pixels: f64| {
        if own >= s {
            return (lo, hi);
        }
        let (c, half) = (0.5 * (lo + hi), 0.5 * s * pixels);
        (c - half, c + half)
    };
    (about(x, sx, w), about(y, sy, h))
}

/// A label's pixel box: (left, top, right, bottom).
type LabelBox = (i32, i32, i32, i32);

/// About 7 pixels per character and 14 per line at 12 px; a glyph reaches 7 from its centre.
const CHAR_WIDTH: i32 = 7;
const GLYPH: i32 = 7;
const LINE_HEIGHT: i32 = 14;

/// Where a label of `chars` characters goes beside the mark at pixel `at`: the first of the
/// offsets above, below and further out, right then left, whose box stays inside `frame`
/// and overlaps no box in `placed` (the first offset inside the frame if every one does);
/// its box is added to `placed`. Returns the offset of the label's top-left corner.
fn label_box(
    at: (i32, i32),
    chars: usize,
    frame: ((i32, i32), (i32, i32)),
    placed: &mut Vec<LabelBox>,
) -> (i32, i32) {
    let width = CHAR_WIDTH * chars as i32;
    let boxed = |(dx, dy): (i32, i32)| {
        (
            at.0 + dx,
            at.1 + dy,
            at.0 + dx + width,
            at.1 + dy + LINE_HEIGHT,
        )
    };
    let inside = |b: &LabelBox| {
        b.0 >= frame.0 .0 && b.1 >= frame.0 .1 && b.2 <= frame.1 .0 && b.3 <= frame.1 .1
    };
    let overlaps = |b: &LabelBox, o: &LabelBox| b.0 < o.2 && o.0 < b.2 && b.1 < o.3 && o.1 < b.3;
    let candidates: Vec<(i32, i32)> = (0..8)
        .flat_map(|k| {
            let dy = [-22, 8][k % 2] + (k / 2) as i32 * [-16, 16][k % 2];
            [(8, dy), (-8 - width, dy)]
        })
        .collect();
    let fits = candidates.iter().copied().filter(|&c| inside(&boxed(c)));
    let chosen = fits
        .clone()
        .find(|&c| placed.iter().all(|o| !overlaps(&boxed(c), o)))
        .or_else(|| fits.clone().next())
        .unwrap_or(candidates[0]);
    placed.push(boxed(chosen));
    chosen
}

/// The black glyph of a mark's shape, about 12 pixels across.
fn glyph<DB: DrawingBackend>(shape: Shape) -> DynElement<'static, DB, (i32, i32)> {
    match shape {
        Shape::Triangle => TriangleMarker::new((0, 0), 6, BLACK.filled()).into_dyn(),
        Shape::Disc => Circle::new((0, 0), 5, BLACK.filled()).into_dyn(),
        Shape::Ring => Circle::new((0, 0), 5, BLACK.stroke_width(2)).into_dyn(),
        Shape::Square => Rectangle::new([(-5, -5), (5, 5)], BLACK.filled()).into_dyn(),
        Shape::Cross => Cross::new((0, 0), 5, BLACK.stroke_width(2)).into_dyn(),
        Shape::Diamond => {
            Polygon::new(vec![(0, -6), (6, 0), (0, 6), (-6, 0)], BLACK.filled()).into_dyn()
        }
    }
}

/// A value over a grid of two parameters, one coloured cell per grid point with its value
/// written in it (blank: no value, e.g. a failed point).
#[derive(Clone, Debug)]
pub struct HeatMap {
    pub title: String,
    pub x: Axis,
    pub y: Axis,
    pub xs: Vec<f64>,
    pub ys: Vec<f64>,
    /// `values[j][i]` at (`xs[i]`, `ys[j]`); NaN where there is none.
    pub values: Vec<Vec<f64>>,
}

impl HeatMap {
    pub fn svg(&self) -> Result<String> {
        svg_of(|root| self.paint(root))
    }

    pub fn png(&self) -> Result<Vec<u8>> {
        png_of(|root| self.paint(root))
    }

    fn paint<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<()> {
        let (nx, ny) = (self.xs.len().max(1), self.ys.len().max(1));
        let xs = self.xs.clone();
        let ys = self.ys.clone();
        let label = |vals: &[f64], v: f64| -> String {
            let i = v.floor();
            if v - i > 0.45 && v - i < 0.55 && i >= 0.0 && (i as usize) < vals.len() {
                tick(vals[i as usize])
            } else {
                String::new()
            }
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(&self.title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(78)
            .build_cartesian_2d(0.0..nx as f64, 0.0..ny as f64)
            .map_err(plot_error)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(4 * nx + 1)
            .y_labels(4 * ny + 1)
            .x_desc(self.x.label.as_str())
            .y_desc(self.y.label.as_str())
            .x_label_formatter(&|v| label(&xs, *v))
            .y_label_formatter(&|v| label(&ys, *v))
            .draw()
            .map_err(plot_error)?;
        let finite = self
            .values
            .iter()
            .flatten()
            .copied()
            .filter(|v| v.is_finite());
        let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        for (j, row) in self.values.iter().enumerate() {
            for (i, &v) in row.iter().enumerate() {
                if !v.is_finite() {
                    continue;
                }
                let t = if hi > lo { (v - lo) / (hi - lo) } else { 0.5 };
                let (x, y) = (i as f64, j as f64);
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(x, y), (x + 1.0, y + 1.0)],
                        colour_scale(t).filled(),
                    )))
                    .map_err(plot_error)?;
                chart
                    .draw_series(std::iter::once(Text::new(
                        tick(v),
                        (x + 0.3, y + 0.55),
                        ("sans-serif", 13),
                    )))
                    .map_err(plot_error)?;
            }
        }
        root.present().map_err(plot_error)
    }

    /// Write `<stem>.svg` and `<stem>.png`.
    pub fn save(&self, stem: &Path) -> Result<()> {
        save_both(stem, &self.svg()?, &self.png()?)
    }
}

/// Light blue (t = 0) to light red (t = 1), pale enough for black text.
fn colour_scale(t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let mix = |a: f64, b: f64| (a + (b - a) * t).round() as u8;
    RGBColor(mix(158.0, 244.0), mix(202.0, 165.0), mix(225.0, 130.0))
}

/// A tick label: plain for moderate magnitudes, otherwise `1.5e-7`.
pub fn tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (1e-2..1e4).contains(&a) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        let s = format!("{v:.2e}");
        match s.split_once('e') {
            Some((m, e)) => format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.')),
            None => s,
        }
    }
}

/// The axis range of some values, padded; decades on a log axis.
fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !lo.is_finite() {
        return if log { (1e-3, 1.0) } else { (0.0, 1.0) };
    }
    if log {
        let (l, h) = (lo.log10().floor(), hi.log10().ceil());
        (10f64.powf(l), 10f64.powf(if h > l { h } else { l + 1.0 }))
    } else if hi > lo {
        let pad = 0.05 * (hi - lo);
        (lo - pad, hi + pad)
    } else {
        let pad = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        (lo - pad, hi + pad)
    }
}

fn with_extension(stem: &Path, ext: &str) -> PathBuf {
    let mut name = stem.as_os_str().to_owned();
    name.push(".");
    name.push(ext);
    PathBuf::from(name)
}

fn save_both(stem: &Path, svg: &str, png: &[u8]) -> Result<()> {
    let svg_path = with_extension(stem, "svg");
    std::fs::write(&svg_path, svg).map_err(|e| Error::io(&svg_path, e))?;
    let png_path = with_extension(stem, "png");
    std::fs::write(&png_path, png).map_err(|e| Error::io(&png_path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: equal aspect widens only the shorter axis, about its centre, so that both
    /// axes have the same data units per pixel: a 0.2 × 0.01 m beam's ranges on a 600 × 400
    /// pixel area come out at 0.2/600 m per pixel on both, the x range untouched.
    #[test]
    fn equal_aspect_gives_both_axes_the_same_units_per_pixel_widening_the_shorter() {
        let ((x0, x1), (y0, y1)) = equal_aspect_ranges((0.0, 0.2), (-0.005, 0.005), (600.0, 400.0));
        assert_eq!((x0, x1), (0.0, 0.2));
        assert!(((y1 - y0) / 400.0 - 0.2 / 600.0).abs() < 1e-15);
        assert!((y0 + y1).abs() < 1e-15);
        // A tall range widens x instead.
        let ((x0, x1), (y0, y1)) = equal_aspect_ranges((1.0, 2.0), (0.0, 10.0), (600.0, 400.0));
        assert_eq!((y0, y1), (0.0, 10.0));
        assert!(((x1 - x0) / 600.0 - 10.0 / 400.0).abs() < 1e-12);
        assert!((0.5 * (x0 + x1) - 1.5).abs() < 1e-12);
        // The figure's own plotting area: the mapped span is the same in x and y.
        let fig = Figure::new("beam", Axis::linear("x [m]"), Axis::linear("y [m]"))
            .curve("outline", vec![(0.0, -0.005), (0.2, -0.005), (0.2, 0.005)])
            .equal_aspect();
        let (w, h) = fig.plot_area().expect("a plotting area");
        let ((x0, x1), (y0, y1)) = fig.ranges();
        println!("plotting area {w} × {h} px; x {x0}..{x1}, y {y0}..{y1}");
        assert!(w > 500.0 && h > 300.0);
        assert!(((x1 - x0) / w - (y1 - y0) / h).abs() < 1e-12 * (x1 - x0) / w);
    }

    /// TEST GOAL: a title too long for the frame at the usual size is drawn smaller, so that
    /// it fits within the margins (a spline sweep's title measured 88 characters); a short one
    /// keeps the usual size.
    #[test]
    fn a_long_title_is_set_smaller_to_fit_the_frame() {
        let mut scratch = String::new();
        let root = canvas(SVGBackend::with_string(&mut scratch, (WIDTH, HEIGHT))).unwrap();
        let long = "strip_sweep: probe first-harmonic amplitude against frequency (spline (degree 3, 41 segments))";
        let size = title_size(&root, long);
        let style = TextStyle::from(("sans-serif", size).into_font());
        let (w, _) = root.estimate_text_size(long, &style).unwrap();
        println!("{size} px, {w} px wide");
        assert!(size < TITLE_SIZES[0]);
        assert!(f64::from(w) <= f64::from(WIDTH) - 2.0 * TITLE_MARGIN);
        assert_eq!(title_size(&root, "short"), TITLE_SIZES[0]);
    }

    /// TEST GOAL: a tick that plotters places a rounding error away from 0 (here -2.2e-16 on
    /// the equal-aspect x range of a half disc of radius 1, as `modes` draws it) is labelled
    /// `0`, and no tick label is a rounding error.
    #[test]
    fn ticks_a_rounding_error_from_zero_are_labelled_zero() {
        let arc: Vec<(f64, f64)> = (0..=32)
            .map(|k| std::f64::consts::PI * (1.0 + k as f64 / 32.0))
            .map(|t| (t.cos(), 1.0 + t.sin()))
            .collect();
        let fig = Figure::new("half disc", Axis::linear("x [m]"), Axis::linear("y [m]"))
            .dashed("outline", arc)
            .equal_aspect();
        let svg = fig.svg().expect("an SVG");
        let labels: Vec<&str> = svg
            .split("</text>")
            .filter_map(|t| t.rsplit('>').next().map(str::trim))
            .collect();
        println!("{labels:?}");
        assert!(labels.contains(&"0"), "{labels:?}");
        assert!(!labels.iter().any(|l| l.contains("e-1")), "{labels:?}");
    }

    /// TEST GOAL: labels of marks crowded on one spot are placed in boxes that overlap
    /// neither each other nor any glyph, inside the frame, while there is room.
    #[test]
    fn crowded_mark_labels_get_boxes_that_overlap_nothing_inside_the_frame() {
        let frame = ((0, 0), (720, 480));
        let marks = [(300, 200), (305, 204), (310, 198), (302, 210), (298, 190)];
        let mut placed: Vec<LabelBox> = marks
            .iter()
            .map(|&(x, y)| (x - GLYPH, y - GLYPH, x + GLYPH, y + GLYPH))
            .collect();
        for &at in &marks {
            label_box(at, 14, frame, &mut placed);
        }
        let overlaps =
            |b: &LabelBox, o: &LabelBox| b.0 < o.2 && o.0 < b.2 && b.1 < o.3 && o.1 < b.3;
        for (i, a) in placed.iter().enumerate() {
            assert!(a.0 >= 0 && a.1 >= 0 && a.2 <= 720 && a.3 <= 480, "{a:?}");
            for b in &placed[i + 1..] {
                // Glyphs of marks this close may overlap each other, never a label.
                let glyphs =
                    i < marks.len() && placed.iter().position(|p| p == b) < Some(marks.len());
                assert!(glyphs || !overlaps(a, b), "{a:?} overlaps {b:?}");
            }
        }
    }
}
