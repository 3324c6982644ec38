//! Factorisation + one solve of the Newton matrix of the stiff chain of
//! `../shared/peers/` (`builders::stiff_chain`) by the solver `Index3` uses
//! (`ChainLdlt`, the envelope LDLᵀ), by faer's sparse LDLᵀ (no residual
//! check) and by a hand-written block-tridiagonal LDLᵀ of the same chain
//! written here, independent of the library's solvers: the floor the
//! library's solve is held to (within 1.3×).
//!
//! ```text
//! cargo bench --bench newton_solve            # criterion, N = 1000 and 10 000
//! cargo bench --bench newton_solve -- ratio   # only the printed ratios
//! cargo bench --bench newton_solve -- threads # split envelope, 1 vs 2 threads
//! ```
//!
//! `threads`: the envelope factor + solve at N = 10 000 (two-sided order,
//! halves concurrent: `ChainLdlt`, `PARALLEL_MIN_DIM`) in a one-thread and
//! a two-thread rayon pool, and the one-sided order in one thread; wall
//! time (what two threads speed up), interleaved, minimum over batches.
//!
//! The ratios are printed from interleaved repetitions (minimum over
//! batches) in the same run, so they do not depend on the machine's speed.

// dense 5×5 block arithmetic reads clearest with index loops
#![allow(clippy::needless_range_loop)]

use criterion::{criterion_group, Criterion};
use mbsolve::builders::stiff_chain;
use mbsolve::formulation::Index3;
use mbsolve::linalg::{SaddleMatrix, SaddlePointSolver, SolverKind, SparseLdlt};
use std::hint::black_box;
use std::time::Instant;

type B5 = [[f64; 5]; 5];

/// Block-tridiagonal LDLᵀ of the stiff chain's saddle matrix, block k =
/// (x_k, y_k, φ_k, the two multipliers of the joint above body k): the
/// block Schur recurrence `S_k = D_k − B_k S_{k−1}⁻¹ B_kᵀ`, each `S_k`
/// factorised densely (LDLᵀ without pivoting: coordinates before
/// multipliers).
struct BlockTridiagonal {
    nb: usize,
    /// `(slot of K, block k, row, col, sub)`: `sub` = entry of `B_k`
    /// (row in block k, column in block k − 1), else of `D_k` (lower).
    map: Vec<(usize, usize, usize, usize, bool)>,
    d: Vec<B5>,
    b: Vec<B5>,
    /// LDLᵀ of `S_k`: unit lower `L` below the diagonal, `d` on it.
    s: Vec<B5>,
    /// `W_k = S_k⁻¹ B_{k+1}ᵀ`.
    w: Vec<B5>,
    z: Vec<[f64; 5]>,
}

/// (block, position) of K's row/column `i` for the stiff chain of `nb`
/// bodies: joint j (rows 2j, 2j + 1) between bodies j and j + 1 belongs to
/// block j + 1, the ground pivot (the last two rows) to block 0.
fn place(i: usize, nb: usize) -> (usize, usize) {
    let n = 3 * nb;
    if i < n {
        (i / 3, i % 3)
    } else {
        let r = i - n;
        if r < 2 * (nb - 1) {
            (r / 2 + 1, 3 + r % 2)
        } else {
            (0, 3 + (r - 2 * (nb - 1)))
        }
    }
}

impl BlockTridiagonal {
    fn new(k: &SaddleMatrix) -> Self {
        let nb = k.n() / 3;
        let mut map = Vec::new();
        for c in 0..k.dim() {
            for s in k.col_ptr()[c]..k.col_ptr()[c + 1] {
                let r = k.row_idx()[s];
                let ((br, pr), (bc, pc)) = (place(r, nb), place(c, nb));
                let ((br, pr), (bc, pc)) = if br >= bc {
                    ((br, pr), (bc, pc))
                } else {
                    ((bc, pc), (br, pr))
                };
                match br - bc {
                    0 => map.push((s, br, pr.max(pc), pr.min(pc), false)),
                    1 => map.push((s, br, pr, pc, true)),
                    _ => panic!("not block-tridiagonal: ({r}, {c})"),
                }
            }
        }
        let z = [[0.0; 5]; 5];
        Self {
            nb,
            map,
            d: vec![z; nb],
            b: vec![z; nb],
            s: vec![z; nb],
            w: vec![z; nb],
            z: vec![[0.0; 5]; nb],
        }
    }

    fn factorize(&mut self, vals: &[f64]) {
        for (d, b) in self.d.iter_mut().zip(&mut self.b) {
            *d = [[0.0; 5]; 5];
            *b = [[0.0; 5]; 5];
        }
        for &(s, k, i, j, sub) in &self.map {
            if sub {
                self.b[k][i][j] += vals[s];
            } else {
                self.d[k][i][j] += vals[s];
            }
        }
        for k in 0..self.nb {
            // S_k = D_k − B_k W_{k−1} (lower triangle)
            let mut s = self.d[k];
            if k > 0 {
                let (b, w) = (&self.b[k], &self.w[k - 1]);
                for i in 0..5 {
                    for j in 0..=i {
                        let mut acc = 0.0;
                        for l in 0..5 {
                            acc += b[i][l] * w[l][j];
                        }
                        s[i][j] -= acc;
                    }
                }
            }
            // dense LDLᵀ of S_k, in place
            for i in 0..5 {
                for j in 0..i {
                    let mut t = s[i][j];
                    for l in 0..j {
                        t -= s[i][l] * s[j][l] * s[l][l];
                    }
                    s[i][j] = t / s[j][j];
                }
                let mut d = s[i][i];
                for l in 0..i {
                    d -= s[i][l] * s[i][l] * s[l][l];
                }
                s[i][i] = d;
            }
            self.s[k] = s;
            // W_k = S_k⁻¹ B_{k+1}ᵀ
            if k + 1 < self.nb {
                let b = self.b[k + 1];
                let mut w = [[0.0; 5]; 5];
                for c in 0..5 {
                    let mut x = [b[c][0], b[c][1], b[c][2], b[c][3], b[c][4]];
                    ldlt_solve(&s, &mut x);
                    for r in 0..5 {
                        w[r][c] = x[r];
                    }
                }
                self.w[k] = w;
            }
        }
    }

    fn solve(&mut self, rhs: &mut [f64]) {
        let nb = self.nb;
        for (i, v) in rhs.iter().enumerate() {
            let (k, p) = place(i, nb);
            self.z[k][p] = *v;
        }
        // forward: z_k −= W_{k−1}ᵀ z_{k−1}
        for k in 1..nb {
            let (prev, cur) = self.z.split_at_mut(k);
            let (zp, w) = (&prev[k - 1], &self.w[k - 1]);
            for c in 0..5 {
                let mut acc = 0.0;
                for r in 0..5 {
                    acc += w[r][c] * zp[r];
                }
                cur[0][c] -= acc;
            }
        }
        // backward: x_k = S_k⁻¹ z_k − W_k x_{k+1}
        for k in (0..nb).rev() {
            ldlt_solve(&self.s[k], &mut self.z[k]);
            if k + 1 < nb {
                let (cur, next) = self.z.split_at_mut(k + 1);
                let w = &self.w[k];
                for r in 0..5 {
                    let mut acc = 0.0;
                    for c in 0..5 {
                        acc += w[r][c] * next[0][c];
                    }
                    cur[k][r] -= acc;
                }
            }
        }
        for (i, v) in rhs.iter_mut().enumerate() {
            let (k, p) = place(i, nb);
            *v = self.z[k][p];
        }
    }
}

/// `x ← S⁻¹ x` with `S = L D Lᵀ` stored in place.
fn ldlt_solve(s: &B5, x: &mut [f64; 5]) {
    for i in 0..5 {
        for l in 0..i {
            x[i] -= s[i][l] * x[l];
        }
    }
    for i in 0..5 {
        x[i] /= s[i][i];
    }
    for i in (0..5).rev() {
        for l in i + 1..5 {
            x[i] -= s[l][i] * x[l];
        }
    }
}

/// The Newton matrix of the stiff chain of `nb` segments at a moving
/// state, as `Index3` assembles it, and the solver `Index3` uses for it.
fn newton_matrix(nb: usize) -> (SaddleMatrix, Vec<f64>) {
    let (sys, mut q, _, _) = stiff_chain(nb, 5f64.to_radians()).expect("chain");
    for (i, x) in q.iter_mut().enumerate() {
        *x += 1e-3 * ((i as f64) * 0.71).sin();
    }
    let qd: Vec<f64> = (0..q.len())
        .map(|i| 0.1 * ((i as f64) * 0.37).cos())
        .collect();
    let lam: Vec<f64> = (0..sys.n_constraints())
        .map(|r| 5.0 + (r as f64 * 0.29).sin())
        .collect();
    let mut f = Index3::new(&sys, SolverKind::Auto).expect("index-3 form");
    let h: f64 = 1e-5;
    let s = 0.3 * h * h;
    f.assemble_and_factorize(0.0, &q, &qd, &lam, 1.1, 0.6 * h, s)
        .expect("factorises");
    let k = f.newton_matrix().clone();
    let b = (0..k.dim()).map(|i| ((i as f64) * 1.3).cos()).collect();
    (k, b)
}

fn factor_solve(s: &mut dyn SaddlePointSolver, k: &SaddleMatrix, b: &[f64], x: &mut [f64]) {
    s.factorize(k).expect("factorises");
    x.copy_from_slice(b);
    s.solve_in_place(k, x).expect("solves");
}

struct Case {
    k: SaddleMatrix,
    b: Vec<f64>,
    x: Vec<f64>,
    env: Box<dyn SaddlePointSolver>,
    faer: SparseLdlt,
    hand: BlockTridiagonal,
}

impl Case {
    fn new(nb: usize) -> Self {
        let (k, b) = newton_matrix(nb);
        let mut env = mbsolve::linalg::solver_for(
            SolverKind::Chain,
            k.dim(),
            mbsolve::linalg::SolverOptions {
                residual_check: false,
            },
        );
        env.analyze(&k).expect("analyses");
        assert_eq!(env.name(), "chain-ldlt");
        let mut faer = SparseLdlt::default().with_residual_check(false);
        faer.analyze(&k).expect("analyses");
        let mut hand = BlockTridiagonal::new(&k);
        // the three agree
        let x = vec![0.0; k.dim()];
        let mut c = Self {
            k,
            b,
            x,
            env,
            faer,
            hand,
        };
        factor_solve(&mut *c.env, &c.k, &c.b, &mut c.x);
        let xe = c.x.clone();
        c.hand.factorize(c.k.values());
        c.x.copy_from_slice(&c.b);
        c.hand.solve(&mut c.x);
        let scale = xe.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let d = xe
            .iter()
            .zip(&c.x)
            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            d <= 1e-8 * scale,
            "envelope vs hand-written: {d:e} (scale {scale:e})"
        );
        hand = BlockTridiagonal::new(&c.k);
        c.hand = hand;
        c
    }
    fn env(&mut self) {
        factor_solve(&mut *self.env, &self.k, &self.b, &mut self.x);
    }
    fn faer(&mut self) {
        factor_solve(&mut self.faer, &self.k, &self.b, &mut self.x);
    }
    fn hand(&mut self) {
        self.hand.factorize(self.k.values());
        self.x.copy_from_slice(&self.b);
        self.hand.solve(&mut self.x);
    }
    /// The solve alone, on the factorisation of the last `env` call.
    fn env_solve(&mut self) {
        self.x.copy_from_slice(&self.b);
        self.env
            .solve_in_place(&self.k, &mut self.x)
            .expect("solves");
    }
    /// The solve alone, on the factorisation of the last `hand` call.
    fn hand_solve(&mut self) {
        self.x.copy_from_slice(&self.b);
        self.hand.solve(&mut self.x);
    }
}

/// Seconds per call of `f`: minimum over `reps` batches of `batch` calls.
fn min_time(case: &mut Case, f: fn(&mut Case), batch: usize) -> f64 {
    let t = Instant::now();
    for _ in 0..batch {
        f(case);
    }
    black_box(&case.x);
    t.elapsed().as_secs_f64() / batch as f64
}

/// Print the ratios to the hand-written solver (interleaved repetitions).
fn ratios() {
    for nb in [1000, 10_000] {
        let mut c = Case::new(nb);
        let batch = (200_000 / nb).max(2);
        let (mut te, mut tf, mut th) = (f64::MAX, f64::MAX, f64::MAX);
        for _ in 0..30 {
            te = te.min(min_time(&mut c, Case::env, batch));
            tf = tf.min(min_time(&mut c, Case::faer, batch));
            th = th.min(min_time(&mut c, Case::hand, batch));
        }
        println!(
            "N = {nb}: factor+solve envelope {:.1} µs, faer simplicial {:.1} µs, \
             hand-written block-tridiagonal {:.1} µs; envelope/hand = {:.2}, faer/hand = {:.2}",
            te * 1e6,
            tf * 1e6,
            th * 1e6,
            te / th,
            tf / th
        );
        // the solve alone (what each Newton iteration on a kept matrix pays)
        c.env();
        c.hand();
        let (mut se, mut sh) = (f64::MAX, f64::MAX);
        for _ in 0..30 {
            se = se.min(min_time(&mut c, Case::env_solve, batch));
            sh = sh.min(min_time(&mut c, Case::hand_solve, batch));
        }
        println!(
            "N = {nb}: solve alone envelope {:.1} µs, hand-written {:.1} µs; envelope/hand = {:.2}",
            se * 1e6,
            sh * 1e6,
            se / sh
        );
    }
}

/// The envelope factor + solve at N = 10 000: split (two-sided) in pools
/// of 1 and 2 threads, one-sided in one thread; bit-identical x checked.
fn threads() {
    let mut c = Case::new(10_000);
    let mut one_sided = mbsolve::linalg::ChainLdlt::default()
        .with_residual_check(false)
        .with_split(false);
    one_sided.analyze(&c.k).expect("analyses");
    let pools: Vec<rayon::ThreadPool> = [1, 2]
        .iter()
        .map(|&n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
        })
        .collect();
    let mut xs = Vec::new();
    for p in &pools {
        p.install(|| c.env());
        xs.push(c.x.clone());
    }
    assert!(xs[0]
        .iter()
        .zip(&xs[1])
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    let batch = 20;
    let (mut t1, mut t2, mut to) = (f64::MAX, f64::MAX, f64::MAX);
    for _ in 0..30 {
        t1 = t1.min(pools[0].install(|| min_time(&mut c, Case::env, batch)));
        t2 = t2.min(pools[1].install(|| min_time(&mut c, Case::env, batch)));
        let t = Instant::now();
        for _ in 0..batch {
            factor_solve(&mut one_sided, &c.k, &c.b, &mut c.x);
        }
        to = to.min(t.elapsed().as_secs_f64() / batch as f64);
    }
    println!(
        "N = 10000: factor+solve split 1 thread {:.1} µs, 2 threads {:.1} µs (speed-up {:.2}); \
         one-sided 1 thread {:.1} µs (split/one-sided {:.2})",
        t1 * 1e6,
        t2 * 1e6,
        t1 / t2,
        to * 1e6,
        t1 / to
    );
}

fn bench(c: &mut Criterion) {
    let pools: Vec<rayon::ThreadPool> = [1, 2]
        .iter()
        .map(|&n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
        })
        .collect();
    let mut case = Case::new(10_000);
    let mut g = c.benchmark_group("newton_factor_solve_threads/N=10000");
    for (p, name) in pools.iter().zip(["split, 1 thread", "split, 2 threads"]) {
        g.bench_function(name, |b| p.install(|| b.iter(|| case.env())));
    }
    g.finish();
    for nb in [1000, 10_000] {
        let mut case = Case::new(nb);
        let mut g = c.benchmark_group(format!("newton_factor_solve/N={nb}"));
        g.bench_function("envelope (ChainLdlt)", |b| b.iter(|| case.env()));
        g.bench_function("faer sparse LDLt", |b| b.iter(|| case.faer()));
        g.bench_function("hand-written block-tridiagonal", |b| b.iter(|| case.hand()));
        g.finish();
    }
}

criterion_group!(benches, bench);

fn main() {
    if std::env::args().any(|a| a == "threads") {
        threads();
        return;
    }
    let only_ratio = std::env::args().any(|a| a == "ratio");
    if !only_ratio {
        benches();
        Criterion::default().configure_from_args().final_summary();
    }
    ratios();
}
