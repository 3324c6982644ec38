//! Generated Jacobians of force elements for the Newton matrix: the
//! torsional spring–dampers along a chain, drag on every body, wall
//! contacts.

use super::kernels;
use super::memo::SharedTrig;
use crate::forces::drag_force;
use crate::forces::Clearance;
use crate::forces::{Drag, TorsionalSpringDamper, WallContact};
use crate::model::{BodyTrig, ForceElement, ForceKernels, StateView};
use crate::trig::{sin_cos, sin_cos4};
use std::ops::Range;

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
    fn add_jacobians(&self, x: StateView<'_>, dq: &mut [f64], dqd: &mut [f64]) {
        let StateView { q, qd, .. } = x;
        let r = self.q0..self.q0 + 3 * (self.n() + 1);
        kernels::torsional_chain_force_jacobians(&q[r.clone()], &qd[r], &self.fp, dq, dqd);
    }
    /// `t = k(φ_j − φ_i − r) + c(φ̇_j − φ̇_i)` added to g_i and subtracted
    /// from g_j, spring after spring: the element's `−T` with the same
    /// roundings, in the same order into each entry (bit-identical;
    /// tests/model/codegen.rs).
    fn add_forces(&self, x: StateView<'_>, g: &mut [f64]) -> bool {
        self.add_forces_range(x, g, 0..self.n(), None)
    }
    /// Springs `elements` only: bodies `elements.start ..= elements.end`.
    fn add_forces_range(
        &self,
        x: StateView<'_>,
        g: &mut [f64],
        elements: Range<usize>,
        _trig: Option<BodyTrig<'_>>,
    ) -> bool {
        let StateView { q, qd, .. } = x;
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
    pub(crate) fn with_trig(mut self, trig: SharedTrig) -> Self {
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
        body_blocks(self.q0, self.fp.len() / 3)
    }
    fn add_jacobians(&self, x: StateView<'_>, dq: &mut [f64], dqd: &mut [f64]) {
        let StateView { q, qd, .. } = x;
        let r = self.q0..self.q0 + self.fp.len();
        kernels::drag_bodies_force_jacobians(&q[r.clone()], &qd[r], &self.fp, dq, dqd);
    }
    /// The drag forces of every body in one loop: the angles' sines and
    /// cosines from the chain's memo (updated here) when shared, else
    /// computed (`DragJacobians::forces_on`).
    fn add_forces(&self, x: StateView<'_>, g: &mut [f64]) -> bool {
        let (StateView { q, qd, .. }, nb) = (x, self.fp.len() / 3);
        if let Some(t) = &self.trig {
            if let Ok(mut m) = t.memo.try_write() {
                let sc = m.update(&q[t.q0..t.q0 + 3 * t.n_bodies]);
                self.forces_with(0..nb, &sc[..2 * nb], qd, g);
                return true;
            }
        }
        self.forces_on(0..nb, q, qd, g);
        true
    }
    /// The drag forces of bodies `elements`: the sines and cosines handed
    /// to the half (`trig`) when it holds those bodies, else the memo's
    /// where current (read, not updated), else computed.
    fn add_forces_range(
        &self,
        x: StateView<'_>,
        g: &mut [f64],
        elements: Range<usize>,
        trig: Option<BodyTrig<'_>>,
    ) -> bool {
        let StateView { q, qd, .. } = x;
        let b0 = self.q0 / 3;
        if let Some(sc) = trig.and_then(|t| t.of(b0 + elements.start..b0 + elements.end)) {
            self.forces_with(elements, sc, qd, g);
            return true;
        }
        if let Some(t) = &self.trig {
            if let Ok(m) = t.memo.try_read() {
                if m.current(&q[t.q0..], elements.clone()) {
                    let sc = &m.sc[2 * elements.start..2 * elements.end];
                    self.forces_with(elements, sc, qd, g);
                    return true;
                }
            }
        }
        self.forces_on(elements, q, qd, g);
        true
    }
}

impl DragJacobians {
    /// The drag forces of bodies `ks` added to `g`, from their angles'
    /// sines and cosines `sc` (`[sin, cos]` per body of `ks`): the
    /// roundings of `Drag::force`, body after body (bit-identical;
    /// tests/model/codegen.rs).
    fn forces_with(&self, ks: Range<usize>, sc: &[f64], qd: &[f64], g: &mut [f64]) {
        let r = self.q0 + 3 * ks.start..self.q0 + 3 * ks.end;
        let fp = &self.fp[3 * ks.start..3 * ks.end];
        assert!(sc.len() == 2 * ks.len() && r.end <= qd.len().min(g.len()));
        let bodies = g[r.clone()].chunks_exact_mut(3).zip(qd[r].chunks_exact(3));
        for ((gk, v), (a, sc)) in bodies.zip(fp.chunks_exact(3).zip(sc.chunks_exact(2))) {
            let f = drag_force((a[0], a[1], a[2]), sc[0], sc[1], [v[0], v[1], v[2]]);
            gk[0] += f[0];
            gk[1] += f[1];
            gk[2] += f[2];
        }
    }
    /// The drag forces of bodies `ks`, the sines and cosines computed four
    /// at a time ([`sin_cos4`], else [`sin_cos`]; the same bits).
    fn forces_on(&self, ks: Range<usize>, q: &[f64], qd: &[f64], g: &mut [f64]) {
        let mut k = ks.start;
        while k < ks.end {
            let m = (ks.end - k).min(4);
            let mut x = [0.0; 4];
            for (l, xl) in x.iter_mut().enumerate().take(m) {
                *xl = q[self.q0 + 3 * (k + l) + 2];
            }
            let sc4 = if m == 4 { sin_cos4(x) } else { None };
            let mut sc = [0.0; 8];
            for l in 0..m {
                (sc[2 * l], sc[2 * l + 1]) = match sc4 {
                    Some((s, c)) => (s[l], c[l]),
                    None => sin_cos(x[l]),
                };
            }
            self.forces_with(k..k + m, &sc[..2 * m], qd, g);
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
    /// The one clearance of every element when they all have the same
    /// (the rod's segments), read from registers in the loops.
    uniform: Option<Clearance>,
}

impl ContactJacobians {
    /// Kernels for `contacts[k]` of body `body0 + k`.
    pub fn new(body0: usize, contacts: &[WallContact]) -> Self {
        Self {
            q0: 3 * body0,
            contacts: contacts.to_vec(),
            clearance: contacts.iter().map(WallContact::clearance).collect(),
            uniform: contacts
                .first()
                .map(WallContact::clearance)
                .filter(|c| contacts.iter().all(|e| e.clearance() == *c)),
            fp: contacts
                .iter()
                .flat_map(|e| {
                    [
                        0.5 * e.width,
                        0.5 * e.length,
                        e.left_wall,
                        e.right_wall,
                        e.law.stiffness,
                        e.law.damping,
                        e.law.friction,
                        e.law.slip_velocity,
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
        body_blocks(self.q0, self.fp.len() / 8)
    }
    /// The generated element kernel for the segments that may touch a
    /// wall only: a segment clear of both walls (the elements' own test,
    /// as in their forces) has every corner at δ ≤ 0, where the kernel
    /// adds zeros, so skipping it leaves `dq`, `dqd` as they were (most
    /// of a long rod's segments, at every factorisation).
    fn add_jacobians(&self, x: StateView<'_>, dq: &mut [f64], dqd: &mut [f64]) {
        let StateView { q, qd, .. } = x;
        let ne = self.fp.len() / 8;
        assert!(dq.len() >= 9 * ne && dqd.len() >= 9 * ne);
        for (k, clear) in self.clearance.iter().enumerate() {
            let o = self.q0 + 3 * k;
            if clear.clear(q[o]) {
                continue;
            }
            let qk: &[f64; 3] = q[o..o + 3].try_into().expect("3 coordinates");
            let qdk: &[f64; 3] = qd[o..o + 3].try_into().expect("3 velocities");
            let pk: &[f64; 8] = self.fp[8 * k..8 * k + 8].try_into().expect("8 parameters");
            let dqk: &mut [f64; 9] = (&mut dq[9 * k..9 * k + 9]).try_into().expect("a 3×3 block");
            let dqdk: &mut [f64; 9] = (&mut dqd[9 * k..9 * k + 9])
                .try_into()
                .expect("a 3×3 block");
            kernels::contact_bodies_element_jacobians(qk, qdk, pk, dqk, dqdk);
        }
    }
    /// The contact forces in one loop over the elements: the segments clear
    /// of both walls (most of a long rod's) are skipped by the elements' own
    /// first test, made here in the loop; the others call their element's
    /// `add_forces`. The same operations in the same order as the elements
    /// called one by one.
    fn add_forces(&self, x: StateView<'_>, g: &mut [f64]) -> bool {
        self.add_forces_range(x, g, 0..self.contacts.len(), None)
    }
    fn add_forces_range(
        &self,
        x: StateView<'_>,
        g: &mut [f64],
        elements: Range<usize>,
        _trig: Option<BodyTrig<'_>>,
    ) -> bool {
        let StateView { t, q, qd } = x;
        for k in elements {
            let clear = match &self.uniform {
                Some(c) => c.clear(q[self.q0 + 3 * k]),
                None => self.clearance[k].clear(q[self.q0 + 3 * k]),
            };
            if !clear {
                ForceElement::add_forces(&self.contacts[k], t, q, qd, g);
            }
        }
        true
    }
}

/// The Jacobian blocks of `n` one-body elements on consecutive bodies from
/// coordinate `q0`: each body's `x, y, φ`.
fn body_blocks(q0: usize, n: usize) -> Vec<Vec<usize>> {
    (0..n)
        .map(|k| (0..3).map(|c| q0 + 3 * k + c).collect())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::RodParams;
    use crate::generated::ChainKernels;
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
        let mut u = crate::numeric::test_uniform(17);
        let mut next = move || u() * 4.0 - 2.0;
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
            let x = StateView {
                t: 0.0,
                q: &q,
                qd: &qd,
            };
            assert!(own.add_forces(x, &mut ga));
            assert!(shared.add_forces(x, &mut gb));
            for (k, (a, b)) in ga.iter().zip(&gb).enumerate() {
                assert_eq!(a.to_bits(), b.to_bits(), "case {case}, g[{k}]");
            }
        }
    }

    /// The contact Jacobians that skip the segments clear of both walls
    /// have the bits of the generated kernel over every segment: at random
    /// states with some segments pressed into a wall (moving, rotating)
    /// and some clear of both, from a body other than the first, into
    /// buffers that already hold values.
    #[test]
    fn contact_jacobians_skipping_clear_segments_have_the_bits_of_the_full_kernel() {
        let (nb, body0) = (40, 3);
        let contacts: Vec<WallContact> = (0..nb)
            .map(|k| RodParams::problem_b(500).contact_element(body0 + k, k))
            .collect();
        let kern = ContactJacobians::new(body0, &contacts);
        let mut u = crate::numeric::test_uniform(99);
        let mut next = move |lo: f64, hi: f64| lo + (hi - lo) * u();
        let n = 3 * (body0 + nb);
        let (mut touching, mut clear) = (0, 0);
        for _ in 0..20 {
            let mut q: Vec<f64> = (0..n).map(|_| next(-1.0, 1.0)).collect();
            let qd: Vec<f64> = (0..n).map(|_| next(-1.0, 1.0)).collect();
            for (k, contact) in contacts.iter().enumerate() {
                let o = 3 * (body0 + k);
                q[o] = next(-0.02, 0.02);
                q[o + 2] = next(-0.3, 0.3);
                if contact.clear_of_walls(q[o]) {
                    clear += 1;
                } else {
                    touching += 1;
                }
            }
            let base_q: Vec<f64> = (0..9 * nb).map(|_| next(-1.0, 1.0)).collect();
            let base_qd: Vec<f64> = (0..9 * nb).map(|_| next(-1.0, 1.0)).collect();
            let (mut dq, mut dqd) = (base_q.clone(), base_qd.clone());
            kern.add_jacobians(
                StateView {
                    t: 0.0,
                    q: &q,
                    qd: &qd,
                },
                &mut dq,
                &mut dqd,
            );
            let (mut want_q, mut want_qd) = (base_q, base_qd);
            let r = 3 * body0..n;
            kernels::contact_bodies_force_jacobians(
                &q[r.clone()],
                &qd[r],
                &kern.fp,
                &mut want_q,
                &mut want_qd,
            );
            for (k, (a, b)) in dq.iter().zip(&want_q).enumerate() {
                assert_eq!(a.to_bits(), b.to_bits(), "dq[{k}]");
            }
            for (k, (a, b)) in dqd.iter().zip(&want_qd).enumerate() {
                assert_eq!(a.to_bits(), b.to_bits(), "dqd[{k}]");
            }
        }
        assert!(
            touching > 100 && clear > 100,
            "{touching} near a wall, {clear} clear"
        );
    }
}
