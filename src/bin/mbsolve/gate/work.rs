//! The bench-gate's deterministic work counts: factorisations, residual
//! evaluations and solves per accepted step against the integrator's own
//! counts and the pinned values.

use super::Check;
use mbsolve::builders::{build_rod, stiff_chain, RodParams};
use mbsolve::formulation::{Index1, Index1Options};
use mbsolve::integrate::{Method, OdeOptions};
use mbsolve::linalg::SolverKind;

/// Work counts of fixed runs, deterministic (no timing): per accepted
/// step, the factorisations, residual evaluations and linear solves the
/// solver and the formulation count themselves must equal those the
/// integrator asked for (a factorisation or solve done twice below the
/// integrator doubles them), and the integrator's own counts per step stay
/// within ±15 % of the pinned values ([`WORK_PINS`]; a change of the
/// Newton strategy moves them on purpose and updates the pins with its
/// reason).
pub fn work_counts() -> Vec<Check> {
    use mbsolve::formulation::Index3;
    use mbsolve::integrate::{Bdf, GenAlpha, ImplicitOptions, Tolerance};
    let mut checks = Vec::new();
    let (sys, q0, qd0, _) = match stiff_chain(100, 5f64.to_radians()) {
        Ok(c) => c,
        Err(e) => {
            return vec![Check {
                name: "work counts".into(),
                ratio: f64::INFINITY,
                threshold: 0.0,
                at_most: true,
                passed: false,
                detail: e.to_string(),
            }]
        }
    };
    let t_end = 2e-3;
    for (what, pins) in WORK_PINS {
        let mut f = Index3::new(&sys, SolverKind::Auto).expect("formulation");
        let ode = if what.starts_with("genalpha") {
            OdeOptions {
                fixed_step: Some(1e-5),
                ..Default::default()
            }
        } else {
            OdeOptions {
                rtol: 1e-6,
                atol: Tolerance::Scalar(1e-9),
                ..Default::default()
            }
        };
        let span = mbsolve::integrate::Span {
            t0: 0.0,
            t_end,
            q0: &q0,
            qd0: &qd0,
            output_times: &[t_end],
            obs: &mut (),
        };
        let run = if what.starts_with("genalpha") {
            let mut g =
                GenAlpha::new(Method::GenAlpha, ImplicitOptions::default(), ode).expect("options");
            g.integrate(&mut f, span).map(|r| (r, g.stats()))
        } else {
            let mut b = Bdf::new(ode).expect("options");
            b.integrate(&mut f, span).map(|r| (r, b.stats()))
        };
        let (rep, st) = match run {
            Ok((rep, st)) if rep.termination == mbsolve::integrate::Termination::Completed => {
                (rep, st)
            }
            Ok((rep, _)) => {
                checks.push(failed_count(what, format!("{:?}", rep.termination)));
                continue;
            }
            Err(e) => {
                checks.push(failed_count(what, e.to_string()));
                continue;
            }
        };
        let fs = f.stats();
        let steps = st.steps.max(1) as f64;
        // below the integrator: the solver's and the formulation's own counts
        // (the initial accelerations use the mass matrix's solver)
        let same = [
            (
                "Newton-matrix factorisations (solver / integrator)",
                fs.newton_solver.factorizations,
                st.factorizations,
            ),
            (
                "Newton solves (solver / integrator's corrections)",
                fs.newton_solver.solves,
                st.newton_iterations,
            ),
            (
                "residual evaluations (formulation / integrator)",
                fs.residuals,
                st.residual_evaluations,
            ),
        ];
        for (name, below, asked) in same {
            // the integrator counts its initial accelerations as one
            // residual evaluation; the formulation counts them apart
            let below = if name.starts_with("residual") {
                below + 1
            } else {
                below
            };
            let r = below as f64 / asked.max(1) as f64;
            checks.push(Check {
                name: format!("work count, {what}: {name}"),
                ratio: r,
                threshold: 1.0,
                at_most: true,
                passed: below == asked,
                detail: format!("{below} counted by the solver/formulation, {asked} asked for"),
            });
        }
        let per_step = [
            ("factorisations", st.factorizations as f64 / steps),
            (
                "residual evaluations",
                st.residual_evaluations as f64 / steps,
            ),
            ("Newton solves", st.newton_iterations as f64 / steps),
        ];
        for ((name, got), pin) in per_step.into_iter().zip(pins) {
            let r = got / pin;
            checks.push(Check {
                name: format!("work count, {what}: {name} per step over the pin {pin}"),
                ratio: r,
                threshold: 1.15,
                at_most: true,
                passed: (1.0 / 1.15..=1.15).contains(&r),
                detail: format!(
                    "{got:.3} per step ({} steps, {} rejected); at least 1/1.15 of the pin too",
                    st.steps, rep.stats.failed_steps
                ),
            });
        }
    }
    // the index-1 right-hand side: one factorisation and one solve each
    let (rod, _) = build_rod(&RodParams::problem_b(200)).expect("problem B builds");
    let (q, qd) = rod.initial_state();
    let opts = Index1Options {
        linear_solver: SolverKind::Sparse,
        ..Default::default()
    };
    let mut f = Index1::new(&rod, opts).expect("formulation");
    let mut qdd = vec![0.0; rod.n_coords()];
    let before = f.stats();
    for _ in 0..10 {
        f.accelerations(0.0, &q, &qd, &mut qdd)
            .expect("RHS evaluates");
    }
    let after = f.stats();
    let fac = after.solver.factorizations - before.solver.factorizations;
    let sol = after.solver.solves - before.solver.solves;
    let evals = after.evaluations - before.evaluations;
    checks.push(Check {
        name: "work count, index-1 RHS (falling rod N = 200, sparse): factorisations and solves per evaluation".into(),
        ratio: (fac + sol) as f64 / (2 * evals).max(1) as f64,
        threshold: 1.0,
        at_most: true,
        passed: fac == evals && sol == evals,
        detail: format!("{evals} evaluations: {fac} factorisations, {sol} solves"),
    });
    checks
}

fn failed_count(what: &str, detail: String) -> Check {
    Check {
        name: format!("work counts, {what}"),
        ratio: f64::INFINITY,
        threshold: 1.0,
        at_most: true,
        passed: false,
        detail,
    }
}

/// Pinned work per accepted step on the stiff chain (N = 100, from rest,
/// 0 … 2 ms): factorisations, residual evaluations, Newton solves, for
/// generalized-α at h = 1e-5 and bdf at rtol 1e-6, atol 1e-9 (pins of
/// the clean build's counts, docs/scaling.md "Gate").
pub const WORK_PINS: [(&str, [f64; 3]); 2] = [
    (
        "genalpha h = 1e-5, stiff chain N = 100",
        [0.941, 3.158, 3.153],
    ),
    ("bdf rtol 1e-6, stiff chain N = 100", [0.142, 2.152, 2.149]),
];
