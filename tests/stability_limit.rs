//! The explicit methods' stability limit (issue 12 item 6,
//! `formulation::fastest_modes` and the check before an explicit run):
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
        sc.run.ode.max_steps = 200; // the warning comes before the run
        let (_, summary) =
            simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
        assert!(
            summary
                .warnings
                .iter()
                .any(|w| w.contains(&format!("the problem is stiff for {method}"))),
            "{method}: {:?}",
            summary.warnings
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
