//! SVG plots read back: the XML parsed, the pixel → value maps fitted to the tick labels, the
//! data polylines and markers by colour (legend glyphs left out), so that tests compare what
//! a plot draws with the numbers it was drawn from.

use std::path::Path;

/// The plotting palette's first two colours (series 1 and 2).
pub const FIRST: &str = "#1F77B4";
pub const SECOND: &str = "#D62728";

/// What an SVG plot holds, read back.
pub struct Svg {
    /// Every text element's content.
    pub texts: Vec<String>,
    /// value = a + b · pixel, fitted to the tick labels.
    pub x_map: (f64, f64),
    pub y_map: (f64, f64),
    /// Data polylines (stroke width 2): colour and pixel points, legend glyphs left out.
    pub lines: Vec<(String, Vec<(f64, f64)>)>,
    /// Marker circles: colour and pixel centre, legend glyphs left out.
    pub circles: Vec<(String, (f64, f64))>,
    /// Filled polygons (marks: triangles): the pixel centroid of each, legend glyphs left out.
    pub polygons: Vec<(f64, f64)>,
    /// The y axis range in values (lowest and highest tick).
    pub y_span: f64,
}

/// Least-squares line value = a + b · pixel through (pixel, value) pairs.
pub fn fit(pairs: &[(f64, f64)]) -> (f64, f64) {
    assert!(pairs.len() >= 2, "fewer than two tick labels: {pairs:?}");
    let n = pairs.len() as f64;
    let (mp, mv) = (
        pairs.iter().map(|p| p.0).sum::<f64>() / n,
        pairs.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let b = pairs.iter().map(|p| (p.0 - mp) * (p.1 - mv)).sum::<f64>()
        / pairs.iter().map(|p| (p.0 - mp).powi(2)).sum::<f64>();
    (mv - b * mp, b)
}

/// `x,y x,y …` as pixel points.
fn pixel_points(text: &str) -> Vec<(f64, f64)> {
    text.split_whitespace()
        .map(|p| {
            let (x, y) = p.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

pub fn read_svg(path: &Path) -> Svg {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let doc = roxmltree::Document::parse(&text)
        .unwrap_or_else(|e| panic!("{} is not XML: {e}", path.display()));
    assert_eq!(doc.root_element().tag_name().name(), "svg");
    let num = |n: &roxmltree::Node, a: &str| n.attribute(a).and_then(|v| v.parse::<f64>().ok());
    let (mut x_ticks, mut y_ticks, mut texts) = (Vec::new(), Vec::new(), Vec::new());
    let mut legend = None;
    let (mut raw_lines, mut raw_circles) = (Vec::new(), Vec::new());
    let mut raw_polygons: Vec<(f64, f64)> = Vec::new();
    for n in doc.descendants().filter(|n| n.is_element()) {
        match n.tag_name().name() {
            "text" => {
                let content = n.text().unwrap_or_default().trim().to_string();
                if let Ok(v) = content.parse::<f64>() {
                    match n.attribute("text-anchor") {
                        Some("end") => y_ticks.push((num(&n, "y").unwrap(), v)),
                        Some("middle") => x_ticks.push((num(&n, "x").unwrap(), v)),
                        _ => {}
                    }
                }
                texts.push(content);
            }
            // The legend's frame: an unfilled black rectangle.
            "rect" if n.attribute("fill") == Some("none") => {
                let r = ["x", "y", "width", "height"].map(|a| num(&n, a).unwrap());
                legend = Some(r);
            }
            "polyline" if n.attribute("stroke-width") == Some("2") => {
                let points = pixel_points(n.attribute("points").unwrap());
                raw_lines.push((n.attribute("stroke").unwrap().to_string(), points));
            }
            "polygon" => {
                let pts = pixel_points(n.attribute("points").unwrap());
                let k = pts.len().max(1) as f64;
                let c = pts
                    .iter()
                    .fold((0.0, 0.0), |a, p| (a.0 + p.0 / k, a.1 + p.1 / k));
                raw_polygons.push(c);
            }
            "circle" => {
                let c = (num(&n, "cx").unwrap(), num(&n, "cy").unwrap());
                raw_circles.push((n.attribute("fill").unwrap_or_default().to_string(), c));
            }
            _ => {}
        }
    }
    let in_legend = |&(x, y): &(f64, f64)| {
        legend.is_some_and(|[lx, ly, w, h]| x >= lx && x <= lx + w && y >= ly && y <= ly + h)
    };
    let y_values: Vec<f64> = y_ticks.iter().map(|t| t.1).collect();
    let lo = y_values.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = y_values.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    Svg {
        texts,
        x_map: fit(&x_ticks),
        y_map: fit(&y_ticks),
        lines: raw_lines
            .into_iter()
            .filter(|(_, pts)| !pts.iter().all(in_legend))
            .collect(),
        circles: raw_circles
            .into_iter()
            .filter(|(_, c)| !in_legend(c))
            .collect(),
        polygons: raw_polygons.into_iter().filter(|c| !in_legend(c)).collect(),
        y_span: hi - lo,
    }
}

impl Svg {
    /// The data points (x, y values) of the polylines of `colour`.
    pub fn series(&self, colour: &str) -> Vec<(f64, f64)> {
        let (ax, bx) = self.x_map;
        let (ay, by) = self.y_map;
        self.lines
            .iter()
            .filter(|(c, _)| c == colour)
            .flat_map(|(_, pts)| pts.iter().map(|&(x, y)| (ax + bx * x, ay + by * y)))
            .collect()
    }

    /// A pixel point as (x, y) values.
    pub fn value(&self, (x, y): (f64, f64)) -> (f64, f64) {
        (
            self.x_map.0 + self.x_map.1 * x,
            self.y_map.0 + self.y_map.1 * y,
        )
    }

    /// The largest and smallest drawn y value of `colour`.
    pub fn y_extremes(&self, colour: &str) -> (f64, f64) {
        let pts = self.series(colour);
        assert!(!pts.is_empty(), "no series drawn in {colour}");
        pts.iter()
            .fold((f64::NEG_INFINITY, f64::INFINITY), |(a, b), p| {
                (a.max(p.1), b.min(p.1))
            })
    }

    /// Whether a drawn value equals `expected` within 1% of the y axis range.
    pub fn assert_close(&self, what: &str, drawn: f64, expected: f64) {
        let tolerance = 0.01 * self.y_span;
        println!("{what}: drawn {drawn:.5e}, expected {expected:.5e} (±{tolerance:.2e})");
        assert!(
            (drawn - expected).abs() <= tolerance,
            "{what}: the plot shows {drawn:e}, the summary says {expected:e}"
        );
    }

    /// Every drawn point of `colour` lies on the periodic samples (t/T, v) linearly
    /// interpolated, within 1% of the y range, allowing the x position two pixels (the dashes' ends are rounded in x and y).
    pub fn assert_on_curve(&self, what: &str, colour: &str, t: &[f64], v: &[f64]) {
        let at = |x: f64| {
            let x = x.rem_euclid(1.0);
            let j = t.partition_point(|&tj| tj <= x).max(1) - 1;
            let (t1, v1) = match t.get(j + 1) {
                Some(&tn) => (tn, v[j + 1]),
                None => (1.0 + t[0], v[0]),
            };
            v[j] + (v1 - v[j]) * (x - t[j]) / (t1 - t[j])
        };
        let pixel = self.x_map.1.abs();
        let tolerance = 0.01 * self.y_span;
        let points = self.series(colour);
        assert!(points.len() > 10, "{what}: {} points drawn", points.len());
        for (x, y) in points {
            let near = [-2.0, -1.0, 0.0, 1.0, 2.0].map(|k| at(x + k * pixel));
            let (lo, hi) = near
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &w| {
                    (a.min(w), b.max(w))
                });
            assert!(
                y >= lo - tolerance && y <= hi + tolerance,
                "{what}: drawn ({x:.4}, {y:.4e}) is off the data ({lo:.4e} to {hi:.4e})"
            );
        }
    }

    pub fn assert_texts(&self, path: &Path, needles: &[&str]) {
        for needle in needles {
            assert!(
                self.texts.iter().any(|t| t.contains(needle)),
                "{}: no text `{needle}` in {:?}",
                path.display(),
                self.texts
            );
        }
    }
}

/// `<stem>.svg` parsed, with `labels` among its texts, and `<stem>.png` a PNG of 720 × 480.
pub fn check_plot(stem: &Path, labels: &[&str]) -> Svg {
    let svg_path = stem.with_extension("svg");
    let svg = read_svg(&svg_path);
    svg.assert_texts(&svg_path, labels);
    let png_path = stem.with_extension("png");
    let png = std::fs::read(&png_path).unwrap_or_else(|e| panic!("{}: {e}", png_path.display()));
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{}", png_path.display());
    assert!(
        png.len() > 10_000,
        "{}: {} bytes",
        png_path.display(),
        png.len()
    );
    let image = png::Decoder::new(std::io::Cursor::new(&png))
        .read_info()
        .unwrap_or_else(|e| panic!("{}: {e}", png_path.display()));
    let info = image.info();
    assert_eq!((info.width, info.height), (720, 480));
    svg
}
