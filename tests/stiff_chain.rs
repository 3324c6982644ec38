//! The cantilevered stiff chain of the peer comparisons (issue 12):
//! the builder against the peers' independent reference (SciPy Radau at
//! rtol 1e-10 on two hand-derived minimal-coordinate models) at N = 10,
//! with the index-1 path (ode45) and generalized-α.

use mbsolve::builders::{stiff_chain, stiff_chain_reference_tip, stiff_chain_tip_x};
use mbsolve::integrate::{Method, Tolerance};
use mbsolve::simulation::{simulate, RunConfig};

fn tip_at_end(method: Method, h: Option<f64>, rtol: f64) -> (f64, usize, Option<u64>) {
    let (sys, q0, qd0, info) = stiff_chain(10, 5f64.to_radians()).unwrap();
    let mut cfg = RunConfig {
        method,
        t_end: 0.1,
        output_dt: 0.1,
        ..Default::default()
    };
    cfg.ode.fixed_step = h;
    if h.is_none() {
        cfg.ode.rtol = rtol;
        cfg.ode.atol = Tolerance::Scalar(rtol * 1e-2);
    }
    let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
    assert_eq!(s.status, "completed", "{s:?}");
    let q = traj.q.last().unwrap();
    (
        stiff_chain_tip_x(&info, q),
        s.steps,
        s.extra.get("newton_iterations").and_then(|v| v.as_u64()),
    )
}

#[test]
fn stiff_chain_n10_matches_the_peer_reference() {
    let reference = stiff_chain_reference_tip(10).unwrap();
    // the initial tip: 1 m at 5°
    let (sys, q0, _, info) = stiff_chain(10, 5f64.to_radians()).unwrap();
    assert!((stiff_chain_tip_x(&info, &q0) - 5f64.to_radians().sin()).abs() < 1e-14);
    let mut phi = vec![0.0; sys.n_constraints()];
    sys.phi(&q0, 0.0, &mut phi);
    assert!(phi.iter().all(|p| p.abs() < 1e-15), "{phi:?}");

    let (x, steps, _) = tip_at_end(Method::Ode45, None, 1e-9);
    eprintln!(
        "ode45 rtol 1e-9: tip {x:.12} ({steps} steps), error {:.2e}",
        x - reference
    );
    assert!((x - reference).abs() < 1e-8, "ode45: {x} vs {reference}");
    // generalized-α (ρ∞ = 0.8) converges to the same tip, second order
    let mut errors = Vec::new();
    for h in [2e-5, 1e-5, 5e-6] {
        let (x, steps, its) = tip_at_end(Method::GenAlpha, Some(h), 0.0);
        let e = (x - reference).abs();
        eprintln!(
            "genalpha h {h:e}: tip {x:.12} ({steps} steps, {:.2} Newton iterations per step), \
             error {e:.2e}",
            its.unwrap() as f64 / steps as f64
        );
        errors.push(e);
    }
    assert!(errors[0] < 2e-5, "{errors:?}");
    for w in errors.windows(2) {
        let order = (w[0] / w[1]).log2();
        assert!((1.7..2.5).contains(&order), "order {order}: {errors:?}");
    }
}
