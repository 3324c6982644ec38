//! The analyses with the chain LU (their default solver) against the same
//! analyses with faer's sparse LU: the static equilibrium of the peers'
//! stiff chain and its 10 lowest modes, N = 50, agree to rounding.

use crate::common::rel_diff;
use mbsolve::analysis::{eigenmodes, static_equilibrium, ModeOptions, StaticOptions, Tangent};
use mbsolve::builders::stiff_chain;
use mbsolve::linalg::SolverKind;

#[test]
fn chain_lu_and_sparse_lu_give_the_same_equilibrium_and_modes() {
    let (sys, q0, _, _) = stiff_chain(50, 5f64.to_radians()).unwrap();
    let with = |linear_solver| StaticOptions {
        linear_solver,
        ..Default::default()
    };
    let chain = static_equilibrium(&sys, &q0, with(SolverKind::ChainLu)).unwrap();
    let sparse = static_equilibrium(&sys, &q0, with(SolverKind::SparseLu)).unwrap();
    assert_eq!(chain.factorizations.solver, "chain-lu");
    assert_eq!(chain.factorizations.fallbacks, 0);
    assert_eq!(sparse.factorizations.solver, "sparse-lu");
    assert_eq!(chain.iterations, sparse.iterations);
    let dq = rel_diff(&chain.q, &sparse.q);
    let dl = rel_diff(&chain.lambda, &sparse.lambda);
    assert!(dq < 1e-12 && dl < 1e-9, "q {dq:e}, λ {dl:e}");
    // the equilibrium hangs, it is not the start
    assert!(rel_diff(&chain.q, &q0) > 1e-3);

    let mut tan = Tangent::new(&sys);
    tan.evaluate(0.0, &chain.q, &vec![0.0; q0.len()], &chain.lambda)
        .unwrap();
    let modes = |linear_solver| {
        let opts = ModeOptions {
            count: 10,
            linear_solver,
            ..Default::default()
        };
        eigenmodes(&tan, opts).unwrap()
    };
    let (a, b) = (modes(SolverKind::ChainLu), modes(SolverKind::SparseLu));
    assert_eq!(a.factorizations.solver, "chain-lu");
    assert_eq!(a.factorizations.fallbacks, 0);
    assert_eq!(b.factorizations.solver, "sparse-lu");
    assert!(a.converged && b.converged);
    assert_eq!(a.modes.len(), 10);
    for (ma, mb) in a.modes.iter().zip(&b.modes) {
        let df = (ma.frequency_hz - mb.frequency_hz).abs() / mb.frequency_hz;
        assert!(
            df < 1e-10,
            "{} Hz vs {} Hz",
            ma.frequency_hz,
            mb.frequency_hz
        );
        let ds = rel_diff(&ma.shape, &mb.shape);
        assert!(ds < 1e-6, "shape at {} Hz: {ds:e}", ma.frequency_hz);
    }
}

#[test]
fn analyses_reject_a_symmetric_solver() {
    let (sys, q0, _, _) = stiff_chain(3, 5f64.to_radians()).unwrap();
    let opts = StaticOptions {
        linear_solver: SolverKind::Chain,
        ..Default::default()
    };
    let e = static_equilibrium(&sys, &q0, opts).unwrap_err().to_string();
    assert!(e.contains("linear_solver Chain"), "{e}");
}

/// The chain LU shows full rank by factorising `[s I, Φ_qᵀ; Φ_q, 0]`
/// and then skips the coordinate partitioning (the stiff chain, above);
/// where a row is redundant that factorisation is rejected and the
/// partitioning decides. Against the sparse LU, which always partitions:
/// the redundant parallelogram (a coupler pin too many per loop) and its
/// non-redundant twin give the same rows left out and the same
/// equilibrium.
#[test]
fn full_rank_shown_by_the_band_lu_or_decided_by_the_partitioning() {
    use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
    for redundant in [true, false] {
        let p = ParallelogramChain {
            loops: 3,
            theta0: -1.2,
            redundant,
            ..Default::default()
        };
        let sys = parallelogram_chain(&p).unwrap();
        let (q0, _) = sys.initial_state();
        let with = |linear_solver| StaticOptions {
            linear_solver,
            ..Default::default()
        };
        let chain = static_equilibrium(&sys, &q0, with(SolverKind::ChainLu)).unwrap();
        let sparse = static_equilibrium(&sys, &q0, with(SolverKind::SparseLu)).unwrap();
        // the redundant one is banded in the body order (the rejected rank
        // test, then the partitioning); the twin's pattern is wider than
        // the band (faer's sparse LU, the partitioning)
        let band = if redundant { "chain-lu" } else { "sparse-lu" };
        assert_eq!(chain.factorizations.solver, band);
        assert_eq!(chain.redundant, sparse.redundant, "redundant = {redundant}");
        assert_eq!(chain.redundant.is_empty(), !redundant);
        // the Newton matrix of the kept rows stays on the band
        assert_eq!(chain.factorizations.fallbacks, 0);
        let dq = rel_diff(&chain.q, &sparse.q);
        let dl = rel_diff(&chain.lambda, &sparse.lambda);
        assert!(dq < 1e-12 && dl < 1e-9, "q {dq:e}, λ {dl:e}");
    }
}
