//! Linear models against the nonlinear runs they approximate.

use faer::Mat;

/// `exp(A τ) x` by a Taylor series of 30 terms in 64 steps of τ/64.
pub fn expm_times(a: &Mat<f64>, tau: f64, x: &[f64]) -> Vec<f64> {
    let steps = 64;
    let h = tau / steps as f64;
    let n = x.len();
    let mut y = x.to_vec();
    for _ in 0..steps {
        let mut term = y.clone();
        let mut sum = y.clone();
        for k in 1..30 {
            let mut next = vec![0.0; n];
            for i in 0..n {
                for j in 0..n {
                    next[i] += a[(i, j)] * term[j];
                }
                next[i] *= h / k as f64;
            }
            term = next;
            for i in 0..n {
                sum[i] += term[i];
            }
        }
        y = sum;
    }
    y
}

/// The runs from `+δx` and `−δx` (their ends `plus`, `minus`) against
/// the linear prediction `linear` of the response to `+δx`: their half
/// difference (free of the quadratic terms) must agree with it within
/// `1e-6` of its largest entry. `what` names the case in the message.
pub fn assert_odd_part_is_linear(what: &str, plus: &[f64], minus: &[f64], linear: &[f64]) {
    let nonlinear: Vec<f64> = plus.iter().zip(minus).map(|(p, m)| 0.5 * (p - m)).collect();
    let size = nonlinear.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
    let err = nonlinear
        .iter()
        .zip(linear)
        .fold(0.0_f64, |s, (n, l)| s.max((n - l).abs()));
    eprintln!("{what}: |exp(A tau) dx - nonlinear| = {err:.3e} of {size:.3e}");
    assert!(err < 1e-6 * size, "{what}: {err:.3e} of {size:.3e}");
}
