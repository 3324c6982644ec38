//! The index-3 residual's two halves by bodies (`System::residual_halves`,
//! used by `Index3` on large systems): where they apply, and the residual
//! they give against the one-piece evaluation of forces and constraint
//! terms, in pools of one thread (where `Index3` evaluates in one piece)
//! and two (in halves).

use mbsolve::builders::{build_rod, stiff_chain, RodParams};
use mbsolve::formulation::Index3;
use mbsolve::integrate::{SecondOrderDae, StateView};
use mbsolve::linalg::SolverKind;
use mbsolve::model::{Evaluation, System};
use mbsolve::parallel::PARALLEL_MIN_COORDS;

/// A state away from rest: `q0` moved by `dx(b)` in x on body `b` and a
/// little everywhere, velocities, accelerations and multipliers.
fn state(
    sys: &System,
    q0: &[f64],
    dx: impl Fn(usize) -> f64,
) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let q: Vec<f64> = q0
        .iter()
        .enumerate()
        .map(|(i, x)| x + 1e-4 * (i as f64 * 0.7).sin() + if i % 3 == 0 { dx(i / 3) } else { 0.0 })
        .collect();
    let qd: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64 * 0.3).cos()).collect();
    let qdd: Vec<f64> = (0..n).map(|i| 10.0 * (i as f64 * 0.11).sin()).collect();
    let lam: Vec<f64> = (0..m).map(|r| 50.0 + (r as f64 * 0.2).sin()).collect();
    (q, qd, qdd, lam)
}

/// The residual of eq. (5) from the system's one-piece evaluations:
/// `s (M q̈ + Φ_qᵀλ − g)`, then Φ.
fn one_piece(sys: &System, q: &[f64], qd: &[f64], qdd: &[f64], lam: &[f64], s: f64) -> Vec<f64> {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let (mut g, mut tmp, mut phi) = (vec![0.0; n], vec![0.0; n], vec![0.0; m]);
    let mut vals = vec![0.0; sys.jacobian_pattern().len()];
    sys.forces_into(0.0, q, qd, &mut g);
    sys.phi_and_jacobian_tmul(q, 0.0, lam, &mut phi, &mut tmp, &mut vals);
    let mass = sys.mass_diagonal();
    let mut r: Vec<f64> = (0..n)
        .map(|k| s * (mass[k] * qdd[k] + tmp[k] - g[k]))
        .collect();
    r.extend(phi);
    r
}

fn check(sys: &System, q0: &[f64], dx: impl Fn(usize) -> f64) {
    let nb = sys.bodies().len();
    assert!(sys.n_coords() >= PARALLEL_MIN_COORDS);
    let h = sys.residual_halves(nb / 2).expect("the halves apply");
    assert_eq!(h.split(), 3 * (nb / 2));
    let (q, qd, qdd, lam) = state(sys, q0, dx);
    let s = 0.37;
    let want = one_piece(sys, &q, &qd, &qdd, &lam, s);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let got = pool.install(|| {
            let mut f = Index3::new(sys, SolverKind::Auto).unwrap();
            let mut r = vec![0.0; want.len()];
            // twice: the second call finds the buffers of the first
            for _ in 0..2 {
                let x = StateView {
                    t: 0.0,
                    q: &q,
                    qd: &qd,
                };
                SecondOrderDae::residual(&mut f, x, &qdd, &lam, s, &mut r).unwrap();
            }
            r
        });
        for i in 0..want.len() {
            assert_eq!(
                got[i].to_bits(),
                want[i].to_bits(),
                "{threads} threads: entry {i}{}: {} against {}",
                if h.boundary().contains(&i) {
                    " (boundary)"
                } else {
                    ""
                },
                got[i],
                want[i]
            );
        }
    }
}

/// The stiff chain (ground pivot after the chain's joints: the low half's
/// rows in two runs): the halves' residual has the bits of the one-piece
/// evaluation, with one thread and with two.
#[test]
fn stiff_chain_residual_in_halves_has_the_bits_of_one_piece() {
    let (sys, q0, _, _) = stiff_chain(2000, 5f64.to_radians()).unwrap();
    let h = sys.residual_halves(1000).unwrap();
    let runs: Vec<_> = h.row_runs().collect();
    assert_eq!(
        runs,
        [(false, 0..2000), (true, 2000..3998), (false, 3998..4000)]
    );
    // body 1000, which the spring and the joint across the split also load
    assert_eq!(h.boundary(), [3000, 3001, 3002]);
    check(&sys, &q0, |_| 0.0);
}

/// The falling rod with fluid loads and wall contacts (gravity and
/// buoyancy split by bodies, drag, springs and contacts by ranges), some
/// segments pushed into the walls, the split body too: the same bits.
#[test]
fn falling_rod_residual_in_halves_has_the_bits_of_one_piece() {
    let (sys, info) = build_rod(&RodParams::problem_b(2000)).unwrap();
    let _ = info;
    let (q0, _) = sys.initial_state();
    // walls at ±0.025 m, half-width 0.015: corners beyond the walls at |x| > 0.01
    let dx = |b: usize| match b % 7 {
        0 => 0.0115,
        6 => -0.0115,
        _ => 0.0,
    };
    assert_eq!(1000 % 7, 6, "the split body is in contact");
    check(&sys, &q0, dx);
    // the contacts act in this state: the forces differ from those of the
    // same rod without contacts, on both sides of the split
    let (free, _) = build_rod(&RodParams {
        contact: false,
        ..RodParams::problem_b(2000)
    })
    .unwrap();
    let (q, qd, _, _) = state(&sys, &q0, dx);
    let (mut g, mut g_free) = (vec![0.0; sys.n_coords()], vec![0.0; sys.n_coords()]);
    sys.forces_into(0.0, &q, &qd, &mut g);
    free.forces_into(0.0, &q, &qd, &mut g_free);
    let split = 3 * 1000;
    let touched = |r: std::ops::Range<usize>| r.filter(|&k| g[k] != g_free[k]).count();
    assert!(touched(0..split) > 100 && touched(split..3 * 2000) > 100);
}

/// The halves need the generated kernels: not with the generic evaluation.
#[test]
fn no_halves_with_the_generic_evaluation() {
    let (mut sys, _, _, _) = stiff_chain(2000, 5f64.to_radians()).unwrap();
    assert!(sys.residual_halves(1000).is_some());
    sys.set_evaluation(Evaluation::Generic).unwrap();
    assert!(sys.residual_halves(1000).is_none());
}
