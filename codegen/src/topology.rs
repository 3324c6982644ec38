//! Topology descriptions (data) and their symbolic model.
//!
//! A [`Topology`] lists planar bodies (reference-point coordinates
//! `x, y, φ`), joints between them or the ground, and force elements. A
//! [`PlanarModel`] turns it into expressions: Φ, the Φ_q values in the
//! runtime's sparse-pattern order, Φ_t, γ (derived by differentiation,
//! `γ = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt`), the values of (Φ_qᵀλ)_q, and for
//! each force element its generalized forces and `∂g/∂q`, `∂g/∂q̇`.
//!
//! Conventions follow mbsolve's runtime (`src/constraints`, `src/forces`):
//! a body-fixed point `s` of body `b` sits at `r_b + R(φ_b) s`; on the
//! ground the point is global. Parameters (body-fixed points, stiffnesses…)
//! are run-time inputs, never baked into the code.

use crate::expr::{Ctx, Id};

/// One side of a joint or force element.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Side {
    /// The fixed frame.
    Ground,
    /// Body number `k` (coordinates `3k, 3k+1, 3k+2`).
    Body(usize),
}

impl Side {
    /// First coordinate of the body, `None` for the ground.
    pub fn offset(self) -> Option<usize> {
        match self {
            Side::Ground => None,
            Side::Body(k) => Some(3 * k),
        }
    }
    /// Body index, or −1 for the ground (the form used in generated tables).
    pub fn code(self) -> i64 {
        match self {
            Side::Ground => -1,
            Side::Body(k) => k as i64,
        }
    }
}

/// Joint kinds (mirroring mbsolve's `Revolute`, `Translational`,
/// `DriveRelativeAngle`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum JointKind {
    /// `Φ = r_i + R_i s_i − r_j − R_j s_j` (2 rows).
    /// Parameters: `s_i (2), s_j (2)`.
    Revolute,
    /// `Φ₁ = n·d`, `n = R_i J u_i`, `d = r_j + R_j s_j − r_i − R_i s_i`;
    /// `Φ₂ = φ_j − φ_i − θ₀` (2 rows).
    /// Parameters: `s_i (2), u_i (2, unit), s_j (2), θ₀`.
    Translational,
    /// `Φ = φ_j − φ_i − f(t)` (1 row). No parameters; time inputs
    /// `f(t), f'(t), f''(t)`.
    DriveAngle,
}

impl JointKind {
    /// Rows.
    pub fn n_eq(self) -> usize {
        match self {
            JointKind::Revolute | JointKind::Translational => 2,
            JointKind::DriveAngle => 1,
        }
    }
    /// Run-time parameters per joint.
    pub fn n_params(self) -> usize {
        match self {
            JointKind::Revolute => 4,
            JointKind::Translational => 7,
            JointKind::DriveAngle => 0,
        }
    }
    /// Time inputs per joint (`f, f', f''`).
    pub fn n_time_inputs(self) -> usize {
        match self {
            JointKind::DriveAngle => 3,
            _ => 0,
        }
    }
    /// Names of the parameters.
    pub fn param_names(self) -> &'static [&'static str] {
        match self {
            JointKind::Revolute => &["six", "siy", "sjx", "sjy"],
            JointKind::Translational => &["six", "siy", "uix", "uiy", "sjx", "sjy", "theta0"],
            JointKind::DriveAngle => &[],
        }
    }
    /// Lower-case name used in generated tables.
    pub fn label(self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Translational => "translational",
            JointKind::DriveAngle => "drive_angle",
        }
    }
    /// Φ_q pattern of one body side (local row, coordinate offset 0..3),
    /// in the runtime's order.
    fn side_pattern(self) -> &'static [(usize, usize)] {
        match self {
            JointKind::Revolute => &[(0, 0), (1, 1), (0, 2), (1, 2)],
            JointKind::Translational => &[(0, 0), (0, 1), (0, 2), (1, 2)],
            JointKind::DriveAngle => &[(0, 2)],
        }
    }
}

/// A joint of a topology.
#[derive(Clone, Debug, PartialEq)]
pub struct JointDesc {
    /// Name (comments only).
    pub name: String,
    /// Kind.
    pub kind: JointKind,
    /// First side.
    pub i: Side,
    /// Second side.
    pub j: Side,
}

/// Force-element kinds with symbolic laws (mirroring mbsolve's
/// `TorsionalSpringDamper` and `Drag`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ForceKind {
    /// `T = −k (φ_j − φ_i − r) − c (φ̇_j − φ̇_i)` on j, `−T` on i.
    /// Parameters: `k, c, r`. Sides `i`, `j`.
    TorsionalSpringDamper,
    /// Quadratic drag on body `i` in still fluid:
    /// `F = a_t |v_t| v_t e_t + a_a |v_a| v_a e_a`, `T = a_r |φ̇| φ̇`,
    /// `e_t = (cos φ, sin φ)`, `e_a = (−sin φ, cos φ)`.
    /// Parameters: `a_t, a_a, a_r`. Side `i` only (`j` ignored).
    Drag,
    /// Hunt–Crossley contact of the four corners `(±w/2, ±l_s/2)` of body
    /// `i` with two vertical walls `x = x_l`, `x = x_r`: per corner and wall
    /// with penetration `δ > 0`, `F_n = max(0, k_h δ^{3/2} (1 + χ δ̇))` normal
    /// to the wall and friction `−μ F_n tanh(ṗ_y / v_s)` along it, acting at
    /// the corner (mbsolve's `WallContact`). Parameters:
    /// `w/2, l_s/2, x_l, x_r, k_h, χ, μ, v_s`. Side `i` only.
    WallContact,
}

impl ForceKind {
    /// Run-time parameters per element.
    pub fn n_params(self) -> usize {
        self.param_names().len()
    }
    /// Names of the parameters.
    pub fn param_names(self) -> &'static [&'static str] {
        match self {
            ForceKind::TorsionalSpringDamper => &["k", "c", "rest"],
            ForceKind::Drag => &["at", "aa", "ar"],
            ForceKind::WallContact => &["hw", "hl", "xl", "xr", "kh", "chi", "mu", "vs"],
        }
    }
}

/// A force element of a topology.
#[derive(Clone, Debug, PartialEq)]
pub struct ForceDesc {
    /// Name (comments only).
    pub name: String,
    /// Kind.
    pub kind: ForceKind,
    /// First side (the body for one-body elements).
    pub i: Side,
    /// Second side.
    pub j: Side,
}

/// A planar multibody topology: bodies, joints and force elements.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Topology {
    /// Name (used in comments and as a default prefix).
    pub name: String,
    /// Number of bodies.
    pub n_bodies: usize,
    /// Joints in row order.
    pub joints: Vec<JointDesc>,
    /// Force elements.
    pub forces: Vec<ForceDesc>,
}

impl Topology {
    /// An empty topology with `n_bodies` bodies.
    pub fn new(name: impl Into<String>, n_bodies: usize) -> Self {
        Self {
            name: name.into(),
            n_bodies,
            ..Self::default()
        }
    }
    /// Add a joint (builder style).
    pub fn joint(mut self, name: &str, kind: JointKind, i: Side, j: Side) -> Self {
        self.joints.push(JointDesc {
            name: name.into(),
            kind,
            i,
            j,
        });
        self
    }
    /// Add a force element (builder style).
    pub fn force(mut self, name: &str, kind: ForceKind, i: Side, j: Side) -> Self {
        self.forces.push(ForceDesc {
            name: name.into(),
            kind,
            i,
            j,
        });
        self
    }
    /// Revolute joint shorthand.
    pub fn revolute(self, name: &str, i: Side, j: Side) -> Self {
        self.joint(name, JointKind::Revolute, i, j)
    }
    /// Check body references.
    pub fn validate(&self) -> Result<(), String> {
        let ok = |s: Side| match s {
            Side::Ground => true,
            Side::Body(k) => k < self.n_bodies,
        };
        for jd in &self.joints {
            if !ok(jd.i) || !ok(jd.j) || jd.i == jd.j {
                return Err(format!(
                    "joint '{}': bad bodies {:?}, {:?}",
                    jd.name, jd.i, jd.j
                ));
            }
        }
        for f in &self.forces {
            let two = f.kind == ForceKind::TorsionalSpringDamper;
            // one-body kinds (drag, contact) use side i only
            if !ok(f.i) || (two && (!ok(f.j) || f.i == f.j)) || (!two && f.i == Side::Ground) {
                return Err(format!(
                    "force '{}': bad bodies {:?}, {:?}",
                    f.name, f.i, f.j
                ));
            }
        }
        Ok(())
    }
}

/// Symbolic model of one joint.
#[derive(Clone, Debug)]
pub struct JointModel {
    /// First row.
    pub row0: usize,
    /// Φ rows.
    pub phi: Vec<Id>,
    /// Φ_q pattern `(local row, global coordinate)`, runtime order.
    pub jac_pattern: Vec<(usize, usize)>,
    /// Φ_q values in pattern order.
    pub jac: Vec<Id>,
    /// Φ_t rows.
    pub phi_t: Vec<Id>,
    /// γ rows.
    pub gamma: Vec<Id>,
    /// (Φ_qᵀλ)_q pattern `(row, col)`, `row ≥ col`, runtime order.
    pub hess_pattern: Vec<(usize, usize)>,
    /// (Φ_qᵀλ)_q values (λ = this joint's multipliers).
    pub hess: Vec<Id>,
    /// The coordinates Φ_qᵀλ touches (sorted), and its values there:
    /// `Σ_r λ_r ∂Φ_r/∂q_c` (λ = this joint's multipliers).
    pub tmul_cols: Vec<usize>,
    /// Φ_qᵀλ at `tmul_cols`.
    pub tmul: Vec<Id>,
    /// Range of this joint's parameters in the flat parameter vector.
    pub params: std::ops::Range<usize>,
    /// Range of this joint's time inputs in the flat time-input vector.
    pub time_inputs: std::ops::Range<usize>,
}

/// Symbolic model of one force element.
#[derive(Clone, Debug)]
pub struct ForceModel {
    /// Footprint coordinates (sorted, distinct).
    pub coords: Vec<usize>,
    /// Generalized force on each footprint coordinate.
    pub g: Vec<Id>,
    /// `∂g/∂q`, `k × k` row-major over the footprint.
    pub dq: Vec<Id>,
    /// `∂g/∂q̇`, `k × k` row-major over the footprint.
    pub dqd: Vec<Id>,
    /// Range of its parameters in the flat force-parameter vector.
    pub params: std::ops::Range<usize>,
}

/// The symbolic model of a topology.
#[derive(Clone, Debug)]
pub struct PlanarModel {
    /// Expressions.
    pub ctx: Ctx,
    /// The description.
    pub topology: Topology,
    /// Coordinates `x0, y0, φ0, x1, …`.
    pub q: Vec<Id>,
    /// Velocities.
    pub qd: Vec<Id>,
    /// Time.
    pub t: Id,
    /// Joint parameters, flat in joint order.
    pub p: Vec<Id>,
    /// Time inputs (`f, f', f''` per drive), flat in joint order.
    pub tf: Vec<Id>,
    /// Lagrange multipliers, one per row.
    pub lambda: Vec<Id>,
    /// Force-element parameters, flat in element order.
    pub fp: Vec<Id>,
    /// Joints.
    pub joints: Vec<JointModel>,
    /// Force elements.
    pub forces: Vec<ForceModel>,
}

struct SideSym {
    x: Id,
    y: Id,
    phi: Id,
    vx: Id,
    vy: Id,
    w: Id,
}

impl PlanarModel {
    /// Derive the model of `topo`.
    ///
    /// # Panics
    /// When the topology is invalid ([`Topology::validate`]) or a derived
    /// partial derivative falls outside the runtime's sparse pattern (a bug).
    pub fn new(topo: &Topology) -> Self {
        topo.validate().expect("invalid topology");
        let mut ctx = Ctx::new();
        let n = 3 * topo.n_bodies;
        let mut q = Vec::with_capacity(n);
        let mut qd = Vec::with_capacity(n);
        for b in 0..topo.n_bodies {
            for a in ["x", "y", "phi"] {
                q.push(ctx.var(format!("{a}{b}")));
            }
        }
        for b in 0..topo.n_bodies {
            for a in ["vx", "vy", "w"] {
                qd.push(ctx.var(format!("{a}{b}")));
            }
        }
        let t = ctx.var("t");
        ctx.set_time(t);
        let mut m = PlanarModel {
            ctx,
            topology: topo.clone(),
            q,
            qd,
            t,
            p: Vec::new(),
            tf: Vec::new(),
            lambda: Vec::new(),
            fp: Vec::new(),
            joints: Vec::new(),
            forces: Vec::new(),
        };
        let mut row0 = 0;
        for (k, jd) in topo.joints.iter().enumerate() {
            let jm = m.joint(k, jd, row0);
            row0 += jd.kind.n_eq();
            m.joints.push(jm);
        }
        for (k, fd) in topo.forces.iter().enumerate() {
            let fm = m.force(k, fd);
            m.forces.push(fm);
        }
        m
    }

    /// Number of coordinates.
    pub fn n_coords(&self) -> usize {
        self.q.len()
    }
    /// Number of constraint rows.
    pub fn n_rows(&self) -> usize {
        self.lambda.len()
    }
    /// Φ_q pattern of the whole topology (global rows), runtime order.
    pub fn jac_pattern(&self) -> Vec<(usize, usize)> {
        self.joints
            .iter()
            .flat_map(|j| j.jac_pattern.iter().map(move |&(r, c)| (j.row0 + r, c)))
            .collect()
    }
    /// (Φ_qᵀλ)_q pattern of the whole topology, joint by joint.
    pub fn hess_pattern(&self) -> Vec<(usize, usize)> {
        self.joints
            .iter()
            .flat_map(|j| j.hess_pattern.iter().copied())
            .collect()
    }
    /// All Φ rows.
    pub fn phi(&self) -> Vec<Id> {
        self.joints.iter().flat_map(|j| j.phi.clone()).collect()
    }
    /// All Φ_q values (pattern order).
    pub fn jac(&self) -> Vec<Id> {
        self.joints.iter().flat_map(|j| j.jac.clone()).collect()
    }
    /// All Φ_t rows.
    pub fn phi_t(&self) -> Vec<Id> {
        self.joints.iter().flat_map(|j| j.phi_t.clone()).collect()
    }
    /// All γ rows.
    pub fn gamma(&self) -> Vec<Id> {
        self.joints.iter().flat_map(|j| j.gamma.clone()).collect()
    }
    /// All (Φ_qᵀλ)_q values.
    pub fn hess(&self) -> Vec<Id> {
        self.joints.iter().flat_map(|j| j.hess.clone()).collect()
    }

    fn side(&mut self, s: Side) -> SideSym {
        match s.offset() {
            Some(o) => SideSym {
                x: self.q[o],
                y: self.q[o + 1],
                phi: self.q[o + 2],
                vx: self.qd[o],
                vy: self.qd[o + 1],
                w: self.qd[o + 2],
            },
            None => {
                let z = self.ctx.zero();
                SideSym {
                    x: z,
                    y: z,
                    phi: z,
                    vx: z,
                    vy: z,
                    w: z,
                }
            }
        }
    }

    /// `R(φ) s` (exactly as the runtime's `rotate`).
    pub fn rotate(&mut self, phi: Id, s: [Id; 2]) -> [Id; 2] {
        let c = &mut self.ctx;
        let (sn, cs) = (c.sin(phi), c.cos(phi));
        let a = c.mul(cs, s[0]);
        let b = c.mul(sn, s[1]);
        let x = c.sub(a, b);
        let a = c.mul(sn, s[0]);
        let b = c.mul(cs, s[1]);
        let y = c.add(a, b);
        [x, y]
    }

    /// Global position of point `s` of a side (global `s` for the ground).
    fn point(&mut self, side: Side, s: [Id; 2]) -> [Id; 2] {
        match side {
            Side::Ground => s,
            Side::Body(_) => {
                let b = self.side(side);
                let rs = self.rotate(b.phi, s);
                let x = self.ctx.add(b.x, rs[0]);
                let y = self.ctx.add(b.y, rs[1]);
                [x, y]
            }
        }
    }

    fn new_params(&mut self, prefix: &str, names: &[&str]) -> (Vec<Id>, std::ops::Range<usize>) {
        let start = self.p.len();
        let ids: Vec<Id> = names
            .iter()
            .map(|n| self.ctx.var(format!("{prefix}_{n}")))
            .collect();
        self.p.extend_from_slice(&ids);
        (ids, start..self.p.len())
    }

    fn joint(&mut self, k: usize, jd: &JointDesc, row0: usize) -> JointModel {
        let (p, params) = self.new_params(&format!("j{k}"), jd.kind.param_names());
        let tf_start = self.tf.len();
        let si = self.side(jd.i);
        let sj = self.side(jd.j);
        let phi: Vec<Id> = match jd.kind {
            JointKind::Revolute => {
                let pi = self.point(jd.i, [p[0], p[1]]);
                let pj = self.point(jd.j, [p[2], p[3]]);
                vec![self.ctx.sub(pi[0], pj[0]), self.ctx.sub(pi[1], pj[1])]
            }
            JointKind::Translational => {
                // n = R(φ_i) J u_i, J u = (−u_y, u_x)
                let mu = self.ctx.neg(p[3]);
                let n = self.rotate(si.phi, [mu, p[2]]);
                let pi = self.point(jd.i, [p[0], p[1]]);
                let pj = self.point(jd.j, [p[4], p[5]]);
                let d0 = self.ctx.sub(pj[0], pi[0]);
                let d1 = self.ctx.sub(pj[1], pi[1]);
                let a = self.ctx.mul(n[0], d0);
                let b = self.ctx.mul(n[1], d1);
                let r0 = self.ctx.add(a, b);
                let dphi = self.ctx.sub(sj.phi, si.phi);
                let r1 = self.ctx.sub(dphi, p[6]);
                vec![r0, r1]
            }
            JointKind::DriveAngle => {
                let f: Vec<Id> = (0..4).map(|d| self.ctx.var(format!("j{k}_f{d}"))).collect();
                for d in 0..3 {
                    self.ctx.set_time_derivative(f[d], f[d + 1]);
                }
                self.tf.extend_from_slice(&f[..3]);
                let dphi = self.ctx.sub(sj.phi, si.phi);
                vec![self.ctx.sub(dphi, f[0])]
            }
        };
        let time_inputs = tf_start..self.tf.len();
        let n_eq = phi.len();
        for r in 0..n_eq {
            self.lambda
                .push(self.ctx.var(format!("lambda{}", row0 + r)));
        }
        let lam = self.lambda[row0..row0 + n_eq].to_vec();

        // Touched coordinates and the runtime pattern.
        let mut jac_pattern = Vec::new();
        let mut cols = Vec::new();
        for s in [jd.i, jd.j] {
            if let Some(o) = s.offset() {
                jac_pattern.extend(jd.kind.side_pattern().iter().map(|&(r, c)| (r, o + c)));
                cols.extend([o, o + 1, o + 2]);
            }
        }
        cols.sort_unstable();
        cols.dedup();
        // Full partials over the touched columns.
        let mut d = vec![vec![self.ctx.zero(); self.q.len()]; n_eq];
        for &c in &cols {
            let col = self.ctx.diff_many(&phi, self.q[c]);
            for r in 0..n_eq {
                d[r][c] = col[r];
            }
        }
        for (r, row) in d.iter().enumerate() {
            for (c, &v) in row.iter().enumerate() {
                if self.ctx.as_const(v) != Some(0.0) {
                    assert!(
                        jac_pattern.contains(&(r, c)),
                        "joint '{}': ∂Φ{r}/∂q{c} is not in the runtime pattern",
                        jd.name
                    );
                }
            }
        }
        let jac: Vec<Id> = jac_pattern.iter().map(|&(r, c)| d[r][c]).collect();
        let phi_t = self.ctx.diff_many(&phi, self.t);

        // γ = −(c_q q̇ + c_t) with c = Φ_q q̇ + Φ_t  (= −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt)
        let mut gamma = Vec::with_capacity(n_eq);
        for r in 0..n_eq {
            let mut terms = Vec::new();
            for &c in &cols {
                let tm = self.ctx.mul(d[r][c], self.qd[c]);
                terms.push(tm);
            }
            terms.push(phi_t[r]);
            let cdot = self.ctx.sum(&terms);
            let mut terms = Vec::new();
            for &c in &cols {
                let dc = self.ctx.diff(cdot, self.q[c]);
                terms.push(self.ctx.mul(dc, self.qd[c]));
            }
            terms.push(self.ctx.diff(cdot, self.t));
            let s = self.ctx.sum(&terms);
            gamma.push(self.ctx.neg(s));
        }

        // (Φ_qᵀλ)_q[a][b] = ∂/∂q_b Σ_r λ_r ∂Φ_r/∂q_a
        let hess_pattern: Vec<(usize, usize)> = match jd.kind {
            JointKind::Revolute => [jd.i, jd.j]
                .iter()
                .filter_map(|s| s.offset().map(|o| (o + 2, o + 2)))
                .collect(),
            JointKind::DriveAngle => Vec::new(),
            JointKind::Translational => {
                let mut v = Vec::new();
                for (a, &ca) in cols.iter().enumerate() {
                    for &cb in &cols[..=a] {
                        v.push((ca.max(cb), ca.min(cb)));
                    }
                }
                v
            }
        };
        let mut hess_full = std::collections::HashMap::new();
        let mut tmul = Vec::with_capacity(cols.len());
        for &ca in &cols {
            let terms: Vec<Id> = (0..n_eq).map(|r| self.ctx.mul(lam[r], d[r][ca])).collect();
            let s = self.ctx.sum(&terms);
            tmul.push(s);
            for &cb in &cols {
                if cb <= ca {
                    let h = self.ctx.diff(s, self.q[cb]);
                    if self.ctx.as_const(h) != Some(0.0) {
                        assert!(
                            hess_pattern.contains(&(ca, cb)),
                            "joint '{}': Hessian entry ({ca}, {cb}) not in the pattern",
                            jd.name
                        );
                    }
                    hess_full.insert((ca, cb), h);
                }
            }
        }
        let hess = hess_pattern.iter().map(|rc| hess_full[rc]).collect();
        JointModel {
            row0,
            phi,
            jac_pattern,
            jac,
            phi_t,
            gamma,
            hess_pattern,
            hess,
            tmul_cols: cols,
            tmul,
            params,
            time_inputs,
        }
    }

    fn force(&mut self, k: usize, fd: &ForceDesc) -> ForceModel {
        let start = self.fp.len();
        let p: Vec<Id> = fd
            .kind
            .param_names()
            .iter()
            .map(|n| self.ctx.var(format!("f{k}_{n}")))
            .collect();
        self.fp.extend_from_slice(&p);
        let params = start..self.fp.len();
        let (coords, g): (Vec<usize>, Vec<Id>) = match fd.kind {
            ForceKind::TorsionalSpringDamper => {
                let si = self.side(fd.i);
                let sj = self.side(fd.j);
                let c = &mut self.ctx;
                let dphi = c.sub(sj.phi, si.phi);
                let drate = c.sub(sj.w, si.w);
                let e = c.sub(dphi, p[2]);
                let mk = c.neg(p[0]);
                let a = c.mul(mk, e);
                let b = c.mul(p[1], drate);
                let torque = c.sub(a, b);
                let minus = c.neg(torque);
                let mut v: Vec<(usize, Id)> = Vec::new();
                if let Some(o) = fd.i.offset() {
                    v.push((o + 2, minus));
                }
                if let Some(o) = fd.j.offset() {
                    v.push((o + 2, torque));
                }
                v.sort_by_key(|x| x.0);
                v.into_iter().unzip()
            }
            ForceKind::Drag => {
                let o = fd.i.offset().expect("drag on the ground");
                let b = self.side(fd.i);
                let c = &mut self.ctx;
                let (sn, cs) = (c.sin(b.phi), c.cos(b.phi));
                let a = c.mul(b.vx, cs);
                let bb = c.mul(b.vy, sn);
                let vt = c.add(a, bb);
                let mvx = c.neg(b.vx);
                let a = c.mul(mvx, sn);
                let bb = c.mul(b.vy, cs);
                let va = c.add(a, bb);
                let avt = c.abs(vt);
                let at_avt = c.mul(p[0], avt);
                let ft = c.mul(at_avt, vt);
                let ava = c.abs(va);
                let aa_ava = c.mul(p[1], ava);
                let fa = c.mul(aa_ava, va);
                let a = c.mul(ft, cs);
                let bb = c.mul(fa, sn);
                let gx = c.sub(a, bb);
                let a = c.mul(ft, sn);
                let bb = c.mul(fa, cs);
                let gy = c.add(a, bb);
                let aw = c.abs(b.w);
                let ar_aw = c.mul(p[2], aw);
                let gw = c.mul(ar_aw, b.w);
                (vec![o, o + 1, o + 2], vec![gx, gy, gw])
            }
            ForceKind::WallContact => {
                let o = fd.i.offset().expect("contact on the ground");
                let b = self.side(fd.i);
                let (hw, hl, kh, chi, mu, vs) = (p[0], p[1], p[4], p[5], p[6], p[7]);
                let mut terms: [Vec<Id>; 3] = [Vec::new(), Vec::new(), Vec::new()];
                for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    let c = &mut self.ctx;
                    let (cx, cy) = (c.constant(sx), c.constant(sy));
                    let s = [c.mul(cx, hw), c.mul(cy, hl)];
                    let rs = self.rotate(b.phi, s);
                    let c = &mut self.ctx;
                    let px = c.add(b.x, rs[0]);
                    let a = c.mul(b.w, rs[1]);
                    let velx = c.sub(b.vx, a);
                    let a = c.mul(b.w, rs[0]);
                    let vely = c.add(b.vy, a);
                    for (sigma, xw) in [(1.0, p[2]), (-1.0, p[3])] {
                        let sg = c.constant(sigma);
                        let gap = c.sub(xw, px);
                        let delta = c.mul(sg, gap);
                        let msg = c.constant(-sigma);
                        let ddot = c.mul(msg, velx);
                        // F_n = max(0, k_h δ √δ (1 + χ δ̇)) for δ > 0, else no contact
                        let a = c.mul(kh, delta);
                        let sq = c.sqrt(delta);
                        let a = c.mul(a, sq);
                        let one = c.one();
                        let cd = c.mul(chi, ddot);
                        let f = c.add(one, cd);
                        let a = c.mul(a, f);
                        let fnorm = c.max0(a);
                        let fnorm = c.select(delta, fnorm);
                        let r = c.div(vely, vs);
                        let th = c.tanh(r);
                        let fx = c.mul(sg, fnorm);
                        let mmu = c.neg(mu);
                        let a = c.mul(mmu, fnorm);
                        let fy = c.mul(a, th);
                        let a = c.mul(rs[0], fy);
                        let bb = c.mul(rs[1], fx);
                        let tq = c.sub(a, bb);
                        terms[0].push(fx);
                        terms[1].push(fy);
                        terms[2].push(tq);
                    }
                }
                let g: Vec<Id> = terms.iter().map(|t| self.ctx.sum(t)).collect();
                (vec![o, o + 1, o + 2], g)
            }
        };
        let kdim = coords.len();
        let mut dq = Vec::with_capacity(kdim * kdim);
        let mut dqd = Vec::with_capacity(kdim * kdim);
        for &gr in &g {
            for &c in &coords {
                dq.push(self.ctx.diff(gr, self.q[c]));
            }
        }
        for &gr in &g {
            for &c in &coords {
                dqd.push(self.ctx.diff(gr, self.qd[c]));
            }
        }
        ForceModel {
            coords,
            g,
            dq,
            dqd,
            params,
        }
    }
}
