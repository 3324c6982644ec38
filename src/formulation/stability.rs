//! The fastest modes of the constrained, linearised system: the
//! stability limit of the explicit integrators.
//!
//! Linearising `M q̈ + Φ_qᵀλ = g(q, q̇)` about a state, with `K = −∂g/∂q`
//! and `C = −∂g/∂q̇` (their symmetric parts) and the motion restricted to
//! the tangent space `Φ_q δq = 0`, the modes satisfy `K x = ω² M x` and the
//! damping rates `C x = σ M x` on that space. Their largest values come
//! from power iteration on `x ← P M⁻¹ K x` (and `C`), where the
//! M-orthogonal projection `P` onto `Φ_q x = 0` is the saddle-point solve
//! `[M Φ_qᵀ; Φ_q 0] [x; μ] = [K v; 0]` — factorised once. The Rayleigh
//! quotients never exceed the true maxima, so a limit derived from them is
//! never stricter than the truth.
//!
//! Covered: the stiffness and damping of the force elements (springs,
//! dampers, contacts in contact). Not covered: the geometric stiffness of
//! the constraint forces `(Φ_qᵀλ)_q` (slow pendulum-like modes).

use super::FormulationError;
use crate::linalg::{solver_for, SaddleMatrix, SolverKind, SolverOptions};
use crate::model::{FdWorkspace, System};

/// Largest natural frequency and damping rate of the constrained,
/// linearised system at a state (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FastestModes {
    /// Largest ω \[rad/s\] (0 without stiffness).
    pub omega: f64,
    /// Largest damping rate σ \[1/s\] (0 without damping).
    pub sigma: f64,
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
    if pattern.is_empty() {
        return Ok(FastestModes {
            omega: 0.0,
            sigma: 0.0,
        });
    }
    let mut dq = vec![0.0; pattern.len()];
    let mut dqd = vec![0.0; pattern.len()];
    let mut ws = FdWorkspace::default();
    sys.add_force_jacobians(t, q, qd, &mut dq, &mut dqd, &mut ws);

    // [M Φ_qᵀ; Φ_q 0], factorised once.
    let mut k = SaddleMatrix::new(n, m, &[], sys.jacobian_pattern());
    let mut jac = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, t, &mut jac);
    k.set_a_diagonal(sys.mass_diagonal());
    k.set_jacobian(&jac);
    let mut solver = solver_for(SolverKind::Sparse, n + m, SolverOptions::default());
    let lin = |source| FormulationError::Linear { t, source };
    solver.analyze(&k).map_err(lin)?;
    solver.factorize(&k).map_err(lin)?;

    let mass = sys.mass_diagonal();
    let mut rates = [0.0; 2];
    for (rate, d) in rates.iter_mut().zip([&dq, &dqd]) {
        // y = ½ (A + Aᵀ) x with A = −∂g/∂(q or q̇)
        let apply = |x: &[f64], y: &mut [f64]| {
            y.fill(0.0);
            for (&(r, c), &v) in pattern.iter().zip(d.iter()) {
                y[r] -= 0.5 * v * x[c];
                y[c] -= 0.5 * v * x[r];
            }
        };
        // deterministic start with all components, projected
        let mut x: Vec<f64> = (0..n)
            .map(|i| 1.0 + 0.5 * ((i as f64) * 0.7).sin())
            .collect();
        let mut rhs = vec![0.0; n + m];
        let mut y = vec![0.0; n];
        let mut rq = 0.0;
        for it in 0..=iterations {
            // x ← P M⁻¹ (A x) (the first pass only projects the start)
            if it == 0 {
                for i in 0..n {
                    rhs[i] = mass[i] * x[i];
                }
            } else {
                apply(&x, &mut y);
                rhs[..n].copy_from_slice(&y);
            }
            rhs[n..].fill(0.0);
            solver.solve_in_place(&k, &mut rhs).map_err(lin)?;
            x.copy_from_slice(&rhs[..n]);
            // M-normalise; Rayleigh quotient xᵀAx / xᵀMx
            let xm: f64 = x
                .iter()
                .zip(mass)
                .map(|(a, mi)| a * a * mi)
                .sum::<f64>()
                .sqrt();
            if xm <= 0.0 || !xm.is_finite() {
                break;
            }
            x.iter_mut().for_each(|v| *v /= xm);
            apply(&x, &mut y);
            rq = x.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>();
        }
        *rate = rq.max(0.0);
    }
    Ok(FastestModes {
        omega: rates[0].sqrt(),
        sigma: rates[1],
    })
}
