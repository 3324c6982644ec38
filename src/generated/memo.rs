//! The memo of a chain's sines and cosines, shared by its constraint
//! kernels and the force kernels on the same bodies.

use crate::trig::{sin_cos, sin_cos4_lanes};

/// Sines and cosines of the chain's body angles, memoised per body on the
/// exact bits of φ: the formulation asks for Φ_q, γ, Φ and Φ_t at the same
/// q one after the other, and the trigonometry is most of their cost
/// ([`sin_cos`](crate::trig::sin_cos): one argument reduction for both).
#[derive(Debug)]
pub(super) struct TrigMemo {
    phi_bits: Vec<u64>,
    pub(super) sc: Vec<f64>,
}

impl TrigMemo {
    pub(super) fn new(n_bodies: usize) -> Self {
        // NaN sentinel: a NaN angle "hits" and gets NaN sines, as sin_cos would.
        Self {
            phi_bits: vec![f64::NAN.to_bits(); n_bodies],
            sc: vec![f64::NAN; 2 * n_bodies],
        }
    }
    /// Are the sines and cosines of bodies `ks` those of `q`'s angles
    /// (bits compared)? For readers that share the memo without updating it.
    pub(super) fn current(&self, q: &[f64], ks: std::ops::Range<usize>) -> bool {
        ks.into_iter()
            .all(|k| self.phi_bits[k] == q[3 * k + 2].to_bits())
    }
    pub(super) fn update(&mut self, q: &[f64]) -> &[f64] {
        // two halves concurrently for long chains: each angle's sin_cos is
        // independent of the others, so the bits do not depend on threads
        let nb = self.phi_bits.len();
        if nb >= TRIG_PARALLEL_MIN_BODIES {
            self.update_in_halves(q, nb / 2, |_| (), |_| ());
        } else {
            trig_update(q, 0, &mut self.phi_bits, &mut self.sc);
        }
        &self.sc
    }
    /// The memo in two parts, bodies below `k` and from `k` (`k` ≤ the
    /// bodies), each updated from `q` and then handed to `lo` or `hi`
    /// (`[sin, cos]` of the part's bodies), the two concurrently in one
    /// hand-over ([`crate::parallel::join_if`]): the same bits as
    /// [`TrigMemo::update`] then `lo` and `hi`.
    pub(super) fn update_in_halves<RA: Send, RB: Send>(
        &mut self,
        q: &[f64],
        k: usize,
        lo: impl FnOnce(&[f64]) -> RA + Send,
        hi: impl FnOnce(&[f64]) -> RB + Send,
    ) -> (RA, RB) {
        let (bits_lo, bits_hi) = self.phi_bits.split_at_mut(k);
        let (sc_lo, sc_hi) = self.sc.split_at_mut(2 * k);
        crate::parallel::join_if(
            true,
            || {
                trig_update(q, 0, bits_lo, sc_lo);
                lo(sc_lo)
            },
            || {
                trig_update(q, k, bits_hi, sc_hi);
                hi(sc_hi)
            },
        )
    }
}

/// Chains of at least this many bodies update their sines and cosines in
/// two concurrent halves ([`TrigMemo`]).
const TRIG_PARALLEL_MIN_BODIES: usize = 2000;

/// A chain's memo of sines and cosines (`ChainKernels::shared_trig`),
/// for force kernels on the same bodies (`DragJacobians::with_trig`):
/// the residual evaluates the forces and the constraint terms at the same
/// q, so the angles' sines and cosines are computed once for both. Same
/// bits: the memo holds [`sin_cos`](crate::trig::sin_cos)'s values.
#[derive(Debug, Clone)]
pub struct SharedTrig {
    pub(super) memo: std::sync::Arc<std::sync::RwLock<TrigMemo>>,
    /// First coordinate of the first body.
    pub(super) q0: usize,
    pub(super) n_bodies: usize,
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
