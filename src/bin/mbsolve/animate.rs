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
    let mut rows = Vec::with_capacity(scene.t.len());
    let zero = vec![0.0; 3 * nb];
    let mut r_row = vec![0.0; 3 * sys.constraints().len()];
    let mut from_columns = 0;
    for (r, q) in scene.poses.iter().enumerate() {
        let qd: Vec<f64> = match &vel {
            Some(v) => v.iter().flat_map(|c| [c[0][r], c[1][r], c[2][r]]).collect(),
            None => zero.clone(),
        };
        let qd = if qd.iter().all(|v| v.is_finite()) {
            qd
        } else {
            zero.clone()
        };
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
            fa.at_with_reactions(scene.t[r], q, &qd, reactions)
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
        "svg" => write_svg(&scene, &a.out, a.speed, a.every)?,
        "gif" => write_gif(&scene, &a.out, a.speed, a.every)?,
        "apng" => write_apng(&scene, &a.out, a.speed, a.every)?,
        "mp4" | "webm" => write_video(&scene, &a.out, a.speed, a.every)?,
        _ => write_png(&scene, &a.out, a.at)?,
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

/// Draw output row `f` of the scene: marks, time stamp, scale bar (on a
/// white background unless `blank` says the canvas is white already).
fn draw_frame<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    s: &Scene,
    f: usize,
    blank: bool,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let size = root.dim_in_pixel();
    let (k, off) = pixel_map(s, size);
    let px = |p: [f64; 2]| {
        (
            (off[0] + k * p[0]).round() as i32,
            (off[1] - k * p[1]).round() as i32,
        )
    };
    if !blank {
        root.fill(&WHITE)?;
    }
    if let Some(g) = &s.note.ghost {
        draw_marks(root, &s.drawing.marks(g), &px, k, true)?;
    }
    draw_marks(root, &s.drawing.marks(&s.poses[f]), &px, k, false)?;
    if let Some(a) = &s.arrows {
        draw_marks(root, &a.marks(f), &px, k, false)?;
    }
    let font = ("sans-serif", 14.0).into_font();
    root.draw(&Text::new(
        format!("t = {:.3} s", s.t[f]),
        (8, 8),
        font.clone(),
    ))?;
    if !s.note.caption.is_empty() {
        root.draw(&Text::new(s.note.caption.as_str(), (8, 28), font.clone()))?;
    }
    let (bar, label) = scale_bar(k, size.0 as f64);
    let (x0, y0) = (10, size.1 as i32 - 12);
    let x1 = x0 + (bar * k).round() as i32;
    root.draw(&PathElement::new(
        vec![(x0, y0 - 4), (x0, y0), (x1, y0), (x1, y0 - 4)],
        BLACK.stroke_width(2),
    ))?;
    root.draw(&Text::new(label, (x1 + 6, y0 - 12), font.clone()))?;
    if let Some(a) = &s.arrows {
        // the key, bottom right: an arrow of the key force and its value
        let (from, to, label) = key_geometry(a, k, size);
        let head = key_head(a, k);
        let p = |x: [f64; 2]| (x[0].round() as i32, x[1].round() as i32);
        root.draw(&PathElement::new(
            vec![p(from), p(to)],
            BLACK.stroke_width(2),
        ))?;
        root.draw(&PathElement::new(
            vec![
                p([to[0] - head, to[1] - 0.5 * head]),
                p(to),
                p([to[0] - head, to[1] + 0.5 * head]),
            ],
            BLACK.stroke_width(2),
        ))?;
        let w = 7 * label.chars().count() as i32;
        root.draw(&Text::new(label, (p(from).0 - w - 6, p(from).1 - 8), font))?;
    }
    Ok(())
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

/// Draw marks through the pixel map `px` (`k` pixels per metre); `faded`:
/// light grey outlines only (a reference pose under the motion).
fn draw_marks<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    marks: &[Mark],
    px: &dyn Fn([f64; 2]) -> (i32, i32),
    k: f64,
    faded: bool,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let fill = RGBColor(0x56, 0xB4, 0xE9).mix(0.5);
    let ground_fill = RGBColor(0xbb, 0xbb, 0xbb);
    let faint = RGBColor(0xc8, 0xc8, 0xc8);
    let ink = |i: Ink| if faded { faint } else { ink_rgb(i) };
    for m in marks {
        match m {
            Mark::Fill { points, ink: i } => {
                let pts: Vec<(i32, i32)> = points.iter().map(|p| px(*p)).collect();
                if !faded {
                    let f = if *i == Ink::Body {
                        fill.filled()
                    } else {
                        ground_fill.filled()
                    };
                    root.draw(&Polygon::new(pts.clone(), f))?;
                }
                let mut closed = pts.clone();
                closed.push(pts[0]);
                root.draw(&PathElement::new(
                    closed,
                    ink(*i).stroke_width(ink_width(*i)),
                ))?;
            }
            Mark::Line { points, ink: i } => {
                let pts: Vec<(i32, i32)> = points.iter().map(|p| px(*p)).collect();
                root.draw(&PathElement::new(pts, ink(*i).stroke_width(ink_width(*i))))?;
            }
            Mark::Circle {
                centre,
                radius,
                ink: i,
                filled,
            } => {
                let r = ((k * radius).round() as i32).max(1);
                if *filled && !faded {
                    root.draw(&Circle::new(px(*centre), r, fill.filled()))?;
                }
                root.draw(&Circle::new(
                    px(*centre),
                    r,
                    ink(*i).stroke_width(ink_width(*i)),
                ))?;
            }
            Mark::Pin { centre } => {
                if !faded {
                    root.draw(&Circle::new(px(*centre), 4, WHITE.filled()))?;
                }
                root.draw(&Circle::new(
                    px(*centre),
                    4,
                    (if faded { faint } else { BLACK }).stroke_width(1),
                ))?;
            }
        }
    }
    Ok(())
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

/// One RGB frame of output row `f`.
fn render_rgb(s: &Scene, f: usize) -> Result<Vec<u8>, String> {
    let (w, h) = s.size;
    let mut buf = vec![255u8; 3 * w as usize * h as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        draw_frame(&root, s, f, true).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(buf)
}

/// The fixed GIF palette: the 6 × 6 × 6 colour cube and 40 greys.
fn palette() -> Vec<u8> {
    let mut p = Vec::with_capacity(768);
    for r in 0..6u8 {
        for g in 0..6u8 {
            for b in 0..6u8 {
                p.extend([r * 51, g * 51, b * 51]);
            }
        }
    }
    for i in 0..40u32 {
        let v = ((i + 1) * 255 / 41) as u8;
        p.extend([v, v, v]);
    }
    p
}

/// The palette index of an RGB pixel: a grey of the 40 (or the cube's
/// black/white) when the channels are within 8 of each other, else the
/// nearest cube colour.
fn quantize(c: &[u8]) -> u8 {
    let (r, g, b) = (c[0] as i32, c[1] as i32, c[2] as i32);
    let (mx, mn) = (r.max(g).max(b), r.min(g).min(b));
    let level = |v: i32| ((v + 25) / 51) as u8;
    if mx - mn <= 8 {
        let v = (r + g + b) / 3;
        if v >= 250 {
            return 215;
        }
        if v <= 3 {
            return 0;
        }
        let i = ((v * 41 + 127) / 255 - 1).clamp(0, 39);
        return 216 + i as u8;
    }
    level(r) * 36 + level(g) * 6 + level(b)
}

/// The GIF: frames chosen by [`schedule`], drawn and LZW-encoded in
/// parallel, written in order with a fixed global palette.
fn write_gif(s: &Scene, path: &Path, speed: f64, every: usize) -> Result<(), String> {
    crate::figure::register_font();
    let (rows, delays) = schedule(&s.t, speed, GIF_MIN_DELAY, every, GIF_TICK);
    let (w, h) = s.size;
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let file = std::fs::File::create(path).map_err(|e| err(&e))?;
    let pal = palette();
    let mut enc = gif::Encoder::new(std::io::BufWriter::new(file), w as u16, h as u16, &pal)
        .map_err(|e| err(&e))?;
    enc.set_repeat(gif::Repeat::Infinite).map_err(|e| err(&e))?;
    // bounded memory: 64 frames at a time
    for chunk in rows.iter().zip(&delays).collect::<Vec<_>>().chunks(64) {
        let frames: Vec<gif::Frame<'static>> = chunk
            .par_iter()
            .map(|(&r, &d)| {
                let rgb = render_rgb(s, r)?;
                let idx: Vec<u8> = rgb.chunks_exact(3).map(quantize).collect();
                let mut f = gif::Frame::from_indexed_pixels(w as u16, h as u16, &idx, None);
                f.delay = d.min(u16::MAX as u32) as u16;
                f.make_lzw_pre_encoded();
                Ok(f)
            })
            .collect::<Result<_, String>>()?;
        for f in &frames {
            enc.write_lzw_pre_encoded_frame(f).map_err(|e| err(&e))?;
        }
    }
    drop(enc);
    report_schedule(s, &rows, &delays, GIF_TICK, speed, "GIF");
    Ok(())
}

/// Shortest APNG frame \[s\] (as the GIF's: browsers slow shorter ones
/// down) and its delay tick (the frame delay is ms/1000).
const APNG_MIN_DELAY: f64 = 0.02;
const APNG_TICK: f64 = 0.001;

/// The APNG: full-colour frames chosen by [`schedule`] at 1 ms delay
/// resolution, drawn in parallel (64 at a time), written in order.
fn write_apng(s: &Scene, path: &Path, speed: f64, every: usize) -> Result<(), String> {
    crate::figure::register_font();
    let (rows, delays) = schedule(&s.t, speed, APNG_MIN_DELAY, every, APNG_TICK);
    let (w, h) = s.size;
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let file = std::fs::File::create(path).map_err(|e| err(&e))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_animated(rows.len() as u32, 0)
        .map_err(|e| err(&e))?;
    let mut writer = enc.write_header().map_err(|e| err(&e))?;
    for chunk in rows.iter().zip(&delays).collect::<Vec<_>>().chunks(64) {
        let frames: Vec<Vec<u8>> = chunk
            .par_iter()
            .map(|(&r, _)| render_rgb(s, r))
            .collect::<Result<_, String>>()?;
        for (rgb, (_, &d)) in frames.iter().zip(chunk) {
            // a delay beyond u16 ms (65 s) in whole seconds
            let (num, den) = if d <= u16::MAX as u32 {
                (d as u16, 1000)
            } else {
                (((d + 500) / 1000).min(u16::MAX as u32) as u16, 1)
            };
            writer.set_frame_delay(num, den).map_err(|e| err(&e))?;
            writer.write_image_data(rgb).map_err(|e| err(&e))?;
        }
    }
    writer.finish().map_err(|e| err(&e))?;
    report_schedule(s, &rows, &delays, APNG_TICK, speed, "APNG");
    Ok(())
}

/// MP4 or WebM through `ffmpeg` on the PATH: constant frame rate (50 fps
/// at most), each frame the output row nearest its wall-clock time.
fn write_video(s: &Scene, path: &Path, speed: f64, every: usize) -> Result<(), String> {
    use std::io::Write as _;
    crate::figure::register_font();
    let n = s.t.len();
    let span = s.t[n - 1] - s.t[0];
    let dt = if n > 1 { span / (n - 1) as f64 } else { 1.0 };
    // frame interval: a whole number of milliseconds ≥ 20 ms
    let d = ((every as f64 * dt / speed).max(VIDEO_MIN_DELAY) * 1000.0).round() / 1000.0;
    let frames = ((span / speed) / d).floor() as usize + 1;
    let fps = format!("{}/1000", (1e6 / (d * 1000.0)).round() as u64);
    let (w, h) = (s.size.0 & !1, s.size.1 & !1);
    let mut child = std::process::Command::new("ffmpeg")
        .args([
            "-loglevel",
            "error",
            "-y",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
        ])
        .args(["-s", &format!("{}x{}", s.size.0, s.size.1)])
        .args(["-framerate", &fps, "-i", "-"])
        .args(["-vf", &format!("crop={w}:{h}:0:0"), "-pix_fmt", "yuv420p"])
        .arg(path)
        .stdin(std::process::Stdio::piped())
        .spawn()
        .map_err(|e| {
            format!(
                "{}: MP4/WebM need ffmpeg on the PATH ({e}); write a .gif or .apng instead",
                path.display()
            )
        })?;
    let mut stdin = child.stdin.take().ok_or("ffmpeg: no stdin")?;
    let mut r = 0;
    for i in 0..frames {
        let target = s.t[0] + i as f64 * d * speed;
        while r + 1 < n && (s.t[r + 1] - target).abs() <= (s.t[r] - target).abs() {
            r += 1;
        }
        let rgb = render_rgb(s, r)?;
        stdin
            .write_all(&rgb)
            .map_err(|e| format!("{}: ffmpeg: {e}", path.display()))?;
    }
    drop(stdin);
    let st = child.wait().map_err(|e| format!("ffmpeg: {e}"))?;
    if !st.success() {
        return Err(format!("{}: ffmpeg failed ({st})", path.display()));
    }
    println!(
        "video: {frames} frames of {:.0} ms; {span:.3} s of simulation at {speed}× real time play in {:.2} s",
        d * 1000.0,
        frames as f64 * d
    );
    Ok(())
}

/// A still PNG of the output time nearest to `at` (default: the last).
fn write_png(s: &Scene, path: &Path, at: Option<f64>) -> Result<(), String> {
    crate::figure::register_font();
    let f = nearest_row(&s.t, at);
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let root = BitMapBackend::new(path, s.size).into_drawing_area();
    draw_frame(&root, s, f, false).map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
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

/// The SVG `points` attribute of `p` through the pixel map `px`:
/// `"x,y x,y …"` with two decimals.
fn svg_points(p: &[[f64; 2]], px: &dyn Fn([f64; 2]) -> (f64, f64)) -> String {
    p.iter()
        .map(|q| {
            let (a, b) = px(*q);
            format!("{a:.2},{b:.2}")
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// One mark as SVG, through the pixel map `px` (world or body frame).
fn svg_mark(o: &mut String, m: &Mark, px: &dyn Fn([f64; 2]) -> (f64, f64), k: f64) {
    let pts = |p: &[[f64; 2]]| svg_points(p, px);
    match m {
        Mark::Fill { points, ink } => {
            let fill = if *ink == Ink::Body {
                r##"fill="#56B4E9" fill-opacity="0.5""##
            } else {
                r##"fill="#bbbbbb""##
            };
            let _ = writeln!(
                o,
                r#"<polygon points="{}" {fill} stroke="{}" stroke-width="{}"/>"#,
                pts(points),
                ink_hex(*ink),
                ink_width(*ink)
            );
        }
        Mark::Line { points, ink } => {
            let _ = writeln!(
                o,
                r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="{}"/>"#,
                pts(points),
                ink_hex(*ink),
                ink_width(*ink)
            );
        }
        Mark::Circle {
            centre,
            radius,
            ink,
            filled,
        } => {
            let (a, b) = px(*centre);
            let fill = if *filled {
                r##"fill="#56B4E9" fill-opacity="0.5""##
            } else {
                r#"fill="none""#
            };
            let _ = writeln!(
                o,
                r#"<circle cx="{a:.2}" cy="{b:.2}" r="{:.2}" {fill} stroke="{}" stroke-width="2"/>"#,
                k * radius,
                ink_hex(*ink)
            );
        }
        Mark::Pin { centre } => {
            let (a, b) = px(*centre);
            let _ = writeln!(
                o,
                r#"<circle cx="{a:.2}" cy="{b:.2}" r="3.5" fill="white" stroke="black" stroke-width="1.5"/>"#
            );
        }
    }
}

/// The force arrows of an animated SVG: per arrow a shaft and a head
/// polyline whose points are animated over `rows` (a zero force: all
/// points at its point of application), titled with its escaped name.
fn svg_arrows(
    o: &mut String,
    a: &SceneArrows,
    rows: &[usize],
    px: &dyn Fn([f64; 2]) -> (f64, f64),
    key_times: &str,
    dur: f64,
) {
    let Some(first) = a.rows.first() else { return };
    for (j, arrow) in first.iter().enumerate() {
        if !rows.iter().any(|&r| a.key.is_visible(a.rows[r][j].force)) {
            continue; // negligible in every frame: no zero-length lines
        }
        let ink = ink_hex(arrow.kind.ink());
        let name = crate::view::escape_html(&arrow.name);
        for part in 0..2 {
            let values: Vec<String> = rows
                .iter()
                .map(|&r| {
                    let x = &a.rows[r][j];
                    let d = [
                        x.force[0] * a.key.metres_per_newton,
                        x.force[1] * a.key.metres_per_newton,
                    ];
                    match arrows::arrow_marks(x.at, d, a.head, arrow.kind.ink()).get(part) {
                        Some(Mark::Line { points, .. }) => svg_points(points, px),
                        _ => svg_points(&vec![x.at; part + 2], px),
                    }
                })
                .collect();
            let _ = writeln!(
                o,
                r#"<polyline class="force" points="{}" fill="none" stroke="{ink}" stroke-width="2"><title>{name}</title><animate attributeName="points" values="{}" keyTimes="{key_times}" dur="{dur}s" repeatCount="indefinite"/></polyline>"#,
                values[0],
                values.join(";")
            );
        }
    }
}

/// The animated SVG: static ground; per body a group of its parts whose
/// translation and rotation are animated (SMIL `animateTransform`);
/// springs and dampers as paths whose points are animated; key times at
/// the rows chosen by [`schedule`] (at most 100 per second of playback).
fn write_svg(s: &Scene, path: &Path, speed: f64, every: usize) -> Result<(), String> {
    use mbsolve::drawing::Part;
    let size = s.size;
    let (k, off) = pixel_map(s, size);
    let (rows, _) = schedule(&s.t, speed, SVG_MIN_DELAY, every, 1e-3);
    let (t0, t1) = (s.t[0], s.t[*rows.last().unwrap_or(&0)]);
    let dur = ((t1 - t0) / speed).max(1e-3);
    let key_times: String = rows
        .iter()
        .map(|&r| {
            if t1 > t0 {
                format!("{:.6}", (s.t[r] - t0) / (t1 - t0))
            } else {
                "0".into()
            }
        })
        .collect::<Vec<_>>()
        .join(";");
    let world_px = |p: [f64; 2]| (off[0] + k * p[0], off[1] - k * p[1]);
    let local_px = |p: [f64; 2]| (k * p[0], -k * p[1]);
    let nb = s.drawing.bodies.len();
    let identity = vec![0.0; 3 * nb];
    // Split the parts: ground, one body, two bodies.
    let mut ground = s.drawing.clone();
    ground.parts.clear();
    let mut per_body = vec![ground.clone(); nb];
    let mut moving = ground.clone();
    for p in &s.drawing.parts {
        let carrier = match p {
            Part::Polygon { body, .. }
            | Part::Bar { body, .. }
            | Part::Disc { body, .. }
            | Part::Contact { body, .. }
            | Part::Pin { body, .. }
            | Part::Guide { body, .. } => Some(*body),
            Part::Support { .. } | Part::Ground { .. } => Some(None),
            Part::Spring { .. } | Part::Damper { .. } => None,
        };
        match carrier {
            Some(None) => ground.parts.push(p.clone()),
            Some(Some(i)) => per_body[i].parts.push(p.clone()),
            None => moving.parts.push(p.clone()),
        }
    }
    let mut o = String::new();
    let _ = writeln!(
        o,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" viewBox="0 0 {} {}">"#,
        size.0, size.1, size.0, size.1
    );
    let (bar, label) = scale_bar(k, size.0 as f64);
    let y0 = size.1 as f64 - 12.0;
    let _ = writeln!(
        o,
        r#"<rect width="100%" height="100%" fill="white"/>
<text x="8" y="18" font-family="sans-serif" font-size="13">t = {t0:.3} … {t1:.3} s ({} frames, {speed}× real time)</text>
<path d="M10,{:.1} v4 h{:.2} v-4" fill="none" stroke="black" stroke-width="2"/>
<text x="{:.1}" y="{:.1}" font-family="sans-serif" font-size="13">{label}</text>"#,
        rows.len(),
        y0 - 4.0,
        bar * k,
        16.0 + bar * k,
        y0,
    );
    if !s.note.caption.is_empty() {
        let _ = writeln!(
            o,
            r#"<text x="8" y="36" font-family="sans-serif" font-size="13">{}</text>"#,
            crate::view::escape_html(&s.note.caption)
        );
    }
    for m in ground.marks(&identity) {
        svg_mark(&mut o, &m, &world_px, k);
    }
    if let Some(g) = &s.note.ghost {
        let _ = writeln!(o, r#"<g opacity="0.3">"#);
        for m in s.drawing.marks(g) {
            svg_mark(&mut o, &m, &world_px, k);
        }
        let _ = writeln!(o, "</g>");
    }
    for (i, d) in per_body.iter().enumerate() {
        let tr: Vec<String> = rows
            .iter()
            .map(|&r| {
                let q = &s.poses[r];
                let (a, b) = world_px([q[3 * i], q[3 * i + 1]]);
                format!("{a:.3},{b:.3}")
            })
            .collect();
        let rot: Vec<String> = rows
            .iter()
            .map(|&r| format!("{:.4}", -s.poses[r][3 * i + 2].to_degrees()))
            .collect();
        let _ = writeln!(
            o,
            r#"<g transform="translate({tr0})"><animateTransform attributeName="transform" type="translate" values="{tr}" keyTimes="{key_times}" dur="{dur}s" repeatCount="indefinite"/>
<g transform="rotate({rot0})"><animateTransform attributeName="transform" type="rotate" values="{rot}" keyTimes="{key_times}" dur="{dur}s" repeatCount="indefinite"/>"#,
            // the first frame as the static pose: what a renderer without
            // SMIL animation (and the print) shows
            tr0 = tr[0].replace(',', " "),
            rot0 = rot[0],
            tr = tr.join(";"),
            rot = rot.join(";"),
        );
        for m in d.marks(&identity) {
            svg_mark(&mut o, &m, &local_px, k);
        }
        let _ = writeln!(o, "</g></g>");
    }
    // Springs and dampers: one polyline per mark, its points animated.
    let frames: Vec<Vec<Mark>> = rows.iter().map(|&r| moving.marks(&s.poses[r])).collect();
    for (j, m) in frames[0].iter().enumerate() {
        let (Mark::Line { points, ink } | Mark::Fill { points, ink }) = m else {
            continue;
        };
        let pts = |p: &[[f64; 2]]| svg_points(p, &world_px);
        let values: Vec<String> = frames
            .iter()
            .map(|f| match &f[j] {
                Mark::Line { points, .. } | Mark::Fill { points, .. } => pts(points),
                _ => String::new(),
            })
            .collect();
        let _ = writeln!(
            o,
            r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="2"><animate attributeName="points" values="{}" keyTimes="{key_times}" dur="{dur}s" repeatCount="indefinite"/></polyline>"#,
            pts(points),
            ink_hex(*ink),
            values.join(";")
        );
    }
    if let Some(a) = &s.arrows {
        svg_arrows(&mut o, a, &rows, &world_px, &key_times, dur);
        let (from, to, label) = key_geometry(a, k, size);
        let h = key_head(a, k);
        let _ = writeln!(
            o,
            r#"<g class="force-key"><path d="M{:.2},{:.2} L{:.2},{:.2} M{:.2},{:.2} L{:.2},{:.2} L{:.2},{:.2}" fill="none" stroke="black" stroke-width="2"/>
<text x="{:.2}" y="{:.2}" font-family="sans-serif" font-size="13" text-anchor="end">{}</text></g>"#,
            from[0],
            from[1],
            to[0],
            to[1],
            to[0] - h,
            to[1] - 0.5 * h,
            to[0],
            to[1],
            to[0] - h,
            to[1] + 0.5 * h,
            from[0] - 6.0,
            from[1] + 4.0,
            crate::view::escape_html(&label)
        );
    }
    let _ = writeln!(o, "</svg>");
    std::fs::write(path, o).map_err(|e| format!("{}: {e}", path.display()))
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

    #[test]
    fn palette_maps_pure_colours_exactly() {
        let p = palette();
        assert_eq!(p.len(), 768);
        for c in [[0u8, 0, 0], [255, 255, 255], [0, 102, 204], [136, 136, 136]] {
            let i = quantize(&c) as usize;
            let q = &p[3 * i..3 * i + 3];
            for k in 0..3 {
                assert!((q[k] as i32 - c[k] as i32).abs() <= 4, "{c:?} -> {q:?}");
            }
        }
    }
}
