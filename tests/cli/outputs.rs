//! `[output] quantities`: velocities, accelerations, joint reactions and
//! energies in the CSV of `mbsolve run`, with units in the sidecar JSON,
//! checked against the closed-form dynamics of a physical pendulum.

use std::collections::HashMap;
use std::process::Command;

const M: f64 = 2.0;
const I: f64 = 0.1;
const L: f64 = 0.5; // pivot to centre of mass
const G: f64 = 9.81;

/// A bar pinned to the ground at its local (−L, 0): the centre of mass is
/// at L (cos φ, sin φ) from the pivot.
fn scenario(method: &str) -> String {
    let phi0: f64 = -std::f64::consts::FRAC_PI_2 + 0.9;
    format!(
        r#"name = "physical_pendulum"
gravity = [0.0, -{G}]

[[body]]
name = "bar"
mass = {M}
inertia = {I}
x = {x}
y = {y}
phi = {phi0}

[[joint]]
type = "revolute"
name = "pivot"
body_i = "ground"
point_i = [0.0, 0.0]
body_j = "bar"
point_j = [-{L}, 0.0]

[integrator]
{method}

[time]
end = 2.0

[output]
dt = 0.01
quantities = ["velocities", "accelerations", "reactions", "energy"]
"#,
        x = L * phi0.cos(),
        y = L * phi0.sin(),
    )
}

/// A run's CSV: its header and rows, columns found by name.
struct Table {
    header: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl Table {
    fn col(&self, name: &str) -> usize {
        self.header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("column {name} in {:?}", self.header))
    }
}

/// `mbsolve run SCENARIO --set … --out DIR`, which must succeed, and the
/// CSV it wrote.
fn mbsolve_run(scenario: &std::path::Path, sets: &[&str], dir: &std::path::Path) -> Table {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_mbsolve"));
    cmd.arg("run").arg(scenario);
    for s in sets {
        cmd.args(["--set", s]);
    }
    let o = cmd
        .args(["--progress", "off", "--out"])
        .arg(dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stem = scenario.file_stem().unwrap().to_str().unwrap();
    let text = std::fs::read_to_string(dir.join(format!("{stem}.csv"))).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    Table { header, rows }
}

fn run(dir: &std::path::Path, method: &str) -> (Vec<String>, Vec<Vec<f64>>) {
    let path = dir.join("physical_pendulum.toml");
    std::fs::write(&path, scenario(method)).unwrap();
    let t = mbsolve_run(&path, &[], dir);
    (t.header, t.rows)
}

#[test]
fn reactions_accelerations_and_energy_match_the_physical_pendulum() {
    for method in [
        r#"method = "ode45"
rtol = 1e-10
atol = 1e-12"#,
        r#"method = "genalpha"
step = 1e-4"#,
    ] {
        let dir = tempfile::tempdir().unwrap();
        let (header, rows) = run(dir.path(), method);
        let col: HashMap<&str, usize> = header
            .iter()
            .enumerate()
            .map(|(i, h)| (h.as_str(), i))
            .collect();
        for name in [
            "bar.vx",
            "bar.vy",
            "bar.omega",
            "bar.ax",
            "bar.ay",
            "bar.alpha",
            "pivot.fx",
            "pivot.fy",
            "pivot.mz",
            "pivot.fx_local",
            "pivot.fy_local",
            "kinetic_energy",
            "potential_energy",
            "total_energy",
        ] {
            assert!(col.contains_key(name), "column {name} in {header:?}");
        }
        // units in the sidecar
        let units: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("physical_pendulum.columns.json")).unwrap(),
        )
        .unwrap();
        let unit = |n: &str| {
            units
                .as_array()
                .unwrap()
                .iter()
                .find(|c| c["name"] == n)
                .unwrap()["unit"]
                .clone()
        };
        assert_eq!(unit("pivot.fx"), "N");
        assert_eq!(unit("bar.alpha"), "rad/s^2");
        assert_eq!(unit("total_energy"), "J");
        // a body's columns carry their positional name of earlier versions
        let alias = |n: &str| {
            units
                .as_array()
                .unwrap()
                .iter()
                .find(|c| c["name"] == n)
                .unwrap()
                .get("alias")
                .cloned()
        };
        assert_eq!(alias("bar.phi"), Some("phi1".into()));
        assert_eq!(alias("bar.alpha"), Some("alpha1".into()));
        assert_eq!(alias("pivot.fx"), None);

        // α and the reactions are evaluated at each output state: exact up
        // to rounding; the energy drifts by the integration error
        let drift_tol = if method.contains("ode45") { 1e-9 } else { 1e-6 };
        let e0 = rows[0][col["total_energy"]];
        let mut max_err = [0.0f64; 4];
        for r in &rows {
            let g = |n: &str| r[col[n]];
            let (phi, w) = (g("bar.phi"), g("bar.omega"));
            // closed form: (I + m L²) φ̈ = −m g L cos φ
            let alpha = -M * G * L * phi.cos() / (I + M * L * L);
            // centre-of-mass acceleration and the pin force R = m a − m g
            let (s, c) = phi.sin_cos();
            let a = [
                -L * alpha * s - L * w * w * c,
                L * alpha * c - L * w * w * s,
            ];
            let rx = M * a[0];
            let ry = M * a[1] + M * G;
            // moment of R about the centre of mass (R acts at the pin, −L along the bar)
            let mz = (-L * c) * ry - (-L * s) * rx;
            // radial component in the bar frame: along −x_local is the tension
            let fx_local = c * rx + s * ry;
            let scale = M * G;
            max_err[0] =
                max_err[0].max((g("bar.alpha") - alpha).abs() / (M * G * L / (I + M * L * L)));
            max_err[1] =
                max_err[1].max(((g("pivot.fx") - rx).abs() + (g("pivot.fy") - ry).abs()) / scale);
            max_err[2] = max_err[2]
                .max(((g("pivot.mz") - mz).abs() + (g("pivot.fx_local") - fx_local).abs()) / scale);
            // energy from the state, and its conservation
            let ke = 0.5 * M * (g("bar.vx").powi(2) + g("bar.vy").powi(2)) + 0.5 * I * w * w;
            let pe = M * G * g("bar.y");
            assert!(
                (g("kinetic_energy") - ke).abs() < 1e-9 * (1.0 + ke),
                "{method}"
            );
            assert!(
                (g("potential_energy") - pe).abs() < 1e-9 * (1.0 + pe.abs()),
                "{method}"
            );
            max_err[3] = max_err[3].max((g("total_energy") - e0).abs() / (M * G * L));
        }
        for (what, e) in ["α", "pin force", "moment and local force", "energy drift"]
            .iter()
            .zip(max_err)
        {
            let tol = if *what == "energy drift" {
                drift_tol
            } else {
                1e-10
            };
            assert!(e < tol, "{method}: {what} relative error {e:e}");
        }
        // the pendulum swings: the reaction is not trivially m g
        let fy: Vec<f64> = rows.iter().map(|r| r[col["pivot.fy"]]).collect();
        let spread = fy.iter().cloned().fold(f64::MIN, f64::max)
            - fy.iter().cloned().fold(f64::MAX, f64::min);
        assert!(spread > 0.3 * M * G, "{spread}");
    }
}

/// The energy balance from the CLI's columns on the four-bar driven by its
/// constant torque M = 0.5 N m: the work column equals M (φ_crank − φ0)
/// (the torque is the only non-conservative load, the joints are ideal)
/// and T + V − E0 − W stays at the integration error.
#[test]
fn energy_balance_columns_on_the_torque_driven_four_bar() {
    let dir = tempfile::tempdir().unwrap();
    let fourbar = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fourbar.toml");
    let table = mbsolve_run(
        &fourbar,
        &[
            "integrator.method=ode45",
            "integrator.rtol=1e-10",
            "integrator.atol=1e-12",
            "output.quantities=[\"energy\"]",
        ],
        dir.path(),
    );
    let col = |n: &str| table.col(n);
    let rows = &table.rows;
    let phi0 = rows[0][col("crank.phi")];
    let e0 = rows[0][col("total_energy")];
    let (mut max_w, mut max_e, mut max_work) = (0.0f64, 0.0f64, 0.0f64);
    for r in rows {
        let w = r[col("work_nonconservative")];
        max_w = max_w.max((w - 0.5 * (r[col("crank.phi")] - phi0)).abs());
        max_e = max_e.max(r[col("energy_balance_error")].abs());
        max_work = max_work.max(w.abs());
        let closed = r[col("total_energy")] - e0 - w;
        // the CSV keeps 13 significant digits
        assert!((closed - r[col("energy_balance_error")]).abs() < 1e-10 * (1.0 + e0.abs()));
    }
    assert!(max_work > 1.0, "the torque does work: {max_work}");
    // trapezoid over the accepted steps: second order in the step
    assert!(max_w < 1e-5 * max_work, "work vs M Δφ: {max_w:e}");
    assert!(max_e < 1e-5 * max_work, "balance error {max_e:e}");
    let s: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("fourbar.summary.json")).unwrap(),
    )
    .unwrap();
    // over the accepted steps the balance error is the trapezoid's: within
    // its own estimate (the summary's), and no warning
    let quad = s["energy_quadrature_error"].as_f64().unwrap();
    let max_step = s["max_energy_balance_error"].as_f64().unwrap();
    assert!(
        max_step >= max_e * (1.0 - 1e-9),
        "{max_step} vs rows {max_e}"
    );
    assert!(max_step <= quad, "{max_step:e} vs estimate {quad:e}");
    assert!(s["warnings"].as_array().unwrap().is_empty(), "{s}");
}

/// The shipped slider-crank: every joint reaction and the drive torque from
/// the CLI's columns against Newton–Euler inverse dynamics of the
/// closed-form kinematics (crank angle θ = ωt, rod angle
/// sin ψ = −r sin θ / l).
#[test]
fn slider_crank_reactions_match_newton_euler_inverse_dynamics() {
    let dir = tempfile::tempdir().unwrap();
    let scen = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/slider_crank.toml");
    let table = mbsolve_run(&scen, &[], dir.path());
    let col = |n: &str| table.col(n);
    let (r, l, w, g) = (0.1, 0.3, 10.0, 9.81);
    let (mc, mr, ms) = (0.2, 0.6, 0.5);
    let (ic, ir) = (mc * r * r / 12.0, mr * l * l / 12.0);
    let cross = |u: [f64; 2], v: [f64; 2]| u[0] * v[1] - u[1] * v[0];
    let mut worst: f64 = 0.0;
    let mut rows = 0;
    for v in &table.rows {
        let t = v[col("t")];
        let th = w * t;
        let (s, c) = th.sin_cos();
        let psi = (-r * s / l).asin();
        let (sp, cp) = psi.sin_cos();
        let psid = -r * c * w / (l * cp);
        let psidd = (r * s * w * w + l * sp * psid * psid) / (l * cp);
        // accelerations of the centres of mass
        let a_c = [-0.5 * r * w * w * c, -0.5 * r * w * w * s];
        let a_a = [-r * w * w * c, -r * w * w * s];
        let a_r = [
            a_a[0] + 0.5 * l * (-sp * psidd - cp * psid * psid),
            a_a[1] + 0.5 * l * (cp * psidd - sp * psid * psid),
        ];
        let a_s = -r * w * w * c - l * (sp * psidd + cp * psid * psid);
        // slider: F_B (from the rod at B, on the slider) + (0, N) + m_s g
        let fbx = ms * a_s;
        // rod: F_A − F_B + m_r g = m_r a_r, I_r ψ̈ = (A − G)×F_A − (B − G)×F_B
        let e = [0.5 * l * cp, 0.5 * l * sp]; // B − G = −(A − G)
                                              // F_Ax = m_r a_rx + F_Bx; F_Ay = m_r (a_ry + g) + F_By
                                              // I_r ψ̈ = −e×F_A − e×F_B, linear in F_By:
                                              //   −e×F_A = −(e0 F_Ay − e1 F_Ax), −e×F_B = −(e0 F_By − e1 F_Bx)
        let fax = mr * a_r[0] + fbx;
        let k = mr * (a_r[1] + g);
        // ir ψ̈ = −e0 (k + F_By) + e1 fax − e0 F_By + e1 fbx
        let fby = (e[1] * fax + e[1] * fbx - e[0] * k - ir * psidd) / (2.0 * e[0]);
        let fay = k + fby;
        let n_slider = ms * g - fby;
        // crank: F_O − F_A + m_c g = m_c a_c; 0 = (O − C)×F_O − (A − C)×F_A + τ
        let fo = [mc * a_c[0] + fax, mc * (a_c[1] + g) + fay];
        let oc = [-0.5 * r * c, -0.5 * r * s];
        let thdd = 0.0; // constant crank speed
        let tau = ic * thdd - (cross(oc, fo) - cross([-oc[0], -oc[1]], [fax, fay]));
        let expect = [
            ("O.fx", fo[0]),
            ("O.fy", fo[1]),
            ("A.fx", fax),
            ("A.fy", fay),
            ("B.fx", fbx),
            ("B.fy", fby),
            ("slide.fx", 0.0),
            ("slide.fy", n_slider),
            ("slide.mz", 0.0),
            ("drive.mz", tau),
        ];
        for (name, want) in expect {
            worst = worst.max((v[col(name)] - want).abs());
        }
        // the multipliers of the ground pin O, Φ = r_ground − r_crank(point):
        // its Φ_q on the crank's x, y is −I, so −Φ_qᵀλ = λ is the force on
        // the crank
        worst = worst.max((v[col("O.lambda1")] - fo[0]).abs());
        worst = worst.max((v[col("O.lambda2")] - fo[1]).abs());
        rows += 1;
    }
    assert_eq!(rows, 201);
    // forces of order m r ω² ≈ 10 N: agreement to the integration accuracy
    assert!(worst < 1e-6, "largest reaction error {worst:e} N");
}
