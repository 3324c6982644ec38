//! The assembled multibody system: numbering and evaluation of Φ, Φ_q, Φ_t,
//! γ and g.

use super::{Body, ModelError};
use crate::constraints::Constraint;
use crate::forces::{ForceElement, Gravity};

/// Specialised evaluation of Φ, Φ_q, Φ_t and γ for a whole system, e.g.
/// code emitted at build time by `mbsolve-codegen` for a known topology.
///
/// Implementations must produce exactly what the generic per-joint
/// evaluation produces (to rounding): the same rows, and Φ_q values in the
/// order of [`System::jacobian_pattern`].
pub trait ConstraintKernels: Send + Sync + std::fmt::Debug {
    /// Name for summaries, e.g. "generated:rod_chain".
    fn name(&self) -> &str;
    /// Φ(q, t).
    fn phi(&self, q: &[f64], t: f64, out: &mut [f64]);
    /// Φ_q values in pattern order.
    fn jacobian_values(&self, q: &[f64], t: f64, vals: &mut [f64]);
    /// Φ_t(q, t).
    fn phi_t(&self, q: &[f64], t: f64, out: &mut [f64]);
    /// γ(q, q̇, t).
    fn gamma(&self, q: &[f64], qd: &[f64], t: f64, out: &mut [f64]);
    /// Φ, Φ_q values and γ in one pass. Default: the three calls; kernels
    /// override it to share the sines and cosines of every angle.
    fn evaluate(
        &self,
        q: &[f64],
        qd: &[f64],
        t: f64,
        phi: &mut [f64],
        vals: &mut [f64],
        gamma: &mut [f64],
    ) {
        self.phi(q, t, phi);
        self.jacobian_values(q, t, vals);
        self.gamma(q, qd, t, gamma);
    }
}

/// Which evaluation of Φ, Φ_q, Φ_t, γ a [`System`] uses
/// (scenario key `constraints.evaluation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Evaluation {
    /// Kernels when attached, the generic per-joint loop otherwise.
    #[default]
    Auto,
    /// Always the generic per-joint loop over [`Constraint`] objects.
    Generic,
    /// The attached kernels (an error when none are attached).
    Generated,
}

/// A planar multibody system.
///
/// **Numbering.** Body `i` (0-based, in the order added) owns coordinates
/// `3i, 3i+1, 3i+2` = `x_i, y_i, φ_i`. Constraint rows follow the order in
/// which joints were added; joint `k` owns rows
/// `row_offset(k) .. row_offset(k) + n_eq`. The structural non-zeros of Φ_q
/// are [`System::jacobian_pattern`]: joint by joint, each in its own order.
///
/// **Evaluation.** All methods take `&self` and write into caller buffers,
/// so a `System` can be shared between threads and formulations.
#[derive(Debug)]
pub struct System {
    bodies: Vec<Body>,
    constraints: Vec<Box<dyn Constraint>>,
    forces: Vec<Box<dyn ForceElement>>,
    row_offset: Vec<usize>,
    jac_offset: Vec<usize>,
    jac_pattern: Vec<(usize, usize)>,
    mass_diag: Vec<f64>,
    kernels: Option<Box<dyn ConstraintKernels>>,
    use_kernels: bool,
}

/// Collects bodies, joints and force elements, then validates them into a [`System`].
#[derive(Debug, Default)]
pub struct SystemBuilder {
    bodies: Vec<Body>,
    constraints: Vec<Box<dyn Constraint>>,
    forces: Vec<Box<dyn ForceElement>>,
    gravity: Option<[f64; 2]>,
}

impl SystemBuilder {
    /// An empty system.
    pub fn new() -> Self {
        Self::default()
    }
    /// Add a body; returns its index.
    pub fn add_body(&mut self, body: Body) -> usize {
        self.bodies.push(body);
        self.bodies.len() - 1
    }
    /// Add a joint; returns its index (constraint rows follow this order).
    pub fn add_constraint(&mut self, c: impl Constraint + 'static) -> usize {
        self.add_boxed_constraint(Box::new(c))
    }
    /// Add a boxed joint.
    pub fn add_boxed_constraint(&mut self, c: Box<dyn Constraint>) -> usize {
        self.constraints.push(c);
        self.constraints.len() - 1
    }
    /// Add a force element.
    pub fn add_force(&mut self, f: impl ForceElement + 'static) -> usize {
        self.add_boxed_force(Box::new(f))
    }
    /// Add a boxed force element.
    pub fn add_boxed_force(&mut self, f: Box<dyn ForceElement>) -> usize {
        self.forces.push(f);
        self.forces.len() - 1
    }
    /// Uniform gravity on every body (added as a [`Gravity`] element at build time).
    pub fn gravity(&mut self, g: [f64; 2]) -> &mut Self {
        self.gravity = Some(g);
        self
    }
    /// Bodies added so far.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }
    /// Mutable access to the bodies (e.g. to set initial states).
    pub fn bodies_mut(&mut self) -> &mut [Body] {
        &mut self.bodies
    }

    /// Validate everything and fix the numbering.
    pub fn build(mut self) -> Result<System, ModelError> {
        if self.bodies.is_empty() {
            return Err(ModelError::Empty);
        }
        for b in &self.bodies {
            b.validate()?;
        }
        if let Some(g) = self.gravity {
            if !g.iter().all(|v| v.is_finite()) {
                return Err(ModelError::InvalidParameter {
                    element: "gravity".into(),
                    field: "g".into(),
                    value: format!("{g:?}"),
                    why: "must be finite".into(),
                });
            }
            let bodies = self
                .bodies
                .iter()
                .enumerate()
                .map(|(i, b)| (i, b.mass))
                .collect();
            // Appended, so indices returned by `add_force` stay valid.
            self.forces.push(Box::new(Gravity { g, bodies }));
        }
        let nb = self.bodies.len();
        let n = 3 * nb;
        let mut row_offset = vec![0];
        let mut jac_offset = vec![0];
        let mut jac_pattern = Vec::new();
        for c in &self.constraints {
            c.validate(nb)?;
            let r0 = *row_offset.last().expect("non-empty");
            for (r, col) in c.jacobian_pattern() {
                debug_assert!(r < c.n_eq() && col < n);
                jac_pattern.push((r0 + r, col));
            }
            row_offset.push(r0 + c.n_eq());
            jac_offset.push(jac_pattern.len());
        }
        for f in &self.forces {
            f.validate(n)?;
        }
        let mass_diag = self
            .bodies
            .iter()
            .flat_map(|b| [b.mass, b.mass, b.inertia])
            .collect();
        Ok(System {
            bodies: self.bodies,
            constraints: self.constraints,
            forces: self.forces,
            row_offset,
            jac_offset,
            jac_pattern,
            mass_diag,
            kernels: None,
            use_kernels: false,
        })
    }
}

impl System {
    /// Bodies in numbering order.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }
    /// Joints in row order.
    pub fn constraints(&self) -> &[Box<dyn Constraint>] {
        &self.constraints
    }
    /// Force elements in the order added (builder gravity last).
    pub fn forces(&self) -> &[Box<dyn ForceElement>] {
        &self.forces
    }
    /// Number of coordinates n = 3 · bodies.
    pub fn n_coords(&self) -> usize {
        self.mass_diag.len()
    }
    /// Number of constraint equations m.
    pub fn n_constraints(&self) -> usize {
        *self.row_offset.last().expect("non-empty")
    }
    /// First row of joint `k`.
    pub fn row_offset(&self, k: usize) -> usize {
        self.row_offset[k]
    }
    /// Diagonal of the mass matrix `M = diag(m_1, m_1, I_1, …)`.
    pub fn mass_diagonal(&self) -> &[f64] {
        &self.mass_diag
    }
    /// Structural non-zeros `(row, col)` of Φ_q in value order.
    pub fn jacobian_pattern(&self) -> &[(usize, usize)] {
        &self.jac_pattern
    }
    /// Initial positions and velocities as given on the bodies.
    pub fn initial_state(&self) -> (Vec<f64>, Vec<f64>) {
        let q = self.bodies.iter().flat_map(|b| b.q0).collect();
        let v = self.bodies.iter().flat_map(|b| b.v0).collect();
        (q, v)
    }
    /// Name of coordinate `k`, 1-based as in outputs: `x1`, `y1`, `phi1`, …
    pub fn coordinate_name(k: usize) -> String {
        let axis = ["x", "y", "phi"][k % 3];
        format!("{axis}{}", k / 3 + 1)
    }

    fn rows(&self, k: usize) -> std::ops::Range<usize> {
        self.row_offset[k]..self.row_offset[k + 1]
    }

    /// Attach specialised kernels (used by default from now on).
    pub fn attach_kernels(&mut self, k: Box<dyn ConstraintKernels>) {
        self.kernels = Some(k);
        self.use_kernels = true;
    }

    /// Choose the evaluation; `Generated` without attached kernels is an error.
    pub fn set_evaluation(&mut self, e: Evaluation) -> Result<(), ModelError> {
        self.use_kernels = match e {
            Evaluation::Auto => self.kernels.is_some(),
            Evaluation::Generic => false,
            Evaluation::Generated => {
                if self.kernels.is_none() {
                    return Err(ModelError::InvalidParameter {
                        element: "system".into(),
                        field: "constraints.evaluation".into(),
                        value: "generated".into(),
                        why: "no generated kernels match this system's topology".into(),
                    });
                }
                true
            }
        };
        Ok(())
    }

    /// Name of the evaluation in use ("generic" or the kernels' name).
    pub fn evaluation_name(&self) -> &str {
        match (&self.kernels, self.use_kernels) {
            (Some(k), true) => k.name(),
            _ => "generic",
        }
    }

    fn active_kernels(&self) -> Option<&dyn ConstraintKernels> {
        if self.use_kernels {
            self.kernels.as_deref()
        } else {
            None
        }
    }

    /// Φ(q, t), eq. (2).
    pub fn phi(&self, q: &[f64], t: f64, out: &mut [f64]) {
        if let Some(k) = self.active_kernels() {
            return k.phi(q, t, out);
        }
        for (k, c) in self.constraints.iter().enumerate() {
            c.phi(q, t, &mut out[self.rows(k)]);
        }
    }
    /// Values of Φ_q(q, t) in the order of [`System::jacobian_pattern`].
    pub fn jacobian_values(&self, q: &[f64], t: f64, vals: &mut [f64]) {
        if let Some(k) = self.active_kernels() {
            return k.jacobian_values(q, t, vals);
        }
        for (k, c) in self.constraints.iter().enumerate() {
            c.jacobian(q, t, &mut vals[self.jac_offset[k]..self.jac_offset[k + 1]]);
        }
    }
    /// True when specialised kernels evaluate the constraints.
    pub fn uses_kernels(&self) -> bool {
        self.active_kernels().is_some()
    }

    /// Φ_q values and γ, and Φ when `phi` is given, in one pass where
    /// kernels allow it (see [`ConstraintKernels::evaluate`]).
    pub fn constraint_terms(
        &self,
        q: &[f64],
        qd: &[f64],
        t: f64,
        phi: Option<&mut [f64]>,
        vals: &mut [f64],
        gamma: &mut [f64],
    ) {
        match (self.active_kernels(), phi) {
            (Some(k), Some(p)) => k.evaluate(q, qd, t, p, vals, gamma),
            (_, phi) => {
                if let Some(p) = phi {
                    self.phi(q, t, p);
                }
                self.jacobian_values(q, t, vals);
                self.gamma(q, qd, t, gamma);
            }
        }
    }

    /// Φ_t(q, t).
    pub fn phi_t(&self, q: &[f64], t: f64, out: &mut [f64]) {
        if let Some(k) = self.active_kernels() {
            return k.phi_t(q, t, out);
        }
        for (k, c) in self.constraints.iter().enumerate() {
            c.phi_t(q, t, &mut out[self.rows(k)]);
        }
    }
    /// γ(q, q̇, t) of the acceleration equation Φ_q q̈ = γ, eq. (4).
    pub fn gamma(&self, q: &[f64], qd: &[f64], t: f64, out: &mut [f64]) {
        if let Some(k) = self.active_kernels() {
            return k.gamma(q, qd, t, out);
        }
        for (k, c) in self.constraints.iter().enumerate() {
            c.gamma(q, qd, t, &mut out[self.rows(k)]);
        }
    }
    /// Generalized forces g(q, q̇, t) (overwrites `g`).
    pub fn forces_into(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        g.fill(0.0);
        for f in &self.forces {
            f.add_forces(t, q, qd, g);
        }
    }
    /// `out = Φ_q x` from Jacobian values `vals`.
    pub fn jacobian_mul(&self, vals: &[f64], x: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (&(r, c), &v) in self.jac_pattern.iter().zip(vals) {
            out[r] += v * x[c];
        }
    }
    /// `out = Φ_qᵀ y` from Jacobian values `vals`.
    pub fn jacobian_tmul(&self, vals: &[f64], y: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (&(r, c), &v) in self.jac_pattern.iter().zip(vals) {
            out[c] += v * y[r];
        }
    }
    /// Kinetic energy ½ q̇ᵀ M q̇.
    pub fn kinetic_energy(&self, qd: &[f64]) -> f64 {
        0.5 * self
            .mass_diag
            .iter()
            .zip(qd)
            .map(|(m, v)| m * v * v)
            .sum::<f64>()
    }
    /// Sum of the potential energies of the conservative force elements.
    pub fn potential_energy(&self, q: &[f64]) -> f64 {
        self.forces
            .iter()
            .filter_map(|f| f.potential_energy(q))
            .sum()
    }
    /// Euclidean norm ‖Φ(q, t)‖₂ (allocates; for outputs, not inner loops).
    pub fn constraint_norm(&self, q: &[f64], t: f64) -> f64 {
        let mut phi = vec![0.0; self.n_constraints()];
        self.phi(q, t, &mut phi);
        phi.iter().map(|v| v * v).sum::<f64>().sqrt()
    }
}
