//! Constraint kernels generated at build time by `mbsolve-codegen`
//! (ARCHITECTURE.md, "Code generation").
//!
//! `build.rs` runs the generator for the built-in topologies and writes
//! `$OUT_DIR/mbsolve_generated.rs`, included here as [`kernels`]: the
//! body–body revolute chain (per-joint kernels plus loops; the rod and the
//! links of the N-link pendulum), one revolute between the ground and a body
//! (the pendulum pivot, the cantilever base), the four-bar (fully unrolled),
//! and force kernels (torsional spring–dampers along a chain, drag on every
//! body). Joint parameters — the body-fixed points — are run-time inputs, so
//! one set of kernels serves every segment length and every N.
//!
//! The kernels implement [`ConstraintKernels`] for a range of joints,
//! including (Φ_qᵀλ)_q for the Newton matrix of the implicit methods, and
//! reproduce the generic per-joint evaluation (same rows, Φ_q values in the
//! order of [`System::jacobian_pattern`]). The builders attach the kernels
//! of what they build ([`ChainKernels::new`] for a rod's or a pendulum's
//! chain, any body numbering, anywhere in a larger system); for systems
//! read from scenario files, [`recognise`] inspects the joints as data
//! ([`crate::model::Constraint::geometry`]) and [`attach_generated`]
//! attaches matching whole-system kernels.
//!
//! Recognised topologies:
//! * **four-bar**: 3 bodies and exactly the revolutes ground–0, 0–1, 1–2,
//!   ground–2 in that order (docs/problems.md, problem A), any pin points;
//! * **revolute chain**: N bodies, joints `k = 0 … N−2` each a revolute with
//!   `body_i = k`, `body_j = k + 1` (any points), in row order — the rod of
//!   problem B (docs/problems.md); optionally one more revolute between the ground (either
//!   side) and any body, as the first or the last joint — the N-link
//!   pendulum and the cantilever of problem D (docs/problems.md).
//!
//! Anything else (another joint kind, other body numbering or order) gives
//! `None`, and the system keeps its generic evaluation.

use crate::forces::drag_force;
use crate::forces::Clearance;
use crate::forces::{Drag, TorsionalSpringDamper, WallContact};
use crate::model::{BodyRef, ConstraintKernels, ForceElement, ForceKernels, JointGeometry, System};

/// The generated functions (`$OUT_DIR/mbsolve_generated.rs`).
pub mod kernels {
    include!(concat!(env!("OUT_DIR"), "/mbsolve_generated.rs"));
}

fn code(b: BodyRef) -> i64 {
    match b {
        BodyRef::Ground => -1,
        BodyRef::Body(i) => i as i64,
    }
}

/// A revolute joint as data: (body i, body j, kernel parameters s_i, s_j).
fn revolute(g: JointGeometry) -> Option<(BodyRef, BodyRef, [f64; 4])> {
    match g {
        JointGeometry::Revolute {
            body_i,
            s_i,
            body_j,
            s_j,
        } => Some((body_i, body_j, [s_i[0], s_i[1], s_j[0], s_j[1]])),
        _ => None,
    }
}

#[inline]
fn arr<const N: usize>(s: &[f64]) -> &[f64; N] {
    s[..N].try_into().expect("slice length")
}

#[inline]
fn arr_mut<const N: usize>(s: &mut [f64]) -> &mut [f64; N] {
    (&mut s[..N]).try_into().expect("slice length")
}

/// A revolute joint between the ground and one body.
#[derive(Debug, Clone)]
struct GroundJoint {
    /// The ground is side i (`Revolute::body_i`)?
    ground_is_i: bool,
    /// The body's first coordinate.
    off: usize,
    row0: usize,
    jac0: usize,
    params: [f64; 4],
}

impl GroundJoint {
    fn phi(&self, q: &[f64], out: &mut [f64]) {
        let (qb, o) = (arr(&q[self.off..]), arr_mut(&mut out[self.row0..]));
        if self.ground_is_i {
            kernels::revolute_gb_phi(qb, &self.params, &[], o);
        } else {
            kernels::revolute_bg_phi(qb, &self.params, &[], o);
        }
    }
    fn jacobian(&self, q: &[f64], vals: &mut [f64]) {
        let (qb, o) = (arr(&q[self.off..]), arr_mut(&mut vals[self.jac0..]));
        if self.ground_is_i {
            kernels::revolute_gb_jacobian(qb, &self.params, &[], o);
        } else {
            kernels::revolute_bg_jacobian(qb, &self.params, &[], o);
        }
    }
    fn phi_t(&self, q: &[f64], out: &mut [f64]) {
        let (qb, o) = (arr(&q[self.off..]), arr_mut(&mut out[self.row0..]));
        if self.ground_is_i {
            kernels::revolute_gb_phi_t(qb, &self.params, &[], o);
        } else {
            kernels::revolute_bg_phi_t(qb, &self.params, &[], o);
        }
    }
    fn gamma(&self, q: &[f64], qd: &[f64], out: &mut [f64]) {
        let (qb, vb) = (arr(&q[self.off..]), arr(&qd[self.off..]));
        let o = arr_mut(&mut out[self.row0..]);
        if self.ground_is_i {
            kernels::revolute_gb_gamma(qb, vb, &self.params, &[], o);
        } else {
            kernels::revolute_bg_gamma(qb, vb, &self.params, &[], o);
        }
    }
    fn eval(&self, q: &[f64], qd: &[f64], phi: &mut [f64], vals: &mut [f64], gamma: &mut [f64]) {
        let (qb, vb) = (arr(&q[self.off..]), arr(&qd[self.off..]));
        let (p, v, g) = (
            arr_mut(&mut phi[self.row0..]),
            arr_mut(&mut vals[self.jac0..]),
            arr_mut(&mut gamma[self.row0..]),
        );
        if self.ground_is_i {
            kernels::revolute_gb_eval(qb, vb, &self.params, &[], p, v, g);
        } else {
            kernels::revolute_bg_eval(qb, vb, &self.params, &[], p, v, g);
        }
    }
    /// Φ into `phi` (the range's rows) and Φ_qᵀλ added to `g` (λ: the
    /// range's multipliers), from the 4 Φ_q values.
    fn phi_tmul(&self, q: &[f64], lambda: &[f64], phi: &mut [f64], g: &mut [f64]) {
        self.phi_tmul_at(q, lambda, phi, g, self.row0)
    }
    /// [`GroundJoint::phi_tmul`] with the joint's rows at `row0` of `phi`
    /// and `lambda`.
    fn phi_tmul_at(&self, q: &[f64], lambda: &[f64], phi: &mut [f64], g: &mut [f64], row0: usize) {
        let (qb, o) = (arr(&q[self.off..]), arr_mut(&mut phi[row0..]));
        if self.ground_is_i {
            kernels::revolute_gb_phi(qb, &self.params, &[], o);
        } else {
            kernels::revolute_bg_phi(qb, &self.params, &[], o);
        }
        let mut vals = [0.0; 4];
        let qb = arr(&q[self.off..]);
        let pattern = if self.ground_is_i {
            kernels::revolute_gb_jacobian(qb, &self.params, &[], &mut vals);
            kernels::REVOLUTE_GB_JAC_PATTERN
        } else {
            kernels::revolute_bg_jacobian(qb, &self.params, &[], &mut vals);
            kernels::REVOLUTE_BG_JAC_PATTERN
        };
        for (&(r, c), v) in pattern.iter().zip(vals) {
            g[self.off + c] += v * lambda[row0 + r];
        }
    }
    fn add_hessian(&self, q: &[f64], lambda: &[f64], vals: &mut [f64]) {
        let qb = arr(&q[self.off..]);
        let l = arr(&lambda[self.row0..]);
        let o = arr_mut(vals);
        if self.ground_is_i {
            kernels::revolute_gb_hessian(qb, &self.params, &[], l, o);
        } else {
            kernels::revolute_bg_hessian(qb, &self.params, &[], l, o);
        }
    }
}

/// `(sin x, cos x)` with one argument reduction for both (the standard
/// library calls libm's `sin` and `cos`, each reducing on its own): Cody–Waite
/// reduction by π/2 in three parts and fdlibm's minimax kernels `__kernel_sin`,
/// `__kernel_cos` on `[−π/4, π/4]` (Sun Microsystems 1993, as in musl's
/// `__sin.c`, `__cos.c`, `__rem_pio2.c`); within 1 ulp of the libm values
/// for `|x| < 2²⁰ π/2` (tested), libm beyond.
// fdlibm's constants as published (each rounds to the intended double)
#[allow(clippy::excessive_precision, clippy::approx_constant)]
pub fn sin_cos(x: f64) -> (f64, f64) {
    const INV_PIO2: f64 = 6.366_197_723_675_813_824_33e-1;
    const PIO2_1: f64 = 1.570_796_326_734_125_614_17e0;
    const PIO2_1T: f64 = 6.077_100_506_506_192_249_32e-11;
    const PIO2_2: f64 = 6.077_100_506_303_965_976_60e-11;
    const PIO2_2T: f64 = 2.022_266_248_795_950_631_54e-21;
    const PIO2_3: f64 = 2.022_266_248_711_166_455_80e-21;
    const PIO2_3T: f64 = 8.478_427_660_368_899_569_97e-32;
    if x.is_nan() || x.abs() >= 1_647_099.0 {
        return x.sin_cos();
    }
    // x = n π/2 + (y0 + y1), the remainder in two doubles
    // round to nearest (even) without a libm call: 1.5·2⁵² forces it
    const TOINT: f64 = 6_755_399_441_055_744.0;
    let n = (x * INV_PIO2 + TOINT) - TOINT;
    let mut r = x - n * PIO2_1;
    let mut w = n * PIO2_1T;
    let mut y0 = r - w;
    let ey = (y0.to_bits() >> 52) as i32 & 0x7ff;
    let ex = (x.to_bits() >> 52) as i32 & 0x7ff;
    if ex - ey > 16 {
        // cancellation: second and, if needed, third part of π/2
        let t = r;
        w = n * PIO2_2;
        r = t - w;
        w = n * PIO2_2T - ((t - r) - w);
        y0 = r - w;
        let ey = (y0.to_bits() >> 52) as i32 & 0x7ff;
        if ex - ey > 49 {
            let t = r;
            w = n * PIO2_3;
            r = t - w;
            w = n * PIO2_3T - ((t - r) - w);
            y0 = r - w;
        }
    }
    let y1 = (r - y0) - w;
    let (s, c) = (kernel_sin(y0, y1), kernel_cos(y0, y1));
    match (n as i64) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// [`sin_cos`] of four angles, lane by lane the same operations (so the
/// same bits) without branches: the quadrant from the low bits of the
/// rounded quotient, the swap and signs as bit selects, so the lanes run
/// in SIMD registers. `None` when a lane needs more than [`sin_cos`]'s first
/// reduction step (a NaN, `|x| ≥ 1 647 099`, or cancellation against a
/// multiple of π/2): then call [`sin_cos`] per angle.
///
/// On x86-64 processors with AVX2 the four lanes run in one 256-bit
/// register (detected at run time; the same operations without fused
/// multiply–adds, so the same bits as the SSE2 path).
#[inline]
pub fn sin_cos4(x: [f64; 4]) -> Option<([f64; 4], [f64; 4])> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor has AVX2 (checked above)
        return unsafe { sin_cos4_avx2(x) };
    }
    sin_cos4_lanes(x)
}

/// [`sin_cos4_lanes`] compiled for AVX2 (no FMA: Rust never contracts
/// `a * b + c`, so the bits are those of the baseline build).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn sin_cos4_avx2(x: [f64; 4]) -> Option<([f64; 4], [f64; 4])> {
    sin_cos4_lanes(x)
}

/// The lanes of [`sin_cos4`].
// fdlibm's constants as published (each rounds to the intended double)
#[allow(clippy::excessive_precision, clippy::approx_constant)]
#[inline(always)]
fn sin_cos4_lanes(x: [f64; 4]) -> Option<([f64; 4], [f64; 4])> {
    const INV_PIO2: f64 = 6.366_197_723_675_813_824_33e-1;
    const PIO2_1: f64 = 1.570_796_326_734_125_614_17e0;
    const PIO2_1T: f64 = 6.077_100_506_506_192_249_32e-11;
    const TOINT: f64 = 6_755_399_441_055_744.0;
    const SIGN: u64 = 1 << 63;
    let (mut s, mut c) = ([0.0; 4], [0.0; 4]);
    let mut ok = true;
    for l in 0..4 {
        let xl = x[l];
        // |x| < 1 647 099 and not NaN: the range of the single reduction
        ok &= xl.abs() < 1_647_099.0;
        let t = xl * INV_PIO2 + TOINT;
        // t = 1.5·2⁵² + n exactly: its low bits are n mod 4
        let quadrant = t.to_bits() & 3;
        let n = t - TOINT;
        let r = xl - n * PIO2_1;
        let w = n * PIO2_1T;
        let y0 = r - w;
        let ey = (y0.to_bits() >> 52) as i64 & 0x7ff;
        let ex = (xl.to_bits() >> 52) as i64 & 0x7ff;
        ok &= ex - ey <= 16;
        let y1 = (r - y0) - w;
        let (ks, kc) = (kernel_sin(y0, y1), kernel_cos(y0, y1));
        // quadrant 0: (s, c), 1: (c, −s), 2: (−s, −c), 3: (−c, s)
        let swap = 0u64.wrapping_sub(quadrant & 1);
        let (kb, cb) = (ks.to_bits(), kc.to_bits());
        let sb = (kb & !swap) | (cb & swap);
        let cb2 = (cb & !swap) | (kb & swap);
        let s_neg = (quadrant & 2) << 62;
        let c_neg = ((quadrant + 1) & 2) << 62;
        s[l] = f64::from_bits(sb ^ (s_neg & SIGN));
        c[l] = f64::from_bits(cb2 ^ (c_neg & SIGN));
    }
    ok.then_some((s, c))
}

/// fdlibm `__kernel_sin(x, y, 1)`: sin(x + y) on `|x| ≤ π/4`, `|y| ≤ ulp(x)/2`.
// fdlibm's constants as published (each rounds to the intended double)
#[allow(clippy::excessive_precision, clippy::approx_constant)]
#[inline(always)]
fn kernel_sin(x: f64, y: f64) -> f64 {
    const S1: f64 = -1.666_666_666_666_663_243_48e-01;
    const S2: f64 = 8.333_333_333_322_489_461_24e-03;
    const S3: f64 = -1.984_126_982_985_794_931_34e-04;
    const S4: f64 = 2.755_731_370_707_006_767_89e-06;
    const S5: f64 = -2.505_076_025_340_686_341_95e-08;
    const S6: f64 = 1.589_690_995_211_550_102_21e-10;
    let z = x * x;
    let w = z * z;
    let r = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    let v = z * x;
    x - ((z * (0.5 * y - v * r) - y) - v * S1)
}

/// fdlibm `__kernel_cos(x, y)`: cos(x + y) on `|x| ≤ π/4`, `|y| ≤ ulp(x)/2`.
// fdlibm's constants as published (each rounds to the intended double)
#[allow(clippy::excessive_precision, clippy::approx_constant)]
#[inline(always)]
fn kernel_cos(x: f64, y: f64) -> f64 {
    const C1: f64 = 4.166_666_666_666_660_190_37e-02;
    const C2: f64 = -1.388_888_888_887_410_957_49e-03;
    const C3: f64 = 2.480_158_728_947_672_941_78e-05;
    const C4: f64 = -2.755_731_435_139_066_330_35e-07;
    const C5: f64 = 2.087_572_321_298_174_827_90e-09;
    const C6: f64 = -1.135_964_755_778_819_482_65e-11;
    let z = x * x;
    let w = z * z;
    let r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    w + (((1.0 - w) - hz) + (z * r - x * y))
}

/// Sines and cosines of the chain's body angles, memoised per body on the
/// exact bits of φ: the formulation asks for Φ_q, γ, Φ and Φ_t at the same
/// q one after the other, and the trigonometry is most of their cost
/// ([`sin_cos`]: one argument reduction for both).
#[derive(Debug)]
struct TrigMemo {
    phi_bits: Vec<u64>,
    sc: Vec<f64>,
}

impl TrigMemo {
    fn new(n_bodies: usize) -> Self {
        // NaN sentinel: a NaN angle "hits" and gets NaN sines, as sin_cos would.
        Self {
            phi_bits: vec![f64::NAN.to_bits(); n_bodies],
            sc: vec![f64::NAN; 2 * n_bodies],
        }
    }
    /// Are the sines and cosines of bodies `ks` those of `q`'s angles
    /// (bits compared)? For readers that share the memo without updating it.
    fn current(&self, q: &[f64], ks: std::ops::Range<usize>) -> bool {
        ks.into_iter()
            .all(|k| self.phi_bits[k] == q[3 * k + 2].to_bits())
    }
    fn update(&mut self, q: &[f64]) -> &[f64] {
        // two halves concurrently for long chains: each angle's sin_cos is
        // independent of the others, so the bits do not depend on threads
        let nb = self.phi_bits.len();
        let half = nb / 2;
        let (bits_lo, bits_hi) = self.phi_bits.split_at_mut(half);
        let (sc_lo, sc_hi) = self.sc.split_at_mut(2 * half);
        if nb >= TRIG_PARALLEL_MIN_BODIES {
            crate::parallel::join_if(
                true,
                || trig_update(q, 0, bits_lo, sc_lo),
                || trig_update(q, half, bits_hi, sc_hi),
            );
        } else {
            trig_update(q, 0, &mut self.phi_bits, &mut self.sc);
        }
        &self.sc
    }
}

/// Chains of at least this many bodies update their sines and cosines in
/// two concurrent halves ([`TrigMemo`]).
const TRIG_PARALLEL_MIN_BODIES: usize = 2000;

/// A chain's memo of sines and cosines ([`ChainKernels::shared_trig`]),
/// for force kernels on the same bodies ([`DragJacobians::with_trig`]):
/// the residual evaluates the forces and the constraint terms at the same
/// q, so the angles' sines and cosines are computed once for both. Same
/// bits: the memo holds [`sin_cos`]'s values.
#[derive(Debug, Clone)]
pub struct SharedTrig {
    memo: std::sync::Arc<std::sync::RwLock<TrigMemo>>,
    /// First coordinate of the first body.
    q0: usize,
    n_bodies: usize,
}

/// Sines and cosines of the angles of bodies `b0, b0 + 1, …` whose angle
/// changed since the last call (bits compared).
fn trig_update(q: &[f64], b0: usize, phi_bits: &mut [u64], sc: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor has AVX2 (checked above)
        return unsafe { trig_update_avx2(q, b0, phi_bits, sc) };
    }
    trig_update_lanes(q, b0, phi_bits, sc)
}

/// [`trig_update_lanes`] compiled for AVX2, the whole loop in one function
/// (the constants stay in registers, and consecutive angles overlap in
/// the core); the same bits as the baseline build (see [`sin_cos4`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn trig_update_avx2(q: &[f64], b0: usize, phi_bits: &mut [u64], sc: &mut [f64]) {
    trig_update_lanes(q, b0, phi_bits, sc)
}

/// The loop of [`trig_update`].
#[inline(always)]
fn trig_update_lanes(q: &[f64], b0: usize, phi_bits: &mut [u64], sc: &mut [f64]) {
    let nb = phi_bits.len();
    let mut k = 0;
    // four bodies at a time where any of them changed ([`sin_cos4`], the
    // same bits as one at a time)
    while k + 4 <= nb {
        let x: [f64; 4] = std::array::from_fn(|l| q[3 * (b0 + k + l) + 2]);
        if (0..4).any(|l| phi_bits[k + l] != x[l].to_bits()) {
            if let Some((s, c)) = sin_cos4_lanes(x) {
                for l in 0..4 {
                    sc[2 * (k + l)] = s[l];
                    sc[2 * (k + l) + 1] = c[l];
                    phi_bits[k + l] = x[l].to_bits();
                }
            } else {
                trig_update_one(q, b0, k..k + 4, phi_bits, sc);
            }
        }
        k += 4;
    }
    trig_update_one(q, b0, k..nb, phi_bits, sc);
}

/// [`trig_update`] of bodies `b0 + k` for `k` in `ks`, one at a time.
fn trig_update_one(
    q: &[f64],
    b0: usize,
    ks: std::ops::Range<usize>,
    phi_bits: &mut [u64],
    sc: &mut [f64],
) {
    for k in ks {
        let phi = q[3 * (b0 + k) + 2];
        if phi_bits[k] != phi.to_bits() {
            let (s, c) = sin_cos(phi);
            sc[2 * k] = s;
            sc[2 * k + 1] = c;
            phi_bits[k] = phi.to_bits();
        }
    }
}

/// Generated kernels for a revolute chain (the rod), optionally with one
/// ground revolute (the N-link pendulum, the cantilever).
#[derive(Debug)]
pub struct ChainKernels {
    name: String,
    /// First coordinate of the chain's first body.
    q0: usize,
    n_joints: usize,
    row0: usize,
    jac0: usize,
    params: Vec<f64>,
    ground: Option<GroundJoint>,
    memo: std::sync::Arc<std::sync::RwLock<TrigMemo>>,
}

/// A ground pivot of a chain: a revolute between the ground and `body`,
/// attached before (`first`) or after the chain's joints.
#[derive(Debug, Clone, Copy)]
pub struct GroundPivot {
    /// The pivot is the first joint of the range (else the last).
    pub first: bool,
    /// The ground is the joint's side i.
    pub ground_is_i: bool,
    /// The pivoted body.
    pub body: usize,
    /// `[s_i, s_j]` of the joint (the ground's point global).
    pub points: [f64; 4],
}

impl ChainKernels {
    /// Kernels for the joints of a chain of bodies `body0, body0 + 1, …`:
    /// joint `k` a revolute between `body0 + k` (point `s_i`) and
    /// `body0 + k + 1` (point `s_j`), `joints[k] = [s_i, s_j]`, in row order;
    /// with an optional ground pivot before or after them.
    pub fn new(body0: usize, joints: &[[f64; 4]], pivot: Option<GroundPivot>) -> Self {
        let nj = joints.len();
        let (row0, jac0, ground) = match pivot {
            None => (0, 0, None),
            Some(p) => {
                let gj = GroundJoint {
                    ground_is_i: p.ground_is_i,
                    off: 3 * p.body,
                    row0: if p.first { 0 } else { 2 * nj },
                    jac0: if p.first { 0 } else { 8 * nj },
                    params: p.points,
                };
                if p.first {
                    (2, 4, Some(gj))
                } else {
                    (0, 0, Some(gj))
                }
            }
        };
        let name = if ground.is_some() {
            "generated:pendulum_chain"
        } else {
            "generated:rod_chain"
        };
        ChainKernels {
            name: name.into(),
            q0: 3 * body0,
            n_joints: nj,
            row0,
            jac0,
            params: joints.iter().flatten().copied().collect(),
            ground,
            memo: std::sync::Arc::new(std::sync::RwLock::new(TrigMemo::new(nj + 1))),
        }
    }

    /// Kernels for the whole of `sys` if its joints form a revolute chain
    /// (see the module documentation), else `None`.
    pub fn recognise(sys: &System) -> Option<Self> {
        let nb = sys.bodies().len();
        let revs: Vec<(BodyRef, BodyRef, [f64; 4])> = sys
            .constraints()
            .iter()
            .map(|c| revolute(c.geometry()))
            .collect::<Option<_>>()?;
        let is_ground =
            |r: &(BodyRef, BodyRef, [f64; 4])| r.0 == BodyRef::Ground || r.1 == BodyRef::Ground;
        let grounds: Vec<usize> = (0..revs.len()).filter(|&k| is_ground(&revs[k])).collect();
        let ground_pos = match grounds.as_slice() {
            [] => None,
            [g] if *g == 0 || *g + 1 == revs.len() => Some(*g),
            _ => return None,
        };
        let chain: Vec<[f64; 4]> = revs
            .iter()
            .filter(|r| !is_ground(r))
            .enumerate()
            .map(|(k, r)| (r.0 == BodyRef::Body(k) && r.1 == BodyRef::Body(k + 1)).then_some(r.2))
            .collect::<Option<_>>()?;
        if chain.len() + 1 != nb {
            return None;
        }
        let pivot = match ground_pos {
            None => None,
            Some(g) => {
                let (ground_is_i, body) = match (revs[g].0, revs[g].1) {
                    (BodyRef::Ground, BodyRef::Body(b)) => (true, b),
                    (BodyRef::Body(b), BodyRef::Ground) => (false, b),
                    _ => return None,
                };
                Some(GroundPivot {
                    first: g == 0,
                    ground_is_i,
                    body,
                    points: revs[g].2,
                })
            }
        };
        let k = ChainKernels::new(0, &chain, pivot);
        (k.pattern() == sys.jacobian_pattern()).then_some(k)
    }

    /// The Φ_q pattern these kernels write (must equal the system's).
    fn pattern(&self) -> Vec<(usize, usize)> {
        let mut p = vec![(0, 0); 8 * self.n_joints + 4 * usize::from(self.ground.is_some())];
        for k in 0..self.n_joints {
            for (e, &(r, c)) in kernels::REVOLUTE_CHAIN_JOINT_JAC_PATTERN.iter().enumerate() {
                p[self.jac0 + 8 * k + e] = (self.row0 + 2 * k + r, self.q0 + 3 * k + c);
            }
        }
        if let Some(g) = &self.ground {
            for (e, &(r, c)) in kernels::REVOLUTE_GB_JAC_PATTERN.iter().enumerate() {
                p[g.jac0 + e] = (g.row0 + r, g.off + c);
            }
        }
        p
    }

    /// The chain's part of q (or q̇): its bodies' coordinates.
    fn chain_q<'q>(&self, q: &'q [f64]) -> &'q [f64] {
        &q[self.q0..self.q0 + 3 * (self.n_joints + 1)]
    }

    /// The memo of the chain's sines and cosines, to share with force
    /// kernels on the chain's bodies ([`SharedTrig`]).
    pub fn shared_trig(&self) -> SharedTrig {
        SharedTrig {
            memo: self.memo.clone(),
            q0: self.q0,
            n_bodies: self.n_joints + 1,
        }
    }

    fn chain_rows(&self) -> std::ops::Range<usize> {
        self.row0..self.row0 + 2 * self.n_joints
    }
    fn chain_vals(&self) -> std::ops::Range<usize> {
        self.jac0..self.jac0 + 8 * self.n_joints
    }

    /// Φ, Φ_q values and γ in one pass (sines and cosines computed once per
    /// body instead of once per function and joint side).
    pub fn evaluate(
        &self,
        q: &[f64],
        qd: &[f64],
        phi: &mut [f64],
        vals: &mut [f64],
        gamma: &mut [f64],
    ) {
        let (r, v) = (self.chain_rows(), self.chain_vals());
        kernels::revolute_chain_eval(
            self.chain_q(q),
            self.chain_q(qd),
            &self.params,
            &mut phi[r.clone()],
            &mut vals[v],
            &mut gamma[r],
        );
        if let Some(g) = &self.ground {
            g.eval(q, qd, phi, vals, gamma);
        }
    }

    /// Add (Φ_qᵀλ)_q in the order of the joints' `hessian_pattern`s,
    /// joint after joint (2 values per chain joint, 1 for the ground joint).
    pub fn add_hessian(&self, q: &[f64], lambda: &[f64], vals: &mut [f64]) {
        let nh = 2 * self.n_joints;
        let (chain_at, ground_at) = match &self.ground {
            Some(g) if g.row0 == 0 => (1, 0),
            _ => (0, nh),
        };
        let (qc, p, l) = (self.chain_q(q), &self.params, &lambda[self.chain_rows()]);
        let o = &mut vals[chain_at..chain_at + nh];
        // memoised sines and cosines (shared with Φ, Φ_q, γ at the same q);
        // computed afresh when another thread holds the memo
        match self.memo.try_write() {
            Ok(mut m) => kernels::revolute_chain_hessian_sc(qc, m.update(qc), p, l, o),
            Err(_) => kernels::revolute_chain_hessian(qc, p, l, o),
        }
        if let Some(g) = &self.ground {
            g.add_hessian(q, lambda, &mut vals[ground_at..ground_at + 1]);
        }
    }
}

impl ConstraintKernels for ChainKernels {
    fn jacobian_pattern(&self) -> Vec<(usize, usize)> {
        self.pattern()
    }
    fn has_hessian(&self) -> bool {
        true
    }
    fn add_hessian(&self, q: &[f64], _t: f64, lambda: &[f64], vals: &mut [f64]) {
        ChainKernels::add_hessian(self, q, lambda, vals)
    }
    fn evaluate(
        &self,
        q: &[f64],
        qd: &[f64],
        _t: f64,
        phi: &mut [f64],
        vals: &mut [f64],
        gamma: &mut [f64],
    ) {
        ChainKernels::evaluate(self, q, qd, phi, vals, gamma)
    }
    fn name(&self) -> &str {
        &self.name
    }
    fn phi(&self, q_all: &[f64], _t: f64, out: &mut [f64]) {
        let o = &mut out[self.chain_rows()];
        let (p, q) = (&self.params, self.chain_q(q_all));
        // memoised sines and cosines; computed afresh when another thread holds the memo
        match self.memo.try_write() {
            Ok(mut m) => kernels::revolute_chain_phi_sc(q, m.update(q), p, o),
            Err(_) => kernels::revolute_chain_phi(q, p, o),
        }
        if let Some(g) = &self.ground {
            g.phi(q_all, out);
        }
    }
    fn jacobian_values(&self, q_all: &[f64], _t: f64, vals: &mut [f64]) {
        let o = &mut vals[self.chain_vals()];
        let (p, q) = (&self.params, self.chain_q(q_all));
        // memoised sines and cosines; computed afresh when another thread holds the memo
        match self.memo.try_write() {
            Ok(mut m) => kernels::revolute_chain_jacobian_sc(q, m.update(q), p, o),
            Err(_) => kernels::revolute_chain_jacobian(q, p, o),
        }
        if let Some(g) = &self.ground {
            g.jacobian(q_all, vals);
        }
    }
    fn phi_tmul(
        &self,
        q_all: &[f64],
        _t: f64,
        lambda: &[f64],
        phi: &mut [f64],
        g: &mut [f64],
    ) -> bool {
        let rows = self.chain_rows();
        let (p, q, l) = (&self.params, self.chain_q(q_all), &lambda[rows.clone()]);
        let (o, gc) = (
            &mut phi[rows],
            &mut g[self.q0..self.q0 + 3 * (self.n_joints + 1)],
        );
        // memoised sines and cosines; computed afresh when another thread holds the memo
        match self.memo.try_write() {
            Ok(mut m) => kernels::revolute_chain_phi_tmul_sc(q, m.update(q), p, l, o, gc),
            Err(_) => kernels::revolute_chain_phi_tmul(q, p, l, o, gc),
        }
        if let Some(gj) = &self.ground {
            gj.phi_tmul(q_all, lambda, phi, g);
        }
        true
    }
    /// The sines and cosines of every angle into the memo (its two halves
    /// concurrently for long chains).
    fn prepare(&self, q: &[f64], _t: f64) {
        if let Ok(mut m) = self.memo.try_write() {
            m.update(self.chain_q(q));
        }
    }
    /// `phi_tmul` of the joints `joints`: the chain's joints among them
    /// with the memo's sines and cosines where current (else computed,
    /// the same bits), then the ground joint when among them — the order
    /// of `phi_tmul`.
    fn phi_tmul_joints(
        &self,
        q_all: &[f64],
        _t: f64,
        lambda: &[f64],
        phi: &mut [f64],
        g: &mut [f64],
        joints: std::ops::Range<usize>,
    ) -> bool {
        let nj = self.n_joints;
        let ground_first = matches!(&self.ground, Some(gj) if gj.row0 == 0);
        // local index of chain joint 0, and the chain joints in the range
        let c0 = usize::from(ground_first);
        let ka = joints.start.saturating_sub(c0).min(nj);
        let kb = joints.end.saturating_sub(c0).min(nj);
        if ka < kb {
            let r = 2 * (ka + c0 - joints.start)..2 * (kb + c0 - joints.start);
            let qc = self.chain_q(q_all);
            let (qk, p) = (&qc[3 * ka..3 * (kb + 1)], &self.params[4 * ka..4 * kb]);
            let (l, o) = (&lambda[r.clone()], &mut phi[r]);
            let gc = &mut g[self.q0 + 3 * ka..self.q0 + 3 * (kb + 1)];
            match self.memo.try_read() {
                Ok(m) if m.current(qc, ka..kb + 1) => kernels::revolute_chain_phi_tmul_sc(
                    qk,
                    &m.sc[2 * ka..2 * (kb + 1)],
                    p,
                    l,
                    o,
                    gc,
                ),
                _ => kernels::revolute_chain_phi_tmul(qk, p, l, o, gc),
            }
        }
        if let Some(gj) = &self.ground {
            let jg = if ground_first { 0 } else { nj };
            if joints.contains(&jg) {
                gj.phi_tmul_at(q_all, lambda, phi, g, 2 * (jg - joints.start));
            }
        }
        true
    }
    fn phi_t(&self, q: &[f64], _t: f64, out: &mut [f64]) {
        kernels::revolute_chain_phi_t(self.chain_q(q), &self.params, &mut out[self.chain_rows()]);
        if let Some(g) = &self.ground {
            g.phi_t(q, out);
        }
    }
    fn gamma(&self, q_all: &[f64], qd_all: &[f64], _t: f64, out: &mut [f64]) {
        let o = &mut out[self.chain_rows()];
        let (p, q, qd) = (&self.params, self.chain_q(q_all), self.chain_q(qd_all));
        // memoised sines and cosines; computed afresh when another thread holds the memo
        match self.memo.try_write() {
            Ok(mut m) => kernels::revolute_chain_gamma_sc(q, m.update(q), qd, p, o),
            Err(_) => kernels::revolute_chain_gamma(q, qd, p, o),
        }
        if let Some(g) = &self.ground {
            g.gamma(q_all, qd_all, out);
        }
    }
}

/// Generated, fully unrolled kernels for the four-bar (docs/problems.md, problem A).
#[derive(Debug, Clone)]
pub struct FourBarKernels {
    params: [f64; kernels::FOURBAR_N_PARAMS],
}

impl FourBarKernels {
    /// Kernels for `sys` if it is a four-bar: 3 bodies and the revolutes
    /// ground–0, 0–1, 1–2, ground–2 in that order (any pin points).
    pub fn recognise(sys: &System) -> Option<Self> {
        if sys.bodies().len() != 3 || sys.constraints().len() != kernels::FOURBAR_JOINTS.len() {
            return None;
        }
        let mut params = [0.0; kernels::FOURBAR_N_PARAMS];
        for (k, (c, &(kind, i, j))) in sys
            .constraints()
            .iter()
            .zip(&kernels::FOURBAR_JOINTS)
            .enumerate()
        {
            let (bi, bj, points) = revolute(c.geometry())?;
            if kind != "revolute" || code(bi) != i || code(bj) != j {
                return None;
            }
            params[4 * k..4 * k + 4].copy_from_slice(&points);
        }
        (sys.jacobian_pattern() == kernels::FOURBAR_JAC_PATTERN).then_some(Self { params })
    }

    /// Φ, Φ_q values and γ in one pass.
    pub fn evaluate(
        &self,
        q: &[f64],
        qd: &[f64],
        phi: &mut [f64],
        vals: &mut [f64],
        gamma: &mut [f64],
    ) {
        kernels::fourbar_eval(
            arr(q),
            arr(qd),
            &self.params,
            &[],
            arr_mut(phi),
            arr_mut(vals),
            arr_mut(gamma),
        );
    }

    /// Add (Φ_qᵀλ)_q in the order of the joints' `hessian_pattern`s.
    pub fn add_hessian(&self, q: &[f64], lambda: &[f64], vals: &mut [f64]) {
        kernels::fourbar_hessian(arr(q), &self.params, &[], arr(lambda), arr_mut(vals));
    }
}

impl ConstraintKernels for FourBarKernels {
    fn jacobian_pattern(&self) -> Vec<(usize, usize)> {
        kernels::FOURBAR_JAC_PATTERN.to_vec()
    }
    fn has_hessian(&self) -> bool {
        true
    }
    fn add_hessian(&self, q: &[f64], _t: f64, lambda: &[f64], vals: &mut [f64]) {
        FourBarKernels::add_hessian(self, q, lambda, vals)
    }
    fn evaluate(
        &self,
        q: &[f64],
        qd: &[f64],
        _t: f64,
        phi: &mut [f64],
        vals: &mut [f64],
        gamma: &mut [f64],
    ) {
        FourBarKernels::evaluate(self, q, qd, phi, vals, gamma)
    }
    fn name(&self) -> &str {
        "generated:fourbar"
    }
    fn phi(&self, q: &[f64], _t: f64, out: &mut [f64]) {
        kernels::fourbar_phi(arr(q), &self.params, &[], arr_mut(out));
    }
    fn jacobian_values(&self, q: &[f64], _t: f64, vals: &mut [f64]) {
        kernels::fourbar_jacobian(arr(q), &self.params, &[], arr_mut(vals));
    }
    fn phi_t(&self, q: &[f64], _t: f64, out: &mut [f64]) {
        kernels::fourbar_phi_t(arr(q), &self.params, &[], arr_mut(out));
    }
    fn gamma(&self, q: &[f64], qd: &[f64], _t: f64, out: &mut [f64]) {
        kernels::fourbar_gamma(arr(q), arr(qd), &self.params, &[], arr_mut(out));
    }
}

/// Generated kernels matching `sys`'s topology (four-bar or revolute
/// chain, see the module documentation), or `None`.
pub fn recognise(sys: &System) -> Option<Box<dyn ConstraintKernels>> {
    if let Some(k) = FourBarKernels::recognise(sys) {
        return Some(Box::new(k));
    }
    ChainKernels::recognise(sys).map(|k| Box::new(k) as Box<dyn ConstraintKernels>)
}

/// Kernels for a revolute chain (optionally with a ground pivot) — the
/// chain part of [`recognise`].
pub fn chain_kernels(sys: &System) -> Option<Box<dyn ConstraintKernels>> {
    ChainKernels::recognise(sys).map(|k| Box::new(k) as Box<dyn ConstraintKernels>)
}

/// Kernels for the four-bar — the four-bar part of [`recognise`].
pub fn fourbar_kernels(sys: &System) -> Option<Box<dyn ConstraintKernels>> {
    FourBarKernels::recognise(sys).map(|k| Box::new(k) as Box<dyn ConstraintKernels>)
}

/// Recognise `sys`'s topology and attach the generated kernels to all its
/// joints, replacing kernels attached before (used from then on, see
/// [`System::attach_kernels`]). Returns whether kernels were attached; the
/// system is unchanged when none match.
pub fn attach_generated(sys: &mut System) -> bool {
    match recognise(sys) {
        Some(k) => {
            sys.detach_kernels();
            sys.attach_kernels(0..sys.constraints().len(), k).is_ok()
        }
        None => false,
    }
}

/// Generated Jacobians of the torsional spring–dampers between neighbours of
/// a chain of bodies `body0, body0 + 1, …` (the rod's bending springs), for
/// the Newton matrix ([`crate::model::ForceKernels`]).
#[derive(Debug, Clone)]
pub struct TorsionalChainJacobians {
    q0: usize,
    fp: Vec<f64>,
}

impl TorsionalChainJacobians {
    /// Kernels for `springs[k]` between bodies `body0 + k` and `body0 + k + 1`.
    pub fn new(body0: usize, springs: &[TorsionalSpringDamper]) -> Self {
        Self {
            q0: 3 * body0,
            fp: springs
                .iter()
                .flat_map(|s| [s.k, s.c, s.rest_angle])
                .collect(),
        }
    }
    fn n(&self) -> usize {
        self.fp.len() / 3
    }
}

impl ForceKernels for TorsionalChainJacobians {
    fn name(&self) -> &str {
        "generated:torsional_chain"
    }
    fn jacobian_coordinates(&self) -> Vec<Vec<usize>> {
        (0..self.n())
            .map(|k| vec![self.q0 + 3 * k + 2, self.q0 + 3 * k + 5])
            .collect()
    }
    fn add_jacobians(&self, _t: f64, q: &[f64], qd: &[f64], dq: &mut [f64], dqd: &mut [f64]) {
        let r = self.q0..self.q0 + 3 * (self.n() + 1);
        kernels::torsional_chain_force_jacobians(&q[r.clone()], &qd[r], &self.fp, dq, dqd);
    }
    /// `t = k(φ_j − φ_i − r) + c(φ̇_j − φ̇_i)` added to g_i and subtracted
    /// from g_j, spring after spring: the element's `−T` with the same
    /// roundings, in the same order into each entry (bit-identical;
    /// tests/codegen.rs).
    fn add_forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) -> bool {
        self.add_forces_range(t, q, qd, g, 0..self.n())
    }
    /// Springs `elements` only: bodies `elements.start ..= elements.end`.
    fn add_forces_range(
        &self,
        _t: f64,
        q: &[f64],
        qd: &[f64],
        g: &mut [f64],
        elements: std::ops::Range<usize>,
    ) -> bool {
        let (a, b) = (elements.start, elements.end);
        let r = self.q0 + 3 * a..self.q0 + 3 * (b + 1);
        let fp = &self.fp[3 * a..3 * b];
        kernels::torsional_chain_forces(&q[r.clone()], &qd[r.clone()], fp, &mut g[r]);
        true
    }
}

/// Generated Jacobians of the quadratic fluid drag on bodies `body0,
/// body0 + 1, …` (the rod's segments; paper's problem B), for the Newton
/// matrix ([`crate::model::ForceKernels`]).
#[derive(Debug, Clone)]
pub struct DragJacobians {
    q0: usize,
    fp: Vec<f64>,
    /// The chain's memo of the bodies' sines and cosines, when shared.
    trig: Option<SharedTrig>,
}

impl DragJacobians {
    /// Kernels for `drags[k]` acting on body `body0 + k`.
    pub fn new(body0: usize, drags: &[Drag]) -> Self {
        Self {
            trig: None,
            q0: 3 * body0,
            fp: drags
                .iter()
                .flat_map(|d| {
                    let (at, aa, ar) = d.coefficients();
                    [at, aa, ar]
                })
                .collect(),
        }
    }
}

impl DragJacobians {
    /// Take the sines and cosines from a chain's memo ([`SharedTrig`]) when
    /// it starts at the same body and covers every drag's body; otherwise
    /// (or while another thread holds the memo) they are computed here.
    pub fn with_trig(mut self, trig: SharedTrig) -> Self {
        if trig.q0 == self.q0 && 3 * trig.n_bodies >= self.fp.len() {
            self.trig = Some(trig);
        }
        self
    }
}

impl ForceKernels for DragJacobians {
    fn name(&self) -> &str {
        "generated:drag_bodies"
    }
    fn jacobian_coordinates(&self) -> Vec<Vec<usize>> {
        (0..self.fp.len() / 3)
            .map(|k| (0..3).map(|c| self.q0 + 3 * k + c).collect())
            .collect()
    }
    fn add_jacobians(&self, _t: f64, q: &[f64], qd: &[f64], dq: &mut [f64], dqd: &mut [f64]) {
        let r = self.q0..self.q0 + self.fp.len();
        kernels::drag_bodies_force_jacobians(&q[r.clone()], &qd[r], &self.fp, dq, dqd);
    }
    /// The drag forces of every body in one loop: the angles' sines and
    /// cosines from the chain's memo (updated here) when shared, else
    /// computed (`DragJacobians::forces_on`).
    fn add_forces(&self, _t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) -> bool {
        let nb = self.fp.len() / 3;
        if let Some(t) = &self.trig {
            if let Ok(mut m) = t.memo.try_write() {
                let sc = m.update(&q[t.q0..t.q0 + 3 * t.n_bodies]);
                for k in 0..nb {
                    self.force(k, sc[2 * k], sc[2 * k + 1], qd, g);
                }
                return true;
            }
        }
        self.forces_on(0..nb, q, qd, g);
        true
    }
    /// The drag forces of bodies `elements`: the memo's sines and cosines
    /// where current (read, not updated: the two halves of the residual
    /// read it at once), else computed.
    fn add_forces_range(
        &self,
        _t: f64,
        q: &[f64],
        qd: &[f64],
        g: &mut [f64],
        elements: std::ops::Range<usize>,
    ) -> bool {
        if let Some(t) = &self.trig {
            if let Ok(m) = t.memo.try_read() {
                if m.current(&q[t.q0..], elements.clone()) {
                    for k in elements {
                        self.force(k, m.sc[2 * k], m.sc[2 * k + 1], qd, g);
                    }
                    return true;
                }
            }
        }
        self.forces_on(elements, q, qd, g);
        true
    }
}

impl DragJacobians {
    /// The drag force of body `k` with its angle's sine and cosine added
    /// to `g`: the roundings of `Drag::force` (bit-identical;
    /// tests/codegen.rs).
    fn force(&self, k: usize, sn: f64, cs: f64, qd: &[f64], g: &mut [f64]) {
        let (o, a) = (self.q0 + 3 * k, 3 * k);
        let f = drag_force(
            (self.fp[a], self.fp[a + 1], self.fp[a + 2]),
            sn,
            cs,
            [qd[o], qd[o + 1], qd[o + 2]],
        );
        g[o] += f[0];
        g[o + 1] += f[1];
        g[o + 2] += f[2];
    }
    /// The drag forces of bodies `ks`, the sines and cosines computed four
    /// at a time ([`sin_cos4`], else [`sin_cos`]; the same bits).
    fn forces_on(&self, ks: std::ops::Range<usize>, q: &[f64], qd: &[f64], g: &mut [f64]) {
        let mut k = ks.start;
        while k < ks.end {
            let m = (ks.end - k).min(4);
            let mut x = [0.0; 4];
            for (l, xl) in x.iter_mut().enumerate().take(m) {
                *xl = q[self.q0 + 3 * (k + l) + 2];
            }
            let sc4 = if m == 4 { sin_cos4(x) } else { None };
            for l in 0..m {
                let (sn, cs) = match sc4 {
                    Some((s, c)) => (s[l], c[l]),
                    None => sin_cos(x[l]),
                };
                self.force(k + l, sn, cs, qd, g);
            }
            k += m;
        }
    }
}

/// Generated Jacobians of the Hunt–Crossley wall contacts of bodies `body0,
/// body0 + 1, …` (the rod's segment corners against the channel walls), for
/// the Newton matrix ([`crate::model::ForceKernels`]).
#[derive(Debug, Clone)]
pub struct ContactJacobians {
    q0: usize,
    fp: Vec<f64>,
    /// The elements, for their forces in one loop, and their wall tests.
    contacts: Vec<WallContact>,
    clearance: Vec<Clearance>,
}

impl ContactJacobians {
    /// Kernels for `contacts[k]` of body `body0 + k`.
    pub fn new(body0: usize, contacts: &[WallContact]) -> Self {
        Self {
            q0: 3 * body0,
            contacts: contacts.to_vec(),
            clearance: contacts.iter().map(WallContact::clearance).collect(),
            fp: contacts
                .iter()
                .flat_map(|e| {
                    [
                        0.5 * e.width,
                        0.5 * e.length,
                        e.left_wall,
                        e.right_wall,
                        e.stiffness,
                        e.damping,
                        e.friction,
                        e.slip_velocity,
                    ]
                })
                .collect(),
        }
    }
}

impl ForceKernels for ContactJacobians {
    fn name(&self) -> &str {
        "generated:contact_bodies"
    }
    fn jacobian_coordinates(&self) -> Vec<Vec<usize>> {
        (0..self.fp.len() / 8)
            .map(|k| (0..3).map(|c| self.q0 + 3 * k + c).collect())
            .collect()
    }
    fn add_jacobians(&self, _t: f64, q: &[f64], qd: &[f64], dq: &mut [f64], dqd: &mut [f64]) {
        let r = self.q0..self.q0 + 3 * (self.fp.len() / 8);
        kernels::contact_bodies_force_jacobians(&q[r.clone()], &qd[r], &self.fp, dq, dqd);
    }
    /// The contact forces in one loop over the elements: the segments clear
    /// of both walls (most of a long rod's) are skipped by the elements' own
    /// first test, made here in the loop; the others call their element's
    /// `add_forces`. The same operations in the same order as the elements
    /// called one by one.
    fn add_forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) -> bool {
        self.add_forces_range(t, q, qd, g, 0..self.contacts.len())
    }
    fn add_forces_range(
        &self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        g: &mut [f64],
        elements: std::ops::Range<usize>,
    ) -> bool {
        for k in elements {
            if !self.clearance[k].clear(q[self.q0 + 3 * k]) {
                ForceElement::add_forces(&self.contacts[k], t, q, qd, g);
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ConstraintKernels;

    /// The drag forces from the chain's shared memo of sines and cosines
    /// have the bits of the drag's own: with the memo cold, warmed by the
    /// constraints at the same q (a hit), and left at another q with only
    /// some angles changed; a memo of other bodies is not taken.
    #[test]
    fn drag_with_the_chain_memo_has_the_bits_of_its_own_trigonometry() {
        let nb = 37;
        let (hinge, half) = (0.05, 0.05);
        let points = vec![[0.0, hinge, 0.0, -hinge]; nb - 1];
        let chain = ChainKernels::new(0, &points, None);
        let drags: Vec<Drag> = (0..nb)
            .map(|b| Drag {
                body: b,
                width: 0.01,
                length: 2.0 * half,
                fluid_density: 1000.0,
                c_transverse: 1.2,
                c_skin: 0.02,
                c_end: 1.0,
                end_face: b == 0,
            })
            .collect();
        let own = DragJacobians::new(0, &drags);
        let shared = DragJacobians::new(0, &drags).with_trig(chain.shared_trig());
        assert!(shared.trig.is_some());
        assert!(DragJacobians::new(1, &drags[1..])
            .with_trig(chain.shared_trig())
            .trig
            .is_none());
        let mut seed = 17u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 4.0 - 2.0
        };
        let n = 3 * nb;
        let mut q: Vec<f64> = (0..n).map(|_| next()).collect();
        let qd: Vec<f64> = (0..n).map(|_| next()).collect();
        let mut phi = vec![0.0; 2 * (nb - 1)];
        for case in 0..3 {
            match case {
                // the constraints first: the drag hits the memo
                1 => chain.phi(&q, 0.0, &mut phi),
                // a few angles changed since the memo was filled
                2 => {
                    for b in [0, 5, 6, 36] {
                        q[3 * b + 2] += 0.3;
                    }
                }
                _ => {}
            }
            let (mut ga, mut gb) = (vec![0.0; n], vec![0.0; n]);
            assert!(own.add_forces(0.0, &q, &qd, &mut ga));
            assert!(shared.add_forces(0.0, &q, &qd, &mut gb));
            for (k, (a, b)) in ga.iter().zip(&gb).enumerate() {
                assert_eq!(a.to_bits(), b.to_bits(), "case {case}, g[{k}]");
            }
        }
    }
}
