//! Stability of a static equilibrium ([`super::statics`]) by the inertia
//! of the constrained stiffness.
//!
//! **Stability** ([`stability`]): the equilibrium is stable when `K` is
//! positive definite on the tangent space `Φ_q δq = 0`. The signs of the
//! eigenvalues of the constrained pencil `(K, M)` (ω² of the modes) come
//! from Sylvester's law of inertia: with `Φ_q` of full row rank `m`, the
//! saddle matrix `S(σ) = [K − σM, Φ_qᵀ; Φ_q, 0]` has `m + (number of ω² < σ)`
//! negative eigenvalues (Gould 1985; Haynsworth's inertia additivity on
//! the null-space form). Its inertia is read from the signs of `D` in an
//! unpivoted sparse LDLᵀ of the congruent matrix
//! `[K − σM + ρΦ_qᵀΦ_q, Φ_qᵀ; Φ_q, 0]` (the augmentation makes the
//! coordinate pivots well sized; it does not change the inertia), so no
//! eigenvalue is computed. Two shifts `σ = ∓s` separate unstable
//! (`ω² < −s`), neutral (`|ω²| ≤ s`) and stable directions.

use super::statics::StaticError;
use super::tangent::{Tangent, Triplets};
use crate::formulation::FormulationError;
use crate::model::System;
use serde::Serialize;

/// Counts of the constrained stiffness's eigenvalue signs ([`stability`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Stability {
    /// Directions with `ω² > s` (stable).
    pub stable: usize,
    /// Directions with `ω² < −s` (unstable).
    pub unstable: usize,
    /// Directions with `|ω²| ≤ s` (neutral: mechanisms, rigid-body motion).
    pub neutral: usize,
}

impl Stability {
    /// "stable", "unstable" (any unstable direction) or "neutral" (none
    /// unstable, some neutral).
    pub fn verdict(&self) -> &'static str {
        if self.unstable > 0 {
            "unstable"
        } else if self.neutral > 0 {
            "neutral"
        } else {
            "stable"
        }
    }
}

/// Φ_q without its redundant rows (those the sparse coordinate
/// partitioning, [`super::partitioning::partition`], eliminates to zero),
/// the kept rows renumbered in order: the same tangent space, full row
/// rank.
fn independent_rows(phi: Triplets) -> Triplets {
    let p =
        super::partitioning::partition(phi.rows, phi.cols, &phi.entries, super::inverse::RANK_TOL);
    if p.redundant.is_empty() {
        return phi;
    }
    let mut new_row = vec![usize::MAX; phi.rows];
    let mut kept = 0;
    for (r, slot) in new_row.iter_mut().enumerate() {
        if p.redundant.binary_search(&r).is_err() {
            *slot = kept;
            kept += 1;
        }
    }
    Triplets {
        rows: kept,
        cols: phi.cols,
        entries: phi
            .entries
            .iter()
            .filter(|e| new_row[e.0] != usize::MAX)
            .map(|&(r, c, v)| (new_row[r], c, v))
            .collect(),
    }
}

/// The stability of the state `(q, λ)` at rest (module docs): the numbers
/// of constrained directions with `ω² > s`, `ω² < −s` and `|ω²| ≤ s`,
/// `s = (2π f_neutral)²` \[1/s²\], from the inertia of two sparse LDLᵀ
/// factorisations. Redundant constraint rows are dropped first (the
/// tangent space `Φ_q δq = 0` is the same; the geometric stiffness keeps
/// every row's λ). A system with controller states is an error: its
/// stability is the first-order system's (module docs).
pub fn stability(
    sys: &System,
    t: f64,
    q: &[f64],
    lambda: &[f64],
    f_neutral: f64,
) -> Result<Stability, StaticError> {
    if let Some(st) = sys.states().first() {
        return Err(FormulationError::Invalid(format!(
            "stability by the constrained stiffness is about the mechanism alone; this system \
             has controller states ('{}', …): its stability is the first-order system's, the \
             eigenvalues of its linearisation (linearize, first_order_modes)",
            st.name
        ))
        .into());
    }
    let n = sys.n_coords();
    let mut tan = Tangent::new(sys);
    tan.evaluate(t, q, &vec![0.0; n], lambda)?;
    let k = tan.stiffness();
    let phi = independent_rows(tan.constraint_jacobian());
    let s = (2.0 * std::f64::consts::PI * f_neutral).powi(2);
    let mass = tan.mass_diagonal();
    let below = |sigma: f64| -> Result<usize, StaticError> {
        let (_, neg, zero) = constrained_inertia(&k, mass, sigma, &phi).map_err(|e| {
            FormulationError::Invalid(format!("stability at σ = {sigma:e} 1/s²: {e}"))
        })?;
        let m = phi.rows;
        if zero > 0 || neg < m {
            return Err(FormulationError::Invalid(format!(
                "stability: the saddle matrix at σ = {sigma:e} 1/s² has {zero} zero and {neg} \
                 negative pivots for {m} independent constraint rows: an eigenvalue sits on \
                 the shift"
            ))
            .into());
        }
        Ok(neg - m)
    };
    let unstable = below(-s)?;
    let below_plus = below(s)?;
    let dof = n - phi.rows;
    Ok(Stability {
        stable: dof.saturating_sub(below_plus),
        unstable,
        neutral: below_plus.saturating_sub(unstable),
    })
}

/// Inertia `(positive, negative, zero)` of
/// `[K_s − σM + ρΦ_qᵀΦ_q, Φ_qᵀ; Φ_q, 0]` (`K_s` the symmetric part of `k`,
/// `M = diag(mass)`), congruent to `[K_s − σM, Φ_qᵀ; Φ_q, 0]` for every ρ,
/// by an unpivoted sparse LDLᵀ (up-looking, Davis's LDL) in an AMD order
/// with each multiplier after the coordinates of its row. A pivot that
/// vanishes exactly is counted as zero and the factorisation continues
/// with a tiny replacement.
pub fn constrained_inertia(
    k: &Triplets,
    mass: &[f64],
    sigma: f64,
    phi: &Triplets,
) -> Result<(usize, usize, usize), String> {
    let (n, m) = (k.cols, phi.rows);
    let dim = n + m;
    // ρ: the coordinate diagonal's size over the Jacobian's squared size
    let mut adiag = vec![0.0f64; n];
    for &(i, j, v) in &k.entries {
        if i == j {
            adiag[i] += v;
        }
    }
    for (i, d) in adiag.iter_mut().enumerate() {
        *d -= sigma * mass[i];
    }
    let amax = adiag.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let pmax = phi.entries.iter().fold(0.0f64, |a, e| a.max(e.2.abs()));
    let rho = if pmax > 0.0 && amax > 0.0 {
        amax / (pmax * pmax)
    } else {
        1.0
    };
    // lower-triangle entries (row ≥ col) of the augmented saddle matrix
    let mut ent: Vec<(usize, usize, f64)> = Vec::new();
    for &(i, j, v) in &k.entries {
        // symmetric part: each of (i, j), (j, i) gets v/2
        let (r, c) = (i.max(j), i.min(j));
        ent.push((r, c, if i == j { v } else { 0.5 * v }));
    }
    for (i, &mi) in mass.iter().enumerate() {
        ent.push((i, i, -sigma * mi));
    }
    let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); m];
    for &(r, c, v) in &phi.entries {
        rows[r].push((c, v));
        ent.push((n + r, c, v));
    }
    for row in &rows {
        for (a, &(ca, va)) in row.iter().enumerate() {
            ent.push((ca, ca, rho * va * va));
            for &(cb, vb) in &row[a + 1..] {
                // (ca, cb) and (cb, ca) share one lower entry; a repeated
                // column gets both on its diagonal
                let v = rho * va * vb;
                if ca == cb {
                    ent.push((ca, ca, 2.0 * v));
                } else {
                    ent.push((ca.max(cb), ca.min(cb), v));
                }
            }
        }
    }
    let order = saddle_order(dim, n, &ent)?;
    let mut inv = vec![0usize; dim];
    for (new, &old) in order.iter().enumerate() {
        inv[old] = new;
    }
    // permuted upper CSC (row ≤ col)
    let mut cols: Vec<Vec<(usize, f64)>> = vec![Vec::new(); dim];
    for &(r, c, v) in &ent {
        let (a, b) = (inv[r], inv[c]);
        cols[a.max(b)].push((a.min(b), v));
    }
    let d = ldl_diagonal(dim, &cols);
    let (mut pos, mut neg, mut zero) = (0, 0, 0);
    for &v in &d {
        if !v.is_finite() {
            return Err("the LDLᵀ broke down (non-finite pivot)".into());
        }
        if v > 0.0 {
            pos += 1;
        } else if v < 0.0 {
            neg += 1;
        } else {
            zero += 1;
        }
    }
    Ok((pos, neg, zero))
}

/// Elimination order: faer's AMD of the pattern, each multiplier row
/// (index ≥ n) postponed until every coordinate of its row is eliminated.
fn saddle_order(dim: usize, n: usize, ent: &[(usize, usize, f64)]) -> Result<Vec<usize>, String> {
    // symmetric pattern, both triangles, sorted and unique
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); dim];
    for &(r, c, _) in ent {
        adj[c].push(r);
        if r != c {
            adj[r].push(c);
        }
    }
    for (c, a) in adj.iter_mut().enumerate() {
        a.push(c);
        a.sort_unstable();
        a.dedup();
    }
    let mut col_ptr = vec![0usize; dim + 1];
    for c in 0..dim {
        col_ptr[c + 1] = col_ptr[c] + adj[c].len();
    }
    let row_idx: Vec<usize> = adj.concat();
    let fwd = crate::linalg::amd_permutation(dim, &col_ptr, &row_idx)?;
    let order = crate::linalg::postpone_multipliers(&fwd, n, |c| &adj[c]);
    if order.len() != dim {
        return Err("the elimination order is not a permutation".into());
    }
    Ok(order)
}

/// The diagonal `D` of the unpivoted LDLᵀ of a symmetric matrix given by
/// its upper-triangle columns (`cols[k]`: `(i, v)` with `i ≤ k`,
/// duplicates summed): Davis's up-looking LDL (elimination tree, then one
/// sparse triangular solve per row). A zero pivot is replaced by a tiny
/// value of the matrix's scale and reported as 0.
fn ldl_diagonal(dim: usize, cols: &[Vec<(usize, f64)>]) -> Vec<f64> {
    const NONE: usize = usize::MAX;
    // symbolic: elimination tree and column counts
    let mut parent = vec![NONE; dim];
    let mut lnz = vec![0usize; dim];
    let mut flag = vec![NONE; dim];
    for k in 0..dim {
        flag[k] = k;
        for &(i0, _) in &cols[k] {
            let mut i = i0;
            if i < k {
                while flag[i] != k {
                    if parent[i] == NONE {
                        parent[i] = k;
                    }
                    lnz[i] += 1;
                    flag[i] = k;
                    i = parent[i];
                }
            }
        }
    }
    let mut lp = vec![0usize; dim + 1];
    for k in 0..dim {
        lp[k + 1] = lp[k] + lnz[k];
    }
    let mut li = vec![0usize; lp[dim]];
    let mut lx = vec![0.0f64; lp[dim]];
    let mut d = vec![0.0f64; dim];
    let mut reported = vec![0.0f64; dim];
    let mut y = vec![0.0f64; dim];
    let mut pattern = vec![0usize; dim];
    lnz.fill(0);
    flag.fill(NONE);
    let big = cols
        .iter()
        .flatten()
        .fold(0.0f64, |a, &(_, v)| a.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    for k in 0..dim {
        y[k] = 0.0;
        let mut top = dim;
        flag[k] = k;
        for &(i0, v) in &cols[k] {
            let mut i = i0;
            y[i] += v;
            let mut len = 0;
            while flag[i] != k {
                pattern[len] = i;
                len += 1;
                flag[i] = k;
                i = parent[i];
            }
            while len > 0 {
                top -= 1;
                len -= 1;
                pattern[top] = pattern[len];
            }
        }
        d[k] = y[k];
        y[k] = 0.0;
        while top < dim {
            let i = pattern[top];
            top += 1;
            let yi = y[i];
            y[i] = 0.0;
            let p2 = lp[i] + lnz[i];
            for p in lp[i]..p2 {
                y[li[p]] -= lx[p] * yi;
            }
            let l_ki = yi / d[i];
            d[k] -= l_ki * yi;
            li[p2] = k;
            lx[p2] = l_ki;
            lnz[i] += 1;
        }
        reported[k] = d[k];
        if d[k] == 0.0 {
            d[k] = 1e-300 * big;
        }
    }
    reported
}
