//! `mbsolve animate`: the motion of a run, as an animated SVG (SMIL, vector,
//! one key frame per output time), a GIF (one frame per drawn output time)
//! or a still PNG of one output time.
//!
//! Geometry comes from the scenario (loaded with the same `--set` overrides
//! as the run): each body is drawn as the polygon of its body-fixed joint
//! points (a rod segment of known width as its rectangle), joints as small
//! circles, ground pivots as triangles, a rod channel's walls as lines.
//! Positions come from the run's CSV, read by column name through
//! [`coordinate_columns`].

use crate::figure::extension;
use crate::plot::Table;
use mbsolve::model::{BodyRef, System};
use mbsolve::scenario;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What `mbsolve animate` was asked for.
pub struct AnimateArgs {
    /// Scenario file of the run.
    pub scenario: PathBuf,
    /// Overrides the run used.
    pub set: Vec<String>,
    /// The run's trajectory CSV.
    pub csv: PathBuf,
    /// Output: .svg (animated, SMIL) or .gif.
    pub out: PathBuf,
    /// Playback speed: simulated seconds per wall-clock second.
    pub speed: f64,
    /// Draw every k-th output time (GIF only; the SVG keeps every one).
    pub every: usize,
    /// PNG still: the output time nearest to this (default: the last).
    pub at: Option<f64>,
}

/// A body's outline in its own frame, and its joint points.
struct Shape {
    /// Outline (closed when it has ≥ 3 points).
    outline: Vec<[f64; 2]>,
    /// Joint points.
    joints: Vec<[f64; 2]>,
}

/// Everything drawn, in world units.
struct Scene {
    shapes: Vec<Shape>,
    ground_pivots: Vec<[f64; 2]>,
    walls: Vec<f64>,
    t: Vec<f64>,
    /// Per output time, (x, y, φ) of every body.
    poses: Vec<Vec<[f64; 3]>>,
    bounds: [f64; 4],
}

/// The CSV columns of body `b`'s coordinates (x, y, φ): the one place that
/// knows the trajectory CSV's column names.
pub fn coordinate_columns(b: usize) -> [String; 3] {
    [0, 1, 2].map(|k| System::coordinate_name(3 * b + k))
}

/// Write the animation; returns the path written.
pub fn animate(a: &AnimateArgs) -> Result<PathBuf, String> {
    if !(a.speed.is_finite() && a.speed > 0.0) {
        return Err(format!("--speed {}: must be finite and > 0", a.speed));
    }
    if a.every == 0 {
        return Err("--every 0: must be ≥ 1".into());
    }
    let ext = extension(&a.out);
    if !["svg", "gif", "png"].contains(&ext.as_str()) {
        return Err(format!(
            "--out {}: unknown animation format '{ext}': use .svg, .gif or .png (one still)",
            a.out.display()
        ));
    }
    let sc = scenario::load(&a.scenario, &a.set).map_err(|e| e.to_string())?;
    let scene = scene(&sc, &a.csv)?;
    match ext.as_str() {
        "svg" => write_svg(&scene, &a.out, a.speed)?,
        "gif" => write_gif(&scene, &a.out, a.speed, a.every)?,
        _ => write_png(&scene, &a.out, a.at)?,
    }
    Ok(a.out.clone())
}

/// Geometry from the scenario, poses from the CSV.
fn scene(sc: &scenario::Scenario, csv: &Path) -> Result<Scene, String> {
    let sys = &sc.system;
    let nb = sys.bodies().len();
    let mut joints: Vec<Vec<[f64; 2]>> = vec![Vec::new(); nb];
    let mut ground_pivots = Vec::new();
    for c in sys.constraints() {
        for (b, p) in c.geometry().attachment_points() {
            match b {
                BodyRef::Ground => ground_pivots.push(p),
                BodyRef::Body(i) => {
                    if !joints[i].iter().any(|q| dist(*q, p) < 1e-12) {
                        joints[i].push(p)
                    }
                }
            }
        }
    }
    let mut outlines: Vec<Option<Vec<[f64; 2]>>> = vec![None; nb];
    let mut walls = Vec::new();
    for (_, rod) in &sc.rods {
        for c in &rod.contacts {
            let (w, l) = (0.5 * c.width, 0.5 * c.length);
            outlines[c.body] = Some(vec![[-w, -l], [w, -l], [w, l], [-w, l]]);
            for x in [c.left_wall, c.right_wall] {
                if !walls.contains(&x) {
                    walls.push(x);
                }
            }
        }
    }
    let shapes: Vec<Shape> = (0..nb)
        .map(|i| {
            let js = joints[i].clone();
            let outline = outlines[i].take().unwrap_or_else(|| match js.len() {
                0 => vec![[0.0, 0.0]],
                1 => vec![[0.0, 0.0], js[0]],
                2 => js.clone(),
                _ => {
                    let mut p = js.clone();
                    let c = p.iter().fold([0.0, 0.0], |a, q| [a[0] + q[0], a[1] + q[1]]);
                    let c = [c[0] / p.len() as f64, c[1] / p.len() as f64];
                    p.sort_by(|a, b| {
                        (a[1] - c[1])
                            .atan2(a[0] - c[0])
                            .total_cmp(&(b[1] - c[1]).atan2(b[0] - c[0]))
                    });
                    p
                }
            });
            Shape {
                outline,
                joints: js,
            }
        })
        .collect();
    let table = Table::read(csv)?;
    let t = table.column(csv, "t")?.to_vec();
    let cols: Vec<[&[f64]; 3]> = (0..nb)
        .map(|b| {
            let [x, y, p] = coordinate_columns(b);
            Ok([
                table.column(csv, &x)?,
                table.column(csv, &y)?,
                table.column(csv, &p)?,
            ])
        })
        .collect::<Result<_, String>>()?;
    let mut poses = Vec::with_capacity(t.len());
    let mut bounds = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    let grow = |b: &mut [f64; 4], p: [f64; 2]| {
        b[0] = b[0].min(p[0]);
        b[1] = b[1].min(p[1]);
        b[2] = b[2].max(p[0]);
        b[3] = b[3].max(p[1]);
    };
    for k in 0..t.len() {
        let pose: Vec<[f64; 3]> = cols.iter().map(|c| [c[0][k], c[1][k], c[2][k]]).collect();
        if pose.iter().flatten().any(|v| !v.is_finite()) || !t[k].is_finite() {
            return Err(format!(
                "{}: row {}: a position is not a finite number",
                csv.display(),
                k + 2
            ));
        }
        for (s, q) in shapes.iter().zip(&pose) {
            for p in s.outline.iter().chain(&s.joints) {
                grow(&mut bounds, world(*q, *p));
            }
        }
        poses.push(pose);
    }
    if poses.is_empty() {
        return Err(format!("{}: no rows to animate", csv.display()));
    }
    for p in &ground_pivots {
        grow(&mut bounds, *p);
    }
    // Walls span the drawn height; they widen the box only horizontally.
    let bottom = bounds[1];
    for &x in &walls {
        grow(&mut bounds, [x, bottom]);
    }
    Ok(Scene {
        shapes,
        ground_pivots,
        walls,
        t,
        poses,
        bounds,
    })
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// r + R(φ) s.
fn world(q: [f64; 3], s: [f64; 2]) -> [f64; 2] {
    let (sn, cs) = q[2].sin_cos();
    [q[0] + cs * s[0] - sn * s[1], q[1] + sn * s[0] + cs * s[1]]
}

/// Map from world to pixels for a canvas of `size`: equal scales, y up,
/// 6 % margin; returns (scale, origin offset).
fn view(b: [f64; 4], size: (u32, u32)) -> (f64, [f64; 2]) {
    let (w, h) = (size.0 as f64, size.1 as f64);
    let span = [(b[2] - b[0]).max(1e-9), (b[3] - b[1]).max(1e-9)];
    let k = 0.88 * (w / span[0]).min(h / span[1]);
    let off = [
        0.5 * w - k * 0.5 * (b[0] + b[2]),
        0.5 * h + k * 0.5 * (b[1] + b[3]),
    ];
    (k, off)
}

/// Canvas size in pixels for a scene: 640 px on the long side.
fn canvas(b: [f64; 4]) -> (u32, u32) {
    let ar = ((b[3] - b[1]) / (b[2] - b[0]).max(1e-9)).clamp(0.25, 4.0);
    if ar <= 1.0 {
        (640, (640.0 * ar).max(240.0) as u32)
    } else {
        ((640.0 / ar).max(240.0) as u32, 640)
    }
}

/// The animated SVG: static ground and walls; per body a group whose
/// translation and rotation are animated (SMIL `animateTransform`, key
/// times = output times).
fn write_svg(s: &Scene, path: &Path, speed: f64) -> Result<(), String> {
    let size = canvas(s.bounds);
    let (k, off) = view(s.bounds, size);
    let (t0, t1) = (s.t[0], *s.t.last().unwrap_or(&s.t[0]));
    let dur = ((t1 - t0) / speed).max(1e-3);
    let key_times: String =
        s.t.iter()
            .map(|t| {
                if t1 > t0 {
                    format!("{:.6}", (t - t0) / (t1 - t0))
                } else {
                    "0".into()
                }
            })
            .collect::<Vec<_>>()
            .join(";");
    let px = |p: [f64; 2]| (off[0] + k * p[0], off[1] - k * p[1]);
    let mut o = String::new();
    let _ = writeln!(
        o,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" viewBox="0 0 {} {}">"#,
        size.0, size.1, size.0, size.1
    );
    let _ = writeln!(
        o,
        r#"<rect width="100%" height="100%" fill="white"/>
<text x="8" y="18" font-family="sans-serif" font-size="13">t = {t0:.3} … {t1:.3} s ({} frames, {speed}× real time)</text>"#,
        s.t.len()
    );
    for &x in &s.walls {
        let (a, _) = px([x, 0.0]);
        let _ = writeln!(
            o,
            r##"<line x1="{a:.2}" y1="0" x2="{a:.2}" y2="{}" stroke="#555" stroke-width="2"/>"##,
            size.1
        );
    }
    for p in &s.ground_pivots {
        let (a, b) = px(*p);
        let _ = writeln!(
            o,
            r##"<path d="M{a:.2},{b:.2} l-6,10 h12 z" fill="#bbb" stroke="black"/>"##
        );
    }
    // Bodies: drawn in their own frame, scaled to pixels and y flipped.
    for (i, sh) in s.shapes.iter().enumerate() {
        let tr: String = s
            .poses
            .iter()
            .map(|q| {
                let (a, b) = px([q[i][0], q[i][1]]);
                format!("{a:.3},{b:.3}")
            })
            .collect::<Vec<_>>()
            .join(";");
        let rot: String = s
            .poses
            .iter()
            .map(|q| format!("{:.4}", -q[i][2].to_degrees()))
            .collect::<Vec<_>>()
            .join(";");
        let pts: String = sh
            .outline
            .iter()
            .map(|p| format!("{:.3},{:.3}", k * p[0], -k * p[1]))
            .collect::<Vec<_>>()
            .join(" ");
        let shape = if sh.outline.len() >= 3 {
            format!(
                r##"<polygon points="{pts}" fill="#56B4E9" fill-opacity="0.5" stroke="#0072B2" stroke-width="2"/>"##
            )
        } else if sh.outline.len() == 2 {
            format!(
                r##"<polyline points="{pts}" fill="none" stroke="#0072B2" stroke-width="4" stroke-linecap="round"/>"##
            )
        } else {
            r##"<circle r="4" fill="#0072B2"/>"##.to_string()
        };
        let _ = writeln!(
            o,
            r#"<g transform="translate({tr0})"><animateTransform attributeName="transform" type="translate" values="{tr}" keyTimes="{key_times}" dur="{dur}s" repeatCount="indefinite"/>
<g transform="rotate({rot0})"><animateTransform attributeName="transform" type="rotate" values="{rot}" keyTimes="{key_times}" dur="{dur}s" repeatCount="indefinite"/>
{shape}"#,
            // the first frame as the static pose: what a renderer without
            // SMIL animation (and the print) shows
            tr0 = tr.split(';').next().unwrap_or("0,0").replace(',', " "),
            rot0 = rot.split(';').next().unwrap_or("0"),
        );
        for j in &sh.joints {
            let _ = writeln!(
                o,
                r##"<circle cx="{:.3}" cy="{:.3}" r="3.5" fill="white" stroke="black" stroke-width="1.5"/>"##,
                k * j[0],
                -k * j[1]
            );
        }
        let _ = writeln!(o, "</g></g>");
    }
    let _ = writeln!(o, "</svg>");
    std::fs::write(path, o).map_err(|e| format!("{}: {e}", path.display()))
}

/// The GIF: every `every`-th output time as a frame, frame delay from the
/// output spacing and `speed`.
fn write_gif(s: &Scene, path: &Path, speed: f64, every: usize) -> Result<(), String> {
    crate::figure::register_font();
    let size = canvas(s.bounds);
    let n = s.t.len();
    let dt = if n > 1 {
        (s.t[n - 1] - s.t[0]) / (n - 1) as f64
    } else {
        0.0
    };
    let delay_ms = ((every as f64 * dt / speed) * 1000.0).clamp(20.0, 10_000.0) as u32;
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let root = BitMapBackend::gif(path, size, delay_ms)
        .map_err(|e| err(&e))?
        .into_drawing_area();
    for f in (0..n).step_by(every) {
        draw_frame(&root, s, f).map_err(|e| err(&e))?;
    }
    Ok(())
}

/// A still PNG of the output time nearest to `at` (default: the last).
fn write_png(s: &Scene, path: &Path, at: Option<f64>) -> Result<(), String> {
    crate::figure::register_font();
    let f = match at {
        None => s.t.len() - 1,
        Some(t) => (0..s.t.len())
            .min_by(|&a, &b| (s.t[a] - t).abs().total_cmp(&(s.t[b] - t).abs()))
            .unwrap_or(0),
    };
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let root = BitMapBackend::new(path, canvas(s.bounds)).into_drawing_area();
    draw_frame(&root, s, f).map_err(|e| err(&e))
}

/// Draw output time `f` of the scene and present it (one GIF frame).
fn draw_frame<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    s: &Scene,
    f: usize,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let size = root.dim_in_pixel();
    let (k, off) = view(s.bounds, size);
    let px = |p: [f64; 2]| {
        (
            (off[0] + k * p[0]).round() as i32,
            (off[1] - k * p[1]).round() as i32,
        )
    };
    let body = RGBColor(0x00, 0x72, 0xB2);
    let fill = RGBColor(0x56, 0xB4, 0xE9).mix(0.5);
    root.fill(&WHITE)?;
    for &x in &s.walls {
        let (a, _) = px([x, 0.0]);
        root.draw(&PathElement::new(
            vec![(a, 0), (a, size.1 as i32)],
            RGBColor(0x55, 0x55, 0x55).stroke_width(2),
        ))?;
    }
    for p in &s.ground_pivots {
        let (a, b) = px(*p);
        root.draw(&Polygon::new(
            vec![(a, b), (a - 6, b + 10), (a + 6, b + 10)],
            RGBColor(0xbb, 0xbb, 0xbb).filled(),
        ))?;
    }
    for (sh, q) in s.shapes.iter().zip(&s.poses[f]) {
        let pts: Vec<(i32, i32)> = sh.outline.iter().map(|p| px(world(*q, *p))).collect();
        if pts.len() >= 3 {
            root.draw(&Polygon::new(pts.clone(), fill.filled()))?;
            let mut closed = pts.clone();
            closed.push(pts[0]);
            root.draw(&PathElement::new(closed, body.stroke_width(2)))?;
        } else if pts.len() == 2 {
            root.draw(&PathElement::new(pts, body.stroke_width(4)))?;
        } else {
            root.draw(&Circle::new(pts[0], 4, body.filled()))?;
        }
        for j in &sh.joints {
            let c = px(world(*q, *j));
            root.draw(&Circle::new(c, 4, WHITE.filled()))?;
            root.draw(&Circle::new(c, 4, BLACK.stroke_width(1)))?;
        }
    }
    root.draw(&Text::new(
        format!("t = {:.3} s", s.t[f]),
        (8, 8),
        ("sans-serif", 14.0).into_font(),
    ))?;
    root.present()
}
