//! The cantilevered stiff chain of the peer comparisons
//! (`../shared/peers/`): N rigid segments of the rod of problem B
//! (1 m, 0.03 m square steel) hanging down from a pivot at the origin, a
//! revolute joint and a torsional spring–damper `k = E w⁴/(12 l_s)`,
//! `c = 10⁻⁵ s · k` at every joint (ground–1 included, rest angle 0 =
//! straight down), gravity 9.81 along −y; released at rest, straight, every
//! segment turned θ₀ = 5° counter-clockwise from the downward vertical.
//! Reported: x of the free end at t = 0.1 s.

use super::known_answer::add_cantilever;
use super::rod::{RodInfo, RodParams};
use crate::model::{Gravity, ModelError, System, SystemBuilder};

/// Tip x at t = 0.1 s. N = 10 and 100: the peers' references
/// (`../shared/peers/README.md`), SciPy Radau at rtol 1e-10 on two
/// independently derived minimal-coordinate right-hand sides; mbsolve's
/// bdf at rtol 1e-9 and radau5 at h = 5e-5 agree with them to 2.6e-9 and
/// 2e-10 (N = 10), 7.6e-10 and 2e-10 (N = 100). N = 1000: mbsolve's
/// radau5 (order 5, h = 1e-4 and 5e-5, Newton tolerance 1e-6 m/s²) and
/// bdf (rtol 1e-9), two methods of different order and error control:
/// radau5 −0.0918238669 (1e-4), −0.0918238611 (5e-5), bdf −0.0918238599
/// (ndf rtol 1e-8: −0.0918238462), so −0.09182386 ± 2e-9 m
/// (within the peers' −0.0918244 ± 1e-6; the superseded generalized-α
/// Richardson value is in docs/bench_exudyn.md). N = 10 000:
/// bdf rtol 1e-9 −0.0924593219 and ndf rtol 1e-8 −0.0924593084, so
/// −0.09245932 ± 2e-8 m.
pub fn stiff_chain_reference_tip(n: usize) -> Option<f64> {
    match n {
        10 => Some(-0.013378720487),
        100 => Some(-0.087394814801),
        1000 => Some(-0.09182386),
        10000 => Some(-0.09245932),
        _ => None,
    }
}

/// The stiff chain of `n` segments, released at `theta0` \[rad\] from the
/// downward vertical: the system, q0, q̇0 (at rest) and the rod's
/// bookkeeping (segment `n − 1` carries the free end at local `(0, +l_s/2)`).
pub fn stiff_chain(
    n: usize,
    theta0: f64,
) -> Result<(System, Vec<f64>, Vec<f64>, RodInfo), ModelError> {
    let params = RodParams {
        n_segments: n,
        // φ = π: segment axes (local +y) point down; the ground spring rests there
        tilt: std::f64::consts::PI,
        fluid: false,
        contact: false,
        ..RodParams::default()
    };
    let mut builder = SystemBuilder::new();
    let mut info = add_cantilever(&mut builder, &params, [0.0, 0.0])?;
    attach_spring_kernels(&mut builder, &info);
    info.gravity = Some(
        builder.add_force(Gravity {
            g: [0.0, -9.81],
            bodies: info
                .bodies
                .iter()
                .map(|&b| (b, info.segment_mass))
                .collect(),
        }),
    );
    let sys = builder.build()?;
    // the straight chain turned by θ₀ about the pivot
    let ls = info.segment_length;
    let (s, c) = theta0.sin_cos();
    let mut q0 = vec![0.0; sys.n_coords()];
    for (i, &b) in info.bodies.iter().enumerate() {
        let d = (i as f64 + 0.5) * ls;
        q0[3 * b] = d * s;
        q0[3 * b + 1] = -d * c;
        q0[3 * b + 2] = std::f64::consts::PI + theta0;
    }
    let qd0 = vec![0.0; sys.n_coords()];
    Ok((sys, q0, qd0, info))
}

/// Attach the generated Jacobians ([`TorsionalChainJacobians`](crate::generated::TorsionalChainJacobians)) to the
/// chain's springs between neighbouring segments (`info.springs[1..]`,
/// consecutive elements on bodies `b, b + 1`); the ground spring keeps its
/// own (one element). [`add_cantilever`] attaches the chain's joint kernels
/// but none for its springs; without these the implicit path evaluates
/// ∂g/∂q, ∂g/∂q̇ of N − 1 springs one virtual call at a time.
fn attach_spring_kernels(builder: &mut SystemBuilder, info: &RodInfo) {
    if let Some(&first) = info.springs.get(1) {
        super::rod::attach_spring_chain_kernels(builder, &info.bodies, first, info);
    }
}

/// x of the free end (bottom of the last segment) from the coordinates `q`.
pub fn stiff_chain_tip_x(info: &RodInfo, q: &[f64]) -> f64 {
    let b = *info.bodies.last().expect("a chain has segments");
    // local (0, −l_s/2) is the end towards the pivot; the free end is (0, +l_s/2)
    q[3 * b] - 0.5 * info.segment_length * q[3 * b + 2].sin()
}
