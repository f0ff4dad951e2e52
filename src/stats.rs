//! Statistical primitives shared by the sensor fits, the gap diagnosis and the evaluation:
//! median, the normal quantile, weighted least squares of a line, the percentile bootstrap, and
//! the tests of paired per-scene differences (Student's t distribution, the paired t test and
//! interval, the Wilcoxon signed-rank test, and the TOST equivalence test).
//!
//! The t distribution is implemented here rather than taken from a crate so that its tails keep
//! full relative precision (p values of 1e-40 are as exact as p values of 0.3): the CDF is the
//! regularised incomplete beta function (continued fraction, modified Lentz) of the smaller tail,
//! with ln B from Stirling's series arranged so that large degrees of freedom do not cancel; the
//! quantile is a bracketed Newton iteration on that CDF. All of the tests below agree with scipy
//! to 1e-9 relative (tools/stats_reference.py, tests/stats.rs).

use crate::rng::Rng;
use rayon::prelude::*;

mod distributions;
pub use distributions::*;

/// Bisection: the point in [lo, hi] where `below` turns from true to false, after `iters`
/// halvings (`below(x)`: the point lies above x). On a log scale, pass ln bounds and take
/// exp of the result.
pub fn bisect(mut lo: f64, mut hi: f64, iters: usize, below: impl Fn(f64) -> bool) -> f64 {
    for _ in 0..iters {
        let mid = 0.5 * (lo + hi);
        if below(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Median (mean of the two middle values for even lengths); NaN when empty. One generic
/// function for the f32 per-pixel statistics and the f64 fit inputs.
pub fn median<T>(v: &mut [T]) -> T
where
    T: Copy
        + PartialOrd
        + Into<f64>
        + From<f32>
        + std::ops::Add<Output = T>
        + std::ops::Mul<Output = T>,
{
    if v.is_empty() {
        return T::from(f32::NAN);
    }
    let m = v.len() / 2;
    let cmp = |a: &T, b: &T| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal);
    let (_, x, _) = v.select_nth_unstable_by(m, cmp);
    let hi = *x;
    if v.len() % 2 == 1 {
        hi
    } else {
        let lo = v[..m]
            .iter()
            .copied()
            .fold(v[0], |a, b| if cmp(&a, &b).is_lt() { b } else { a });
        T::from(0.5) * (lo + hi)
    }
}

/// The median of |r| for values r of a continuous variable rounded to a lattice of step `q`
/// (integer codes and their integer combinations): the plain median of such data jumps by a
/// whole step, which for a noise of about one step biases a MAD σ by up to ±25 %. Each |r| is
/// a class — [0, q/2) for 0, [(k − ½)q, (k + ½)q) for k ≥ 1 — and the median is interpolated
/// within its class, as for grouped data. NaN for no values.
pub fn lattice_abs_median(values: impl Iterator<Item = f64>, q: f64) -> f64 {
    let mut k: Vec<u64> = values.map(|r| (r.abs() / q).round() as u64).collect();
    if k.is_empty() {
        return f64::NAN;
    }
    k.sort_unstable();
    let half = k.len() as f64 / 2.0;
    let class = k[(k.len() / 2).min(k.len() - 1)];
    let below = k.partition_point(|&v| v < class) as f64;
    let within = (k.partition_point(|&v| v <= class) as f64 - below).max(1.0);
    let (lower, width) = if class == 0 {
        (0.0, 0.5)
    } else {
        (class as f64 - 0.5, 1.0)
    };
    q * (lower + (half - below) / within * width)
}

/// Inverse of the standard normal CDF (Acklam's rational approximation, |error| < 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.38357751867269e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// One observation of a weighted straight-line fit: `y` with standard error `se` at `x`, from
/// `n` samples.
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub se: f64,
    pub n: usize,
}

/// A straight line y = a·x + b with the standard errors of a and b and the reduced χ².
pub struct LineFit {
    pub a: f64,
    pub b: f64,
    pub a_se: f64,
    pub b_se: f64,
    pub chi2_reduced: f64,
}

/// Straight-line WLS y = a·x + b with w_k = 1/SE_k²:
/// S = Σw, Sx = Σwx, Sy = Σwy, Sxx = Σwx², Sxy = Σwxy, Δ = S·Sxx − Sx²,
/// a = (S·Sxy − Sx·Sy)/Δ, b = (Sxx·Sy − Sx·Sxy)/Δ, Var a = S/Δ, Var b = Sxx/Δ.
/// First pass with the given SEs, then three passes with SE_k = c·ŷ_k/√n_k (c the median
/// of se_k·√n_k/y_k, ŷ_k the previous fit, floored at y_k/2), which keeps the weights
/// independent of each point's own noise (variances of variances: the noise PTC). Standard
/// errors are scaled by √max(1, χ²/(K − 2)). None when the x values do not span a line.
pub fn wls(points: &[Point]) -> Option<LineFit> {
    let solve = |se: &[f64]| -> Option<(f64, f64, f64, f64)> {
        let (mut s, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (p, &e) in points.iter().zip(se) {
            let w = 1.0 / (e * e);
            s += w;
            sx += w * p.x;
            sy += w * p.y;
            sxx += w * p.x * p.x;
            sxy += w * p.x * p.y;
        }
        let delta = s * sxx - sx * sx;
        if !delta.is_finite() || delta <= 1e-9 * s * sxx {
            return None;
        }
        let a = (s * sxy - sx * sy) / delta;
        let b = (sxx * sy - sx * sxy) / delta;
        Some((a, b, s / delta, sxx / delta))
    };
    // Floor SEs at a tiny fraction of the y scale so that a zero SE cannot dominate.
    let scale = points
        .iter()
        .map(|p| p.y.abs())
        .fold(0.0, f64::max)
        .max(1e-9);
    let floor = 1e-6 * scale;
    let mut se: Vec<f64> = points.iter().map(|p| p.se.max(floor)).collect();
    let (mut a, mut b, ..) = solve(&se)?;
    let mut rel: Vec<f64> = points
        .iter()
        .filter(|p| p.y > 0.0 && p.n > 1)
        .map(|p| p.se * (p.n as f64).sqrt() / p.y)
        .collect();
    if !rel.is_empty() {
        let c = median(&mut rel);
        for _ in 0..3 {
            se = points
                .iter()
                .map(|p| {
                    let pred = (a * p.x + b).max(0.5 * p.y).max(floor);
                    (c * pred / (p.n as f64).sqrt()).max(floor)
                })
                .collect();
            (a, b, ..) = solve(&se)?;
        }
    }
    let (a, b, var_a, var_b) = solve(&se)?;
    let chi2: f64 = points
        .iter()
        .zip(&se)
        .map(|(p, e)| ((p.y - a * p.x - b) / e).powi(2))
        .sum();
    let dof = points.len() as f64 - 2.0;
    let chi2_reduced = if dof > 0.0 { chi2 / dof } else { f64::NAN };
    let inflate = if chi2_reduced.is_finite() {
        chi2_reduced.max(1.0).sqrt()
    } else {
        1.0
    };
    Some(LineFit {
        a,
        b,
        a_se: var_a.sqrt() * inflate,
        b_se: var_b.sqrt() * inflate,
        chi2_reduced,
    })
}

/// Percentile bootstrap of the mean: returns `(mean, lo, hi)` with `[lo, hi]` the central
/// `level` interval (e.g. 0.95) of `resamples` resampled means. Deterministic from `seed`
/// (resample b draws from `Rng::from_parts(seed, [b])`, so thread count does not matter);
/// percentiles interpolate linearly as numpy's default does. An empty sample gives NaNs; one
/// value or `resamples == 0` gives a zero-width interval at the mean. Non-finite values
/// propagate (a +inf PSNR makes the mean +inf). Panics unless `0 < level < 1`.
pub fn bootstrap_ci(values: &[f64], resamples: usize, seed: u64, level: f64) -> (f64, f64, f64) {
    assert!(
        level > 0.0 && level < 1.0,
        "bootstrap_ci: level must be in (0, 1), got {level}"
    );
    let n = values.len();
    if n == 0 {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    if n == 1 || resamples == 0 {
        return (mean, mean, mean);
    }
    let means: Vec<f64> = (0..resamples as u64)
        .into_par_iter()
        .map(|b| {
            let mut rng = Rng::from_parts(seed, &[b]);
            (0..n).map(|_| values[rng.int(0, n - 1)]).sum::<f64>() / n as f64
        })
        .collect();
    percentile_interval(mean, means, level)
}

/// Two-level percentile bootstrap of a grand mean over a crossed design: `values[s][c]` is the
/// value of training seed `s` on test scene `c` (every row the same length). The estimate is the
/// mean over seeds of the mean over scenes; resample `b` draws seeds with replacement, then scenes
/// with replacement (one draw of scenes shared by all drawn seeds, because every seed was scored on
/// the same scenes), both from `Rng::from_parts(seed, [b])`. A level with one member is not
/// resampled, so one row gives exactly `bootstrap_ci` of that row. Resampling both levels counts
/// the seed × scene interaction twice: the interval errs on the wide side. Returns
/// `(mean, lo, hi)`; an empty table gives NaNs. Panics unless `0 < level < 1` and rows are equal.
pub fn bootstrap_crossed(
    values: &[Vec<f64>],
    resamples: usize,
    seed: u64,
    level: f64,
) -> (f64, f64, f64) {
    assert!(
        level > 0.0 && level < 1.0,
        "bootstrap_crossed: level must be in (0, 1), got {level}"
    );
    let (ns, nc) = (values.len(), values.first().map_or(0, Vec::len));
    assert!(
        values.iter().all(|r| r.len() == nc),
        "bootstrap_crossed: rows of unequal length"
    );
    if ns == 0 || nc == 0 {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let stat = |seeds: &[usize], scenes: &[usize]| {
        seeds
            .iter()
            .map(|&s| scenes.iter().map(|&c| values[s][c]).sum::<f64>() / scenes.len() as f64)
            .sum::<f64>()
            / seeds.len() as f64
    };
    let all_seeds: Vec<usize> = (0..ns).collect();
    let all_scenes: Vec<usize> = (0..nc).collect();
    let mean = stat(&all_seeds, &all_scenes);
    if ns * nc == 1 || resamples == 0 {
        return (mean, mean, mean);
    }
    let draw = |rng: &mut Rng, n: usize| -> Vec<usize> {
        if n == 1 {
            vec![0]
        } else {
            (0..n).map(|_| rng.int(0, n - 1)).collect()
        }
    };
    let means: Vec<f64> = (0..resamples as u64)
        .into_par_iter()
        .map(|b| {
            let mut rng = Rng::from_parts(seed, &[b]);
            let seeds = draw(&mut rng, ns);
            let scenes = draw(&mut rng, nc);
            stat(&seeds, &scenes)
        })
        .collect();
    percentile_interval(mean, means, level)
}

/// `(mean, lo, hi)` with `[lo, hi]` the central `level` interval of the resampled means.
fn percentile_interval(mean: f64, mut means: Vec<f64>, level: f64) -> (f64, f64, f64) {
    means.sort_by(f64::total_cmp);
    let alpha = (1.0 - level) / 2.0;
    (
        mean,
        percentile_sorted(&means, alpha),
        percentile_sorted(&means, 1.0 - alpha),
    )
}

/// numpy's default ('linear') percentile of sorted data, `q` in [0, 1].
fn percentile_sorted(sorted: &[f64], q: f64) -> f64 {
    let pos = q * (sorted.len() - 1) as f64;
    let i = pos.floor() as usize;
    let frac = pos - i as f64;
    if i + 1 >= sorted.len() {
        return sorted[sorted.len() - 1];
    }
    sorted[i] + (sorted[i + 1] - sorted[i]) * frac
}

// ---------------------------------------------------------------------------------------------
// Tests of paired differences
// ---------------------------------------------------------------------------------------------

/// The mean, sample standard deviation and standard error of the mean of finite values (n ≥ 2).
/// Exactly equal values give sd = 0 and the mean equal to the value itself (no rounding residue
/// that would turn sd into a spurious 1e-17).
fn describe(diffs: &[f64]) -> Option<(f64, f64, f64)> {
    let n = diffs.len();
    if n < 2 || diffs.iter().any(|d| !d.is_finite()) {
        return None;
    }
    if diffs.iter().all(|&d| d == diffs[0]) {
        return Some((diffs[0], 0.0, 0.0));
    }
    let mean = diffs.iter().sum::<f64>() / n as f64;
    let ss: f64 = diffs.iter().map(|d| (d - mean) * (d - mean)).sum();
    let sd = (ss / (n - 1) as f64).sqrt();
    Some((mean, sd, sd / (n as f64).sqrt()))
}

/// num/se with the zero-spread convention: ±∞ for a non-zero numerator, 0 for a zero one.
fn t_ratio(num: f64, se: f64) -> f64 {
    if se > 0.0 {
        num / se
    } else if num == 0.0 {
        0.0
    } else {
        num.signum() * f64::INFINITY
    }
}

/// The paired t test of H0 "mean difference = 0" and the two-sided confidence interval of the
/// mean difference.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PairedT {
    /// Number of differences; the degrees of freedom are n − 1.
    pub n: usize,
    /// Mean difference.
    pub mean: f64,
    /// Sample standard deviation (divisor n − 1).
    pub sd: f64,
    /// Standard error of the mean, sd/√n.
    pub se: f64,
    /// t = mean/se.
    pub t: f64,
    /// Two-sided p value, 2·P(T_{n−1} > |t|).
    pub p: f64,
    /// The confidence level of the interval.
    pub level: f64,
    /// mean − t_{(1+level)/2, n−1}·se.
    pub ci_lower: f64,
    /// mean + t_{(1+level)/2, n−1}·se.
    pub ci_upper: f64,
}

/// Paired (one-sample) t test on per-scene differences: two-sided test of H0 "the mean
/// difference is 0" and the two-sided `level` confidence interval mean ± t_{(1+level)/2, n−1}·se.
/// `None` for n < 2 or when any difference is not finite (NaN or ±∞ are rejected rather than
/// filtered, so that a missing score cannot silently shrink the pairing).
/// Zero spread (all differences exactly equal): sd = se = 0, the interval is the single point
/// [mean, mean], and t = ±∞ with p = 0 when the mean is non-zero (scipy gives the same), t = 0
/// with p = 1 when every difference is 0 (no evidence of any difference; scipy gives NaN).
/// Reference: scipy.stats.ttest_1samp(d, 0) and its confidence_interval(level).
/// Panics unless 0 < level < 1.
pub fn paired_t(diffs: &[f64], level: f64) -> Option<PairedT> {
    assert!(
        level > 0.0 && level < 1.0,
        "paired_t: level must be in (0, 1), got {level}"
    );
    let (mean, sd, se) = describe(diffs)?;
    let n = diffs.len();
    let df = (n - 1) as f64;
    let t = t_ratio(mean, se);
    let p = (2.0 * student_t_cdf(-t.abs(), df)).min(1.0);
    let half = if se > 0.0 {
        -student_t_quantile(0.5 * (1.0 - level), df) * se
    } else {
        0.0
    };
    Some(PairedT {
        n,
        mean,
        sd,
        se,
        t,
        p,
        level,
        ci_lower: mean - half,
        ci_upper: mean + half,
    })
}

/// How the Wilcoxon p value was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum WilcoxonMethod {
    /// The exact null distribution of W+ (all 2ⁿ sign assignments equally likely).
    Exact,
    /// The normal approximation with the tie-corrected variance, without continuity correction.
    Approx,
}

/// The Wilcoxon signed-rank test of H0 "the differences are symmetric about 0".
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Wilcoxon {
    /// scipy's two-sided statistic, min(W+, W−).
    pub statistic: f64,
    /// Sum of the ranks of |d| over the positive differences (average ranks for ties).
    pub w_plus: f64,
    /// Sum of the ranks over the negative differences; W+ + W− = n(n + 1)/2.
    pub w_minus: f64,
    /// Number of non-zero differences (zeros are dropped before ranking).
    pub n: usize,
    /// Two-sided p value.
    pub p: f64,
    /// Exact or normal approximation.
    pub method: WilcoxonMethod,
    /// For the normal approximation, z = (W+ − n(n + 1)/4)/σ with the tie-corrected
    /// σ² = n(n + 1)(2n + 1)/24 − Σ(t³ − t)/48 (positive when positive differences dominate;
    /// scipy reports −|z|). `None` for the exact method.
    pub z: Option<f64>,
}

/// Wilcoxon signed-rank test of H0 "the differences are symmetric about 0", two-sided.
/// Zeros are dropped before ranking (Wilcoxon's convention, scipy's zero_method='wilcox'); the
/// remaining |d| get average ranks. With n ≤ 50 non-zero differences and no ties among their
/// |d| (exact f64 equality), the p value is the exact 2·min(P(W+ ≤ w), P(W+ ≥ w)) capped at 1;
/// otherwise the normal approximation with the tie-corrected variance and no continuity
/// correction, p = 2·P(Z > |z|). The statistic is scipy's two-sided one, min(W+, W−); W+ and
/// W− are reported as well to show the direction.
/// Reference: scipy.stats.wilcoxon(d, zero_method='wilcox', correction=False,
/// alternative='two-sided', method='exact' | 'approx' (named 'asymptotic' in current scipy)).
/// `None` when any difference is not finite (rejected, not filtered) or no difference is
/// non-zero.
pub fn wilcoxon_signed_rank(diffs: &[f64]) -> Option<Wilcoxon> {
    if diffs.iter().any(|d| !d.is_finite()) {
        return None;
    }
    let mut nz: Vec<f64> = diffs.iter().copied().filter(|&d| d != 0.0).collect();
    let n = nz.len();
    if n == 0 {
        return None;
    }
    nz.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    // Average ranks over runs of equal |d|; Σ(t³ − t) over the runs.
    let (mut w_plus, mut tie_sum) = (0.0, 0.0);
    let mut i = 0;
    while i < n {
        let mut j = i + 1;
        while j < n && nz[j].abs() == nz[i].abs() {
            j += 1;
        }
        let rank = 0.5 * ((i + 1) + j) as f64;
        w_plus += rank * nz[i..j].iter().filter(|&&d| d > 0.0).count() as f64;
        let t = (j - i) as f64;
        tie_sum += t * t * t - t;
        i = j;
    }
    let nf = n as f64;
    let total = nf * (nf + 1.0) / 2.0;
    let w_minus = total - w_plus;
    let (p, method, z) = if n <= 50 && tie_sum == 0.0 {
        let w = w_plus.round() as usize;
        let counts = signed_rank_counts(n);
        let all = 2f64.powi(n as i32);
        let below: u64 = counts[..=w].iter().sum();
        let above: u64 = counts[w..].iter().sum();
        let p = (2.0 * (below.min(above) as f64) / all).min(1.0);
        (p, WilcoxonMethod::Exact, None)
    } else {
        let sigma = ((nf * (nf + 1.0) * (2.0 * nf + 1.0) - tie_sum / 2.0) / 24.0).sqrt();
        let z = (w_plus - total / 2.0) / sigma;
        let p = (2.0 * normal_upper_tail(z.abs())).min(1.0);
        (p, WilcoxonMethod::Approx, Some(z))
    };
    Some(Wilcoxon {
        statistic: w_plus.min(w_minus),
        w_plus,
        w_minus,
        n,
        p,
        method,
        z,
    })
}

/// counts[k] = number of subsets of {1, …, n} with sum k (the null distribution of W+ times
/// 2ⁿ); exact in u64 for n ≤ 63.
fn signed_rank_counts(n: usize) -> Vec<u64> {
    let max = n * (n + 1) / 2;
    let mut counts = vec![0u64; max + 1];
    counts[0] = 1;
    for r in 1..=n {
        let top = r * (r + 1) / 2;
        for k in (r..=top).rev() {
            counts[k] += counts[k - r];
        }
    }
    counts
}

/// The TOST equivalence test of a mean paired difference within ±margin.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Tost {
    /// Number of differences; the degrees of freedom are n − 1.
    pub n: usize,
    /// Mean difference.
    pub mean: f64,
    /// Sample standard deviation (divisor n − 1).
    pub sd: f64,
    /// Standard error of the mean, sd/√n.
    pub se: f64,
    /// The equivalence margin: H1 is −margin < mean < margin.
    pub margin: f64,
    /// The significance level α of each one-sided test.
    pub alpha: f64,
    /// (mean + margin)/se, the test of H0 "mean ≤ −margin".
    pub t_lower: f64,
    /// P(T_{n−1} > t_lower).
    pub p_lower: f64,
    /// (mean − margin)/se, the test of H0 "mean ≥ margin".
    pub t_upper: f64,
    /// P(T_{n−1} < t_upper).
    pub p_upper: f64,
    /// max(p_lower, p_upper).
    pub p: f64,
    /// p < α: the mean difference lies within ±margin at level α.
    pub equivalent: bool,
    /// mean − t_{1−α, n−1}·se, the lower end of the (1 − 2α) interval.
    pub ci_lower: f64,
    /// mean + t_{1−α, n−1}·se, the upper end of the (1 − 2α) interval.
    pub ci_upper: f64,
}

/// Equivalence of the mean paired difference to 0 within ±`margin` by two one-sided t tests
/// (Schuirmann): H0 "mean ≤ −margin or mean ≥ margin" against H1 "−margin < mean < margin";
/// p = max(p_lower, p_upper) and `equivalent` = p < `level_alpha`. That is the case exactly when
/// the (1 − 2α) interval mean ± t_{1−α, n−1}·se lies strictly inside (−margin, margin), which is
/// returned as well. `None` for n < 2 or when any difference is not finite (rejected, not
/// filtered). Zero spread follows [`paired_t`]: a one-sided t is ±∞ (p 0 or 1) unless the mean
/// sits exactly on the margin, where t = 0 and that side's p is ½.
/// Reference: computed with scipy.stats.t and equal to statsmodels'
/// ttost_paired(d, 0, −margin, margin) (tools/stats_reference.py).
/// Panics unless margin is finite and positive and 0 < level_alpha < ½.
pub fn tost_paired(diffs: &[f64], margin: f64, level_alpha: f64) -> Option<Tost> {
    assert!(
        margin.is_finite() && margin > 0.0,
        "tost_paired: margin must be finite and positive, got {margin}"
    );
    assert!(
        level_alpha > 0.0 && level_alpha < 0.5,
        "tost_paired: alpha must be in (0, 0.5), got {level_alpha}"
    );
    let (mean, sd, se) = describe(diffs)?;
    let n = diffs.len();
    let df = (n - 1) as f64;
    let t_lower = t_ratio(mean + margin, se);
    let t_upper = t_ratio(mean - margin, se);
    let p_lower = student_t_cdf(-t_lower, df);
    let p_upper = student_t_cdf(t_upper, df);
    let p = p_lower.max(p_upper);
    let half = if se > 0.0 {
        -student_t_quantile(level_alpha, df) * se
    } else {
        0.0
    };
    Some(Tost {
        n,
        mean,
        sd,
        se,
        margin,
        alpha: level_alpha,
        t_lower,
        p_lower,
        t_upper,
        p_upper,
        p,
        equivalent: p < level_alpha,
        ci_lower: mean - half,
        ci_upper: mean + half,
    })
}
