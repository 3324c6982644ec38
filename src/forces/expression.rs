//! Loads given by user expressions (docs/expressions.md): a force at a body point, a
//! torque, or a force along the line between two points, each a function of
//! time and of the coordinates and velocities of named bodies, written in the
//! expression language of `mbsolve-codegen` (docs/expressions.md).
//!
//! The whole generalized-force vector g is built symbolically in one DAG —
//! the expressions, the point positions `r + R(φ) s`, the line direction —
//! so ∂g/∂q and ∂g/∂q̇ are exact symbolic derivatives (chain rule included)
//! and are compiled with g into one allocation-free [`Tape`].

use super::{ForceElement, ForceJacobians};
use mbsolve_codegen::{parse, Ctx, Id, ParseError, Tape};
use std::sync::Mutex;

mod joint;

/// Why an expression load cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum ExpressionError {
    /// An expression does not parse (or names something unknown).
    #[error("expression load '{load}', {field} = \"{text}\": {source}")]
    Parse {
        /// The load.
        load: String,
        /// Which expression (`fx`, `fy`, `torque`, `force`).
        field: String,
        /// The text.
        text: String,
        /// The parser's error (with byte position).
        source: Box<ParseError>,
    },
    /// A body name not given to the builder.
    #[error("expression load '{load}': unknown body '{body}'")]
    UnknownBody {
        /// The load.
        load: String,
        /// The name.
        body: String,
    },
    /// A non-finite point coordinate.
    #[error("expression load '{load}': point {point:?} is not finite")]
    BadPoint {
        /// The load.
        load: String,
        /// The point.
        point: [f64; 2],
    },
}

/// Position, velocity and local body number of a point, symbolically.
type PointExpr = ([Id; 2], [Id; 2], Option<usize>);

/// One end of a line force: a body-fixed point (body name, point in the body
/// frame) or a fixed point of the ground (`body = None`, global coordinates).
#[derive(Clone, Debug)]
pub struct LinePoint {
    /// Body name, `None` for the ground.
    pub body: Option<String>,
    /// The point (body frame, or global for the ground).
    pub point: [f64; 2],
}

/// Builder of an [`ExpressionLoad`]: the name → coordinate binding (the
/// resolver the scenario loader calls) and the load terms.
///
/// Variables in expressions: `t` \[s\]; for every body `B` given to
/// [`ExpressionLoadBuilder::new`]: `B.x`, `B.y` \[m\], `B.phi` \[rad\],
/// `B.vx`, `B.vy` \[m/s\], `B.omega` \[rad/s\]. In a line force also
/// `length` \[m\] and `length_rate` \[m/s\] of the line.
#[derive(Debug)]
pub struct ExpressionLoadBuilder {
    name: String,
    ctx: Ctx,
    /// Every name a body is read by, with its local index (into `bodies`).
    names: Vec<(String, usize)>,
    bodies: Vec<usize>,
    t: Id,
    q: Vec<Id>,
    qd: Vec<Id>,
    g: Vec<Id>,
    /// Controller states read: (name, coordinate w, variable z = ẇ,
    /// generalized force on w = ż).
    states: Vec<(String, usize, Id, Id)>,
}

impl ExpressionLoadBuilder {
    /// A load named `name` that may read the bodies `bodies` (name, body
    /// index); its Jacobian footprint is their coordinates.
    /// Bodies are ordered by index (so the footprint is sorted); a body
    /// given under several names (aliases such as `arm.last` and
    /// `arm.link[3]`) is one body, readable by each of them.
    pub fn new(name: &str, bodies: &[(&str, usize)]) -> Self {
        let mut aliases = bodies.to_vec();
        aliases.sort_by_key(|b| b.1);
        let mut bodies = aliases.clone();
        bodies.dedup_by_key(|b| b.1);
        let mut ctx = Ctx::new();
        let t = ctx.var("t");
        ctx.set_time(t);
        let (mut q, mut qd) = (Vec::new(), Vec::new());
        for (n, _) in &bodies {
            for c in ["x", "y", "phi"] {
                q.push(ctx.var(format!("{n}.{c}")));
            }
        }
        for (n, _) in &bodies {
            for c in ["vx", "vy", "omega"] {
                qd.push(ctx.var(format!("{n}.{c}")));
            }
        }
        let zero = ctx.zero();
        ExpressionLoadBuilder {
            name: name.into(),
            g: vec![zero; q.len()],
            ctx,
            names: aliases
                .iter()
                .map(|a| {
                    let k = bodies.iter().position(|b| b.1 == a.1).unwrap_or_default();
                    (a.0.to_string(), k)
                })
                .collect(),
            bodies: bodies.iter().map(|b| b.1).collect(),
            t,
            q,
            qd,
            states: Vec::new(),
        }
    }

    /// Let the expressions read the controller states `states` (name,
    /// coordinate w of [`crate::model::SystemBuilder::add_state`]) by
    /// name: the variable is z = ẇ; they join the Jacobian footprint.
    pub fn with_states(mut self, states: &[(&str, usize)]) -> Self {
        for &(n, w) in states {
            if !self.states.iter().any(|s| s.1 == w) {
                let z = self.ctx.var(n);
                let zero = self.ctx.zero();
                self.states.push((n.to_string(), w, z, zero));
            }
        }
        self
    }

    /// The derivative ż \[unit of z per s\] of the controller state `state`
    /// (given to [`ExpressionLoadBuilder::with_states`]): the generalized
    /// force on its coordinate w.
    pub fn state_rate(mut self, state: &str, rate: &str) -> Result<Self, ExpressionError> {
        let Some(k) = self.states.iter().position(|s| s.0 == state) else {
            return Err(ExpressionError::UnknownBody {
                load: self.name.clone(),
                body: state.into(),
            });
        };
        let f = self.parse("derivative", rate, &[])?;
        self.states[k].3 = self.ctx.add(self.states[k].3, f);
        Ok(self)
    }

    fn local(&self, body: &str) -> Result<usize, ExpressionError> {
        self.names
            .iter()
            .find(|n| n.0 == body)
            .map(|n| n.1)
            .ok_or(ExpressionError::UnknownBody {
                load: self.name.clone(),
                body: body.into(),
            })
    }

    /// Resolve a variable name (see the type's documentation); `extra` are
    /// term-local names.
    fn parse(
        &mut self,
        field: &str,
        text: &str,
        extra: &[(&str, Id)],
    ) -> Result<Id, ExpressionError> {
        let (names, q, qd, t) = (&self.names, &self.q, &self.qd, self.t);
        let states = &self.states;
        parse(&mut self.ctx, text, |n, _| {
            if n == "t" {
                return Some(t);
            }
            if let Some(&(_, id)) = extra.iter().find(|e| e.0 == n) {
                return Some(id);
            }
            if let Some(s) = states.iter().find(|s| s.0 == n) {
                return Some(s.2);
            }
            let (b, c) = n.rsplit_once('.')?;
            let k = names.iter().find(|m| m.0 == b)?.1;
            match c {
                "x" => Some(q[3 * k]),
                "y" => Some(q[3 * k + 1]),
                "phi" => Some(q[3 * k + 2]),
                "vx" => Some(qd[3 * k]),
                "vy" => Some(qd[3 * k + 1]),
                "omega" => Some(qd[3 * k + 2]),
                _ => None,
            }
        })
        .map_err(|source| ExpressionError::Parse {
            load: self.name.clone(),
            field: field.into(),
            text: text.into(),
            source: Box::new(source),
        })
    }

    fn check_point(&self, p: [f64; 2]) -> Result<(), ExpressionError> {
        if p.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(ExpressionError::BadPoint {
                load: self.name.clone(),
                point: p,
            })
        }
    }

    /// Global position `r + R(φ) s` and velocity `ṙ + ω J R(φ) s` of a point,
    /// symbolically; ground points are constants.
    fn point(&mut self, p: &LinePoint) -> Result<PointExpr, ExpressionError> {
        self.check_point(p.point)?;
        let c = &mut self.ctx;
        let (sx, sy) = (c.constant(p.point[0]), c.constant(p.point[1]));
        let Some(b) = &p.body else {
            let z = c.zero();
            return Ok(([sx, sy], [z, z], None));
        };
        let k = self.local(b)?;
        let c = &mut self.ctx;
        let (co, si) = (c.cos(self.q[3 * k + 2]), c.sin(self.q[3 * k + 2]));
        let (a, bb) = (c.mul(co, sx), c.mul(si, sy));
        let rsx = c.sub(a, bb);
        let (a, bb) = (c.mul(si, sx), c.mul(co, sy));
        let rsy = c.add(a, bb);
        let px = c.add(self.q[3 * k], rsx);
        let py = c.add(self.q[3 * k + 1], rsy);
        let w = self.qd[3 * k + 2];
        let (a, bb) = (c.mul(w, rsy), c.mul(w, rsx));
        let vx = c.sub(self.qd[3 * k], a);
        let vy = c.add(self.qd[3 * k + 1], bb);
        Ok(([px, py], [vx, vy], Some(k)))
    }

    /// Add the force `f` (global components) at global point `p` of local
    /// body `k` to g: `[f_x, f_y, (p − r) × f]`.
    fn add_point_force(&mut self, k: usize, p: [Id; 2], f: [Id; 2]) {
        let c = &mut self.ctx;
        let rx = c.sub(p[0], self.q[3 * k]);
        let ry = c.sub(p[1], self.q[3 * k + 1]);
        let (a, b) = (c.mul(rx, f[1]), c.mul(ry, f[0]));
        let m = c.sub(a, b);
        for (i, v) in [f[0], f[1], m].into_iter().enumerate() {
            self.g[3 * k + i] = c.add(self.g[3 * k + i], v);
        }
    }

    /// The force `f u` at the point `plus.1` of body `plus.0` and `−f u` at
    /// `minus.1` of body `minus.0` (`None`: the ground, which takes nothing).
    fn add_force_pair(
        &mut self,
        f: Id,
        u: [Id; 2],
        plus: (Option<usize>, [Id; 2]),
        minus: (Option<usize>, [Id; 2]),
    ) {
        let c = &mut self.ctx;
        let (fx, fy) = (c.mul(f, u[0]), c.mul(f, u[1]));
        if let (Some(k), p) = plus {
            self.add_point_force(k, p, [fx, fy]);
        }
        if let (Some(k), p) = minus {
            let c = &mut self.ctx;
            let (nx, ny) = (c.neg(fx), c.neg(fy));
            self.add_point_force(k, p, [nx, ny]);
        }
    }

    /// A force `(fx, fy)` in the global frame \[N\] at the body-fixed point
    /// `point` of `body`.
    pub fn force(
        mut self,
        body: &str,
        point: [f64; 2],
        fx: &str,
        fy: &str,
    ) -> Result<Self, ExpressionError> {
        let pt = LinePoint {
            body: Some(body.into()),
            point,
        };
        let (p, _, k) = self.point(&pt)?;
        let fx = self.parse("fx", fx, &[])?;
        let fy = self.parse("fy", fy, &[])?;
        self.add_point_force(k.expect("body point"), p, [fx, fy]);
        Ok(self)
    }

    /// A torque \[N m\] (counter-clockwise positive) on `body`.
    pub fn torque(mut self, body: &str, torque: &str) -> Result<Self, ExpressionError> {
        let k = self.local(body)?;
        let m = self.parse("torque", torque, &[])?;
        self.g[3 * k + 2] = self.ctx.add(self.g[3 * k + 2], m);
        Ok(self)
    }

    /// A scalar force \[N\] along the line between `a` and `b`, positive in
    /// tension (pulling the points together, as a stretched spring): `+f u`
    /// on `a`, `−f u` on `b`, `u = (p_b − p_a)/length`. The expression may
    /// use `length` and `length_rate` (= `u · (v_b − v_a)`).
    pub fn line_force(
        mut self,
        a: &LinePoint,
        b: &LinePoint,
        force: &str,
    ) -> Result<Self, ExpressionError> {
        let (pa, va, ka) = self.point(a)?;
        let (pb, vb, kb) = self.point(b)?;
        let c = &mut self.ctx;
        let dx = c.sub(pb[0], pa[0]);
        let dy = c.sub(pb[1], pa[1]);
        let (dx2, dy2) = (c.powi(dx, 2), c.powi(dy, 2));
        let l2 = c.add(dx2, dy2);
        let len = c.sqrt(l2);
        let ux = c.div(dx, len);
        let uy = c.div(dy, len);
        let dvx = c.sub(vb[0], va[0]);
        let dvy = c.sub(vb[1], va[1]);
        let (a1, a2) = (c.mul(ux, dvx), c.mul(uy, dvy));
        let rate = c.add(a1, a2);
        let f = self.parse("force", force, &[("length", len), ("length_rate", rate)])?;
        self.add_force_pair(f, [ux, uy], (ka, pa), (kb, pb));
        Ok(self)
    }

    /// Differentiate and compile.
    pub fn build(mut self) -> ExpressionLoad {
        // coordinates: the bodies' (x, y, φ each), then the states' w
        let g: Vec<Id> = self
            .g
            .iter()
            .copied()
            .chain(self.states.iter().map(|s| s.3))
            .collect();
        let n = g.len();
        let mut outs = g.clone();
        // ∂g/∂q: the bodies' positions (nothing reads a state's w)
        for v in self.q.clone() {
            let d = self.ctx.diff_many(&g, v);
            outs.extend(d);
        }
        let zero = self.ctx.zero();
        outs.extend(std::iter::repeat_n(zero, n * self.states.len()));
        // ∂g/∂q̇: the bodies' velocities, then the states z = ẇ
        let zs: Vec<Id> = self.states.iter().map(|s| s.2).collect();
        for v in self.qd.clone().into_iter().chain(zs) {
            let d = self.ctx.diff_many(&g, v);
            outs.extend(d);
        }
        // outs = g (n), then column blocks ∂g/∂v for v in q, then q̇.
        let tape = Tape::new(&self.ctx, &outs);
        let coords: Vec<usize> = self
            .bodies
            .iter()
            .flat_map(|&b| [3 * b, 3 * b + 1, 3 * b + 2])
            .chain(self.states.iter().map(|s| s.1))
            .collect();
        // where each variable of the tape comes from
        let nb = self.q.len();
        let mut fill = Vec::with_capacity(2 * nb + self.states.len());
        let number = |id: Id| self.ctx.var_number(id).expect("a variable");
        for (i, &c) in coords[..nb].iter().enumerate() {
            fill.push((number(self.q[i]), false, c));
            fill.push((number(self.qd[i]), true, c));
        }
        for s in &self.states {
            fill.push((number(s.2), true, s.1));
        }
        let n_vars = self.ctx.n_vars();
        ExpressionLoad {
            name: self.name,
            coords,
            time_var: number(self.t),
            fill,
            scratch: Mutex::new(Scratch {
                tape,
                vars: vec![0.0; n_vars],
                out: vec![0.0; n + 2 * n * n],
            }),
        }
    }
}

#[derive(Debug)]
struct Scratch {
    tape: Tape,
    vars: Vec<f64>,
    out: Vec<f64>,
}

/// A load from expressions; build with [`ExpressionLoadBuilder`].
/// Exact symbolic Jacobians; evaluation allocates nothing.
#[derive(Debug)]
pub struct ExpressionLoad {
    name: String,
    /// Global coordinates of the named bodies (local order x, y, φ per
    /// body), then of the states read.
    coords: Vec<usize>,
    /// The tape's variable number of t.
    time_var: usize,
    /// Every other variable of the tape: (its number, from q̇ rather than
    /// q, the coordinate).
    fill: Vec<(usize, bool, usize)>,
    scratch: Mutex<Scratch>,
}

impl ExpressionLoad {
    /// Evaluate the tape at (t, q, q̇); returns the locked scratch.
    fn run(&self, t: f64, q: &[f64], qd: &[f64]) -> std::sync::MutexGuard<'_, Scratch> {
        let mut s = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        let Scratch { tape, vars, out } = &mut *s;
        vars[self.time_var] = t;
        for &(k, velocity, c) in &self.fill {
            vars[k] = if velocity { qd[c] } else { q[c] };
        }
        tape.eval(vars, out);
        s
    }
}

impl ForceElement for ExpressionLoad {
    fn name(&self) -> String {
        format!("expression load '{}'", self.name)
    }
    fn coordinates(&self) -> Vec<usize> {
        let mut c = self.coords.clone();
        c.sort_unstable();
        c.dedup();
        c
    }
    fn jacobian_coordinates(&self) -> Vec<usize> {
        self.coords.clone()
    }
    fn add_forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        let s = self.run(t, q, qd);
        for (i, &c) in self.coords.iter().enumerate() {
            g[c] += s.out[i];
        }
    }
    fn add_jacobians(&self, t: f64, q: &[f64], qd: &[f64], out: ForceJacobians<'_>) {
        let ForceJacobians { dq, dqd, .. } = out;
        let s = self.run(t, q, qd);
        let n = self.coords.len();
        for col in 0..n {
            for row in 0..n {
                dq[row * n + col] += s.out[n + col * n + row];
                dqd[row * n + col] += s.out[n + n * n + col * n + row];
            }
        }
    }
}
