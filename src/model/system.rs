//! The assembled multibody system: numbering and evaluation of Φ, Φ_q, Φ_t,
//! γ and g.

use super::{Body, Constraint, FdWorkspace, ForceElement, ForceJacobians, Gravity, ModelError};
use std::ops::Range;

mod halves;
mod kernels;
pub use halves::ResidualHalves;
pub use kernels::{
    BodyTrig, ConstraintKernels, ConstraintTerms, ForceKernels, HalfTask, StateView,
};

/// Force kernels attached to a range of elements, with the range of their
/// Jacobian values.
#[derive(Debug)]
struct ForceKernelBlock {
    elements: Range<usize>,
    vals: Range<usize>,
    kernels: Box<dyn ForceKernels>,
}

/// Kernels attached to a range of joints, with the ranges of rows, Φ_q
/// values and Hessian values they cover.
#[derive(Debug)]
struct KernelBlock {
    joints: Range<usize>,
    rows: Range<usize>,
    vals: Range<usize>,
    hess: Range<usize>,
    kernels: Box<dyn ConstraintKernels>,
}

/// A per-joint term of the constraints (`System::along_plan`).
#[derive(Debug, Clone, Copy)]
enum Term<'a> {
    /// Φ(q, t), eq. (2).
    Phi,
    /// Φ_q(q, t) values in pattern order.
    Jacobian,
    /// Φ_t(q, t).
    PhiT,
    /// γ(q, q̇, t), eq. (4), at these velocities q̇.
    Gamma(&'a [f64]),
}

/// One step of an evaluation plan: a joint (or force element) evaluated
/// generically, or a kernel block.
#[derive(Debug, Clone, Copy)]
enum Segment {
    Joint(usize),
    Kernels(usize),
}

/// Which evaluation of Φ, Φ_q, Φ_t, γ a [`System`] uses
/// (scenario key `constraints.evaluation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Evaluation {
    /// Kernels where attached, the generic per-joint loop elsewhere.
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
    hess_offset: Vec<usize>,
    hess_pattern: Vec<(usize, usize)>,
    mass_diag: Vec<f64>,
    kernels: Vec<KernelBlock>,
    use_kernels: bool,
    /// The evaluation plan: every joint once, in row order.
    plan: Vec<Segment>,
    force_jac_offset: Vec<usize>,
    force_jac_pattern: Vec<(usize, usize)>,
    force_kernels: Vec<ForceKernelBlock>,
    /// The plan for force Jacobians: every element once, in order.
    force_plan: Vec<Segment>,
    /// The names messages give the force elements ([`System::force_label`]).
    force_names: Vec<Option<String>>,
    /// Controller states ([`SystemBuilder::add_state`]), after the bodies'
    /// coordinates.
    states: Vec<State>,
}

/// A controller state z (first order, `ż = f`), held as the velocity of an
/// extra coordinate w of unit mass (`ẅ = f`): every second-order method
/// integrates it with the mechanism; it has no gravity, no constraints and
/// no kinetic energy. The generalized force on w is the derivative f.
#[derive(Debug, Clone)]
pub struct State {
    /// Its name (expressions read z by it; its output column).
    pub name: String,
    /// z(t0).
    pub initial: f64,
    /// Its unit, as the output column states it (`"rad s"`); `"1"`
    /// (dimensionless) unless given ([`SystemBuilder::add_state_with_unit`]).
    pub unit: String,
}

/// Collects bodies, joints and force elements, then validates them into a [`System`].
#[derive(Debug, Default)]
pub struct SystemBuilder {
    bodies: Vec<Body>,
    constraints: Vec<Box<dyn Constraint>>,
    forces: Vec<Box<dyn ForceElement>>,
    gravity: Option<[f64; 2]>,
    kernels: Vec<(Range<usize>, Box<dyn ConstraintKernels>)>,
    force_kernels: Vec<(Range<usize>, Box<dyn ForceKernels>)>,
    /// States, with the number of bodies when each was added.
    states: Vec<(State, usize)>,
}

impl SystemBuilder {
    /// Add a controller state ([`State`]) after every body (add the bodies
    /// first); returns its coordinate w, `3 · bodies + k` for the k-th
    /// state: z is `q̇[w]`, and a force element's generalized force on `w`
    /// is `ż`.
    pub fn add_state(&mut self, name: impl Into<String>, initial: f64) -> usize {
        self.add_state_with_unit(name, initial, "1")
    }
    /// [`SystemBuilder::add_state`] with the state's unit (text for the
    /// output column, e.g. `"rad s"`; no effect on the dynamics).
    pub fn add_state_with_unit(
        &mut self,
        name: impl Into<String>,
        initial: f64,
        unit: impl Into<String>,
    ) -> usize {
        let w = 3 * self.bodies.len() + self.states.len();
        self.states.push((
            State {
                name: name.into(),
                initial,
                unit: unit.into(),
            },
            self.bodies.len(),
        ));
        w
    }
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
    /// Attach specialised kernels to the joints `joints` (indices returned
    /// by [`SystemBuilder::add_constraint`]); checked and used from
    /// [`SystemBuilder::build`] on. Builders attach the kernels of the
    /// sub-structures they create (a rod's chain of revolutes).
    pub fn attach_kernels(&mut self, joints: Range<usize>, k: Box<dyn ConstraintKernels>) {
        self.kernels.push((joints, k));
    }
    /// Attach Jacobian kernels to the force elements `elements` (indices
    /// returned by [`SystemBuilder::add_force`]); checked and used from
    /// [`SystemBuilder::build`] on.
    pub(crate) fn attach_force_kernels(
        &mut self,
        elements: Range<usize>,
        k: Box<dyn ForceKernels>,
    ) {
        self.force_kernels.push((elements, k));
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
    /// Joints added so far, in row order.
    pub fn constraints(&self) -> &[Box<dyn Constraint>] {
        &self.constraints
    }
    /// Force elements added so far (the index the next one gets).
    pub fn n_forces(&self) -> usize {
        self.forces.len()
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
        for (s, n_bodies) in &self.states {
            if *n_bodies != nb || !s.initial.is_finite() {
                return Err(ModelError::InvalidParameter {
                    element: format!("state '{}'", s.name),
                    field: "initial".into(),
                    value: s.initial.to_string(),
                    why: "must be finite, and states are added after every body".into(),
                });
            }
        }
        let n = 3 * nb + self.states.len();
        let mut row_offset = vec![0];
        let mut jac_offset = vec![0];
        let mut jac_pattern = Vec::new();
        let mut hess_offset = vec![0];
        let mut hess_pattern = Vec::new();
        for c in &self.constraints {
            c.validate(nb)?;
            let r0 = *row_offset.last().expect("non-empty");
            for (r, col) in c.jacobian_pattern() {
                debug_assert!(r < c.n_eq() && col < n);
                jac_pattern.push((r0 + r, col));
            }
            row_offset.push(r0 + c.n_eq());
            jac_offset.push(jac_pattern.len());
            for (r, col) in c.hessian_pattern() {
                if r >= n || col >= n {
                    return Err(ModelError::InvalidParameter {
                        element: c.name(),
                        field: "hessian_pattern".into(),
                        value: format!("({r}, {col})"),
                        why: format!("outside the {n} coordinates"),
                    });
                }
                hess_pattern.push((r, col));
            }
            hess_offset.push(hess_pattern.len());
        }
        let mut force_jac_offset = vec![0];
        let mut force_jac_pattern = Vec::new();
        for f in &self.forces {
            force_jacobian_block(f.as_ref(), n, &mut force_jac_pattern)?;
            force_jac_offset.push(force_jac_pattern.len());
        }
        let mass_diag = self
            .bodies
            .iter()
            .flat_map(|b| [b.mass, b.mass, b.inertia])
            .chain(self.states.iter().map(|_| 1.0))
            .collect();
        let mut sys = System {
            plan: (0..self.constraints.len()).map(Segment::Joint).collect(),
            force_plan: (0..self.forces.len()).map(Segment::Joint).collect(),
            force_jac_offset,
            force_jac_pattern,
            force_kernels: Vec::new(),
            bodies: self.bodies,
            constraints: self.constraints,
            forces: self.forces,
            row_offset,
            jac_offset,
            jac_pattern,
            hess_offset,
            hess_pattern,
            mass_diag,
            kernels: Vec::new(),
            use_kernels: false,
            force_names: Vec::new(),
            states: self.states.into_iter().map(|s| s.0).collect(),
        };
        for (joints, k) in self.kernels {
            sys.attach_kernels(joints, k)?;
        }
        for (elements, k) in self.force_kernels {
            sys.attach_force_kernels(elements, k)?;
        }
        Ok(sys)
    }
}

/// Validate force element `f` in a system of `n` coordinates and append
/// its Jacobian block (k × k over its Jacobian coordinates) to `pattern`.
fn force_jacobian_block(
    f: &dyn ForceElement,
    n: usize,
    pattern: &mut Vec<(usize, usize)>,
) -> Result<(), ModelError> {
    f.validate(n)?;
    let cols = f.jacobian_coordinates();
    if let Some(&c) = cols.iter().find(|&&c| c >= n) {
        return Err(ModelError::InvalidParameter {
            element: f.name(),
            field: "jacobian_coordinates".into(),
            value: c.to_string(),
            why: format!("outside the {n} coordinates"),
        });
    }
    pattern.extend(cols.iter().flat_map(|&r| cols.iter().map(move |&c| (r, c))));
    Ok(())
}

impl System {
    /// Append a force element to a built system (after every element it
    /// has, gravity included), validated as [`SystemBuilder::build`] does;
    /// returns its index. Its Jacobian block goes last in
    /// `System::force_jacobian_pattern`; attached kernels keep theirs.
    /// For forces a scenario file cannot describe, such as a
    /// [`crate::forces::CallbackForce`] added to a loaded scenario's system.
    pub fn add_force(&mut self, f: Box<dyn ForceElement>) -> Result<usize, ModelError> {
        force_jacobian_block(f.as_ref(), self.n_coords(), &mut self.force_jac_pattern)?;
        self.force_jac_offset.push(self.force_jac_pattern.len());
        self.forces.push(f);
        self.plan_with(self.use_kernels);
        Ok(self.forces.len() - 1)
    }
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
    /// Name force element `i` in messages (a scenario gives each element
    /// its `[[force]]`'s key and name, e.g. `force[0] 'spring'`).
    pub fn set_force_name(&mut self, i: usize, name: impl Into<String>) {
        if self.force_names.len() <= i {
            self.force_names.resize(i + 1, None);
        }
        self.force_names[i] = Some(name.into());
    }
    /// How messages name force element `i`: its name
    /// ([`System::set_force_name`]) and what it is, `force[0] 'spring'
    /// (point spring-damper …)`, or `force element #i (…)` when unnamed.
    pub fn force_label(&self, i: usize) -> String {
        let what = self.forces.get(i).map_or_else(String::new, |f| f.name());
        match self.force_names.get(i).and_then(|n| n.as_deref()) {
            Some(n) => format!("{n} ({what})"),
            None => format!("force element #{i} ({what})"),
        }
    }
    /// Number of coordinates n = 3 · bodies + states.
    pub fn n_coords(&self) -> usize {
        self.mass_diag.len()
    }
    /// Number of the bodies' coordinates, 3 · bodies (the states' come after).
    pub fn n_body_coords(&self) -> usize {
        3 * self.bodies.len()
    }
    /// The controller states, in coordinate order after the bodies'.
    pub fn states(&self) -> &[State] {
        &self.states
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
        let q = self.bodies.iter().flat_map(|b| b.q0);
        let q = q.chain(self.states.iter().map(|_| 0.0)).collect();
        let v = self.bodies.iter().flat_map(|b| b.v0);
        let v = v.chain(self.states.iter().map(|s| s.initial)).collect();
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

    /// A per-joint term of the constraints at `(q, t)` into `out`, along the
    /// evaluation plan: each joint evaluated alone into its rows (its
    /// entries of Φ_q for [`Term::Jacobian`]), each kernel block into its
    /// own.
    fn along_plan(&self, term: Term<'_>, q: &[f64], t: f64, out: &mut [f64]) {
        let offsets = match term {
            Term::Jacobian => &self.jac_offset,
            _ => &self.row_offset,
        };
        for s in &self.plan {
            match *s {
                Segment::Joint(k) => {
                    let (c, o) = (&self.constraints[k], &mut out[offsets[k]..offsets[k + 1]]);
                    match term {
                        Term::Phi => c.phi(q, t, o),
                        Term::Jacobian => c.jacobian(q, t, o),
                        Term::PhiT => c.phi_t(q, t, o),
                        Term::Gamma(qd) => c.gamma(q, qd, t, o),
                    }
                }
                Segment::Kernels(i) => {
                    let b = &self.kernels[i];
                    let part = match term {
                        Term::Jacobian => b.vals.clone(),
                        _ => b.rows.clone(),
                    };
                    let (k, o) = (&b.kernels, &mut out[part]);
                    match term {
                        Term::Phi => k.phi(q, t, o),
                        Term::Jacobian => k.jacobian_values(q, t, o),
                        Term::PhiT => k.phi_t(q, t, o),
                        Term::Gamma(qd) => k.gamma(q, qd, t, o),
                    }
                }
            }
        }
    }

    /// Φ(q, t), eq. (2).
    pub fn phi(&self, q: &[f64], t: f64, out: &mut [f64]) {
        self.along_plan(Term::Phi, q, t, out);
    }
    /// Values of Φ_q(q, t) in the order of [`System::jacobian_pattern`].
    pub fn jacobian_values(&self, q: &[f64], t: f64, vals: &mut [f64]) {
        self.along_plan(Term::Jacobian, q, t, vals);
    }
    /// True when specialised kernels evaluate (some of) the constraints.
    pub fn uses_kernels(&self) -> bool {
        self.use_kernels && !self.kernels.is_empty()
    }

    /// The entries `(row, col)` of the force Jacobians: each element's
    /// `k × k` block over its [`ForceElement::jacobian_coordinates`],
    /// row-major, element after element (elements without Jacobian
    /// coordinates have none).
    pub(crate) fn force_jacobian_pattern(&self) -> &[(usize, usize)] {
        &self.force_jac_pattern
    }

    /// Add ∂g/∂q to `dq` and ∂g/∂q̇ to `dqd` in the order of
    /// [`System::force_jacobian_pattern`]: the force kernels' where
    /// attached, each element's otherwise (finite differences through `ws`
    /// for elements without analytic Jacobians).
    pub(crate) fn add_force_jacobians(
        &self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        dq: &mut [f64],
        dqd: &mut [f64],
        ws: &mut FdWorkspace,
    ) {
        for s in &self.force_plan {
            match *s {
                Segment::Joint(e) => {
                    let r = self.force_jac_offset[e]..self.force_jac_offset[e + 1];
                    if !r.is_empty() {
                        let out = ForceJacobians {
                            dq: &mut dq[r.clone()],
                            dqd: &mut dqd[r],
                            ws: &mut *ws,
                        };
                        self.forces[e].add_jacobians(t, q, qd, out);
                    }
                }
                Segment::Kernels(i) => {
                    let b = &self.force_kernels[i];
                    let (dq, dqd) = (&mut dq[b.vals.clone()], &mut dqd[b.vals.clone()]);
                    b.kernels.add_jacobians(StateView { t, q, qd }, dq, dqd);
                }
            }
        }
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
        match phi {
            Some(p) => {
                for s in &self.plan {
                    match *s {
                        Segment::Joint(k) => {
                            let c = &self.constraints[k];
                            c.phi(q, t, &mut p[self.rows(k)]);
                            c.jacobian(q, t, &mut vals[self.jac_offset[k]..self.jac_offset[k + 1]]);
                            c.gamma(q, qd, t, &mut gamma[self.rows(k)]);
                        }
                        Segment::Kernels(i) => {
                            let b = &self.kernels[i];
                            let out = ConstraintTerms {
                                phi: &mut p[b.rows.clone()],
                                vals: &mut vals[b.vals.clone()],
                                gamma: &mut gamma[b.rows.clone()],
                            };
                            b.kernels.evaluate(q, qd, t, out);
                        }
                    }
                }
            }
            None => {
                self.jacobian_values(q, t, vals);
                self.gamma(q, qd, t, gamma);
            }
        }
    }

    /// Structural non-zeros `(row, col)`, `row ≥ col`, of the symmetric
    /// (Φ_qᵀλ)_q: every joint's [`Constraint::hessian_pattern`], joint
    /// after joint (duplicates possible).
    pub fn hessian_pattern(&self) -> &[(usize, usize)] {
        &self.hess_pattern
    }

    /// Add (Φ_qᵀλ)_q in the order of [`System::hessian_pattern`]: the
    /// kernels' where they provide it, each joint's otherwise (finite
    /// differences through `ws` for joints without an exact one).
    pub fn add_constraint_hessians(
        &self,
        q: &[f64],
        t: f64,
        lambda: &[f64],
        vals: &mut [f64],
        ws: &mut FdWorkspace,
    ) {
        let joint = |k: usize, vals: &mut [f64], ws: &mut FdWorkspace| {
            self.constraints[k].add_hessian(
                q,
                t,
                &lambda[self.rows(k)],
                &mut vals[self.hess_offset[k]..self.hess_offset[k + 1]],
                ws,
            )
        };
        for s in &self.plan {
            match *s {
                Segment::Joint(k) => joint(k, vals, ws),
                Segment::Kernels(i) => {
                    let b = &self.kernels[i];
                    if b.kernels.has_hessian() {
                        b.kernels.add_hessian(
                            q,
                            t,
                            &lambda[b.rows.clone()],
                            &mut vals[b.hess.clone()],
                        );
                    } else {
                        for k in b.joints.clone() {
                            joint(k, vals, ws);
                        }
                    }
                }
            }
        }
    }

    /// Φ_t(q, t).
    pub fn phi_t(&self, q: &[f64], t: f64, out: &mut [f64]) {
        self.along_plan(Term::PhiT, q, t, out);
    }
    /// γ(q, q̇, t) of the acceleration equation Φ_q q̈ = γ, eq. (4).
    pub fn gamma(&self, q: &[f64], qd: &[f64], t: f64, out: &mut [f64]) {
        self.along_plan(Term::Gamma(qd), q, t, out);
    }
    /// Generalized forces g(q, q̇, t) (overwrites `g`).
    pub fn forces_into(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        g.fill(0.0);
        for s in &self.force_plan {
            match *s {
                Segment::Joint(e) => self.forces[e].add_forces(t, q, qd, g),
                Segment::Kernels(i) => {
                    let b = &self.force_kernels[i];
                    if !b.kernels.add_forces(StateView { t, q, qd }, g) {
                        for f in &self.forces[b.elements.clone()] {
                            f.add_forces(t, q, qd, g);
                        }
                    }
                }
            }
        }
    }
    /// Φ(q, t) into `phi` and `out = Φ_q(q, t)ᵀ λ` in one pass over the
    /// joints (the constraint part of the index-3 residual, eq. (5)): the
    /// attached kernels' fused [`ConstraintKernels::phi_tmul`] where they
    /// have it, else Φ and the Φ_q values (into the scratch `vals`, pattern
    /// order) joint by joint.
    pub fn phi_and_jacobian_tmul(
        &self,
        q: &[f64],
        t: f64,
        lambda: &[f64],
        phi: &mut [f64],
        out: &mut [f64],
        vals: &mut [f64],
    ) {
        out.fill(0.0);
        let tmul = |e: Range<usize>, vals: &[f64], out: &mut [f64]| {
            self.add_jacobian_tmul(e, vals, lambda, out)
        };
        for s in &self.plan {
            match *s {
                Segment::Joint(k) => {
                    let e = self.jac_offset[k]..self.jac_offset[k + 1];
                    let c = &self.constraints[k];
                    c.phi(q, t, &mut phi[self.rows(k)]);
                    c.jacobian(q, t, &mut vals[e.clone()]);
                    tmul(e, vals, out);
                }
                Segment::Kernels(i) => {
                    let b = &self.kernels[i];
                    let rows = b.rows.clone();
                    let fused = b.kernels.phi_tmul(
                        q,
                        t,
                        &lambda[rows.clone()],
                        &mut phi[rows.clone()],
                        out,
                    );
                    if !fused {
                        b.kernels.phi(q, t, &mut phi[rows]);
                        b.kernels.jacobian_values(q, t, &mut vals[b.vals.clone()]);
                        tmul(b.vals.clone(), vals, out);
                    }
                }
            }
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
        self.add_jacobian_tmul(0..self.jac_pattern.len(), vals, y, out);
    }
    /// `out += Φ_qᵀ y` over the Jacobian entries `e` (pattern order).
    fn add_jacobian_tmul(&self, e: Range<usize>, vals: &[f64], y: &[f64], out: &mut [f64]) {
        for (&(r, c), &v) in self.jac_pattern[e.clone()].iter().zip(&vals[e]) {
            out[c] += v * y[r];
        }
    }
    /// Kinetic energy ½ q̇ᵀ M q̇ of the bodies (the states have none).
    pub fn kinetic_energy(&self, qd: &[f64]) -> f64 {
        0.5 * self.mass_diag[..self.n_body_coords()]
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
