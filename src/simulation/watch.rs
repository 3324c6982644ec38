//! The observer of one run ([`Watch`]): outputs to the sink, the
//! constraint violation and its guards, the energy balance, monitors,
//! the step budget.

use super::*;

pub(super) struct Watch<'s, 'm, 'd, 'k> {
    pub(super) sys: &'s System,
    pub(super) n: usize,
    pub(super) sink: &'k mut dyn Sink,
    pub(super) rows: usize,
    /// The sink's error that ended the run, with the output time.
    pub(super) sink_error: Option<String>,
    /// Max ‖Φ‖ and ‖Φ̇‖, and ‖Φ‖ at the last output.
    pub(super) max_norm: f64,
    pub(super) max_velocity_norm: f64,
    pub(super) final_norm: f64,
    pub(super) phi: Vec<f64>,
    pub(super) phi_t: Vec<f64>,
    pub(super) jac: Vec<f64>,
    pub(super) phid: Vec<f64>,
    pub(super) monitors: &'m mut [&'d mut dyn Monitor],
    /// What to change when the constraints drift, in the keys the run's
    /// method accepts ([`drift_advice`]).
    pub(super) advice: String,
    /// What `phi_fail` is (for its message).
    pub(super) phi_fail_why: String,
    /// Guard bounds: ‖Φ‖ warn / fail, |position| fail.
    pub(super) phi_warn: f64,
    pub(super) phi_fail: f64,
    pub(super) pos_fail: f64,
    /// ‖Φ̇‖ warns above `100 (rtol V + atol)`, V the largest body speed
    /// seen at an output.
    pub(super) rtol: f64,
    pub(super) atol: f64,
    pub(super) speed: f64,
    pub(super) warned_phid: bool,
    pub(super) stop_on_divergence: bool,
    pub(super) warned_phi: bool,
    pub(super) warned_pos: bool,
    /// Why the run diverged (status "diverged").
    pub(super) diverged: Option<String>,
    /// A fixed-step run's step budget ([`STALL_FACTOR`] × its nominal
    /// step count) and why it was exceeded (status "failed").
    pub(super) step_budget: Option<(usize, f64, f64)>,
    pub(super) stalled: Option<String>,
    pub(super) warnings: Vec<String>,
    pub(super) outputs: OutputQuantities,
    /// Eq. (5) at the output states, for q̈ and λ.
    pub(super) extras: Option<Index1<'s>>,
    pub(super) qdd: Vec<f64>,
    pub(super) reaction_map: crate::model::ReactionMap,
    pub(super) reactions: Vec<f64>,
    pub(super) warned_extras: bool,
    /// Integrator notices already shown through the sink (the first ones of
    /// `Report::warnings`).
    pub(super) forwarded: usize,
    /// Energy balance (when [`OutputQuantities::energy`]): E(t0), the work
    /// of non-conservative and constraint forces integrated over the
    /// accepted steps (trapezoid), the power and time at the last step,
    /// the largest |E − E0 − W| and the energy scale seen.
    pub(super) balance: Option<Balance>,
    /// Rank of Φ_q along the run (small systems): redundant rows at t0,
    /// singular configurations crossed.
    pub(super) singular: Option<SingularityMonitor>,
    /// The run projects or partitions (keeps the branch at a singular
    /// configuration): the rank-loss warning says so instead of advising it.
    pub(super) keeps_branch: bool,
}

/// Energy gain, as a fraction of the run's energy scale, above which an
/// implicit run (generalized-α, HHT, Newmark, the augmented Lagrangian,
/// bdf, radau5) warns that its energy balance broke: their numerical damping only
/// removes energy. The constraint study's passing
/// implicit runs from consistent starts drift by at most 1.7e-4 of E0,
/// either sign; the trapezoidal rule (newmark, ρ∞ = 1) on the four-bar at
/// h = 5e-3 gains 1.5 J on a scale of 5.5 J by t = 0.5 s, its
/// constraint-velocity error undamped (tests/formulation/redundant.rs).
pub const IMPLICIT_ENERGY_GAIN: f64 = 1e-2;

/// A fixed-step implicit run that has taken this many times the steps its
/// step `h` needs for the whole span (plus [`STALL_SLACK`]) stops with
/// status "failed": the step keeps being cut (each Newton failure halves
/// it, and it grows back by doubling), so the run crawls. Healthy runs
/// stay within a fraction of a percent of the nominal count; a run whose
/// energy blows up can otherwise crawl for millions of steps
/// (docs/scaling.md, "Measurements behind the defaults").
pub const STALL_FACTOR: f64 = 10.0;

/// Steps allowed beyond [`STALL_FACTOR`] × the nominal count (short runs).
pub const STALL_SLACK: usize = 1000;

/// The energy balance `E(t) − E(t0) = W(t)` tracked by [`Watch`]
/// (`crate::model::energy` docs).
pub(super) struct Balance {
    pub(super) e0: f64,
    /// Work and power of the force elements and of the constraints.
    pub(super) work: [f64; 2],
    pub(super) power: [f64; 2],
    pub(super) t: f64,
    pub(super) max_error: f64,
    /// The largest signed `T + V − E0 − W` (energy gained).
    pub(super) max_gain: f64,
    /// The energy in play: the largest of |T0| + |V0| + |W|, T, |V_g − V_g0|
    /// and |V_e − V_e0| over the run ([`Watch::balance_at`]).
    pub(super) scale: f64,
    /// `[V_g, V_e]` at the start.
    pub(super) v0: [f64; 2],
    /// The energy of a velocity error of `atol` in every body,
    /// ½ Σ m · atol² (plus ½ Σ I · atol²): below it a balance error is
    /// the tolerance's, not the run's.
    pub(super) floor: f64,
    /// Estimated error of the trapezoid quadrature of W so far, and the
    /// last step's slope of P and size.
    pub(super) e_parts0: f64,
    pub(super) quadrature_error: f64,
    pub(super) last_slope: Option<(f64, f64)>,
    pub(super) rheonomic: bool,
    pub(super) ws: crate::model::EnergyWorkspace,
    /// Which force elements are gravity (V_g; the others' potentials are V_e).
    pub(super) is_gravity: Vec<bool>,
}

impl<'s, 'm, 'd, 'k> Watch<'s, 'm, 'd, 'k> {
    pub(super) fn new(
        sys: &'s System,
        cfg: &RunConfig,
        q0: &[f64],
        monitors: &'m mut [&'d mut dyn Monitor],
        sink: &'k mut dyn Sink,
    ) -> Self {
        let m = sys.n_constraints();
        let g = &cfg.guards;
        // length scale: the largest position coordinate of q0 (x, y of each body)
        let l = q0[..sys.n_body_coords()]
            .chunks(3)
            .flat_map(|b| b[..2].iter())
            .fold(1e-3, |a: f64, v| a.max(v.abs()));
        let atol = match &cfg.ode.atol {
            Tolerance::Scalar(a) => *a,
            Tolerance::Vector(v) => v.iter().cloned().fold(0.0, f64::max),
        };
        let phi_warn = g
            .constraint_warn
            .unwrap_or(100.0 * (cfg.ode.rtol * l + atol));
        // the mechanism's size: the diagonal of the box around the bodies'
        // reference points at t0, at least `l`
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for b in q0[..sys.n_body_coords()].chunks(3) {
            for k in 0..2 {
                lo[k] = lo[k].min(b[k]);
                hi[k] = hi[k].max(b[k]);
            }
        }
        let size = if q0.is_empty() {
            l
        } else {
            l.max((hi[0] - lo[0]).hypot(hi[1] - lo[1]))
        };
        let (phi_fail, phi_fail_why) = match g.constraint_fail {
            Some(f) => (f, "guards.constraint_fail".to_string()),
            None => {
                let by_tol = l.max(10.0 * phi_warn);
                // an incorrect start's own violation is the run's to reduce
                let mut phi0 = vec![0.0; m];
                sys.phi(q0, cfg.t0, &mut phi0);
                let by_size = (SIZE_FRACTION * size).max(10.0 * norm2(&phi0));
                if by_size < by_tol {
                    (
                        by_size,
                        format!(
                            "{SIZE_FRACTION} of the mechanism's size {size:.3e} m, or 10 × ‖Φ‖ at \
                             the start"
                        ),
                    )
                } else {
                    (by_tol, "the larger of L and 10 × the warning bound".into())
                }
            }
        };
        let o = cfg.outputs;
        let extras = if o_needs_extras(&o) || o.energy {
            // eq. (5) with the run's Baumgarte terms (none for the
            // index-3 and penalty runs), without projection
            let mut opts = Index1Options {
                linear_solver: cfg.formulation.linear_solver,
                ..Index1Options::default()
            };
            if !cfg.method.is_index3() && cfg.formulation.formulation != Formulation::Penalty {
                opts.baumgarte = cfg.formulation.baumgarte;
            }
            Index1::new(sys, opts).ok()
        } else {
            None
        };
        Self {
            outputs: o,
            extras,
            qdd: vec![0.0; sys.n_coords()],
            reaction_map: sys.reaction_map(),
            reactions: vec![0.0; 3 * sys.constraints().len()],
            warned_extras: false,
            forwarded: 0,
            balance: None,
            singular: SingularityMonitor::new(sys, cfg.t0, q0),
            keeps_branch: if cfg.method.is_generalized_alpha() {
                cfg.implicit.project
            } else {
                cfg.formulation.projection.enabled
                    || cfg.formulation.formulation == Formulation::Partitioned
            },
            advice: drift_advice(cfg),
            phi_fail_why,
            phi_warn,
            phi_fail,
            pos_fail: g.position_factor * l,
            rtol: cfg.ode.rtol,
            atol,
            speed: 0.0,
            warned_phid: false,
            stop_on_divergence: g.stop_on_divergence,
            warned_phi: false,
            warned_pos: false,
            diverged: None,
            step_budget: cfg
                .ode
                .fixed_step
                .filter(|_| cfg.method.is_generalized_alpha() && !cfg.implicit.adaptive)
                .map(|h| {
                    let nominal = ((cfg.t_end - cfg.t0) / h).ceil().max(1.0);
                    ((STALL_FACTOR * nominal) as usize + STALL_SLACK, h, cfg.t0)
                }),
            stalled: None,
            warnings: Vec::new(),
            sys,
            n: sys.n_coords(),
            sink,
            rows: 0,
            sink_error: None,
            max_norm: 0.0,
            max_velocity_norm: 0.0,
            final_norm: f64::NAN,
            phi: vec![0.0; m],
            phi_t: vec![0.0; m],
            jac: vec![0.0; sys.jacobian_pattern().len()],
            phid: vec![0.0; m],
            monitors,
        }
    }
}

impl Watch<'_, '_, '_, '_> {
    /// `[P_nc, P_c]` at `(t, q, q̇)` (λ from eq. (5) only for rheonomic
    /// systems, where the constraint forces do work).
    fn power(&mut self, t: f64, q: &[f64], qd: &[f64]) -> [f64; 2] {
        let Some(b) = self.balance.as_mut() else {
            return [0.0; 2];
        };
        let p = self.sys.nonconservative_power(t, q, qd, &mut b.ws);
        let mut pc = 0.0;
        if b.rheonomic {
            if let Some(f) = self.extras.as_mut() {
                pc = if f.accelerations(t, q, qd, &mut self.qdd).is_ok() {
                    self.sys.constraint_power(q, t, f.lambda(), &mut b.ws)
                } else {
                    f64::NAN
                };
            }
        }
        [p, pc]
    }

    /// `[V_g, V_e]`: the potential of gravity and every other potential.
    fn potentials(&self, q: &[f64]) -> [f64; 2] {
        let mut v = [0.0; 2];
        let Some(b) = self.balance.as_ref() else {
            return v;
        };
        for (f, &g) in self.sys.forces().iter().zip(&b.is_gravity) {
            if let Some(e) = f.potential_energy(q) {
                v[usize::from(!g)] += e;
            }
        }
        v
    }

    /// Start the energy balance at `(t0, q0, q̇0)`.
    pub(super) fn start_balance(&mut self, t0: f64, q0: &[f64], qd0: &[f64]) {
        if !self.outputs.energy {
            return;
        }
        // λ at every step for the constraint power λᵀΦ_t (zero for
        // scleronomic joints, but a drive may be at rest at t0)
        let rheonomic = self.sys.n_constraints() > 0;
        let e0 = self.sys.mechanical_energy(q0, qd0);
        let e_parts0 = self.sys.kinetic_energy(qd0).abs() + self.sys.potential_energy(q0).abs();
        let floor = 0.5
            * self.atol
            * self.atol
            * self
                .sys
                .bodies()
                .iter()
                .map(|b| 2.0 * b.mass.abs() + b.inertia.abs())
                .sum::<f64>();
        self.balance = Some(Balance {
            e0,
            work: [0.0; 2],
            power: [0.0; 2],
            t: t0,
            max_error: 0.0,
            max_gain: 0.0,
            scale: e_parts0,
            v0: [0.0; 2],
            floor,
            e_parts0,
            quadrature_error: 0.0,
            last_slope: None,
            rheonomic,
            ws: Default::default(),
            is_gravity: self
                .sys
                .forces()
                .iter()
                .map(|f| f.name() == "gravity")
                .collect(),
        });
        let p = self.power(t0, q0, qd0);
        let v0 = self.potentials(q0);
        if let Some(b) = self.balance.as_mut() {
            b.power = p;
            b.v0 = v0;
        }
    }

    /// The balance at `(t, q, q̇)` with the works extended from the last
    /// step by the trapezoid; `accept` makes `t` the new last step.
    fn balance_at(&mut self, t: f64, q: &[f64], qd: &[f64], accept: bool) -> Option<EnergyTerms> {
        self.balance.as_ref()?;
        let pp = self.power(t, q, qd);
        let ke = self.sys.kinetic_energy(qd);
        let [vg, ve] = self.potentials(q);
        let b = self.balance.as_mut()?;
        let wp: [f64; 2] =
            std::array::from_fn(|k| b.work[k] + 0.5 * (b.power[k] + pp[k]) * (t - b.t));
        let (w, p, p_last) = (wp[0] + wp[1], pp[0] + pp[1], b.power[0] + b.power[1]);
        let err = ke + vg + ve - b.e0 - w;
        // the physical scale: |T0| + |V0| + the largest |W| (not T + V,
        // which grows with a solution that blows up)
        b.scale = b.scale.max(b.e_parts0 + w.abs());
        // and the energy actually in play: the largest kinetic energy and
        // changes of the potentials (a falling body's T, not only its T0)
        for v in [ke, (vg - b.v0[0]).abs(), (ve - b.v0[1]).abs()] {
            if v.is_finite() {
                b.scale = b.scale.max(v);
            }
        }
        if err.is_finite() {
            b.max_error = b.max_error.max(err.abs());
            b.max_gain = b.max_gain.max(err);
        }
        if accept {
            // trapezoid error of this step, h³/12 |P''| with P'' from the
            // slopes of this and the previous step
            let h = t - b.t;
            if h > 0.0 {
                let slope = (p - p_last) / h;
                if let Some((s0, h0)) = b.last_slope {
                    let curv = (slope - s0) / (0.5 * (h + h0));
                    if curv.is_finite() {
                        b.quadrature_error += h * h * h / 12.0 * curv.abs();
                    }
                }
                b.last_slope = Some((slope, h));
            }
            b.work = wp;
            b.power = pp;
            b.t = t;
        }
        Some(EnergyTerms {
            kinetic: ke,
            gravity: vg,
            elastic: ve,
            work_forces: wp[0],
            work_drives: wp[1],
            balance_error: err,
        })
    }

    pub(super) fn warn(&mut self, message: String) {
        self.sink.warning(&message);
        self.warnings.push(message);
    }

    /// The velocity-level guard at an output: ‖Φ̇‖ = ‖Φ_q q̇ + Φ_t‖ beyond
    /// `100 (rtol V + atol)`, V the largest body speed seen so far.
    fn guard_velocity(&mut self, t: f64, qd: &[f64], vn: f64) {
        let v = qd[..self.sys.n_body_coords()]
            .chunks(3)
            .map(|b| b[0].hypot(b[1]))
            .fold(0.0, f64::max);
        if v.is_finite() {
            self.speed = self.speed.max(v);
        }
        let bound = 100.0 * (self.rtol * self.speed + self.atol);
        if vn > bound && !self.warned_phid {
            self.warned_phid = true;
            self.warn(format!(
                "velocity constraint violation ‖Φ_q q̇ + Φ_t‖ = {vn:.3e} at t = {t} exceeds \
                 {bound:.3e} (100 (rtol V + atol), V = {:.3e} m/s the largest body speed): the \
                 velocities do not fit the joints; {}",
                self.speed,
                self.advice,
                t = Time(t)
            ));
        }
    }

    /// The guards of [`Guards`] after an accepted step, and (`at_output`:
    /// the interpolated states written between steps, without the drift
    /// warning) at each output.
    fn guard(&mut self, t: f64, q: &[f64], cn: f64, at_output: bool) -> ControlFlow<String> {
        if cn > self.phi_warn && !self.warned_phi && !at_output {
            self.warned_phi = true;
            self.warn(format!(
                "constraint violation ‖Φ‖ = {cn:.3e} at t = {t} exceeds {:.3e} (100 (rtol L + atol)): \
                 the solution is drifting off its constraints; {}",
                self.phi_warn, self.advice, t = Time(t)));
        }
        let pos = q[..self.sys.n_body_coords()]
            .chunks(3)
            .flat_map(|b| b[..2].iter())
            .fold(0.0, |a: f64, v| a.max(v.abs()));
        let reason = if cn > self.phi_fail && at_output {
            Some(format!(
                "constraint violation ‖Φ‖ = {cn:.3e} in the output at t = {t}, interpolated \
                 between steps, exceeds {:.3e} ({}): the step is too large for the motion \
                 between outputs; reduce the step (integrator.step or the tolerances)",
                self.phi_fail,
                self.phi_fail_why,
                t = Time(t)
            ))
        } else if cn > self.phi_fail {
            Some(format!(
                "constraint violation ‖Φ‖ = {cn:.3e} at t = {t} exceeds {:.3e} \
                 ({}): the mechanism has come apart; {}",
                self.phi_fail,
                self.phi_fail_why,
                self.advice,
                t = Time(t)
            ))
        } else if pos > self.pos_fail {
            Some(format!(
                "a position coordinate reached {pos:.3e} m at t = {t} (more than {:.1e} m): \
                 the integration is unstable — reduce the step",
                self.pos_fail,
                t = Time(t)
            ))
        } else {
            None
        };
        match reason {
            Some(r) if self.stop_on_divergence => {
                self.diverged = Some(r.clone());
                ControlFlow::Break(r)
            }
            Some(r) if !self.warned_pos => {
                self.warned_pos = true;
                self.warn(r);
                ControlFlow::Continue(())
            }
            _ => ControlFlow::Continue(()),
        }
    }
}

/// A constraint violation ‖Φ‖ above this fraction of the mechanism's size
/// (the diagonal of the box around the bodies' reference points at t0, at
/// least the largest of their coordinates) — or above 10 × ‖Φ‖ at the start
/// where that is larger — ends the run as `"diverged"` whatever the
/// tolerances: 0.25.
pub const SIZE_FRACTION: f64 = 0.25;

/// What to change when a run drifts off its constraints, naming only keys
/// the run's method and formulation accept (docs/scenarios.md).
pub(super) fn drift_advice(cfg: &RunConfig) -> String {
    let f = cfg.formulation.formulation;
    if cfg.method.is_generalized_alpha() && f == Formulation::AugmentedLagrangian {
        "reduce integrator.step or raise stabilization.penalty".into()
    } else if cfg.method.is_generalized_alpha() && !cfg.implicit.project {
        "set integrator.project = true, or reduce integrator.newton_tol or the step".into()
    } else if cfg.method.is_generalized_alpha() {
        "reduce integrator.newton_tol or the step (integrator.project is already on)".into()
    } else if cfg.method.is_index3() {
        "tighten integrator.rtol and integrator.atol".into()
    } else if f == Formulation::Penalty {
        "tighten the tolerances or raise stabilization.penalty".into()
    } else if f == Formulation::Partitioned {
        "tighten the tolerances or lower stabilization.partition_condition".into()
    } else if cfg.formulation.projection.enabled {
        "tighten the tolerances (stabilization.projection is already on), or use an \
         index-3 method"
            .into()
    } else {
        "tighten the tolerances, use Baumgarte stabilization (stabilization.alpha > 0) or \
         stabilization.projection = true, or an index-3 method"
            .into()
    }
}

/// The first non-finite number of an output row, named, or `None`.
fn first_non_finite(s: &Sample<'_>) -> Option<String> {
    let bad = |v: &[f64]| v.iter().position(|x| !x.is_finite());
    let named = |what: &str, v: Option<&[f64]>| {
        v.and_then(|v| bad(v).map(|k| format!("{what}[{k}] = {}", v[k])))
    };
    named("q", Some(s.q))
        .or_else(|| named("q̇", Some(s.qd)))
        .or_else(|| named("Φ", Some(s.phi)))
        .or_else(|| named("‖Φ‖", Some(&[s.constraint_norm])))
        .or_else(|| named("‖Φ̇‖", Some(&[s.velocity_constraint_norm])))
        .or_else(|| named("q̈", s.qdd))
        .or_else(|| named("λ", s.lambda))
        .or_else(|| named("reaction", s.reactions))
        .or_else(|| {
            s.energy.as_ref().and_then(|e| {
                [
                    ("kinetic energy", e.kinetic),
                    ("gravity potential", e.gravity),
                    ("elastic potential", e.elastic),
                    ("work of forces", e.work_forces),
                    ("work of drives", e.work_drives),
                    ("energy balance error", e.balance_error),
                ]
                .into_iter()
                .find(|(_, v)| !v.is_finite())
                .map(|(n, v)| format!("{n} = {v}"))
            })
        })
}

/// Whether the outputs need q̈ and λ at every output time.
fn o_needs_extras(o: &OutputQuantities) -> bool {
    o.accelerations || o.reactions || o.drives
}

pub(super) fn norm2(v: &[f64]) -> f64 {
    let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if n.is_finite() && n > 1e-150 {
        return n;
    }
    // the squares overflowed or underflowed: scale by the largest modulus
    let m = crate::numeric::max_abs(v);
    if m == 0.0 || !m.is_finite() || v.iter().any(|x| x.is_nan()) {
        return if v.iter().any(|x| x.is_nan()) {
            f64::NAN
        } else {
            m
        };
    }
    m * v.iter().map(|x| (x / m) * (x / m)).sum::<f64>().sqrt()
}

impl Observer for Watch<'_, '_, '_, '_> {
    fn output(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        let (q, qd) = y.split_at(self.n);
        self.sys.phi(q, t, &mut self.phi);
        self.sys.phi_t(q, t, &mut self.phi_t);
        self.sys.jacobian_values(q, t, &mut self.jac);
        self.sys.jacobian_mul(&self.jac, qd, &mut self.phid);
        for (a, b) in self.phid.iter_mut().zip(&self.phi_t) {
            *a += b;
        }
        let cn = norm2(&self.phi);
        let vn = norm2(&self.phid);
        self.guard_velocity(t, qd, vn);
        self.max_norm = self.max_norm.max(cn);
        self.max_velocity_norm = self.max_velocity_norm.max(vn);
        self.final_norm = cn;
        // the guards on the finite rows after the start (a non-finite one
        // fails below; the start's own violation is the steps' to judge)
        if self.rows > 0 && cn.is_finite() && vn.is_finite() && y.iter().all(|v| v.is_finite()) {
            if let ControlFlow::Break(r) = self.guard(t, q, cn, true) {
                return ControlFlow::Break(r);
            }
        }
        let balance = self.balance_at(t, q, qd, false);
        let mut have_extras = false;
        if let Some(f) = self
            .extras
            .as_mut()
            .filter(|_| o_needs_extras(&self.outputs))
        {
            match f.accelerations(t, q, qd, &mut self.qdd) {
                Ok(()) => {
                    have_extras = true;
                    if self.outputs.reactions {
                        self.sys.joint_reactions(
                            &self.reaction_map,
                            &self.jac,
                            f.lambda(),
                            &mut self.reactions,
                        );
                    }
                }
                Err(e) => {
                    self.qdd.fill(f64::NAN);
                    self.reactions.fill(f64::NAN);
                    if !self.warned_extras {
                        self.warned_extras = true;
                        let m = format!(
                            "accelerations and reactions at t = {t}: {e} (NaN written)",
                            t = Time(t)
                        );
                        self.warn(m);
                    }
                }
            }
        }
        let o = self.outputs;
        let lambda = match (&self.extras, have_extras) {
            (Some(f), true) if o.reactions || o.drives => Some(f.lambda()),
            _ => None,
        };
        let sample = Sample {
            t,
            q,
            qd,
            phi: &self.phi,
            constraint_norm: cn,
            velocity_constraint_norm: vn,
            qdd: o.accelerations.then_some(&self.qdd[..]),
            lambda,
            reactions: o.reactions.then_some(&self.reactions[..]),
            energy: o.energy.then(|| {
                balance.unwrap_or(EnergyTerms {
                    kinetic: f64::NAN,
                    gravity: f64::NAN,
                    elastic: f64::NAN,
                    work_forces: f64::NAN,
                    work_drives: f64::NAN,
                    balance_error: f64::NAN,
                })
            }),
        };
        if let Some(what) = first_non_finite(&sample) {
            // a non-finite number is never written: the run fails here
            let msg = format!(
                "non-finite output at t = {t}: {what} (the row is not written; the run's \
                 state or a derived quantity overflowed — check the scenario's magnitudes)",
                t = Time(t)
            );
            self.sink_error = Some(msg.clone());
            return ControlFlow::Break(msg);
        }
        match self.sink.output(&sample) {
            Ok(()) => {
                self.rows += 1;
                ControlFlow::Continue(())
            }
            Err(e) => {
                let msg = format!("writing the output at t = {t} failed: {e}", t = Time(t));
                self.sink_error = Some(msg.clone());
                ControlFlow::Break(msg)
            }
        }
    }
    fn step(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        let (q, qd) = y.split_at(self.n);
        self.sys.phi(q, t, &mut self.phi);
        let cn = norm2(&self.phi);
        self.max_norm = self.max_norm.max(cn);
        for m in self.monitors.iter_mut() {
            m.step(t, q, qd);
        }
        self.balance_at(t, q, qd, true);
        if let Some(c) = self.singular.as_mut().and_then(|s| s.step(self.sys, t, q)) {
            let advice = if self.keeps_branch {
                "this run's projection or partitioning keeps it on its branch to the tolerance; \
                 the energy balance (output.quantities = [\"energy\"]) confirms it"
            } else {
                "the solution may switch to another branch of motion with no other sign (check \
                 the energy balance, output.quantities = [\"energy\"]); use a method that keeps \
                 the branch: stabilization.projection = true, formulation = \"partitioned\" or \
                 the augmented Lagrangian (docs/constraint_methods.md)"
            };
            self.warn(format!(
                "Φ_q lost rank at t ≈ {} (rank measure {:.1e}): the mechanism passed through a \
                 singular configuration, where the equations of motion do not fix the branch; \
                 {advice}",
                Time(c.t),
                c.ratio
            ));
        }
        self.guard(t, q, cn, false)
    }
    fn progress(&mut self, t: f64, stats: &Stats) -> ControlFlow<String> {
        if let Some((budget, h, t0)) = self.step_budget {
            if stats.steps > budget {
                let r =
                    format!(
                    "the fixed step h = {h:e} s keeps being cut: {} steps ({} failed attempts) \
                     reached only t = {t} s, {budget} steps being {STALL_FACTOR} times what \
                     h needs for the whole run (mean step {:.3e} s) — Newton keeps failing \
                     here (the warnings list the first failures): the motion is too fast or \
                     the position singular for this step; reduce it, or use \
                     integrator.adaptive = true",
                    stats.steps,
                    stats.failed_steps,
                    (t - t0) / stats.steps as f64, t = Time(t));
                self.stalled = Some(r.clone());
                return ControlFlow::Break(r);
            }
        }
        self.sink.progress(t, stats)
    }
    fn warning(&mut self, message: &str) {
        self.sink.warning(message);
        self.forwarded += 1;
    }
}
