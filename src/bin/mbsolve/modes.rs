//! `mbsolve modes SCENARIO [--count K] [--at static|initial|t=T] [--out DIR]`:
//! undamped and damped natural frequencies, damping ratios and mode shapes
//! about the static equilibrium, the initial state or the state a run reaches at T
//! ([`mbsolve::analysis::modes`]); writes `DIR/<stem>.modes.json`, a
//! figure of the first shapes (`DIR/<stem>.modes.svg`, `.png`, `.csv`) and
//! an animation of each mode drawn with the model's drawing
//! (`DIR/<stem>.mode<k>.svg` and `.gif`, one period in 2 s; `.png` the
//! largest deflection; from the synthetic run table `<stem>.mode<k>.csv`
//! of `q₀ + a sin(ωt) x` and its rate, in a run's named columns `B.x`,
//! `B.vx`, …), with `--forces` the force arrows of `animate --forces`.

use crate::animate::{self, coordinate_columns};
use crate::figure::{Figure, Series};
use crate::output::write_atomic;
use crate::statics::{equilibrium_of, stem};
use mbsolve::analysis::linearize::{linearize, LinearizeOptions, Method};
use mbsolve::analysis::{
    eigenmodes, first_order_modes, FirstOrderMode, ModeOptions, Modes, Tangent,
};
use mbsolve::formulation::Index3;
use mbsolve::linalg::SolverKind;
use mbsolve::model::System;
use mbsolve::scenario;
use serde_json::json;
use std::path::Path;
use std::process::ExitCode;

/// Where the system is linearised: `static`, `initial` or `t=T`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum At {
    /// The static equilibrium (`mbsolve static`), at rest.
    Static,
    /// The scenario's initial state, λ from its consistent accelerations.
    Initial,
    /// The state a run of the scenario reaches at this time \[s\], λ from
    /// its consistent accelerations.
    Time(f64),
}

impl std::str::FromStr for At {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "static" => Ok(Self::Static),
            "initial" => Ok(Self::Initial),
            _ => {
                let v = s
                    .strip_prefix("t=")
                    .ok_or_else(|| format!("'{s}': expected static, initial or t=T"))?;
                let t: f64 = v
                    .trim()
                    .parse()
                    .map_err(|_| format!("'{s}': '{v}' is not a number"))?;
                if !t.is_finite() {
                    return Err(format!("'{s}': T must be finite"));
                }
                Ok(Self::Time(t))
            }
        }
    }
}

/// Arguments of the command.
pub struct ModesArgs<'a> {
    /// Scenario file.
    pub scenario: &'a Path,
    /// `--set` overrides.
    pub set: &'a [String],
    /// Number of modes.
    pub count: usize,
    /// Linearisation point.
    pub at: At,
    /// Output directory.
    pub out: &'a Path,
    /// Animations of the first this many modes.
    pub animate: usize,
    /// Force arrows drawn on the animations (`--forces`; default: none).
    pub forces: mbsolve::drawing::arrows::ArrowSet,
}

/// The command.
pub fn command(a: &ModesArgs) -> Result<ExitCode, String> {
    if a.count == 0 {
        return Err("--count 0: must be ≥ 1".into());
    }
    let path = a.scenario;
    let mut t_at = None;
    let (sc, q, qd, lambda) = match a.at {
        At::Static => {
            let (sc, eq) = equilibrium_of(path, a.set)?;
            let qd = eq.velocities();
            (sc, eq.q, qd, eq.lambda)
        }
        At::Initial | At::Time(_) => {
            let sc = scenario::load(path, a.set).map_err(|e| e.to_string())?;
            let (t, q, qd) = match a.at {
                At::Time(t) => crate::linearize::state_at_time(&sc, t)
                    .map_err(|e| format!("{}: --at t={t}: {e}", path.display()))?,
                _ => (sc.run.t0, sc.q0.clone(), sc.qd0.clone()),
            };
            let (n, m) = (sc.system.n_coords(), sc.system.n_constraints());
            let mut lam = vec![0.0; m];
            let mut qdd = vec![0.0; n];
            let mut f = Index3::new(&sc.system, SolverKind::Auto).map_err(|e| e.to_string())?;
            f.accelerations(t, &q, &qd, &mut qdd, &mut lam)
                .map_err(|e| format!("{}: {e}", path.display()))?;
            t_at = Some(t);
            (sc, q, qd, lam)
        }
    };
    let sys = &sc.system;
    let t0 = t_at.unwrap_or(sc.run.t0);
    let mut tan = Tangent::new(sys);
    tan.evaluate(t0, &q, &qd, &lambda)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let modes = eigenmodes(
        &tan,
        ModeOptions {
            count: a.count,
            ..Default::default()
        },
    )
    .map_err(|e| format!("{}: {e}", path.display()))?;
    // with controller states: the first-order modes, states included
    let first_order = if sys.states().is_empty() {
        None
    } else {
        Some(first_order(&sc, a.at, t0, &q, &qd).map_err(|e| format!("{}: {e}", path.display()))?)
    };
    crate::output::create_dir(a.out)?;
    let stem = stem(path);
    let names: Vec<String> = coordinate_columns(sys).into_iter().flatten().collect();
    let list: Vec<_> = modes
        .modes
        .iter()
        .enumerate()
        .map(|(i, md)| {
            json!({
                "mode": i + 1,
                "frequency_hz": md.frequency_hz,
                "omega_squared": md.omega_squared,
                "damped_frequency_hz": md.damped_frequency_hz,
                "damping_ratio": md.damping_ratio,
                "residual": md.residual,
                "shape": md.shape[..names.len()],
            })
        })
        .collect();
    let report = json!({
        "scenario": path.display().to_string(),
        "at": match a.at {
            At::Static => "static".to_string(),
            At::Initial => "initial".to_string(),
            At::Time(t) => format!("t={t}"),
        },
        "t0": t0,
        "q": q,
        "qd": qd,
        "shift": modes.shift,
        "lanczos_steps": modes.lanczos_steps,
        "converged": modes.converged,
        "damping": "projected on the computed undamped modes (exact for damping diagonal in that basis)",
        "coordinates": names,
        "modes": list,
    });
    let mut report = report;
    if let Some((states, fo)) = &first_order {
        report["undamped"] =
            json!("the mechanism's modes with the controller states held fixed (δz = 0)");
        report["first_order_states"] = json!(states);
        report["first_order_modes"] = json!(fo
            .iter()
            .map(|m| json!({
                "re": m.re,
                "im": m.im,
                "oscillatory": m.oscillatory,
                "frequency_hz": m.frequency_hz,
                "damped_frequency_hz": m.damped_frequency_hz,
                "damping_ratio": m.damping_ratio,
                "time_constant_s": m.time_constant_s,
                "shape": m.shape,
            }))
            .collect::<Vec<_>>());
    }
    let json_path = a.out.join(format!("{stem}.modes.json"));
    write_atomic(
        &json_path,
        &(serde_json::to_string_pretty(&report).unwrap_or_default() + "\n"),
    )
    .map_err(|e| e.to_string())?;
    for (i, md) in modes.modes.iter().enumerate() {
        say!(
            "mode {:>3}: {:>14.6} Hz  damped {:>14.6} Hz  ζ = {:.3e}",
            i + 1,
            md.frequency_hz,
            md.damped_frequency_hz,
            md.damping_ratio
        );
    }
    if let Some((_, fo)) = &first_order {
        say!("(undamped modes above: the mechanism with its controller states held fixed)");
        say!("first-order modes of the system with its controller states (eigenvalues s of A):");
        for m in fo {
            if m.oscillatory {
                say!(
                    "  s = {:.6e} ± {:.6e} i: {:.6} Hz, damped {:.6} Hz, ζ = {:.4e}",
                    m.re,
                    m.im,
                    m.frequency_hz,
                    m.damped_frequency_hz,
                    m.damping_ratio.unwrap_or(f64::NAN)
                );
            } else {
                say!(
                    "  s = {:.6e}: non-oscillatory (time constant {})",
                    m.re,
                    m.time_constant_s
                        .map(|t| format!("{t:.6e} s"))
                        .unwrap_or_else(|| "none".into())
                );
            }
        }
    }
    if !modes.converged {
        eprintln!(
            "warning: not every mode met the tolerance after {} Lanczos steps (see residual)",
            modes.lanczos_steps
        );
    }
    say!("wrote {}", json_path.display());
    shapes_figure(&modes, sys, a.out, &stem)?;
    for k in 0..a.animate.min(modes.modes.len()) {
        for p in animation(a, sys, &q, &modes, k, &stem)? {
            say!("wrote {}", p.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The first-order modes of a system with controller states at `(t, q,
/// q̇)`: the eigenvalues of its linearisation's A (exact at the static
/// equilibrium, central differences elsewhere), with A's state names.
fn first_order(
    sc: &scenario::Scenario,
    at: At,
    t: f64,
    q: &[f64],
    qd: &[f64],
) -> Result<(Vec<String>, Vec<FirstOrderMode>), String> {
    let mut opts = LinearizeOptions::default();
    if at == At::Static {
        opts.method = Method::Tangent;
        opts.rest_tol = 1e-6;
    }
    let ss = linearize(&sc.system, &[], t, q, qd, &[], &[], &opts).map_err(|e| e.to_string())?;
    let modes = first_order_modes(&ss.a).map_err(|e| e.to_string())?;
    Ok((ss.states.into_iter().map(|s| s.0).collect(), modes))
}

/// Figure of the first (at most 4) shapes: per body, the translation (x
/// or y) with the larger amplitude over those modes, φ for pure rotations.
fn shapes_figure(modes: &Modes, sys: &System, out: &Path, stem: &str) -> Result<(), String> {
    let nb = sys.bodies().len();
    let shown = &modes.modes[..modes.modes.len().min(4)];
    if shown.is_empty() || nb == 0 {
        return Ok(());
    }
    let norm = |c: usize| -> f64 {
        shown
            .iter()
            .map(|md| (0..nb).map(|b| md.shape[3 * b + c].powi(2)).sum::<f64>())
            .sum()
    };
    // a translation (x or y, the larger) unless the shapes are rotations
    // only (φ and lengths are not comparable)
    let comp = if norm(0).max(norm(1)) > 1e-24 * norm(2) {
        if norm(0) >= norm(1) {
            0
        } else {
            1
        }
    } else {
        2
    };
    let axis = ["x", "y", "φ"][comp];
    let fig = Figure {
        title: format!("{stem}: mode shapes ({axis} of each body, M-normalised)"),
        x_label: "body".into(),
        y_label: format!("{axis} component"),
        series: shown
            .iter()
            .enumerate()
            .map(|(i, md)| Series {
                label: format!("mode {} ({:.4} Hz)", i + 1, md.frequency_hz),
                x: (1..=nb).map(|b| b as f64).collect(),
                y: (0..nb).map(|b| md.shape[3 * b + comp]).collect(),
            })
            .collect(),
        log_y: false,
        ..Default::default()
    };
    let s = format!("{stem}.modes");
    fig.save(out, &s).map_err(|e| e.to_string())?;
    fig.render(&out.join(format!("{s}.png")))
        .map_err(|e| e.to_string())?;
    say!("wrote {}", out.join(format!("{s}.svg")).display());
    Ok(())
}

/// Mode `k` as a synthetic run table over one period, drawn by `animate`
/// with the model's drawing over the faded state it oscillates about:
/// an animated SVG, a GIF and a PNG of the largest deflection.
fn animation(
    a: &ModesArgs,
    sys: &System,
    q0: &[f64],
    modes: &Modes,
    k: usize,
    stem: &str,
) -> Result<Vec<std::path::PathBuf>, String> {
    let md = &modes.modes[k];
    let nb = sys.bodies().len();
    // amplitude: the largest displacement 10 % of the model's extent, the
    // largest rotation at most 0.3 rad
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for b in 0..nb {
        for c in 0..2 {
            lo[c] = lo[c].min(q0[3 * b + c]);
            hi[c] = hi[c].max(q0[3 * b + c]);
        }
    }
    // the model's size counts its joints' points too (one body hanging
    // from a ground pin has no extent of reference points)
    let size = mbsolve::drawing::Drawing::new(sys, q0, &vec![None; nb], &[]).scale;
    let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(size).max(1e-3);
    let (mut dmax, mut rmax) = (0.0f64, 0.0f64);
    for b in 0..nb {
        dmax = dmax.max(md.shape[3 * b].hypot(md.shape[3 * b + 1]));
        rmax = rmax.max(md.shape[3 * b + 2].abs());
    }
    let amp = (0.1 * extent / dmax.max(1e-300)).min(0.3 / rmax.max(1e-300));
    let period = if md.frequency_hz > 0.0 {
        1.0 / md.frequency_hz
    } else {
        1.0
    };
    let frames = 48;
    // the run table's names: positions B.x, B.y, B.phi, then velocities
    // B.vx, B.vy, B.omega (the time derivative a ω cos(ωt) x, which the
    // force arrows' dampers and friction read)
    let labels = mbsolve::output::body_labels(sys);
    let mut header = vec!["t".to_string()];
    header.extend(coordinate_columns(sys).into_iter().flatten());
    header.extend(
        labels
            .iter()
            .flat_map(|b| mbsolve::output::VELOCITY.map(|c| format!("{b}.{c}"))),
    );
    let mut w = csv::Writer::from_writer(Vec::new());
    let werr = |e: csv::Error| e.to_string();
    w.write_record(&header).map_err(werr)?;
    let omega = 2.0 * std::f64::consts::PI / period;
    for f in 0..=frames {
        let t = period * f as f64 / frames as f64;
        let (s, c) = (2.0 * std::f64::consts::PI * f as f64 / frames as f64).sin_cos();
        let mut row = vec![format!("{t:e}")];
        row.extend(
            q0.iter()
                .zip(&md.shape)
                .take(sys.n_body_coords())
                .map(|(q, x)| format!("{:e}", q + amp * s * x)),
        );
        row.extend(
            md.shape
                .iter()
                .take(sys.n_body_coords())
                .map(|x| format!("{:e}", amp * omega * c * x)),
        );
        w.write_record(&row).map_err(werr)?;
    }
    let text =
        String::from_utf8(w.into_inner().map_err(|e| e.to_string())?).map_err(|e| e.to_string())?;
    let csv = a.out.join(format!("{stem}.mode{}.csv", k + 1));
    write_atomic(&csv, &text).map_err(|e| e.to_string())?;
    let note = animate::Annotation {
        caption: format!(
            "mode {}: {:.4} Hz (grey: the state it oscillates about)",
            k + 1,
            md.frequency_hz
        ),
        ghost: Some(q0[..sys.n_body_coords()].to_vec()),
        synthetic: true,
    };
    let mut written = Vec::new();
    // the animated SVG and the GIF play one period in 2 s; the PNG is the
    // largest deflection (a quarter period)
    for (ext, at) in [("svg", None), ("gif", None), ("png", Some(0.25 * period))] {
        let p = animate::animate_annotated(
            &animate::AnimateArgs {
                scenario: a.scenario.to_path_buf(),
                set: a.set.to_vec(),
                csv: csv.clone(),
                out: a.out.join(format!("{stem}.mode{}.{ext}", k + 1)),
                speed: period / 2.0,
                every: 1,
                at,
                forces: a.forces,
            },
            note.clone(),
        )?;
        written.push(p);
    }
    Ok(written)
}
