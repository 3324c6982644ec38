//! What a figure draws as marks: curves, markers, reference lines and
//! legend samples (SVG in floating point; bitmaps through plotters),
//! their colours, dash patterns and marker shapes.

use super::*;

impl Figure {
    /// The curves, reference lines, markers and legend samples as SVG
    /// elements in floating-point coordinates, for the frame `f` drawn at
    /// scale `s`.
    pub(super) fn svg_marks(&self, f: &Frame, s: f64) -> String {
        let mut o = String::new();
        let (xa, xb) = (f.px.0.min(f.px.1), f.px.0.max(f.px.1));
        let (ya, yb) = (f.py.0.min(f.py.1), f.py.0.max(f.py.1));
        let _ = write!(
            o,
            r#"<defs><clipPath id="plot-area"><rect x="{}" y="{}" width="{}" height="{}"/></clipPath></defs>
<g clip-path="url(#plot-area)" fill="none">
"#,
            num(xa),
            num(ya),
            num(xb - xa),
            num(yb - ya)
        );
        let grey = rgb(REFERENCE);
        for (label, v) in &self.hlines {
            if let Some(v) = self.plotted(*v) {
                let (a, y) = f.map((f.ranges.0, v));
                let (b, _) = f.map((f.ranges.1, v));
                let _ = writeln!(
                    o,
                    r#"<path d="M{} {}H{}" stroke="{grey}" stroke-width="{}"{}/>"#,
                    num(a),
                    num(y),
                    num(b),
                    num(1.2 * s),
                    reference_dash_attr(self.hline_group(label), s)
                );
            }
        }
        for i in self.draw_order() {
            let pieces = self.pieces(&self.series[i]);
            let colour = rgb(PALETTE[i % PALETTE.len()]);
            let mut d = String::new();
            let mut dots = String::new();
            for p in &pieces {
                if p.len() == 1 {
                    let (x, y) = f.map(p[0]);
                    let _ = writeln!(
                        dots,
                        r#"<circle cx="{}" cy="{}" r="{}" fill="{colour}"/>"#,
                        num(x),
                        num(y),
                        num(DOT_PX * s)
                    );
                    continue;
                }
                for (k, &pt) in p.iter().enumerate() {
                    let (x, y) = f.map(pt);
                    let _ = write!(d, "{}{} {}", if k == 0 { "M" } else { "L" }, num(x), num(y));
                }
            }
            if !d.is_empty() {
                let _ = writeln!(
                    o,
                    r#"<path d="{d}" stroke="{colour}" stroke-width="{}" stroke-linejoin="round"{}/>"#,
                    num(CURVE_PX * s),
                    dash_attr(i, s)
                );
            }
            o += &dots;
        }
        o += "</g>\n";
        for i in self.draw_order() {
            let pts: Vec<(f64, f64)> = self.pieces(&self.series[i]).concat();
            for p in markers(&pts, i) {
                if f.contains(p) {
                    o += &svg_marker(f.map(p), i, s);
                }
            }
        }
        for (i, &(a, b, y)) in f.rows.iter().enumerate() {
            if i < self.series.len() {
                let _ = writeln!(
                    o,
                    r#"<path d="M{} {}H{}" fill="none" stroke="{}" stroke-width="{}"{}/>"#,
                    num(a),
                    num(y),
                    num(b),
                    rgb(PALETTE[i % PALETTE.len()]),
                    num(CURVE_PX * s),
                    dash_attr(i, s)
                );
                o += &svg_marker((0.5 * (a + b), y), i, s);
            } else {
                let _ = writeln!(
                    o,
                    r#"<path d="M{} {}H{}" fill="none" stroke="{grey}" stroke-width="{}"{}/>"#,
                    num(a),
                    num(y),
                    num(b),
                    num(1.2 * s),
                    reference_dash_attr(i - self.series.len(), s)
                );
            }
        }
        o
    }

    /// The distinct labels of the reference lines, in order: one legend
    /// row and one line style each.
    pub(super) fn hline_labels(&self) -> Vec<&str> {
        let mut v: Vec<&str> = Vec::new();
        for (label, _) in &self.hlines {
            if !v.contains(&label.as_str()) {
                v.push(label);
            }
        }
        v
    }

    /// The index of `label` among [`Figure::hline_labels`].
    pub(super) fn hline_group(&self, label: &str) -> usize {
        self.hline_labels()
            .iter()
            .position(|l| *l == label)
            .unwrap_or(0)
    }

    /// Curves in drawing order: largest amplitude first, so that no curve
    /// hides behind one of larger excursion (the legend keeps the given order).
    pub(super) fn draw_order(&self) -> Vec<usize> {
        let amp = |c: &Series| {
            c.y.iter()
                .filter_map(|&y| self.plotted(y))
                .fold(f64::MIN, |a, y| a.max(if self.log_y { y } else { y.abs() }))
        };
        let mut order: Vec<usize> = (0..self.series.len()).collect();
        order.sort_by(|&a, &b| amp(&self.series[b]).total_cmp(&amp(&self.series[a])));
        order
    }

    /// The plotted points of one curve in axis coordinates, as the runs of
    /// consecutive plotted samples: a sample that is not plotted (see
    /// [`Figure::plotted`]; or a non-finite abscissa) ends a piece.
    pub(super) fn pieces(&self, c: &Series) -> Vec<Vec<(f64, f64)>> {
        let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
        let mut cur: Vec<(f64, f64)> = Vec::new();
        for (&x, &y) in c.x.iter().zip(&c.y) {
            match self.plotted(y).filter(|_| x.is_finite()) {
                Some(v) => cur.push((x, v)),
                None => {
                    if !cur.is_empty() {
                        out.push(std::mem::take(&mut cur));
                    }
                }
            }
        }
        if !cur.is_empty() {
            out.push(cur);
        }
        out
    }
}

/// Colour of reference lines.
pub(super) const REFERENCE: RGBColor = RGBColor(0x66, 0x66, 0x66);

/// Style of reference lines at scale `s`.
pub(super) fn reference_style(s: f64) -> ShapeStyle {
    REFERENCE.stroke_width((1.2 * s).max(1.0) as u32)
}

/// Dash `i` of the cycle solid, `dashed`, `dotted` (each `(on, off)`),
/// scaled by `s`; `None` when solid.
fn cycle_dash(i: usize, s: f64, [dashed, dotted]: [(f64, f64); 2]) -> Option<(f64, f64)> {
    match i % 3 {
        0 => None,
        1 => Some((dashed.0 * s, dashed.1 * s)),
        _ => Some((dotted.0 * s, dotted.1 * s)),
    }
}

/// The SVG `stroke-dasharray` attribute of a dash ("" when solid).
fn dash_attribute(dash: Option<(f64, f64)>) -> String {
    dash.map_or(String::new(), |(on, off)| {
        format!(r#" stroke-dasharray="{} {}""#, num(on), num(off))
    })
}

/// Dash pattern of the reference lines of group `g`: solid, dashed,
/// dotted in turn.
pub(super) fn reference_dash(g: usize, s: f64) -> Option<(f64, f64)> {
    cycle_dash(g, s, [(5.0, 3.0), (1.2, 2.4)])
}

/// The SVG `stroke-dasharray` attribute of reference group `g`.
pub(super) fn reference_dash_attr(g: usize, s: f64) -> String {
    dash_attribute(reference_dash(g, s))
}

/// `#RRGGBB`.
pub(super) fn rgb(c: RGBColor) -> String {
    format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
}

/// A coordinate for SVG: two decimals (1/100 of a user unit), trailing
/// zeros dropped.
pub(super) fn num(v: f64) -> String {
    let t = format!("{v:.2}");
    let t = t.trim_end_matches('0').trim_end_matches('.');
    if t == "-0" {
        "0".into()
    } else {
        t.to_string()
    }
}

/// `1e-9` as 10⁻⁹, other values as `1.5e-9`.
pub(super) fn number_text(v: f64) -> String {
    let n = v.log10().round();
    if (v - 10f64.powf(n)).abs() <= 1e-12 * v {
        decade(n as i32)
    } else {
        format!("{v:.3e}")
    }
}

/// Line style of curve `i`: solid, dashed, dotted in turn.
pub(super) fn dash(i: usize, s: f64) -> Option<(f64, f64)> {
    cycle_dash(i, s, [(6.0, 3.5), (1.6, 2.6)])
}

/// The SVG `stroke-dasharray` attribute of curve `i` ("" when solid).
pub(super) fn dash_attr(i: usize, s: f64) -> String {
    dash_attribute(dash(i, s))
}

/// The sparse markers of curve `i` among its points (phase shifted per
/// curve so that coinciding curves show every marker).
pub(super) fn markers(pts: &[(f64, f64)], i: usize) -> Vec<(f64, f64)> {
    if pts.len() > 2 * MARKERS {
        let stride = pts.len() / MARKERS;
        let phase = (i * stride / PALETTE.len().max(1)) % stride;
        pts.iter().skip(phase).step_by(stride).copied().collect()
    } else {
        pts.to_vec()
    }
}

/// Marker radius \[CSS px\].
pub(super) const MARKER_PX: f64 = 2.6;

/// The marker of curve `i` at pixel `(x, y)` as an SVG element: circle,
/// triangle, square, cross in turn.
pub(super) fn svg_marker((x, y): (f64, f64), i: usize, s: f64) -> String {
    let c = rgb(PALETTE[i % PALETTE.len()]);
    let r = MARKER_PX * s;
    let sw = num(CURVE_PX * s);
    match i % 4 {
        0 => format!(
            "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"{sw}\"/>\n",
            num(x),
            num(y),
            num(r)
        ),
        1 => {
            let t = r + s;
            let (dx, dy) = (t * 0.866_025_403_784_438_6, 0.5 * t);
            format!(
                "<path d=\"M{} {}L{} {}L{} {}Z\" fill=\"{c}\" stroke=\"{c}\" stroke-width=\"{sw}\"/>\n",
                num(x),
                num(y - t),
                num(x + dx),
                num(y + dy),
                num(x - dx),
                num(y + dy)
            )
        }
        2 => format!(
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"{sw}\"/>\n",
            num(x - r),
            num(y - r),
            num(2.0 * r),
            num(2.0 * r)
        ),
        _ => format!(
            "<path d=\"M{} {}L{} {}M{} {}L{} {}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"{sw}\"/>\n",
            num(x - r),
            num(y - r),
            num(x + r),
            num(y + r),
            num(x - r),
            num(y + r),
            num(x + r),
            num(y - r)
        ),
    }
}

/// Draw one curve (bitmaps) with its line style, its one-sample pieces as
/// dots, and sparse markers.
pub(super) fn draw_curve<DB, X, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
    pieces: Vec<Vec<(f64, f64)>>,
    i: usize,
    s: f64,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>>
where
    DB: DrawingBackend,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let style = curve_style(i, s);
    let marks = markers(&pieces.concat(), i);
    for p in pieces {
        if p.len() == 1 {
            chart.draw_series(std::iter::once(Circle::new(
                p[0],
                (DOT_PX * s) as i32,
                style.filled(),
            )))?;
            continue;
        }
        match dash(i, s) {
            None => {
                chart.draw_series(LineSeries::new(p, style))?;
            }
            Some((on, off)) => {
                chart.draw_series(DashedLineSeries::new(p, on as u32, off as u32, style))?;
            }
        }
    }
    let r = (MARKER_PX * s) as i32;
    match i % 4 {
        0 => chart.draw_series(marks.into_iter().map(|p| Circle::new(p, r, style)))?,
        1 => chart.draw_series(
            marks
                .into_iter()
                .map(|p| TriangleMarker::new(p, r + s as i32, style.filled())),
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

/// Stroke of curve `i` at scale `s` (bitmaps).
pub(super) fn curve_style(i: usize, s: f64) -> ShapeStyle {
    PALETTE[i % PALETTE.len()].stroke_width((CURVE_PX * s).round().max(1.0) as u32)
}

/// The legend's sample of curve `i` (bitmaps): its line style from `a` to
/// `b` (pixel coordinates of `area`) with its marker in the middle.
pub(super) fn draw_sample<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    a: (i32, i32),
    b: (i32, i32),
    i: usize,
    s: f64,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let style = curve_style(i, s);
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
    let r = (MARKER_PX * s) as i32;
    match i % 4 {
        0 => area.draw(&Circle::new(m, r, style))?,
        1 => area.draw(&TriangleMarker::new(m, r + s as i32, style.filled()))?,
        2 => area.draw(&Rectangle::new(
            [(m.0 - r, m.1 - r), (m.0 + r, m.1 + r)],
            style,
        ))?,
        _ => area.draw(&Cross::new(m, r, style))?,
    }
    Ok(())
}
