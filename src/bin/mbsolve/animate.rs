//! `mbsolve animate`: the motion of a run, as an animated SVG (SMIL), a GIF,
//! an APNG (full colour, no external tool), an MP4/WebM (through `ffmpeg`
//! on the PATH; without it the command says so and names the other
//! formats) or a still PNG of one output time.
//!
//! What is drawn is the library's drawing model ([`mbsolve::drawing`]):
//! bodies as their shapes, joints, guides, springs, dampers, contacts and
//! walls, with a time stamp and a scale bar; with `--forces`, arrows of
//! the contact forces and joint reactions ([`mbsolve::drawing::arrows`])
//! and their key. Positions come from the run's CSV, read by column name
//! (`B.x, B.y, B.phi`, or the positional `x1, y1, phi1` of earlier
//! versions); velocities (for the forces) from its `B.vx, B.vy, B.omega`
//! columns, or zero when the run did not write them; joint reactions from
//! its `J.fx, J.fy, J.mz` columns where it wrote them, else computed from
//! the state.
//!
//! Time is honest: each frame shows the output row at its wall-clock time
//! `(t − t₀)/speed`; rows are skipped so that no frame lasts less than the
//! format allows (GIF: 20 ms, browsers slow shorter delays down), and the
//! delays are rounded cumulatively to the format's tick (GIF: 10 ms), so
//! the whole plays in `(t_end − t₀)/speed`.
//!
//! Here: the arguments, the scene (drawing, poses, arrows) and the frame
//! schedule; the raster formats in `raster.rs`, the SVG in `svg.rs`.

use crate::figure::extension;
use crate::plot::Table;
use mbsolve::drawing::arrows::{self, Arrow, ArrowKey, ArrowSet, ForceArrows};
use mbsolve::drawing::{self, BodyShape, Drawing, Ink, Mark};
use mbsolve::model::System;
use mbsolve::output::{POSITION, VELOCITY};
use mbsolve::scenario;
use plotters::prelude::*;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

mod raster;
mod svg;

/// What `mbsolve animate` was asked for.
pub struct AnimateArgs {
    /// Scenario file of the run.
    pub scenario: PathBuf,
    /// Overrides the run used.
    pub set: Vec<String>,
    /// The run's trajectory CSV.
    pub csv: PathBuf,
    /// Output: .svg (animated, SMIL), .gif, .apng, .mp4, .webm or .png
    /// (still).
    pub out: PathBuf,
    /// Playback speed: simulated seconds per wall-clock second.
    pub speed: f64,
    /// Show at most every k-th output row (1: as many as the format allows).
    pub every: usize,
    /// PNG still: the output time nearest to this (default: the last).
    pub at: Option<f64>,
    /// Force arrows drawn (default: none).
    pub forces: ArrowSet,
}

/// A drawing and the motion it shows.
pub struct Scene {
    /// The drawing model, fitted to the motion.
    pub drawing: Drawing,
    /// Output times \[s\].
    pub t: Vec<f64>,
    /// Per output time, (x, y, φ) of every body, flattened.
    pub poses: Vec<Vec<f64>>,
    /// Canvas size in pixels.
    pub size: (u32, u32),
    /// Text and reference pose drawn on every frame ([`Annotation`]).
    pub note: Annotation,
    /// Force arrows per output time and their key; `None`: none drawn.
    pub arrows: Option<SceneArrows>,
}

/// The force arrows of a scene ([`add_arrows`]).
#[derive(Debug, Clone)]
pub struct SceneArrows {
    /// Per output time, the arrows that act at some time (the same ones,
    /// in the same order, at every time).
    pub rows: Vec<Vec<Arrow>>,
    /// Scale and key.
    pub key: ArrowKey,
    /// Arrow head length \[m\].
    pub head: f64,
}

impl SceneArrows {
    /// The marks of the arrows of output row `f`.
    pub fn marks(&self, f: usize) -> Vec<Mark> {
        arrows::marks(&self.rows[f], &self.key, self.head)
    }
}

/// Compute the arrows of `set` for every row of the scene from the table
/// (positions, and velocities when it has them), scale them so that the
/// largest is a quarter of the model's size, and grow the drawn box to
/// hold them when `grow` says so. Arrows that are zero at every output
/// time are left out. Returns a note when the velocities are missing.
pub fn add_arrows(
    scene: &mut Scene,
    sc: &scenario::Scenario,
    table: &Table,
    set: ArrowSet,
    grow: bool,
) -> Result<Option<String>, String> {
    if set == ArrowSet::default() {
        return Ok(None);
    }
    let sys = &sc.system;
    let nb = sys.bodies().len();
    let rod_contacts: Vec<_> = sc
        .rods
        .iter()
        .flat_map(|(_, r)| r.contacts.iter().cloned())
        .collect();
    let mut fa = ForceArrows::new(sys, set, &rod_contacts)?;
    let labels = mbsolve::output::body_labels(sys);
    let vel: Option<Vec<[&[f64]; 3]>> = (0..nb)
        .map(|b| body_columns(table, &labels, b, VELOCITY))
        .collect();
    let given = if set.reactions {
        reaction_columns(table, sys)
    } else {
        None
    };
    // controller states: z is the velocity of its coordinate (after the
    // bodies'), read from its column; the coordinate itself (∫z) enters
    // no force, so it is held at 0
    let states: Option<Vec<&[f64]>> = sys
        .states()
        .iter()
        .map(|s| table.find(&s.name).map(|k| table.columns[k].as_slice()))
        .collect();
    let mut q_all = vec![0.0; sys.n_coords()];
    let mut rows = Vec::with_capacity(scene.t.len());
    let zero = vec![0.0; 3 * nb];
    let mut r_row = vec![0.0; 3 * sys.constraints().len()];
    let mut from_columns = 0;
    for (r, q) in scene.poses.iter().enumerate() {
        let qd: Vec<f64> = match &vel {
            Some(v) => v.iter().flat_map(|c| [c[0][r], c[1][r], c[2][r]]).collect(),
            None => zero.clone(),
        };
        let mut qd = if qd.iter().all(|v| v.is_finite()) {
            qd
        } else {
            zero.clone()
        };
        qd.extend(sys.states().iter().enumerate().map(|(k, s)| {
            states
                .as_ref()
                .map(|c| c[k][r])
                .filter(|z| z.is_finite())
                .unwrap_or(s.initial)
        }));
        q_all[..3 * nb].copy_from_slice(q);
        // the run's reactions where it wrote them (finite) for this row
        let reactions = given.as_ref().and_then(|cols| {
            for (k, c) in cols.iter().enumerate() {
                let v = c.map_or([0.0; 3], |c| [c[0][r], c[1][r], c[2][r]]);
                r_row[3 * k..3 * k + 3].copy_from_slice(&v);
            }
            r_row.iter().all(|v| v.is_finite()).then_some(&r_row[..])
        });
        from_columns += usize::from(reactions.is_some());
        rows.push(
            fa.at_with_reactions(scene.t[r], &q_all, &qd, reactions)
                .map_err(|e| format!("force arrows at t = {}: {e}", scene.t[r]))?,
        );
    }
    // keep the arrows that act at some time
    let n = rows.first().map_or(0, Vec::len);
    let acts: Vec<bool> = (0..n)
        .map(|j| rows.iter().any(|a| a[j].force != [0.0, 0.0]))
        .collect();
    for a in &mut rows {
        let mut j = 0;
        a.retain(|_| {
            j += 1;
            acts[j - 1]
        });
    }
    let max = rows
        .iter()
        .map(|a| arrows::max_force(a))
        .fold(0.0, f64::max);
    let Some(key) = ArrowKey::new(max, 0.25 * scene.drawing.scale) else {
        return Ok(Some(
            "force arrows: no contact force or reaction acts at any output time".into(),
        ));
    };
    let b = &mut scene.drawing.bounds;
    for a in rows.iter().flatten().filter(|_| grow) {
        for p in [
            a.at,
            [
                a.at[0] + key.metres_per_newton * a.force[0],
                a.at[1] + key.metres_per_newton * a.force[1],
            ],
        ] {
            if p.iter().all(|v| v.is_finite()) {
                b[0] = b[0].min(p[0]);
                b[1] = b[1].min(p[1]);
                b[2] = b[2].max(p[0]);
                b[3] = b[3].max(p[1]);
            }
        }
    }
    if grow {
        scene.size = canvas(scene.drawing.bounds);
    }
    scene.arrows = Some(SceneArrows {
        rows,
        key,
        head: 0.03 * scene.drawing.scale,
    });
    let mut notes = Vec::new();
    if vel.is_none() {
        notes.push(
            "force arrows: the CSV has no velocity columns (output.quantities = \
             [\"velocities\"]): forces computed at zero velocity"
                .to_string(),
        );
    }
    if states.is_none() {
        notes.push(
            "force arrows: the CSV lacks a controller state's column: forces computed with \
             the states at their initial values"
                .to_string(),
        );
    }
    if set.reactions && sys.n_constraints() > 0 {
        let n = scene.t.len();
        notes.push(if from_columns == n {
            "force arrows: joint reactions from the run's columns (J.fx, J.fy)".to_string()
        } else if from_columns > 0 {
            format!(
                "force arrows: joint reactions from the run's columns at {from_columns} of {n} \
                 output times, computed from the state (eq. (5) without Baumgarte terms) at \
                 the others (values not finite)"
            )
        } else {
            "force arrows: joint reactions computed from the state (eq. (5) without \
             Baumgarte terms): the run wrote no reaction columns (output.quantities = \
             [\"reactions\"])"
                .to_string()
        });
    }
    Ok((!notes.is_empty()).then(|| notes.join("\n")))
}

/// The columns of body `b`'s three quantities `names` (e.g.
/// [`mbsolve::output::POSITION`]): the named `B.x, B.y, B.phi` (`labels`:
/// [`mbsolve::output::body_labels`]), or in a table of earlier versions the
/// positional `x1, y1, phi1`; `None` when one is missing.
fn body_columns<'t>(
    table: &'t Table,
    labels: &[String],
    b: usize,
    names: [&str; 3],
) -> Option<[&'t [f64]; 3]> {
    // the positional name only where the table has it as its own header
    // (not read through another model's names: x1 of a four-bar's table
    // is its crank, not this model's first body)
    let col = |n: &str| {
        let old = format!("{n}{}", b + 1);
        table
            .find(&format!("{}.{n}", labels[b]))
            .or_else(|| table.names.iter().position(|h| *h == old))
            .map(|k| table.columns[k].as_slice())
    };
    Some([col(names[0])?, col(names[1])?, col(names[2])?])
}

/// Per constraint, the run's reaction columns `J.fx, J.fy, J.mz` on its
/// body ([`mbsolve::output::columns`]; `None` for a constraint that acts
/// on no body); joints sharing a label are matched to that label's
/// columns in order. `None` unless every joint on a body has them.
fn reaction_columns<'t>(table: &'t Table, sys: &System) -> Option<Vec<Option<[&'t [f64]; 3]>>> {
    let map = sys.reaction_map();
    let mut seen = std::collections::HashMap::<String, usize>::new();
    (0..sys.constraints().len())
        .map(|k| {
            let label = mbsolve::output::joint_label(sys, k);
            let nth = seen.entry(label.clone()).or_insert(0);
            let n = *nth;
            *nth += 1;
            if map.body(k).is_none() {
                return Some(None);
            }
            let col = |c: &str| {
                let name = format!("{label}.{c}");
                table
                    .names
                    .iter()
                    .enumerate()
                    .filter(|(_, h)| **h == name)
                    .nth(n)
                    .map(|(i, _)| table.columns[i].as_slice())
            };
            Some(Some([col("fx")?, col("fy")?, col("mz")?]))
        })
        .collect()
}

/// What a frame shows besides the motion (default: nothing).
#[derive(Debug, Clone, Default)]
pub struct Annotation {
    /// A line under the time stamp (e.g. a mode's frequency); empty: none.
    pub caption: String,
    /// A pose (x, y, φ per body) drawn faded under the motion, e.g. the
    /// equilibrium a mode oscillates about; `None`: none.
    pub ghost: Option<Vec<f64>>,
    /// The table was made here (a mode's motion), not written by a run:
    /// no notes on which columns the run wrote.
    pub synthetic: bool,
}

/// The named position columns of every body (`B.x, B.y, B.phi`, as a
/// run writes them: [`mbsolve::output::columns`]), for tables made here
/// (the mode animations).
pub fn coordinate_columns(sys: &System) -> Vec<[String; 3]> {
    mbsolve::output::body_labels(sys)
        .iter()
        .map(|b| POSITION.map(|c| format!("{b}.{c}")))
        .collect()
}

/// Shortest frame the GIF format plays as written \[s\] (browsers slow
/// shorter delays down to 100 ms).
pub const GIF_MIN_DELAY: f64 = 0.02;
/// GIF delay tick \[s\].
const GIF_TICK: f64 = 0.01;
/// Frame interval of MP4/WebM and of the SVG key frames at most \[s\].
const VIDEO_MIN_DELAY: f64 = 0.02;
const SVG_MIN_DELAY: f64 = 0.01;

/// Write the animation; returns the path written.
pub fn animate(a: &AnimateArgs) -> Result<PathBuf, String> {
    animate_annotated(a, Annotation::default())
}

/// [`animate`] with a caption and a reference pose on every frame.
pub fn animate_annotated(a: &AnimateArgs, note: Annotation) -> Result<PathBuf, String> {
    if !(a.speed.is_finite() && a.speed > 0.0) {
        return Err(format!("--speed {}: must be finite and > 0", a.speed));
    }
    if a.every == 0 {
        return Err("--every 0: must be ≥ 1".into());
    }
    let ext = extension(&a.out);
    if !["svg", "gif", "apng", "png", "mp4", "webm"].contains(&ext.as_str()) {
        return Err(format!(
            "--out {}: unknown animation format '{ext}': use .svg, .gif, .apng, .mp4, .webm or .png (one still)",
            a.out.display()
        ));
    }
    let sc = scenario::load(&a.scenario, &a.set).map_err(|e| e.to_string())?;
    let table = Table::read(&a.csv)?;
    let mut scene = scene(&sc, &table, &a.csv)?;
    if let Some(n) = add_arrows(&mut scene, &sc, &table, a.forces, true)
        .map_err(|e| format!("{}: {e}", a.csv.display()))?
        .filter(|_| !note.synthetic)
    {
        println!("{n}");
    }
    if let Some(g) = &note.ghost {
        if g.len() != scene.poses[0].len() || g.iter().any(|v| !v.is_finite()) {
            return Err(format!(
                "{}: the reference pose has {} finite entries, the model {} coordinates",
                a.csv.display(),
                g.len(),
                scene.poses[0].len()
            ));
        }
    }
    scene.note = note;
    match ext.as_str() {
        "svg" => svg::write_svg(&scene, &a.out, a.speed, a.every)?,
        "gif" => raster::write_gif(&scene, &a.out, a.speed, a.every)?,
        "apng" => raster::write_apng(&scene, &a.out, a.speed, a.every)?,
        "mp4" | "webm" => raster::write_video(&scene, &a.out, a.speed, a.every)?,
        _ => raster::write_png(&scene, &a.out, a.at)?,
    }
    Ok(a.out.clone())
}

/// The drawing of the scenario (rod segments as their rectangles, the
/// channel walls), fitted to the poses of the table.
pub fn scene(sc: &scenario::Scenario, table: &Table, csv: &Path) -> Result<Scene, String> {
    let sys = &sc.system;
    let nb = sys.bodies().len();
    let mut shapes: Vec<Option<BodyShape>> = sc.shapes.clone();
    shapes.resize(nb, None);
    let mut walls = Vec::new();
    for (_, rod) in &sc.rods {
        for c in &rod.contacts {
            shapes[c.body] = Some(BodyShape::Box([c.width, c.length]));
            for x in [c.left_wall, c.right_wall] {
                if !walls.contains(&x) {
                    walls.push(x);
                }
            }
        }
    }
    let mut d = Drawing::new(sys, &sc.q0, &shapes, &walls);
    let t = table.column(csv, "t")?.to_vec();
    let labels = mbsolve::output::body_labels(sys);
    let cols: Vec<[&[f64]; 3]> = (0..nb)
        .map(|b| {
            body_columns(table, &labels, b, POSITION).ok_or_else(|| {
                // the error names the missing named column
                POSITION
                    .iter()
                    .map(|c| table.column(csv, &format!("{}.{c}", labels[b])))
                    .find_map(Result::err)
                    .unwrap_or_default()
            })
        })
        .collect::<Result<_, String>>()?;
    let mut poses = Vec::with_capacity(t.len());
    for k in 0..t.len() {
        let pose: Vec<f64> = cols
            .iter()
            .flat_map(|c| [c[0][k], c[1][k], c[2][k]])
            .collect();
        if pose.iter().any(|v| !v.is_finite()) || !t[k].is_finite() {
            return Err(format!(
                "{}: row {}: a time or position is not a finite number",
                csv.display(),
                k + 2
            ));
        }
        poses.push(pose);
    }
    if poses.is_empty() {
        return Err(format!("{}: no rows to animate", csv.display()));
    }
    if t.windows(2).any(|w| w[1] < w[0]) {
        return Err(format!("{}: the times t decrease", csv.display()));
    }
    d.fit(poses.iter().map(|p| p.as_slice()));
    let size = canvas(d.bounds);
    Ok(Scene {
        drawing: d,
        t,
        poses,
        size,
        note: Annotation::default(),
        arrows: None,
    })
}

/// Canvas size in pixels for a world box: 640 px on the long side, at
/// least 360 px on the short one (a tall rod in its channel keeps room
/// beside it for the time stamp and the scale bar).
pub fn canvas(b: [f64; 4]) -> (u32, u32) {
    let ar = ((b[3] - b[1]) / (b[2] - b[0]).max(1e-9)).clamp(0.25, 4.0);
    if ar <= 1.0 {
        (640, (640.0 * ar).max(360.0) as u32)
    } else {
        ((640.0 / ar).max(360.0) as u32, 640)
    }
}

/// Which output rows to show and how long each lasts, in ticks of `tick`
/// seconds: the first row, then the first row at least `every` rows and
/// `min_delay` of wall-clock time (`Δt/speed`) after the last one shown;
/// each delay is the difference of the rounded wall-clock times of the
/// two rows (so the rounding never accumulates), the last frame's the
/// typical one.
pub fn schedule(
    t: &[f64],
    speed: f64,
    min_delay: f64,
    every: usize,
    tick: f64,
) -> (Vec<usize>, Vec<u32>) {
    let wall = |r: usize| (t[r] - t[0]) / speed;
    let mut rows = vec![0];
    let mut r = 0;
    loop {
        let last = *rows.last().unwrap_or(&0);
        r = (r + 1).max(last + every);
        while r < t.len() && wall(r) - wall(last) < min_delay * (1.0 - 1e-9) {
            r += 1;
        }
        if r >= t.len() {
            break;
        }
        rows.push(r);
    }
    let ticks = |r: usize| (wall(r) / tick).round() as i64;
    let min_ticks = (min_delay / tick).round().max(1.0) as u32;
    let mut delays: Vec<u32> = rows
        .windows(2)
        .map(|w| (ticks(w[1]) - ticks(w[0])).max(min_ticks as i64) as u32)
        .collect();
    let typical = if delays.is_empty() {
        min_ticks
    } else {
        let mut d = delays.clone();
        d.sort_unstable();
        d[d.len() / 2]
    };
    delays.push(typical);
    (rows, delays)
}

/// Tell the user what plays at which speed.
fn report_schedule(s: &Scene, rows: &[usize], delays: &[u32], tick: f64, speed: f64, what: &str) {
    let span = s.t[s.t.len() - 1] - s.t[0];
    let total: f64 = delays.iter().map(|&d| d as f64 * tick).sum();
    let min = delays.iter().copied().min().unwrap_or(0) as f64 * tick;
    let stride = if rows.len() > 1 {
        (rows[rows.len() - 1] - rows[0]) as f64 / (rows.len() - 1) as f64
    } else {
        1.0
    };
    println!(
        "{what}: {} of {} output rows shown (every {:.3}th on average), frames of ≥ {:.0} ms; \
         {:.3} s of simulation at {speed}× real time play in {:.2} s",
        rows.len(),
        s.t.len(),
        stride,
        min * 1000.0,
        span,
        total
    );
}

/// Pixel map of a scene's canvas.
fn pixel_map(s: &Scene, size: (u32, u32)) -> (f64, [f64; 2]) {
    drawing::view(s.drawing.bounds, (size.0 as f64, size.1 as f64))
}

/// Colours of the inks (shared with `assets/viewer.js`).
fn ink_rgb(ink: Ink) -> RGBColor {
    match ink {
        Ink::Body => RGBColor(0x00, 0x72, 0xB2),
        Ink::Ground => RGBColor(0x44, 0x44, 0x44),
        Ink::Hatch => RGBColor(0x88, 0x88, 0x88),
        Ink::Spring => RGBColor(0xD5, 0x5E, 0x00),
        Ink::Damper => RGBColor(0x00, 0x9E, 0x73),
        Ink::Contact => RGBColor(0xCC, 0x79, 0xA7),
        Ink::Reaction => RGBColor(0xE6, 0x9F, 0x00),
    }
}

fn ink_hex(ink: Ink) -> String {
    let c = ink_rgb(ink);
    format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
}

fn ink_width(ink: Ink) -> u32 {
    match ink {
        Ink::Hatch => 1,
        _ => 2,
    }
}

/// The key's arrow in pixels (from, to, pointing right, 12 px above the
/// bottom, ending 12 px from the right edge) and its label.
pub fn key_geometry(a: &SceneArrows, k: f64, size: (u32, u32)) -> ([f64; 2], [f64; 2], String) {
    let len = a.key.key_length() * k;
    let y = size.1 as f64 - 12.0;
    let x1 = size.0 as f64 - 12.0;
    ([x1 - len, y], [x1, y], a.key.label())
}

/// The key's head length in pixels (the arrows' own, at most 40 % of it).
fn key_head(a: &SceneArrows, k: f64) -> f64 {
    (a.head * k).min(0.4 * a.key.key_length() * k)
}

/// The scale bar's length \[m\] (at most a fifth of the width) and label.
pub fn scale_bar(k: f64, width: f64) -> (f64, String) {
    let l = drawing::scale_bar(0.2 * width / k);
    let label = if l >= 1.0 {
        format!("{l} m")
    } else if l >= 1e-3 {
        format!("{} mm", (l * 1e3 * 1e6).round() / 1e6)
    } else {
        format!("{l:e} m")
    };
    (l, label)
}

/// The row whose time is nearest to `at` (default: the last row).
pub fn nearest_row(t: &[f64], at: Option<f64>) -> usize {
    match at {
        None => t.len() - 1,
        Some(x) => (0..t.len())
            .min_by(|&a, &b| (t[a] - x).abs().total_cmp(&(t[b] - x).abs()))
            .unwrap_or(0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedule_keeps_wall_time_and_the_minimum_delay() {
        // 1501 rows, 1 ms apart, real time: frames of 20 ms, every 20th row
        let t: Vec<f64> = (0..1501).map(|k| k as f64 * 1e-3).collect();
        let (rows, delays) = schedule(&t, 1.0, 0.02, 1, 0.01);
        assert_eq!(rows.len(), 76);
        assert!(rows.windows(2).all(|w| w[1] - w[0] == 20), "{rows:?}");
        assert!(delays.iter().all(|&d| d == 2));
        let total: u32 = delays.iter().sum();
        assert_eq!(total, 152, "1.5 s plus the last frame's 20 ms");
        // irregular output: the rounded delays sum to the span exactly
        let t: Vec<f64> = (0..400).map(|k| (k as f64 * 0.0137).powf(1.3)).collect();
        let (rows, delays) = schedule(&t, 0.5, 0.02, 1, 0.01);
        let span_ticks = ((t[*rows.last().unwrap()] - t[0]) / 0.5 / 0.01).round() as u32;
        let sum: u32 = delays[..delays.len() - 1].iter().sum();
        assert_eq!(sum, span_ticks);
        assert!(delays.iter().all(|&d| d >= 2));
    }
}
