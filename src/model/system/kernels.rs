//! Kernels attached to ranges of joints and force elements: the traits
//! they implement, attaching and detaching them, and the evaluation plan
//! that interleaves them with the generic per-element loop.

use super::{Evaluation, ForceKernelBlock, KernelBlock, Segment, System};
use crate::model::ModelError;
use std::ops::Range;

/// Specialised evaluation of Φ, Φ_q, Φ_t, γ (and optionally (Φ_qᵀλ)_q) for
/// a contiguous range of joints, e.g. code emitted at build time by
/// `mbsolve-codegen` for a known topology ([`crate::generated`]).
///
/// Attached to a range of joints ([`crate::model::SystemBuilder::attach_kernels`],
/// [`System::attach_kernels`]), the kernels read the global q and q̇ and
/// write the range's rows (`out`, `gamma`: the range's rows only) and Φ_q
/// values (`vals`: the range's entries of [`System::jacobian_pattern`]).
/// They must produce what the generic per-joint evaluation produces (to
/// rounding); the pattern is checked when they are attached.
pub trait ConstraintKernels: Send + Sync + std::fmt::Debug {
    /// Name for summaries, e.g. "generated:rod_chain".
    fn name(&self) -> &str;
    /// The Φ_q pattern the kernels write: `(row within the range, global
    /// column)` in order; must equal the range's joints' patterns.
    fn jacobian_pattern(&self) -> Vec<(usize, usize)>;
    /// Do the kernels evaluate (Φ_qᵀλ)_q ([`ConstraintKernels::add_hessian`])?
    fn has_hessian(&self) -> bool {
        false
    }
    /// Add (Φ_qᵀλ)_q of the range's joints, joint after joint in the order of
    /// their [`crate::model::Constraint::hessian_pattern`]s (λ: the range's multipliers).
    /// Called only when [`ConstraintKernels::has_hessian`].
    fn add_hessian(&self, q: &[f64], t: f64, lambda: &[f64], vals: &mut [f64]) {
        let _ = (q, t, lambda, vals);
    }
    /// Φ(q, t).
    fn phi(&self, q: &[f64], t: f64, out: &mut [f64]);
    /// Φ_q values in pattern order.
    fn jacobian_values(&self, q: &[f64], t: f64, vals: &mut [f64]);
    /// Φ_t(q, t).
    fn phi_t(&self, q: &[f64], t: f64, out: &mut [f64]);
    /// γ(q, q̇, t).
    fn gamma(&self, q: &[f64], qd: &[f64], t: f64, out: &mut [f64]);
    /// Φ(q, t) into `phi` and Φ_qᵀλ **added** to `g` (all coordinates;
    /// λ: the range's multipliers) in one pass, without the Φ_q values:
    /// the constraint part of the index-3 residual. Returns false when the
    /// kernels do not have it (the caller then takes Φ and Φ_q).
    fn phi_tmul(&self, q: &[f64], t: f64, lambda: &[f64], phi: &mut [f64], g: &mut [f64]) -> bool {
        let _ = (q, t, lambda, phi, g);
        false
    }
    /// The index-3 residual's two halves `lo` and `hi` concurrently
    /// (on the run's two threads), each handed the shared work of its
    /// bodies (below `split_body`, and from it) done in the same hand-over
    /// as the half itself: the sines and cosines of their angles
    /// ([`BodyTrig`]), which the half's [`ConstraintKernels::phi_tmul_joints`]
    /// and [`ForceKernels::add_forces_range`] read. Default: no shared
    /// work (`None`).
    fn in_halves(&self, q: &[f64], t: f64, split_body: usize, lo: HalfTask<'_>, hi: HalfTask<'_>) {
        let _ = (q, t, split_body);
        crate::parallel::join_if(true, || lo(None), || hi(None));
    }
    /// [`ConstraintKernels::phi_tmul`] of the range's joints `joints` only
    /// (indices within the range, in row order): their Φ into `phi` and
    /// their λ from `lambda` (both: those joints' rows only), Φ_qᵀλ added
    /// to `g` (all coordinates) with the operations `phi_tmul` does for
    /// them. For the index-3 residual's two halves, which call it
    /// concurrently on disjoint joints inside [`ConstraintKernels::in_halves`]
    /// (`trig`: the sines and cosines it handed the half, if any).
    /// Returns false when the kernels do not have it (the halves are then
    /// not used).
    #[allow(clippy::too_many_arguments)]
    fn phi_tmul_joints(
        &self,
        q: &[f64],
        t: f64,
        lambda: &[f64],
        phi: &mut [f64],
        g: &mut [f64],
        joints: Range<usize>,
        trig: Option<BodyTrig<'_>>,
    ) -> bool {
        let _ = (q, t, lambda, phi, g, joints, trig);
        false
    }
    /// Φ, Φ_q values and γ in one pass into `out`. Default: the three
    /// calls; kernels override it to share the sines and cosines of every
    /// angle.
    fn evaluate(&self, q: &[f64], qd: &[f64], t: f64, out: ConstraintTerms<'_>) {
        self.phi(q, t, out.phi);
        self.jacobian_values(q, t, out.vals);
        self.gamma(q, qd, t, out.gamma);
    }
}

/// One half of the index-3 residual ([`ConstraintKernels::in_halves`]):
/// run with the sines and cosines of its bodies when the kernels share
/// them.
pub type HalfTask<'a> = &'a mut (dyn FnMut(Option<BodyTrig<'_>>) + Send);

/// `[sin φ_b, cos φ_b]` of the consecutive bodies `b = body0, body0 + 1,
/// …` (global body indices, `sc.len() / 2` of them): one half's part of a
/// chain's memo of sines and cosines ([`ConstraintKernels::in_halves`]),
/// the values of the crate's one `sin_cos`.
#[derive(Debug, Clone, Copy)]
pub struct BodyTrig<'a> {
    /// Global index of the first body.
    pub body0: usize,
    /// `[sin, cos]` per body.
    pub sc: &'a [f64],
}

impl<'a> BodyTrig<'a> {
    /// `[sin, cos]` of the bodies `bodies` (global indices) when all of
    /// them are here.
    pub fn of(&self, bodies: Range<usize>) -> Option<&'a [f64]> {
        let a = bodies.start.checked_sub(self.body0)?;
        let b = bodies.end.checked_sub(self.body0)?;
        self.sc.get(2 * a..2 * b)
    }
}

/// Where [`ConstraintKernels::evaluate`] writes its range's terms in one
/// pass: Φ and γ (the range's rows, the same length, so named rather than
/// placed) and the Φ_q values (the range's entries of
/// [`System::jacobian_pattern`]).
#[derive(Debug)]
pub struct ConstraintTerms<'a> {
    /// Φ(q, t).
    pub phi: &'a mut [f64],
    /// Φ_q values in pattern order.
    pub vals: &'a mut [f64],
    /// γ(q, q̇, t), the right-hand side of `Φ_q q̈ = γ`.
    pub gamma: &'a mut [f64],
}

/// A state `(t, q, q̇)`: where force kernels evaluate, and what the
/// implicit schemes hand their problem
/// ([`crate::integrate::SecondOrderDae`]).
#[derive(Debug, Clone, Copy)]
pub struct StateView<'a> {
    /// Time t \[s\].
    pub t: f64,
    /// Positions q, n of them.
    pub q: &'a [f64],
    /// Velocities q̇, n of them.
    pub qd: &'a [f64],
}

/// Specialised Jacobians ∂g/∂q and ∂g/∂q̇ of a contiguous range of force
/// elements (e.g. generated by `mbsolve-codegen`), for the Newton matrix of
/// the implicit methods, and optionally the forces g themselves
/// ([`ForceKernels::add_forces`]) — only bit-identical to the elements', so
/// attaching kernels changes no trajectory of the explicit methods.
pub trait ForceKernels: Send + Sync + std::fmt::Debug {
    /// Name for summaries, e.g. "generated:drag_bodies".
    fn name(&self) -> &str;
    /// Each element's [`crate::model::ForceElement::jacobian_coordinates`], in order (checked
    /// against the elements' own when attached).
    fn jacobian_coordinates(&self) -> Vec<Vec<usize>>;
    /// Add the elements' Jacobian blocks at `x` (each `k × k` row-major
    /// over its Jacobian coordinates, element after element) to `dq`, `dqd`.
    fn add_jacobians(&self, x: StateView<'_>, dq: &mut [f64], dqd: &mut [f64]);
    /// Add the elements' generalized forces at `x` to `g` (all
    /// coordinates) in one loop, **bit-identical** to the elements' own
    /// `add_forces` called in order (same operations, same order into every
    /// entry of g); false (the default): the elements do it.
    fn add_forces(&self, x: StateView<'_>, g: &mut [f64]) -> bool {
        let _ = (x, g);
        false
    }
    /// [`ForceKernels::add_forces`] of the elements `elements` (indices
    /// within the range) only, bit-identical to those elements' own
    /// `add_forces` in order (`trig`: sines and cosines of bodies handed
    /// to a half of the residual, [`ConstraintKernels::in_halves`]); false
    /// (the default): the elements do it.
    fn add_forces_range(
        &self,
        x: StateView<'_>,
        g: &mut [f64],
        elements: Range<usize>,
        trig: Option<BodyTrig<'_>>,
    ) -> bool {
        let _ = (x, g, elements, trig);
        false
    }
}

impl System {
    /// Attach specialised kernels to the joints `joints` (used by default
    /// from now on). Errors when the range is out of bounds, overlaps
    /// kernels attached before, or the kernels' Φ_q pattern differs from the
    /// joints'.
    pub fn attach_kernels(
        &mut self,
        joints: Range<usize>,
        k: Box<dyn ConstraintKernels>,
    ) -> Result<(), ModelError> {
        let taken = self.kernels.iter().map(|b| &b.joints);
        let at = Attach::new(k.name(), "joints", &joints, self.constraints.len(), taken)?;
        let [rows, vals, hess] = [&self.row_offset, &self.jac_offset, &self.hess_offset]
            .map(|offsets| offsets[joints.start]..offsets[joints.end]);
        let mine: Vec<(usize, usize)> = self.jac_pattern[vals.clone()]
            .iter()
            .map(|&(r, c)| (r - rows.start, c))
            .collect();
        let differs = "the kernels' Φ_q pattern differs from the joints' (another topology?)";
        at.same(k.jacobian_pattern(), mine, differs)?;
        self.kernels.push(KernelBlock {
            joints,
            rows,
            vals,
            hess,
            kernels: k,
        });
        self.plan_with(true);
        Ok(())
    }

    /// Attach Jacobian kernels to the force elements `elements` (used by
    /// default from now on). Errors when the range is out of bounds,
    /// overlaps kernels attached before, or the kernels' Jacobian
    /// coordinates differ from the elements'.
    pub(crate) fn attach_force_kernels(
        &mut self,
        elements: Range<usize>,
        k: Box<dyn ForceKernels>,
    ) -> Result<(), ModelError> {
        let taken = self.force_kernels.iter().map(|b| &b.elements);
        let at = Attach::new(
            k.name(),
            "force elements",
            &elements,
            self.forces.len(),
            taken,
        )?;
        let mine: Vec<Vec<usize>> = self.forces[elements.clone()]
            .iter()
            .map(|f| f.jacobian_coordinates())
            .collect();
        let differs = "the kernels' Jacobian coordinates differ from the elements'";
        at.same(k.jacobian_coordinates(), mine, differs)?;
        let vals = self.force_jac_offset[elements.start]..self.force_jac_offset[elements.end];
        self.force_kernels.push(ForceKernelBlock {
            elements,
            vals,
            kernels: k,
        });
        self.plan_with(true);
        Ok(())
    }

    /// Remove every attached kernel (back to the generic evaluation).
    pub(crate) fn detach_kernels(&mut self) {
        self.kernels.clear();
        self.force_kernels.clear();
        self.plan_with(false);
    }

    /// Evaluate with the attached kernels (`on`) or generically: the
    /// evaluation plans (the kernel blocks in item order).
    pub(super) fn plan_with(&mut self, on: bool) {
        self.use_kernels = on;
        self.kernels.sort_by_key(|b| b.joints.start);
        self.force_kernels.sort_by_key(|b| b.elements.start);
        let joints: Vec<Range<usize>> = self.kernels.iter().map(|b| b.joints.clone()).collect();
        self.plan = plan(on, &joints, self.constraints.len());
        let elements: Vec<Range<usize>> = self
            .force_kernels
            .iter()
            .map(|b| b.elements.clone())
            .collect();
        self.force_plan = plan(on, &elements, self.forces.len());
    }

    /// Choose the evaluation; `Generated` without attached kernels is an error.
    pub fn set_evaluation(&mut self, e: Evaluation) -> Result<(), ModelError> {
        let any = !self.kernels.is_empty() || !self.force_kernels.is_empty();
        let on = match e {
            Evaluation::Auto => any,
            Evaluation::Generic => false,
            Evaluation::Generated => {
                if !any {
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
        self.plan_with(on);
        Ok(())
    }

    /// Name of the constraint evaluation in use: "generic", or the
    /// kernels' names (joined by "+", with "+generic" when some joints have
    /// none). Force kernels: [`System::force_kernel_names`].
    pub fn evaluation_name(&self) -> String {
        if !self.uses_kernels() {
            return "generic".into();
        }
        let mut names: Vec<&str> = self.kernels.iter().map(|b| b.kernels.name()).collect();
        if self.plan.iter().any(|s| matches!(s, Segment::Joint(_))) {
            names.push("generic");
        }
        names.join("+")
    }

    /// Names of the force-Jacobian kernels in use (empty: none).
    pub fn force_kernel_names(&self) -> Vec<&str> {
        if !self.use_kernels {
            return Vec::new();
        }
        self.force_kernels
            .iter()
            .map(|b| b.kernels.name())
            .collect()
    }
}

/// The checks of attaching the kernels `name` to the range `range` of
/// `field` ("joints" or "force elements"); their errors name the kernels,
/// the field and the range.
struct Attach {
    element: String,
    field: &'static str,
    value: String,
}

impl Attach {
    /// `range` lies within the `n` items and overlaps no range in `taken`
    /// (the kernels attached before).
    fn new<'a>(
        name: &str,
        field: &'static str,
        range: &Range<usize>,
        n: usize,
        mut taken: impl Iterator<Item = &'a Range<usize>>,
    ) -> Result<Self, ModelError> {
        let at = Self {
            element: name.to_string(),
            field,
            value: format!("{range:?}"),
        };
        if range.start > range.end || range.end > n {
            return Err(at.error(format!("not a range of the {n} {field}")));
        }
        if taken.any(|b| b == range || (b.start < range.end && range.start < b.end)) {
            // "joints", "elements"
            let items = field.trim_start_matches("force ");
            return Err(at.error(format!("overlaps {items} that already have kernels")));
        }
        Ok(at)
    }
    /// The kernels' pattern `theirs` equals the items' `mine`; else the
    /// error `differs`.
    fn same<T: PartialEq>(&self, theirs: T, mine: T, differs: &str) -> Result<(), ModelError> {
        if theirs == mine {
            Ok(())
        } else {
            Err(self.error(differs.into()))
        }
    }
    fn error(&self, why: String) -> ModelError {
        ModelError::InvalidParameter {
            element: self.element.clone(),
            field: self.field.into(),
            value: self.value.clone(),
            why,
        }
    }
}

/// An evaluation plan over `n` items: kernel blocks (when `on`) for the
/// sorted, disjoint `ranges`, the items one by one elsewhere.
fn plan(on: bool, ranges: &[Range<usize>], n: usize) -> Vec<Segment> {
    let mut out = Vec::with_capacity(n);
    let mut j = 0;
    if on {
        for (i, r) in ranges.iter().enumerate() {
            out.extend((j..r.start).map(Segment::Joint));
            out.push(Segment::Kernels(i));
            j = r.end;
        }
    }
    out.extend((j..n).map(Segment::Joint));
    out
}
