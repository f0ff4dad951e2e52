//! Statistical primitives shared by the sensor fits, the gap diagnosis and the evaluation:
//! median, the normal quantile, weighted least squares of a line, and the percentile bootstrap.

use crate::rng::Rng;
use rayon::prelude::*;

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
