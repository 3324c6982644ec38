//! Sparse coordinate partitioning (`mbsolve::analysis::partitioning`)
//! against the dense complete pivoting of Φ_q (`linalg::full_pivot_order`,
//! a different algorithm): the same rank and redundancy on every shipped
//! mechanism and on a redundant parallelogram chain, a dependent set whose
//! columns of Φ_q are regular, the same linear model from either choice;
//! and a stiff chain far beyond what the dense path can hold.

use mbsolve::analysis::inverse::{freedom, partition_at, RANK_TOL};
use mbsolve::analysis::linearize::{linearize, LinearizeOptions};
use mbsolve::analysis::partitioning::partition;
use mbsolve::analysis::{static_equilibrium, StaticOptions};
use mbsolve::builders::{parallelogram_chain, stiff_chain, ParallelogramChain};
use mbsolve::linalg::full_pivot_order;
use mbsolve::model::System;
use mbsolve::scenario;
use std::path::Path;
use std::time::Instant;

fn load(name: &str) -> scenario::Scenario {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name);
    scenario::load(&p, &[]).unwrap()
}

/// Dense row-major Φ_q.
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

/// Rank and smallest/largest pivot ratio of the columns `cols` of the
/// dense `m × n` matrix `a` by complete pivoting.
fn columns_rank(a: &[f64], m: usize, n: usize, cols: &[usize]) -> (usize, f64) {
    let k = cols.len();
    let mut sub = vec![0.0; m * k];
    for r in 0..m {
        for (j, &c) in cols.iter().enumerate() {
            sub[r * k + j] = a[r * n + c];
        }
    }
    let o = full_pivot_order(&mut sub, m, k, RANK_TOL);
    let ratio = match (o.pivots.first(), o.pivots.last()) {
        (Some(first), Some(last)) => last / first,
        _ => 1.0, // no constraints: nothing to condition
    };
    (o.rank, ratio)
}

fn check(name: &str, sys: &System, q: &[f64]) {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let a = dense(sys, q);
    let d = full_pivot_order(&mut a.clone(), m, n, RANK_TOL);
    let p = partition_at(sys, q, 0.0);
    assert_eq!(
        p.rank, d.rank,
        "{name}: rank sparse {} dense {}",
        p.rank, d.rank
    );
    assert_eq!(p.redundant.len(), m - d.rank, "{name}: redundant rows");
    assert_eq!(p.independent.len(), n - d.rank, "{name}: independent count");
    assert_eq!(p.dependent.len() + p.independent.len(), n, "{name}: split");
    // the dependent columns carry the whole rank, well conditioned
    let (r, ratio) = columns_rank(&a, m, n, &p.dependent);
    assert_eq!(r, d.rank, "{name}: the dependent columns are singular");
    assert!(
        ratio > 1e-4,
        "{name}: dependent block pivot ratio {ratio:e}"
    );
    // freedom() reports the same
    let f = freedom(sys, q, 0.0);
    assert_eq!((f.dof, f.redundant), (n - d.rank, m - d.rank), "{name}");
    assert_eq!(f.coordinates, p.independent, "{name}");
}

#[test]
fn rank_and_redundancy_agree_with_complete_pivoting() {
    for name in [
        "fourbar.toml",
        "slider_crank.toml",
        "quarter_car_guided.toml",
        "spring_pendulum.toml",
        "two_rods.toml",
    ] {
        let sc = load(name);
        check(name, &sc.system, &sc.q0);
    }
    let (sys, q0, _, _) = stiff_chain(12, 5f64.to_radians()).unwrap();
    check("stiff chain N = 12", &sys, &q0);
    for (loops, redundant) in [(1, false), (3, false), (3, true), (5, true)] {
        let p = ParallelogramChain {
            loops,
            redundant,
            ..Default::default()
        };
        let sys = parallelogram_chain(&p).unwrap();
        let (q, _) = p.state(0.3, 0.0);
        check(
            &format!("parallelogram k = {loops}, redundant {redundant}"),
            &sys,
            &q,
        );
    }
}

#[test]
fn explicit_small_matrices() {
    // x0 + x1 = 0 and 2 x0 + 2 x1 = 0 (redundant), x2 in no row
    let p = partition(
        2,
        3,
        &[(0, 0, 1.0), (0, 1, 1.0), (1, 0, 2.0), (1, 1, 2.0)],
        1e-9,
    );
    assert_eq!(p.rank, 1);
    assert_eq!(p.redundant.len(), 1);
    assert_eq!(p.independent.len(), 2);
    assert!(p.independent.contains(&2));
    // a small pivot refused for a large one in its row: row 0 is
    // 1e-3 x0 + x1, x0 appears only there; x1 must be the pivot
    let p = partition(1, 2, &[(0, 0, 1e-3), (0, 1, 1.0)], 1e-9);
    assert_eq!(
        (p.dependent.clone(), p.independent.clone()),
        (vec![1], vec![0])
    );
    // duplicates summed, an empty matrix leaves every column free
    let p = partition(1, 2, &[(0, 0, 1.0), (0, 0, -1.0), (0, 1, 1.0)], 1e-9);
    assert_eq!(p.independent, vec![0]);
    let p = partition(0, 2, &[], 1e-9);
    assert_eq!((p.rank, p.independent), (0, vec![0, 1]));
}

#[test]
fn linear_model_is_the_same_from_the_dense_choice() {
    // the four-bar without its drive torque at its static equilibrium
    // (θ = 89.58°, unstable): the independent coordinate from the sparse
    // elimination (default) and from complete pivoting (given); about an
    // equilibrium the state matrix is similar under the change of chart,
    // so its trace (0, no damping) and determinant (−ω²) agree
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fourbar.toml");
    let sc = scenario::load(&p, &["force[0].torque=0".to_string()]).unwrap();
    let sys = &sc.system;
    let eq = static_equilibrium(sys, &sc.q0, StaticOptions::default()).unwrap();
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let qd = vec![0.0; n];
    let mut a = dense(sys, &eq.q);
    let d = full_pivot_order(&mut a, m, n, RANK_TOL);
    let dense_choice: Vec<usize> = d.cols[d.rank..].to_vec();
    let sparse_choice = partition_at(sys, &eq.q, 0.0).independent;
    println!("independent: sparse {sparse_choice:?}, dense {dense_choice:?}");
    let model = |independent: Option<Vec<usize>>| {
        let opts = LinearizeOptions {
            independent,
            ..Default::default()
        };
        linearize(sys, &[], 0.0, &eq.q, &qd, &[], &[], &opts).unwrap()
    };
    let (sparse, given) = (model(None), model(Some(dense_choice)));
    let tr = |x: &faer::Mat<f64>| x[(0, 0)] + x[(1, 1)];
    let det = |x: &faer::Mat<f64>| x[(0, 0)] * x[(1, 1)] - x[(0, 1)] * x[(1, 0)];
    assert_eq!(sparse.a.nrows(), 2);
    let (t1, t2) = (tr(&sparse.a), tr(&given.a));
    let (d1, d2) = (det(&sparse.a), det(&given.a));
    assert!(t1.abs() < 1e-8 && t2.abs() < 1e-8, "trace {t1} vs {t2}");
    assert!(d1 < 0.0, "unstable: det = −ω² > 0? {d1}");
    assert!((d1 - d2).abs() <= 1e-8 * d1.abs(), "det {d1} vs {d2}");
}

#[test]
fn stiff_chain_beyond_the_dense_path() {
    // N = 20 000: Φ_q is 40 000 × 60 000 (19 GB dense); the sparse choice
    // makes every angle independent and every translation dependent
    let n_seg = 20_000;
    let (sys, q0, _, _) = stiff_chain(n_seg, 5f64.to_radians()).unwrap();
    let t = Instant::now();
    let p = partition_at(&sys, &q0, 0.0);
    let secs = t.elapsed().as_secs_f64();
    println!("stiff chain N = {n_seg}: partition in {secs:.3} s");
    let phis: Vec<usize> = (0..n_seg).map(|k| 3 * k + 2).collect();
    assert_eq!(p.rank, 2 * n_seg);
    assert!(p.redundant.is_empty());
    assert_eq!(p.independent, phis);
}
