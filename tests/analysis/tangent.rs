//! The tangent matrices against central finite differences of the
//! system's own forces and constraint terms.

// matrices are indexed by row and column throughout
#![allow(clippy::needless_range_loop)]

use mbsolve::analysis::Tangent;
use mbsolve::builders::stiff_chain;

/// `r(q, q̇) = g(q, q̇) − Φ_q(q)ᵀ λ` at fixed λ.
fn residual(sys: &mbsolve::model::System, q: &[f64], qd: &[f64], lam: &[f64]) -> Vec<f64> {
    let n = sys.n_coords();
    let mut g = vec![0.0; n];
    sys.forces_into(0.0, q, qd, &mut g);
    let mut jac = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, 0.0, &mut jac);
    let mut t = vec![0.0; n];
    sys.jacobian_tmul(&jac, lam, &mut t);
    g.iter().zip(&t).map(|(a, b)| a - b).collect()
}

#[test]
fn stiffness_and_damping_match_finite_differences() {
    let (sys, mut q, mut qd, _) = stiff_chain(4, 0.3).unwrap();
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    // a bent, moving state and arbitrary multipliers
    for (i, v) in q.iter_mut().enumerate() {
        *v += 1e-2 * ((i as f64) * 0.7).sin();
    }
    for (i, v) in qd.iter_mut().enumerate() {
        *v = 0.3 * ((i as f64) * 1.3).cos();
    }
    let lam: Vec<f64> = (0..m).map(|r| 5.0 + r as f64).collect();
    let mut tan = Tangent::new(&sys);
    tan.evaluate(0.0, &q, &qd, &lam).unwrap();
    let k = tan.stiffness().to_dense();
    let c = tan.damping().to_dense();
    let jq = tan.constraint_jacobian().to_dense();
    let h = 1e-6;
    let (mut kmax, mut cmax, mut ek, mut ec) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for j in 0..n {
        let (mut qp, mut qm) = (q.clone(), q.clone());
        qp[j] += h;
        qm[j] -= h;
        let (rp, rm) = (
            residual(&sys, &qp, &qd, &lam),
            residual(&sys, &qm, &qd, &lam),
        );
        let (mut vp, mut vm) = (qd.clone(), qd.clone());
        vp[j] += h;
        vm[j] -= h;
        let (sp, sm) = (residual(&sys, &q, &vp, &lam), residual(&sys, &q, &vm, &lam));
        for i in 0..n {
            let kfd = -(rp[i] - rm[i]) / (2.0 * h);
            let cfd = -(sp[i] - sm[i]) / (2.0 * h);
            kmax = kmax.max(kfd.abs());
            cmax = cmax.max(cfd.abs());
            ek = ek.max((k[(i, j)] - kfd).abs());
            ec = ec.max((c[(i, j)] - cfd).abs());
        }
    }
    assert!(kmax > 1.0 && cmax > 0.0);
    assert!(ek <= 1e-6 * kmax, "K: error {ek} of max {kmax}");
    assert!(ec <= 1e-6 * cmax, "C: error {ec} of max {cmax}");
    // Φ_q against differences of Φ
    let mut phi_p = vec![0.0; m];
    let mut phi_m = vec![0.0; m];
    for j in 0..n {
        let (mut qp, mut qm) = (q.clone(), q.clone());
        qp[j] += h;
        qm[j] -= h;
        sys.phi(&qp, 0.0, &mut phi_p);
        sys.phi(&qm, 0.0, &mut phi_m);
        for r in 0..m {
            let d = (phi_p[r] - phi_m[r]) / (2.0 * h);
            assert!((jq[(r, j)] - d).abs() < 1e-8, "Φ_q({r}, {j})");
        }
    }
    // the mass diagonal is the system's
    let mm = tan.mass().to_dense();
    for i in 0..n {
        assert_eq!(mm[(i, i)], sys.mass_diagonal()[i]);
    }
}
