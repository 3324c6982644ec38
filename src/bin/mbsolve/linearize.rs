//! `mbsolve linearize SCENARIO [--at initial|t=T|static] [--inputs …]
//! [--outputs …] [--independent …] [--method …] [--out DIR]`: the
//! state-space model about a state ([`mbsolve::analysis::linearize`]).
//! Writes `DIR/<stem>.linear.json` (names, units, state, matrices,
//! eigenvalues of A) and each matrix as `DIR/<stem>.linear.{A,B,C,D}.csv`
//! (a header of column names, each row led by its name) and `.npy`
//! (NumPy format 1.0, little-endian float64, C order).

use crate::output::write_atomic;
use mbsolve::analysis::linearize::{
    linearize, Input, LinearizeOptions, Method, Output, StateSpace,
};
use mbsolve::analysis::{static_equilibrium_from, StaticOptions};
use mbsolve::model::System;
use mbsolve::scenario::{self, Scenario};
use mbsolve::simulation::simulate;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `mbsolve linearize`.
#[derive(clap::Args)]
pub struct LinearizeArgs {
    /// Scenario file (TOML).
    pub scenario: PathBuf,
    /// Override a scenario key (repeatable), as for `run`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// The state: `initial` (the scenario's assembled initial state),
    /// `t=T` (the state a run of the scenario reaches at T s) or `static`
    /// (the static equilibrium from the initial state, as `mbsolve
    /// static`; linearised by the exact tangent matrices).
    #[arg(long, default_value = "initial")]
    pub at: String,
    /// Inputs, comma-separated: generalized forces `BODY.fx`, `BODY.fy`
    /// (N, along global x, y at the centre of mass) and `BODY.mz` (N m);
    /// a drive's joint name `DRIVE` (or `DRIVE.acc`): the acceleration of
    /// its prescribed motion (m/s² or rad/s²), whose offset and rate join
    /// the states as `DRIVE.offset`, `DRIVE.rate`.
    #[arg(long, value_delimiter = ',')]
    pub inputs: Vec<String>,
    /// Outputs, comma-separated: coordinates `BODY.x|y|phi`, velocities
    /// `BODY.vx|vy|omega`, sensor readings `SENSOR.QUANTITY`, controller
    /// states by name.
    #[arg(long, value_delimiter = ',')]
    pub outputs: Vec<String>,
    /// Independent coordinates `BODY.x|y|phi`, comma-separated [default:
    /// the non-pivot columns of a sparse elimination of Φ_q].
    #[arg(long, value_delimiter = ',')]
    pub independent: Vec<String>,
    /// `auto` (exact tangent matrices at an equilibrium at rest, central
    /// differences elsewhere), `tangent` or `fd`.
    #[arg(long, default_value = "auto", value_parser = ["auto", "tangent", "fd"])]
    pub method: String,
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}

/// The command; `Err` is printed by `main` with exit status 2.
pub fn command(a: &LinearizeArgs) -> Result<ExitCode, String> {
    let file = a.scenario.display().to_string();
    let sc = scenario::load(&a.scenario, &a.set).map_err(|e| e.to_string())?;
    let sys = &sc.system;
    let inputs = a
        .inputs
        .iter()
        .map(|s| parse_input(sys, s))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| format!("{file}: --inputs: {e}"))?;
    let outputs = a
        .outputs
        .iter()
        .map(|s| parse_output(&sc, s))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| format!("{file}: --outputs: {e}"))?;
    let independent = if a.independent.is_empty() {
        None
    } else {
        Some(
            a.independent
                .iter()
                .map(|s| match parse_coordinate(sys, s)? {
                    (k, false) => Ok(k),
                    (_, true) => Err(format!("'{s}' is a velocity, not a coordinate")),
                })
                .collect::<Result<Vec<_>, String>>()
                .map_err(|e| format!("{file}: --independent: {e}"))?,
        )
    };
    let (t, q, qd) = state(&sc, &a.at).map_err(|e| format!("{file}: --at {}: {e}", a.at))?;
    let mut opts = LinearizeOptions {
        independent,
        method: match a.method.as_str() {
            "tangent" => Method::Tangent,
            "fd" => Method::FiniteDifferences,
            _ => Method::Auto,
        },
        ..Default::default()
    };
    if a.at == "static" {
        // an equilibrium to the static solver's relative tolerance (1e-10
        // of the largest load): the exact tangent path
        opts.rest_tol = 1e-6;
        if opts.method == Method::Auto {
            opts.method = Method::Tangent;
        }
    }
    let ss = linearize(sys, &sc.sensors, t, &q, &qd, &inputs, &outputs, &opts)
        .map_err(|e| format!("{file}: {e}"))?;
    let stem = a
        .scenario
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| sc.name.clone());
    crate::output::create_dir(&a.out)?;
    let eig = eigenvalues(&ss);
    let json = a.out.join(format!("{stem}.linear.json"));
    write_atomic(&json, &(to_json(a, &sc, &ss, &eig) + "\n")).map_err(|e| e.to_string())?;
    let names = |v: &[(String, &str)]| v.iter().map(|x| x.0.clone()).collect::<Vec<_>>();
    let (xs, us, ys) = (names(&ss.states), names(&ss.inputs), names(&ss.outputs));
    for (m, rows, cols, name) in [
        (&ss.a, &xs, &xs, "A"),
        (&ss.b, &xs, &us, "B"),
        (&ss.c, &ys, &xs, "C"),
        (&ss.d, &ys, &us, "D"),
    ] {
        let csv = a.out.join(format!("{stem}.linear.{name}.csv"));
        write_atomic(&csv, &matrix_csv(m, rows, cols)).map_err(|e| e.to_string())?;
        let npy = a.out.join(format!("{stem}.linear.{name}.npy"));
        write_npy(&npy, m).map_err(|e| format!("{}: {e}", npy.display()))?;
    }
    say!(
        "{}: linearised at t = {} s ({}), {} states, {} inputs, {} outputs; independent {}",
        sc.name,
        ss.t,
        ss.method.name(),
        ss.states.len(),
        ss.inputs.len(),
        ss.outputs.len(),
        ss.states[..ss.independent.len()]
            .iter()
            .map(|s| s.0.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    );
    for (re, im) in eig.iter().filter(|e| e.1 >= 0.0) {
        if *im > 0.0 {
            let w = re.hypot(*im);
            say!(
                "  eigenvalue {re:.6e} ± {im:.6e} i: |λ|/2π = {:.6e} Hz, damped {:.6e} Hz, \
                 damping ratio −Re λ/|λ| = {:.4e}",
                w / std::f64::consts::TAU,
                im / std::f64::consts::TAU,
                -re / w
            );
        } else {
            say!("  eigenvalue {re:.6e}");
        }
    }
    say!("wrote {} and the matrices beside it", json.display());
    Ok(ExitCode::SUCCESS)
}

/// The state to linearise about: `(t, q, q̇)`.
fn state(sc: &Scenario, at: &str) -> Result<(f64, Vec<f64>, Vec<f64>), String> {
    match at {
        "initial" => Ok((sc.run.t0, sc.q0.clone(), sc.qd0.clone())),
        "static" => {
            let opts = StaticOptions {
                t0: sc.run.t0,
                ..Default::default()
            };
            let z0 = &sc.qd0[sc.system.n_body_coords()..];
            let eq =
                static_equilibrium_from(&sc.system, &sc.q0, z0, opts).map_err(|e| e.to_string())?;
            let qd = eq.velocities();
            Ok((sc.run.t0, eq.q, qd))
        }
        s => {
            let v = s
                .strip_prefix("t=")
                .ok_or_else(|| "expected initial, static or t=T".to_string())?;
            let t: f64 = v
                .trim()
                .parse()
                .map_err(|_| format!("'{v}' is not a number"))?;
            state_at_time(sc, t)
        }
    }
}

/// The state `(t, q, q̇)` a run of the scenario (its own settings, no
/// output files) reaches at `t` ≥ t₀.
pub(crate) fn state_at_time(sc: &Scenario, t: f64) -> Result<(f64, Vec<f64>, Vec<f64>), String> {
    if !(t.is_finite() && t >= sc.run.t0) {
        return Err(format!("T = {t} must be finite and ≥ t0 = {}", sc.run.t0));
    }
    if t == sc.run.t0 {
        return Ok((t, sc.q0.clone(), sc.qd0.clone()));
    }
    let mut cfg = sc.run.clone();
    cfg.t_end = t;
    cfg.output_dt = t - sc.run.t0;
    cfg.outputs = Default::default();
    let (traj, summary) =
        simulate(&sc.system, &sc.q0, &sc.qd0, &cfg, &mut []).map_err(|e| e.to_string())?;
    if summary.status != "completed" {
        return Err(format!(
            "the run to T stopped at t = {} ({}): {}",
            summary.t_reached,
            summary.status,
            summary.message.unwrap_or_default()
        ));
    }
    match (traj.t.last(), traj.q.last(), traj.qd.last()) {
        (Some(&t), Some(q), Some(qd)) => Ok((t, q.clone(), qd.clone())),
        _ => Err("the run to T delivered no state".into()),
    }
}

/// `BODY.QUANTITY` → (index of the body named BODY, QUANTITY); `expected`
/// names the form in the error.
fn body_and_quantity<'a>(
    sys: &System,
    s: &'a str,
    expected: &str,
) -> Result<(usize, &'a str), String> {
    let (body, q) = s
        .rsplit_once('.')
        .ok_or_else(|| format!("'{s}': expected {expected}"))?;
    let b = sys
        .bodies()
        .iter()
        .position(|x| x.name == body)
        .ok_or_else(|| format!("'{s}': no body named '{body}'"))?;
    Ok((b, q))
}

/// `BODY.x|y|phi` → (coordinate, false); `BODY.vx|vy|omega` → (coordinate, true).
fn parse_coordinate(sys: &System, s: &str) -> Result<(usize, bool), String> {
    let (b, q) = body_and_quantity(sys, s, "BODY.QUANTITY")?;
    let (k, vel) = match q {
        "x" => (0, false),
        "y" => (1, false),
        "phi" => (2, false),
        "vx" => (0, true),
        "vy" => (1, true),
        "omega" => (2, true),
        _ => {
            return Err(format!(
                "'{s}': unknown quantity '{q}' (x, y, phi, vx, vy, omega)"
            ))
        }
    };
    Ok((3 * b + k, vel))
}

fn parse_input(sys: &System, s: &str) -> Result<Input, String> {
    let joint_name = s.strip_suffix(".acc").unwrap_or(s);
    let joint = sys
        .constraints()
        .iter()
        .position(|c| mbsolve::model::joint_short_name(c.as_ref()).as_deref() == Some(joint_name));
    if let Some(joint) = joint {
        return if sys.constraints()[joint].drive_unit().is_some() {
            Ok(Input::Drive { joint })
        } else {
            Err(format!(
                "'{s}': joint '{joint_name}' is not a drive (drive_coordinate or drive_angle)"
            ))
        };
    }
    let (b, q) = body_and_quantity(sys, s, "BODY.fx, BODY.fy, BODY.mz or a drive's name")?;
    let k = match q {
        "fx" => 0,
        "fy" => 1,
        "mz" => 2,
        _ => return Err(format!("'{s}': unknown input '{q}' (fx, fy, mz)")),
    };
    Ok(Input::Force {
        coordinate: 3 * b + k,
    })
}

fn parse_output(sc: &Scenario, s: &str) -> Result<Output, String> {
    if let Some(k) = sc.system.states().iter().position(|x| x.name == s) {
        return Ok(Output::State(k));
    }
    if let Some((name, q)) = s.rsplit_once('.') {
        if let Some(i) = sc.sensors.iter().position(|x| x.name == name) {
            let quantities = sc.sensors[i].quantities(&sc.system);
            return match quantities.iter().position(|x| x.0 == q) {
                Some(index) => Ok(Output::Sensor { sensor: i, index }),
                None => Err(format!(
                    "'{s}': sensor '{name}' has no quantity '{q}' ({})",
                    quantities
                        .iter()
                        .map(|x| x.0)
                        .collect::<Vec<_>>()
                        .join(", ")
                )),
            };
        }
    }
    match parse_coordinate(&sc.system, s)? {
        (k, false) => Ok(Output::Coordinate(k)),
        (k, true) => Ok(Output::Velocity(k)),
    }
}

/// Eigenvalues of A as `(re, im)`, sorted by imaginary part then real.
fn eigenvalues(ss: &StateSpace) -> Vec<(f64, f64)> {
    if ss.a.nrows() == 0 {
        return Vec::new();
    }
    let mut e: Vec<(f64, f64)> = match ss.a.eigenvalues() {
        Ok(v) => v.iter().map(|z| (z.re, z.im)).collect(),
        Err(_) => return Vec::new(),
    };
    e.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.total_cmp(&b.0)));
    e
}

fn rows_of(m: &faer::Mat<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
        .collect()
}

fn to_json(a: &LinearizeArgs, sc: &Scenario, ss: &StateSpace, eig: &[(f64, f64)]) -> String {
    let named = |v: &[(String, &str)]| {
        v.iter()
            .map(|(n, u)| serde_json::json!({"name": n, "unit": u}))
            .collect::<Vec<_>>()
    };
    let j = serde_json::json!({
        "analysis": "linearization",
        "scenario": a.scenario.display().to_string(),
        "overrides": a.set,
        "mbsolve_version": env!("CARGO_PKG_VERSION"),
        "at": a.at,
        "t": ss.t,
        "method": ss.method.name(),
        "form": "xdot = A x + B u, y = C x + D u; x = (z, zdot, drive offsets and rates, controller states), z the independent coordinates",
        "independent": ss.states[..ss.independent.len()].iter().map(|s| s.0.clone()).collect::<Vec<_>>(),
        "states": named(&ss.states),
        "inputs": named(&ss.inputs),
        "outputs": named(&ss.outputs),
        "A": rows_of(&ss.a),
        "B": rows_of(&ss.b),
        "C": rows_of(&ss.c),
        "D": rows_of(&ss.d),
        "eigenvalues": eig.iter().map(|&(re, im)| serde_json::json!({"re": re, "im": im})).collect::<Vec<_>>(),
        "q": ss.q,
        "qd": ss.qd,
        "qdd": ss.qdd,
        "lambda": ss.lambda,
        "coordinates": (0..sc.system.n_coords()).map(|k| mbsolve::analysis::inverse::coordinate_label(&sc.system, k)).collect::<Vec<_>>(),
    });
    serde_json::to_string_pretty(&j).unwrap_or_default()
}

/// A CSV field, quoted when it holds a comma, quote or line break.
fn field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn matrix_csv(m: &faer::Mat<f64>, rows: &[String], cols: &[String]) -> String {
    let mut out = String::from("row");
    for c in cols {
        out.push(',');
        out.push_str(&field(c));
    }
    out.push('\n');
    for (i, r) in rows.iter().enumerate() {
        out.push_str(&field(r));
        for j in 0..m.ncols() {
            out.push_str(&format!(",{:.17e}", m[(i, j)]));
        }
        out.push('\n');
    }
    out
}

/// NumPy `.npy` format 1.0: magic, header dict padded to a multiple of
/// 64 bytes, then the values (little-endian f64, C order).
fn write_npy(path: &Path, m: &faer::Mat<f64>) -> std::io::Result<()> {
    let dict = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': ({}, {}), }}",
        m.nrows(),
        m.ncols()
    );
    let unpadded = 10 + dict.len() + 1;
    let pad = (64 - unpadded % 64) % 64;
    let header = format!("{dict}{}\n", " ".repeat(pad));
    let mut bytes = Vec::with_capacity(10 + header.len() + 8 * m.nrows() * m.ncols());
    bytes.extend_from_slice(b"\x93NUMPY\x01\x00");
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for i in 0..m.nrows() {
        for j in 0..m.ncols() {
            bytes.extend_from_slice(&m[(i, j)].to_le_bytes());
        }
    }
    let tmp = crate::output::sibling(path, ".tmp");
    {
        use std::io::Write;
        let mut f = crate::output::create_fresh(&tmp).map_err(std::io::Error::other)?;
        f.write_all(&bytes)?;
        f.sync_all()?;
    }
    std::fs::rename(&tmp, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn npy_header_is_aligned_and_csv_fields_quoted() {
        let m = faer::Mat::<f64>::from_fn(2, 3, |i, j| (i * 3 + j) as f64);
        let dir = std::env::temp_dir().join(format!("mbsolve-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("m.npy");
        write_npy(&p, &m).unwrap();
        let b = std::fs::read(&p).unwrap();
        let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
        assert_eq!((10 + hlen) % 64, 0);
        assert_eq!(b.len(), 10 + hlen + 6 * 8);
        let last = f64::from_le_bytes(b[b.len() - 8..].try_into().unwrap());
        assert_eq!(last, 5.0);
        assert!(std::str::from_utf8(&b[10..10 + hlen])
            .unwrap()
            .contains("'shape': (2, 3)"));
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(field("a,b"), "\"a,b\"");
        assert_eq!(field("x\"y"), "\"x\"\"y\"");
        assert_eq!(field("C.segment[1].x"), "C.segment[1].x");
    }
}
