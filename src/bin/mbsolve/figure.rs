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
//!   plotting |y|; zeros (and values below a stated floor) are gaps in the
//!   curve, stated under the legend, never bridged by a line.
//! * SVG coordinates of curves, markers and reference lines are floating
//!   point (no grid snapping); plotters' frame sits on a 1/10 px grid.
//! * Every figure written by [`Figure::save`] gets, beside the SVG, the CSV
//!   of exactly the plotted columns, their units (`.columns.json`) and a
//!   `.redraw.txt` with the `mbsolve plot` command that redraws it from
//!   that CSV.
//!
//! Text metrics come from the DejaVu Sans font embedded in the binary
//! (`assets/fonts/`, Bitstream Vera licence), so PNG rendering needs no
//! system font library.

use crate::output::{write_columns_csv, OutputError};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Once;

mod marks;
use marks::*;

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
/// Radius of the dot that draws a curve's one-sample piece \[CSS px\].
const DOT_PX: f64 = 2.2;
/// Curve line width \[CSS px\] (1 pt).
const CURVE_PX: f64 = 4.0 / 3.0;

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

/// SVG user units per CSS px. Plotters writes whole user units, so the
/// frame it draws (axes, ticks, text) sits on a grid of 1/10 px (0.026 mm);
/// curves, markers, reference lines and legend samples are written by
/// [`Figure::svg_marks`] in floating point and do not snap to any grid.
const SVG_SCALE: f64 = 10.0;

/// One curve of a figure.
#[derive(Debug, Clone, Default)]
pub struct Series {
    /// Legend label (and CSV column name).
    pub label: String,
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates.
    pub y: Vec<f64>,
}

/// A line figure: title, axis labels, curves, linear or logarithmic y.
///
/// A curve is drawn as separate pieces wherever a sample is not plotted
/// (non-finite; on a log axis also zero or below [`Figure::log_floor`]):
/// never one line joined across such a gap. A piece of one sample is drawn
/// as a dot. Gaps of a log axis are stated under the legend.
#[derive(Debug, Clone, Default)]
pub struct Figure {
    /// Title above the plotting area.
    pub title: String,
    /// Abscissa label, `quantity [unit]` (also the CSV's first column name).
    pub x_label: String,
    /// Ordinate label, `quantity [unit]`.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
    /// Logarithmic ordinate: |y| plotted, zeros are gaps. Default linear.
    pub log_y: bool,
    /// Log axes only: the smallest |y| drawn, in the ordinate's unit;
    /// smaller values are gaps and the axis starts at this value's decade.
    /// Default `None`: the smallest nonzero |y| sets the axis.
    pub log_floor: Option<f64>,
    /// Horizontal reference lines `(label, y)`, y in the ordinate's unit
    /// (e.g. channel walls): thin grey lines across the plot, named in the
    /// legend, inside the axis range. Default none.
    pub hlines: Vec<(String, f64)>,
    /// Text under the legend, one line per `\n`. Default empty.
    pub note: String,
}

/// Where the frame put the plotting area and the legend's rows, in the
/// backend's pixels (absolute).
struct Frame {
    /// Axis ranges (x0, x1, y0, y1); log10 |y| on a log axis.
    ranges: (f64, f64, f64, f64),
    /// Pixel abscissae of x0 and x1.
    px: (f64, f64),
    /// Pixel ordinates of y0 and y1 (y0 below: py.0 > py.1).
    py: (f64, f64),
    /// Legend samples (x start, x end, y): one per curve, then one per
    /// reference line.
    rows: Vec<(f64, f64, f64)>,
}

impl Frame {
    /// Pixel position of a point in axis coordinates (unrounded; plotters
    /// places the same point at its floor, its ticks included).
    fn map(&self, (x, y): (f64, f64)) -> (f64, f64) {
        let (x0, x1, y0, y1) = self.ranges;
        (
            self.px.0 + (x - x0) / (x1 - x0) * (self.px.1 - self.px.0),
            self.py.0 + (y - y0) / (y1 - y0) * (self.py.1 - self.py.0),
        )
    }

    /// Is the point inside the axis ranges?
    fn contains(&self, (x, y): (f64, f64)) -> bool {
        let (x0, x1, y0, y1) = self.ranges;
        (x0..=x1).contains(&x) && (y0..=y1).contains(&y)
    }
}

impl Figure {
    /// Write `<stem>.svg`, the plotted data `<stem>.csv` (first column the
    /// abscissa named after `x_label`, one column per curve named after its
    /// label), `<stem>.columns.json` (each CSV column's name and unit, the
    /// units taken from the axis labels' brackets) and `<stem>.redraw.txt`
    /// (the `mbsolve plot` command that redraws the SVG from the CSV) in
    /// `dir`.
    pub fn save(&self, dir: &Path, stem: &str) -> Result<(), OutputError> {
        let csv = dir.join(format!("{stem}.csv"));
        self.write_csv(&csv)?;
        let json = dir.join(format!("{stem}.columns.json"));
        std::fs::write(&json, self.columns_json()).map_err(|e| OutputError::new(&json, e))?;
        // drawn from exactly the values in the CSV, so that the redraw
        // command reproduces the SVG byte for byte
        self.as_written().render(&dir.join(format!("{stem}.svg")))?;
        let q = |s: &str| format!("'{}'", s.replace('\'', "'\\''"));
        let mut cmd = format!("mbsolve plot {stem}.csv --x {}", q(&self.x_label));
        for s in &self.series {
            cmd += &format!(" --y {}", q(&s.label));
        }
        if self.log_y {
            cmd += " --log-y";
        }
        if let Some(f) = self.log_floor {
            cmd += &format!(" --log-floor {f:e}");
        }
        for (label, v) in &self.hlines {
            cmd += &format!(" --hline {}", q(&format!("{label}={v:e}")));
        }
        if !self.note.is_empty() {
            cmd += &format!(" --note {}", q(&self.note));
        }
        cmd += &format!(
            " --y-label {} --title {} --out {stem}.svg\n",
            q(&self.y_label),
            q(&self.title)
        );
        let path = dir.join(format!("{stem}.redraw.txt"));
        std::fs::write(&path, cmd).map_err(|e| OutputError::new(&path, e))
    }

    /// This figure with every value as the CSV holds it (rounded to the
    /// 13 significant digits [`write_columns_csv`] writes).
    fn as_written(&self) -> Figure {
        let round = |v: &Vec<f64>| -> Vec<f64> {
            v.iter()
                .map(|x| {
                    if x.is_finite() {
                        format!("{x:.12e}").parse().unwrap_or(*x)
                    } else {
                        *x
                    }
                })
                .collect()
        };
        let mut f = self.clone();
        for s in &mut f.series {
            s.x = round(&s.x);
            s.y = round(&s.y);
        }
        f
    }

    /// The `columns.json` of the CSV [`Figure::write_csv`] writes: name and
    /// unit of every column (the format `mbsolve run` writes beside its
    /// tables, read back by `mbsolve plot`).
    pub fn columns_json(&self) -> String {
        let mut cols = vec![serde_json::json!({
            "name": self.x_label,
            "unit": unit_of(&self.x_label),
        })];
        for s in &self.series {
            cols.push(serde_json::json!({"name": s.label, "unit": unit_of(&self.y_label)}));
        }
        serde_json::to_string_pretty(&cols).unwrap_or_default() + "\n"
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
                let k = SVG_SCALE;
                let size = ((w * k) as u32, (h * k) as u32);
                let mut text = String::new();
                let frame = {
                    let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
                    let frame = self
                        .draw(&root, k, false)
                        .map_err(|e| OutputError::new(path, e))?;
                    root.present().map_err(|e| OutputError::new(path, e))?;
                    frame
                };
                let text = set_physical_size(&text, size, w, h)
                    .ok_or_else(|| OutputError::new(path, "unexpected SVG from plotters"))?;
                let end = text
                    .rfind("</svg>")
                    .ok_or_else(|| OutputError::new(path, "unexpected SVG from plotters"))?;
                let out = format!(
                    "{}{}{}",
                    &text[..end],
                    self.svg_marks(&frame, k),
                    &text[end..]
                );
                std::fs::write(path, out).map_err(|e| OutputError::new(path, e))
            }
            "png" => {
                let size = ((w * PNG_SCALE) as u32, (h * PNG_SCALE) as u32);
                let root = BitMapBackend::new(path, size).into_drawing_area();
                self.draw(&root, PNG_SCALE, true)
                    .map_err(|e| OutputError::new(path, e))?;
                root.present().map_err(|e| OutputError::new(path, e))
            }
            other => Err(OutputError::new(
                path,
                format!("unknown figure format '{other}': use .svg or .png"),
            )),
        }
    }

    /// Data ranges: (x0, x1, y0, y1), y for log axes in log10 |y| over the
    /// plotted values; reference lines included.
    fn ranges(&self) -> (f64, f64, f64, f64) {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        // the abscissa over every sample with finite values (a gap of a
        // log axis at the start keeps its place), the ordinate over the
        // plotted ones
        for s in &self.series {
            for (&x, &y) in s.x.iter().zip(&s.y) {
                if x.is_finite() && y.is_finite() {
                    x0 = x0.min(x);
                    x1 = x1.max(x);
                }
                if let Some(y) = self.plotted(y).filter(|_| x.is_finite()) {
                    y0 = y0.min(y);
                    y1 = y1.max(y);
                }
            }
        }
        if x0 > x1 || y0 > y1 {
            return if self.log_y {
                (0.0, 1.0, -3.0, 0.0)
            } else {
                (0.0, 1.0, -1.0, 1.0)
            };
        }
        for &(_, v) in &self.hlines {
            if let Some(v) = self.plotted(v) {
                y0 = y0.min(v);
                y1 = y1.max(v);
            }
        }
        if x1 <= x0 {
            x1 = x0 + 1.0;
        }
        if self.log_y {
            // whole decades (values are log10 |y|), from the floor's
            if let Some(f) = self.log_floor.filter(|f| *f > 0.0 && f.is_finite()) {
                y0 = f.log10();
            }
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

    /// The coordinate plotted for `y`, if any: y, or log10 |y| on a log
    /// axis (none for zero and |y| below the floor).
    fn plotted(&self, y: f64) -> Option<f64> {
        if !y.is_finite() {
            None
        } else if self.log_y {
            let floor = self.log_floor.unwrap_or(0.0);
            (y != 0.0 && y.abs() >= floor).then(|| y.abs().log10())
        } else {
            Some(y)
        }
    }

    /// The gap note of a log axis: which finite values are not drawn, if
    /// any curve has one.
    fn gap_note(&self) -> Option<String> {
        if !self.log_y {
            return None;
        }
        let dropped = self
            .series
            .iter()
            .flat_map(|c| c.x.iter().zip(&c.y))
            .any(|(x, &y)| x.is_finite() && y.is_finite() && self.plotted(y).is_none());
        if !dropped {
            return None;
        }
        Some(match self.log_floor {
            Some(f) if f > 0.0 => format!("gaps: where |y| < {}", number_text(f)),
            _ => "gaps: where y = 0".to_string(),
        })
    }

    /// The lines under the legend: the gap note, then [`Figure::note`].
    fn note_lines(&self) -> Vec<String> {
        let mut v: Vec<String> = self.gap_note().into_iter().collect();
        v.extend(
            self.note
                .lines()
                .filter(|l| !l.trim().is_empty())
                .map(str::to_string),
        );
        v
    }

    /// Lay out title, plotting area and legend on `root`; `s` scales every
    /// length (1 = CSS px at 96 dpi). With `curves`, draw the curves and
    /// the legend samples with plotters (bitmaps); without, leave them to
    /// [`Figure::svg_marks`]. Returns where things went.
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        s: f64,
        curves: bool,
    ) -> Result<Frame, DrawingAreaErrorKind<DB::ErrorType>> {
        root.fill(&WHITE)?;
        let font = |px: f64| ("sans-serif", px * s).into_font();
        let area = root
            .margin((6.0 * s) as u32, 0, (4.0 * s) as u32, 0)
            .titled(&self.title, font(TITLE_PX))?;
        let (w, _) = area.dim_in_pixel();
        let notes = self.note_lines();
        let chars = |t: &str| t.chars().count() as f64;
        let max_label = self
            .series
            .iter()
            .map(|c| chars(&c.label))
            .chain(self.hlines.iter().map(|h| chars(&h.0)))
            .chain(
                notes
                    .iter()
                    .map(|n| chars(n) * TICK_PX / LEGEND_PX - 70.0 / LEGEND_PX),
            )
            .fold(0.0, f64::max);
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
        let line = |c: RGBAColor| c.stroke_width(s.max(1.0) as u32);
        let mut mesh = chart.configure_mesh();
        mesh.x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style(font(TICK_PX))
            .axis_desc_style(font(LABEL_PX))
            .x_label_formatter(&x_formatter)
            .y_label_formatter(&y_formatter)
            .axis_style(line(BLACK.to_rgba()))
            .set_all_tick_mark_size((5.0 * s) as u32)
            .light_line_style(TRANSPARENT)
            .bold_line_style(line(BLACK.mix(0.12)));
        if log_y {
            mesh.y_labels((decades + 1).clamp(2, 12));
        }
        mesh.draw()?;
        let xr = chart.as_coord_spec().get_x_axis_pixel_range();
        let yr = chart.as_coord_spec().get_y_axis_pixel_range();
        let base = legend.get_base_pixel();
        let row = 1.6 * LEGEND_PX * s;
        let labels: Vec<&str> = self
            .series
            .iter()
            .map(|c| c.label.as_str())
            .chain(self.hline_labels())
            .collect();
        let rows: Vec<(f64, f64, f64)> = (0..labels.len())
            .map(|i| {
                let y = (10.0 * s + row * (i as f64 + 0.5)).round();
                (
                    base.0 as f64 + 6.0 * s,
                    base.0 as f64 + 34.0 * s,
                    base.1 as f64 + y,
                )
            })
            .collect();
        let frame = Frame {
            ranges: (x0, x1, y0, y1),
            px: (xr.start as f64, xr.end as f64),
            py: (yr.end as f64, yr.start as f64),
            rows,
        };
        if curves {
            for (label, v) in &self.hlines {
                if let Some(v) = self.plotted(*v) {
                    let g = self.hline_group(label);
                    let style = reference_style(s);
                    match reference_dash(g, s) {
                        None => chart.draw_series(LineSeries::new([(x0, v), (x1, v)], style))?,
                        Some((on, off)) => chart.draw_series(DashedLineSeries::new(
                            [(x0, v), (x1, v)],
                            on as u32,
                            off as u32,
                            style,
                        ))?,
                    };
                }
            }
            for i in self.draw_order() {
                draw_curve(&mut chart, self.pieces(&self.series[i]), i, s)?;
            }
        }
        // The legend, beside the plotting area.
        for (i, label) in labels.iter().enumerate() {
            let (_, _, y) = frame.rows[i];
            let y = y as i32 - base.1;
            if curves {
                let (xa, xb) = ((6.0 * s) as i32, (34.0 * s) as i32);
                if i < self.series.len() {
                    draw_sample(&legend, (xa, y), (xb, y), i, s)?;
                } else {
                    let style = reference_style(s);
                    match reference_dash(i - self.series.len(), s) {
                        None => legend.draw(&PathElement::new(vec![(xa, y), (xb, y)], style))?,
                        Some((on, off)) => {
                            let mut x = xa as f64;
                            while x < xb as f64 {
                                let xe = (x + on).min(xb as f64);
                                legend.draw(&PathElement::new(
                                    vec![(x as i32, y), (xe as i32, y)],
                                    style,
                                ))?;
                                x += on + off;
                            }
                        }
                    }
                }
            }
            legend.draw(&Text::new(
                label.to_string(),
                ((40.0 * s) as i32, y),
                TextStyle::from(font(LEGEND_PX)).pos(Pos::new(HPos::Left, VPos::Center)),
            ))?;
        }
        let top = 10.0 * s + row * (labels.len() as f64 + 0.4);
        for (k, n) in notes.iter().enumerate() {
            legend.draw(&Text::new(
                n.clone(),
                (
                    (6.0 * s) as i32,
                    (top + 1.4 * TICK_PX * s * (k as f64 + 0.5)) as i32,
                ),
                TextStyle::from(font(TICK_PX)).pos(Pos::new(HPos::Left, VPos::Center)),
            ))?;
        }
        Ok(frame)
    }
}

/// The unit in the brackets that end an axis label (`"t [s]"` → `"s"`),
/// `""` without brackets.
pub fn unit_of(label: &str) -> &str {
    let l = label.trim_end();
    match (l.ends_with(']'), l.rfind('[')) {
        (true, Some(k)) => l[k + 1..l.len() - 1].trim(),
        _ => "",
    }
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

/// Give the SVG plotters wrote at `size` user units its physical size
/// (width and height in cm of a `w` × `h` CSS px figure; the `viewBox`
/// keeps the user units), so that its point sizes hold. `None` if the
/// header is not the one plotters writes.
fn set_physical_size(text: &str, size: (u32, u32), w: f64, h: f64) -> Option<String> {
    let old = format!(r#"<svg width="{}" height="{}""#, size.0, size.1);
    let new = format!(
        r#"<svg width="{:.2}cm" height="{:.2}cm""#,
        w / PX_PER_CM,
        h / PX_PER_CM
    );
    text.starts_with(&old).then(|| text.replacen(&old, &new, 1))
}
