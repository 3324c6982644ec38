//! Generated kernels of a revolute chain (the rod), optionally with one
//! ground revolute (the N-link pendulum, the cantilever).

use super::memo::{SharedTrig, TrigMemo};
use super::{arr, arr_mut, kernels, revolute};
use crate::model::{BodyRef, BodyTrig, ConstraintKernels, ConstraintTerms, HalfTask, System};
use crate::trig::sin_cos;

/// The kernel `$gb` when the ground is the joint's side i, else `$bg`
/// (the same kernel of the other orientation).
macro_rules! side {
    ($joint:expr, $gb:ident, $bg:ident) => {
        if $joint.ground_is_i {
            kernels::$gb
        } else {
            kernels::$bg
        }
    };
}

/// `memoised!(chain; f_sc(q, args…))`: with `qc` the chain's part of the
/// system's `q`, `kernels::f_sc(qc, sc, args…)` with the sines and cosines
/// `sc` of its angles from the chain's memo (updated here, shared with Φ,
/// Φ_q, γ and the force kernels at the same q), or computed afresh by
/// `fresh_trig` when another thread holds the memo: the same bits either
/// way, so a run's bits do not depend on which concurrent task took the
/// memo.
macro_rules! memoised {
    ($chain:expr; $sc:ident($q:expr $(, $arg:expr)*)) => {{
        let qc = $chain.chain_q($q);
        match $chain.memo.try_write() {
            Ok(mut m) => kernels::$sc(qc, m.update(qc) $(, $arg)*),
            Err(_) => kernels::$sc(qc, &fresh_trig(qc) $(, $arg)*),
        }
    }};
}

/// `[sin φ_b, cos φ_b]` of every body of `q` (3 coordinates per body) by
/// [`sin_cos`], the function whose values the memo holds. (The plain
/// generated kernels call the standard library's `sin_cos`, which differs
/// from it in the last bit for some angles.)
fn fresh_trig(q: &[f64]) -> Vec<f64> {
    q.chunks_exact(3)
        .flat_map(|b| {
            let (s, c) = sin_cos(b[2]);
            [s, c]
        })
        .collect()
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
        side!(self, revolute_gb_phi, revolute_bg_phi)(qb, &self.params, &[], o);
    }
    fn jacobian(&self, q: &[f64], vals: &mut [f64]) {
        let (qb, o) = (arr(&q[self.off..]), arr_mut(&mut vals[self.jac0..]));
        side!(self, revolute_gb_jacobian, revolute_bg_jacobian)(qb, &self.params, &[], o);
    }
    fn phi_t(&self, q: &[f64], out: &mut [f64]) {
        let (qb, o) = (arr(&q[self.off..]), arr_mut(&mut out[self.row0..]));
        side!(self, revolute_gb_phi_t, revolute_bg_phi_t)(qb, &self.params, &[], o);
    }
    fn gamma(&self, q: &[f64], qd: &[f64], out: &mut [f64]) {
        let (qb, vb) = (arr(&q[self.off..]), arr(&qd[self.off..]));
        let o = arr_mut(&mut out[self.row0..]);
        side!(self, revolute_gb_gamma, revolute_bg_gamma)(qb, vb, &self.params, &[], o);
    }
    fn eval(&self, q: &[f64], qd: &[f64], out: ConstraintTerms<'_>) {
        let (qb, vb) = (arr(&q[self.off..]), arr(&qd[self.off..]));
        let (p, v, g) = (
            arr_mut(&mut out.phi[self.row0..]),
            arr_mut(&mut out.vals[self.jac0..]),
            arr_mut(&mut out.gamma[self.row0..]),
        );
        side!(self, revolute_gb_eval, revolute_bg_eval)(qb, vb, &self.params, &[], p, v, g);
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
        side!(self, revolute_gb_phi, revolute_bg_phi)(qb, &self.params, &[], o);
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
        side!(self, revolute_gb_hessian, revolute_bg_hessian)(qb, &self.params, &[], l, o);
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

    /// `revolute_chain_phi_tmul_sc` of the chain's joints `ks` (`qc`, `gc`:
    /// the chain's coordinates; `l`, `o`: those joints' rows), joint after
    /// joint: the sines and cosines of the joints whose two bodies `trig`
    /// holds from it, of the others (one at each end of a half) by
    /// [`sin_cos`]; without `trig`, from the memo where current, else
    /// `fresh_trig`. The same operations and bits every way.
    fn phi_tmul_chain_joints(
        &self,
        qc: &[f64],
        ks: std::ops::Range<usize>,
        l: &[f64],
        o: &mut [f64],
        gc: &mut [f64],
        trig: Option<BodyTrig<'_>>,
    ) {
        let b0 = self.q0 / 3;
        // the joints ja..jb whose bodies ja..=jb `trig` holds
        let held = trig.map(|t| {
            let first = (t.body0.saturating_sub(b0)).max(ks.start);
            let end = (t.body0 + t.sc.len() / 2)
                .saturating_sub(b0 + 1)
                .min(ks.end);
            (t, first, end.max(first))
        });
        let mut run = |js: std::ops::Range<usize>, sc: &[f64]| {
            let r = 2 * (js.start - ks.start)..2 * (js.end - ks.start);
            kernels::revolute_chain_phi_tmul_sc(
                &qc[3 * js.start..3 * (js.end + 1)],
                sc,
                &self.params[4 * js.start..4 * js.end],
                &l[r.clone()],
                &mut o[r],
                &mut gc[3 * js.start..3 * (js.end + 1)],
            )
        };
        match held {
            Some((t, ja, jb)) if ja < jb => {
                let one = |j: usize| {
                    let ((s0, c0), (s1, c1)) = (sin_cos(qc[3 * j + 2]), sin_cos(qc[3 * j + 5]));
                    [s0, c0, s1, c1]
                };
                for j in ks.start..ja {
                    run(j..j + 1, &one(j));
                }
                let sc = t.of(b0 + ja..b0 + jb + 1).expect("held bodies");
                run(ja..jb, sc);
                for j in jb..ks.end {
                    run(j..j + 1, &one(j));
                }
            }
            _ => match self.memo.try_read() {
                Ok(m) if m.current(qc, ks.start..ks.end + 1) => {
                    run(ks.clone(), &m.sc[2 * ks.start..2 * (ks.end + 1)])
                }
                _ => {
                    let qk = &qc[3 * ks.start..3 * (ks.end + 1)];
                    run(ks.clone(), &fresh_trig(qk))
                }
            },
        }
    }

    /// The memo of the chain's sines and cosines, to share with force
    /// kernels on the chain's bodies ([`SharedTrig`]).
    pub(crate) fn shared_trig(&self) -> SharedTrig {
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
}

impl ConstraintKernels for ChainKernels {
    fn jacobian_pattern(&self) -> Vec<(usize, usize)> {
        self.pattern()
    }
    fn has_hessian(&self) -> bool {
        true
    }
    /// (Φ_qᵀλ)_q joint after joint (2 values per chain joint, 1 for the
    /// ground joint).
    fn add_hessian(&self, q: &[f64], _t: f64, lambda: &[f64], vals: &mut [f64]) {
        let nh = 2 * self.n_joints;
        let (chain_at, ground_at) = match &self.ground {
            Some(g) if g.row0 == 0 => (1, 0),
            _ => (0, nh),
        };
        let (p, l) = (&self.params, &lambda[self.chain_rows()]);
        let o = &mut vals[chain_at..chain_at + nh];
        memoised!(self; revolute_chain_hessian_sc(q, p, l, o));
        if let Some(g) = &self.ground {
            g.add_hessian(q, lambda, &mut vals[ground_at..ground_at + 1]);
        }
    }
    fn evaluate(&self, q: &[f64], qd: &[f64], _t: f64, out: ConstraintTerms<'_>) {
        // sines and cosines computed once per body instead of once per
        // function and joint side
        let (r, v) = (self.chain_rows(), self.chain_vals());
        kernels::revolute_chain_eval(
            self.chain_q(q),
            self.chain_q(qd),
            &self.params,
            &mut out.phi[r.clone()],
            &mut out.vals[v],
            &mut out.gamma[r],
        );
        if let Some(g) = &self.ground {
            g.eval(q, qd, out);
        }
    }
    fn name(&self) -> &str {
        &self.name
    }
    fn phi(&self, q: &[f64], _t: f64, out: &mut [f64]) {
        let o = &mut out[self.chain_rows()];
        memoised!(self; revolute_chain_phi_sc(q, &self.params, o));
        if let Some(g) = &self.ground {
            g.phi(q, out);
        }
    }
    fn jacobian_values(&self, q: &[f64], _t: f64, vals: &mut [f64]) {
        let o = &mut vals[self.chain_vals()];
        memoised!(self; revolute_chain_jacobian_sc(q, &self.params, o));
        if let Some(g) = &self.ground {
            g.jacobian(q, vals);
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
        let (p, l) = (&self.params, &lambda[rows.clone()]);
        let (o, gc) = (
            &mut phi[rows],
            &mut g[self.q0..self.q0 + 3 * (self.n_joints + 1)],
        );
        memoised!(self; revolute_chain_phi_tmul_sc(q_all, p, l, o, gc));
        if let Some(gj) = &self.ground {
            gj.phi_tmul(q_all, lambda, phi, g);
        }
        true
    }
    /// The residual's halves with the memo in two parts at `split_body`:
    /// each half updates its bodies' sines and cosines and then runs with
    /// them, in one hand-over (`TrigMemo::update_in_halves`); without
    /// the memo (another thread holds it, or the split is not inside the
    /// chain) the halves run without it.
    fn in_halves(&self, q: &[f64], _t: f64, split_body: usize, lo: HalfTask<'_>, hi: HalfTask<'_>) {
        let (b0, nb) = (self.q0 / 3, self.n_joints + 1);
        let k = split_body.wrapping_sub(b0);
        if (1..nb).contains(&k) {
            if let Ok(mut m) = self.memo.try_write() {
                m.update_in_halves(
                    self.chain_q(q),
                    k,
                    |sc| lo(Some(BodyTrig { body0: b0, sc })),
                    |sc| hi(Some(BodyTrig { body0: b0 + k, sc })),
                );
                return;
            }
        }
        crate::parallel::join_if(true, || lo(None), || hi(None));
    }
    /// `phi_tmul` of the joints `joints`: the chain's joints among them
    /// (`ChainKernels::phi_tmul_chain_joints`), then the ground joint
    /// when among them — the order of `phi_tmul`.
    fn phi_tmul_joints(
        &self,
        q_all: &[f64],
        _t: f64,
        lambda: &[f64],
        phi: &mut [f64],
        g: &mut [f64],
        joints: std::ops::Range<usize>,
        trig: Option<BodyTrig<'_>>,
    ) -> bool {
        let nj = self.n_joints;
        let ground_first = matches!(&self.ground, Some(gj) if gj.row0 == 0);
        // local index of chain joint 0, and the chain joints in the range
        let c0 = usize::from(ground_first);
        let ka = joints.start.saturating_sub(c0).min(nj);
        let kb = joints.end.saturating_sub(c0).min(nj);
        if ka < kb {
            let r = 2 * (ka + c0 - joints.start)..2 * (kb + c0 - joints.start);
            let (l, o) = (&lambda[r.clone()], &mut phi[r]);
            let gc = &mut g[self.q0..self.q0 + 3 * (nj + 1)];
            self.phi_tmul_chain_joints(self.chain_q(q_all), ka..kb, l, o, gc, trig);
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
    fn gamma(&self, q: &[f64], qd: &[f64], _t: f64, out: &mut [f64]) {
        let (qdc, o) = (self.chain_q(qd), &mut out[self.chain_rows()]);
        memoised!(self; revolute_chain_gamma_sc(q, qdc, &self.params, o));
        if let Some(g) = &self.ground {
            g.gamma(q, qd, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Φ, Φ_q, (Φ_qᵀλ)_q, γ and Φ_qᵀλ of a chain, in that order.
    fn terms(k: &ChainKernels, q: &[f64], qd: &[f64], lam: &[f64]) -> Vec<Vec<f64>> {
        let (m, nv) = (2 * k.n_joints, 8 * k.n_joints);
        let (mut phi, mut vals, mut hess) = (vec![0.0; m], vec![0.0; nv], vec![0.0; m]);
        let (mut gamma, mut phi2, mut g) = (vec![0.0; m], vec![0.0; m], vec![0.0; q.len()]);
        k.phi(q, 0.0, &mut phi);
        k.jacobian_values(q, 0.0, &mut vals);
        k.add_hessian(q, 0.0, lam, &mut hess);
        k.gamma(q, qd, 0.0, &mut gamma);
        k.phi_tmul(q, 0.0, lam, &mut phi2, &mut g);
        let (mut phi3, mut g3) = (vec![0.0; m], vec![0.0; q.len()]);
        k.phi_tmul_joints(q, 0.0, lam, &mut phi3, &mut g3, 0..k.n_joints, None);
        vec![phi, vals, hess, gamma, phi2, g, phi3, g3]
    }

    /// The chain's kernels give the same bits with the sines and cosines
    /// from the memo and computed afresh (when another thread holds the
    /// memo), so a run's bits do not depend on which task won the memo.
    #[test]
    fn the_memo_and_the_fresh_sines_give_the_same_bits() {
        let nb = 257;
        let joints = vec![[0.05, 0.0, -0.05, 0.0]; nb - 1];
        let k = ChainKernels::new(0, &joints, None);
        let x = |i: usize| (i as f64 * 0.7548776662466927).fract();
        let q: Vec<f64> = (0..3 * nb).map(|i| 40.0 * x(i) - 20.0).collect();
        let qd: Vec<f64> = (0..3 * nb).map(|i| 3.0 * x(i + 7) - 1.5).collect();
        let lam: Vec<f64> = (0..2 * (nb - 1)).map(|i| x(i + 3) - 0.5).collect();
        // the angles are ones where the standard library's sines differ
        // from the memo's (`trig::sin_cos`, within an ulp), so the test
        // could fail
        let differ = (0..nb).filter(|&b| q[3 * b + 2].sin_cos() != sin_cos(q[3 * b + 2]));
        assert!(differ.count() > 0);
        let with_memo = terms(&k, &q, &qd, &lam);
        let memo = k.memo.clone();
        let held = memo.write().unwrap();
        let fresh = terms(&k, &q, &qd, &lam);
        drop(held);
        for (a, b) in with_memo.iter().zip(&fresh) {
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(a), bits(b));
        }
    }
}
