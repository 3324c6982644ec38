//! Eigenmodes against references mbsolve does not compute: the
//! cantilevered chain's linearised equations in absolute angles (derived
//! here by hand, dense generalised eigenproblem with faer) and the
//! Euler–Bernoulli cantilever; the pendulum √(g/l) and the physical
//! pendulum √(mgd/I); the quarter car's 2 × 2 closed form and its damped
//! 4 × 4 state matrix.

// matrices are indexed by row and column throughout
#![allow(clippy::needless_range_loop)]

use crate::common::rod::cantilever_at;
use faer::{Mat, Side};
use mbsolve::analysis::{eigenmodes, static_equilibrium, ModeOptions, StaticOptions, Tangent};
use mbsolve::builders::RodParams;
use mbsolve::scenario;
use std::f64::consts::PI;

/// The chain of the peers (`../shared/peers/chain_model.py`) without
/// gravity: hanging straight down, springs and dampers at every joint.
fn chain(n: usize) -> (mbsolve::model::System, Vec<f64>, RodParams) {
    cantilever_at(n, PI, [0.0, 0.0])
}

/// The lowest `count` ω of the chain linearised about the straight state
/// in absolute angles θ_i: `M = m S + I·1` with `S_ij = l²(N − max(i,j) + ½)`,
/// `S_ii = l²(N − i + ¼)` (1-based; kinetic energy of the segment centres),
/// `K = k DᵀD` (D: θ_1, θ_i − θ_{i−1}); L⁻¹ K L⁻ᵀ by Cholesky, symmetric eigen.
fn hand_omegas(p: &RodParams, count: usize) -> Vec<f64> {
    let n = p.n_segments;
    let (ls, m, i0, k) = (
        p.segment_length(),
        p.segment_mass(),
        p.segment_inertia(),
        p.spring_stiffness(),
    );
    let mut mm = Mat::<f64>::zeros(n, n);
    let mut kk = Mat::<f64>::zeros(n, n);
    for a in 0..n {
        for b in 0..n {
            let (i, j) = (a + 1, b + 1);
            let s = if i == j {
                ls * ls * ((n - i) as f64 + 0.25)
            } else {
                ls * ls * ((n - i.max(j)) as f64 + 0.5)
            };
            mm[(a, b)] = m * s + if a == b { i0 } else { 0.0 };
        }
        kk[(a, a)] = if a + 1 < n { 2.0 * k } else { k };
        if a + 1 < n {
            kk[(a, a + 1)] = -k;
            kk[(a + 1, a)] = -k;
        }
    }
    let llt = mm.llt(Side::Lower).unwrap();
    let l = llt.L().to_owned();
    let lower_solve = |b: &Mat<f64>| -> Mat<f64> {
        let mut x = b.clone();
        for c in 0..n {
            for r in 0..n {
                let mut v = x[(r, c)];
                for j in 0..r {
                    v -= l[(r, j)] * x[(j, c)];
                }
                x[(r, c)] = v / l[(r, r)];
            }
        }
        x
    };
    let x = lower_solve(&kk);
    let a = lower_solve(&x.transpose().to_owned());
    let sym = (&a + a.transpose()) * faer::Scale(0.5);
    let ev = sym.self_adjoint_eigenvalues(Side::Lower).unwrap();
    ev.iter().take(count).map(|v| v.sqrt()).collect()
}

fn chain_modes(n: usize, count: usize) -> (Vec<f64>, Vec<f64>, RodParams) {
    let (sys, q0, p) = chain(n);
    let mut tan = Tangent::new(&sys);
    let z = vec![0.0; sys.n_coords()];
    tan.evaluate(0.0, &q0, &z, &vec![0.0; sys.n_constraints()])
        .unwrap();
    let modes = eigenmodes(
        &tan,
        ModeOptions {
            count,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(modes.converged);
    let w: Vec<f64> = modes
        .modes
        .iter()
        .map(|m| 2.0 * PI * m.frequency_hz)
        .collect();
    let z: Vec<f64> = modes.modes.iter().map(|m| m.damping_ratio).collect();
    (w, z, p)
}

#[test]
fn chain_lowest_three_match_the_hand_derived_absolute_angle_model() {
    for n in [10, 40] {
        let (w, zeta, p) = chain_modes(n, 3);
        let reference = hand_omegas(&p, 3);
        for i in 0..3 {
            let e = (w[i] - reference[i]).abs() / reference[i];
            println!(
                "N = {n} mode {}: {} vs {} rad/s, rel {e:.2e}",
                i + 1,
                w[i],
                reference[i]
            );
            assert!(
                e < 1e-9,
                "N = {n}, mode {}: {} vs {}",
                i + 1,
                w[i],
                reference[i]
            );
            // C = (c/k) K exactly (no gravity, λ = 0): ζ = (c/k) ω / 2
            let z = p.damping_time * reference[i] / 2.0;
            assert!(
                (zeta[i] - z).abs() < 1e-6 * z,
                "N = {n}, mode {}: ζ {} vs {z}",
                i + 1,
                zeta[i]
            );
        }
    }
}

/// Many modes of a chain whose coordinates are not a whole number of the
/// Lanczos basis's blocks (240): more Lanczos steps than the basis first
/// has room for (32), so the basis grows during the iteration; every
/// frequency against the hand-derived model.
#[test]
fn many_modes_match_the_hand_derived_model_as_the_basis_grows() {
    let (count, n) = (30, 80);
    let (w, _, p) = chain_modes(n, count);
    let reference = hand_omegas(&p, count);
    for i in 0..count {
        let e = (w[i] - reference[i]).abs() / reference[i];
        assert!(e < 1e-9, "mode {}: {} vs {}", i + 1, w[i], reference[i]);
    }
    let (sys, q0, _) = chain(n);
    let mut tan = Tangent::new(&sys);
    let z = vec![0.0; sys.n_coords()];
    tan.evaluate(0.0, &q0, &z, &vec![0.0; sys.n_constraints()])
        .unwrap();
    let opts = ModeOptions {
        count,
        ..Default::default()
    };
    let steps = eigenmodes(&tan, opts).unwrap().lanczos_steps;
    assert!(steps > 32, "{steps} Lanczos steps: the basis did not grow");
}

#[test]
fn chain_converges_to_euler_bernoulli_at_first_order() {
    let beta = [1.8751, 4.6941, 7.8548];
    let p1 = RodParams::problem_b(1);
    let ei = p1.youngs_modulus * p1.width.powi(4) / 12.0;
    let rho_a = p1.density * p1.width * p1.width;
    let l = p1.length;
    let eb: Vec<f64> = beta
        .iter()
        .map(|b| b * b * (ei / (rho_a * l.powi(4))).sqrt())
        .collect();
    let ns = [20, 40, 80];
    let errs: Vec<Vec<f64>> = ns
        .iter()
        .map(|&n| {
            let (w, _, _) = chain_modes(n, 3);
            (0..3).map(|i| (w[i] - eb[i]).abs() / eb[i]).collect()
        })
        .collect();
    for i in 0..3 {
        let r1 = (errs[0][i] / errs[1][i]).log2();
        let r2 = (errs[1][i] / errs[2][i]).log2();
        println!(
            "mode {}: errors {:.3e} {:.3e} {:.3e} (N = 20, 40, 80), rates {r1:.3} {r2:.3}",
            i + 1,
            errs[0][i],
            errs[1][i],
            errs[2][i]
        );
        // first order in 1/N (the base spring has the full k of an
        // interior joint; module docs of tests/model/beam.rs): the observed
        // rates must reach `lo` per mode, lower for higher modes, which are
        // still pre-asymptotic at N ≤ 80 (fewer segments per wavelength)
        assert!(errs[2][i] < errs[1][i] && errs[1][i] < errs[0][i]);
        let lo = [0.93, 0.88, 0.8][i];
        assert!((lo..1.1).contains(&r1), "mode {}: rate {r1}", i + 1);
        assert!((lo..1.1).contains(&r2), "mode {}: rate {r2}", i + 1);
    }
    assert!(errs[2][0] < 2e-2);
}

fn parse(text: &str) -> scenario::Scenario {
    scenario::parse(text, "test.toml", "test", &[]).unwrap()
}

/// The modes about the static equilibrium of a scenario text.
fn static_modes(text: &str, count: usize) -> mbsolve::analysis::Modes {
    let sc = parse(text);
    let eq = static_equilibrium(&sc.system, &sc.q0, StaticOptions::default()).unwrap();
    let mut tan = Tangent::new(&sc.system);
    tan.evaluate(0.0, &eq.q, &vec![0.0; eq.q.len()], &eq.lambda)
        .unwrap();
    eigenmodes(
        &tan,
        ModeOptions {
            count,
            ..Default::default()
        },
    )
    .unwrap()
}

fn pendulum(mass: f64, inertia: f64, d: f64, start_deg: f64) -> String {
    let (s, c) = start_deg.to_radians().sin_cos();
    format!(
        r#"
gravity = [0.0, -9.81]
[[body]]
name = "bob"
mass = {mass}
inertia = {inertia}
x = {x}
y = {y}
phi_deg = {start_deg}
[[joint]]
type = "revolute"
name = "pivot"
body_i = "ground"
point_i = [0.0, 0.0]
body_j = "bob"
point_j = [0.0, {d}]
[time]
end = 1.0
"#,
        x = d * s,
        y = -d * c
    )
}

#[test]
fn pendulum_and_physical_pendulum() {
    // a point-like bob (I = 1e-10 m l²): ω² = mgl/(ml² + I) = (g/l)(1 − 1e-10)
    let (m, l) = (2.0, 0.7);
    let md = static_modes(&pendulum(m, 1e-10 * m * l * l, l, 20.0), 1);
    let w = 2.0 * PI * md.modes[0].frequency_hz;
    let r = (9.81 / l).sqrt();
    assert!((w - r).abs() < 1e-8 * r, "{w} vs {r}");
    // a uniform bar of length 2d pivoted at its end: √(m g d / (I_c + m d²))
    let (m, d) = (1.5, 0.4);
    let ic = m * (2.0 * d) * (2.0 * d) / 12.0;
    let md = static_modes(&pendulum(m, ic, d, -35.0), 1);
    let w = 2.0 * PI * md.modes[0].frequency_hz;
    let r = (m * 9.81 * d / (ic + m * d * d)).sqrt();
    assert!((w - r).abs() < 1e-9 * r, "{w} vs {r}");
    assert!(md.modes[0].damping_ratio.abs() < 1e-12);
}

fn quarter_car(cs: f64) -> String {
    format!(
        r#"
gravity = [0.0, -9.81]
[[body]]
name = "wheel"
mass = 40.0
inertia = 1.0
y = 0.3
[[body]]
name = "body"
mass = 300.0
inertia = 10.0
y = 0.8
[[joint]]
type = "translational"
name = "wheel guide"
body_i = "ground"
point_i = [0.0, 0.0]
axis_i = [0.0, 1.0]
body_j = "wheel"
point_j = [0.0, 0.0]
[[joint]]
type = "translational"
name = "body guide"
body_i = "ground"
point_i = [0.0, 0.0]
axis_i = [0.0, 1.0]
body_j = "body"
point_j = [0.0, 0.0]
[[force]]
type = "spring"
name = "tyre"
body_i = "ground"
point_i = [0.0, 0.0]
body_j = "wheel"
point_j = [0.0, 0.0]
free_length = 0.3
stiffness = 200000.0
[[force]]
type = "spring"
name = "suspension"
body_i = "wheel"
point_i = [0.0, 0.0]
body_j = "body"
point_j = [0.0, 0.0]
free_length = 0.5
stiffness = 20000.0
damping = {cs}
[time]
end = 1.0
"#
    )
}

#[test]
fn quarter_car_two_frequencies_and_damping() {
    let (ms, mu, ks, kt): (f64, f64, f64, f64) = (300.0, 40.0, 20000.0, 200000.0);
    // ms mu ω⁴ − (ms (ks + kt) + mu ks) ω² + ks kt = 0
    let (a, b, c) = (ms * mu, -(ms * (ks + kt) + mu * ks), ks * kt);
    let disc = (b * b - 4.0 * a * c).sqrt();
    let w2 = [(-b - disc) / (2.0 * a), (-b + disc) / (2.0 * a)];
    let md = static_modes(&quarter_car(0.0), 2);
    assert_eq!(md.modes.len(), 2);
    for i in 0..2 {
        let e = (md.modes[i].omega_squared - w2[i]).abs() / w2[i];
        assert!(
            e < 1e-9,
            "mode {}: {} vs {}",
            i + 1,
            md.modes[i].omega_squared,
            w2[i]
        );
    }
    // damped: eigenvalues of [0 I; −M⁻¹K −M⁻¹C] (coordinates wheel, body)
    let cs = 1500.0;
    let md = static_modes(&quarter_car(cs), 2);
    let mut s = Mat::<f64>::zeros(4, 4);
    s[(0, 2)] = 1.0;
    s[(1, 3)] = 1.0;
    let kmat = [[ks + kt, -ks], [-ks, ks]];
    let cmat = [[cs, -cs], [-cs, cs]];
    let mass = [mu, ms];
    for i in 0..2 {
        for j in 0..2 {
            s[(2 + i, j)] = -kmat[i][j] / mass[i];
            s[(2 + i, 2 + j)] = -cmat[i][j] / mass[i];
        }
    }
    let ev = s.eigenvalues().unwrap();
    let mut upper: Vec<(f64, f64)> = ev
        .iter()
        .filter(|e| e.im > 0.0)
        .map(|e| (e.re, e.im))
        .collect();
    upper.sort_by(|a, b| a.0.hypot(a.1).total_cmp(&b.0.hypot(b.1)));
    assert_eq!(upper.len(), 2);
    for (i, &(re, im)) in upper.iter().enumerate() {
        let (fd, zeta) = (im / (2.0 * PI), -re / re.hypot(im));
        let m = &md.modes[i];
        println!(
            "quarter car mode {}: fd {} vs {fd}, ζ {} vs {zeta}",
            i + 1,
            m.damped_frequency_hz,
            m.damping_ratio
        );
        assert!((m.damped_frequency_hz - fd).abs() < 1e-8 * fd);
        assert!((m.damping_ratio - zeta).abs() < 1e-8);
    }
}

/// The CLI: `static` writes an equilibrium a `run` starts from and stays
/// at; `modes` writes the JSON (frequencies of the closed form), the
/// figure and an animation.
#[test]
fn cli_static_run_and_modes_of_the_quarter_car() {
    use std::process::Command;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path();
    let scen = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/quarter_car_guided.toml"
    );
    let bin = env!("CARGO_BIN_EXE_mbsolve");
    let st = Command::new(bin)
        .args(["static", scen, "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let report: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("quarter_car_guided.static.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(report["stability"]["verdict"], "stable");
    // tyre and suspension carry the weights: body 0.5 − 300 g/k_s above
    // the wheel, wheel 0.3 − 340 g/k_t
    let y_wheel = report["bodies"][0]["y"].as_f64().unwrap();
    let y_body = report["bodies"][1]["y"].as_f64().unwrap();
    assert!((y_wheel - (0.3 - 340.0 * 9.81 / 200000.0)).abs() < 1e-12);
    assert!((y_body - y_wheel - (0.5 - 300.0 * 9.81 / 20000.0)).abs() < 1e-12);
    let state = out.join("quarter_car_guided.equilibrium.json");
    let run = Command::new(bin)
        .args(["run", scen, "-q", "--set", "time.end=0.2", "--set"])
        .arg(format!("initial.state={}", state.display()))
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let csv = std::fs::read_to_string(out.join("quarter_car_guided.csv")).unwrap();
    let last: Vec<f64> = csv
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        (last[2] - y_wheel).abs() < 1e-9 && (last[5] - y_body).abs() < 1e-9,
        "{last:?}"
    );
    let md = Command::new(bin)
        .args(["modes", scen, "--count", "2", "--animate", "1", "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(
        md.status.success(),
        "{}",
        String::from_utf8_lossy(&md.stderr)
    );
    let modes: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("quarter_car_guided.modes.json")).unwrap(),
    )
    .unwrap();
    let f: Vec<f64> = modes["modes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["frequency_hz"].as_f64().unwrap())
        .collect();
    for (got, want) in f.iter().zip([1.2383298747931333, 11.809820194374181]) {
        assert!((got - want).abs() < 1e-9 * want, "{got} vs {want}");
    }
    for file in [
        "quarter_car_guided.modes.svg",
        "quarter_car_guided.modes.png",
        "quarter_car_guided.mode1.svg",
    ] {
        assert!(out.join(file).exists(), "{file}");
    }
    // bad input: a count of 0 and a missing state file are named errors
    let bad = Command::new(bin)
        .args(["modes", scen, "--count", "0", "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--count 0"));
    let bad = Command::new(bin)
        .args([
            "run",
            scen,
            "-q",
            "--set",
            "initial.state=/nonexistent/s.json",
            "--out",
        ])
        .arg(out)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let e = String::from_utf8_lossy(&bad.stderr);
    assert!(
        e.contains("initial.state") && e.contains("/nonexistent/s.json"),
        "{e}"
    );
}

/// A hanging chain of 50 and 100 links (no joint springs) against the
/// hanging uniform rope: `ω_n = (j₀,ₙ / 2) √(g/L)`, j₀,ₙ the zeros of J₀
/// (Rayleigh, Theory of Sound §100); the discrete error shrinks with N.
#[test]
fn hanging_chain_approaches_the_bessel_frequencies() {
    let j0 = [2.404825557695773, 5.520078110286311, 8.653727912911013];
    let mut errs = Vec::new();
    for links in [50, 100] {
        let text = format!(
            "gravity = [0.0, -9.81]\n[[chain]]\nname = \"rope\"\nlinks = {links}\nlength = {}\n\
             mass = 0.01\nangle_deg = 200.0\npivot = true\n[time]\nend = 1.0\n",
            1.0 / links as f64
        );
        let md = static_modes(&text, 3);
        let e: Vec<f64> = (0..3)
            .map(|i| {
                let w = 2.0 * PI * md.modes[i].frequency_hz;
                let r = 0.5 * j0[i] * 9.81f64.sqrt();
                (w - r).abs() / r
            })
            .collect();
        println!("hanging chain, {links} links: relative errors {e:?}");
        errs.push(e);
    }
    let bound = [3e-5, 1e-3, 4e-3];
    for i in 0..3 {
        assert!(errs[0][i] < bound[i], "mode {}: {}", i + 1, errs[0][i]);
        assert!(errs[1][i] < errs[0][i], "mode {}: no convergence", i + 1);
    }
}

/// `modes --at t=T` about a swinging physical pendulum: the state the run
/// reaches at T (reported in the JSON) and the linearised frequency about
/// it in closed form, ω² = (m g d cos φ + m d² φ̇²) / (I + m d²) (the
/// geometric stiffness of the pin force, which carries the weight and the
/// centripetal force), with the energy of the reported state equal to the
/// start's.
#[test]
fn cli_modes_about_the_state_of_a_run_at_t() {
    use std::process::Command;
    let dir = tempfile::tempdir().unwrap();
    let (m, ic, d, start) = (1.5, 0.08, 0.4, 50.0f64);
    let scen = dir.path().join("swing.toml");
    std::fs::write(&scen, pendulum(m, ic, d, start)).unwrap();
    let bin = env!("CARGO_BIN_EXE_mbsolve");
    let out = Command::new(bin)
        .args(["modes", "--count", "1", "--animate", "0", "--at", "t=0.23"])
        .arg(&scen)
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("swing.modes.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(r["at"], "t=0.23");
    assert!((r["t0"].as_f64().unwrap() - 0.23).abs() < 1e-12);
    let (phi, w) = (r["q"][2].as_f64().unwrap(), r["qd"][2].as_f64().unwrap());
    // the run moved: about a third of the way down from 50°, fast
    assert!(
        phi.abs() < 45f64.to_radians() && w.abs() > 1.0,
        "φ {phi}, φ̇ {w}"
    );
    let g = 9.81;
    let io = ic + m * d * d;
    let e0 = -m * g * d * start.to_radians().cos();
    let e = 0.5 * io * w * w - m * g * d * phi.cos();
    assert!((e - e0).abs() < 1e-3 * e0.abs(), "energy {e} vs {e0}");
    let want = ((m * g * d * phi.cos() + m * d * d * w * w) / io).sqrt() / (2.0 * PI);
    let got = r["modes"][0]["frequency_hz"].as_f64().unwrap();
    assert!((got - want).abs() < 1e-8 * want, "{got} vs {want} Hz");
    // a bad time is a named error
    let bad = Command::new(bin)
        .args(["modes", "--at", "t=abc"])
        .arg(&scen)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("t=abc"));
}

/// The shipped quarter car (bodies only: the road a driven body, the wheel
/// and the chassis held to vertical motion by drives): `modes` draws each
/// mode with the model's drawing (animated SVG, GIF, a PNG of the largest
/// deflection), and the motion drawn is the 2 × 2 closed form's shape —
/// body bounce (the wheel follows at (k_s − ω² m_s)/k_s ≈ 0.1 of the
/// chassis) and wheel hop (the wheel at ≈ −78 times the chassis).
#[test]
fn quarter_car_mode_animations_show_body_bounce_and_wheel_hop() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path();
    let scen = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/quarter_car.toml");
    let md = std::process::Command::new(env!("CARGO_BIN_EXE_mbsolve"))
        .args(["modes", scen, "--count", "2", "--animate", "2", "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(
        md.status.success(),
        "{}",
        String::from_utf8_lossy(&md.stderr)
    );
    let (ms, mu, ks, kt): (f64, f64, f64, f64) = (250.0, 35.0, 16000.0, 160000.0);
    let (a, b, c) = (ms * mu, -(ms * (ks + kt) + mu * ks), ks * kt);
    let disc = (b * b - 4.0 * a * c).sqrt();
    let w2 = [(-b - disc) / (2.0 * a), (-b + disc) / (2.0 * a)];
    for k in 0..2 {
        for ext in ["svg", "gif", "png"] {
            let p = out.join(format!("quarter_car.mode{}.{ext}", k + 1));
            assert!(std::fs::metadata(&p).unwrap().len() > 0, "{}", p.display());
        }
        let svg =
            std::fs::read_to_string(out.join(format!("quarter_car.mode{}.svg", k + 1))).unwrap();
        let hz = w2[k].sqrt() / (2.0 * PI);
        assert!(
            svg.contains(&format!("mode {}: {hz:.4} Hz", k + 1)),
            "no caption with {hz:.4} Hz"
        );
        let dec = png::Decoder::new(
            std::fs::File::open(out.join(format!("quarter_car.mode{}.png", k + 1))).unwrap(),
        );
        let info = dec.read_info().unwrap().info().clone();
        assert!(info.width >= 360 && info.height >= 360);
        // the drawn motion: rows 0 (the equilibrium) and 12 (a quarter of
        // the 48-frame period: the largest deflection)
        let mut r =
            csv::Reader::from_path(out.join(format!("quarter_car.mode{}.csv", k + 1))).unwrap();
        let h = r.headers().unwrap().clone();
        let col = |name: &str| h.iter().position(|c| c == name).unwrap();
        let rows: Vec<Vec<f64>> = r
            .records()
            .map(|x| x.unwrap().iter().map(|v| v.parse().unwrap()).collect())
            .collect();
        // the run table's named columns (body 2 is the wheel, 3 the chassis)
        let (yw, yc) = (col("wheel.y"), col("chassis.y"));
        let ratio = (rows[12][yw] - rows[0][yw]) / (rows[12][yc] - rows[0][yc]);
        let want = (ks - w2[k] * ms) / ks;
        println!("mode {}: wheel/chassis {ratio} vs {want}", k + 1);
        assert!(
            (ratio - want).abs() < 1e-8 * want.abs().max(1.0),
            "{ratio} vs {want}"
        );
        // x and φ held by the drives: no sideways or rotating motion drawn
        for name in ["wheel.x", "wheel.phi", "chassis.x", "chassis.phi"] {
            assert!(rows
                .iter()
                .all(|row| (row[col(name)] - rows[0][col(name)]).abs() < 1e-12));
        }
    }
}
