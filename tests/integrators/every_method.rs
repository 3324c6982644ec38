//! Every constraint-enforcement method, selected by
//! scenario keys, converges to the same motion — on the four-bar against
//! ode45 at rtol 1e-12 (an independent run of eq. (5) with projection), on
//! the driven slider-crank against its closed-form kinematics — and the
//! fixed-step index-3 methods with their order 2. (The penalty method
//! converges as its penalty grows: tests/formulation/constraint_methods.rs,
//! `penalty_violation_falls_like_one_over_alpha`.)

use mbsolve::scenario::{self, Scenario, FOURBAR_TOML};
use mbsolve::simulation::{simulate, Trajectory};

const SLIDER_TOML: &str = include_str!("../../scenarios/slider_crank.toml");

fn parse(text: &str, overrides: &[&str]) -> Scenario {
    crate::common::setup::parse(text, overrides).unwrap()
}

fn run(text: &str, overrides: &[&str]) -> Trajectory {
    let sc = parse(text, overrides);
    let (t, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.status, "completed", "{overrides:?}: {:?}", s.message);
    t
}

/// The methods: label, scenario keys (tolerances or step added by the
/// caller), and whether they take a fixed step (order 2).
const METHODS: &[(&str, &[&str], bool)] = &[
    ("eq. (5)", &["integrator.method=ode45"], false),
    (
        "Baumgarte α = β = 10",
        &[
            "integrator.method=ode45",
            "stabilization.alpha=10",
            "stabilization.rule=\"equal\"",
        ],
        false,
    ),
    (
        "eq. (9), λ eliminated",
        &[
            "integrator.method=ode45",
            "formulation=eliminated",
            "stabilization.alpha=10",
            "stabilization.rule=\"equal\"",
        ],
        false,
    ),
    (
        "projection",
        &["integrator.method=ode45", "stabilization.projection=true"],
        false,
    ),
    (
        "direct correction",
        &[
            "integrator.method=ode45",
            "stabilization.projection=true",
            "stabilization.correction=\"direct\"",
        ],
        false,
    ),
    (
        "step rule α = β = 1/h",
        &[
            "integrator.method=ode45",
            "integrator.max_step=1e-3",
            "stabilization.rule=\"step\"",
        ],
        false,
    ),
    (
        "partitioning",
        &["integrator.method=ode45", "formulation=partitioned"],
        false,
    ),
    ("bdf", &["integrator.method=bdf"], false),
    (
        "augmented Lagrangian, trapezoidal",
        &[
            "integrator.method=trapezoidal",
            "formulation=augmented_lagrangian",
        ],
        true,
    ),
    (
        "augmented Lagrangian, generalized-α",
        &[
            "integrator.method=genalpha",
            "formulation=augmented_lagrangian",
        ],
        true,
    ),
    ("generalized-α", &["integrator.method=genalpha"], true),
    (
        "generalized-α + projection",
        &["integrator.method=genalpha", "integrator.project=true"],
        true,
    ),
];

fn with(base: &[&str], extra: &[String]) -> Vec<String> {
    base.iter()
        .map(|s| s.to_string())
        .chain(extra.iter().cloned())
        .collect()
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(|s| s.as_str()).collect()
}

/// Largest coordinate difference over the common output times.
fn deviation(a: &Trajectory, b: &Trajectory) -> f64 {
    assert_eq!(a.t.len(), b.t.len());
    a.q.iter()
        .zip(&b.q)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v).abs()))
        .fold(0.0, f64::max)
}

#[test]
fn every_method_follows_ode45_on_the_four_bar() {
    let common = ["time.end=1.0", "output.dt=0.01", "output.quantities=[]"];
    let reference = run(
        FOURBAR_TOML,
        &[
            &common[..],
            &[
                "integrator.method=ode45",
                "integrator.rtol=1e-12",
                "integrator.atol=1e-14",
                "stabilization.projection=true",
            ],
        ]
        .concat(),
    );
    for (label, keys, fixed) in METHODS {
        let base: Vec<&str> = common.iter().chain(keys.iter()).copied().collect();
        if *fixed {
            // order 2: the error falls ≈ 4× per halving of h
            let errs: Vec<f64> = [1e-4, 5e-5]
                .iter()
                .map(|h| {
                    let o = with(&base, &[format!("integrator.step={h}")]);
                    deviation(&run(FOURBAR_TOML, &strs(&o)), &reference)
                })
                .collect();
            let rate = (errs[0] / errs[1]).log2();
            eprintln!(
                "four-bar, {label}: {:.3e} → {:.3e}, order {rate:.2}",
                errs[0], errs[1]
            );
            assert!(errs[1] < 1e-4, "{label}: {:e}", errs[1]);
            assert!((1.7..2.4).contains(&rate), "{label}: order {rate}");
        } else {
            let o = with(
                &base,
                &[
                    "integrator.rtol=1e-10".into(),
                    "integrator.atol=1e-12".into(),
                ],
            );
            let e = deviation(&run(FOURBAR_TOML, &strs(&o)), &reference);
            eprintln!("four-bar, {label}: {e:.3e}");
            assert!(e < 1e-4, "{label}: {e:e}");
        }
    }
}

#[test]
fn every_method_follows_the_slider_crank_kinematics() {
    // driven at φ = 10 t: the slider's x = r cos φ + √(l² − r² sin² φ)
    // (r = 0.1, l = 0.3); the shipped file's ode45 tolerances are dropped
    // so that each method sets its own
    let text = SLIDER_TOML
        .replace("rtol = 1e-10\n", "")
        .replace("atol = 1e-12\n", "");
    let (r, l) = (0.1_f64, 0.3_f64);
    let common = ["time.end=0.7", "output.dt=0.01", "output.quantities=[]"];
    for (label, keys, fixed) in METHODS {
        let base: Vec<&str> = common.iter().chain(keys.iter()).copied().collect();
        let extra: Vec<String> = if *fixed {
            vec!["integrator.step=1e-4".into()]
        } else {
            vec![
                "integrator.rtol=1e-10".into(),
                "integrator.atol=1e-12".into(),
            ]
        };
        let o = with(&base, &extra);
        let t = run(&text, &strs(&o));
        let e =
            t.t.iter()
                .zip(&t.q)
                .map(|(tk, q)| {
                    let phi = 10.0 * tk;
                    let x = r * phi.cos() + (l * l - r * r * phi.sin().powi(2)).sqrt();
                    (q[6] - x).abs()
                })
                .fold(0.0, f64::max);
        eprintln!("slider-crank, {label}: {e:.3e} m");
        assert!(e < 1e-6, "{label}: {e:e}");
    }
}

/// A method-table alias fixes its parameter: `trapezoidal` is newmark
/// with ρ∞ = 1 (β = ¼, γ = ½), and giving `integrator.rho_inf` as well
/// is an error naming the key and what the alias fixes.
#[test]
fn the_trapezoidal_alias_is_newmark_with_rho_inf_one() {
    let keys = ["integrator.method=trapezoidal", "integrator.step=1e-3"];
    let sc = parse(FOURBAR_TOML, &keys);
    assert_eq!(sc.run.method, mbsolve::integrate::Method::Newmark);
    assert_eq!(sc.run.implicit.rho_inf, 1.0);
    let o: Vec<String> = keys
        .iter()
        .map(|s| s.to_string())
        .chain(["integrator.rho_inf=0.5".to_string()])
        .collect();
    let e = scenario::parse(FOURBAR_TOML, "test.toml", "test", &o)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("integrator.rho_inf")
            && e.contains("0.5 is given, but method = \"trapezoidal\" is newmark with rho_inf = 1"),
        "{e}"
    );
}

/// The rows an implicit method interpolates between its steps have their
/// positions projected onto `Φ(q, t) = 0`: on the driven slider-crank (no
/// degree of freedom, so the constraints alone fix the positions) every
/// output row's slider position matches the closed form
/// `x = r cos φ + √(l² − r² sin² φ)`, `φ = 10 t`, to the step ends'
/// Newton tolerance (bound 1e-7 m at rtol 1e-5), although the adaptive
/// steps span many output intervals and the interpolants alone are off by
/// 1e-5 … 1e-3 m. The projection touches only what is written: steps,
/// Newton iterations and the final state are the same bits with 51
/// output rows as with 2.
#[test]
fn implicit_output_rows_between_steps_lie_on_the_constraints() {
    let text = SLIDER_TOML
        .replace("rtol = 1e-10\n", "")
        .replace("atol = 1e-12\n", "");
    let (r, l) = (0.1_f64, 0.3_f64);
    let exact = |t: f64| {
        let (phi, w) = (10.0 * t, 10.0);
        let root = (l * l - r * r * phi.sin().powi(2)).sqrt();
        let x = r * phi.cos() + root;
        let xd = -r * w * phi.sin() - r * r * w * phi.sin() * phi.cos() / root;
        (x, xd)
    };
    let methods: [&[&str]; 4] = [
        &["integrator.method=radau5", "integrator.adaptive=true"],
        &["integrator.method=genalpha", "integrator.adaptive=true"],
        &["integrator.method=bdf"],
        &["integrator.method=bdf", "integrator.ndf=true"],
    ];
    for keys in methods {
        let common = [
            "time.end=0.5",
            "output.quantities=[]",
            "integrator.rtol=1e-5",
            "integrator.atol=1e-8",
        ];
        let base: Vec<&str> = common.iter().chain(keys.iter()).copied().collect();
        let go = |dt: &str| {
            let o = with(&base, &[format!("output.dt={dt}")]);
            let sc = parse(&text, &strs(&o));
            let (t, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
            assert_eq!(s.status, "completed", "{keys:?}: {:?}", s.message);
            (t, s)
        };
        let ((dense, sd), (sparse, ss)) = (go("0.01"), go("0.5"));
        assert_eq!(dense.t.len(), 51, "{keys:?}");
        let (mut ex, mut ev) = (0.0_f64, 0.0_f64);
        for ((tk, q), qd) in dense.t.iter().zip(&dense.q).zip(&dense.qd) {
            let (x, xd) = exact(*tk);
            ex = ex.max((q[6] - x).abs());
            ev = ev.max((qd[6] - xd).abs());
        }
        eprintln!(
            "{keys:?}: {} steps, rows off by {ex:.2e} m, {ev:.2e} m/s",
            sd.steps
        );
        assert!(ex <= 1e-7, "{keys:?}: {ex:e} m");
        assert_eq!(sd.steps, ss.steps, "{keys:?}");
        assert_eq!(
            sd.extra.get("newton_iterations"),
            ss.extra.get("newton_iterations")
        );
        let (qd_end, qs_end) = (dense.q.last().unwrap(), sparse.q.last().unwrap());
        assert!(
            qd_end
                .iter()
                .zip(qs_end)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{keys:?}: the final state depends on the output rows"
        );
    }
}
