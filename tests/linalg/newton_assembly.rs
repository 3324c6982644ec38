//! The Newton matrix of `Index3` on chains: the generated assembly against
//! the generic one, the envelope LDLᵀ (`ChainLdlt`) against faer's sparse
//! LDLᵀ and a dense solve, and whole runs with either evaluation.

use faer::Side;
use mbsolve::builders::{
    add_link_chain, build_rod, stiff_chain, stiff_chain_tip_x, LinkChain, RodParams,
};
use mbsolve::constraints::Revolute;
use mbsolve::formulation::{Index3, NewtonSolverKind};
use mbsolve::integrate::Method;
use mbsolve::linalg::{
    solver_for, ChainLdlt, SaddleMatrix, SaddlePointSolver, SolverKind, SolverOptions, SparseLdlt,
};
use mbsolve::model::{BodyRef, Evaluation, System, SystemBuilder};
use mbsolve::simulation::{simulate, RunConfig};

/// A state away from rest: q from the system, small velocities and
/// multipliers that vary along the chain.
fn state(sys: &System, q0: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let mut q = q0.to_vec();
    for (i, x) in q.iter_mut().enumerate() {
        *x += 1e-3 * ((i as f64) * 0.71).sin();
    }
    let qd: Vec<f64> = (0..n).map(|i| 0.1 * ((i as f64) * 0.37).cos()).collect();
    let qdd: Vec<f64> = (0..n).map(|i| 2.0 * ((i as f64) * 0.13).sin()).collect();
    let lam: Vec<f64> = (0..m).map(|r| 5.0 + ((r as f64) * 0.29).sin()).collect();
    (q, qd, qdd, lam)
}

/// The three chains of the brief: the stiff chain (cantilever with a
/// ground pivot and torsional springs everywhere), the falling rod (free
/// chain, drag, contact, generated force Jacobians) and a pivoted n-link
/// chain with springs.
fn chains() -> Vec<(&'static str, System, Vec<f64>)> {
    let (stiff, q_stiff, _, _) = stiff_chain(40, 5f64.to_radians()).unwrap();
    let (rod, _) = build_rod(&RodParams::problem_b(30)).unwrap();
    let q_rod = rod.initial_state().0;
    let mut b = SystemBuilder::new();
    let chain = LinkChain {
        links: 25,
        length: 0.2,
        mass: 0.3,
        inertia: 1e-3,
        position: [0.0, 0.0],
        angle: 2.5,
        stiffness: 40.0,
        damping: 0.01,
        pivot: true,
    };
    add_link_chain(&mut b, "c", &chain).unwrap();
    b.gravity([0.0, -9.81]);
    let links = b.build().unwrap();
    let q_links = links.initial_state().0;
    vec![
        ("stiff chain", stiff, q_stiff),
        ("falling rod", rod, q_rod),
        ("pivoted 25-link chain", links, q_links),
    ]
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let scale = a.iter().chain(b).fold(0.0_f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(b)
        .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()))
        / scale.max(f64::MIN_POSITIVE)
}

/// Generated (kernels) and generic (per joint, per element) evaluation give
/// the same Newton matrix and residual to 1e-12 relative, on all three
/// chains, and the kernels are in use.
#[test]
fn generated_newton_matrix_and_residual_equal_generic() {
    for (name, mut sys, q0) in chains() {
        assert!(sys.uses_kernels(), "{name}: kernels attached");
        let (q, qd, qdd, lam) = state(&sys, &q0);
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        let c = [0.8, 3e-4, 2.5e-9];
        let eval = |sys: &System| {
            let mut f = Index3::new(sys, SolverKind::Auto).unwrap();
            f.assemble_and_factorize(0.1, &q, &qd, &lam, c[0], c[1], c[2])
                .unwrap();
            let mut r = vec![0.0; n + m];
            f.residual_into(0.1, &q, &qd, &qdd, &lam, c[2], &mut r)
                .unwrap();
            (f.newton_matrix().values().to_vec(), r)
        };
        sys.set_evaluation(Evaluation::Generated).unwrap();
        let (kg, rg) = eval(&sys);
        sys.set_evaluation(Evaluation::Generic).unwrap();
        let (kn, rn) = eval(&sys);
        let (dk, dr) = (rel_diff(&kg, &kn), rel_diff(&rg, &rn));
        assert!(dk < 1e-12, "{name}: Newton matrix differs by {dk:e}");
        assert!(dr < 1e-12, "{name}: residual differs by {dr:e}");
        // and the matrix carries the c_k (Φ_qᵀλ)_q and force terms at all
        let mut f = Index3::new(&sys, SolverKind::Auto).unwrap();
        f.assemble_and_factorize(0.1, &q, &qd, &lam, c[0], 0.0, 0.0)
            .unwrap();
        assert!(rel_diff(f.newton_matrix().values(), &kn) > 1e-12, "{name}");
    }
}

/// The envelope LDLᵀ is chosen for every chain's Newton matrix and solves
/// it as faer's sparse LDLᵀ and a dense LU do (1e-10 relative).
#[test]
fn chain_ldlt_matches_sparse_and_dense_on_chain_newton_matrices() {
    for (name, sys, q0) in chains() {
        let (q, qd, _, lam) = state(&sys, &q0);
        let mut f = Index3::new(&sys, SolverKind::Auto).unwrap();
        assert_eq!(f.solver_name(), "chain-ldlt", "{name}");
        f.assemble_and_factorize(0.0, &q, &qd, &lam, 0.8, 3e-4, 2.5e-9)
            .unwrap();
        let k = &f.newton_matrix().clone();
        let b: Vec<f64> = (0..k.dim()).map(|i| ((i as f64) * 1.3).cos()).collect();
        let mut x_env = b.clone();
        f.solve_newton(0.0, &mut x_env).unwrap();
        let mut sparse = SparseLdlt::default();
        sparse.analyze(k).unwrap();
        sparse.factorize(k).unwrap();
        let mut x_sp = b.clone();
        sparse.solve_in_place(k, &mut x_sp).unwrap();
        let mut dense = solver_for(SolverKind::Dense, k.dim(), SolverOptions::default());
        dense.analyze(k).unwrap();
        dense.factorize(k).unwrap();
        let mut x_d = b.clone();
        dense.solve_in_place(k, &mut x_d).unwrap();
        let (ds, dd) = (rel_diff(&x_env, &x_sp), rel_diff(&x_env, &x_d));
        assert!(ds < 1e-10, "{name}: envelope vs sparse {ds:e}");
        assert!(dd < 1e-10, "{name}: envelope vs dense {dd:e}");
        // the residual of the unchecked solve is at rounding level
        let mut work = vec![0.0; k.dim()];
        let res = k.relative_residual(&x_env, &b, &mut work);
        assert!(res < 1e-11, "{name}: residual {res:e}");
    }
}

/// A closed loop across the numbering (the last body pinned back to the
/// first) is not a chain: `ChainLdlt` falls back to faer and still solves.
#[test]
fn chain_ldlt_falls_back_on_a_loop_across_the_numbering() {
    let mut b = SystemBuilder::new();
    let chain = LinkChain {
        links: 40,
        length: 0.1,
        mass: 0.1,
        inertia: 1e-4,
        position: [0.0, 0.0],
        angle: 0.0,
        stiffness: 0.0,
        damping: 0.0,
        pivot: false,
    };
    let info = add_link_chain(&mut b, "c", &chain).unwrap();
    let (first, last) = (info.bodies[0], *info.bodies.last().unwrap());
    b.add_constraint(Revolute::new(
        "closure",
        BodyRef::Body(first),
        [0.0, -0.05],
        BodyRef::Body(last),
        [0.0, 0.05],
    ));
    let sys = b.build().unwrap();
    let (q, _) = sys.initial_state();
    let mut k = SaddleMatrix::new(
        sys.n_coords(),
        sys.n_constraints(),
        &[],
        sys.jacobian_pattern(),
    );
    let mut jac = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(&q, 0.0, &mut jac);
    k.set_a_diagonal(sys.mass_diagonal());
    k.set_jacobian(&jac);
    let mut s = ChainLdlt::default();
    s.analyze(&k).unwrap();
    assert_eq!(s.is_envelope(), Some(false));
    assert_eq!(s.name(), "sparse-ldlt");
    s.factorize(&k).unwrap();
    // a consistent right-hand side b = K x₀ (the straight closed chain's
    // Φ_q may be rank-deficient)
    let x0: Vec<f64> = (0..k.dim()).map(|i| (i as f64).sin()).collect();
    let mut b0 = vec![0.0; k.dim()];
    k.mul_vec(&x0, &mut b0);
    let mut x = b0.clone();
    s.solve_in_place(&k, &mut x).unwrap();
    let mut work = vec![0.0; k.dim()];
    assert!(k.relative_residual(&x, &b0, &mut work) < 1e-10);
}

/// A redundant row (the same joint twice) is regularised as by faer's
/// LDLᵀ: the coordinate part of the solution is the unique one.
#[test]
fn chain_ldlt_regularises_a_redundant_row_like_sparse_ldlt() {
    // n = 6 (two bodies), rows: joint 0–1 (2 rows) and the same again.
    let jp = [
        (0, 0),
        (0, 2),
        (0, 3),
        (0, 5),
        (1, 1),
        (1, 2),
        (1, 4),
        (1, 5),
    ];
    let mut pattern: Vec<(usize, usize)> = jp.to_vec();
    pattern.extend(jp.iter().map(|&(r, c)| (r + 2, c)));
    let vals = [1.0, 0.3, -1.0, 0.2, 1.0, -0.4, -1.0, 0.1];
    let mut all = vals.to_vec();
    all.extend_from_slice(&vals);
    let mut k = SaddleMatrix::new(6, 4, &[], &pattern);
    k.set_a_diagonal(&[2.0, 2.0, 0.5, 3.0, 3.0, 0.7]);
    k.set_jacobian(&all);
    let mut env = ChainLdlt::default();
    env.analyze(&k).unwrap();
    assert_eq!(env.is_envelope(), Some(true));
    let info = env.factorize(&k).unwrap();
    assert!(info.regularized_pivots > 0);
    let mut sp = SparseLdlt::default();
    sp.analyze(&k).unwrap();
    sp.factorize(&k).unwrap();
    // consistent right-hand side: both copies of a row ask for the same
    let b0 = [1.0, -2.0, 0.5, 0.3, 1.0, 0.2, 0.05, -0.1, 0.05, -0.1];
    let (mut xe, mut xs) = (b0.to_vec(), b0.to_vec());
    env.solve_in_place(&k, &mut xe).unwrap();
    sp.solve_in_place(&k, &mut xs).unwrap();
    let d = rel_diff(&xe[..6], &xs[..6]);
    assert!(d < 1e-7, "coordinates {:?} vs {:?}", &xe[..6], &xs[..6]);
    // the physical multipliers are the sums of the duplicated pairs
    for r in 0..2 {
        let (se, ss) = (xe[6 + r] + xe[8 + r], xs[6 + r] + xs[8 + r]);
        assert!((se - ss).abs() < 1e-6 * ss.abs().max(1.0), "{se} vs {ss}");
    }
}

/// Whole gen-α runs of the stiff chain with the generated and the generic
/// evaluation agree (tip within 1e-10 m after 2 ms).
#[test]
fn whole_runs_agree_generated_and_generic() {
    let (mut sys, q0, qd0, info) = stiff_chain(60, 5f64.to_radians()).unwrap();
    let cfg = RunConfig {
        method: Method::GenAlpha,
        t_end: 2e-3,
        output_dt: 1e-3,
        ode: mbsolve::integrate::OdeOptions {
            fixed_step: Some(1e-5),
            ..Default::default()
        },
        ..Default::default()
    };
    let mut tips = Vec::new();
    for ev in [Evaluation::Generated, Evaluation::Generic] {
        sys.set_evaluation(ev).unwrap();
        let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
        assert_eq!(s.status, "completed", "{:?}", s.message);
        assert_eq!(s.linear_solver, "chain-ldlt");
        tips.push(stiff_chain_tip_x(&info, traj.q.last().unwrap()));
    }
    assert!((tips[0] - tips[1]).abs() < 1e-10, "{tips:?}");
    // the tip moved (from x = 1 m · sin 5°)
    assert!((tips[0] - 5f64.to_radians().sin()).abs() > 1e-6, "{tips:?}");
}

/// The generated kernels' `sin_cos` (one reduction for both) is within
/// 1 ulp of libm's `sin` and `cos` over ±2000 rad and at the edges of the
/// reduction (multiples of π/4, tiny and huge arguments, NaN).
#[test]
fn fast_sin_cos_is_within_one_ulp_of_libm() {
    let ulp = |a: f64, b: f64| {
        if a == b {
            0.0
        } else {
            (a - b).abs() / (f64::EPSILON * a.abs().max(b.abs()).max(f64::MIN_POSITIVE))
        }
    };
    let mut xs: Vec<f64> = (0..200_000)
        .map(|i| -2000.0 + 4000.0 * (i as f64) / 200_000.0 + 1e-7 * (i as f64).sin())
        .collect();
    for k in -64..=64 {
        let a = k as f64 * std::f64::consts::FRAC_PI_4;
        xs.extend([a, a.next_up(), a.next_down(), a + 1e-9]);
    }
    xs.extend([0.0, 1e-300, -1e-20, 3.0e5, -1.6e6, 1e7, 1e300]);
    let mut worst = 0.0_f64;
    for &x in &xs {
        let (s, c) = mbsolve::generated::sin_cos(x);
        // relative to max(|value|, ulp of 1 × |x|-scaled reduction error)
        let (es, ec) = (ulp(s, x.sin()), ulp(c, x.cos()));
        let tiny = |v: f64| v.abs() < 1e-9; // near a zero: absolute error
        let e = if tiny(x.sin()) {
            (s - x.sin()).abs() / f64::EPSILON
        } else {
            es
        }
        .max(if tiny(x.cos()) {
            (c - x.cos()).abs() / f64::EPSILON
        } else {
            ec
        });
        worst = worst.max(e);
        assert!(
            e <= 1.0,
            "x = {x:e}: ({s:e}, {c:e}) vs ({:e}, {:e})",
            x.sin(),
            x.cos()
        );
    }
    let (s, c) = mbsolve::generated::sin_cos(f64::NAN);
    assert!(s.is_nan() && c.is_nan());
    assert!(worst > 0.0, "differs from libm somewhere (else it is libm)");
}

/// The four-lane `sin_cos4` gives `sin_cos`'s bits lane by lane wherever it
/// answers, answers on ordinary angles, and declines (None) for a NaN, a
/// huge argument and an angle cancelling against a multiple of π/2.
#[test]
fn four_lane_sin_cos_has_the_bits_of_sin_cos() {
    use mbsolve::generated::{sin_cos, sin_cos4};
    let mut xs: Vec<f64> = (0..40_000)
        .map(|i| -700.0 + 1400.0 * (i as f64) / 40_000.0 + 1e-7 * (i as f64).sin())
        .collect();
    for k in -16..=16 {
        let a = k as f64 * std::f64::consts::FRAC_PI_4;
        xs.extend([a + 1e-3, a - 1e-3, a + 0.3, -a - 0.7]);
    }
    let mut answered = 0;
    for x in xs.chunks_exact(4) {
        let x: [f64; 4] = x.try_into().expect("four");
        if let Some((s, c)) = sin_cos4(x) {
            answered += 1;
            for l in 0..4 {
                let (s1, c1) = sin_cos(x[l]);
                assert_eq!(
                    (s[l].to_bits(), c[l].to_bits()),
                    (s1.to_bits(), c1.to_bits()),
                    "x = {:e}",
                    x[l]
                );
            }
        }
    }
    // declined: some lane within |x|·2⁻¹⁶ of a multiple of π/2 (≈ 5 % of
    // the chunks up to 700 rad)
    assert!(
        10 * answered >= 9 * (xs.len() / 4),
        "{answered} of {}",
        xs.len() / 4
    );
    // a hanging chain's angles
    assert!(sin_cos4([-1.4, -1.5, -1.6, -1.7]).is_some());
    for odd in [
        f64::NAN,
        2e6,
        -std::f64::consts::FRAC_PI_2,
        std::f64::consts::PI,
    ] {
        assert!(sin_cos4([0.1, 0.2, odd, 0.3]).is_none(), "{odd:e}");
    }
}

/// The fused index-3 residual checks finiteness once (on the residual) and
/// still names the first non-finite part: the state, then the constraint
/// forces Φ_qᵀλ (an infinite multiplier), then the residual itself (an
/// infinite acceleration), on the generated and the generic evaluation.
#[test]
fn non_finite_residual_parts_are_named() {
    for (name, mut sys, q0) in chains() {
        for ev in [Evaluation::Generated, Evaluation::Generic] {
            sys.set_evaluation(ev).unwrap();
            let (q, qd, qdd, lam) = state(&sys, &q0);
            let (n, m) = (sys.n_coords(), sys.n_constraints());
            let mut f = Index3::new(&sys, SolverKind::Auto).unwrap();
            let mut r = vec![0.0; n + m];
            let mut run = |q: &[f64], qdd: &[f64], lam: &[f64]| {
                f.residual_into(0.1, q, &qd, qdd, lam, 1e-9, &mut r)
                    .map_err(|e| e.to_string())
            };
            assert!(run(&q, &qdd, &lam).is_ok(), "{name} {ev:?}");
            let mut bad_q = q.clone();
            bad_q[5] = f64::NAN;
            let e = run(&bad_q, &qdd, &lam).unwrap_err();
            assert!(e.contains("state component phi2"), "{name} {ev:?}: {e}");
            let mut bad_lam = lam.clone();
            bad_lam[m - 1] = f64::INFINITY;
            let e = run(&q, &qdd, &bad_lam).unwrap_err();
            assert!(
                e.contains("the constraint forces Φ_qᵀλ"),
                "{name} {ev:?}: {e}"
            );
            let mut bad_qdd = qdd.clone();
            bad_qdd[n - 1] = f64::INFINITY;
            let e = run(&q, &bad_qdd, &lam).unwrap_err();
            assert!(e.contains("the index-3 residual"), "{name} {ev:?}: {e}");
        }
    }
}

/// In symmetric storage the force Jacobians enter the Newton matrix by
/// their reciprocal part (`DynamicBlocks::write`): against the full matrix
/// of the LU path at the same state, each off-diagonal pair of the `A`
/// block holds `sign(a) min(|a|, |b|)` where `a = A_ij`, `b = A_ji` agree
/// in sign, else 0. The state presses a rod segment's corner into a wall
/// while it slides along it: friction couples the penetration to the force
/// along the wall one way, and there the symmetric part `(a + b)/2` of the
/// `A` block is indefinite while the reciprocal part is positive definite
/// (dense Cholesky of the block).
#[test]
fn symmetric_newton_matrix_takes_the_reciprocal_part_of_force_jacobians() {
    let p = RodParams::problem_b(300);
    let (rod, _) = build_rod(&p).unwrap();
    let (mut q, mut qd) = rod.initial_state();
    let n = rod.n_coords();
    // segment 5: its outermost corner 1e-4 m into the right wall, sliding
    // down at 0.05 m/s (50 v_s)
    let b = 5;
    let phi = q[3 * b + 2];
    let reach = 0.5 * p.width * phi.cos().abs() + 0.5 * (p.length / 300.0) * phi.sin().abs();
    q[3 * b] = 0.5 * p.channel_width + 1e-4 - reach;
    qd[3 * b + 1] = -0.05;
    let lam = vec![0.0; rod.n_constraints()];
    let recip = |a: f64, b: f64| {
        if a * b > 0.0 {
            a.signum() * a.abs().min(b.abs())
        } else {
            0.0
        }
    };
    // radau5's real stage at h = 2e-3 (γ = 0.2749): c = [1, hγ, (hγ)²],
    // where the contact stiffness c_k k_n is ≈ 500 segment masses (at
    // N = 10 000 the same holds at h = 4e-4)
    let hg = 2e-3 * 0.274_888_829_595_676_6;
    let mut exercised = 0;
    for c in [[1.0, 0.0, hg * hg], [1.0, hg, 0.0], [1.0, hg, hg * hg]] {
        let dense = |kind| {
            let mut f = Index3::with_newton_solver(&rod, SolverKind::Auto, kind).unwrap();
            f.assemble_and_factorize(0.05, &q, &qd, &lam, c[0], c[1], c[2])
                .unwrap();
            f.newton_matrix().to_dense()
        };
        let sym = dense(NewtonSolverKind::SymmetricLdlt);
        let full = dense(NewtonSolverKind::SparseLu);
        let scale = (0..n).fold(0.0_f64, |m, i| m.max(full[(i, i)].abs()));
        let mut sym_part = faer::Mat::<f64>::zeros(n, n);
        let mut reciprocal = faer::Mat::<f64>::zeros(n, n);
        for i in 0..n {
            for j in 0..n {
                let (a, bb) = (full[(i, j)], full[(j, i)]);
                let want = if i == j { a } else { recip(a, bb) };
                // one term per pair only where a single Jacobian (∂g/∂q or
                // ∂g/∂q̇) contributes; with both, per Jacobian
                if c[1] == 0.0 || c[2] == 0.0 {
                    assert!(
                        (sym[(i, j)] - want).abs() <= 1e-12 * scale,
                        "c = {c:?}, ({i}, {j}): {} against {want} (full {a}, {bb})",
                        sym[(i, j)]
                    );
                    if (want - 0.5 * (a + bb)).abs() > 1e-6 * scale {
                        exercised += 1;
                    }
                }
                sym_part[(i, j)] = 0.5 * (a + bb);
                reciprocal[(i, j)] = sym[(i, j)];
            }
        }
        if c[1] != 0.0 && c[2] != 0.0 {
            assert!(
                sym_part.llt(Side::Lower).is_err(),
                "the symmetric part is indefinite here"
            );
            assert!(
                reciprocal.llt(Side::Lower).is_ok(),
                "the reciprocal part is positive definite"
            );
        }
    }
    assert!(exercised > 0, "no one-way coupling at this state");
}
