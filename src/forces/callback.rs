//! A force element whose law is user code: a [`CallbackLaw`] (a closure or
//! any type implementing it) of the time and the positions and velocities
//! of chosen coordinates, returning the generalized forces on them (a term
//! of g(q, q̇, t) in eq. (5)). Its Jacobians are the law's own or central
//! finite differences ([`FdWorkspace`]).
//!
//! A law may fail (an exception in a Python callback, a controller out of
//! range): the first error is kept in the element's [`CallbackError`] and
//! from then on the element writes NaN into its forces without calling the
//! law again, so the formulation's finiteness check of g ends the run as
//! `"failed"` at that evaluation, with the rows before it intact. Whoever
//! runs the system reads the error from the handle
//! ([`CallbackForce::error_handle`]) to name the cause.
//!
//! ```
//! use mbsolve::forces::CallbackForce;
//! // a linear torsion spring on body 0's angle (coordinate 2), k = 3 N m/rad
//! let spring = CallbackForce::new("spring", vec![2], |_t: f64, q: &[f64], _qd: &[f64], g: &mut [f64]| {
//!     g[0] = -3.0 * q[0];
//!     Ok::<(), String>(())
//! });
//! assert_eq!(spring.error_handle().get(), None);
//! ```

use crate::model::{check_coordinates, ForceElement, ForceJacobians, ModelError};
use std::fmt;
use std::sync::{Arc, Mutex, PoisonError};

/// The law of a [`CallbackForce`]: the generalized forces on its `k`
/// coordinates, in the order given to [`CallbackForce::new`].
pub trait CallbackLaw: Send + Sync {
    /// Write (not add) into `g` (length k) the generalized forces at time
    /// `t` \[s\], positions `q` and velocities `qd` of the element's
    /// coordinates (each length k; m, rad and m/s, rad/s). Forces in N,
    /// torques in N m. `Err(message)` stops the run (see the module docs).
    fn forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) -> Result<(), String>;

    /// Write `∂g/∂q` into `dq` and `∂g/∂q̇` into `dqd` (k × k row-major,
    /// `[r * k + c] = ∂g_r/∂q_c`, zeroed on entry) and return `Ok(true)`;
    /// `Ok(false)`: no Jacobian given, central finite differences of
    /// [`CallbackLaw::forces`] are used instead. Default: `Ok(false)`.
    fn jacobians(
        &self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        dq: &mut [f64],
        dqd: &mut [f64],
    ) -> Result<bool, String> {
        let _ = (t, q, qd, dq, dqd);
        Ok(false)
    }
}

impl<F> CallbackLaw for F
where
    F: Fn(f64, &[f64], &[f64], &mut [f64]) -> Result<(), String> + Send + Sync,
{
    fn forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) -> Result<(), String> {
        self(t, q, qd, g)
    }
}

/// The first error of a [`CallbackForce`]'s law, shared between the
/// element and whoever runs the system (clones share the slot).
#[derive(Debug, Default, Clone)]
pub struct CallbackError(Arc<Mutex<Option<String>>>);

impl CallbackError {
    /// The first error recorded, if any.
    pub fn get(&self) -> Option<String> {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
    /// Record `message` unless an error is recorded already; the element
    /// then stops calling its law (e.g. a failure in code run after each
    /// step on the law's behalf).
    pub fn set(&self, message: String) {
        let mut slot = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        if slot.is_none() {
            *slot = Some(message);
        }
    }
    fn is_set(&self) -> bool {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .is_some()
    }
}

/// Gathered inputs and outputs of one call (the element is shared: `&self`).
#[derive(Debug, Default)]
struct Scratch {
    q: Vec<f64>,
    qd: Vec<f64>,
    g: Vec<f64>,
    dq: Vec<f64>,
    dqd: Vec<f64>,
}

/// A force element with a [`CallbackLaw`] on chosen global coordinates
/// (`3i, 3i+1, 3i+2` are body i's x, y, φ). Called once per evaluation of
/// the forces (each right-hand side or residual, including the stages and
/// rejected steps of a method) and, without a law Jacobian, 4k more times
/// per Jacobian evaluation (central differences in q and q̇).
pub struct CallbackForce {
    name: String,
    /// Global coordinates in the law's order (distinct).
    coords: Vec<usize>,
    law: Box<dyn CallbackLaw>,
    scratch: Mutex<Scratch>,
    error: CallbackError,
}

impl fmt::Debug for CallbackForce {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CallbackForce")
            .field("name", &self.name)
            .field("coords", &self.coords)
            .field("error", &self.error.get())
            .finish_non_exhaustive()
    }
}

impl CallbackForce {
    /// A callback force named `name` on the global coordinates `coords`
    /// (distinct; the law sees and returns them in this order).
    pub fn new(name: &str, coords: Vec<usize>, law: impl CallbackLaw + 'static) -> Self {
        Self::boxed(name, coords, Box::new(law))
    }

    /// [`CallbackForce::new`] with a boxed law.
    pub(crate) fn boxed(name: &str, coords: Vec<usize>, law: Box<dyn CallbackLaw>) -> Self {
        let k = coords.len();
        Self {
            name: name.to_string(),
            coords,
            law,
            scratch: Mutex::new(Scratch {
                q: vec![0.0; k],
                qd: vec![0.0; k],
                g: vec![0.0; k],
                dq: vec![0.0; k * k],
                dqd: vec![0.0; k * k],
            }),
            error: CallbackError::default(),
        }
    }

    /// The slot holding the law's first error (a clone sharing it).
    pub fn error_handle(&self) -> CallbackError {
        self.error.clone()
    }

    /// Gather q, q̇ of the element's coordinates into the scratch.
    fn gather(&self, s: &mut Scratch, q: &[f64], qd: &[f64]) {
        for (i, &c) in self.coords.iter().enumerate() {
            s.q[i] = q[c];
            s.qd[i] = qd[c];
        }
    }
}

impl ForceElement for CallbackForce {
    fn name(&self) -> String {
        format!("callback force '{}'", self.name)
    }
    fn coordinates(&self) -> Vec<usize> {
        let mut c = self.coords.clone();
        c.sort_unstable();
        c
    }
    fn jacobian_coordinates(&self) -> Vec<usize> {
        self.coords.clone()
    }
    fn add_forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        let mut guard = self.scratch.lock().unwrap_or_else(PoisonError::into_inner);
        let s = &mut *guard;
        if !self.error.is_set() {
            self.gather(s, q, qd);
            s.g.fill(0.0);
            match self.law.forces(t, &s.q, &s.qd, &mut s.g) {
                Ok(()) => {
                    for (i, &c) in self.coords.iter().enumerate() {
                        g[c] += s.g[i];
                    }
                    return;
                }
                Err(m) => self.error.set(m),
            }
        }
        for &c in &self.coords {
            g[c] = f64::NAN;
        }
    }
    fn add_jacobians(&self, t: f64, q: &[f64], qd: &[f64], out: ForceJacobians<'_>) {
        let ForceJacobians { dq, dqd, ws } = out;
        let given = {
            let mut guard = self.scratch.lock().unwrap_or_else(PoisonError::into_inner);
            let s = &mut *guard;
            if self.error.is_set() {
                Err(())
            } else {
                self.gather(s, q, qd);
                s.dq.fill(0.0);
                s.dqd.fill(0.0);
                match self.law.jacobians(t, &s.q, &s.qd, &mut s.dq, &mut s.dqd) {
                    Ok(true) => {
                        for (d, v) in dq.iter_mut().zip(&s.dq) {
                            *d += v;
                        }
                        for (d, v) in dqd.iter_mut().zip(&s.dqd) {
                            *d += v;
                        }
                        Ok(true)
                    }
                    Ok(false) => Ok(false),
                    Err(m) => {
                        self.error.set(m);
                        Err(())
                    }
                }
            }
        };
        match given {
            Ok(true) => {}
            // the scratch is unlocked: the differences call `add_forces`
            Ok(false) => ws.jacobians(self, t, q, qd, dq, dqd),
            Err(()) => {
                dq.fill(f64::NAN);
                dqd.fill(f64::NAN);
            }
        }
    }
    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        let bad = |value: String, why: &str| ModelError::InvalidParameter {
            element: self.name(),
            field: "coordinates".into(),
            value,
            why: why.into(),
        };
        if self.coords.is_empty() {
            return Err(bad("[]".into(), "must name at least one coordinate"));
        }
        let mut sorted = self.coords.clone();
        sorted.sort_unstable();
        if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
            return Err(bad(w[0].to_string(), "appears twice"));
        }
        check_coordinates(&self.name(), &sorted, n_coords)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario;
    use crate::simulation::simulate;

    /// A pendulum (bob on a revolute at the origin, l = 0.5 m) with a
    /// torsion spring-damper and a sinusoidal torque as an expression
    /// force, or without it (for a callback to add).
    fn pendulum(method: &str, expr: bool) -> scenario::Scenario {
        let force = if expr {
            "[[force]]\ntype = \"expression\"\nname = \"law\"\nbody = \"bob\"\n\
             torque = \"-2*bob.phi - 0.1*bob.omega + 0.3*sin(3*t)\"\n"
        } else {
            ""
        };
        let step = match method {
            "genalpha" => "step = 1e-3\n",
            "radau5" => "adaptive = true\n",
            _ => "",
        };
        let text = format!(
            "gravity = [0.0, -9.81]\n[[body]]\nname = \"bob\"\nmass = 1.0\ninertia = 0.02\n\
             x = 0.5\ny = 0.0\nphi = 0.0\n[[joint]]\ntype = \"revolute\"\nbody_i = \"ground\"\n\
             point_i = [0.0, 0.0]\nbody_j = \"bob\"\npoint_j = [-0.5, 0.0]\n{force}\
             [integrator]\nmethod = \"{method}\"\n{step}[time]\nend = 1.0\n[output]\ndt = 0.01\n"
        );
        scenario::parse(&text, "pendulum.toml", "pendulum", &[]).expect("valid scenario")
    }

    /// The expression's law as a closure on (x, y, φ) of the bob.
    fn law(t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) -> Result<(), String> {
        g[2] = -2.0 * q[2] - 0.1 * qd[2] + 0.3 * (3.0 * t).sin();
        Ok(())
    }

    /// The callback force gives the expression force's trajectory to
    /// rounding, explicit (ode45) and implicit (finite-difference
    /// Jacobian: genalpha, bdf; a given Jacobian: radau5).
    #[test]
    fn equals_expression_force() {
        for method in ["ode45", "genalpha", "bdf", "radau5"] {
            let e = pendulum(method, true);
            let (te, se) = simulate(&e.system, &e.q0, &e.qd0, &e.run, &mut []).unwrap();
            let mut c = pendulum(method, false);
            let f: Box<dyn CallbackLaw> = if method == "radau5" {
                struct WithJacobian;
                impl CallbackLaw for WithJacobian {
                    fn forces(
                        &self,
                        t: f64,
                        q: &[f64],
                        qd: &[f64],
                        g: &mut [f64],
                    ) -> Result<(), String> {
                        law(t, q, qd, g)
                    }
                    fn jacobians(
                        &self,
                        _t: f64,
                        _q: &[f64],
                        _qd: &[f64],
                        dq: &mut [f64],
                        dqd: &mut [f64],
                    ) -> Result<bool, String> {
                        dq[8] = -2.0;
                        dqd[8] = -0.1;
                        Ok(true)
                    }
                }
                Box::new(WithJacobian)
            } else {
                Box::new(law)
            };
            c.system
                .add_force(Box::new(CallbackForce::boxed("law", vec![0, 1, 2], f)))
                .unwrap();
            let (tc, sc) = simulate(&c.system, &c.q0, &c.qd0, &c.run, &mut []).unwrap();
            assert_eq!(se.status, "completed", "{method}");
            assert_eq!(sc.status, "completed", "{method}");
            assert_eq!(te.t, tc.t, "{method}");
            let mut worst = 0.0_f64;
            for (a, b) in te.q.iter().zip(&tc.q) {
                for (x, y) in a.iter().zip(b) {
                    worst = worst.max((x - y).abs());
                }
            }
            // the same law summed in another order (gravity before or
            // after it): differences of rounding, amplified by the
            // adaptive step choice at most to the tolerance's scale
            assert!(worst < 1e-9, "{method}: max |Δq| = {worst:e}");
            // the swing is not trivial (the comparison means something)
            let phi_range =
                te.q.iter()
                    .map(|q| q[2])
                    .fold(0.0_f64, |m, p| m.max(p.abs()));
            assert!(phi_range > 0.5, "{method}: max |φ| = {phi_range}");
        }
    }

    /// A law that fails at t > 0.5 ends the run as failed, with the rows
    /// before it kept and the law's message in the handle; the law is not
    /// called again after its error.
    #[test]
    fn failure_stops_the_run_and_keeps_rows() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        for method in ["ode45", "genalpha"] {
            let mut c = pendulum(method, false);
            let after = Arc::new(AtomicUsize::new(0));
            let seen = after.clone();
            let f = CallbackForce::new(
                "law",
                vec![0, 1, 2],
                move |t: f64, q: &[f64], qd: &[f64], g: &mut [f64]| {
                    if t > 0.5 {
                        seen.fetch_add(1, Ordering::Relaxed);
                        return Err(format!("out of range at t = {t}"));
                    }
                    law(t, q, qd, g)
                },
            );
            let handle = f.error_handle();
            c.system.add_force(Box::new(f)).unwrap();
            let (tr, s) = simulate(&c.system, &c.q0, &c.qd0, &c.run, &mut []).unwrap();
            assert_eq!(s.status, "failed", "{method}: {:?}", s.message);
            let m = handle.get().expect("the law's error is kept");
            assert!(m.starts_with("out of range at t = 0.5"), "{method}: {m}");
            assert_eq!(
                after.load(Ordering::Relaxed),
                1,
                "{method}: called after its error"
            );
            assert!(s.message.unwrap().contains("not finite"), "{method}");
            // the failing call is a stage of the step that would cross
            // t = 0.5: the rows end at the last accepted step before it,
            // up to one of ode45's steps earlier
            let last = *tr.t.last().unwrap();
            assert!(last > 0.3 && last <= 0.5, "{method}: rows up to t = {last}");
            assert_eq!(tr.t.len(), s.output_rows);
        }
    }

    /// Duplicate, missing and out-of-range coordinates are refused.
    #[test]
    fn bad_coordinates_are_refused() {
        let ok = |_t: f64, _q: &[f64], _qd: &[f64], _g: &mut [f64]| Ok::<(), String>(());
        let mut c = pendulum("ode45", false);
        for (coords, why) in [
            (vec![], "at least one"),
            (vec![2, 2], "twice"),
            (vec![3], ""),
        ] {
            let e = c
                .system
                .add_force(Box::new(CallbackForce::new("x", coords, ok)))
                .unwrap_err()
                .to_string();
            assert!(e.contains(why), "{e}");
        }
        assert_eq!(
            c.system
                .add_force(Box::new(CallbackForce::new("x", vec![2], ok)))
                .unwrap(),
            c.system.forces().len() - 1
        );
    }
}
