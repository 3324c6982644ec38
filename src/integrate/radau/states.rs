//! The stage states of a Radau IIA step: `Q_i = q_n + c_i h v_n +
//! h² Σ_j (𝔄²)_ij A_j`, `V_i = v_n + h Σ_j 𝔄_ij A_j` (the module docs of
//! [`super`], "Stages"), element-wise and in two halves for large n.

use super::stages::{dot, RadauStages, Tableau};
use super::Run;
use crate::parallel::Halve;

/// What stages `stages` of a step of `h` are made of ([`stage_states_into`],
/// [`stage_rows`]): the tableau, the step's start `q`, `v` and the stage
/// accelerations `st` (all of one length: the coordinates a pass covers).
#[derive(Clone)]
pub(super) struct StageBase<'a, const S: usize> {
    pub(super) tab: &'a RadauStages<S>,
    pub(super) stages: std::ops::Range<usize>,
    pub(super) h: f64,
    pub(super) q: &'a [f64],
    pub(super) v: &'a [f64],
    pub(super) st: [&'a [f64]; S],
}

impl<const S: usize> Halve for StageBase<'_, S> {
    fn halve(self, k: usize) -> (Self, Self) {
        let ((q0, q1), (v0, v1)) = (self.q.halve(k), self.v.halve(k));
        let (st0, st1) = self.st.halve(k);
        let lo = StageBase {
            q: q0,
            v: v0,
            st: st0,
            ..self.clone()
        };
        (
            lo,
            StageBase {
                q: q1,
                v: v1,
                st: st1,
                ..self
            },
        )
    }
}

/// The stages of `base` (`K` of them) into `qs[..]`, `vs[..]` (one per
/// stage, of the length of `base.q`):
/// `Q_i = q_n + c_i h v_n + h² Σ_j (𝔄²)_ij A_j`, `V_i = v_n + h Σ_j 𝔄_ij A_j`;
/// element-wise, in two halves concurrently for large n (one hand-over
/// for all `K` stages, each half stage after stage: [`stage_rows`]).
pub(super) fn stage_states_into<const S: usize, const K: usize>(
    base: StageBase<'_, S>,
    qs: [&mut [f64]; K],
    vs: [&mut [f64]; K],
) {
    let n = base.q.len();
    crate::parallel::split_pass(
        n >= crate::parallel::PARALLEL_MIN_COORDS,
        n,
        (base, qs, vs),
        |_, (base, qs, vs)| stage_rows(base, qs, vs),
        |(), ()| (),
    );
}

/// The rows of [`stage_states_into`] over one range of coordinates (all
/// slices of its length), stage after stage, on this thread.
pub(super) fn stage_rows<const S: usize, const K: usize>(
    base: StageBase<'_, S>,
    qs: [&mut [f64]; K],
    vs: [&mut [f64]; K],
) {
    for ((qs, vs), i) in qs.into_iter().zip(vs).zip(base.stages.clone()) {
        stage_row(qs, vs, &base, i);
    }
}

/// Stage `i` of [`stage_rows`] into `qs`, `vs`. The outputs are
/// parameters of their own (references the compiler knows overlap
/// nothing else), so the loop is vectorised without run-time overlap
/// checks, which it would need for slices held in arrays, and for more of
/// them than it takes.
fn stage_row<const S: usize>(qs: &mut [f64], vs: &mut [f64], base: &StageBase<'_, S>, i: usize) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the processor has AVX (checked above)
        return unsafe { stage_row_avx(qs, vs, base, i) };
    }
    stage_row_lanes(qs, vs, base, i)
}

/// [`stage_row_lanes`] compiled for AVX: four lanes instead of two, the
/// same operations on each coordinate (no fused multiply-add), the same
/// bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn stage_row_avx<const S: usize>(
    qs: &mut [f64],
    vs: &mut [f64],
    base: &StageBase<'_, S>,
    i: usize,
) {
    stage_row_lanes(qs, vs, base, i)
}

/// The loop of [`stage_row`]: `Q_i = q_n + c_i h v_n + h² Σ_j (𝔄²)_ij A_j`,
/// `V_i = v_n + h Σ_j 𝔄_ij A_j`.
#[inline(always)]
fn stage_row_lanes<const S: usize>(
    qs: &mut [f64],
    vs: &mut [f64],
    base: &StageBase<'_, S>,
    i: usize,
) {
    let StageBase {
        tab, h, q, v, st, ..
    } = *base;
    let (ch, a, a2) = (tab.c[i] * h, &tab.a[i], &tab.a2[i]);
    // slices of one length: no bounds checks in the loop
    let n = q.len();
    let (qs, vs, v, st) = (&mut qs[..n], &mut vs[..n], &v[..n], st.map(|s| &s[..n]));
    for k in 0..n {
        qs[k] = q[k] + ch * v[k] + h * h * dot(a2, |j| st[j][k]);
        vs[k] = v[k] + h * dot(a, |j| st[j][k]);
    }
}

/// `stage_base!(run, stages, h)`: the [`StageBase`] of a [`Run`]'s stages
/// `stages` for a step of `h`, over every coordinate (a macro, not a
/// method: it borrows the run's fields one by one, beside the stage
/// buffers being written).
macro_rules! stage_base {
    ($run:expr, $stages:expr, $h:expr) => {{
        let n = $run.n;
        StageBase {
            tab: $run.tab.stages(),
            stages: $stages,
            h: $h,
            q: &$run.q[..n],
            v: &$run.v[..n],
            st: std::array::from_fn(|j| &$run.a[j][..n]),
        }
    }};
}

impl<const S: usize, T: Tableau<S>> Run<'_, '_, S, T> {
    /// Stage i's position and velocity into `qs`, `vs`:
    /// `Q_i = q_n + c_i h v_n + h² Σ_j (𝔄²)_ij A_j`, `V_i = v_n + h Σ_j 𝔄_ij A_j`.
    pub(super) fn stage_state(&mut self, i: usize, h: f64) {
        let n = self.n;
        let (qs, vs) = ([&mut self.qs[..n]], [&mut self.vs[..n]]);
        stage_states_into(stage_base!(self, i..i + 1, h), qs, vs);
    }

    /// Every stage's position and velocity into `qst`, `vst` (as
    /// [`Self::stage_state`] for each stage, the same operations), in one
    /// element-wise pass: one hand-over for all stages.
    pub(super) fn stage_states(&mut self, h: f64) {
        let n = self.n;
        let qst = self.qst.each_mut().map(|x| &mut x[..n]);
        let vst = self.vst.each_mut().map(|x| &mut x[..n]);
        stage_states_into(stage_base!(self, 0..S, h), qst, vst);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stage rows (in vector lanes, with AVX where the processor has
    /// it) give the bits of the stage formula evaluated one coordinate at
    /// a time, left to right, for three and five stages and a length that
    /// is not a multiple of the lanes: no fused multiply–add and no
    /// reordered sum.
    #[test]
    fn stage_rows_give_the_bits_of_the_formula() {
        fn check<const S: usize>() {
            let tab = RadauStages::<S>::new();
            let n = 37;
            let x = |i: usize| (i as f64 * 0.754_877_666_246_692_7).fract() - 0.5;
            let q: Vec<f64> = (0..n).map(|k| 1e-4 * x(k)).collect();
            let v: Vec<f64> = (0..n).map(|k| x(k + 101)).collect();
            let st: [Vec<f64>; S] =
                std::array::from_fn(|j| (0..n).map(|k| 1e3 * x(k + 211 * (j + 1))).collect());
            let h = 3.7e-4;
            let mut qs: [Vec<f64>; S] = std::array::from_fn(|_| vec![0.0; n]);
            let mut vs: [Vec<f64>; S] = std::array::from_fn(|_| vec![0.0; n]);
            let base = StageBase {
                tab: &tab,
                stages: 0..S,
                h,
                q: &q,
                v: &v,
                st: std::array::from_fn(|j| &st[j][..]),
            };
            stage_rows(
                base,
                qs.each_mut().map(|x| &mut x[..]),
                vs.each_mut().map(|x| &mut x[..]),
            );
            for i in 0..S {
                for k in 0..n {
                    let (mut sq, mut sv) = (tab.a2[i][0] * st[0][k], tab.a[i][0] * st[0][k]);
                    for j in 1..S {
                        sq += tab.a2[i][j] * st[j][k];
                        sv += tab.a[i][j] * st[j][k];
                    }
                    let q_ik = q[k] + tab.c[i] * h * v[k] + h * h * sq;
                    let v_ik = v[k] + h * sv;
                    assert_eq!(qs[i][k].to_bits(), q_ik.to_bits(), "Q_{i}[{k}]");
                    assert_eq!(vs[i][k].to_bits(), v_ik.to_bits(), "V_{i}[{k}]");
                }
            }
        }
        check::<3>();
        check::<5>();
    }
}
