//! The fastest modes of the constrained, linearised system: the
//! stability limit of the explicit integrators.
//!
//! Linearising `M q̈ + Φ_qᵀλ = g(q, q̇)` about a state, with `K = −∂g/∂q`
//! and `C = −∂g/∂q̇` (their symmetric parts) and the motion restricted to
//! the tangent space `Φ_q δq = 0`, the modes satisfy `K x = ω² M x` and the
//! damping rates `C x = σ M x` on that space. Their largest values come
//! from power iteration on `x ← P M⁻¹ K x` (and `C`), where the
//! M-orthogonal projection `P` onto `Φ_q x = 0` is the saddle-point solve
//! `[M Φ_qᵀ; Φ_q 0] [x; μ] = [K v; 0]` — factorised once
//! ([`crate::linalg::SolverKind::Chain`]). The Rayleigh
//! quotients never exceed the true maxima, so a limit derived from them is
//! never stricter than the truth.
//!
//! A negative stiffness (a compressed spring's geometric stiffness, a
//! load that grows with the displacement) makes a statically unstable
//! mode growing like `exp(γ t)`, `γ² = −λ_min(K, M)`: no method, implicit
//! or explicit, follows it accurately with steps much above `1/γ`. The
//! second power iteration, shifted by the first one's Rayleigh quotient
//! `s`, on `A − s M`, finds the other end of the spectrum. Each rate names
//! the force element with the largest share `xᵀ A_e x` of the Rayleigh
//! quotient of its mode.
//!
//! Covered: the stiffness and damping of the force elements (springs,
//! dampers, contacts in contact). Not covered: the geometric stiffness of
//! the constraint forces `(Φ_qᵀλ)_q` (slow pendulum-like modes).

use super::{linear_at, FormulationError};
use crate::linalg::{solver_for, SaddleMatrix, SolverKind, SolverOptions};
use crate::model::{FdWorkspace, System};
use crate::parallel::{split_pass, split_passes, PARALLEL_MIN_COORDS};

/// Largest natural frequency and damping rate of the constrained,
/// linearised system at a state (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FastestModes {
    /// Largest ω \[rad/s\] (0 without stiffness).
    pub omega: f64,
    /// Largest damping rate σ \[1/s\] (0 without damping).
    pub sigma: f64,
    /// Largest growth rate γ = √(−λ_min) \[1/s\] of a statically unstable
    /// mode (negative stiffness on the constrained motion); 0 without one.
    pub growth: f64,
    /// Index in [`System::forces`] of the element with the largest share of
    /// ω, σ and γ (in that order); `None` where the rate is 0.
    pub sources: [Option<usize>; 3],
    /// Largest translational acceleration \[m/s²\] the loads alone give a
    /// body at the state, `|(ẍ, ÿ)|` of `[M Φ_qᵀ; Φ_q 0] [q̈; λ] = [g; 0]`
    /// (velocity terms left out).
    pub accel: f64,
    /// That body's index, and the force element with the largest
    /// unconstrained acceleration `‖M^{-1/2} g_e‖` (`None` without loads).
    pub accel_source: (usize, Option<usize>),
}

impl FastestModes {
    /// The largest step an explicit method with a stability region
    /// reaching `reach` along the imaginary and negative real axes (rk4:
    /// ≈ 2.8) can take: `reach / max(ω, σ)`; infinite for a system with
    /// neither.
    pub fn step_limit(&self, reach: f64) -> f64 {
        let rate = self.omega.max(self.sigma);
        if rate > 0.0 {
            reach / rate
        } else {
            f64::INFINITY
        }
    }
}

/// How far the stability regions of the explicit methods reach along the
/// imaginary axis (rk4: 2√2; Dormand–Prince 5(4): ≈ 3.3 — Hairer, Nørsett &
/// Wanner I, §IV.2; Bogacki–Shampine 3(2): √3) and the negative real
/// axis (rk4: 2.785; DP: 3.3; BS: 2.5): the smaller of the two. For
/// ode113's Adams–Bashforth–Moulton PECE pairs the largest reach over its
/// orders, 2 (order 1, Heun's method, along the negative real axis; the
/// higher orders reach less — Shampine & Gordon 1975): its limit is never
/// stricter than the truth, so a "stiff for ode113" warning is certain.
pub fn explicit_reach(method: crate::integrate::Method) -> Option<f64> {
    use crate::integrate::Method;
    match method {
        Method::Rk4 => Some(2.785),
        Method::Ode45 => Some(3.3),
        Method::Ode23 => Some(3f64.sqrt()),
        Method::Ode113 => Some(2.0),
        _ => None,
    }
}

/// [`FastestModes`] at `(t, q, q̇)` by `iterations` power iterations each.
pub fn fastest_modes(
    sys: &System,
    t: f64,
    q: &[f64],
    qd: &[f64],
    iterations: usize,
) -> Result<FastestModes, FormulationError> {
    let n = sys.n_coords();
    let m = sys.n_constraints();
    let pattern = sys.force_jacobian_pattern();

    // [M Φ_qᵀ; Φ_q 0], factorised once.
    let mut k = SaddleMatrix::new(n, m, &[], sys.jacobian_pattern());
    let mut jac = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, t, &mut jac);
    k.set_a_diagonal(sys.mass_diagonal());
    k.set_jacobian(&jac);
    // the envelope LDLᵀ for chain patterns, faer's sparse LDLᵀ otherwise
    // (`ChainLdlt`): the two agree to rounding, and the envelope's solves
    // stay linear in the chain's length where faer's fall out of the cache.
    // Without the residual check (a serial product K x per solve): power
    // iteration tolerates an inexact projection as Newton does, each pass
    // starting from the last one's result; a non-finite solve still fails
    let options = SolverOptions {
        residual_check: false,
    };
    let mut solver = solver_for(SolverKind::Chain, n + m, options);
    let lin = linear_at(t);
    solver.analyze(&k).map_err(lin)?;
    solver.factorize(&k).map_err(lin)?;

    // the loads' accelerations from rest
    let mass = sys.mass_diagonal();
    let mut rhs = vec![0.0; n + m];
    sys.forces_into(t, q, qd, &mut rhs[..n]);
    solver.solve_in_place(&k, &mut rhs).map_err(lin)?;
    let (accel_body, accel) = rhs[..sys.n_body_coords()]
        .chunks(3)
        .map(|b| b[0].hypot(b[1]))
        .enumerate()
        .fold(
            (0, 0.0),
            |a, b| if b.1 > a.1 || b.1.is_nan() { b } else { a },
        );
    // each element adds to its footprint only (`ForceElement::coordinates`),
    // so reading and clearing that footprint keeps the loop linear in the
    // number of elements (a clear of all of `g` per element is quadratic)
    let mut g = vec![0.0; n];
    let mut loudest = (None, 0.0);
    for (e, f) in sys.forces().iter().enumerate() {
        let footprint = f.coordinates();
        f.add_forces(t, q, qd, &mut g);
        let mut a = 0.0;
        for &i in &footprint {
            a += g[i] * g[i] / mass[i];
            g[i] = 0.0;
        }
        if a > loudest.1 || (a.is_nan() && loudest.0.is_none()) {
            loudest = (Some(e), a);
        }
    }
    let accel_source = (accel_body, loudest.0);

    if pattern.is_empty() {
        return Ok(FastestModes {
            omega: 0.0,
            sigma: 0.0,
            growth: 0.0,
            sources: [None; 3],
            accel,
            accel_source,
        });
    }
    let mut dq = vec![0.0; pattern.len()];
    let mut dqd = vec![0.0; pattern.len()];
    let mut ws = FdWorkspace::default();
    sys.add_force_jacobians(t, q, qd, &mut dq, &mut dqd, &mut ws);

    // each element's block of the pattern: element after element, k × k
    let mut blocks = Vec::with_capacity(sys.forces().len());
    let mut at = 0;
    for e in sys.forces() {
        let k = e.jacobian_coordinates().len();
        blocks.push(at..at + k * k);
        at += k * k;
    }
    let blocks = if at == pattern.len() {
        blocks
    } else {
        Vec::new()
    };
    // the element with the largest share `sign · xᵀ A_e x`,
    // A_e = −½ (J_e + J_eᵀ)
    let source = |x: &[f64], d: &[f64], sign: f64| -> Option<usize> {
        let share = |r: &std::ops::Range<usize>| -> f64 {
            let s: f64 = pattern[r.clone()]
                .iter()
                .zip(&d[r.clone()])
                .map(|(&(i, j), v)| -v * x[i] * x[j])
                .sum();
            sign * s
        };
        let (best, v) = blocks
            .iter()
            .enumerate()
            .map(|(e, r)| (e, share(r)))
            .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        (v > 0.0).then_some(best)
    };
    let par = n >= PARALLEL_MIN_COORDS;
    // the entries by the rows they write: both in the low half of the
    // rows, both in the high half, or one in each (all in the first list
    // without halves)
    let parts = EntryHalves::new(pattern, if par { n / 2 } else { n });
    // Rayleigh quotient and vector of the power iteration on
    // x ← P M⁻¹ (A − s M) x (module docs), reported as that of A; the
    // element-wise passes in two halves for large n (`parallel::split_pass`,
    // cut at n/2 whatever the thread count; the sums are each half's
    // ordered sum, low + high)
    let mut iterate = |d: &[f64], s: f64| -> Result<(f64, Vec<f64>), FormulationError> {
        // deterministic start with all components, projected
        let x0 = |i: usize| 1.0 + 0.5 * ((i as f64) * 0.7).sin();
        let mut rhs: Vec<f64> = (0..n + m)
            .map(|i| if i < n { mass[i] * x0(i) } else { 0.0 })
            .collect();
        let mut x = vec![0.0; n];
        let mut rq = 0.0;
        for _ in 0..=iterations {
            // x ← P M⁻¹ (A x) (the first pass only projects the start)
            solver.solve_in_place(&k, &mut rhs).map_err(lin)?;
            // ‖x‖_M² of the projection
            let xm2 = split_pass(
                par,
                n,
                (&mut x[..], &rhs[..n], mass),
                |_, (x, r, mass): (&mut [f64], &[f64], &[f64])| {
                    x.copy_from_slice(r);
                    x.iter().zip(mass).map(|(a, mi)| a * a * mi).sum::<f64>()
                },
                |lo, hi| lo + hi,
            );
            let xm = xm2.sqrt();
            if xm <= 0.0 || !xm.is_finite() {
                break;
            }
            // M-normalise; y = −s M x into the next right-hand side, its
            // multiplier rows cleared
            {
                let (y, rl) = rhs.split_at_mut(n);
                split_passes(
                    par,
                    (
                        n,
                        (&mut x[..], y, mass),
                        |_, (x, y, mass): (&mut [f64], &mut [f64], &[f64])| {
                            for ((xi, yi), mi) in x.iter_mut().zip(y.iter_mut()).zip(mass) {
                                *xi /= xm;
                                *yi = -s * mi * *xi;
                            }
                        },
                    ),
                    (m, rl, |_, rl: &mut [f64]| rl.fill(0.0)),
                    |(), ()| (),
                );
            }
            // y −= ½ (A + Aᵀ) x: each half its own rows' entries, then
            // those across the cut; Rayleigh quotient xᵀ y (xᵀ M x = 1)
            let x = &x[..];
            let [lo, hi, across] = &parts.0;
            let add = |base: usize, y: &mut [f64], entries: &[u32]| {
                for &e in entries {
                    let ((r, c), v) = (pattern[e as usize], d[e as usize]);
                    y[r - base] -= 0.5 * v * x[c];
                    y[c - base] -= 0.5 * v * x[r];
                }
            };
            let y = &mut rhs[..n];
            let cut = if par { n / 2 } else { n };
            let (y_lo, y_hi) = y.split_at_mut(cut);
            crate::parallel::join_if(par, || add(0, y_lo, lo), || add(cut, y_hi, hi));
            add(0, y, across);
            rq = split_pass(
                par,
                n,
                (x, &*y),
                |_, (x, y): (&[f64], &[f64])| x.iter().zip(y).map(|(a, b)| a * b).sum::<f64>(),
                |lo, hi| lo + hi,
            );
        }
        Ok((rq + s, x))
    };
    // stiffness: the dominant end of the spectrum, then the other one
    let (l1, x1) = iterate(&dq, 0.0)?;
    let (l2, x2) = if l1.is_finite() && l1 != 0.0 {
        iterate(&dq, l1)?
    } else {
        (l1, x1.clone())
    };
    let ((hi, xh), (lo, xl)) = if l1 >= l2 {
        ((l1, x1), (l2, x2))
    } else {
        ((l2, x2), (l1, x1))
    };
    let (sigma, xs) = iterate(&dqd, 0.0)?;
    let omega = hi.max(0.0).sqrt();
    let sigma = sigma.max(0.0);
    let growth = (-lo).max(0.0).sqrt();
    let sources = [
        (omega > 0.0).then(|| source(&xh, &dq, 1.0)).flatten(),
        (sigma > 0.0).then(|| source(&xs, &dqd, 1.0)).flatten(),
        (growth > 0.0).then(|| source(&xl, &dq, -1.0)).flatten(),
    ];
    Ok(FastestModes {
        omega,
        sigma,
        growth,
        sources,
        accel,
        accel_source,
    })
}

/// The entries of a pattern (`pattern[e] = (r, c)`, rows and columns of
/// one `n × n` matrix) by the rows `r` and `c` they touch, each list in
/// the entries' order: both below `cut`, both at or above it, one on each
/// side.
struct EntryHalves([Vec<u32>; 3]);

impl EntryHalves {
    fn new(pattern: &[(usize, usize)], cut: usize) -> Self {
        let mut parts: [Vec<u32>; 3] = Default::default();
        for (e, &(r, c)) in pattern.iter().enumerate() {
            let part = match (r < cut, c < cut) {
                (true, true) => 0,
                (false, false) => 1,
                _ => 2,
            };
            // entries of a pattern held in memory: fewer than 2³²
            parts[part].push(e as u32);
        }
        Self(parts)
    }
}
