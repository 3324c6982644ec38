//! `linalg::full_pivot_order` (faer's complete-pivoting LU) against an
//! independent textbook elimination (Golub & Van Loan, Alg. 3.4.2, written
//! out below with a row-by-row search): the factors reproduce `P A Q`, the
//! rank and the pivot magnitudes agree on random and rank-deficient
//! matrices, and on every shipped mechanism the rank and the pivots of
//! coordinate partitioning are those of the row-by-row search; where Φ_q's
//! ±1 entries tie and faer picks another column (pinned: the 40-loop
//! parallelogram chain), the chosen block is as well conditioned (the same
//! pivots).

use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
use mbsolve::formulation::{Index1Options, PartitionOptions, Partitioned};
use mbsolve::linalg::full_pivot_order;
use mbsolve::model::System;
use mbsolve::scenario;
use std::path::Path;

/// Complete pivoting, row-major, the first largest entry in a row-by-row
/// scan of the remaining submatrix: `(rank, rows, cols, pivots)`.
fn textbook(
    a: &mut [f64],
    m: usize,
    n: usize,
    tol: f64,
) -> (usize, Vec<usize>, Vec<usize>, Vec<f64>) {
    let mut rows: Vec<usize> = (0..m).collect();
    let mut cols: Vec<usize> = (0..n).collect();
    let mut pivots = Vec::new();
    let mut first = 0.0;
    for k in 0..m.min(n) {
        let (mut bi, mut bj, mut best) = (k, k, -1.0_f64);
        for i in k..m {
            for j in k..n {
                let v = a[rows[i] * n + cols[j]].abs();
                if v > best {
                    (bi, bj, best) = (i, j, v);
                }
            }
        }
        if k == 0 {
            first = best;
        }
        if best <= tol * first || best == 0.0 || best.is_nan() {
            break;
        }
        rows.swap(k, bi);
        cols.swap(k, bj);
        pivots.push(best);
        let (pr, pc) = (rows[k], cols[k]);
        let p = a[pr * n + pc];
        for &r in &rows[k + 1..] {
            let f = a[r * n + pc] / p;
            if f != 0.0 {
                for &c in &cols[k..] {
                    a[r * n + c] -= f * a[pr * n + c];
                }
            }
        }
    }
    (pivots.len(), rows, cols, pivots)
}

/// xorshift in [−1, 1).
fn rng(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        2.0 * ((s >> 11) as f64 / (1u64 << 53) as f64) - 1.0
    }
}

/// `max |P A Q − L U| / max |A|` from the overwritten `lu` (unit lower L,
/// upper U, row-major, in the permuted order).
fn reconstruction_error(
    a: &[f64],
    lu: &[f64],
    m: usize,
    n: usize,
    rows: &[usize],
    cols: &[usize],
) -> f64 {
    let k = m.min(n);
    let amax = a.iter().fold(0.0_f64, |x, v| x.max(v.abs()));
    let mut err = 0.0_f64;
    for i in 0..m {
        for j in 0..n {
            let mut s = 0.0;
            for p in 0..=i.min(j).min(k - 1) {
                let l = if p == i { 1.0 } else { lu[i * n + p] };
                s += l * lu[p * n + j];
            }
            err = err.max((a[rows[i] * n + cols[j]] - s).abs());
        }
    }
    err / amax
}

#[test]
fn factors_reproduce_the_matrix_and_agree_with_the_textbook_elimination() {
    let mut r = rng(0x2545_f491_4f6c_dd1d);
    for (m, n, rank) in [
        (1, 1, 1),
        (3, 5, 3),
        (5, 3, 3),
        (8, 8, 8),
        (12, 20, 7),
        (20, 12, 5),
        (30, 30, 29),
        (40, 61, 40),
    ] {
        // A = B C with B m × rank, C rank × n: rank exactly `rank`
        let b: Vec<f64> = (0..m * rank).map(|_| r()).collect();
        let c: Vec<f64> = (0..rank * n).map(|_| r()).collect();
        let mut a = vec![0.0; m * n];
        for i in 0..m {
            for j in 0..n {
                a[i * n + j] = (0..rank).map(|p| b[i * rank + p] * c[p * n + j]).sum();
            }
        }
        let mut lu = a.clone();
        let o = full_pivot_order(&mut lu, m, n, 1e-10);
        assert_eq!(o.rank, rank, "{m}×{n}");
        let e = reconstruction_error(&a, &lu, m, n, &o.rows, &o.cols);
        assert!(e < 1e-13, "{m}×{n}: |PAQ − LU| = {e:e}");
        let mut t = a.clone();
        let (tr, trows, tcols, tpiv) = textbook(&mut t, m, n, 1e-10);
        assert_eq!(tr, rank);
        // random entries: no ties, the same pivots in the same order
        assert_eq!(o.rows[..rank], trows[..rank], "{m}×{n} rows");
        assert_eq!(o.cols[..rank], tcols[..rank], "{m}×{n} cols");
        for (x, y) in o.pivots.iter().zip(&tpiv) {
            assert!((x - y).abs() <= 1e-12 * y, "{m}×{n}: pivot {x} vs {y}");
        }
        // tol = 0: every nonzero pivot; rounding leaves the deficient
        // ones at ~1e-16 of the first
        let o0 = full_pivot_order(&mut a.clone(), m, n, 0.0);
        assert!(o0.rank >= rank);
        if let Some(p) = o0.pivots.get(rank) {
            assert!(*p < 1e-12 * o0.pivots[0], "{p:e}");
        }
    }
    // degenerate shapes and a zero matrix
    let o = full_pivot_order(&mut [], 0, 4, 0.0);
    assert_eq!((o.rank, o.cols.len()), (0, 4));
    let o = full_pivot_order(&mut [0.0; 6], 2, 3, 1e-8);
    assert_eq!((o.rank, o.rows.len(), o.cols.len()), (0, 2, 3));
    let o = full_pivot_order(&mut [f64::NAN, 1.0], 1, 2, 1e-8);
    assert_eq!((o.rank, o.cols[0]), (1, 1));
}

fn load(name: &str) -> scenario::Scenario {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name);
    scenario::load(&p, &[]).unwrap()
}

/// Dense row-major Φ_q at `q`.
fn dense(sys: &System, q: &[f64]) -> Vec<f64> {
    let n = sys.n_coords();
    let mut vals = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, 0.0, &mut vals);
    let mut a = vec![0.0; sys.n_constraints() * n];
    for (&(r, c), &v) in sys.jacobian_pattern().iter().zip(&vals) {
        a[r * n + c] += v;
    }
    a
}

#[test]
fn shipped_mechanisms_keep_their_partition() {
    let mut cases: Vec<(String, System, Vec<f64>)> = Vec::new();
    for f in [
        "falling_rod.toml",
        "fourbar.toml",
        "parallelogram_chain.toml",
        "quarter_car.toml",
        "quarter_car_guided.toml",
        "quarter_car_parameters.toml",
        "slider_crank.toml",
        "spring_pendulum.toml",
        "two_rods.toml",
    ] {
        let sc = load(f);
        cases.push((f.to_string(), sc.system, sc.q0));
    }
    for (loops, redundant) in [(1, false), (3, true)] {
        let p = ParallelogramChain {
            loops,
            redundant,
            ..Default::default()
        };
        let sys = parallelogram_chain(&p).unwrap();
        let q0 = sys.initial_state().0;
        cases.push((
            format!("parallelogram {loops} redundant {redundant}"),
            sys,
            q0,
        ));
    }
    let mut moved = Vec::new();
    for (name, sys, q0) in &cases {
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        let a = dense(sys, q0);
        let o = full_pivot_order(&mut a.clone(), m, n, 1e-8);
        for _ in 0..5 {
            let again = full_pivot_order(&mut a.clone(), m, n, 1e-8);
            assert_eq!(again, o, "{name}: the same matrix, another order");
        }
        let (tr, trows, tcols, tpiv) = textbook(&mut a.clone(), m, n, 1e-8);
        let sorted = |v: &[usize]| {
            let mut v = v.to_vec();
            v.sort_unstable();
            v
        };
        assert_eq!(o.rank, tr, "{name}: rank");
        let (dep, tdep) = (sorted(&o.cols[..tr]), sorted(&tcols[..tr]));
        {
            // ties may be broken the other way (and the later pivots then
            // differ): the chosen rows and columns must be a regular block,
            // its smallest complete pivot relative to its first within a
            // factor 10 of the row scan's
            let mut block = Vec::with_capacity(tr * tr);
            for &r in &o.rows[..tr] {
                for &c in &o.cols[..tr] {
                    block.push(a[r * n + c]);
                }
            }
            let (br, _, _, bpiv) = textbook(&mut block, tr, tr, 1e-8);
            assert_eq!(br, tr, "{name}: the chosen block is singular");
            let ratio = |p: &[f64]| p.last().map_or(1.0, |l| l / p[0]);
            assert!(
                ratio(&bpiv) >= 0.1 * ratio(&tpiv),
                "{name}: pivot ratio {} against {}",
                ratio(&bpiv),
                ratio(&tpiv)
            );
        }
        if dep != tdep || sorted(&o.rows[..tr]) != sorted(&trows[..tr]) {
            let only: Vec<usize> = dep.iter().filter(|c| !tdep.contains(c)).copied().collect();
            let was: Vec<usize> = tdep.iter().filter(|c| !dep.contains(c)).copied().collect();
            moved.push(format!("{name}: dependent {only:?} instead of {was:?}"));
        }
        // and what coordinate partitioning integrates
        if n <= mbsolve::formulation::MAX_PARTITION_COORDS {
            let part = Partitioned::new(
                sys,
                PartitionOptions::default(),
                Index1Options::default(),
                0.0,
                q0,
            )
            .unwrap();
            assert_eq!(
                part.independent(),
                sorted(&o.cols[tr..]),
                "{name}: independent"
            );
        }
        eprintln!(
            "{name}: rank {tr} of {m} rows, {n} coordinates, independent {:?} (row scan {:?})",
            sorted(&o.cols[tr..]),
            sorted(&tcols[tr..])
        );
    }
    // Pinned, and documented in `full_pivot_order`: of the shipped
    // mechanisms only the 40-loop chain's tie is broken the other way by
    // faer's search than by a row-by-row scan (one independent
    // coordinate of a 1-DOF chain for another), and the redundant chain's
    // rows.
    eprintln!("ties broken differently: {moved:?}");
    assert!(
        moved
            .iter()
            .all(|m| m.starts_with("parallelogram_chain.toml")
                || m.starts_with("parallelogram 3 redundant true")),
        "{moved:?}"
    );
}
