//! What the messages of a failing or drifting run say is true: a rank
//! statement at a Newton stop comes from the factorisations that ran at the
//! system's full size, and the advice of a drift warning names only keys
//! the chosen method accepts.

use crate::common::cli::{mbsolve, scenario, stderr, stdout};
use std::path::Path;

/// The summary of a run written into `dir`.
fn summary(dir: &Path, stem: &str) -> serde_json::Value {
    let p = dir.join(format!("{stem}.summary.json"));
    serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap()
}

/// `mbsolve check`'s "rank of Phi_q" line for the chain with `sets`.
fn checked_rank(sets: &[&str]) -> usize {
    let chain = scenario("parallelogram_chain.toml");
    let mut args = vec!["check", chain.as_str()];
    for s in sets {
        args.extend(["--set", s]);
    }
    let o = mbsolve(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let line = out
        .lines()
        .find(|l| l.starts_with("rank of Phi_q"))
        .unwrap_or_else(|| panic!("no rank line in:\n{out}"));
    line.split_whitespace().nth(3).unwrap().parse().unwrap()
}

/// The IFToMM A02 chain (40 parallelogram loops, 243 coordinates, 242
/// constraint rows, one degree of freedom) is far beyond the size of the
/// dense rank monitor, so the message at a Newton stop of generalized-α
/// (index 3) may only report what the sparse LDLᵀ factorisations of the
/// Newton matrix found. `integrator.max_newton = 1` makes every step fail
/// (the step is cut to nothing at t = 0) without changing the matrices.
/// - Off the singular positions (θ0 = 0.3 rad) Φ_q has full rank 242
///   (one degree of freedom): the message says no factorisation found a
///   regularised pivot, with their number and the system's size as in the
///   summary, and does not exclude a nearly singular position.
/// - At the singular position (θ0 = 0: all bars on the ground line, each
///   of the 40 loops loses one rank, rank 202) the message counts the
///   regularised pivots of the summary and points to the augmented
///   Lagrangian.
///
/// In both, `mbsolve check` reports the analytic rank, and no message
/// claims a rank it did not test ("kept its rank").
#[test]
fn a_newton_stop_on_the_a02_chain_states_only_the_rank_its_factorisations_saw() {
    for (theta0, rank) in [("0.3", 242), ("0", 202)] {
        let theta = format!("parameters.theta0={theta0}");
        assert_eq!(checked_rank(&[&theta]), rank, "θ0 = {theta0}");
        let dir = tempfile::tempdir().unwrap();
        let chain = scenario("parallelogram_chain.toml");
        let o = mbsolve(&[
            "run",
            &chain,
            "--unset",
            "formulation",
            "--set",
            &theta,
            "--set",
            "integrator.step=1e-4",
            "--set",
            "integrator.max_newton=1",
            "--set",
            "time.end=0.01",
            "--quiet",
            "--out",
            dir.path().to_str().unwrap(),
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "θ0 = {theta0}: {err}");
        let s = summary(dir.path(), "parallelogram_chain");
        assert_eq!(s["status"], "failed");
        assert_eq!(s["formulation"], "index3");
        assert_eq!(s["coordinates"], 243);
        let msg = s["message"].as_str().unwrap();
        assert!(msg.contains("Newton does not converge"), "{msg}");
        assert!(
            err.contains(msg),
            "the console repeats the summary's message"
        );
        for never in ["kept its rank", "not a singular position"] {
            assert!(!msg.contains(never), "θ0 = {theta0}: '{never}' in {msg}");
        }
        let fact = s["factorizations"].as_u64().unwrap();
        let pivots = s["regularized_pivots"].as_u64().unwrap();
        let indefinite = s["indefinite_pivots"].as_u64().unwrap();
        assert!(fact > 0);
        assert_eq!(indefinite, 0, "θ0 = {theta0}: {msg}");
        if rank == 242 {
            assert_eq!(pivots, 0, "{msg}");
            let said = format!(
                "no regularised pivot in the {fact} factorisations of the Newton matrix \
                 (243 coordinates)"
            );
            assert!(msg.contains(&said), "{msg}");
            assert!(
                msg.contains("nearly singular position is not excluded"),
                "{msg}"
            );
        } else {
            assert!(pivots > 0, "{msg}");
            let said = format!("{pivots} regularised pivots: if the position is singular");
            assert!(msg.contains(&said), "{msg}");
            assert!(msg.contains("augmented_lagrangian"), "{msg}");
        }
    }
}

/// A drift warning under generalized-α advises what that method accepts:
/// `integrator.project` (Baumgarte terms and `stabilization.projection`
/// are refused for it). The four-bar at h = 5e-3 drifts at the velocity
/// level beyond 100 (rtol V + atol); following the advice is accepted, the
/// index-1 advice is refused (exit 2, an input error) with a message
/// naming `integrator.project`,
/// and with projection on the advice no longer asks for it.
#[test]
fn a_drift_warning_under_generalized_alpha_advises_integrator_project() {
    let fourbar = scenario("fourbar.toml");
    let run = |extra: &[&str]| {
        let dir = tempfile::tempdir().unwrap();
        let mut args = vec![
            "run",
            fourbar.as_str(),
            "--set",
            "integrator.method=genalpha",
            "--set",
            "integrator.step=5e-3",
            "--quiet",
            "--out",
            dir.path().to_str().unwrap(),
        ];
        for e in extra {
            args.extend(["--set", e]);
        }
        let o = mbsolve(&args);
        let s = if o.status.success() {
            Some(summary(dir.path(), "fourbar"))
        } else {
            None
        };
        (o, s)
    };
    let drift_warnings = |s: &serde_json::Value| -> Vec<String> {
        s["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|w| w.as_str())
            .filter(|w| w.contains("constraint violation"))
            .map(String::from)
            .collect()
    };
    let (o, s) = run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = s.unwrap();
    assert_eq!(s["status"], "completed");
    let w = drift_warnings(&s);
    assert!(!w.is_empty(), "no drift warning: {:?}", s["warnings"]);
    for w in &w {
        assert!(w.contains("set integrator.project = true"), "{w}");
        for never in ["Baumgarte", "stabilization."] {
            assert!(!w.contains(never), "'{never}' advised to genalpha: {w}");
        }
    }
    // the advice is accepted …
    let (o, s) = run(&["integrator.project=true"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = s.unwrap();
    assert_eq!(s["status"], "completed");
    for w in drift_warnings(&s) {
        assert!(w.contains("integrator.project is already on"), "{w}");
        assert!(!w.contains("set integrator.project"), "{w}");
    }
    // … what an index-1 run would be told is refused, pointing to it
    for refused in ["stabilization.alpha=10", "stabilization.projection=true"] {
        let (o, _) = run(&[refused]);
        assert_eq!(o.status.code(), Some(2), "{refused} accepted");
        let err = stderr(&o);
        assert!(err.contains("integrator.project"), "{refused}: {err}");
    }
}
