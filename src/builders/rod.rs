//! The falling flexible rod (docs/problems.md, problem B) and the chain
//! helpers it shares with the known-answer chains of problem D
//! ([`super::known_answer`]).

use crate::constraints::Revolute;
use crate::forces::{
    Buoyancy, Check, ContactLaw, CornerState, Drag, Gravity, TorsionalSpringDamper, WallContact,
};
use crate::generated::{
    ChainKernels, ContactJacobians, DragJacobians, GroundPivot, SharedTrig, TorsionalChainJacobians,
};
use crate::model::{Body, BodyRef, ModelError, System, SystemBuilder};
use serde::{Deserialize, Serialize};

/// Every physical input of the falling-rod problem (docs/problems.md, problem B), SI units.
///
/// [`RodParams::problem_b`] gives the reference values. The rod is cut into
/// `n_segments` rigid segments of length `l_s = length / n_segments`,
/// numbered from the bottom, with mass `m = ρ w² l_s`, inertia
/// `I = m (l_s² + w²) / 12`, joined by revolute joints (paper eq. (14)) that
/// carry torsional spring–dampers `k = E w⁴ / (12 l_s)`, `c = damping_time · k`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RodParams {
    /// Rod length l \[m\] (1).
    pub length: f64,
    /// Width w of the square cross-section \[m\] (0.03).
    pub width: f64,
    /// Density ρ of the rod \[kg/m³\] (7850, steel).
    pub density: f64,
    /// Young's modulus E \[Pa\] (2.1e11).
    pub youngs_modulus: f64,
    /// Damping time c/k of the joint spring–dampers \[s\] (1e-5).
    pub damping_time: f64,
    /// Number of segments N ≥ 1 (10 in the paper).
    pub n_segments: usize,
    /// Initial tilt φ0 of the straight rod \[rad\] (0.6° = 0.6 π/180);
    /// φ = 0 is vertical, positive counter-clockwise.
    pub tilt: f64,
    /// Initial velocity (v_x, v_y) of every segment centre \[m/s\] ((0.1, 0)).
    pub initial_velocity: [f64; 2],
    /// Channel width d \[m\]: walls at x = ±d/2 (0.05).
    pub channel_width: f64,
    /// Water density ρ_w \[kg/m³\] (1000).
    pub water_density: f64,
    /// Transverse drag coefficient C_t (1.2), also used for rotational drag.
    pub drag_transverse: f64,
    /// Axial skin-friction coefficient C_f (0.02).
    pub drag_skin: f64,
    /// End-face drag coefficient C_e of the bottom segment (1.0).
    pub drag_end: f64,
    /// Hertz contact stiffness k_h \[N/m^{3/2}\] (1e9).
    pub contact_stiffness: f64,
    /// Hunt–Crossley damping factor χ \[s/m\] (0.75).
    pub contact_damping: f64,
    /// Wall friction coefficient μ (0.3).
    pub friction_coefficient: f64,
    /// Regularisation velocity v_s of the friction law \[m/s\] (1e-3).
    pub friction_velocity: f64,
    /// Magnitude of gravity g \[m/s²\] (9.81), acting along −y.
    pub gravity: f64,
    /// Whether the fluid loads (buoyancy and drag) are included.
    pub fluid: bool,
    /// Whether the wall contacts are included.
    pub contact: bool,
}

impl Default for RodParams {
    /// [`RodParams::problem_b`] with the paper's 10 segments.
    fn default() -> Self {
        Self::problem_b(10)
    }
}

/// Element name used in the parameter errors of this module.
const ROD: Check = Check {
    element: "rod parameters",
};

impl RodParams {
    /// problem B (docs/problems.md) exactly, with `n_segments` segments.
    pub fn problem_b(n_segments: usize) -> Self {
        Self {
            length: 1.0,
            width: 0.03,
            density: 7850.0,
            youngs_modulus: 2.1e11,
            damping_time: 1e-5,
            n_segments,
            tilt: 0.6_f64.to_radians(),
            initial_velocity: [0.1, 0.0],
            channel_width: 0.05,
            water_density: 1000.0,
            drag_transverse: 1.2,
            drag_skin: 0.02,
            drag_end: 1.0,
            contact_stiffness: 1e9,
            contact_damping: 0.75,
            friction_coefficient: 0.3,
            friction_velocity: 1e-3,
            gravity: 9.81,
            fluid: true,
            contact: true,
        }
    }

    /// Segment length `l_s = l / N`.
    pub fn segment_length(&self) -> f64 {
        self.length / self.n_segments as f64
    }
    /// Segment mass `m = ρ w² l_s`.
    pub fn segment_mass(&self) -> f64 {
        self.density * self.width * self.width * self.segment_length()
    }
    /// Segment inertia about its centre `I = m (l_s² + w²) / 12`.
    pub fn segment_inertia(&self) -> f64 {
        let ls = self.segment_length();
        self.segment_mass() * (ls * ls + self.width * self.width) / 12.0
    }
    /// Bending stiffness of the continuous rod `E I_A = E w⁴ / 12` \[N m²\].
    pub fn bending_stiffness(&self) -> f64 {
        self.youngs_modulus * self.width.powi(4) / 12.0
    }
    /// Joint spring stiffness `k = E w⁴ / (12 l_s)` \[N m/rad\].
    pub fn spring_stiffness(&self) -> f64 {
        self.bending_stiffness() / self.segment_length()
    }
    /// Joint damping `c = damping_time · k` \[N m s/rad\].
    pub fn spring_damping(&self) -> f64 {
        self.damping_time * self.spring_stiffness()
    }
    /// Rod axis `e_a = (−sin φ0, cos φ0)` of the initial straight rod.
    pub(super) fn axis(&self) -> [f64; 2] {
        let (s, c) = self.tilt.sin_cos();
        [-s, c]
    }
    /// Initial centre of segment `i` (0-based from the first end) of the
    /// straight rod whose first end (the bottom of segment 1) is at
    /// `first_end`: `first_end + (i + ½) l_s e_a`; `None`: the rod centre at
    /// the origin, the segments along the tilted axis.
    pub(crate) fn placed_centre(&self, first_end: Option<[f64; 2]>, i: usize) -> [f64; 2] {
        let ls = self.segment_length();
        let e = self.axis();
        match first_end {
            None => {
                let a = (i as f64 + 0.5) * ls - 0.5 * self.length;
                [a * e[0], a * e[1]]
            }
            Some(p) => {
                let a = (i as f64 + 0.5) * ls;
                [p[0] + a * e[0], p[1] + a * e[1]]
            }
        }
    }

    /// The parameters shared by every chain built from a `RodParams`.
    pub(super) fn validate_structure(&self) -> Result<(), ModelError> {
        if self.n_segments == 0 {
            return Err(ROD.fail(
                "n_segments",
                "0".into(),
                "the rod needs at least one segment",
            ));
        }
        let (l, w, d, e) = (self.length, self.width, self.density, self.youngs_modulus);
        ROD.positive(&[
            ("length", l),
            ("width", w),
            ("density", d),
            ("youngs_modulus", e),
        ])?;
        ROD.sign("damping_time", self.damping_time, false)?;
        ROD.finite("tilt", self.tilt)
    }

    /// Check every parameter used by [`add_rod`]: positive finite segment
    /// count, length, width, density, Young's modulus; non-negative damping
    /// time and gravity; finite tilt and initial velocity; with `fluid`,
    /// non-negative water density and drag coefficients; with `contact`,
    /// positive k_h and v_s, non-negative χ and μ, a channel wider than the
    /// rod and an initial state whose corners do not penetrate a wall.
    /// Errors name the field and its value.
    pub fn validate(&self) -> Result<(), ModelError> {
        self.validate_at(None)
    }

    /// [`RodParams::validate`] for the rod placed with its first end at
    /// `first_end` ([`RodParams::placed_centre`]).
    pub(crate) fn validate_at(&self, first_end: Option<[f64; 2]>) -> Result<(), ModelError> {
        self.validate_structure()?;
        if let Some(p) = first_end {
            ROD.finite_point("position", p)?;
        }
        ROD.finite_point("initial_velocity", self.initial_velocity)?;
        ROD.sign("gravity", self.gravity, false)?;
        if self.fluid {
            ROD.sign("water_density", self.water_density, false)?;
            ROD.sign("drag_transverse", self.drag_transverse, false)?;
            ROD.sign("drag_skin", self.drag_skin, false)?;
            ROD.sign("drag_end", self.drag_end, false)?;
        }
        if self.contact {
            ROD.sign("channel_width", self.channel_width, true)?;
            if self.channel_width <= self.width {
                return Err(ROD.fail(
                    "channel_width",
                    self.channel_width.to_string(),
                    &format!(
                        "the channel must be wider than the rod (width = {})",
                        self.width
                    ),
                ));
            }
            ROD.sign("contact_stiffness", self.contact_stiffness, true)?;
            ROD.sign("contact_damping", self.contact_damping, false)?;
            ROD.sign("friction_coefficient", self.friction_coefficient, false)?;
            ROD.sign("friction_velocity", self.friction_velocity, true)?;
            // Initial penetration: every corner of the straight tilted rod.
            let mut worst: Option<(f64, usize, usize, &str)> = None;
            let probe = self.contact_element(0, 0);
            let (sn, cs) = self.tilt.sin_cos();
            for i in 0..self.n_segments {
                let r = self.placed_centre(first_end, i);
                for c in 0..4 {
                    let s = probe.corner_offset(c);
                    let px = r[0] + cs * s[0] - sn * s[1];
                    for (wall, delta) in [
                        ("left", -0.5 * self.channel_width - px),
                        ("right", px - 0.5 * self.channel_width),
                    ] {
                        if delta > 0.0 && worst.is_none_or(|w| delta > w.0) {
                            worst = Some((delta, i, c, wall));
                        }
                    }
                }
            }
            if let Some((delta, i, c, wall)) = worst {
                return Err(ROD.fail(
                    "tilt",
                    format!("{} rad ({}°)", self.tilt, self.tilt.to_degrees()),
                    &format!(
                        "at the initial state corner {c} of segment {} penetrates the {wall} \
                         wall by {delta:.3e} m (channel_width = {}, length = {}, width = {})",
                        i + 1,
                        self.channel_width,
                        self.length,
                        self.width
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The drag element of segment `segment` (0: the bottom one, with the
    /// end face) on body `body`.
    fn drag_element(&self, body: usize, segment: usize) -> Drag {
        Drag {
            body,
            width: self.width,
            length: self.segment_length(),
            fluid_density: self.water_density,
            c_transverse: self.drag_transverse,
            c_skin: self.drag_skin,
            c_end: self.drag_end,
            end_face: segment == 0,
        }
    }

    /// The wall-contact element of segment `segment` (of length
    /// [`Self::segment_length`]) on body `body`: the channel's walls at
    /// `±channel_width / 2` and the Hertz law of these parameters.
    pub fn contact_element(&self, body: usize, segment: usize) -> WallContact {
        WallContact {
            body,
            segment,
            width: self.width,
            length: self.segment_length(),
            left_wall: -0.5 * self.channel_width,
            right_wall: 0.5 * self.channel_width,
            law: ContactLaw {
                stiffness: self.contact_stiffness,
                damping: self.contact_damping,
                friction: self.friction_coefficient,
                slip_velocity: self.friction_velocity,
            },
        }
    }
}

/// What a chain builder of this module added: body, joint and force-element
/// indices and the derived parameters. Force indices are those returned by
/// [`SystemBuilder::add_force`]; the builders of this module add gravity as
/// an ordinary element, so they are also the indices into
/// [`System::forces`] — unless the caller of [`add_rod`] also enables
/// [`SystemBuilder::gravity`], which inserts gravity at position 0 and
/// shifts every force index by one.
#[derive(Debug, Clone, PartialEq)]
pub struct RodInfo {
    /// Body indices of the segments (the rod: from the bottom; the pendulum:
    /// from the pivot).
    pub bodies: Vec<usize>,
    /// Joint indices of the revolute joints between consecutive segments:
    /// `joints[i]` connects `bodies[i]` and `bodies[i + 1]`.
    pub joints: Vec<usize>,
    /// Joint index of the pin to the ground (cantilever, pendulum).
    pub base_joint: Option<usize>,
    /// Segment length l_s \[m\].
    pub segment_length: f64,
    /// Segment mass \[kg\].
    pub segment_mass: f64,
    /// Segment moment of inertia about its centre \[kg m²\].
    pub segment_inertia: f64,
    /// Joint spring stiffness k \[N m/rad\] (0 without springs).
    pub spring_stiffness: f64,
    /// Joint damping c \[N m s/rad\] (0 without springs).
    pub spring_damping: f64,
    /// Force indices of the torsional spring–dampers (the cantilever's base
    /// spring first).
    pub springs: Vec<usize>,
    /// Force index of the buoyancy element.
    pub buoyancy: Option<usize>,
    /// Force indices of the drag elements, per segment.
    pub drag: Vec<usize>,
    /// Force index of the gravity element (not set by [`add_rod`]).
    pub gravity: Option<usize>,
    /// Force index of the cantilever's tip load.
    pub tip_load: Option<usize>,
    /// Force indices of the wall-contact elements, per segment.
    pub contact_elements: Vec<usize>,
    /// Copies of the wall-contact elements (same order), for
    /// [`RodInfo::corner_states`].
    pub contacts: Vec<WallContact>,
}

impl RodInfo {
    pub(super) fn empty() -> Self {
        Self {
            bodies: Vec::new(),
            joints: Vec::new(),
            base_joint: None,
            segment_length: 0.0,
            segment_mass: 0.0,
            segment_inertia: 0.0,
            spring_stiffness: 0.0,
            spring_damping: 0.0,
            springs: Vec::new(),
            buoyancy: None,
            drag: Vec::new(),
            gravity: None,
            tip_load: None,
            contact_elements: Vec::new(),
            contacts: Vec::new(),
        }
    }

    /// Number of segments.
    pub fn n_segments(&self) -> usize {
        self.bodies.len()
    }

    /// Clear `out`, then list every corner that penetrates a wall at the
    /// state `q`, `qd` (segment by segment from the bottom, corners in
    /// [`WallContact::corner_offset`] order). Empty without contact elements.
    pub fn corner_states(&self, q: &[f64], qd: &[f64], out: &mut Vec<CornerState>) {
        out.clear();
        // the segments clear of both walls (most of them) skipped here, by
        // the elements' own first test
        for c in &self.contacts {
            if !c.clear_of_walls(q[3 * c.body]) {
                c.corner_states(q, qd, out);
            }
        }
    }
}

/// How the bodies and joints of a chain are named: `Numbered("segment")`
/// gives "segment 1", "segment joint 1" (the library's rod and pendulum);
/// `Component("rod1", "segment")` gives "rod1.segment[1]", "rod1.joint[1]"
/// (scenario components, 1-based like their scenario names).
#[derive(Debug, Clone, Copy)]
pub(super) enum ChainNames<'a> {
    Numbered(&'a str),
    Component(&'a str, &'a str),
}

impl ChainNames<'_> {
    fn body(&self, i: usize) -> String {
        match self {
            ChainNames::Numbered(n) => format!("{n} {}", i + 1),
            ChainNames::Component(c, part) => format!("{c}.{part}[{}]", i + 1),
        }
    }
    fn joint(&self, i: usize) -> String {
        match self {
            ChainNames::Numbered(n) => format!("{n} joint {}", i + 1),
            ChainNames::Component(c, _) => format!("{c}.joint[{}]", i + 1),
        }
    }
}

/// Add the segments and joints of a straight chain to `builder`.
/// `centre(i)` gives segment i's centre; joint i connects the point
/// `(0, hinge)` of segment i with `(0, −hinge)` of segment i+1. Returns the
/// bodies, the joints and the joints' points `[s_i, s_j]` (for
/// [`ChainKernels::new`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn add_chain(
    builder: &mut SystemBuilder,
    name: ChainNames,
    n: usize,
    mass: f64,
    inertia: f64,
    phi: f64,
    velocity: [f64; 2],
    hinge: f64,
    centre: impl Fn(usize) -> [f64; 2],
) -> (Vec<usize>, Vec<usize>, Vec<[f64; 4]>) {
    let bodies: Vec<usize> = (0..n)
        .map(|i| {
            let c = centre(i);
            builder.add_body(
                Body::new(name.body(i), mass, inertia, [c[0], c[1], phi]).with_velocity([
                    velocity[0],
                    velocity[1],
                    0.0,
                ]),
            )
        })
        .collect();
    let joints = bodies
        .windows(2)
        .enumerate()
        .map(|(i, b)| {
            builder.add_constraint(Revolute::new(
                name.joint(i),
                BodyRef::Body(b[0]),
                [0.0, hinge],
                BodyRef::Body(b[1]),
                [0.0, -hinge],
            ))
        })
        .collect();
    let points = vec![[0.0, hinge, 0.0, -hinge]; n.saturating_sub(1)];
    (bodies, joints, points)
}

/// Attach the generated chain kernels ([`ChainKernels`]) to the chain's
/// joints (and a ground pivot added right after them): the builder knows
/// the topology, so nothing has to be recognised. Returns the kernels'
/// memo of sines and cosines, for force kernels on the same bodies.
pub(super) fn attach_chain_kernels(
    builder: &mut SystemBuilder,
    bodies: &[usize],
    joints: &[usize],
    points: &[[f64; 4]],
    pivot: Option<(usize, GroundPivot)>,
) -> Option<SharedTrig> {
    let first = joints.first().copied().or(pivot.map(|p| p.0));
    let last = pivot.map(|p| p.0).or(joints.last().copied());
    let (Some(a), Some(b), Some(&body0)) = (first, last, bodies.first()) else {
        return None;
    };
    let kernels = ChainKernels::new(body0, points, pivot.map(|p| p.1));
    let trig = kernels.shared_trig();
    builder.attach_kernels(a..b + 1, Box::new(kernels));
    Some(trig)
}

/// Add the falling rod of problem B (docs/problems.md) to `builder`.
///
/// Adds, after validating `params` ([`RodParams::validate`]):
/// * `N` segment bodies numbered from the bottom ("segment 1" … "segment N"):
///   mass `ρ w² l_s`, inertia `m (l_s² + w²)/12`, body-frame y along the rod,
///   ends at local `(0, ∓l_s/2)`;
/// * `N − 1` revolute joints, eq. (14): top of segment i = bottom of i+1;
/// * a [`TorsionalSpringDamper`] in every joint, `k = E w⁴/(12 l_s)`,
///   `c = damping_time · k`;
/// * with `params.fluid`: one [`Buoyancy`] element for all segments and a
///   [`Drag`] per segment (end-face drag on the bottom one);
/// * with `params.contact`: a [`WallContact`] per segment, walls at `±d/2`.
///
/// Initial state: straight rod at tilt φ0 with its centre at the origin,
/// every centre moving at `initial_velocity`, `φ̇ = 0` (consistent with the
/// joints). Gravity is *not* added (it is system-wide): use [`build_rod`],
/// or add a [`Gravity`] element / [`SystemBuilder::gravity`] with
/// `(0, −params.gravity)` yourself.
pub fn add_rod(builder: &mut SystemBuilder, params: &RodParams) -> Result<RodInfo, ModelError> {
    add_rod_with(builder, params, ChainNames::Numbered("segment"), None)
}

/// [`add_rod`] as a named component placed with its first end (the bottom
/// end of segment 1) at `first_end` (`None`: the rod centre at the origin,
/// as [`add_rod`]); the rod points along `(−sin φ0, cos φ0)`, φ0 =
/// `params.tilt`. Segments are named `"{name}.segment[k]"`, joints
/// `"{name}.joint[k]"`, k = 1 … N from the first end (the scenario's
/// `[[rod]]`, docs/scenarios.md).
pub fn add_named_rod(
    builder: &mut SystemBuilder,
    params: &RodParams,
    name: &str,
    first_end: Option<[f64; 2]>,
) -> Result<RodInfo, ModelError> {
    add_rod_with(
        builder,
        params,
        ChainNames::Component(name, "segment"),
        first_end,
    )
}

fn add_rod_with(
    builder: &mut SystemBuilder,
    params: &RodParams,
    names: ChainNames,
    first_end: Option<[f64; 2]>,
) -> Result<RodInfo, ModelError> {
    params.validate_at(first_end)?;
    let p = params;
    let n = p.n_segments;
    let ls = p.segment_length();
    let (m, inertia) = (p.segment_mass(), p.segment_inertia());
    let (bodies, joints, points) = add_chain(
        builder,
        names,
        n,
        m,
        inertia,
        p.tilt,
        p.initial_velocity,
        0.5 * ls,
        |i| p.placed_centre(first_end, i),
    );
    let trig = attach_chain_kernels(builder, &bodies, &joints, &points, None);
    let mut info = RodInfo::empty();
    info.segment_length = ls;
    info.segment_mass = m;
    info.segment_inertia = inertia;
    info.spring_stiffness = p.spring_stiffness();
    info.spring_damping = p.spring_damping();
    info.springs = bodies
        .windows(2)
        .map(|b| {
            builder.add_force(TorsionalSpringDamper::new(
                BodyRef::Body(b[0]),
                BodyRef::Body(b[1]),
                info.spring_stiffness,
                info.spring_damping,
            ))
        })
        .collect();
    if p.fluid {
        let volume = p.width * p.width * ls;
        info.buoyancy = Some(builder.add_force(Buoyancy {
            fluid_density: p.water_density,
            gravity: p.gravity,
            bodies: bodies.iter().map(|&b| (b, volume)).collect(),
        }));
        info.drag = bodies
            .iter()
            .enumerate()
            .map(|(i, &b)| builder.add_force(p.drag_element(b, i)))
            .collect();
    }
    if p.contact {
        for (i, &b) in bodies.iter().enumerate() {
            let c = p.contact_element(b, i);
            info.contact_elements.push(builder.add_force(c.clone()));
            info.contacts.push(c);
        }
    }
    attach_force_kernels(builder, &bodies, &info, p, trig);
    info.bodies = bodies;
    info.joints = joints;
    Ok(info)
}

/// Attach [`TorsionalChainJacobians`] to the torsional spring–dampers
/// (stiffness and damping of `info`) between consecutive `bodies`: the
/// `bodies.len() − 1` force elements from id `first` on, which must couple
/// `bodies[k]` and `bodies[k + 1]` in that order.
pub(super) fn attach_spring_chain_kernels(
    builder: &mut SystemBuilder,
    bodies: &[usize],
    first: usize,
    info: &RodInfo,
) {
    let Some(&body0) = bodies.first() else {
        return;
    };
    let springs: Vec<TorsionalSpringDamper> = bodies
        .windows(2)
        .map(|b| {
            TorsionalSpringDamper::new(
                BodyRef::Body(b[0]),
                BodyRef::Body(b[1]),
                info.spring_stiffness,
                info.spring_damping,
            )
        })
        .collect();
    builder.attach_force_kernels(
        first..first + springs.len(),
        Box::new(TorsionalChainJacobians::new(body0, &springs)),
    );
}

/// Attach the generated force-Jacobian kernels of the rod's springs, drags
/// and contacts (each a contiguous run of elements on consecutive bodies);
/// the drag takes its sines and cosines from the chain kernels' memo
/// `trig` when there is one.
fn attach_force_kernels(
    builder: &mut SystemBuilder,
    bodies: &[usize],
    info: &RodInfo,
    p: &RodParams,
    trig: Option<SharedTrig>,
) {
    let range = |ids: &[usize]| ids.first().map(|&a| a..a + ids.len());
    let Some(&body0) = bodies.first() else {
        return;
    };
    if let Some(&first) = info.springs.first() {
        attach_spring_chain_kernels(builder, bodies, first, info);
    }
    if let Some(r) = range(&info.drag) {
        let drags: Vec<Drag> = bodies
            .iter()
            .enumerate()
            .map(|(i, &b)| p.drag_element(b, i))
            .collect();
        let mut kernels = DragJacobians::new(body0, &drags);
        if let Some(t) = trig {
            kernels = kernels.with_trig(t);
        }
        builder.attach_force_kernels(r, Box::new(kernels));
    }
    if let Some(r) = range(&info.contact_elements) {
        builder.attach_force_kernels(r, Box::new(ContactJacobians::new(body0, &info.contacts)));
    }
}

/// The standalone falling rod of problem B (docs/problems.md): [`add_rod`] plus a
/// [`Gravity`] element `(0, −g)` on every segment (omitted when g = 0).
pub fn build_rod(params: &RodParams) -> Result<(System, RodInfo), ModelError> {
    let mut builder = SystemBuilder::new();
    let mut info = add_rod(&mut builder, params)?;
    if params.gravity != 0.0 {
        info.gravity = Some(
            builder.add_force(Gravity {
                g: [0.0, -params.gravity],
                bodies: info
                    .bodies
                    .iter()
                    .map(|&b| (b, info.segment_mass))
                    .collect(),
            }),
        );
    }
    Ok((builder.build()?, info))
}
