//! Kinematics and inverse dynamics (`mbsolve::analysis::inverse`) against
//! references mbsolve did not compute: the slider-crank's drive torque in
//! closed form (power balance, derived below) and from the forward run's
//! `drives` output (an integration, not the constraints alone); the
//! four-bar's remaining freedom.

use mbsolve::analysis::inverse::{freedom, InverseDynamics, InverseError, InverseOptions};
use mbsolve::model::drives;
use mbsolve::scenario;
use mbsolve::simulation::{simulate_into, Sample, Sink};
use std::path::Path;

fn load(name: &str) -> scenario::Scenario {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name);
    scenario::load(&p, &[]).unwrap()
}

/// The slider-crank of scenarios/slider_crank.toml in closed form: crank
/// OA (r) at θ = ω t about O, rod AB (l) with angle β, sin β = −r sin θ / l,
/// slider B on the x axis. Returns (x_B, β, drive torque τ). The torque
/// from the power balance τ ω = dT/dt + dV/dt (the drive is the only
/// non-conservative force): dT/dt = Σ m a·v + I α ω_body, dV/dt = Σ m g v_y.
#[allow(clippy::too_many_arguments)]
fn closed_form(t: f64, r: f64, l: f64, w: f64, m: [f64; 3], i_rod: f64, g: f64) -> (f64, f64, f64) {
    let th = w * t;
    let (s, c) = th.sin_cos();
    let beta = (-r * s / l).asin();
    let (sb, cb) = beta.sin_cos();
    let bd = -r * w * c / (l * cb);
    let bdd = (r * w * w * s + l * sb * bd * bd) / (l * cb);
    // crank centre
    let vc = [-0.5 * r * w * s, 0.5 * r * w * c];
    let ac = [-0.5 * r * w * w * c, -0.5 * r * w * w * s];
    // pin A and rod centre G
    let va = [-r * w * s, r * w * c];
    let aa = [-r * w * w * c, -r * w * w * s];
    let vg = [va[0] - 0.5 * l * bd * sb, va[1] + 0.5 * l * bd * cb];
    let ag = [
        aa[0] + 0.5 * l * (-bdd * sb - bd * bd * cb),
        aa[1] + 0.5 * l * (bdd * cb - bd * bd * sb),
    ];
    // slider B
    let xb = r * c + l * cb;
    let vb = -r * w * s - l * sb * bd;
    let ab = -r * w * w * c - l * (cb * bd * bd + sb * bdd);
    let dot = |a: [f64; 2], b: [f64; 2]| a[0] * b[0] + a[1] * b[1];
    let power = m[0] * dot(ac, vc)
        + m[0] * g * vc[1]
        + m[1] * dot(ag, vg)
        + i_rod * bdd * bd
        + m[1] * g * vg[1]
        + m[2] * ab * vb;
    (xb, beta, power / w)
}

/// Drive torques −λ_drive of a forward run at its output times.
struct DriveTorque {
    row: usize,
    t: Vec<f64>,
    tau: Vec<f64>,
}

impl Sink for DriveTorque {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.t.push(s.t);
        self.tau
            .push(-s.lambda.expect("lambda requested")[self.row]);
        Ok(())
    }
}

#[test]
fn slider_crank_drive_torque_matches_closed_form_and_forward_run() {
    let mut sc = load("slider_crank.toml");
    let sys = &sc.system;
    let b = sys.bodies();
    let (r, l, w, g) = (0.1, 0.3, 10.0, 9.81);
    let m = [b[0].mass, b[1].mass, b[2].mass];
    let d = drives(sys);
    assert_eq!(d.len(), 1);
    let mut inv = InverseDynamics::new(sys, &sc.q0, sc.run.t0, InverseOptions::default()).unwrap();
    let times = sc.run.output_times();
    assert!(times.len() > 100);
    let mut inverse_tau = Vec::new();
    let (mut err_tau, mut err_pos, mut peak) = (0.0_f64, 0.0_f64, 0.0_f64);
    for &t in &times {
        let s = inv.at(t).unwrap();
        let (xb, beta, tau) = closed_form(t, r, l, w, m, b[1].inertia, g);
        let got = d[0].force(s.lambda.unwrap());
        inverse_tau.push(got);
        err_tau = err_tau.max((got - tau).abs());
        peak = peak.max(tau.abs());
        err_pos = err_pos.max((s.q[6] - xb).abs()).max((s.q[5] - beta).abs());
        assert!(s.constraint_norm < 1e-11, "|Phi| = {}", s.constraint_norm);
    }
    // the crank turns 10 rad: the torque swings through several periods
    assert!(peak > 0.5, "peak torque {peak}");
    assert!(err_tau < 1e-9 * peak.max(1.0), "torque error {err_tau:.3e}");
    assert!(err_pos < 1e-11, "position error {err_pos:.3e}");

    // the forward run (ode45, rtol 1e-10) with its drives output
    sc.run.outputs.drives = true;
    let mut sink = DriveTorque {
        row: d[0].row,
        t: Vec::new(),
        tau: Vec::new(),
    };
    let summary = simulate_into(sys, &sc.q0, &sc.qd0, &sc.run, &mut [], &mut sink).unwrap();
    assert_eq!(summary.status, "completed");
    assert_eq!(sink.t.len(), times.len());
    let mut err_run = 0.0_f64;
    for (k, (&a, &b)) in sink.tau.iter().zip(&inverse_tau).enumerate() {
        assert_eq!(sink.t[k], times[k]);
        err_run = err_run.max((a - b).abs());
    }
    eprintln!(
        "peak torque {peak:.6} N m; inverse vs closed form {err_tau:.3e} N m, positions {err_pos:.3e}; forward run vs inverse {err_run:.3e} N m"
    );
    assert!(
        err_run < 1e-8 * peak,
        "forward run vs inverse: {err_run:.3e}"
    );
}

#[test]
fn four_bar_freedom_is_named() {
    let sc = load("fourbar.toml");
    let f = freedom(&sc.system, &sc.q0, 0.0);
    assert_eq!(f.dof, 1);
    assert_eq!(f.redundant, 0);
    assert_eq!(f.coordinates.len(), 1);
    // every one of the four pins turns with the crank
    assert_eq!(f.joints, vec![0, 1, 2, 3]);
    match InverseDynamics::new(&sc.system, &sc.q0, 0.0, InverseOptions::default()) {
        Err(e @ InverseError::Underdetermined { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains("1 degree(s) of freedom"), "{msg}");
            assert!(msg.contains("A, B, C, D"), "{msg}");
        }
        Err(e) => panic!("wrong error {e}"),
        Ok(_) => panic!("a free four-bar was accepted"),
    }
}

#[test]
fn cli_writes_run_columns_and_refuses_a_free_mechanism() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let run = |scen: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_mbsolve"))
            .arg("inverse")
            .arg(root.join("scenarios").join(scen))
            .args(["--out", dir.path().to_str().unwrap()])
            .output()
            .unwrap()
    };
    let o = run("slider_crank.toml");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(dir.path().join("slider_crank.inverse.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    for c in [
        "t",
        "slider.x",
        "rod.phi",
        "rod.alpha",
        "O.fx",
        "slide.fy",
        "drive.drive",
    ] {
        assert!(header.contains(&c), "missing column {c}");
    }
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let sc = load("slider_crank.toml");
    let b = sc.system.bodies();
    let m = [b[0].mass, b[1].mass, b[2].mass];
    let mut rows = 0;
    for line in lines {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let (xb, _, tau) = closed_form(v[0], 0.1, 0.3, 10.0, m, b[1].inertia, 9.81);
        assert!((v[col("drive.drive")] - tau).abs() < 1e-9, "t = {}", v[0]);
        assert!((v[col("slider.x")] - xb).abs() < 1e-11);
        rows += 1;
    }
    assert_eq!(rows, sc.run.output_times().len());
    let s: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("slider_crank.inverse.summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(s["status"], "completed");
    assert_eq!(s["drives"]["drive"]["unit"], "N m");

    let o = run("fourbar.toml");
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("fourbar.toml") && err.contains("1 degree(s) of freedom"),
        "{err}"
    );
}
