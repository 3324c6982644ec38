//! Numeric factorisation + one solve of the saddle-point matrix of a planar
//! pendulum chain (N bodies, ground joint + N − 1 revolute joints:
//! n = 3N, m = 2N) — the per-evaluation cost of the index-1 formulation.
//!
//! * `factor_solve/{sparse_amd, sparse_chain, sparse_natural, dense, yardstick}/N`
//!   for N ∈ {10, 100, 1000, 10 000} (dense only up to 1000): `SparseLdlt`
//!   with AMD (+ multiplier postponement), with the Baraff chain order
//!   (`chain_order`) and with the natural order, `DenseLu`, and a
//!   hand-written O(N) block-tridiagonal LDLᵀ of the same chain as the
//!   yardstick (blocks pre-extracted; it times elimination + solve only).
//! * `breakeven/{dense, sparse}/dim` on small chains: where `DenseLu` stops
//!   being faster than `SparseLdlt` (→ `linalg::AUTO_DENSE_MAX_DIM`).
//!
//! Symbolic analysis is done once outside the timed loop, as in the solver.
//! Run: `cargo bench --bench saddle_point` (≈ 1.5 min on 2 cores).
//!
//! Measured figures: docs/linear_solvers.md (the defaults they chose) and
//! docs/scaling.md.

// Small fixed-size block kernels read best with explicit indices.
#![allow(clippy::needless_range_loop)]

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode};
use mbsolve::linalg::{
    chain_order, DenseLu, Ordering, SaddleMatrix, SaddlePointSolver, SparseLdlt,
};
use std::time::Duration;

// ---------------------------------------------------------------------------
// The chain matrix.

struct Rng(u64);
impl Rng {
    fn unif(&mut self) -> f64 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.0 = x;
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn body_len(i: usize) -> f64 {
    0.5 + 0.37 * ((i * 7) % 5) as f64
}

/// Pendulum chain: joint 0 = ground – bottom of body 0 (rows 0, 1), joint
/// j = top of body j − 1 – bottom of body j (rows 2j, 2j + 1). Random
/// angles and masses.
fn chain(nb: usize, seed: u64) -> SaddleMatrix {
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let phi: Vec<f64> = (0..nb).map(|_| 6.2 * rng.unif() - 3.1).collect();
    let mut pat = Vec::new();
    let mut val = Vec::new();
    let mut end = |j: usize, i: usize, s: f64, sign: f64| {
        let (c, sn) = (phi[i].cos(), phi[i].sin());
        let rs = [c * s, sn * s];
        pat.extend_from_slice(&[
            (2 * j, 3 * i),
            (2 * j, 3 * i + 2),
            (2 * j + 1, 3 * i + 1),
            (2 * j + 1, 3 * i + 2),
        ]);
        val.extend_from_slice(&[sign, -sign * rs[1], sign, sign * rs[0]]);
    };
    end(0, 0, -0.5 * body_len(0), -1.0);
    for j in 1..nb {
        end(j, j - 1, 0.5 * body_len(j - 1), 1.0);
        end(j, j, -0.5 * body_len(j), -1.0);
    }
    let mut k = SaddleMatrix::new(3 * nb, 2 * nb, &[], &pat);
    let mut d = vec![0.0; 3 * nb];
    for i in 0..nb {
        let m = (0.1f64.ln() + rng.unif() * (1e3f64.ln() - 0.1f64.ln())).exp();
        d[3 * i] = m;
        d[3 * i + 1] = m;
        d[3 * i + 2] = m * body_len(i).powi(2) / 12.0;
    }
    k.set_a_diagonal(&d);
    k.set_jacobian(&val);
    k
}

fn chain_perm(nb: usize) -> Vec<usize> {
    let rows: Vec<_> = (0..nb).map(|j| (j, 2 * j..2 * j + 2)).collect();
    chain_order(nb, 2 * nb, &rows)
}

fn rhs(dim: usize) -> Vec<f64> {
    (0..dim).map(|i| (0.37 * i as f64).sin()).collect()
}

// ---------------------------------------------------------------------------
// Yardstick: block-tridiagonal LDLᵀ along the path
// B_{N−1}, J_{N−1}, B_{N−2}, J_{N−2}, …, B_0, J_0 (leaf first, Baraff).

type Blk = [[f64; 3]; 3];

struct BlockTri {
    size: Vec<usize>,
    /// Global indices of each node's rows.
    idx: Vec<[usize; 3]>,
    diag: Vec<Blk>,
    /// `low[p]` = K[node p + 1, node p].
    low: Vec<Blk>,
    dinv: Vec<Blk>,
    /// `w[p]` = low[p] · D_p⁻¹ (the block of L).
    w: Vec<Blk>,
    y: Vec<[f64; 3]>,
}

impl BlockTri {
    fn from_chain(k: &SaddleMatrix) -> Self {
        let nb = k.n() / 3;
        let n = k.n();
        let nodes = 2 * nb;
        let mut size = vec![0; nodes];
        let mut idx = vec![[0; 3]; nodes];
        // node and local index of each global index
        let mut loc = vec![(0usize, 0usize); k.dim()];
        for i in 0..nb {
            let pb = 2 * (nb - 1 - i);
            size[pb] = 3;
            idx[pb] = [3 * i, 3 * i + 1, 3 * i + 2];
            let pj = pb + 1;
            size[pj] = 2;
            idx[pj] = [n + 2 * i, n + 2 * i + 1, 0];
            for l in 0..3 {
                loc[3 * i + l] = (pb, l);
            }
            for l in 0..2 {
                loc[n + 2 * i + l] = (pj, l);
            }
        }
        let mut diag = vec![[[0.0; 3]; 3]; nodes];
        let mut low = vec![[[0.0; 3]; 3]; nodes];
        let (cp, ri, v) = (k.col_ptr(), k.row_idx(), k.values());
        for c in 0..k.dim() {
            for s in cp[c]..cp[c + 1] {
                let (pr, lr) = loc[ri[s]];
                let (pc, lc) = loc[c];
                if pr == pc {
                    diag[pr][lr][lc] = v[s];
                    diag[pr][lc][lr] = v[s];
                } else if pr == pc + 1 {
                    low[pc][lr][lc] = v[s];
                } else if pc == pr + 1 {
                    low[pr][lc][lr] = v[s];
                } else {
                    panic!("not a chain");
                }
            }
        }
        Self {
            dinv: vec![[[0.0; 3]; 3]; nodes],
            w: vec![[[0.0; 3]; 3]; nodes],
            y: vec![[0.0; 3]; nodes],
            size,
            idx,
            diag,
            low,
        }
    }

    fn factor(&mut self) {
        let p_n = self.size.len();
        for p in 0..p_n {
            let s = self.size[p];
            let mut d = self.diag[p];
            if p > 0 {
                // D_p = B_p − W_{p−1} C_{p−1}ᵀ
                let sp = self.size[p - 1];
                let (w, c) = (&self.w[p - 1], &self.low[p - 1]);
                for i in 0..s {
                    for j in 0..s {
                        let mut acc = 0.0;
                        for l in 0..sp {
                            acc += w[i][l] * c[j][l];
                        }
                        d[i][j] -= acc;
                    }
                }
            }
            self.dinv[p] = inverse(&d, s);
            if p + 1 < p_n {
                let sn = self.size[p + 1];
                let (c, di) = (&self.low[p], &self.dinv[p]);
                let mut w = [[0.0; 3]; 3];
                for i in 0..sn {
                    for j in 0..s {
                        let mut acc = 0.0;
                        for l in 0..s {
                            acc += c[i][l] * di[l][j];
                        }
                        w[i][j] = acc;
                    }
                }
                self.w[p] = w;
            }
        }
    }

    fn solve(&mut self, x: &mut [f64]) {
        let p_n = self.size.len();
        for p in 0..p_n {
            let s = self.size[p];
            let mut y = [0.0; 3];
            for l in 0..s {
                y[l] = x[self.idx[p][l]];
            }
            if p > 0 {
                let sp = self.size[p - 1];
                for i in 0..s {
                    for l in 0..sp {
                        y[i] -= self.w[p - 1][i][l] * self.y[p - 1][l];
                    }
                }
            }
            self.y[p] = y;
        }
        let mut next = [0.0; 3];
        for p in (0..p_n).rev() {
            let s = self.size[p];
            let mut xp = [0.0; 3];
            for i in 0..s {
                for l in 0..s {
                    xp[i] += self.dinv[p][i][l] * self.y[p][l];
                }
            }
            if p + 1 < p_n {
                let sn = self.size[p + 1];
                for i in 0..s {
                    for l in 0..sn {
                        xp[i] -= self.w[p][l][i] * next[l];
                    }
                }
            }
            for l in 0..s {
                x[self.idx[p][l]] = xp[l];
            }
            next = xp;
        }
    }
}

/// Inverse of the leading `s × s` block (Gauss–Jordan, partial pivoting).
fn inverse(a: &Blk, s: usize) -> Blk {
    let mut a = *a;
    let mut inv = [[0.0; 3]; 3];
    for i in 0..s {
        inv[i][i] = 1.0;
    }
    for c in 0..s {
        let p = (c..s)
            .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
            .unwrap();
        a.swap(c, p);
        inv.swap(c, p);
        let d = 1.0 / a[c][c];
        for j in 0..s {
            a[c][j] *= d;
            inv[c][j] *= d;
        }
        for i in 0..s {
            if i != c {
                let f = a[i][c];
                for j in 0..s {
                    a[i][j] -= f * a[c][j];
                    inv[i][j] -= f * inv[c][j];
                }
            }
        }
    }
    inv
}

// ---------------------------------------------------------------------------

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let m = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / m
}

fn sparse_solver(k: &SaddleMatrix, ord: Ordering) -> SparseLdlt {
    let mut s = SparseLdlt::new(ord);
    s.analyze(k).unwrap();
    s
}

fn factor_solve(c: &mut Criterion) {
    let mut g = c.benchmark_group("factor_solve");
    for nb in [10usize, 100, 1000, 10_000] {
        let k = chain(nb, nb as u64);
        let b = rhs(k.dim());
        let mut x = b.clone();
        let large = nb >= 1000;
        g.sample_size(if large { 20 } else { 50 });
        g.warm_up_time(Duration::from_millis(if large { 500 } else { 300 }));
        g.measurement_time(Duration::from_millis(if large { 2000 } else { 1000 }));
        g.sampling_mode(SamplingMode::Auto);

        // Reference solution for the sanity checks.
        let mut xref = b.clone();
        {
            let mut s = sparse_solver(&k, Ordering::Natural);
            s.factorize(&k).unwrap();
            s.solve_in_place(&k, &mut xref).unwrap();
        }
        for (name, ord, check) in [
            ("sparse_amd", Ordering::Amd, true),
            ("sparse_amd_nocheck", Ordering::Amd, false),
            ("sparse_chain", Ordering::Custom(chain_perm(nb)), true),
            ("sparse_natural", Ordering::Natural, true),
        ] {
            let mut s = sparse_solver(&k, ord);
            s = s.with_residual_check(check);
            s.factorize(&k).unwrap();
            x.copy_from_slice(&b);
            s.solve_in_place(&k, &mut x).unwrap();
            assert!(rel_diff(&x, &xref) < 1e-9);
            eprintln!(
                "N = {nb}: {name}: dim {}, nnz(K) {}, nnz(L) {}, supernodal {:?}",
                k.dim(),
                k.nnz(),
                s.factor_nnz().unwrap(),
                s.is_supernodal().unwrap()
            );
            g.bench_function(BenchmarkId::new(name, nb), |bch| {
                bch.iter(|| {
                    s.factorize(black_box(&k)).unwrap();
                    x.copy_from_slice(&b);
                    s.solve_in_place(&k, &mut x).unwrap();
                    black_box(&x);
                })
            });
        }

        let mut bt = BlockTri::from_chain(&k);
        bt.factor();
        x.copy_from_slice(&b);
        bt.solve(&mut x);
        assert!(rel_diff(&x, &xref) < 1e-8, "yardstick disagrees");
        g.bench_function(BenchmarkId::new("yardstick", nb), |bch| {
            bch.iter(|| {
                bt.factor();
                x.copy_from_slice(&b);
                bt.solve(&mut x);
                black_box(&x);
            })
        });

        if nb <= 1000 {
            let mut d = DenseLu::default();
            d.analyze(&k).unwrap();
            if nb == 1000 {
                // ~5000 × 5000 LU: seconds per iteration.
                g.sample_size(10);
                g.sampling_mode(SamplingMode::Flat);
                g.warm_up_time(Duration::from_millis(1));
                g.measurement_time(Duration::from_secs(5));
            }
            g.bench_function(BenchmarkId::new("dense", nb), |bch| {
                bch.iter(|| {
                    d.factorize(black_box(&k)).unwrap();
                    x.copy_from_slice(&b);
                    d.solve_in_place(&k, &mut x).unwrap();
                    black_box(&x);
                })
            });
        }
    }
    g.finish();
}

fn breakeven(c: &mut Criterion) {
    let mut g = c.benchmark_group("breakeven");
    g.sample_size(30);
    g.warm_up_time(Duration::from_millis(200));
    g.measurement_time(Duration::from_millis(400));
    for nb in [1usize, 2, 3, 4, 6, 8, 12, 16, 24] {
        let k = chain(nb, 3 + nb as u64);
        let dim = k.dim();
        let b = rhs(dim);
        let mut x = b.clone();
        let mut d = DenseLu::default();
        d.analyze(&k).unwrap();
        g.bench_function(BenchmarkId::new("dense", dim), |bch| {
            bch.iter(|| {
                d.factorize(black_box(&k)).unwrap();
                x.copy_from_slice(&b);
                d.solve_in_place(&k, &mut x).unwrap();
                black_box(&x);
            })
        });
        let mut s = sparse_solver(&k, Ordering::default());
        g.bench_function(BenchmarkId::new("sparse", dim), |bch| {
            bch.iter(|| {
                s.factorize(black_box(&k)).unwrap();
                x.copy_from_slice(&b);
                s.solve_in_place(&k, &mut x).unwrap();
                black_box(&x);
            })
        });
    }
    g.finish();
}

criterion_group!(benches, factor_solve, breakeven);
criterion_main!(benches);
