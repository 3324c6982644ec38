//! The bench-gate's hot paths timed against an in-process yardstick (a
//! block Cholesky of known flop count), in thread CPU time.

use super::{per_call, Check};
use mbsolve::builders::stiff_chain;
use mbsolve::linalg::{SaddleMatrix, SaddlePointSolver, SolverKind};

/// Blocks of the yardstick ([`yardstick`]).
const YARD_BLOCKS: usize = 20_000;

/// Flops of one yardstick run: per 3 × 3 block about 36 for the Schur
/// update, 20 for the Cholesky factor, 45 for the next off-diagonal block
/// and 60 for the forward and back substitution: ≈ 160 per block.
pub const YARD_FLOPS: f64 = 160.0 * YARD_BLOCKS as f64;

/// The yardstick of the hot-path timings: the block Cholesky factorisation
/// and solve of a fixed symmetric positive definite block-tridiagonal
/// matrix (3 × 3 blocks, [`YARD_BLOCKS`] of them; diagonal blocks
/// `4I + S`, off-diagonal blocks `−I/2 + T`, `S`, `T` small and fixed),
/// about [`YARD_FLOPS`] flops streamed through memory like a chain
/// factorisation. Plain Rust without the crate's or faer's code, so that
/// a regression there cannot move the yardstick. Returns a checksum (kept
/// live against the optimiser).
pub(super) fn yardstick(
    l_diag: &mut [[f64; 9]],
    l_off: &mut [[f64; 9]],
    x: &mut [[f64; 3]],
) -> f64 {
    let nb = l_diag.len();
    let d = |i: usize| -> [f64; 9] {
        let s = 0.1 * ((i % 7) as f64) / 7.0;
        [4.0 + s, s, 0.0, s, 4.0, s, 0.0, s, 4.0 - s]
    };
    let b = |i: usize| -> [f64; 9] {
        let t = 0.05 * ((i % 5) as f64) / 5.0;
        [-0.5, t, 0.0, 0.0, -0.5, t, t, 0.0, -0.5]
    };
    for i in 0..nb {
        // A = D_i − L_{i,i−1} L_{i,i−1}ᵀ (lower triangle)
        let mut a = d(i);
        if i > 0 {
            let lo = &l_off[i - 1];
            for r in 0..3 {
                for c in 0..=r {
                    let mut s = 0.0;
                    for k in 0..3 {
                        s += lo[3 * r + k] * lo[3 * c + k];
                    }
                    a[3 * r + c] -= s;
                }
            }
        }
        // Cholesky of A
        let l = &mut l_diag[i];
        *l = [0.0; 9];
        for c in 0..3 {
            let mut s = a[3 * c + c];
            for k in 0..c {
                s -= l[3 * c + k] * l[3 * c + k];
            }
            let p = s.sqrt();
            l[3 * c + c] = p;
            for r in c + 1..3 {
                let mut s = a[3 * r + c];
                for k in 0..c {
                    s -= l[3 * r + k] * l[3 * c + k];
                }
                l[3 * r + c] = s / p;
            }
        }
        // L_{i+1,i} = B_iᵀ L_iiᵀ⁻¹: rows x of X with X L_iiᵀ = B_iᵀ
        if i + 1 < nb {
            let bi = b(i);
            let lo = &mut l_off[i];
            for r in 0..3 {
                for c in 0..3 {
                    let mut s = bi[3 * c + r];
                    for k in 0..c {
                        s -= lo[3 * r + k] * l[3 * c + k];
                    }
                    lo[3 * r + c] = s / l[3 * c + c];
                }
            }
        }
    }
    // forward: L y = 1, back: Lᵀ x = y
    for i in 0..nb {
        let mut r = [1.0; 3];
        if i > 0 {
            let (lo, y) = (&l_off[i - 1], x[i - 1]);
            for (k, rk) in r.iter_mut().enumerate() {
                *rk -= lo[3 * k] * y[0] + lo[3 * k + 1] * y[1] + lo[3 * k + 2] * y[2];
            }
        }
        let l = &l_diag[i];
        for k in 0..3 {
            let mut s = r[k];
            for j in 0..k {
                s -= l[3 * k + j] * x[i][j];
            }
            x[i][k] = s / l[3 * k + k];
        }
    }
    for i in (0..nb).rev() {
        let mut r = x[i];
        if i + 1 < nb {
            let (lo, y) = (&l_off[i], x[i + 1]);
            for (k, rk) in r.iter_mut().enumerate() {
                *rk -= lo[k] * y[0] + lo[3 + k] * y[1] + lo[6 + k] * y[2];
            }
        }
        let l = &l_diag[i];
        for k in (0..3).rev() {
            let mut s = r[k];
            for j in k + 1..3 {
                s -= l[3 * j + k] * x[i][j];
            }
            x[i][k] = s / l[3 * k + k];
        }
    }
    x.iter().map(|v| v[0] + v[1] + v[2]).sum()
}

/// Bounds of [`hot_paths_against_yardstick`]: each hot path's time over
/// the yardstick's may be at most this many times its clean ratio
/// ([`HOT_PATH_CLEAN`]): between a clean run's spread of the median and
/// the cost of a path done twice (2× its repeated part), at their
/// geometric middle (the figures: docs/scaling.md, "The gate's hot paths").
pub const HOT_PATH_MARGIN: f64 = 1.3;

/// Repetitions of each hot-path measurement; the median of the per-round
/// ratios counts.
pub const HOT_PATH_ROUNDS: usize = 15;

/// One hot path: its name, the ratio to the yardstick measured on a clean
/// build (the reference of the bound, a pin) and the closure timed.
struct HotPath<'a> {
    name: &'static str,
    clean: f64,
    run: Box<dyn FnMut() + 'a>,
}

impl<'a> HotPath<'a> {
    /// The path `name` run by `run` (its clean time set later).
    fn new(name: &'static str, run: impl FnMut() + 'a) -> Self {
        HotPath {
            name,
            clean: 0.0,
            run: Box::new(run),
        }
    }
}

/// The hot path `name`: `solver` factorises `k` and solves `k x = b`.
fn factor_and_solve<'a, S: SaddlePointSolver>(
    name: &'static str,
    solver: &'a mut S,
    (k, b, x): (&'a SaddleMatrix, &'a [f64], &'a mut [f64]),
) -> HotPath<'a> {
    HotPath::new(name, move || {
        solver.factorize(k).expect("factorises");
        x.copy_from_slice(b);
        solver.solve_in_place(k, x).expect("solves");
    })
}

/// The hot paths of an implicit run on the stiff chain (N = 1000, its
/// Newton matrix at a bent, moving state), each timed against the
/// [`yardstick`] in the same round, on the gate's one thread: the sparse
/// LDLᵀ factor + solve (faer, chain ordering), the chain LDLᵀ factor +
/// solve (`ChainLdlt`, the Newton default), the index-3 residual and one
/// Newton iteration (residual, assembly and factorisation, solve). For
/// each path the median over [`HOT_PATH_ROUNDS`] rounds of
/// (path time / yardstick time) must stay below [`HOT_PATH_MARGIN`] ×
/// its clean ratio.
pub fn hot_paths_against_yardstick() -> Vec<Check> {
    use mbsolve::formulation::Index3;
    use mbsolve::linalg::{ChainLdlt, SparseLdlt};
    let (sys, q0, _, _) = stiff_chain(1000, 5f64.to_radians()).expect("stiff chain builds");
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let q: Vec<f64> = q0
        .iter()
        .enumerate()
        .map(|(i, x)| x + 1e-4 * (i as f64 * 0.7).sin())
        .collect();
    let qd: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64 * 1.3).cos()).collect();
    let qdd: Vec<f64> = (0..n).map(|i| (i as f64 * 0.4).sin()).collect();
    let lam: Vec<f64> = (0..m).map(|i| 1.0 + 0.1 * (i as f64 * 0.3).sin()).collect();
    let (h, beta, gamma) = (1e-5, 0.3, 0.6);
    let (c_m, c_c, c_k) = (1.0, gamma * h, beta * h * h);
    let mut f = Index3::new(&sys, SolverKind::Auto).expect("formulation");
    f.assemble_and_factorize(0.0, &q, &qd, &lam, c_m, c_c, c_k)
        .expect("factorises");
    let k = f.newton_matrix().clone();
    let b: Vec<f64> = (0..n + m).map(|i| (i as f64 * 0.37).sin()).collect();
    let mut sparse = SparseLdlt::default().with_residual_check(false);
    let mut chain = ChainLdlt::default().with_residual_check(false);
    let mut x = b.clone();
    let setup = sparse
        .analyze(&k)
        .and_then(|_| chain.analyze(&k))
        .map_err(|e| e.to_string());
    if let Err(e) = setup {
        return vec![Check {
            name: "hot paths against the yardstick".into(),
            ratio: f64::INFINITY,
            threshold: HOT_PATH_MARGIN,
            at_most: true,
            passed: false,
            detail: e,
        }];
    }
    let mut x2 = b.clone();
    let mut x3 = b.clone();
    let mut r = vec![0.0; n + m];
    let mut r2 = vec![0.0; n + m];
    let mut f2 = Index3::new(&sys, SolverKind::Auto).expect("formulation");
    let mut paths = [
        factor_and_solve(
            "sparse LDLᵀ factor + solve (faer), stiff chain N = 1000 Newton matrix",
            &mut sparse,
            (&k, &b, &mut x),
        ),
        factor_and_solve(
            "chain LDLᵀ factor + solve, stiff chain N = 1000 Newton matrix",
            &mut chain,
            (&k, &b, &mut x2),
        ),
        HotPath::new("index-3 residual, stiff chain N = 1000", || {
            f.residual_into(0.0, &q, &qd, &qdd, &lam, 1.0, &mut r)
                .expect("residual");
        }),
        HotPath::new(
            "one Newton iteration (residual, assembly + factorisation, solve), stiff chain N = 1000",
            || {
                f2.residual_into(0.0, &q, &qd, &qdd, &lam, 1.0, &mut r2)
                    .expect("residual");
                f2.assemble_and_factorize(0.0, &q, &qd, &lam, c_m, c_c, c_k)
                    .expect("factorises");
                x3.copy_from_slice(&r2);
                f2.solve_newton(0.0, &mut x3).expect("solves");
            },
        ),
    ];
    for (p, clean) in paths.iter_mut().zip(HOT_PATH_CLEAN) {
        p.clean = clean;
    }
    let mut l_diag = vec![[0.0; 9]; YARD_BLOCKS];
    let mut l_off = vec![[0.0; 9]; YARD_BLOCKS];
    let mut xy = vec![[0.0; 3]; YARD_BLOCKS];
    let mut yard = || {
        std::hint::black_box(yardstick(&mut l_diag, &mut l_off, &mut xy));
    };
    // warm-up and batch sizes of ≈ 4 ms each
    let t_yard = per_call(3, &mut yard);
    let batch = |t: f64| ((4e-3 / t.max(1e-9)).ceil() as usize).clamp(1, 1000);
    let yard_batch = batch(t_yard);
    let batches: Vec<usize> = paths
        .iter_mut()
        .map(|p| batch(per_call(3, &mut p.run)))
        .collect();
    let mut ratios = vec![Vec::with_capacity(HOT_PATH_ROUNDS); paths.len()];
    let mut yard_times = Vec::with_capacity(HOT_PATH_ROUNDS);
    for _ in 0..HOT_PATH_ROUNDS {
        for (i, p) in paths.iter_mut().enumerate() {
            // the yardstick right before each path: a load change hits both
            let ty = per_call(yard_batch, &mut yard);
            let tp = per_call(batches[i], &mut p.run);
            yard_times.push(ty);
            ratios[i].push(tp / ty);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let ty = median(&mut yard_times);
    paths
        .iter()
        .zip(&mut ratios)
        .map(|(p, rs)| {
            let r = median(rs);
            let bound = HOT_PATH_MARGIN * p.clean;
            Check {
                name: format!("{} over the yardstick", p.name),
                ratio: r,
                threshold: bound,
                at_most: true,
                passed: r <= bound,
                detail: format!(
                    "{r:.4}, median of {HOT_PATH_ROUNDS} rounds (spread {:.4}–{:.4}); {:.1} µs vs yardstick {:.2} ms ({:.2} Gflop/s) of thread CPU time; clean ratio {}",
                    rs[0],
                    rs[rs.len() - 1],
                    r * ty * 1e6,
                    ty * 1e3,
                    YARD_FLOPS / ty * 1e-9,
                    p.clean
                ),
            }
        })
        .collect()
}

/// Ratios (path time / yardstick time) of [`hot_paths_against_yardstick`]
/// on a clean build, in the order of the paths there: sparse, chain,
/// residual, Newton iteration (pins from clean gate runs: docs/scaling.md,
/// "The gate's hot paths and work counts").
pub const HOT_PATH_CLEAN: [f64; 4] = [0.217, 0.142, 0.0086, 0.198];
