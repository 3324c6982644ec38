//! Line figures fit for a paper, drawn with plotters.
//!
//! * Size in physical units: [`WIDTH_CM`] × [`HEIGHT_CM`] (a journal's full
//!   text width); the SVG carries that size, so its fonts keep their point
//!   sizes when placed at that width (tick labels 8 pt, axis and legend text
//!   8.6–9 pt). PNGs are rendered at [`PNG_SCALE`] × 96 dpi.
//! * Colours: the Okabe–Ito colour-blind-safe palette without its yellow
//!   (Okabe & Ito 2008, "Color Universal Design"), combined with line
//!   styles (solid, dashed, dotted) and sparse markers, so that overlapping
//!   curves stay distinguishable in print and in grey scale.
//! * The legend sits beside the plotting area, never on the data.
//! * Logarithmic ordinates are log axes with ticks at the decades (10ⁿ),
//!   plotting |y|.
//! * Every figure written by [`Figure::save`] gets, beside the SVG, the CSV
//!   of exactly the plotted columns and a `.redraw.txt` with the `mbsolve
//!   plot` command that redraws it from that CSV.
//!
//! Text metrics come from the DejaVu Sans font embedded in the binary
//! (`assets/fonts/`, Bitstream Vera licence), so PNG rendering needs no
//! system font library.

use crate::output::{write_columns_csv, OutputError};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;
use std::sync::Once;

/// Figure width \[cm\] (full text width of a two-column journal).
pub const WIDTH_CM: f64 = 17.0;
/// Figure height \[cm\].
pub const HEIGHT_CM: f64 = 10.0;
/// CSS pixels per centimetre (96 dpi): the SVG's user unit.
const PX_PER_CM: f64 = 96.0 / 2.54;
/// PNG resolution as a multiple of 96 dpi (3 → 288 dpi).
pub const PNG_SCALE: f64 = 3.0;

/// Okabe–Ito palette without yellow (#F0E442 is near invisible on white).
const PALETTE: [RGBColor; 7] = [
    RGBColor(0x00, 0x72, 0xB2), // blue
    RGBColor(0xD5, 0x5E, 0x00), // vermillion
    RGBColor(0x00, 0x9E, 0x73), // bluish green
    RGBColor(0xCC, 0x79, 0xA7), // reddish purple
    RGBColor(0xE6, 0x9F, 0x00), // orange
    RGBColor(0x56, 0xB4, 0xE9), // sky blue
    RGBColor(0x00, 0x00, 0x00), // black
];

/// Font sizes in CSS px at 96 dpi (1 pt = 4/3 px).
const TITLE_PX: f64 = 12.5;
const LABEL_PX: f64 = 12.0;
const TICK_PX: f64 = 10.7;
const LEGEND_PX: f64 = 11.5;
/// Markers per curve.
const MARKERS: usize = 8;

static FONT: Once = Once::new();

/// Register the embedded font with plotters (idempotent).
pub fn register_font() {
    FONT.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");
        // The font is embedded and known to parse; a failure would only
        // degrade text layout, never the data.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, bytes);
    });
}

/// One curve of a figure.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label (and CSV column name).
    pub label: String,
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates.
    pub y: Vec<f64>,
}

/// A line figure: title, axis labels, curves, linear or logarithmic y.
#[derive(Debug, Clone)]
pub struct Figure {
    /// Title above the plotting area.
    pub title: String,
    /// Abscissa label (also the CSV's first column name).
    pub x_label: String,
    /// Ordinate label.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
    /// Logarithmic ordinate (|y| plotted; zeros and non-finite values dropped).
    pub log_y: bool,
}

impl Figure {
    /// Write `<stem>.svg`, the plotted data `<stem>.csv` (first column the
    /// abscissa named after `x_label`, one column per curve named after its
    /// label) and `<stem>.redraw.txt` (the `mbsolve plot` command that
    /// redraws the SVG from the CSV) in `dir`.
    pub fn save(&self, dir: &Path, stem: &str) -> Result<(), OutputError> {
        let csv = dir.join(format!("{stem}.csv"));
        self.write_csv(&csv)?;
        self.render(&dir.join(format!("{stem}.svg")))?;
        let mut cmd = format!(
            "mbsolve plot {stem}.csv --x '{}'",
            self.x_label.replace('\'', "'\\''")
        );
        for s in &self.series {
            cmd += &format!(" --y '{}'", s.label.replace('\'', "'\\''"));
        }
        if self.log_y {
            cmd += " --log-y";
        }
        cmd += &format!(
            " --y-label '{}' --title '{}' --out {stem}.svg\n",
            self.y_label.replace('\'', "'\\''"),
            self.title.replace('\'', "'\\''")
        );
        let path = dir.join(format!("{stem}.redraw.txt"));
        std::fs::write(&path, cmd).map_err(|e| OutputError::new(&path, e))
    }

    /// The plotted data as CSV: the abscissa of the longest curve, then one
    /// column per curve. Every curve must share that abscissa (a shorter
    /// curve — a run that stopped early — a prefix of it); its missing rows
    /// are left empty.
    pub fn write_csv(&self, path: &Path) -> Result<(), OutputError> {
        let longest = self
            .series
            .iter()
            .max_by_key(|s| s.x.len())
            .map(|s| s.x.clone())
            .unwrap_or_default();
        for s in &self.series {
            if s.x.len() != s.y.len() || s.x[..] != longest[..s.x.len()] {
                return Err(OutputError::new(
                    path,
                    format!(
                        "curve '{}' does not share the figure's abscissa: cannot write one table",
                        s.label
                    ),
                ));
            }
        }
        let padded: Vec<Vec<f64>> = self
            .series
            .iter()
            .map(|s| {
                let mut y = s.y.clone();
                y.resize(longest.len(), f64::NAN);
                y
            })
            .collect();
        let mut cols: Vec<(&str, &[f64])> = vec![(self.x_label.as_str(), &longest)];
        for (s, y) in self.series.iter().zip(&padded) {
            cols.push((s.label.as_str(), y));
        }
        write_columns_csv(path, &cols)
    }

    /// Draw to `path`: SVG or PNG by its extension.
    pub fn render(&self, path: &Path) -> Result<(), OutputError> {
        register_font();
        let w = (WIDTH_CM * PX_PER_CM).round();
        let h = (HEIGHT_CM * PX_PER_CM).round();
        match extension(path).as_str() {
            "svg" => {
                {
                    let root = SVGBackend::new(path, (w as u32, h as u32)).into_drawing_area();
                    self.draw(&root, 1.0)
                        .map_err(|e| OutputError::new(path, e))?;
                    root.present().map_err(|e| OutputError::new(path, e))?;
                }
                set_physical_size(path, w, h)
            }
            "png" => {
                let size = ((w * PNG_SCALE) as u32, (h * PNG_SCALE) as u32);
                let root = BitMapBackend::new(path, size).into_drawing_area();
                self.draw(&root, PNG_SCALE)
                    .map_err(|e| OutputError::new(path, e))?;
                root.present().map_err(|e| OutputError::new(path, e))
            }
            other => Err(OutputError::new(
                path,
                format!("unknown figure format '{other}': use .svg or .png"),
            )),
        }
    }

    /// Data ranges: (x0, x1, y0, y1), y for log axes over |y| > 0.
    fn ranges(&self) -> (f64, f64, f64, f64) {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for s in &self.series {
            for (&x, &y) in s.x.iter().zip(&s.y) {
                if let Some(y) = self.plotted(y) {
                    if x.is_finite() {
                        x0 = x0.min(x);
                        x1 = x1.max(x);
                        y0 = y0.min(y);
                        y1 = y1.max(y);
                    }
                }
            }
        }
        if x0 > x1 {
            return if self.log_y {
                (0.0, 1.0, -3.0, 0.0)
            } else {
                (0.0, 1.0, -1.0, 1.0)
            };
        }
        if x1 <= x0 {
            x1 = x0 + 1.0;
        }
        if self.log_y {
            // whole decades (values are log10 |y|)
            (y0, y1) = (y0.floor(), y1.ceil());
            if y1 <= y0 {
                y1 = y0 + 1.0;
            }
        } else {
            if y1 - y0 <= 1e-300 {
                let d = y0.abs().max(1.0);
                (y0, y1) = (y0 - 0.5 * d, y1 + 0.5 * d);
            }
            let pad = 0.05 * (y1 - y0);
            (y0, y1) = (y0 - pad, y1 + pad);
        }
        (x0, x1, y0, y1)
    }

    /// The coordinate plotted for `y`, if any: y, or log10 |y| on a log axis.
    fn plotted(&self, y: f64) -> Option<f64> {
        if !y.is_finite() {
            None
        } else if self.log_y {
            (y != 0.0).then(|| y.abs().log10())
        } else {
            Some(y)
        }
    }

    /// Lay out title, plotting area and legend on `root`; `s` scales every
    /// length (1 = CSS px at 96 dpi).
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        s: f64,
    ) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        root.fill(&WHITE)?;
        let font = |px: f64| ("sans-serif", px * s).into_font();
        let area = root
            .margin((6.0 * s) as u32, 0, (4.0 * s) as u32, 0)
            .titled(&self.title, font(TITLE_PX))?;
        let (w, _) = area.dim_in_pixel();
        let max_label = self
            .series
            .iter()
            .map(|c| c.label.chars().count())
            .max()
            .unwrap_or(0) as f64;
        let legend_w = ((max_label * 0.6 * LEGEND_PX + 48.0) * s).clamp(60.0 * s, 0.4 * w as f64);
        let (plot, legend) = area.split_horizontally(w - legend_w as u32);
        let (x0, x1, y0, y1) = self.ranges();
        let x_fmt = tick_format(x0, x1);
        let mut builder = ChartBuilder::on(&plot);
        builder
            .margin_top((6.0 * s) as u32)
            .margin_right((10.0 * s) as u32)
            .margin_left((4.0 * s) as u32)
            .x_label_area_size((38.0 * s) as u32)
            .y_label_area_size((62.0 * s) as u32);
        let styles: Vec<ShapeStyle> = (0..self.series.len())
            .map(|i| PALETTE[i % PALETTE.len()].stroke_width((1.6 * s).max(1.0) as u32))
            .collect();
        // Log axes are drawn in log10 |y| with ticks labelled 10ⁿ at the
        // decades only: plotters' own log coordinate drops key points below
        // f64::EPSILON, which constraint residuals reach.
        let log_y = self.log_y;
        let y_lin = tick_format(y0, y1);
        let y_fmt = move |v: f64| {
            if !log_y {
                y_lin(v)
            } else if (v - v.round()).abs() < 1e-9 {
                decade(v.round() as i32)
            } else {
                String::new()
            }
        };
        let decades = (y1 - y0).round() as usize;
        let x_formatter = |v: &f64| x_fmt(*v);
        let y_formatter = |v: &f64| y_fmt(*v);
        let mut chart = builder.build_cartesian_2d(x0..x1, y0..y1)?;
        let mut mesh = chart.configure_mesh();
        mesh.x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style(font(TICK_PX))
            .axis_desc_style(font(LABEL_PX))
            .x_label_formatter(&x_formatter)
            .y_label_formatter(&y_formatter)
            .light_line_style(WHITE)
            .bold_line_style(BLACK.mix(0.12));
        if log_y {
            mesh.y_labels((decades + 1).clamp(2, 12));
        }
        mesh.draw()?;
        for i in self.draw_order() {
            let pts = self.points(&self.series[i]);
            draw_curve(&mut chart, pts, i, styles[i], s)?;
        }
        // The legend, beside the plotting area.
        let row = 1.6 * LEGEND_PX * s;
        for (i, c) in self.series.iter().enumerate() {
            let y = (10.0 * s + row * (i as f64 + 0.5)) as i32;
            let (xa, xb) = ((6.0 * s) as i32, (34.0 * s) as i32);
            draw_sample(&legend, (xa, y), (xb, y), i, styles[i], s)?;
            legend.draw(&Text::new(
                c.label.clone(),
                ((40.0 * s) as i32, y),
                TextStyle::from(font(LEGEND_PX)).pos(Pos::new(HPos::Left, VPos::Center)),
            ))?;
        }
        Ok(())
    }

    /// Curves in drawing order: largest amplitude first, so that no curve
    /// hides behind one of larger excursion (the legend keeps the given order).
    fn draw_order(&self) -> Vec<usize> {
        let amp = |c: &Series| {
            c.y.iter()
                .filter_map(|&y| self.plotted(y))
                .fold(f64::MIN, |a, y| a.max(if self.log_y { y } else { y.abs() }))
        };
        let mut order: Vec<usize> = (0..self.series.len()).collect();
        order.sort_by(|&a, &b| amp(&self.series[b]).total_cmp(&amp(&self.series[a])));
        order
    }

    /// The finite plotted points of one curve.
    fn points(&self, c: &Series) -> Vec<(f64, f64)> {
        c.x.iter()
            .zip(&c.y)
            .filter_map(|(&x, &y)| Some((x, self.plotted(y)?)).filter(|p| p.0.is_finite()))
            .collect()
    }
}

/// Line style of curve `i`: solid, dashed, dotted in turn.
fn dash(i: usize, s: f64) -> Option<(f64, f64)> {
    match i % 3 {
        0 => None,
        1 => Some((6.0 * s, 3.5 * s)),
        _ => Some((1.6 * s, 2.6 * s)),
    }
}

/// Draw one curve with its line style and sparse markers (phase shifted
/// per curve so that coinciding curves show every marker).
fn draw_curve<DB, X, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
    pts: Vec<(f64, f64)>,
    i: usize,
    style: ShapeStyle,
    s: f64,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>>
where
    DB: DrawingBackend,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let marks: Vec<(f64, f64)> = if pts.len() > 2 * MARKERS {
        let stride = pts.len() / MARKERS;
        let phase = (i * stride / PALETTE.len().max(1)) % stride;
        pts.iter().skip(phase).step_by(stride).copied().collect()
    } else {
        pts.clone()
    };
    match dash(i, s) {
        None => {
            chart.draw_series(LineSeries::new(pts, style))?;
        }
        Some((on, off)) => {
            chart.draw_series(DashedLineSeries::new(pts, on as u32, off as u32, style))?;
        }
    }
    let r = (2.6 * s) as i32;
    match i % 4 {
        0 => chart.draw_series(marks.into_iter().map(|p| Circle::new(p, r, style)))?,
        1 => chart.draw_series(
            marks
                .into_iter()
                .map(|p| TriangleMarker::new(p, r + 1, style)),
        )?,
        2 => chart.draw_series(
            marks
                .into_iter()
                .map(|p| EmptyElement::at(p) + Rectangle::new([(-r, -r), (r, r)], style)),
        )?,
        _ => chart.draw_series(marks.into_iter().map(|p| Cross::new(p, r, style)))?,
    };
    Ok(())
}

/// The legend's sample of curve `i`: its line style from `a` to `b` (pixel
/// coordinates of `area`) with its marker in the middle.
fn draw_sample<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    a: (i32, i32),
    b: (i32, i32),
    i: usize,
    style: ShapeStyle,
    s: f64,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    match dash(i, s) {
        None => area.draw(&PathElement::new(vec![a, b], style))?,
        Some((on, off)) => {
            let mut x = a.0 as f64;
            while x < b.0 as f64 {
                let xe = (x + on).min(b.0 as f64);
                area.draw(&PathElement::new(
                    vec![(x as i32, a.1), (xe as i32, a.1)],
                    style,
                ))?;
                x += on + off;
            }
        }
    }
    let m = ((a.0 + b.0) / 2, a.1);
    let r = (2.6 * s) as i32;
    match i % 4 {
        0 => area.draw(&Circle::new(m, r, style))?,
        1 => area.draw(&TriangleMarker::new(m, r + 1, style))?,
        2 => area.draw(&Rectangle::new(
            [(m.0 - r, m.1 - r), (m.0 + r, m.1 + r)],
            style,
        ))?,
        _ => area.draw(&Cross::new(m, r, style))?,
    }
    Ok(())
}

/// Tick label format for an axis spanning `lo..hi`: enough decimals for the
/// span, scientific notation for very small or large magnitudes.
fn tick_format(lo: f64, hi: f64) -> impl Fn(f64) -> String {
    let span = (hi - lo).abs().max(f64::MIN_POSITIVE);
    let mag = lo.abs().max(hi.abs());
    let sci = !(1e-3..1e5).contains(&mag);
    let decimals = (2.0 - span.log10().floor()).clamp(0.0, 9.0) as usize;
    move |v: f64| {
        if v == 0.0 || v.abs() < 1e-12 * span {
            "0".to_string()
        } else if sci {
            format!("{v:.1e}")
        } else {
            let t = format!("{v:.decimals$}");
            if t.contains('.') {
                t.trim_end_matches('0').trim_end_matches('.').to_string()
            } else {
                t
            }
        }
    }
}

/// "10ⁿ" with a superscript exponent.
fn decade(n: i32) -> String {
    const SUP: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut e: String = n
        .unsigned_abs()
        .to_string()
        .chars()
        .map(|c| SUP[c as usize - '0' as usize])
        .collect();
    if n < 0 {
        e.insert(0, '⁻');
    }
    format!("10{e}")
}

/// Lower-case extension of `path` ("" if none).
pub fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Give the SVG written by plotters its physical size (width and height in
/// cm, the drawing in a `viewBox` of CSS px), so that its point sizes hold.
fn set_physical_size(path: &Path, w: f64, h: f64) -> Result<(), OutputError> {
    let text = std::fs::read_to_string(path).map_err(|e| OutputError::new(path, e))?;
    let old = format!(r#"<svg width="{w}" height="{h}""#);
    let new = format!(
        r#"<svg width="{:.2}cm" height="{:.2}cm""#,
        w / PX_PER_CM,
        h / PX_PER_CM
    );
    if !text.starts_with(&old) {
        return Err(OutputError::new(
            path,
            "unexpected SVG header from plotters: cannot set the physical size",
        ));
    }
    std::fs::write(path, text.replacen(&old, &new, 1)).map_err(|e| OutputError::new(path, e))
}
