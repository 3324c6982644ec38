//! Numeric utilities shared by every floor of the library (a leaf: it
//! imports nothing of the crate).

/// Index and value of the first non-finite entry, if any. A fast pass
/// first: `x − x` is 0 for a finite `x` and NaN otherwise, summed in 8
/// independent lanes (vectorisable); only when the sum is not 0 is the
/// entry searched for.
#[allow(clippy::eq_op)] // x − x is the finiteness test
pub fn first_non_finite(v: &[f64]) -> Option<(usize, f64)> {
    let mut acc = [0.0f64; 8];
    let chunks = v.chunks_exact(8);
    let mut tail = 0.0;
    for x in chunks.remainder() {
        tail += x - x;
    }
    for c in chunks {
        for (a, x) in acc.iter_mut().zip(c) {
            *a += x - x;
        }
    }
    if acc.iter().sum::<f64>() + tail == 0.0 {
        return None;
    }
    v.iter()
        .enumerate()
        .find(|(_, x)| !x.is_finite())
        .map(|(i, x)| (i, *x))
}

/// The maximum norm `‖v‖∞ = maxᵢ |vᵢ|` (0 for an empty `v`; NaN entries
/// are passed over, as [`f64::max`] does).
pub(crate) fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0_f64, |a, x| a.max(x.abs()))
}

/// `‖a − b‖∞` over the common length of `a` and `b` (as [`max_abs`]).
pub(crate) fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()))
}

/// `f()` compiled for AVX when the processor has it ([`avx`]; `f`'s body is
/// inlined there): a complex product's two parts in one `vaddsubpd`,
/// four lanes of an element-wise pass instead of two, three-operand
/// instructions. The same operations in the same order (AVX has no fused
/// multiply-add), so the same bits as the baseline build.
#[inline(always)]
pub(crate) fn with_avx<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") && !baseline_only() {
        // SAFETY: the processor has AVX (checked above)
        return unsafe { avx(f) };
    }
    f()
}

#[cfg(test)]
std::thread_local! {
    /// [`with_avx`] on this thread runs the baseline build even where the
    /// processor has AVX (the tests compare the two builds' bits).
    pub(crate) static BASELINE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Is [`with_avx`] held to the baseline build ([`BASELINE`], tests only)?
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn baseline_only() -> bool {
    #[cfg(test)]
    return BASELINE.get();
    #[cfg(not(test))]
    false
}

/// `f()` with AVX enabled (for [`with_avx`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn avx<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// A complex number `[re, im]`.
pub(crate) type C64 = [f64; 2];

/// `a + b`.
#[inline]
pub(crate) fn cadd(a: C64, b: C64) -> C64 {
    [a[0] + b[0], a[1] + b[1]]
}

/// `a − b`.
#[inline]
pub(crate) fn csub(a: C64, b: C64) -> C64 {
    [a[0] - b[0], a[1] - b[1]]
}

/// `a b`.
#[inline]
pub(crate) fn cmul(a: C64, b: C64) -> C64 {
    [a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0]]
}

/// `a / b` (`a b̄ / |b|²`).
#[inline]
pub(crate) fn cdiv(a: C64, b: C64) -> C64 {
    let d = b[0] * b[0] + b[1] * b[1];
    [
        (a[0] * b[0] + a[1] * b[1]) / d,
        (a[1] * b[0] - a[0] * b[1]) / d,
    ]
}

/// `|a|` (without overflow: [`f64::hypot`]).
#[inline]
pub(crate) fn cabs(a: C64) -> f64 {
    a[0].hypot(a[1])
}

/// Uniform pseudo-random numbers in `[0, 1)` for tests: Knuth's MMIX
/// linear congruential generator from `seed`, the top 53 bits.
/// A time `t` [s] as messages print it: the `{:e}` form rounded to 12
/// significant digits, so a time summed from steps (`1.0150000000000001`)
/// reads `1.015e0`, or the shortest round-trip `{:e}` where that is
/// shorter (subnormals); non-finite values as `{}` prints them.
pub(crate) struct Time(pub f64);

impl std::fmt::Display for Time {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = format!("{:.11e}", self.0);
        let rounded = match s.split_once('e') {
            Some((m, e)) => format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.')),
            None => s,
        };
        let shortest = format!("{:e}", self.0);
        f.write_str(if shortest.len() < rounded.len() {
            &shortest
        } else {
            &rounded
        })
    }
}

#[cfg(test)]
pub(crate) fn test_uniform(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::Time;

    #[test]
    fn times_print_with_twelve_significant_digits() {
        let s = |t: f64| Time(t).to_string();
        assert_eq!(s(1.0150000000000001), "1.015e0");
        assert_eq!(s(0.1 + 0.2), "3e-1");
        assert_eq!(s(0.0), "0e0");
        assert_eq!(s(-2.5e-3), "-2.5e-3");
        assert_eq!(s(1.234567890123456), "1.23456789012e0");
        assert_eq!(s(1.3e-322), "1.3e-322");
        assert_eq!(s(120.0), "1.2e2");
        assert_eq!(s(f64::NAN), "NaN");
        assert_eq!(s(f64::NEG_INFINITY), "-inf");
    }
}
