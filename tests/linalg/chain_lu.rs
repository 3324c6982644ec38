//! The chain LU (`linalg::ChainLu`: partial pivoting in the band of the
//! body-by-body order) against faer's dense LU on chain matrices that are
//! unsymmetric, indefinite and have zero diagonal entries (so that an
//! elimination without pivoting would stop), and its two fallbacks to the
//! sparse LU: a pattern too wide for the band, and a factorisation it
//! rejects.

use crate::common::rel_diff;
use faer::linalg::solvers::Solve;
use faer::Mat;
use mbsolve::linalg::{
    APattern, ChainLu, LinalgError, SaddleMatrix, SaddlePointSolver, Storage, Symmetry,
};

/// Deterministic values in [−1, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// A planar chain of `nb` bodies with revolute joints (ground–body 0,
/// body k−1–body k; `closed`: also body 0–body `nb − 1`, a loop across
/// the numbering) in full storage: `A` an unsymmetric 3 × 3
/// block per body and unsymmetric couplings of neighbouring bodies'
/// angles and of one body's x to the next one's y; random values, the
/// translations' diagonal entries zero, the angles' of alternating sign.
fn chain_matrix(nb: usize, closed: bool, seed: u64) -> SaddleMatrix {
    let n = 3 * nb;
    let mut a = Vec::new();
    for b in 0..nb {
        for i in 0..3 {
            for j in 0..3 {
                a.push((3 * b + i, 3 * b + j));
            }
        }
        if b + 1 < nb {
            a.extend([
                (3 * b + 2, 3 * b + 5),
                (3 * b + 5, 3 * b + 2),
                (3 * b, 3 * b + 4),
            ]);
        }
    }
    let mut ap = APattern::new();
    ap.push_block(&a, Symmetry::Unsymmetric);
    let mut jac = Vec::new();
    let mut joints: Vec<(Option<usize>, usize)> = vec![(None, 0)];
    joints.extend((1..nb).map(|b| (Some(b - 1), b)));
    if closed {
        joints.push((Some(0), nb - 1));
    }
    for (r, &(lo, hi)) in joints.iter().enumerate() {
        for body in lo.into_iter().chain([hi]) {
            jac.extend([
                (2 * r, 3 * body),
                (2 * r, 3 * body + 2),
                (2 * r + 1, 3 * body + 1),
                (2 * r + 1, 3 * body + 2),
            ]);
        }
    }
    let m = 2 * joints.len();
    let mut k = SaddleMatrix::with_storage(n, m, &ap, &jac, Storage::Full);
    let mut rng = Lcg(seed);
    for v in k.values_mut() {
        *v = rng.next();
    }
    let diag = k.diag_slots().to_vec();
    for b in 0..nb {
        k.values_mut()[diag[3 * b]] = 0.0;
        k.values_mut()[diag[3 * b + 1]] = 0.0;
        let s = if b % 2 == 0 { 1.0 } else { -1.0 };
        k.values_mut()[diag[3 * b + 2]] = s * (2.0 + rng.next());
    }
    k
}

/// The dense LU's solution of `k x = b`.
fn dense_solve(k: &SaddleMatrix, b: &[f64]) -> Vec<f64> {
    let d = k.to_dense();
    let rhs = Mat::<f64>::from_fn(b.len(), 1, |i, _| b[i]);
    let x = d.partial_piv_lu().solve(&rhs);
    (0..b.len()).map(|i| x[(i, 0)]).collect()
}

/// Normwise backward error `‖K x − b‖∞ / (‖K‖∞ ‖x‖∞ + ‖b‖∞)` (of the
/// order of the unit roundoff for a backward-stable solve).
fn backward_error(k: &SaddleMatrix, x: &[f64], b: &[f64]) -> f64 {
    let dim = k.dim();
    let mut row_sum = vec![0.0f64; dim];
    for c in 0..dim {
        for s in k.col_ptr()[c]..k.col_ptr()[c + 1] {
            row_sum[k.row_idx()[s]] += k.values()[s].abs();
        }
    }
    let norm = |v: &[f64]| v.iter().fold(0.0f64, |a, e| a.max(e.abs()));
    let mut r = vec![0.0; dim];
    k.mul_vec(x, &mut r);
    for (ri, bi) in r.iter_mut().zip(b) {
        *ri -= bi;
    }
    norm(&r) / (norm(&row_sum) * norm(x) + norm(b))
}

fn rhs(dim: usize) -> Vec<f64> {
    (0..dim).map(|i| 1.0 + (0.7 * i as f64).sin()).collect()
}

#[test]
fn chain_lu_matches_dense_lu_on_unsymmetric_indefinite_chains() {
    for (nb, seed) in [(1, 1), (2, 2), (7, 3), (40, 4), (400, 5)] {
        let k = chain_matrix(nb, false, seed);
        // the first coordinate's diagonal is 0: no elimination without
        // row interchanges gets past it
        assert_eq!(k.values()[k.diag_slots()[0]], 0.0);
        let mut lu = ChainLu::default();
        lu.analyze(&k).unwrap();
        assert_eq!(lu.is_band(), Some(true), "nb = {nb}");
        let (kl, ku) = lu.bandwidths().unwrap();
        assert!(kl <= 10 && ku <= 10, "nb = {nb}: bandwidths {kl}, {ku}");
        for round in 0..2 {
            lu.factorize(&k).unwrap();
            let b = rhs(k.dim());
            let mut x = b.clone();
            lu.solve_in_place(&k, &mut x).unwrap();
            let reference = dense_solve(&k, &b);
            let e = rel_diff(&x, &reference);
            assert!(e < 1e-10, "nb = {nb}, round {round}: {e:e}");
            let eta = backward_error(&k, &x, &b);
            assert!(eta < 1e-15, "nb = {nb}: backward error {eta:e}");
        }
        assert_eq!(lu.fallbacks(), 0);
        assert_eq!(lu.name(), "chain-lu");
        assert_eq!(lu.stats().factorizations, 2);
    }
}

#[test]
fn chain_lu_hands_a_pattern_too_wide_for_the_band_to_the_sparse_lu() {
    // a loop from the last body back to body 0: the body order's band is
    // as wide as the chain
    let k = chain_matrix(30, true, 7);
    let mut lu = ChainLu::default();
    lu.analyze(&k).unwrap();
    assert_eq!(lu.is_band(), Some(false));
    assert_eq!(lu.name(), "sparse-lu");
    lu.factorize(&k).unwrap();
    let b = rhs(k.dim());
    let mut x = b.clone();
    lu.solve_in_place(&k, &mut x).unwrap();
    let e = rel_diff(&x, &dense_solve(&k, &b));
    assert!(e < 1e-10, "{e:e}");
    // the same loop on a short chain fits the band
    let k = chain_matrix(4, true, 8);
    lu.analyze(&k).unwrap();
    assert_eq!(lu.is_band(), Some(true));
}

#[test]
fn chain_lu_hands_a_rejected_factorisation_to_the_sparse_lu() {
    let k = chain_matrix(25, false, 9);
    let b = rhs(k.dim());
    let reference = dense_solve(&k, &b);
    // a growth limit below 1 rejects every factorisation
    let mut lu = ChainLu::default().with_growth_limit(0.5);
    lu.analyze(&k).unwrap();
    assert_eq!(lu.is_band(), Some(true));
    for round in 1..=2 {
        lu.factorize(&k).unwrap();
        let mut x = b.clone();
        lu.solve_in_place(&k, &mut x).unwrap();
        let e = rel_diff(&x, &reference);
        assert!(e < 1e-10, "{e:e}");
        assert_eq!(lu.fallbacks(), round);
    }
    // the default limit keeps the band
    let mut lu = ChainLu::default();
    lu.analyze(&k).unwrap();
    lu.factorize(&k).unwrap();
    assert_eq!(lu.fallbacks(), 0);
}

#[test]
fn chain_lu_reports_a_singular_matrix_as_an_error() {
    // every entry of x_3's row and column zero (A and the constraints'):
    // singular
    let mut k = chain_matrix(8, false, 11);
    let x3 = 9;
    let (col_ptr, row_idx) = (k.col_ptr().to_vec(), k.row_idx().to_vec());
    for c in 0..k.dim() {
        for (s, &r) in row_idx
            .iter()
            .enumerate()
            .take(col_ptr[c + 1])
            .skip(col_ptr[c])
        {
            if c == x3 || r == x3 {
                k.values_mut()[s] = 0.0;
            }
        }
    }
    let mut lu = ChainLu::default();
    lu.analyze(&k).unwrap();
    match lu.factorize(&k) {
        Err(LinalgError::Singular(_)) => {}
        Ok(_) => {
            // the sparse LU may accept it; its solution is then not finite
            let mut x = rhs(k.dim());
            assert!(lu.solve_in_place(&k, &mut x).is_err());
        }
        Err(e) => panic!("unexpected error {e}"),
    }
    assert_eq!(lu.fallbacks(), 1);
}
