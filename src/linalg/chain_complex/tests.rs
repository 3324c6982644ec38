use super::*;
use crate::linalg::{APattern, Symmetry, PARALLEL_MIN_DIM};

/// A chain-like saddle matrix: `bodies` bodies of 3 coordinates, a
/// 2-row joint between neighbours, springs coupling neighbouring
/// angles; values from `seed`.
fn chain_pair(bodies: usize, seed: u64) -> (SaddleMatrix, SaddleMatrix) {
    let n = 3 * bodies;
    let mut a_entries = Vec::new();
    for b in 0..bodies {
        for i in 0..3 {
            for j in 0..=i {
                a_entries.push((3 * b + i, 3 * b + j));
            }
        }
        if b + 1 < bodies {
            a_entries.push((3 * b + 5, 3 * b + 2));
        }
    }
    let mut jac = Vec::new();
    for jn in 0..bodies - 1 {
        for r in 0..2 {
            for c in [3 * jn + r, 3 * jn + 2, 3 * jn + 3 + r, 3 * jn + 5] {
                jac.push((2 * jn + r, c));
            }
        }
    }
    let m = 2 * (bodies - 1);
    let mut a = APattern::new();
    a.push_block(&a_entries, Symmetry::Symmetric);
    let mut state = seed;
    let mut rnd = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    let mut mats =
        [(); 2].map(|()| SaddleMatrix::with_storage(n, m, &a, &jac, Storage::SymmetricLower));
    for (part, k) in mats.iter_mut().enumerate() {
        k.set_zero();
        for (id, &(i, j)) in a_entries.iter().enumerate() {
            // a diagonally dominant real part, a smaller imaginary one
            let v = if i == j { 4.0 + rnd() } else { 0.5 * rnd() };
            k.add_a(id, if part == 0 { v } else { 0.3 * rnd() + 0.1 * v });
        }
        let jv: Vec<f64> = jac
            .iter()
            .map(|_| if part == 0 { 1.0 + rnd() } else { 0.0 })
            .collect();
        k.set_jacobian(&jv);
    }
    let [re, im] = mats;
    (re, im)
}

/// Do two complex solutions `(re, im)` have the same bits?
fn same_bits(a: &(Vec<f64>, Vec<f64>), b: &(Vec<f64>, Vec<f64>)) -> bool {
    let bits = |x: &(Vec<f64>, Vec<f64>)| -> Vec<u64> {
        x.0.iter().chain(&x.1).map(|v| v.to_bits()).collect()
    };
    bits(a) == bits(b)
}

/// The residual `(K_r + i K_i)(x_r + i x_i) − b` of the solution,
/// computed with the two real matrices' products (independent of the
/// factorisation), is at rounding level.
#[test]
fn solves_complex_symmetric_chain_systems() {
    for bodies in [2, 5, 40] {
        let (kr, ki) = chain_pair(bodies, bodies as u64);
        let mut f = ComplexChainLdlt::analyze(&kr).expect("a chain pattern");
        f.factorize(&kr, &ki).expect("nonsingular");
        let dim = kr.dim();
        let br: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.37).sin()).collect();
        let bi: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.11).cos()).collect();
        let (mut xr, mut xi) = (br.clone(), bi.clone());
        f.solve(&mut xr, &mut xi).expect("finite");
        let mul = |k: &SaddleMatrix, x: &[f64]| {
            let mut y = vec![0.0; dim];
            k.mul_vec(x, &mut y);
            y
        };
        let (rr, ii, ri, ir) = (mul(&kr, &xr), mul(&ki, &xi), mul(&kr, &xi), mul(&ki, &xr));
        let mut worst: f64 = 0.0;
        for i in 0..dim {
            worst = worst
                .max((rr[i] - ii[i] - br[i]).abs())
                .max((ri[i] + ir[i] - bi[i]).abs());
        }
        assert!(worst < 1e-12, "N = {bodies}: residual {worst:e}");
        // the imaginary part matters: solving with K_r alone is far off
        let mut g = ComplexChainLdlt::analyze(&kr).expect("a chain pattern");
        let zero = {
            let mut z = ki.clone();
            z.set_zero();
            z
        };
        g.factorize(&kr, &zero).expect("nonsingular");
        let (mut yr, mut yi) = (br.clone(), bi.clone());
        g.solve(&mut yr, &mut yi).expect("finite");
        let diff = yr
            .iter()
            .zip(&xr)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff > 1e-3, "N = {bodies}: K_i had no effect ({diff:e})");
    }
}

/// The residual of `x` for `b` through the two real matrices'
/// products (independent of the factorisation): its largest entry.
fn residual(kr: &SaddleMatrix, ki: &SaddleMatrix, x: (&[f64], &[f64]), b: (&[f64], &[f64])) -> f64 {
    let dim = kr.dim();
    let mul = |k: &SaddleMatrix, x: &[f64]| {
        let mut y = vec![0.0; dim];
        k.mul_vec(x, &mut y);
        y
    };
    let (rr, ii, ri, ir) = (mul(kr, x.0), mul(ki, x.1), mul(kr, x.1), mul(ki, x.0));
    (0..dim).fold(0.0, |w: f64, i| {
        w.max((rr[i] - ii[i] - b.0[i]).abs())
            .max((ri[i] + ir[i] - b.1[i]).abs())
    })
}

fn solve_with(
    f: &mut ComplexChainLdlt,
    kr: &SaddleMatrix,
    ki: &SaddleMatrix,
) -> (Vec<f64>, Vec<f64>) {
    let dim = kr.dim();
    f.factorize(kr, ki).expect("nonsingular");
    let mut xr: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.37).sin()).collect();
    let mut xi: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.11).cos()).collect();
    f.solve(&mut xr, &mut xi).expect("finite");
    (xr, xi)
}

/// From SPLIT_MIN_DIM on the order is two-sided (halves and a
/// separator): it solves to rounding level, agrees with the one-sided
/// order to rounding, and a second solve with the same factors gives
/// the same bits.
#[test]
fn the_two_sided_order_solves_like_the_one_sided_one() {
    for bodies in [400, 1001] {
        let (kr, ki) = chain_pair(bodies, 3 + bodies as u64);
        let dim = kr.dim();
        assert!(dim >= crate::linalg::SPLIT_MIN_DIM);
        let mut two = ComplexChainLdlt::analyze(&kr).expect("a chain pattern");
        assert!(
            two.envelope.s0 < two.envelope.sb && two.envelope.sb < dim,
            "split"
        );
        let mut one = ComplexChainLdlt::analyze_order(&kr, false).expect("a chain pattern");
        assert_eq!((one.envelope.s0, one.envelope.sb), (dim, dim));
        let br: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.37).sin()).collect();
        let bi: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.11).cos()).collect();
        let x2 = solve_with(&mut two, &kr, &ki);
        let x1 = solve_with(&mut one, &kr, &ki);
        let r = residual(&kr, &ki, (&x2.0, &x2.1), (&br, &bi));
        assert!(r < 1e-12, "N = {bodies}: residual {r:e}");
        let diff =
            x1.0.iter()
                .chain(&x1.1)
                .zip(x2.0.iter().chain(&x2.1))
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
        let size = x1.0.iter().chain(&x1.1).fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(diff <= 1e-12 * size, "N = {bodies}: {diff:e} of {size:e}");
        let again = solve_with(&mut two, &kr, &ki);
        assert!(same_bits(&again, &x2));
    }
}

/// Above PARALLEL_MIN_DIM the halves run through `join_if`: in pools
/// of one and two threads the solution has the same bits.
#[test]
fn the_halves_give_the_same_bits_on_one_thread_and_two() {
    let (kr, ki) = chain_pair(2100, 11);
    assert!(kr.dim() >= PARALLEL_MIN_DIM);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut f = ComplexChainLdlt::analyze(&kr).expect("a chain pattern");
                solve_with(&mut f, &kr, &ki)
            })
    };
    let (a, b) = (run(1), run(2));
    assert!(same_bits(&a, &b));
    let dim = kr.dim();
    let br: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.37).sin()).collect();
    let bi: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.11).cos()).collect();
    let r = residual(&kr, &ki, (&a.0, &a.1), (&br, &bi));
    assert!(r < 1e-12, "residual {r:e}");
}

/// The solve checks the entries of its solution as its backward rows
/// write them: a right-hand side with one non-finite part of one entry
/// (at the start, the middle and the end: rows of both halves and of the
/// separator) gives `NonFiniteSolution` in pools of one and two threads.
#[test]
fn a_non_finite_right_hand_side_is_reported_on_one_thread_and_two() {
    let (kr, ki) = chain_pair(2100, 13);
    let dim = kr.dim();
    assert!(dim >= PARALLEL_MIN_DIM);
    let mut f = ComplexChainLdlt::analyze(&kr).expect("a chain pattern");
    f.factorize(&kr, &ki).unwrap();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            for at in [0, dim / 2, dim - 1] {
                for imaginary in [false, true] {
                    let mut br: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.37).sin()).collect();
                    let mut bi: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.11).cos()).collect();
                    if imaginary {
                        bi[at] = f64::INFINITY;
                    } else {
                        br[at] = f64::NAN;
                    }
                    let r = f.solve(&mut br, &mut bi);
                    assert!(
                        matches!(r, Err(LinalgError::NonFiniteSolution(_))),
                        "{threads} thread(s), entry {at}: {r:?}"
                    );
                }
            }
        });
    }
}

#[test]
fn errors_before_factorisation_and_on_singular_pivots() {
    let (kr, ki) = chain_pair(3, 7);
    let mut f = ComplexChainLdlt::analyze(&kr).expect("a chain pattern");
    let dim = kr.dim();
    let (mut a, mut b) = (vec![1.0; dim], vec![0.0; dim]);
    assert!(matches!(
        f.solve(&mut a, &mut b),
        Err(LinalgError::NotReady(_))
    ));
    let mut zero = ki.clone();
    zero.set_zero();
    let err = f.factorize(&zero, &zero).unwrap_err();
    assert!(matches!(err, LinalgError::Singular(_)), "{err}");
    assert!(f.solve(&mut a, &mut b).is_err());
    let mut nan = kr.clone();
    nan.values_mut()[0] = f64::NAN;
    assert!(matches!(
        f.factorize(&nan, &ki),
        Err(LinalgError::NonFinite { .. })
    ));
}

/// The substitutions' compact row table (`RowTable`) walks the envelope
/// rows of the layout: counting `ptr` on by the stored lengths from each
/// half's first row gives every plain row's `ptr` and `first`, and the
/// half's end; the permutation is the same. One- and two-sided orders.
#[test]
fn the_row_table_walks_the_envelope_rows() {
    for (bodies, split) in [(50, false), (400, true), (1001, true)] {
        let (kr, _) = chain_pair(bodies, 7);
        let e = Envelope::<Complex>::analyze(&kr, split).expect("a chain pattern");
        assert_eq!(e.s0 < e.dim, split);
        let t = &e.rows;
        assert!(t.perm.iter().zip(&e.perm).all(|(&a, &b)| a as usize == b));
        for half in [0..e.s0, e.s0..e.sb] {
            let mut p = e.ptr[half.start];
            for i in half.clone() {
                assert_eq!(p, e.ptr[i], "N = {bodies}, row {i}");
                assert_eq!(i - usize::from(t.len[i]), e.first[i], "row {i}");
                p += usize::from(t.len[i]);
            }
            assert_eq!(p, e.ptr[half.end], "N = {bodies}");
        }
    }
}

/// The factorisation and the sweeps compiled for AVX give the bits of the
/// baseline build (the same operations in the same order), real and
/// complex, one- and two-sided orders; and both solve the system (the residual through
/// the matrices' products, independent of the factorisation).
#[test]
fn the_avx_build_factorises_and_solves_with_the_bits_of_the_baseline_build() {
    use crate::numeric::BASELINE;
    for (bodies, split) in [(40, false), (1001, true)] {
        let (kr, ki) = chain_pair(bodies, 11);
        let dim = kr.dim();
        let b: (Vec<f64>, Vec<f64>) = (
            (0..dim).map(|i| (i as f64 * 0.37).sin()).collect(),
            (0..dim).map(|i| (i as f64 * 0.11).cos()).collect(),
        );
        let mut c = ComplexChainLdlt::analyze_order(&kr, split).expect("a chain pattern");
        let mut r = Envelope::<f64>::analyze(&kr, split).expect("a chain pattern");
        let mut run = |baseline: bool| {
            BASELINE.set(baseline);
            c.factorize(&kr, &ki).expect("nonsingular");
            r.factorize(kr.values(), DEFAULT_EPSILON, DEFAULT_DELTA)
                .expect("nonsingular");
            let mut x = b.clone();
            c.solve(&mut x.0, &mut x.1).expect("finite");
            let mut y = b.0.clone();
            assert!(r.solve(&Scatter::new(&mut y)));
            BASELINE.set(false);
            (x, y)
        };
        let (avx, base) = (run(false), run(true));
        assert!(same_bits(&avx.0, &base.0), "N = {bodies}: complex");
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&avx.1), bits(&base.1), "N = {bodies}: real");
        let res = residual(&kr, &ki, (&base.0 .0, &base.0 .1), (&b.0, &b.1));
        assert!(res < 1e-12, "N = {bodies}: complex residual {res:e}");
        let mut kx = vec![0.0; dim];
        kr.mul_vec(&base.1, &mut kx);
        let res = kx
            .iter()
            .zip(&b.0)
            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(res < 1e-12, "N = {bodies}: real residual {res:e}");
    }
}

/// The row table refuses a plain row whose envelope leaves its half (a
/// row of `B` reaching into `T`) and a permutation entry beyond the
/// dimension: the sweeps read without bounds checks on its word.
#[test]
fn the_row_table_refuses_rows_outside_their_half() {
    let perm: Vec<usize> = (0..6).collect();
    // rows 0..3 in T, 3..5 in B, 5 the separator
    let first = [0, 0, 1, 3, 3, 0];
    assert!(crate::linalg::chain::RowTable::new(&first, &perm, 3, 5).is_some());
    let into_t = [0, 0, 1, 2, 3, 0];
    assert!(crate::linalg::chain::RowTable::new(&into_t, &perm, 3, 5).is_none());
    let beyond = [0, 1, 2, 3, 4, 6];
    assert!(crate::linalg::chain::RowTable::new(&first, &beyond, 3, 5).is_none());
}
