//! The known-answer chains of problem D (docs/problems.md): the
//! finite-segment cantilever and the N-link pendulum.

use super::rod::{add_chain, attach_chain_kernels, ChainNames, RodInfo, RodParams};
use crate::constraints::Revolute;
use crate::forces::Check;
use crate::forces::{AppliedForce, Gravity, TorsionalSpringDamper};
use crate::generated::GroundPivot;
use crate::model::{BodyRef, ModelError, System, SystemBuilder, TimeFunction};

/// The finite-segment cantilever of problem D (docs/problems.md).
///
/// The rod of `params` (length, width, density, Young's modulus, damping
/// time, segment count and tilt are used) stands straight along the
/// direction of `params.tilt` (φ = 0: vertical, pointing up) with the bottom
/// end of segment 1 pinned to the ground at the origin by a revolute joint
/// and a [`TorsionalSpringDamper`] of the same `k`, `c` as the other joints
/// (relaxed in the straight state). A constant force `tip_load` `(F_x, F_y)`,
/// fixed in the global frame, acts at the top end of segment N (omitted when
/// zero). No fluid, contact or gravity; the initial state is at rest.
///
/// Euler–Bernoulli limits: tip deflection `P l³ / (3 E I_A)`,
/// `ω_n = (β_n l)² sqrt(E I_A / (ρ A l⁴))`, `I_A = w⁴/12`, `A = w²`.
pub fn cantilever(params: &RodParams, tip_load: [f64; 2]) -> Result<(System, RodInfo), ModelError> {
    let mut builder = SystemBuilder::new();
    let info = add_cantilever(&mut builder, params, tip_load)?;
    Ok((builder.build()?, info))
}

/// [`cantilever`] added to `builder` (its bodies and joints after those
/// already there), with its kernels attached to its own ranges.
pub fn add_cantilever(
    builder: &mut SystemBuilder,
    params: &RodParams,
    tip_load: [f64; 2],
) -> Result<RodInfo, ModelError> {
    params.validate_structure()?;
    Check {
        element: "cantilever",
    }
    .finite_point("tip_load", tip_load)?;
    let p = params;
    let n = p.n_segments;
    let ls = p.segment_length();
    let e = p.axis();
    let (m, inertia) = (p.segment_mass(), p.segment_inertia());
    let (bodies, joints, points) = add_chain(
        builder,
        ChainNames::Numbered("segment"),
        n,
        m,
        inertia,
        p.tilt,
        [0.0, 0.0],
        0.5 * ls,
        |i| {
            let a = (i as f64 + 0.5) * ls;
            [a * e[0], a * e[1]]
        },
    );
    let mut info = RodInfo::empty();
    let pin = (&bodies[..], &joints[..], &points[..]);
    info.base_joint = Some(pin_to_ground(builder, "cantilever base", pin, -0.5 * ls));
    info.segment_length = ls;
    info.segment_mass = m;
    info.segment_inertia = inertia;
    info.spring_stiffness = p.spring_stiffness();
    info.spring_damping = p.spring_damping();
    info.springs.push(builder.add_force(TorsionalSpringDamper {
        body_i: BodyRef::Ground,
        body_j: BodyRef::Body(bodies[0]),
        k: info.spring_stiffness,
        c: info.spring_damping,
        rest_angle: p.tilt,
    }));
    for b in bodies.windows(2) {
        info.springs
            .push(builder.add_force(TorsionalSpringDamper::new(
                BodyRef::Body(b[0]),
                BodyRef::Body(b[1]),
                info.spring_stiffness,
                info.spring_damping,
            )));
    }
    if tip_load != [0.0, 0.0] {
        info.tip_load = Some(builder.add_force(AppliedForce {
            name: "tip load".into(),
            body: bodies[n - 1],
            point: [0.0, 0.5 * ls],
            fx: TimeFunction::Constant(tip_load[0]),
            fy: TimeFunction::Constant(tip_load[1]),
        }));
    }
    info.bodies = bodies;
    info.joints = joints;
    Ok(info)
}

/// The conservative N-link pendulum of problem D (docs/problems.md): `n` uniform slender
/// links (length `link_length`, mass `link_mass`, inertia `m l²/12`), body
/// frame y along the link with ends at local `(0, ∓l/2)`, numbered from the
/// pivot: the top end of link 1 is pinned to the ground at the origin, the
/// bottom end of link i to the top end of link i+1. No springs, drag or
/// contact; a [`Gravity`] element `(0, −gravity)` (omitted when 0).
///
/// Initial state: a straight chain at rest, every `φ_i = initial_angle`
/// (φ = 0 hangs straight down; positive swings the chain towards +x).
pub fn n_link_pendulum(
    n: usize,
    link_length: f64,
    link_mass: f64,
    initial_angle: f64,
    gravity: f64,
) -> Result<(System, RodInfo), ModelError> {
    const PEND: Check = Check {
        element: "n-link pendulum",
    };
    if n == 0 {
        return Err(PEND.fail("n", "0".into(), "the pendulum needs at least one link"));
    }
    PEND.positive(&[("link_length", link_length), ("link_mass", link_mass)])?;
    PEND.sign("gravity", gravity, false)?;
    PEND.finite("initial_angle", initial_angle)?;
    let (s, c) = initial_angle.sin_cos();
    let down = [s, -c]; // −e_a: from the top end towards the bottom end
    let inertia = link_mass * link_length * link_length / 12.0;
    let mut builder = SystemBuilder::new();
    // Link i's bottom (0, −l/2) meets link i+1's top (0, +l/2): joint
    // "hinge" −l/2 on the upper link, +l/2 on the lower.
    let (bodies, joints, points) = add_chain(
        &mut builder,
        ChainNames::Numbered("link"),
        n,
        link_mass,
        inertia,
        initial_angle,
        [0.0, 0.0],
        -0.5 * link_length,
        |i| {
            let a = (i as f64 + 0.5) * link_length;
            [a * down[0], a * down[1]]
        },
    );
    let mut info = RodInfo::empty();
    let pin = (&bodies[..], &joints[..], &points[..]);
    info.base_joint = Some(pin_to_ground(
        &mut builder,
        "pendulum pivot",
        pin,
        0.5 * link_length,
    ));
    if gravity != 0.0 {
        info.gravity = Some(builder.add_force(Gravity {
            g: [0.0, -gravity],
            bodies: bodies.iter().map(|&b| (b, link_mass)).collect(),
        }));
    }
    info.segment_length = link_length;
    info.segment_mass = link_mass;
    info.segment_inertia = inertia;
    info.bodies = bodies;
    info.joints = joints;
    Ok((builder.build()?, info))
}

/// Pin the local point `(0, y)` of the chain's first body to the ground at
/// the origin by a revolute joint `name`, and attach the chain kernels with
/// that ground pivot (`chain`: the bodies, joints and joint points of
/// `add_chain`). Returns the joint's index.
fn pin_to_ground(
    builder: &mut SystemBuilder,
    name: &str,
    (bodies, joints, points): (&[usize], &[usize], &[[f64; 4]]),
    y: f64,
) -> usize {
    let base = builder.add_constraint(Revolute::new(
        name,
        BodyRef::Ground,
        [0.0, 0.0],
        BodyRef::Body(bodies[0]),
        [0.0, y],
    ));
    let pivot = GroundPivot {
        first: false,
        ground_is_i: true,
        body: bodies[0],
        points: [0.0, 0.0, 0.0, y],
    };
    attach_chain_kernels(builder, bodies, joints, points, Some((base, pivot)));
    base
}
