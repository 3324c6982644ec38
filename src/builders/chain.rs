//! A chain of N uniform links described once (the scenario's `[[chain]]`,
//! docs/scenarios.md): revolute joints between neighbours, an optional
//! linear torsional spring–damper in every one, an optional ground pivot;
//! the generated kernels attached to exactly its joints and springs.

use super::rod::{add_chain, attach_chain_kernels, ChainNames};
use crate::constraints::Revolute;
use crate::forces::Check;
use crate::forces::TorsionalSpringDamper;
use crate::generated::{GroundPivot, TorsionalChainJacobians};
use crate::model::{BodyRef, ModelError, SystemBuilder};

/// Element name used in the parameter errors of this module.
const CHAIN: Check = Check {
    element: "chain parameters",
};

/// A straight chain of `links` uniform links, SI units.
///
/// Link k (1-based from the first end) has its body frame y along the link,
/// its first end at local `(0, −l/2)` and its last end at `(0, +l/2)`; the
/// revolute joint k joins the last end of link k to the first end of link
/// k+1. Initially the chain is straight and at rest, every link at body
/// angle φ = `angle` (direction from first to last end `(−sin φ, cos φ)`:
/// φ = 0 points up, φ = π hangs down), the first end of link 1 at
/// `position`.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkChain {
    /// Number of links N ≥ 1.
    pub links: usize,
    /// Link length l \[m\].
    pub length: f64,
    /// Link mass m \[kg\].
    pub mass: f64,
    /// Link moment of inertia about its centre \[kg m²\].
    pub inertia: f64,
    /// First end of link 1 \[m\].
    pub position: [f64; 2],
    /// Initial body angle φ of every link \[rad\].
    pub angle: f64,
    /// Stiffness k of the torsional spring in every link joint,
    /// `T = −k (φ_{k+1} − φ_k) − c (φ̇_{k+1} − φ̇_k)` \[N m/rad\]; with
    /// `damping` both 0: no springs.
    pub stiffness: f64,
    /// Damping c of the torsional springs \[N m s/rad\].
    pub damping: f64,
    /// Pin the first end of link 1 to the ground at `position`.
    pub pivot: bool,
}

/// What [`add_link_chain`] added (indices into the builder's lists).
#[derive(Debug, Clone, PartialEq)]
pub struct ChainInfo {
    /// The links, from the first end.
    pub bodies: Vec<usize>,
    /// `joints[k]` joins `bodies[k]` and `bodies[k + 1]`.
    pub joints: Vec<usize>,
    /// The ground pivot (added after `joints`).
    pub pivot: Option<usize>,
    /// The torsional spring–dampers, `springs[k]` in `joints[k]`.
    pub springs: Vec<usize>,
}

impl LinkChain {
    /// Check every field: `links ≥ 1`; `length`, `mass`, `inertia` finite
    /// and > 0; `stiffness`, `damping` finite and ≥ 0; `position`, `angle`
    /// finite. Errors name the field and its value.
    pub fn validate(&self) -> Result<(), ModelError> {
        if self.links == 0 {
            return Err(CHAIN.fail("links", "0".into(), "the chain needs at least one link"));
        }
        let (l, m, i) = (self.length, self.mass, self.inertia);
        CHAIN.positive(&[("length", l), ("mass", m), ("inertia", i)])?;
        CHAIN.non_negative(&[("stiffness", self.stiffness), ("damping", self.damping)])?;
        CHAIN.finite_point("position", self.position)?;
        CHAIN.finite("angle", self.angle)
    }
}

/// Add the chain `c` named `name` to `builder` (after validating it):
/// links "`name`.link\[k\]", joints "`name`.joint\[k\]", the pivot
/// "`name`.pivot", k = 1 … N. Attaches [`crate::generated::ChainKernels`]
/// to its joints (and pivot) and [`TorsionalChainJacobians`] to its
/// springs, so the chain keeps the generated kernels inside any larger
/// system. Gravity is not added (it is system-wide).
pub fn add_link_chain(
    builder: &mut SystemBuilder,
    name: &str,
    c: &LinkChain,
) -> Result<ChainInfo, ModelError> {
    c.validate()?;
    let l = c.length;
    let (s, co) = c.angle.sin_cos();
    let e = [-s, co];
    let (bodies, joints, points) = add_chain(
        builder,
        ChainNames::Component(name, "link"),
        c.links,
        c.mass,
        c.inertia,
        c.angle,
        [0.0, 0.0],
        0.5 * l,
        |i| {
            let a = (i as f64 + 0.5) * l;
            [c.position[0] + a * e[0], c.position[1] + a * e[1]]
        },
    );
    let pivot = c.pivot.then(|| {
        let k = builder.add_constraint(Revolute::new(
            format!("{name}.pivot"),
            BodyRef::Ground,
            c.position,
            BodyRef::Body(bodies[0]),
            [0.0, -0.5 * l],
        ));
        let p = GroundPivot {
            first: false,
            ground_is_i: true,
            body: bodies[0],
            points: [c.position[0], c.position[1], 0.0, -0.5 * l],
        };
        (k, p)
    });
    attach_chain_kernels(builder, &bodies, &joints, &points, pivot);
    let mut springs = Vec::new();
    if c.stiffness != 0.0 || c.damping != 0.0 {
        let elements = TorsionalSpringDamper::in_chain(&bodies, c.stiffness, c.damping);
        springs = elements
            .iter()
            .map(|s| builder.add_force(s.clone()))
            .collect();
        if let Some(&first) = springs.first() {
            builder.attach_force_kernels(
                first..first + springs.len(),
                Box::new(TorsionalChainJacobians::new(bodies[0], &elements)),
            );
        }
    }
    Ok(ChainInfo {
        bodies,
        joints,
        pivot: pivot.map(|p| p.0),
        springs,
    })
}
