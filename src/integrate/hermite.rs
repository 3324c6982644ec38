//! Cubic Hermite interpolation: the dense output of the methods whose
//! steps give values and derivatives at both ends (rk4; generalized-α for
//! positions from velocities and velocities from accelerations).

/// `out = y(t + σh)` of the cubic through `y0, y1` with slopes `f0, f1` at
/// the ends of `[t, t + h]` (Hairer, Nørsett & Wanner I, §II.6, eq. (6.7)):
/// `h00 y0 + h h10 f0 + h01 y1 + h h11 f1` with the Hermite basis
/// `h00 = 2σ³ − 3σ² + 1`, `h10 = σ³ − 2σ² + σ`, `h01 = −2σ³ + 3σ²`,
/// `h11 = σ³ − σ²`.
pub(crate) fn cubic(
    out: &mut [f64],
    sigma: f64,
    h: f64,
    y0: &[f64],
    f0: &[f64],
    y1: &[f64],
    f1: &[f64],
) {
    let s2 = sigma * sigma;
    let s3 = s2 * sigma;
    let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
    let h10 = (s3 - 2.0 * s2 + sigma) * h;
    let h01 = -2.0 * s3 + 3.0 * s2;
    let h11 = (s3 - s2) * h;
    for i in 0..out.len() {
        out[i] = h00 * y0[i] + h10 * f0[i] + h01 * y1[i] + h11 * f1[i];
    }
}

#[cfg(test)]
mod tests {
    /// Exact for cubics: y = t³ − 2t + 1 on [0.5, 2].
    #[test]
    fn reproduces_a_cubic() {
        let y = |t: f64| t * t * t - 2.0 * t + 1.0;
        let f = |t: f64| 3.0 * t * t - 2.0;
        let (t0, h) = (0.5, 1.5);
        for k in 0..=10 {
            let s = k as f64 / 10.0;
            let mut out = [0.0];
            super::cubic(
                &mut out,
                s,
                h,
                &[y(t0)],
                &[f(t0)],
                &[y(t0 + h)],
                &[f(t0 + h)],
            );
            assert!((out[0] - y(t0 + s * h)).abs() < 1e-13, "σ = {s}");
        }
    }
}
