//! Sparse saddle-point solver against the dense reference on planar chain and
//! closed-loop matrices built directly (no model code involved).

use mbsolve::linalg::{
    chain_order, solver_for, APattern, DenseLu, LinalgError, Ordering, SaddleMatrix,
    SaddlePointSolver, SolverKind, SolverOptions, SparseLdlt, Storage, Symmetry,
    AUTO_DENSE_MAX_DIM,
};
use std::ops::Range;

// ---------------------------------------------------------------------------
// Allocation counter (per thread, so parallel tests do not interfere).

use crate::counting::allocations;

// ---------------------------------------------------------------------------
// Random numbers (xorshift; no extra dependency).

struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.0 = x;
        x
    }
    /// Uniform in [0, 1).
    fn unif(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unif()
    }
    /// Log-uniform in [lo, hi].
    fn log_range(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unif()).exp()
    }
    fn vec(&mut self, len: usize) -> Vec<f64> {
        (0..len).map(|_| self.range(-1.0, 1.0)).collect()
    }
}

// ---------------------------------------------------------------------------
// Planar chain / loop saddle matrices.

/// One end of a revolute joint: a body point `s` (body frame) or the ground.
#[derive(Clone, Copy)]
enum End {
    Body(usize, [f64; 2]),
    Ground,
}

/// A system of planar bodies (coordinates `3i..3i+2` = x, y, φ) and
/// revolute joints `Φ = r_a + R(φ_a) s_a − r_b − R(φ_b) s_b` (2 rows each).
struct System2d {
    n_bodies: usize,
    joints: Vec<(End, End)>,
    /// Child body of each joint (for the Baraff-style chain order), if any.
    child: Vec<Option<usize>>,
    /// Full coupling of all coordinates in `A` (Newton-like dense block).
    dense_a: bool,
    /// Within-body coupling x–φ, y–φ in `A` (Newton-like block diagonal).
    body_a: bool,
}

impl System2d {
    fn body_len(i: usize) -> f64 {
        0.5 + 0.37 * ((i * 7) % 5) as f64
    }
    fn top(i: usize) -> End {
        End::Body(i, [0.5 * Self::body_len(i), 0.0])
    }
    fn bot(i: usize) -> End {
        End::Body(i, [-0.5 * Self::body_len(i), 0.0])
    }

    /// Pendulum chain: ground – bottom of body 0, top of body i – bottom of
    /// body i + 1.
    fn chain(n_bodies: usize) -> Self {
        let mut joints = vec![(End::Ground, Self::bot(0))];
        let mut child = vec![Some(0)];
        for i in 0..n_bodies - 1 {
            joints.push((Self::top(i), Self::bot(i + 1)));
            child.push(Some(i + 1));
        }
        Self {
            n_bodies,
            joints,
            child,
            dense_a: false,
            body_a: false,
        }
    }

    /// Closed loop (four-bar for 3 bodies): the chain plus a ground joint at
    /// the top of the last body.
    fn closed_loop(n_bodies: usize) -> Self {
        let mut s = Self::chain(n_bodies);
        s.joints.push((Self::top(n_bodies - 1), End::Ground));
        s.child.push(None);
        s
    }

    /// Duplicate the rows of joint `j` (a redundant constraint).
    fn duplicate_joint(mut self, j: usize) -> Self {
        let jt = self.joints[j];
        self.joints.push(jt);
        self.child.push(None);
        self
    }

    fn n(&self) -> usize {
        3 * self.n_bodies
    }
    fn m(&self) -> usize {
        2 * self.joints.len()
    }

    fn a_pattern(&self) -> Vec<(usize, usize)> {
        let mut p = Vec::new();
        if self.dense_a {
            for i in 0..self.n() {
                for j in 0..i {
                    p.push((i, j));
                }
            }
        } else if self.body_a {
            for b in 0..self.n_bodies {
                p.push((3 * b + 2, 3 * b));
                p.push((3 * b + 2, 3 * b + 1));
            }
        }
        p
    }

    fn jac_pattern(&self) -> Vec<(usize, usize)> {
        let mut p = Vec::new();
        for (j, (a, b)) in self.joints.iter().enumerate() {
            for end in [a, b] {
                if let End::Body(i, _) = *end {
                    p.extend_from_slice(&[
                        (2 * j, 3 * i),
                        (2 * j, 3 * i + 2),
                        (2 * j + 1, 3 * i + 1),
                        (2 * j + 1, 3 * i + 2),
                    ]);
                }
            }
        }
        p
    }

    fn matrix(&self) -> SaddleMatrix {
        SaddleMatrix::new(self.n(), self.m(), &self.a_pattern(), &self.jac_pattern())
    }

    /// Random angles and masses (log-uniform over 4 decades), same pattern.
    fn fill(&self, k: &mut SaddleMatrix, rng: &mut Rng) {
        let n = self.n();
        let phi: Vec<f64> = (0..self.n_bodies).map(|_| rng.range(-3.1, 3.1)).collect();
        let mut diag = vec![0.0; n];
        for b in 0..self.n_bodies {
            let m = rng.log_range(0.1, 1000.0);
            let l = Self::body_len(b);
            diag[3 * b] = m;
            diag[3 * b + 1] = m;
            diag[3 * b + 2] = m * l * l / 12.0;
        }
        // Jacobian, in jac_pattern order.
        let mut jac = Vec::new();
        for (a, b) in &self.joints {
            for (end, sign) in [(a, 1.0), (b, -1.0)] {
                if let End::Body(i, s) = *end {
                    let (c, sn) = (phi[i].cos(), phi[i].sin());
                    let rs = [c * s[0] - sn * s[1], sn * s[0] + c * s[1]];
                    jac.extend_from_slice(&[sign, -sign * rs[1], sign, sign * rs[0]]);
                }
            }
        }
        k.set_jacobian(&jac);
        if self.dense_a {
            // A = M + B Bᵀ with a few global low-rank couplings (SPD).
            k.set_a_diagonal(&diag);
            let u: Vec<Vec<f64>> = (0..3).map(|_| rng.vec(n)).collect();
            let mut d = diag.clone();
            for ui in &u {
                for (i, v) in ui.iter().enumerate() {
                    d[i] += v * v;
                }
            }
            k.set_a_diagonal(&d);
            let a_slots = k.a_slots().to_vec();
            let vals = k.values_mut();
            let mut idx = 0;
            for i in 0..n {
                for j in 0..i {
                    vals[a_slots[idx]] = u.iter().map(|ui| ui[i] * ui[j]).sum();
                    idx += 1;
                }
            }
        } else if self.body_a {
            // Per body [m 0 c1; 0 m c2; c1 c2 I + …] kept SPD.
            let mut d = diag.clone();
            let mut off = Vec::new();
            for b in 0..self.n_bodies {
                let c1 = rng.range(-0.4, 0.4) * (diag[3 * b] * diag[3 * b + 2]).sqrt();
                let c2 = rng.range(-0.4, 0.4) * (diag[3 * b + 1] * diag[3 * b + 2]).sqrt();
                d[3 * b + 2] *= 1.5;
                off.push(c1);
                off.push(c2);
            }
            k.set_a_diagonal(&d);
            let a_slots = k.a_slots().to_vec();
            let vals = k.values_mut();
            for (s, v) in a_slots.iter().zip(off) {
                vals[*s] = v;
            }
        } else {
            k.set_a_diagonal(&diag);
        }
        k.set_d_diagonal(&vec![0.0; self.m()]);
    }

    /// Baraff-style order from `chain_order`.
    fn chain_order(&self) -> Vec<usize> {
        let rows: Vec<(usize, Range<usize>)> = self
            .child
            .iter()
            .enumerate()
            .filter_map(|(j, c)| c.map(|b| (b, 2 * j..2 * j + 2)))
            .collect();
        chain_order(self.n_bodies, self.m(), &rows)
    }

    fn orderings(&self) -> Vec<(&'static str, Ordering)> {
        vec![
            ("amd", Ordering::Amd),
            ("natural", Ordering::Natural),
            ("chain", Ordering::Custom(self.chain_order())),
        ]
    }
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, x| a.max(x.abs()))
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    max_abs(&d) / max_abs(b).max(f64::MIN_POSITIVE)
}

fn dense_solve(k: &SaddleMatrix, b: &[f64]) -> Vec<f64> {
    let mut d = DenseLu::default();
    d.analyze(k).unwrap();
    d.factorize(k).unwrap();
    let mut x = b.to_vec();
    d.solve_in_place(k, &mut x).unwrap();
    x
}

fn residual(k: &SaddleMatrix, x: &[f64], b: &[f64]) -> f64 {
    let mut w = vec![0.0; b.len()];
    k.relative_residual(x, b, &mut w)
}

/// Sparse (every ordering) against dense on one system, `reps` value sets.
fn check_against_dense(sys: &System2d, seed: u64, reps: usize) {
    let mut k = sys.matrix();
    for (name, ord) in sys.orderings() {
        let mut rng = Rng::new(seed);
        let mut s = SparseLdlt::new(ord);
        s.analyze(&k).unwrap();
        for rep in 0..reps {
            sys.fill(&mut k, &mut rng);
            let b = rng.vec(k.dim());
            let info = s.factorize(&k).unwrap();
            assert_eq!(
                info.regularized_pivots, 0,
                "{name}: full-rank matrix needed regularisation"
            );
            let mut x = b.clone();
            s.solve_in_place(&k, &mut x).unwrap();
            let xd = dense_solve(&k, &b);
            let rd = rel_diff(&x, &xd);
            let res = residual(&k, &x, &b);
            assert!(
                rd <= 1e-10,
                "{name} bodies={} rep={rep}: relative difference {rd:e}",
                sys.n_bodies
            );
            assert!(
                res <= 1e-12,
                "{name} bodies={} rep={rep}: residual {res:e}",
                sys.n_bodies
            );
        }
        let st = s.stats();
        assert_eq!(st.analyses, 1);
        assert_eq!(st.factorizations, reps);
        assert_eq!(st.solves, reps);
        assert_eq!(st.regularized_pivots, 0);
    }
}

#[test]
fn chain_matches_dense() {
    for (nb, reps) in [(1, 3), (2, 3), (10, 3), (200, 1)] {
        check_against_dense(&System2d::chain(nb), 17 + nb as u64, reps);
    }
}

#[test]
fn closed_loop_matches_dense() {
    for nb in [3, 10, 60] {
        check_against_dense(&System2d::closed_loop(nb), 5 + nb as u64, 2);
    }
}

#[test]
fn coupled_mass_block_matches_dense() {
    let mut sys = System2d::chain(40);
    sys.body_a = true;
    check_against_dense(&sys, 3, 2);
}

#[test]
fn dense_mass_block_supernodal_matches_dense() {
    let mut sys = System2d::closed_loop(40);
    sys.dense_a = true;
    check_against_dense(&sys, 9, 2);
    let k = sys.matrix();
    let mut s = SparseLdlt::new(Ordering::Amd);
    s.analyze(&k).unwrap();
    assert_eq!(
        s.is_supernodal(),
        Some(true),
        "meant to cover the supernodal path"
    );
}

#[test]
fn refactorize_many_times_with_one_analysis() {
    let sys = System2d::closed_loop(25);
    let mut k = sys.matrix();
    let mut rng = Rng::new(99);
    let mut s = SparseLdlt::default();
    s.analyze(&k).unwrap();
    for _ in 0..30 {
        sys.fill(&mut k, &mut rng);
        s.factorize(&k).unwrap();
        for _ in 0..2 {
            let b = rng.vec(k.dim());
            let mut x = b.clone();
            s.solve_in_place(&k, &mut x).unwrap();
            assert!(rel_diff(&x, &dense_solve(&k, &b)) <= 1e-10);
            assert!(residual(&k, &x, &b) <= 1e-12);
        }
    }
    let st = s.stats();
    assert_eq!(st.analyses, 1);
    assert_eq!(st.factorizations, 30);
    assert_eq!(st.solves, 60);
    assert_eq!(st.regularized_pivots, 0);
}

/// Duplicated joint rows, consistent right-hand side: no NaNs, regularised
/// pivots reported, coordinates equal to the dense solution of the
/// non-redundant system, multipliers of the duplicated pair sum to the
/// non-redundant multiplier.
#[test]
fn redundant_constraints_are_regularised() {
    let cases: Vec<(System2d, usize)> = vec![
        (System2d::chain(1), 0),
        (System2d::chain(10), 5),
        (System2d::chain(10), 0),
        (System2d::closed_loop(3), 3),
        (System2d::closed_loop(30), 12),
    ];
    for (base, dup) in cases {
        let red = System2d {
            n_bodies: base.n_bodies,
            joints: base.joints.clone(),
            child: base.child.clone(),
            dense_a: false,
            body_a: false,
        }
        .duplicate_joint(dup);
        let mut kb = base.matrix();
        let mut kr = red.matrix();
        let (n, m) = (base.n(), base.m());
        for (name, ord) in red.orderings() {
            let mut s = SparseLdlt::new(ord);
            s.analyze(&kr).unwrap();
            for rep in 0..3u64 {
                // Same values in both matrices (same seed).
                base.fill(&mut kb, &mut Rng::new(40 + rep));
                red.fill(&mut kr, &mut Rng::new(40 + rep));
                let mut rng = Rng::new(1000 + rep);
                let bb = rng.vec(n + m);
                let xb = dense_solve(&kb, &bb);
                let mut br = bb.clone();
                br.extend_from_slice(&bb[n + 2 * dup..n + 2 * dup + 2]);
                let info = s.factorize(&kr).unwrap();
                assert!(
                    info.regularized_pivots > 0,
                    "{name}: redundant rows not detected"
                );
                let mut x = br.clone();
                s.solve_in_place(&kr, &mut x).unwrap();
                assert!(x.iter().all(|v| v.is_finite()), "{name}: non-finite");
                let dq = rel_diff(&x[..n], &xb[..n]);
                assert!(
                    dq <= 1e-10,
                    "{name} dup={dup}: coordinates differ by {dq:e}"
                );
                // Multipliers of the non-duplicated rows and the pair sum.
                let mut lam = x[n..n + m].to_vec();
                lam[2 * dup] += x[n + m];
                lam[2 * dup + 1] += x[n + m + 1];
                let dl = rel_diff(&lam, &xb[n..]);
                assert!(dl <= 1e-8, "{name} dup={dup}: multipliers differ by {dl:e}");
                let res = residual(&kr, &x, &br);
                assert!(res <= 1e-10, "{name} dup={dup}: residual {res:e}");
            }
            let st = s.stats();
            assert_eq!(st.analyses, 1);
            assert!(st.regularized_pivots >= 3);
        }
    }
}

#[test]
fn singular_position_gives_no_nan() {
    // Two ground joints on one body at the same point: Φ_q rank 2 of 4, and
    // an inconsistent right-hand side — must not produce NaNs.
    let sys = System2d::chain(1).duplicate_joint(0);
    let mut k = sys.matrix();
    sys.fill(&mut k, &mut Rng::new(5));
    let mut s = SparseLdlt::default();
    s.analyze(&k).unwrap();
    let info = s.factorize(&k).unwrap();
    assert_eq!(info.regularized_pivots, 2);
    let mut x = vec![1.0, -1.0, 0.5, 0.1, 0.2, 0.3, 0.4];
    s.solve_in_place(&k, &mut x).unwrap();
    assert!(x.iter().all(|v| v.is_finite()));
    assert!(s.stats().refinements >= 1);
}

#[test]
fn zero_and_non_finite_inputs() {
    let sys = System2d::chain(3);
    let mut k = sys.matrix();
    let mut s = SparseLdlt::default();
    let mut x = vec![0.0; k.dim()];
    assert!(matches!(s.factorize(&k), Err(LinalgError::NotReady(_))));
    s.analyze(&k).unwrap();
    assert!(matches!(
        s.solve_in_place(&k, &mut x),
        Err(LinalgError::NotReady(_))
    ));
    sys.fill(&mut k, &mut Rng::new(1));
    let slot = k.diag_slots()[4];
    k.values_mut()[slot] = f64::NAN;
    assert!(matches!(
        s.factorize(&k),
        Err(LinalgError::NonFinite { .. })
    ));
    sys.fill(&mut k, &mut Rng::new(1));
    s.factorize(&k).unwrap();
    let mut short = vec![0.0; 2];
    assert!(matches!(
        s.solve_in_place(&k, &mut short),
        Err(LinalgError::Dimension { .. })
    ));
    // Zero right-hand side: zero solution.
    s.solve_in_place(&k, &mut x).unwrap();
    assert!(x.iter().all(|&v| v == 0.0));
}

#[test]
fn factorize_and_solve_do_not_allocate() {
    for (sys, supernodal) in [
        (System2d::chain(300), false),
        (
            {
                let mut s = System2d::closed_loop(40);
                s.dense_a = true;
                s
            },
            true,
        ),
    ] {
        let mut k = sys.matrix();
        let mut rng = Rng::new(8);
        for ord in [Ordering::Amd, Ordering::Custom(sys.chain_order())] {
            let mut s = SparseLdlt::new(ord);
            s.analyze(&k).unwrap();
            assert_eq!(s.is_supernodal(), Some(supernodal));
            sys.fill(&mut k, &mut rng);
            s.factorize(&k).unwrap(); // warm-up
            let mut b = rng.vec(k.dim());
            s.solve_in_place(&k, &mut b).unwrap();
            sys.fill(&mut k, &mut rng);
            let mut b = rng.vec(k.dim());
            let before = allocations();
            s.factorize(&k).unwrap();
            let after_factor = allocations();
            s.solve_in_place(&k, &mut b).unwrap();
            let after_solve = allocations();
            assert_eq!(after_factor - before, 0, "factorize allocated");
            assert_eq!(after_solve - after_factor, 0, "solve allocated");
        }
    }
}

#[test]
#[allow(clippy::absurd_extreme_comparisons)] // the measured threshold is 0
fn solver_for_kinds() {
    assert_eq!(
        solver_for(SolverKind::Dense, 1000, SolverOptions::default()).name(),
        "dense-lu"
    );
    assert_eq!(
        solver_for(SolverKind::Sparse, 5, SolverOptions::default()).name(),
        "sparse-ldlt"
    );
    assert_eq!(
        solver_for(SolverKind::Auto, 10_000, SolverOptions::default()).name(),
        "sparse-ldlt"
    );
    if AUTO_DENSE_MAX_DIM > 1 {
        assert_eq!(
            solver_for(
                SolverKind::Auto,
                AUTO_DENSE_MAX_DIM - 1,
                SolverOptions::default()
            )
            .name(),
            "dense-lu"
        );
    }
    assert_eq!(
        solver_for(
            SolverKind::Auto,
            AUTO_DENSE_MAX_DIM,
            SolverOptions::default()
        )
        .name(),
        "sparse-ldlt"
    );
    // Both kinds solve the same system through the trait object.
    let sys = System2d::closed_loop(3);
    let mut k = sys.matrix();
    sys.fill(&mut k, &mut Rng::new(2));
    let b = Rng::new(3).vec(k.dim());
    let mut xs = Vec::new();
    for kind in [SolverKind::Dense, SolverKind::Sparse, SolverKind::Auto] {
        let mut s = solver_for(kind, k.dim(), SolverOptions::default());
        s.analyze(&k).unwrap();
        s.factorize(&k).unwrap();
        let mut x = b.clone();
        s.solve_in_place(&k, &mut x).unwrap();
        xs.push(x);
    }
    assert!(rel_diff(&xs[1], &xs[0]) <= 1e-10);
    assert!(rel_diff(&xs[2], &xs[0]) <= 1e-10);
}

/// Every solver kind through the one seam, each on the storage it asks
/// for: the same assembly calls, the same solution. The Schur complement
/// (eq. (9)) gets a diagonal `A`; the sparse LU an unsymmetric `A` that the
/// dense LU of the full matrix cross-checks, while the symmetric solvers
/// see its symmetric part.
#[test]
fn every_solver_kind_through_one_assembly() {
    let (n, m) = (6, 3);
    let jac: Vec<(usize, usize)> = vec![(0, 0), (0, 3), (1, 1), (1, 4), (2, 2), (2, 5), (2, 0)];
    let jv = [1.0, -1.0, 0.5, 2.0, -0.3, 1.1, 0.7];
    let mut a = APattern::new();
    let blk: Vec<(usize, usize)> = [0, 1, 3]
        .iter()
        .flat_map(|&r| [0, 1, 3].map(move |c| (r, c)))
        .collect();
    let id = a.push_block(&blk, Symmetry::Unsymmetric);
    let hid = a.push_block(&[(5, 2)], Symmetry::Symmetric);
    let assemble = |k: &mut SaddleMatrix, diag_only: bool| {
        k.set_zero();
        for i in 0..n {
            k.add_diagonal(i, 3.0 + i as f64);
        }
        if !diag_only {
            for e in 0..blk.len() {
                k.add_a(
                    id + e,
                    0.1 * (e as f64 + 1.0) * if e % 2 == 0 { 1.0 } else { -0.5 },
                );
            }
            k.add_a(hid, 0.4);
        }
        k.set_jacobian(&jv);
    };
    let b: Vec<f64> = (0..n + m).map(|i| (i as f64 * 0.7).sin() + 0.2).collect();
    let empty = APattern::new();
    let solve = |kind: SolverKind, diag_only: bool| -> (Vec<f64>, Storage) {
        let mut s = solver_for(kind, n + m, SolverOptions::default());
        let mut k = SaddleMatrix::with_storage(
            n,
            m,
            if diag_only { &empty } else { &a },
            &jac,
            s.storage(),
        );
        assemble(&mut k, diag_only);
        s.analyze(&k).unwrap();
        s.factorize(&k).unwrap();
        let mut x = b.clone();
        s.solve_in_place(&k, &mut x).unwrap();
        // the residual of the matrix the solver was given
        let mut r = vec![0.0; n + m];
        k.mul_vec(&x, &mut r);
        assert!(rel_diff(&r, &b) < 1e-12, "{kind:?}: residual");
        (x, k.storage())
    };
    // diagonal A: all five agree
    let (reference, _) = solve(SolverKind::Dense, true);
    for kind in [
        SolverKind::Sparse,
        SolverKind::Auto,
        SolverKind::SparseLu,
        SolverKind::Schur,
    ] {
        assert!(
            rel_diff(&solve(kind, true).0, &reference) < 1e-12,
            "{kind:?}"
        );
    }
    // unsymmetric A: LU solves the full matrix, LDLᵀ its symmetric part
    let (lu, storage) = solve(SolverKind::SparseLu, false);
    assert_eq!(storage, Storage::Full);
    let (ldlt, storage) = solve(SolverKind::Sparse, false);
    assert_eq!(storage, Storage::SymmetricLower);
    assert!(rel_diff(&lu, &ldlt) > 1e-6, "the skew part must matter");
    // the Schur complement refuses a non-diagonal A, LDLᵀ a full matrix
    let mut k = SaddleMatrix::with_storage(n, m, &a, &jac, Storage::SymmetricLower);
    assemble(&mut k, false);
    let mut schur = solver_for(SolverKind::Schur, n + m, SolverOptions::default());
    assert!(schur.analyze(&k).is_err());
    let k = SaddleMatrix::with_storage(n, m, &a, &jac, Storage::Full);
    let mut ldlt = solver_for(SolverKind::Sparse, n + m, SolverOptions::default());
    assert!(matches!(ldlt.analyze(&k), Err(LinalgError::Storage { .. })));
}

#[test]
fn chain_order_layout() {
    // 2 bodies, ground joint rows 0..2 → body 0, joint rows 2..4 → body 1,
    // closure rows 4..6 unnamed.
    let o = chain_order(2, 6, &[(0, 0..2), (1, 2..4)]);
    assert_eq!(o, vec![3, 4, 5, 8, 9, 0, 1, 2, 6, 7, 10, 11]);
}

/// The chain LDLᵀ tells an indefinite `A` block (a coordinate pivot of the
/// wrong sign: an implicit method's Newton matrix at a wild iterate) from
/// Φ_q losing rank (a multiplier pivot ≈ 0, redundant rows): both are
/// regularised, only the first is `FactorInfo::indefinite` and counted in
/// `indefinite_pivots`.
#[test]
fn chain_ldlt_tells_indefinite_a_from_rank_loss() {
    use mbsolve::linalg::ChainLdlt;
    // rank loss: a duplicated joint
    let red = System2d::chain(10).duplicate_joint(4);
    let mut k = red.matrix();
    red.fill(&mut k, &mut Rng::new(3));
    let mut s = ChainLdlt::default();
    s.analyze(&k).unwrap();
    assert_eq!(s.is_envelope(), Some(true));
    let info = s.factorize(&k).unwrap();
    assert!(info.regularized_pivots > 0 && !info.indefinite, "{info:?}");
    assert_eq!(s.stats().indefinite_pivots, 0);
    // a regular chain with its A block negated: every coordinate pivot ≤ 0
    let sys = System2d::chain(10);
    let mut k = sys.matrix();
    sys.fill(&mut k, &mut Rng::new(3));
    let mut s = ChainLdlt::default();
    s.analyze(&k).unwrap();
    let info = s.factorize(&k).unwrap();
    assert_eq!(info.regularized_pivots, 0);
    assert!(!info.indefinite);
    let a_slots: Vec<usize> = k.a_slots().to_vec();
    let diag: Vec<usize> = k.diag_slots()[..sys.n()].to_vec();
    for slot in a_slots.into_iter().chain(diag) {
        k.values_mut()[slot] = -k.values()[slot].abs();
    }
    let info = s.factorize(&k).unwrap();
    assert!(info.indefinite && info.regularized_pivots > 0, "{info:?}");
    let st = s.stats();
    assert_eq!(st.indefinite_pivots, st.regularized_pivots);
}
