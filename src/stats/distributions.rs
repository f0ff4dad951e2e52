//! Distribution functions the tests need: log-gamma and the regularised incomplete beta,
//! Student's t (CDF and quantile) and the normal tail.

use super::*;

// ---------------------------------------------------------------------------------------------
// Student's t distribution
// ---------------------------------------------------------------------------------------------

/// ½·ln(2π).
pub(super) const LN_SQRT_2PI: f64 = 0.918_938_533_204_672_8;

/// ln Γ(x) − [(x − ½)·ln x − x + ½·ln 2π]: Stirling's series, for x ≥ 10 (the first omitted
/// term is below 4e-17 there).
pub(super) fn stirling_correction(x: f64) -> f64 {
    let r = 1.0 / x;
    let r2 = r * r;
    r * (1.0 / 12.0
        + r2 * (-1.0 / 360.0
            + r2 * (1.0 / 1260.0
                + r2 * (-1.0 / 1680.0
                    + r2 * (1.0 / 1188.0 + r2 * (-691.0 / 360_360.0 + r2 * (1.0 / 156.0)))))))
}

/// ln Γ(x) for x > 0: the recurrence Γ(x) = Γ(x + k)/(x·…·(x + k − 1)) up to x + k ≥ 10, then
/// Stirling's series.
pub(super) fn ln_gamma(x: f64) -> f64 {
    let mut z = x;
    let mut prod = 1.0;
    while z < 10.0 {
        prod *= z;
        z += 1.0;
    }
    (z - 0.5) * z.ln() - z + LN_SQRT_2PI + stirling_correction(z) - prod.ln()
}

/// ln B(a, b) for a, b > 0. With the larger argument ≥ 10, ln Γ(big) − ln Γ(big + small) is
/// written as −(big − ½)·ln(1 + small/big) − small·ln(big + small) + small + Δcorrection, so
/// that the large (x − ½)·ln x terms never cancel (t tails at large degrees of freedom).
pub(super) fn ln_beta(a: f64, b: f64) -> f64 {
    let (small, big) = if a < b { (a, b) } else { (b, a) };
    if big < 10.0 {
        return ln_gamma(a) + ln_gamma(b) - ln_gamma(a + b);
    }
    let sum = big + small;
    ln_gamma(small) - (big - 0.5) * (small / big).ln_1p() - small * sum.ln()
        + small
        + stirling_correction(big)
        - stirling_correction(sum)
}

/// The continued fraction of I_x(a, b) (modified Lentz), converging fast for
/// x < (a + 1)/(a + b + 2).
pub(super) fn beta_continued_fraction(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let guard = |v: f64| if v.abs() < TINY { TINY } else { v };
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 / guard(1.0 - qab * x / qap);
    let mut h = d;
    for m in 1..100_000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let even = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 / guard(1.0 + even * d);
        c = guard(1.0 + even / c);
        h *= d * c;
        let odd = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 / guard(1.0 + odd * d);
        c = guard(1.0 + odd / c);
        let step = d * c;
        h *= step;
        if (step - 1.0).abs() <= 4.0 * f64::EPSILON {
            break;
        }
    }
    h
}

/// Regularised incomplete beta I_x(a, b), with y = 1 − x passed separately so that neither tail
/// loses precision to 1 − x. The continued fraction always evaluates the smaller side.
pub(super) fn beta_inc(a: f64, b: f64, x: f64, y: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if y <= 0.0 {
        return 1.0;
    }
    if x > (a + 1.0) / (a + b + 2.0) {
        return 1.0 - beta_inc(b, a, y, x);
    }
    let ln_x = if x > 0.5 { (-y).ln_1p() } else { x.ln() };
    let ln_y = if y > 0.5 { (-x).ln_1p() } else { y.ln() };
    (a * ln_x + b * ln_y - ln_beta(a, b)).exp() / a * beta_continued_fraction(a, b, x)
}

/// P(T > x) for x ≥ 0: ½·I_{ν/(ν+x²)}(ν/2, ½).
pub(super) fn t_upper_tail(x: f64, df: f64) -> f64 {
    if x > 1e150 {
        // x² overflows; here I_w(a, ½) = w^a/(a·B(a, ½))·(1 + O(w)) with w = ν/x² < 1e-290,
        // and w^a = (√ν/x)^ν (powf keeps the precision that exp of a large logarithm loses).
        let a = 0.5 * df;
        let w_a = (df.sqrt() / x).powf(df);
        if w_a > 1e-300 {
            return 0.5 * w_a * (-ln_beta(a, 0.5)).exp() / a;
        }
        return 0.5 * (a * (df.ln() - 2.0 * x.ln()) - ln_beta(a, 0.5)).exp() / a;
    }
    let x2 = x * x;
    0.5 * beta_inc(0.5 * df, 0.5, df / (df + x2), x2 / (df + x2))
}

/// ln of the t density at x ≥ 0.
pub(super) fn t_ln_pdf(x: f64, df: f64) -> f64 {
    let ln_1p = if x > 1e150 {
        2.0 * x.ln() - df.ln()
    } else {
        (x * x / df).ln_1p()
    };
    -0.5 * (df + 1.0) * ln_1p - 0.5 * df.ln() - ln_beta(0.5 * df, 0.5)
}

/// Student's t cumulative distribution P(T ≤ t) with `df` > 0 degrees of freedom (any positive
/// real). Computed from the smaller tail, so P(T ≤ t) for t ≪ 0 keeps full relative precision
/// (use `student_t_cdf(-t, df)` for an upper tail). NaN when `t` or `df` is NaN or `df ≤ 0`.
/// Precision: about 1e-14 relative; at large `df` and moderate |t| the continued fraction loses
/// digits in proportion to `df` (about 1e-11 at df = 1e5, 1e-9 at df = 1e7).
/// Reference: scipy.stats.t.cdf (agreement 1e-9 relative for 0.5 ≤ df ≤ 1e4, tests/stats.rs).
pub fn student_t_cdf(t: f64, df: f64) -> f64 {
    if t.is_nan() || df.is_nan() || df <= 0.0 {
        return f64::NAN;
    }
    if df.is_infinite() {
        return normal_cdf(t);
    }
    if t.is_infinite() {
        return if t > 0.0 { 1.0 } else { 0.0 };
    }
    let tail = t_upper_tail(t.abs(), df);
    if t < 0.0 { tail } else { 1.0 - tail }
}

/// Student's t quantile: the t with P(T ≤ t) = `p`, `df` > 0 degrees of freedom (any positive
/// real). ±∞ at p = 1 and p = 0 (and where the quantile exceeds the f64 range); NaN when `p` is
/// outside [0, 1], NaN, or `df ≤ 0`. The tail probability min(p, 1 − p) is matched to full
/// relative precision (bracketed Newton on ln P(T > e^u) in u, then Newton on P(T > x) in x).
/// Reference: scipy.stats.t.ppf (agreement 1e-9 relative for 0.5 ≤ df ≤ 1e4, tests/stats.rs).
pub fn student_t_quantile(p: f64, df: f64) -> f64 {
    if p.is_nan() || df.is_nan() || df <= 0.0 || !(0.0..=1.0).contains(&p) {
        return f64::NAN;
    }
    if p == 0.0 {
        return f64::NEG_INFINITY;
    }
    if p == 1.0 {
        return f64::INFINITY;
    }
    if p == 0.5 {
        return 0.0;
    }
    if df.is_infinite() {
        return normal_quantile(p);
    }
    if p < 0.5 {
        -t_upper_quantile(p, df)
    } else {
        t_upper_quantile(1.0 - p, df)
    }
}

/// The x > 0 with P(T > x) = q, for 0 < q < ½.
pub(super) fn t_upper_quantile(q: f64, df: f64) -> f64 {
    // g(u) = ln P(T > e^u) − ln q falls monotonically in u and is nearly linear in the
    // power-law tail, so Newton in u converges from far away; a bracket guards every step.
    const U_MAX: f64 = 709.0; // e^709 ≈ 8e307
    const U_MIN: f64 = -740.0;
    let ln_q = q.ln();
    let g = |u: f64| t_upper_tail(u.exp(), df).ln() - ln_q;
    // Start from Cornish–Fisher, or from the power-law tail P(T > x) ≈ ν^{ν/2−1}·x^{−ν}/B(ν/2, ½)
    // where that puts x well inside it (x² > 4ν).
    let z = -normal_quantile(q);
    let mut u = (z + (z * z * z + z) / (4.0 * df)).max(1e-300).ln();
    let power_tail = ((0.5 * df - 1.0) * df.ln() - ln_beta(0.5 * df, 0.5) - ln_q) / df;
    if power_tail > u && 2.0 * power_tail > (4.0 * df).ln() {
        u = power_tail;
    }
    u = u.clamp(U_MIN, U_MAX);
    // Bracket: g(lo) > 0 ≥ g(hi).
    let (mut lo, mut hi) = (u, u);
    if g(u) > 0.0 {
        let mut step = 1.0;
        loop {
            hi = (hi + step).min(U_MAX);
            if g(hi) <= 0.0 {
                break;
            }
            if hi >= U_MAX {
                return f64::INFINITY;
            }
            lo = hi;
            step *= 2.0;
        }
    } else {
        let mut step = 1.0;
        loop {
            lo = (lo - step).max(U_MIN);
            if g(lo) > 0.0 {
                break;
            }
            if lo <= U_MIN {
                return 0.0;
            }
            hi = lo;
            step *= 2.0;
        }
    }
    for _ in 0..200 {
        let x = u.exp();
        let tail = t_upper_tail(x, df);
        let gu = tail.ln() - ln_q;
        if gu > 0.0 {
            lo = u;
        } else {
            hi = u;
        }
        // d/du ln P(T > e^u) = −x·pdf(x)/P(T > x).
        let slope = -(t_ln_pdf(x, df).exp() * x) / tail;
        let mut next = u - gu / slope;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        let done = (next - u).abs() <= 1e-14 * u.abs().max(1.0) || hi - lo <= 1e-14;
        u = next;
        if done {
            break;
        }
    }
    // Polish in x, where the last bits of e^u are not limited by the spacing of u. The step
    // (P(T > x) − q)/pdf(x) is formed as (P/q − 1)·q/pdf because pdf alone underflows far out.
    let mut x = u.exp();
    for _ in 0..3 {
        let step = (t_upper_tail(x, df) / q - 1.0) * (ln_q - t_ln_pdf(x, df)).exp();
        let next = x + step;
        if !next.is_finite() || next <= 0.0 || step.abs() <= 1e-17 * x {
            break;
        }
        x = next;
    }
    x
}

/// Standard normal P(Z ≤ z), to full relative precision in both tails: P(Z > |z|) =
/// ½·Q(½, z²/2), the regularised upper incomplete gamma by its series below z²/2 = 1.5 and its
/// continued fraction (modified Lentz) above.
pub(super) fn normal_cdf(z: f64) -> f64 {
    if z.is_nan() {
        return f64::NAN;
    }
    let upper = normal_upper_tail(z.abs());
    if z < 0.0 { upper } else { 1.0 - upper }
}

/// P(Z > x) for x ≥ 0.
pub(super) fn normal_upper_tail(x: f64) -> f64 {
    let w = 0.5 * x * x;
    if w < 1.5 {
        // P(½, w) = e^{−w}·w^½/Γ(½)·Σ_{n≥0} wⁿ/(½·(3/2)⋯(½ + n)).
        let (mut term, mut sum, mut ap) = (2.0, 2.0, 0.5);
        for _ in 0..200 {
            ap += 1.0;
            term *= w / ap;
            sum += term;
            if term < sum * f64::EPSILON {
                break;
            }
        }
        let lower = sum * (-w).exp() * w.sqrt() / std::f64::consts::PI.sqrt();
        return 0.5 * (1.0 - lower);
    }
    if w > 800.0 {
        return 0.0;
    }
    // Q(½, w) = e^{−w}·w^½/Γ(½) · 1/(w + ½ − 1·½/(w + 5/2 − 2·3/2/(w + 9/2 − …))).
    const TINY: f64 = 1e-300;
    let guard = |v: f64| if v.abs() < TINY { TINY } else { v };
    let mut b = w + 0.5;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..1000 {
        let i = i as f64;
        let an = -i * (i - 0.5);
        b += 2.0;
        d = 1.0 / guard(an * d + b);
        c = guard(b + an / c);
        let step = d * c;
        h *= step;
        if (step - 1.0).abs() <= 4.0 * f64::EPSILON {
            break;
        }
    }
    0.5 * (-w).exp() * w.sqrt() / std::f64::consts::PI.sqrt() * h
}
