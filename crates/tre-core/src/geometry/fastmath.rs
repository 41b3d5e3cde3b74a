//! Fast f32 `exp`, `exp2` and logistic functions built from plain IEEE-754 f32 operations (no
//! tables, no FMA, no branches), so that loops over lane arrays auto-vectorise on any x86-64 and a
//! numpy float32 mirror doing the same operations in the same order reproduces them bit for bit.
//!
//! Every function below is written as the exact sequence of f32 operations it performs; each
//! `a op b` is one correctly rounded f32 operation, evaluated left to right as written.
//! `max(a, b)` and `min(a, b)` take `b` when `a` is NaN (so NaN propagates into the result).

use super::simd::from_fn;

/// Lanes of one block of the lane arrays that the vectorised kernels loop over.
pub const BLOCK: usize = 8;

/// 1.5 · 2²³: `(y + ROUND) − ROUND` rounds `y` to an integer (ties to even) for |y| < 2²².
const ROUND: f32 = 12_582_912.0;

/// log₂ e, rounded to f32.
const LOG2_E: f32 = std::f32::consts::LOG2_E;

/// ln 2 split for Cody–Waite range reduction: `LN2_HI` is 355/512 exactly (9 significant bits),
/// so `n · LN2_HI` is exact for |n| ≤ 127.
const LN2_HI: f32 = 0.693_359_4;
/// ln 2 − `LN2_HI`.
const LN2_LO: f32 = -2.121_944_4e-4;

/// Coefficients of `exp`'s polynomial (Cephes `expf`), highest degree first.
const EXP_POLY: [f32; 6] = [
    1.987_569_1e-4,
    1.398_199_9e-3,
    8.333_452e-3,
    4.166_579_6e-2,
    1.666_666_5e-1,
    0.5,
];

/// Coefficients `c₅ … c₁` of `exp2`'s polynomial `2^f ≈ 1 + f·(c₁ + f·(c₂ + …))` on
/// [−½, ½] (minimax in relative error, 9.2e-8), highest degree first; `c₁` is fitted, not ln 2.
#[allow(clippy::approx_constant)]
const EXP2_POLY: [f32; 5] = [
    1.326_472_7e-3,
    9.671_513e-3,
    5.550_733_6e-2,
    2.402_224_2e-1,
    6.931_47e-1,
];

/// `A` and `B` of the rational approximation in [`recip_one_plus_exp2`].
const EXP2_RATIONAL: [f32; 2] = [0.039_936_27, 0.346_571_37];

/// Domain of [`exp`]: inputs are clamped to it, so results stay normal and finite.
pub const EXP_DOMAIN: (f32, f32) = (-87.0, 88.0);
/// Domain of [`exp2`]: inputs are clamped to it, so results stay normal and finite.
pub const EXP2_DOMAIN: (f32, f32) = (-125.0, 127.0);
/// Domain of [`recip_one_plus_exp2`]: inputs are clamped to it, so results stay normal.
pub const LOGISTIC2_DOMAIN: (f32, f32) = (-120.0, 120.0);

/// `max(y, lo)` then `min(·, hi)`, NaN-propagating.
#[inline(always)]
fn clamp(y: f32, (lo, hi): (f32, f32)) -> f32 {
    let y = if y < lo { lo } else { y };
    if y > hi {
        hi
    } else {
        y
    }
}

/// `min(y, hi)` then `max(·, lo)`, with NaN taken as +∞ (one instruction each on x86).
#[inline(always)]
fn clamp_nan_high(y: f32, (lo, hi): (f32, f32)) -> f32 {
    let y = if y < hi { y } else { hi };
    if y > lo {
        y
    } else {
        lo
    }
}

/// 2ⁿ for the integer `n` held in `r = n + ROUND`, as f32 bits `(bits(r) + 127) << 23`
/// (wrapping u32 arithmetic), for −126 ≤ n ≤ 127.
#[inline(always)]
fn pow2_of_rounded(r: f32) -> f32 {
    f32::from_bits(r.to_bits().wrapping_add(127) << 23)
}

/// eˣ with relative error below 2e-7 over the whole f32 range of results it returns.
///
/// Operations: `x ← min(88, max(−87, x))` (NaN stays NaN); `r = x·log₂e + ROUND`; `n = r − ROUND`;
/// `f = (x − n·LN2_HI) − n·LN2_LO`; `p = (((((E₀f + E₁)f + E₂)f + E₃)f + E₄)f + E₅)·(f·f) + f + 1`
/// (added left to right); result `p · 2ⁿ` with 2ⁿ from the bits of `r` (see the source for the
/// constants). NaN gives NaN.
///
/// ```
/// use tre_core::geometry::fastmath::exp;
/// assert_eq!(exp(0.0), 1.0);
/// assert!((f64::from(exp(-3.5)) / (-3.5f64).exp() - 1.0).abs() < 2e-7);
/// ```
#[inline]
pub fn exp(x: f32) -> f32 {
    let x = clamp(x, EXP_DOMAIN);
    let r = x * LOG2_E + ROUND;
    let n = r - ROUND;
    let f = (x - n * LN2_HI) - n * LN2_LO;
    let [e0, e1, e2, e3, e4, e5] = EXP_POLY;
    let poly = ((((e0 * f + e1) * f + e2) * f + e3) * f + e4) * f + e5;
    let p = poly * (f * f) + f + 1.0;
    p * pow2_of_rounded(r)
}

/// 2ʸ with relative error below 2.5e-7.
///
/// Operations: `y ← min(127, max(−125, y))` (NaN stays NaN); `r = y + ROUND`; `n = r − ROUND`; `f = y − n`;
/// `g = f·f`; `q = (C₂·f + C₁) + ((C₄·f + C₃) + C₅·g)·g` (Estrin's scheme, for a short
/// dependency chain); result `(1 + f·q) · 2ⁿ` with 2ⁿ from the bits of `r`. NaN gives NaN.
///
/// ```
/// use tre_core::geometry::fastmath::exp2;
/// assert_eq!(exp2(3.0), 8.0);
/// assert!((f64::from(exp2(-0.3)) / (-0.3f64).exp2() - 1.0).abs() < 2.5e-7);
/// ```
#[inline]
pub fn exp2(y: f32) -> f32 {
    exp2_in_domain(clamp(y, EXP2_DOMAIN))
}

/// [`exp2`] without the clamp, for `y` already within [`EXP2_DOMAIN`].
#[inline(always)]
fn exp2_in_domain(y: f32) -> f32 {
    let r = y + ROUND;
    let n = r - ROUND;
    let f = y - n;
    let [c5, c4, c3, c2, c1] = EXP2_POLY;
    let f2 = f * f;
    let q = (c2 * f + c1) + ((c4 * f + c3) + c5 * f2) * f2;
    (1.0 + f * q) * pow2_of_rounded(r)
}

/// `1 / (1 + 2ʸ)`, the logistic sigmoid of `−y·ln 2`, with relative error below 7e-7, from a
/// rational approximation of 2ᶠ that shares the final division: with `2ᶠ ≈ (E + O)/(E − O)`
/// (`E = 1 + A·f²`, `O = B·f`, fitted for minimax relative error 4.5e-7 on [−½, ½]),
/// `1 / (1 + 2ⁿ·2ᶠ) = (E − O) / ((E − O) + 2ⁿ·(E + O))`. `y` is first clamped to ±120 (an
/// absolute change below 1e-36); NaN is taken as +∞ (result `1 / (1 + 2¹²⁰)`).
///
/// Operations: `y ← max(min(y, 120), −120)`; `r = y + ROUND`; `n = r − ROUND`; `f = y − n`;
/// `e = A·(f·f) + 1`; `o = B·f`; `q = e − o`; result `q / (q + (e + o)·2ⁿ)` with 2ⁿ from the
/// bits of `r`.
///
/// ```
/// use tre_core::geometry::fastmath::recip_one_plus_exp2;
/// assert_eq!(recip_one_plus_exp2(0.0), 0.5);
/// assert!((recip_one_plus_exp2(1.0) - 1.0 / 3.0).abs() < 1e-7);
/// ```
#[inline]
pub fn recip_one_plus_exp2(y: f32) -> f32 {
    let y = clamp_nan_high(y, LOGISTIC2_DOMAIN);
    let r = y + ROUND;
    let n = r - ROUND;
    let f = y - n;
    let [a, b] = EXP2_RATIONAL;
    let e = a * (f * f) + 1.0;
    let o = b * f;
    let q = e - o;
    q / (q + (e + o) * pow2_of_rounded(r))
}

/// The logistic sigmoid `1 / (1 + e⁻ˣ)`, as [`recip_one_plus_exp2`]`(−x · log₂e)`.
///
/// ```
/// use tre_core::geometry::fastmath::sigmoid;
/// assert_eq!(sigmoid(0.0), 0.5);
/// assert!((sigmoid(2.0) - 0.880_797_1).abs() < 1e-6);
/// ```
#[inline]
pub fn sigmoid(x: f32) -> f32 {
    recip_one_plus_exp2(-x * LOG2_E)
}

/// The sum of a block of lane accumulators in a fixed tree order:
/// `((a₀ + a₄) + (a₂ + a₆)) + ((a₁ + a₅) + (a₃ + a₇))`, i.e. halving the block three times.
///
/// ```
/// use tre_core::geometry::fastmath::sum_block;
/// assert_eq!(sum_block([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]), 36.0);
/// ```
#[inline]
pub fn sum_block(a: [f32; BLOCK]) -> f32 {
    let h: [f32; 4] = from_fn(|l| a[l] + a[l + 4]);
    let q: [f32; 2] = from_fn(|l| h[l] + h[l + 2]);
    q[0] + q[1]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every `step`-th f32 in `[lo, hi]`.
    fn samples(lo: f32, hi: f32, count: usize) -> impl Iterator<Item = f32> {
        (0..=count).map(move |i| lo + (hi - lo) * i as f32 / count as f32)
    }

    fn max_rel_err(
        f: impl Fn(f32) -> f32,
        g: impl Fn(f64) -> f64,
        xs: impl Iterator<Item = f32>,
    ) -> f64 {
        xs.map(|x| (f64::from(f(x)) / g(f64::from(x)) - 1.0).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn exp_is_accurate_over_its_domain() {
        let err = max_rel_err(exp, f64::exp, samples(-87.0, 88.0, 2_000_000));
        assert!(err < 2e-7, "max relative error {err:e}");
        let near_zero = max_rel_err(exp, f64::exp, samples(-1.0, 1.0, 200_000));
        assert!(near_zero < 1.5e-7, "max relative error {near_zero:e}");
    }

    #[test]
    fn ln2_split_is_exact() {
        assert_eq!(LN2_HI, 355.0 / 512.0);
        assert!((f64::from(LN2_HI) + f64::from(LN2_LO) - std::f64::consts::LN_2).abs() < 1e-11);
    }

    #[test]
    fn exp_clamps_and_propagates_nan() {
        assert_eq!(exp(-1000.0), exp(-87.0));
        assert_eq!(exp(1000.0), exp(88.0));
        assert!(exp(-87.0).is_normal() && exp(88.0).is_finite());
        assert!(exp(f32::NAN).is_nan());
        assert_eq!(exp(f32::NEG_INFINITY), exp(-87.0));
    }

    #[test]
    fn exp2_is_accurate_and_exact_on_integers() {
        let err = max_rel_err(exp2, f64::exp2, samples(-125.0, 127.0, 2_000_000));
        assert!(err < 2.5e-7, "max relative error {err:e}");
        for n in -125..=127 {
            assert_eq!(f64::from(exp2(n as f32)), (n as f64).exp2());
        }
        assert!(exp2(f32::NAN).is_nan());
    }

    #[test]
    fn logistic_is_accurate_and_normal() {
        let reference = |y: f64| 1.0 / (1.0 + y.exp2());
        let err = max_rel_err(
            recip_one_plus_exp2,
            reference,
            samples(-120.0, 120.0, 2_000_000),
        );
        assert!(err < 7e-7, "max relative error {err:e}");
        assert!(recip_one_plus_exp2(1e9).is_normal());
        assert_eq!(recip_one_plus_exp2(-1e9), 1.0);
        let s = max_rel_err(
            sigmoid,
            |x| 1.0 / (1.0 + (-x).exp()),
            samples(-20.0, 20.0, 100_000),
        );
        assert!(s < 2e-6, "max relative error {s:e}");
    }
}
