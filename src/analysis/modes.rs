//! Eigenmodes of the constrained system linearised about a state
//! ([`super::tangent`]: `M δq̈ + C δq̇ + K δq + Φ_qᵀ δλ = 0`, `Φ_q δq = 0`).
//!
//! **Undamped modes**: `K x = ω² M x`, `Φ_q x = 0` — the `count` eigenvalues
//! nearest the shift σ (the lowest ones for σ at or below the spectrum)
//! by Lanczos with M-orthogonal reorthogonalisation (partial: against
//! the whole basis only where the measured loss of orthogonality exceeds
//! `√ε`, Simon 1984; `orthogonalise`) on the shift-inverted operator
//! `x ↦ y`, `[K − σM, Φ_qᵀ; Φ_q, 0] [y; μ] = [M x; 0]`
//! (Ericsson & Ruhe 1980; the constrained form keeps every iterate in
//! `Φ_q y = 0`). The saddle matrix is factorised once by an LU with
//! partial pivoting ([`crate::linalg::ChainLu`]: in the band of the
//! body-by-body order for a chain, faer's sparse LU otherwise; exact also
//! where `K` is indefinite or singular on the coordinates); each Lanczos
//! step is one solve, so the cost is linear in N for chains. No dense N × N matrix is
//! formed. Ritz values `θ` of the tridiagonal matrix give
//! `ω² = σ + 1/θ`; a mode is converged when its residual estimate
//! `|β_j s_j| ≤ tol |θ|`. `K` is used as evaluated (symmetric for
//! conservative forces).
//!
//! **Damped modes**: the linearised first-order system projected onto the
//! undamped shapes `X` (M-orthonormal): `ẍ_r + XᵀCX ẋ_r + XᵀKX x_r = 0`, a
//! `2k × 2k` dense eigenproblem (faer). Exact when `C` is diagonal in
//! that basis (proportional damping, e.g. `C = αK`); otherwise the
//! coupling to the modes left out is neglected (modal truncation). Each
//! eigenvalue `s` is assigned to the undamped mode that dominates its
//! eigenvector; an underdamped mode gives `f_d = Im s / 2π`,
//! `ζ = −Re s / |s|`; an overdamped one (two real `s₁, s₂`)
//! `ω_n = √(s₁ s₂)`, `ζ = −(s₁ + s₂) / (2 ω_n)`, `f_d = 0`.

//!
//! **Controller states** ([`crate::model::State`]: the velocity z of a
//! coordinate w nothing reads): the undamped and damped modes above are
//! the mechanism's with the states held fixed (`δz = 0`: w is kept out of
//! the iteration, its shape entries are 0). The modes of the whole
//! first-order system, states included, are the eigenvalues of the
//! linearisation's `A` ([`first_order_modes`] of
//! [`super::linearize::StateSpace::a`]).

use super::tangent::Tangent;
use crate::formulation::FormulationError;
use crate::linalg::{SaddlePointSolver, SolverKind, Storage};
use serde::Serialize;

/// Options of [`eigenmodes`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModeOptions {
    /// Number of modes wanted (default 6; fewer when the system has fewer
    /// degrees of freedom).
    pub count: usize,
    /// Shift σ \[1/s²\]; `None` (default): 0, or, when the shifted matrix is
    /// singular (free rigid-body motion), `−10⁻⁶` of the largest
    /// `|K_ii| / M_ii` (of 1 when `K` has no diagonal:
    /// [`Tangent::stiffness_scale`]).
    pub shift: Option<f64>,
    /// Relative residual of a converged Ritz value (default 1e-10).
    pub tol: f64,
    /// Largest Lanczos basis (default 0: `max(4 count + 40, 80)`, at most
    /// the degrees of freedom).
    pub max_basis: usize,
    /// Solver of the shifted matrix: [`SolverKind::ChainLu`] (default: the
    /// band LU in the body-by-body order, faer's sparse LU for other
    /// patterns) or [`SolverKind::SparseLu`]; the symmetric solvers are
    /// rejected (`K` can be unsymmetric, `K − σM` indefinite).
    pub linear_solver: SolverKind,
}

impl Default for ModeOptions {
    fn default() -> Self {
        Self {
            count: 6,
            shift: None,
            tol: 1e-10,
            max_basis: 0,
            linear_solver: SolverKind::ChainLu,
        }
    }
}

/// One mode ([`eigenmodes`]).
#[derive(Debug, Clone, Serialize)]
pub struct Mode {
    /// ω² of the undamped mode \[1/s²\] (negative: an unstable direction).
    pub omega_squared: f64,
    /// Undamped natural frequency `√ω² / 2π` \[Hz\] (0 when ω² ≤ 0).
    pub frequency_hz: f64,
    /// Damped natural frequency \[Hz\] (0 for an overdamped mode).
    pub damped_frequency_hz: f64,
    /// Damping ratio ζ (0: undamped).
    pub damping_ratio: f64,
    /// Shape per coordinate (x, y, φ per body), M-normalised (`xᵀMx = 1`),
    /// its largest entry positive.
    pub shape: Vec<f64>,
    /// Relative residual estimate of the Ritz value.
    pub residual: f64,
}

/// The result of [`eigenmodes`].
#[derive(Debug, Clone, Serialize)]
pub struct Modes {
    /// The modes, by increasing ω².
    pub modes: Vec<Mode>,
    /// The shift σ used \[1/s²\].
    pub shift: f64,
    /// Lanczos steps (one solve each).
    pub lanczos_steps: usize,
    /// Whether every returned mode met the tolerance.
    pub converged: bool,
    /// The shifted matrix's factorisations (solver, count, fallbacks).
    pub factorizations: super::Factorizations,
}

/// The `count` undamped modes nearest the shift and their damped
/// counterparts at the last evaluated state of `tan` (module docs).
pub fn eigenmodes(tan: &Tangent, opts: ModeOptions) -> Result<Modes, FormulationError> {
    let (n, m) = (tan.n(), tan.m());
    // the controller states' coordinates nb.. are held (module docs)
    let nb = tan.system().n_body_coords();
    let mass = tan.mass_diagonal();
    let dof = nb.saturating_sub(m);
    let count = opts.count.min(dof);
    if count == 0 {
        return Ok(Modes {
            modes: Vec::new(),
            shift: 0.0,
            lanczos_steps: 0,
            converged: true,
            factorizations: Default::default(),
        });
    }
    let mut k = tan.saddle_matrix(Storage::Full);
    let mut solver = super::full_storage_solver(opts.linear_solver, n + m, "eigenmodes")?;
    let lin = |source| FormulationError::Linear {
        t: f64::NAN,
        source,
    };
    solver.analyze(&k).map_err(lin)?;
    // σ as asked, or 0 and then (singular at 0) a fraction of K's scale
    let tries = if opts.shift.is_some() { 1 } else { 2 };
    let mut shifts: Vec<f64> = Vec::new();
    let mut sigma = f64::NAN;
    while shifts.len() < tries {
        let s = match (opts.shift, shifts.len()) {
            (Some(s), _) => s,
            (None, 0) => 0.0,
            (None, _) => -1e-6 * tan.stiffness_scale(),
        };
        shifts.push(s);
        tan.write_saddle(&mut k, [-s, 0.0, 1.0]);
        // a held state: its row of K (−∂ż/∂q) only feeds its own entry,
        // which is zeroed after every solve; a unit diagonal keeps the
        // matrix regular (its column of K is 0: nothing reads w)
        for w in nb..n {
            k.add_diagonal(w, 1.0 + s);
        }
        if solver.factorize(&k).is_ok() && probe(&mut *solver, &k, mass, n, m) {
            sigma = s;
            break;
        }
    }
    if sigma.is_nan() {
        return Err(FormulationError::Invalid(format!(
            "eigenmodes: the shifted matrix [K − σM, Φ_qᵀ; Φ_q, 0] is singular at σ = {shifts:?} \
             (redundant constraints?)"
        )));
    }
    let max_basis = if opts.max_basis == 0 {
        (4 * count + 40).max(80)
    } else {
        opts.max_basis
    }
    .min(dof)
    .max(count);
    // Lanczos, partial reorthogonalisation in the M inner product
    let mut basis = Basis::new(n, max_basis.min(LANCZOS_START_CAPACITY));
    let (mut alpha, mut beta) = (Vec::new(), Vec::new());
    let mut x = vec![0.0; n + m];
    let mut coeffs: Vec<f64> = Vec::new();
    let mdot = |a: &[f64], b: &[f64]| -> f64 {
        a.iter().zip(b).zip(mass).map(|((x, y), w)| x * y * w).sum()
    };
    // start: the operator applied to a deterministic, non-special vector
    let mut w: Vec<f64> = (0..n)
        .map(|i| match i < nb {
            true => 1.0 + 0.5 * ((i as f64) * 0.618_033_988_75).fract(),
            false => 0.0,
        })
        .collect();
    for ((b, &wi), &mi) in x.iter_mut().zip(&w).zip(mass) {
        *b = mi * wi;
    }
    apply(&mut *solver, &k, &mut w, &mut x, n)?;
    w[nb..].fill(0.0);
    let nv = mdot(&w, &w).sqrt();
    if nv == 0.0 || !nv.is_finite() {
        return Err(FormulationError::Invalid(
            "eigenmodes: the start vector vanished in the constrained space".into(),
        ));
    }
    basis.push_scaled(&w, nv, mass, &mut x[..n]);
    let (ritz, converged) = loop {
        apply(&mut *solver, &k, &mut w, &mut x, n)?;
        w[nb..].fill(0.0);
        // the recurrence and a Gram–Schmidt pass, partial or full
        let beta_prev = beta.last().copied().unwrap_or(0.0);
        let (a, norm2) = orthogonalise(&basis, mass, &mut w, beta_prev, &mut coeffs);
        let bnext = norm2.sqrt();
        alpha.push(a);
        let size = basis.len();
        let check = size >= count && (size % 5 == 0 || size == max_basis || bnext == 0.0);
        let anorm = alpha.iter().fold(0.0f64, |s, a| s.max(a.abs()));
        let breakdown = bnext.is_nan() || bnext <= 1e-13 * anorm;
        if check || breakdown || size >= max_basis {
            let ritz = tridiagonal_ritz(&alpha, &beta, bnext, count)?;
            let converged = ritz.iter().all(|r| r.2 <= opts.tol);
            if converged || breakdown || size >= max_basis {
                break (ritz, converged);
            }
        }
        beta.push(bnext);
        basis.push_scaled(&w, bnext, mass, &mut x[..n]);
    };
    let steps = basis.len();
    // shapes X s (block by block, so that the basis's block stays in the
    // cache for every shape), M-normalised, by increasing ω²
    // (each block summed from 0 in a buffer and appended: no zeroed
    // shapes to add into)
    let mut shapes: Vec<Vec<f64>> = ritz.iter().map(|_| Vec::with_capacity(n)).collect();
    for (_, vs) in basis.blocks() {
        let bs = vs.len() / steps;
        for (shape, (_, s, _)) in shapes.iter_mut().zip(&ritz) {
            let mut acc = [0.0f64; REORTH_BLOCK];
            let acc = &mut acc[..bs];
            for (b, &c) in vs.chunks_exact(bs).zip(s) {
                for (xi, bi) in acc.iter_mut().zip(b) {
                    *xi += c * bi;
                }
            }
            shape.extend_from_slice(acc);
        }
    }
    let mut modes: Vec<(f64, Vec<f64>, f64)> = ritz
        .into_iter()
        .zip(shapes)
        .map(|((theta, _, res), mut shape)| {
            let nrm = mdot(&shape, &shape).sqrt();
            let big = shape
                .iter()
                .fold(0.0f64, |a, &v| if v.abs() > a.abs() { v } else { a });
            let sgn = if big < 0.0 { -1.0 } else { 1.0 };
            shape.iter_mut().for_each(|e| *e *= sgn / nrm);
            (sigma + 1.0 / theta, shape, res)
        })
        .collect();
    modes.sort_by(|a, b| a.0.total_cmp(&b.0));
    // the basis's memory, no longer needed, holds the damped projection's
    let damped = damped_modes(tan, &modes, basis.into_storage())?;
    Ok(Modes {
        modes: modes
            .into_iter()
            .zip(damped)
            .map(|((w2, shape, residual), (fd, zeta))| Mode {
                omega_squared: w2,
                frequency_hz: w2.max(0.0).sqrt() / (2.0 * std::f64::consts::PI),
                damped_frequency_hz: fd,
                damping_ratio: zeta,
                shape,
                residual,
            })
            .collect(),
        shift: sigma,
        lanczos_steps: steps,
        converged,
        factorizations: super::Factorizations::of(&*solver),
    })
}

/// Entries per block of [`orthogonalise`] and [`Basis`]: the blocks of
/// `w`, `M` and of every basis vector (one per Lanczos step) stay
/// in the L1 / L2 cache while a block is worked on.
const REORTH_BLOCK: usize = 64;

/// Largest cosine `|bᵀ M w| / ‖w‖_M` between `w` and a basis vector
/// older than `v_{j−1}` that [`orthogonalise`] leaves in place:
/// semi-orthogonality, `√ε` (Simon 1984: with every such cosine at most
/// `√ε` the tridiagonal matrix is the projection of the operator onto an
/// orthonormal basis to `O(ε ‖Op‖)`, so its Ritz values are accurate to
/// rounding).
const SEMI_ORTHOGONAL: f64 = 1.490_116_119_384_765_6e-8;

/// The orthogonalisation of one Lanczos step in the M inner product,
/// `w = Op v_j` against the (M-orthonormal) `basis` `v_0 … v_j`: the
/// three-term recurrence `w ← w − α v_j − β v_{j−1}` (`α = v_jᵀ M w`,
/// `β` = `beta_prev`, the previous step's norm) as the first pass, then
/// the coefficients `c_b = bᵀ M w` against the whole basis. When every
/// `c_b` of the vectors older than `v_{j−1}` is at most
/// [`SEMI_ORTHOGONAL`] `‖w‖_M` (partial reorthogonalisation with the
/// measured inner products in place of Simon's estimates), only `c_j v_j`
/// and `c_{j−1} v_{j−1}` are removed (local reorthogonalisation); else a
/// classical Gram–Schmidt pass against the whole basis,
/// `w ← w − Σ_b c_b b` — the recurrence removes the large components,
/// the full pass what the loss of orthogonality left ("twice is enough":
/// Giraud, Langou & Rozložník 2005; Paige's full reorthogonalisation of
/// Lanczos). When the full pass still shrinks `w` below `1/√2` of its
/// norm (Daniel, Gragg, Kaufman & Stewart 1976) it is repeated once.
/// Sweeps over blocks of the coordinates: `α` (`v_j`, `w`); the
/// recurrence fused with the coefficients (the whole basis); the update
/// with `wᵀ M w` (two vectors, or the whole basis). Returns
/// `(α + c_j, wᵀ M w)` (the diagonal of the tridiagonal matrix with the
/// correction, the squared norm).
fn orthogonalise(
    basis: &Basis,
    mass: &[f64],
    w: &mut [f64],
    beta_prev: f64,
    coeffs: &mut Vec<f64>,
) -> (f64, f64) {
    let j = basis.len() - 1;
    // c_b += bᵀ M w over one block (`vs`: the block of every vector)
    let dots = |c: &mut [f64], w: &[f64], lo: usize, vs: &[f64]| {
        let bs = w.len();
        let mut mw = [0.0f64; REORTH_BLOCK];
        let mw = &mut mw[..bs];
        for ((d, wi), mi) in mw.iter_mut().zip(w).zip(&mass[lo..lo + bs]) {
            *d = wi * mi;
        }
        for (c, b) in c.iter_mut().zip(vs.chunks_exact(bs)) {
            *c += b.iter().zip(mw.iter()).map(|(x, y)| x * y).sum::<f64>();
        }
    };
    // w ← w − Σ c_b v_{first + b} over one block
    let update = |c: &[f64], w: &mut [f64], vs: &[f64], first: usize| {
        let bs = w.len();
        for (&c, b) in c.iter().zip(vs.chunks_exact(bs).skip(first)) {
            for (wi, bi) in w.iter_mut().zip(b) {
                *wi -= c * bi;
            }
        }
    };
    let mnorm2 = |w: &[f64], lo: usize| {
        w.iter()
            .zip(&mass[lo..lo + w.len()])
            .map(|(x, m)| x * x * m)
            .sum::<f64>()
    };
    let mut alpha = 0.0;
    for (lo, vs) in basis.blocks() {
        let bs = vs.len() / basis.len();
        let vj = &vs[j * bs..(j + 1) * bs];
        for ((x, v), m) in w[lo..lo + bs].iter().zip(vj).zip(&mass[lo..lo + bs]) {
            alpha += x * v * m;
        }
    }
    coeffs.clear();
    coeffs.resize(basis.len(), 0.0);
    let mut before = 0.0;
    for (lo, vs) in basis.blocks() {
        let bs = vs.len() / basis.len();
        let wb = &mut w[lo..lo + bs];
        for (wi, vi) in wb.iter_mut().zip(&vs[j * bs..]) {
            *wi -= alpha * vi;
        }
        if j > 0 {
            for (wi, pi) in wb.iter_mut().zip(&vs[(j - 1) * bs..]) {
                *wi -= beta_prev * pi;
            }
        }
        before += mnorm2(wb, lo);
        dots(coeffs, wb, lo, vs);
    }
    let older = j.saturating_sub(1);
    let lim = SEMI_ORTHOGONAL * before.sqrt();
    if coeffs[..older].iter().all(|c| c.abs() <= lim) {
        let mut norm2 = 0.0;
        for (lo, vs) in basis.blocks() {
            let wb = &mut w[lo..lo + vs.len() / basis.len()];
            update(&coeffs[older..], wb, vs, older);
            norm2 += mnorm2(wb, lo);
        }
        return (alpha + coeffs[j], norm2);
    }
    let (mut correction, mut repeated) = (0.0, false);
    loop {
        correction += coeffs[j];
        let mut norm2 = 0.0;
        for (lo, vs) in basis.blocks() {
            let wb = &mut w[lo..lo + vs.len() / basis.len()];
            update(coeffs, wb, vs, 0);
            norm2 += mnorm2(wb, lo);
        }
        if repeated || norm2 >= 0.5 * before {
            return (alpha + correction, norm2);
        }
        // the full pass removed more than half of ‖w‖²: once more
        (before, repeated) = (norm2, true);
        coeffs.iter_mut().for_each(|c| *c = 0.0);
        for (lo, vs) in basis.blocks() {
            dots(coeffs, &w[lo..lo + vs.len() / basis.len()], lo, vs);
        }
    }
}

/// Basis vectors allocated at the start of [`eigenmodes`]' Lanczos
/// iteration ([`Basis`] doubles its capacity when they are used up).
const LANCZOS_START_CAPACITY: usize = 32;

/// The Lanczos basis `v_0 … v_{len−1}` (length `n` each), block-major:
/// for each block of [`REORTH_BLOCK`] coordinates `lo..hi`, the entries
/// `lo..hi` of every vector one after the other, so that a sweep of
/// [`orthogonalise`] over the whole basis reads one contiguous stretch
/// of memory per block. Block `b` (`lo = b·REORTH_BLOCK`, `bs = hi − lo`)
/// starts at `lo · cap`; vector `j`'s part of it at `lo · cap + j · bs`.
struct Basis {
    n: usize,
    cap: usize,
    len: usize,
    data: Vec<f64>,
}

impl Basis {
    /// An empty basis of vectors of length `n`, room for `cap` of them.
    fn new(n: usize, cap: usize) -> Self {
        let cap = cap.max(1);
        Self {
            n,
            cap,
            len: 0,
            data: vec![0.0; n * cap],
        }
    }

    /// Number of vectors.
    fn len(&self) -> usize {
        self.len
    }

    /// Per block of coordinates: its first coordinate `lo` and the block
    /// of every vector, `len · bs` entries (vector `j` at `j · bs`).
    fn blocks(&self) -> impl Iterator<Item = (usize, &[f64])> + '_ {
        (0..self.n).step_by(REORTH_BLOCK).map(move |lo| {
            let bs = REORTH_BLOCK.min(self.n - lo);
            (lo, &self.data[lo * self.cap..lo * self.cap + self.len * bs])
        })
    }

    /// Append `v = w / d`, doubling the capacity when it is used up, and
    /// write `M v` into `mv` (`mass` the diagonal of `M`): the operator's
    /// next right-hand side.
    fn push_scaled(&mut self, w: &[f64], d: f64, mass: &[f64], mv: &mut [f64]) {
        if self.len == self.cap {
            let mut grown = Self::new(self.n, 2 * self.cap);
            for lo in (0..self.n).step_by(REORTH_BLOCK) {
                let used = self.len * REORTH_BLOCK.min(self.n - lo);
                grown.data[lo * grown.cap..lo * grown.cap + used]
                    .copy_from_slice(&self.data[lo * self.cap..lo * self.cap + used]);
            }
            grown.len = self.len;
            *self = grown;
        }
        let j = self.len;
        for lo in (0..self.n).step_by(REORTH_BLOCK) {
            let bs = REORTH_BLOCK.min(self.n - lo);
            let at = lo * self.cap + j * bs;
            let dst = self.data[at..at + bs].iter_mut().zip(&mut mv[lo..lo + bs]);
            for ((v, o), (&wi, &mi)) in dst.zip(w[lo..lo + bs].iter().zip(&mass[lo..lo + bs])) {
                *v = wi / d;
                *o = mi * *v;
            }
        }
        self.len += 1;
    }

    /// The storage, for reuse once the basis is no longer needed.
    fn into_storage(self) -> Vec<f64> {
        self.data
    }
}

/// `y = Op x`: `[K − σM, Φ_qᵀ; Φ_q, 0] [y; μ] = [M x; 0]`, `buf[..n]`
/// holding `M x` on entry.
fn apply(
    solver: &mut dyn SaddlePointSolver,
    k: &crate::linalg::SaddleMatrix,
    y: &mut [f64],
    buf: &mut [f64],
    n: usize,
) -> Result<(), FormulationError> {
    buf[n..].fill(0.0);
    solver
        .solve_in_place(k, buf)
        .map_err(|source| FormulationError::Linear {
            t: f64::NAN,
            source,
        })?;
    y.copy_from_slice(&buf[..n]);
    Ok(())
}

/// One trial solve: finite and not absurdly large (a numerically
/// singular factorisation).
fn probe(
    solver: &mut dyn SaddlePointSolver,
    k: &crate::linalg::SaddleMatrix,
    mass: &[f64],
    n: usize,
    m: usize,
) -> bool {
    let mut b = vec![0.0; n + m];
    for (i, bi) in b[..n].iter_mut().enumerate() {
        *bi = mass[i] * (1.0 + 0.25 * ((i as f64) * 0.37).sin());
    }
    if solver.solve_in_place(k, &mut b).is_err() {
        return false;
    }
    b.iter().all(|v| v.is_finite() && v.abs() < 1e200)
}

/// The `count` Ritz pairs of largest |θ| of the Lanczos tridiagonal
/// `T = tridiag(β, α, β)`: `(θ, eigenvector of T, relative residual
/// estimate |β_next s_last| / |θ|)`.
fn tridiagonal_ritz(
    alpha: &[f64],
    beta: &[f64],
    bnext: f64,
    count: usize,
) -> Result<Vec<(f64, Vec<f64>, f64)>, FormulationError> {
    let j = alpha.len();
    let mut t = faer::Mat::<f64>::zeros(j, j);
    for i in 0..j {
        t[(i, i)] = alpha[i];
        if i + 1 < j {
            t[(i + 1, i)] = beta[i];
            t[(i, i + 1)] = beta[i];
        }
    }
    let e = t
        .self_adjoint_eigen(faer::Side::Lower)
        .map_err(|e| FormulationError::Invalid(format!("eigenmodes: tridiagonal eigen: {e:?}")))?;
    let (s, u) = (e.S().column_vector(), e.U());
    let mut idx: Vec<usize> = (0..j).collect();
    idx.sort_by(|&a, &b| s[b].abs().total_cmp(&s[a].abs()));
    Ok(idx
        .into_iter()
        .take(count.min(j))
        .map(|c| {
            let theta = s[c];
            let vec: Vec<f64> = (0..j).map(|r| u[(r, c)]).collect();
            let res = (bnext * vec[j - 1]).abs() / theta.abs().max(f64::MIN_POSITIVE);
            (theta, vec, res)
        })
        .collect())
}

/// Damped frequency \[Hz\] and damping ratio per undamped mode, from the
/// projected first-order system (module docs).
fn damped_modes(
    tan: &Tangent,
    modes: &[(f64, Vec<f64>, f64)],
    mut scratch: Vec<f64>,
) -> Result<Vec<(f64, f64)>, FormulationError> {
    let k = modes.len();
    let n = tan.n();
    // the shapes by coordinate (n × k, row-major), so that one pass over
    // the entries of C or K applies them to every shape, and `A X`, in
    // `scratch`'s memory
    // (X is written whole and `projected` zeroes A X: no zeroing here)
    if scratch.len() < 2 * n * k {
        scratch.resize(2 * n * k, 0.0);
    }
    let (x, ax) = scratch[..2 * n * k].split_at_mut(n * k);
    for (j, mode) in modes.iter().enumerate() {
        for (r, &v) in mode.1.iter().enumerate() {
            x[r * k + j] = v;
        }
    }
    let cr = projected(x, k, tan.damping_entries(), ax);
    let kr = projected(x, k, tan.stiffness_entries(), ax);
    let mut a = faer::Mat::<f64>::zeros(2 * k, 2 * k);
    for i in 0..k {
        a[(i, k + i)] = 1.0;
        for j in 0..k {
            a[(k + i, j)] = -kr[(i, j)];
            a[(k + i, k + j)] = -cr[(i, j)];
        }
    }
    let e = a
        .eigen()
        .map_err(|e| FormulationError::Invalid(format!("eigenmodes: damped eigen: {e:?}")))?;
    let (s, u) = (e.S().column_vector(), e.U());
    // per mode: a complex eigenvalue with Im > 0, or the real ones
    let mut complex: Vec<Option<(f64, f64)>> = vec![None; k];
    let mut reals: Vec<Vec<f64>> = vec![Vec::new(); k];
    for col in 0..2 * k {
        let (re, im) = (s[col].re, s[col].im);
        let owner = (0..k)
            .max_by(|&a, &b| {
                let ma =
                    u[(a, col)].norm() + u[(k + a, col)].norm() / (1.0 + kr[(a, a)].abs().sqrt());
                let mb =
                    u[(b, col)].norm() + u[(k + b, col)].norm() / (1.0 + kr[(b, b)].abs().sqrt());
                ma.total_cmp(&mb)
            })
            .unwrap_or(0);
        let tiny = 1e-12 * (re.abs() + im.abs());
        if im > tiny {
            complex[owner] = Some((re, im));
        } else if im.abs() <= tiny {
            reals[owner].push(re);
        }
    }
    let two_pi = 2.0 * std::f64::consts::PI;
    Ok((0..k)
        .map(|i| {
            if let Some((re, im)) = complex[i] {
                let mag = re.hypot(im);
                (im / two_pi, -re / mag)
            } else if reals[i].len() >= 2 {
                let (s1, s2) = (reals[i][0], reals[i][1]);
                let wn = (s1 * s2).abs().sqrt();
                (0.0, -(s1 + s2) / (2.0 * wn.max(f64::MIN_POSITIVE)))
            } else {
                (0.0, f64::NAN)
            }
        })
        .collect())
}

/// `Xᵀ A X` (`k × k`) of the `n × k` row-major `x` and the matrix given
/// by its `entries` (duplicates summed): `A X` into `ax` (same shape as
/// `x`) by one pass over the entries, then the products row by row (each
/// row of `x` and `A X` read once).
fn projected(
    x: &[f64],
    k: usize,
    entries: impl Iterator<Item = (usize, usize, f64)>,
    ax: &mut [f64],
) -> faer::Mat<f64> {
    ax.fill(0.0);
    for (i, j, v) in entries {
        for (y, &xv) in ax[i * k..i * k + k].iter_mut().zip(&x[j * k..j * k + k]) {
            *y += v * xv;
        }
    }
    let mut r = vec![0.0; k * k];
    for (xr, ar) in x.chunks_exact(k).zip(ax.chunks_exact(k)) {
        for (ri, &xi) in r.chunks_exact_mut(k).zip(xr) {
            for (rij, &aj) in ri.iter_mut().zip(ar) {
                *rij += xi * aj;
            }
        }
    }
    faer::Mat::from_fn(k, k, |i, j| r[i * k + j])
}

/// One eigenvalue `s` of a first-order model `ẋ = A x` ([`first_order_modes`]).
#[derive(Debug, Clone, Serialize)]
pub struct FirstOrderMode {
    /// Re s \[1/s\].
    pub re: f64,
    /// Im s ≥ 0 \[rad/s\] (a complex pair is listed once).
    pub im: f64,
    /// Whether s is complex (an oscillation); a real s is a
    /// non-oscillatory mode (decay or growth at rate Re s).
    pub oscillatory: bool,
    /// Natural frequency `|s| / 2π` \[Hz\].
    pub frequency_hz: f64,
    /// Damped frequency `Im s / 2π` \[Hz\] (0 for a real s).
    pub damped_frequency_hz: f64,
    /// Damping ratio `−Re s / |s|` of a complex s; `None` for a real one
    /// (non-oscillatory; see `time_constant_s`).
    pub damping_ratio: Option<f64>,
    /// `−1 / Re s` \[s\] of a real s (negative: growth); `None` for a
    /// complex one or s = 0.
    pub time_constant_s: Option<f64>,
    /// The eigenvector `(re, im)` per state, scaled so that its largest
    /// entry is 1.
    pub shape: Vec<(f64, f64)>,
}

/// The eigenvalues and eigenvectors of a dense `A` (faer's real
/// Schur-based eigen), by increasing `|s|`, each complex pair once
/// (`Im s > 0`; `|Im s| ≤ 1e-12 |s|` counts as real).
pub fn first_order_modes(a: &faer::Mat<f64>) -> Result<Vec<FirstOrderMode>, FormulationError> {
    let n = a.nrows();
    if n == 0 {
        return Ok(Vec::new());
    }
    let e = a
        .eigen()
        .map_err(|e| FormulationError::Invalid(format!("first-order modes: eigen: {e:?}")))?;
    let (s, u) = (e.S().column_vector(), e.U());
    let two_pi = 2.0 * std::f64::consts::PI;
    let mut out = Vec::new();
    for c in 0..n {
        let (re, im) = (s[c].re, s[c].im);
        let mag = re.hypot(im);
        let real = im.abs() <= 1e-12 * mag;
        if !real && im < 0.0 {
            continue;
        }
        let big = (0..n)
            .map(|r| u[(r, c)])
            .max_by(|x, y| x.norm().total_cmp(&y.norm()))
            .unwrap_or(u[(0, c)]);
        let shape = (0..n)
            .map(|r| {
                let v = u[(r, c)] / big;
                (v.re, if real { 0.0 } else { v.im })
            })
            .collect();
        out.push(FirstOrderMode {
            re,
            im: if real { 0.0 } else { im },
            oscillatory: !real,
            frequency_hz: mag / two_pi,
            damped_frequency_hz: if real { 0.0 } else { im / two_pi },
            damping_ratio: (!real).then(|| -re / mag),
            time_constant_s: (real && re != 0.0).then(|| -1.0 / re),
            shape,
        });
    }
    out.sort_by(|x, y| x.re.hypot(x.im).total_cmp(&y.re.hypot(y.im)));
    Ok(out)
}
