//! The explicit methods' stability limit
//! (`formulation::fastest_modes` and the check before an explicit run):
//! the fastest mode of a pivoted spring chain against the same chain in
//! minimal coordinates (joint angles, written here), a fixed rk4 step just
//! above the limit refused with a message naming it and one just below it
//! running bounded, and the "stiff for" warning of the adaptive explicit
//! methods.

use mbsolve::formulation::fastest_modes;
use mbsolve::integrate::Method;
use mbsolve::{scenario, simulation};

const LINKS: usize = 3;
const MASS: f64 = 1.0;
const LENGTH: f64 = 1.0;

/// A pivoted chain of `LINKS` uniform links with joint springs `k`, `c`,
/// without gravity, started straight and at rest, under `method`.
fn chain(k: f64, c: f64, extra: &str) -> scenario::Scenario {
    let text = format!(
        r#"
gravity = [0.0, 0.0]
[[chain]]
name = "c"
links = {LINKS}
length = {LENGTH}
mass = {MASS}
stiffness = {k}
damping = {c}
pivot = true
angle_deg = 180.0
{extra}
[time]
end = 0.01
[output]
dt = 0.001
"#
    );
    scenario::parse(&text, "chain.toml", "chain", &[]).unwrap()
}

/// Largest `λ` of `K x = λ M x` for the chain in absolute link angles θ_k
/// about the straight configuration (minimal coordinates, independent of
/// the constrained formulation): `M_ij = m Σ_k a_ki a_kj + I δ_ij` with
/// the centre of link k moving by `a_kj = l` (j < k), `l/2` (j = k)
/// transversally, and `K` the joint springs `½ k Σ (θ_{k+1} − θ_k)²`.
/// Power iteration on `M⁻¹ K` with a dense solve.
fn largest_eigenvalue(k: f64) -> f64 {
    let n = LINKS;
    let a = |kk: usize, j: usize| match j.cmp(&kk) {
        std::cmp::Ordering::Less => LENGTH,
        std::cmp::Ordering::Equal => LENGTH / 2.0,
        std::cmp::Ordering::Greater => 0.0,
    };
    let inertia = MASS * LENGTH * LENGTH / 12.0;
    let mut m = vec![vec![0.0; n]; n];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..n).map(|kk| MASS * a(kk, i) * a(kk, j)).sum::<f64>();
            if i == j {
                *v += inertia;
            }
        }
    }
    let mut kmat = vec![vec![0.0; n]; n];
    for j in 0..n - 1 {
        kmat[j][j] += k;
        kmat[j + 1][j + 1] += k;
        kmat[j][j + 1] -= k;
        kmat[j + 1][j] -= k;
    }
    // solve M y = b by Gaussian elimination with partial pivoting
    let solve = |b: &[f64]| -> Vec<f64> {
        let mut aug: Vec<Vec<f64>> = m
            .iter()
            .zip(b)
            .map(|(r, &bi)| r.iter().copied().chain([bi]).collect())
            .collect();
        for col in 0..n {
            let p = (col..n)
                .max_by(|&x, &y| aug[x][col].abs().total_cmp(&aug[y][col].abs()))
                .unwrap();
            aug.swap(col, p);
            let pivot = aug[col].clone();
            for row in aug.iter_mut().skip(col + 1) {
                let f = row[col] / pivot[col];
                for (v, p) in row.iter_mut().zip(&pivot).skip(col) {
                    *v -= f * p;
                }
            }
        }
        let mut x = vec![0.0; n];
        for r in (0..n).rev() {
            let s: f64 = (r + 1..n).map(|cc| aug[r][cc] * x[cc]).sum();
            x[r] = (aug[r][n] - s) / aug[r][r];
        }
        x
    };
    let mut x: Vec<f64> = (0..n).map(|i| 1.0 + i as f64).collect();
    let mut lambda = 0.0;
    for _ in 0..2000 {
        let kx: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| kmat[i][j] * x[j]).sum())
            .collect();
        let y = solve(&kx);
        let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
        lambda = y.iter().zip(&x).map(|(a, b)| a * b).sum::<f64>()
            / x.iter().map(|v| v * v).sum::<f64>();
        x = y.iter().map(|v| v / norm).collect();
    }
    lambda
}

#[test]
fn fastest_mode_matches_minimal_coordinates() {
    let (k, c) = (1.0e4, 2.0);
    let sc = chain(k, c, "");
    let modes = fastest_modes(&sc.system, 0.0, &sc.q0, &sc.qd0, 200).unwrap();
    let lambda = largest_eigenvalue(k);
    let omega = lambda.sqrt();
    // joint dampers have the springs' pattern: σ_max = (c / k) ω²_max
    let sigma = c / k * lambda;
    println!(
        "ω: {:.10e} (minimal coordinates {omega:.10e}); σ: {:.10e} ({sigma:.10e})",
        modes.omega, modes.sigma
    );
    assert!((modes.omega / omega - 1.0).abs() < 1e-8);
    assert!((modes.sigma / sigma - 1.0).abs() < 1e-8);
    // the limit of a method is its reach over the fastest rate
    let reach = mbsolve::formulation::explicit_reach(Method::Rk4).unwrap();
    assert!((modes.step_limit(reach) - reach / omega.max(sigma)).abs() < 1e-12);
}

#[test]
fn rk4_above_the_limit_is_refused_and_below_it_runs_bounded() {
    let k = 1.0e4;
    let omega = largest_eigenvalue(k).sqrt();
    let limit = 2.785 / omega;
    // above: refused before the run, naming the limit
    let above = chain(
        k,
        0.0,
        &format!(
            "[integrator]\nmethod = \"rk4\"\nstep = {:e}\n",
            1.05 * limit
        ),
    );
    let Err(err) = simulation::simulate(&above.system, &above.q0, &above.qd0, &above.run, &mut [])
    else {
        panic!("a step above the stability limit must be refused");
    };
    let msg = err.to_string();
    println!("{msg}");
    let simulation::SimulationError::Unstable { limit: l, .. } = err else {
        panic!("expected SimulationError::Unstable, got {msg}");
    };
    assert!((l / limit - 1.0).abs() < 1e-6, "limit {l} vs {limit}");
    assert!(msg.contains("stability limit") && msg.contains(&format!("{l:.3e}")));

    // below: runs bounded from a start with the joints bending at ±1 rad/s
    // (above the limit the fastest mode grows by ≈ 1.25 per step)
    let start = "[initial]\nconsistent = true\n\
                 [[initial.joint]]\nname = \"c.joint[1]\"\nangle = 0.0\nrate = 1.0\n\
                 [[initial.joint]]\nname = \"c.joint[2]\"\nangle = 0.0\nrate = -1.0\n";
    let mut below = chain(
        k,
        0.0,
        &format!(
            "{start}[integrator]\nmethod = \"rk4\"\nstep = {:e}\n",
            0.95 * limit
        ),
    );
    below.run.t_end = 4000.0 * 0.95 * limit;
    let (traj, summary) =
        simulation::simulate(&below.system, &below.q0, &below.qd0, &below.run, &mut []).unwrap();
    assert_eq!(summary.status, "completed", "{:?}", summary.message);
    let vmax = |qd: &[f64]| qd.iter().map(|v| v.abs()).fold(0.0, f64::max);
    let (v0, v1) = (vmax(&traj.qd[0]), vmax(traj.qd.last().unwrap()));
    println!(
        "max |q̇|: {v0:.3e} at t0, {v1:.3e} at {:.3e} s",
        summary.t_reached
    );
    assert!(v0 > 0.5, "the start must move: {v0}");
    assert!(
        v1.is_finite() && v1 < 2.0 * v0,
        "velocities grew from {v0} to {v1}"
    );
}

#[test]
fn adaptive_explicit_methods_warn_that_the_problem_is_stiff() {
    for method in ["ode23", "ode45", "ode113"] {
        let mut sc = chain(
            1.0e10,
            0.0,
            &format!("[integrator]\nmethod = \"{method}\"\n"),
        );
        sc.run.t_end = 1.0;
        // the warning comes before the run; the sink stops it at once
        let mut sink = FirstRow::default();
        simulation::simulate_into(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [], &mut sink)
            .unwrap();
        assert!(
            sink.0
                .iter()
                .any(|w| w.contains(&format!("the problem is stiff for {method}"))),
            "{method}: {:?}",
            sink.0
        );
        // more steps than the cap (2.9e5 > 200): refused, naming the element
        sc.run.ode.max_steps = 200;
        let err = simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(&format!("too stiff for {method}"))
                && err.contains("more than the cap of 2.0e2")
                && err.contains("torsional spring-damper"),
            "{err}"
        );
    }
    // a soft chain over a short span gets no such warning
    let sc = chain(10.0, 0.0, "[integrator]\nmethod = \"ode113\"\n");
    let (_, summary) = simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert!(
        !summary.warnings.iter().any(|w| w.contains("stiff for")),
        "{:?}",
        summary.warnings
    );
}

/// The issue's case: the falling rod at N = 8000 under rk4 with h = 1e-9
/// grew to 1e61 N and ended in a "singular saddle-point matrix"; now it
/// stops at once (exit 2, no output rows) with the limit and the mode.
#[test]
fn falling_rod_rk4_above_its_limit_stops_at_once() {
    let dir = std::env::temp_dir().join(format!("mbsolve-stability-{}", std::process::id()));
    let scenario =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/falling_rod.toml");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_mbsolve"))
        .args(["run"])
        .arg(&scenario)
        .args([
            "--set",
            "rod.segments=8000",
            "--set",
            "integrator.method=\"rk4\"",
            "--set",
            "integrator.step=1e-9",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stderr}");
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("rk4 with step 1e-9 s (integrator.step) is unstable"),
        "{stderr}"
    );
    // the limit is printed and lies below the step
    let limit: f64 = stderr
        .split("stability limit is ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .expect("the limit in the message");
    assert!(limit > 0.0 && limit < 1e-9, "{limit}");
    assert!(!stderr.contains("singular"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A slider on a guide along x, pushed by a spring from the ground point
/// (0, d) compressed to length d < L0: the potential ½ k (r − L0)²,
/// r = √(x² + d²), has V''(0) = k (1 − L0/d) < 0, so the equilibrium
/// x = 0 is unstable with growth rate γ = √(k (L0/d − 1) / m).
fn compressed_slider(k: f64, free_length: f64, extra: &str) -> scenario::Scenario {
    let text = format!(
        r#"
gravity = [0.0, 0.0]
[[body]]
name = "slider"
mass = 2.0
inertia = 0.1
[[joint]]
type = "translational"
name = "guide"
body_i = "ground"
point_i = [0.0, 0.0]
axis_i = [1.0, 0.0]
body_j = "slider"
point_j = [0.0, 0.0]
[[force]]
type = "spring"
name = "push"
body_i = "ground"
point_i = [0.0, 0.5]
body_j = "slider"
point_j = [0.0, 0.0]
free_length = {free_length}
stiffness = {k}
{extra}
[time]
end = 1.0
[output]
dt = 0.01
"#
    );
    scenario::parse(&text, "slider.toml", "slider", &[]).unwrap()
}

#[test]
fn growth_rate_of_a_compressed_spring_matches_its_potential() {
    let (k, l0, d, m) = (1.0e3, 0.8, 0.5, 2.0);
    let sc = compressed_slider(k, l0, "");
    let modes = fastest_modes(&sc.system, 0.0, &sc.q0, &sc.qd0, 200).unwrap();
    let gamma = (k * (l0 / d - 1.0) / m).sqrt();
    println!("γ = {:.10e} (analytic {gamma:.10e})", modes.growth);
    assert!((modes.growth / gamma - 1.0).abs() < 1e-8, "{modes:?}");
    // the spring is the source of the growth
    assert_eq!(modes.sources[2], Some(0), "{modes:?}");
    // stretched instead (L0 < d): stable along the guide, no growth
    let sc = compressed_slider(k, 0.3, "");
    let modes = fastest_modes(&sc.system, 0.0, &sc.q0, &sc.qd0, 200).unwrap();
    assert_eq!(modes.growth, 0.0, "{modes:?}");
}

/// Collects the warnings and stops the run at its first output.
#[derive(Default)]
struct FirstRow(Vec<String>);

impl simulation::Sink for FirstRow {
    fn output(
        &mut self,
        _: &simulation::Sample<'_>,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Err("stopped by the test".into())
    }
    fn warning(&mut self, message: &str) {
        self.0.push(message.to_string());
    }
}

#[test]
fn statically_unstable_start_warns_and_refuses_beyond_the_step_cap() {
    let methods = [
        "method = \"ode45\"",
        "method = \"genalpha\"\nadaptive = true",
    ];
    for method in methods {
        let start = |k: f64| {
            let sc = compressed_slider(k, 0.8, &format!("[integrator]\n{method}\n"));
            let mut sink = FirstRow::default();
            simulation::simulate_into(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [], &mut sink)
                .map(|_| sink.0)
        };
        // k = 1e18: γ = √(k · 0.3) ≈ 5.5e8 1/s, more steps over the span of
        // 1 s than the cap of 5e7: refused before any step, naming the
        // element and the rate
        let err = start(1e18).unwrap_err().to_string();
        println!("{method}: {err}");
        assert!(err.contains("statically unstable"), "{err}");
        assert!(
            err.contains("force[0] 'push' (point spring-damper"),
            "{err}"
        );
        assert!(err.contains("γ = 5.477e8"), "{err}");
        // k = 1e12: γ ≈ 5.5e5 1/s, 5.5e5 steps: a warning
        let warnings = start(1e12).unwrap();
        assert!(
            warnings
                .iter()
                .any(|w| w.contains("statically unstable") && w.contains("γ = 5.477e5")),
            "{method}: {warnings:?}"
        );
        // k = 1e3: γ ≈ 17 1/s: nothing
        let warnings = start(1e3).unwrap();
        assert!(
            !warnings.iter().any(|w| w.contains("unstable")),
            "{method}: {warnings:?}"
        );
    }
}

/// Loads out of scale: the two rods' brace with a free length of 1e6 m
/// pushes with 2.8e8 N; the run would take minutes. The warning at t0
/// names the element and the time scale √(2 L / a) against the span.
#[test]
fn loads_out_of_scale_are_named_before_the_run() {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/two_rods.toml");
    let start = |free_length: &str| {
        let sc = scenario::load(&p, &[format!("force[0].free_length={free_length}")]).unwrap();
        let mut sink = FirstRow::default();
        simulation::simulate_into(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [], &mut sink)
            .map(|_| sink.0)
    };
    let warnings = start("1e6").unwrap();
    let w = warnings
        .iter()
        .find(|w| w.contains("the loads at t0 accelerate body"))
        .unwrap_or_else(|| panic!("{warnings:?}"));
    // the brace is force[0] of the file (element #18 after the rods' 18
    // torsional springs), named as the file names it; its force
    // k (L0 − L) = 200 · (1e6 − 0.707) N
    assert!(w.contains("force[0] 'brace' (point spring-damper"), "{w}");
    assert!(!w.contains("#18"), "{w}");
    assert!(w.contains("norm 2.829e8"), "{w}");
    // the shipped free length: nothing
    let warnings = start("0.7071067811865476").unwrap();
    assert!(
        !warnings.iter().any(|w| w.contains("loads")),
        "{warnings:?}"
    );
    // 1e12 m: more crossings than the step cap, refused
    let err = start("1e12").unwrap_err().to_string();
    assert!(err.contains("more than the cap of 5.0e7 steps"), "{err}");
}
