//! Sines and cosines for the generated kernels and the force elements:
//! one argument reduction for both (fdlibm's kernels), a four-lane
//! variant; a leaf that uses nothing else of the crate.

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
    let ex = (x.to_bits() >> 52) as i32 & 0x7ff;
    // cancellation of more than 16 (then 49) bits: the second (then third)
    // part of π/2
    for (part, tail, bits) in [(PIO2_2, PIO2_2T, 16), (PIO2_3, PIO2_3T, 49)] {
        let ey = (y0.to_bits() >> 52) as i32 & 0x7ff;
        if ex - ey <= bits {
            break;
        }
        let t = r;
        w = n * part;
        r = t - w;
        w = n * tail - ((t - r) - w);
        y0 = r - w;
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
pub(crate) fn sin_cos4_lanes(x: [f64; 4]) -> Option<([f64; 4], [f64; 4])> {
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
