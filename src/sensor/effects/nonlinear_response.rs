//! `nonlinear_response`: the signal is not proportional to exposure × ISO. The signal above
//! black, normalised u = I/R (R = white − black), goes through a response curve f before noise,
//! I → R·f(I/R). Two named families (`shape`), each with the identity as a special case:
//! - `power_law`: f(u) = u^p (`exponent` p; p = 1 is linear);
//! - `toe`, `shoulder`, `toe_shoulder`: a linear segment with a hyperbolic toe below and a
//!   soft shoulder toward saturation, f = S∘T with T(u) = √(u² + t²) − t (`toe` t: quadratic
//!   u²/2t below t, then linear with the offset −t a toe leaves on an EMVA 1288 linearity
//!   plot) and S(v) = v / (1 + (v/s)⁴)^¼ (`shoulder` s: a smooth min(v, s), < 0.4 % below s/2,
//!   saturating at s); t = 0 and s = ∞ are the identity.
//!
//! Statistic (scene bursts): scene bursts of one frame size are one static scene at different
//! exposure × ISO. Against the burst of the largest exposure (the reference), each other burst
//! j gives the exponent p̂_j = ln(Σ s_ref / Σ s_j) / ln(E_ref / E_j), s = temporal mean − black
//! over pixels where the reference is below 90 % and s_j above 2 % of the range (1 for a linear
//! sensor; the measured ratio of a tone-mapped EV0/EV−3 pair is not 8). Flat series (EMVA
//! 1288 linearity): flats of one ISO and size at several exposure times, one illumination;
//! each flat's mean signal above the dark mean against the longest unsaturated exposure's,
//! p̂ = ln(μ_ref / μ_j) / ln(t_ref / t_j): a power law gives the same p̂ at every level, a toe
//! raises it at low levels, a shoulder lowers it near the top.
//!
//! Fit: every candidate shape is fitted to the captures' exposure pairs (flat-series levels,
//! and binned scene pixels where scenes exist): (y_hi, y_lo, ρ) with ρ the exposure ratio,
//! residual ln f⁻¹(y_hi) − ln f⁻¹(y_lo) − ln ρ (the illumination cancels). The power law is
//! named unless the better of `toe` and `shoulder` halves its RMS residual, and `toe_shoulder`
//! only if it halves that again; each step also needs the simpler shape's RMS over the pairs'
//! precision (2·10⁻³), so pairs that cannot tell shapes apart (one exposure ratio) keep the
//! power law. A power law keeps the calibrated estimate p = p_model × mean(measured /
//! simulated) over its statistics.

use super::curve::MAX_LINEAR;
use super::not_fitted;
use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::NONLINEAR_RESPONSE;
const NAME: &str = "response exponent";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "signal not proportional to exposure × ISO: I → R·f(I/R), f a power law or a \
            linear segment with a toe and/or a shoulder",
    needs: "scene bursts of one scene at two exposures, or flats of one ISO at two exposure times",
    statistics,
    fit,
    adjust: None,
};

pub use super::curve::{Curve, curve};

/// Scene bursts grouped by their declared `scene` (captures.toml); bursts without one by
/// frame size (the fallback: one size = one scene, which the report names); within a group
/// the reference (largest exposure) first.
pub fn scene_groups(s: &[Summary]) -> Vec<Vec<&Summary>> {
    let mut groups: Vec<Vec<&Summary>> = Vec::new();
    for b in s.iter().filter(|b| b.kind == BurstKind::Scene) {
        match groups.iter_mut().find(|g| match (&g[0].scene, &b.scene) {
            (Some(x), Some(y)) => x == y && (g[0].width, g[0].height) == (b.width, b.height),
            (None, None) => (g[0].width, g[0].height) == (b.width, b.height),
            _ => false,
        }) {
            Some(g) => g.push(b),
            None => groups.push(vec![b]),
        }
    }
    for g in &mut groups {
        g.sort_by(|a, b| b.exposure().total_cmp(&a.exposure()));
    }
    groups.retain(|g| g.len() >= 2);
    groups
}

/// Flat series (EMVA 1288 linearity): flat bursts of one ISO and frame size at two or more
/// declared exposure times, taken as one illumination (docs/noise.md: the signal is
/// proportional to exposure for one target); longest exposure first.
pub fn flat_series(s: &[Summary]) -> Vec<Vec<&Summary>> {
    let mut groups: Vec<Vec<&Summary>> = Vec::new();
    for b in s.iter().filter(|b| b.kind == BurstKind::Flat) {
        match groups
            .iter_mut()
            .find(|g| (g[0].iso, g[0].width, g[0].height) == (b.iso, b.width, b.height))
        {
            Some(g) => g.push(b),
            None => groups.push(vec![b]),
        }
    }
    for g in &mut groups {
        g.sort_by(|a, b| b.exposure_s.total_cmp(&a.exposure_s));
    }
    groups.retain(|g| g[0].exposure_s > 1.01 * g[g.len() - 1].exposure_s);
    groups
}

/// Per-channel mean signal of a flat above `zero` (non-hot values).
pub fn flat_level(b: &Summary, zero: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|c| super::masked_mean(&b.mean, |i| i % 3 == c && b.not_hot(i)) - zero[c])
}

/// The reference of a flat series: its longest exposure below 90 % of the range.
pub fn flat_reference<'a>(g: &[&'a Summary], zero: [f64; 3], top: f64) -> Option<&'a Summary> {
    g.iter()
        .copied()
        .find(|b| flat_level(b, zero).iter().all(|&v| v < 0.9 * top))
}

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    let top = p.white - p.black;
    // Flat series: the signal above the same ISO's dark mean (no pedestal enters) of each
    // flat against the reference, p̂ = ln(μ_ref / μ_j) / ln(t_ref / t_j).
    for g in flat_series(s) {
        let zero = super::summary::dark_mean(s, g[0].iso).unwrap_or([p.black; 3]);
        let Some(r) = flat_reference(&g, zero, top) else {
            continue;
        };
        let mr = flat_level(r, zero).iter().sum::<f64>();
        for b in g.iter().filter(|b| b.exposure_s < r.exposure_s / 1.01) {
            let mb = flat_level(b, zero).iter().sum::<f64>();
            if mb <= 0.02 * top || mr <= mb {
                continue;
            }
            out.push(Stat {
                key: format!(
                    "{}: {NAME} (flat series) against {}",
                    p.bursts[b.burst].name, p.bursts[r.burst].name
                ),
                effect: Some(ID),
                value: (mr / mb).ln() / (r.exposure_s / b.exposure_s).ln(),
                min_effect: 0.02,
                sd_floor: 1e-4,
                unit: "",
            });
        }
    }
    for g in scene_groups(s) {
        let r = g[0];
        for b in &g[1..] {
            let rho = r.exposure() / b.exposure();
            if rho < 1.01 {
                continue;
            }
            let (mut sr, mut sb) = (0.0, 0.0);
            for (vr, vb) in r.mean.iter().zip(&b.mean) {
                let (xr, xb) = (vr - p.black, vb - p.black);
                if xr < 0.9 * top && xb > 0.02 * top {
                    sr += xr;
                    sb += xb;
                }
            }
            if sb <= 0.0 {
                continue;
            }
            out.push(Stat {
                key: format!(
                    "{}: {NAME} against {}",
                    p.bursts[b.burst].name, p.bursts[r.burst].name
                ),
                effect: Some(ID),
                value: (sr / sb).ln() / rho.ln(),
                min_effect: 0.02,
                sd_floor: 1e-4,
                unit: "",
            });
        }
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let pairs = exposure_pairs(ctx.protocol, ctx.summaries);
    if pairs.is_empty() {
        return Err(not_fitted(
            ID,
            "no scene bursts at two exposures and no flat series",
        ));
    }
    let (shape, _) = choose(&fit_shapes(&pairs));
    if let Curve::ToeShoulder { .. } = shape {
        return Ok(shape.params());
    }
    // A power law: the estimate calibrated against the model's own simulation (it cancels
    // what the statistics' pixel selection does to a curve).
    let stats = ctx.pairs(ID, "");
    if stats.is_empty() {
        return Err(not_fitted(ID, "no response statistic in these captures"));
    }
    let ratio = stats.iter().map(|(m, s)| m / s).sum::<f64>() / stats.len() as f64;
    let e = ctx.protocol.exponent() * ratio;
    if !(0.2..=5.0).contains(&e) {
        return Err(not_fitted(
            ID,
            format!("fitted exponent {e:.4} is outside [0.2, 5]"),
        ));
    }
    Ok(Curve::Power(e).params())
}

/// One exposure pair: normalised signals (y_hi, y_lo) of one target at exposures whose ratio
/// is `ratio` (> 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pair {
    pub y_hi: f64,
    pub y_lo: f64,
    pub ratio: f64,
}

/// The measured exposure pairs (module docs): per flat series and channel, every two flats
/// whose signals are 0.5–95 % of the range; per scene, against its reference, the pixels
/// binned by the reference's signal (12 log-spaced bins over 2–90 %; sums over a bin, so
/// per-pixel noise averages out; bins whose mean x_b is under 0.3 % are left out).
pub fn exposure_pairs(p: &Protocol, s: &[Summary]) -> Vec<Pair> {
    let top = p.white - p.black;
    let mut out = Vec::new();
    for g in flat_series(s) {
        let zero = super::summary::dark_mean(s, g[0].iso).unwrap_or([p.black; 3]);
        let levels: Vec<[f64; 3]> = g.iter().map(|b| flat_level(b, zero)).collect();
        // Per channel: a coloured illumination gives each channel its own level.
        #[allow(clippy::needless_range_loop)]
        for c in 0..3 {
            for i in 0..g.len() {
                for j in i + 1..g.len() {
                    let (hi, lo) = (levels[i][c] / p.range, levels[j][c] / p.range);
                    let ratio = g[i].exposure_s / g[j].exposure_s;
                    let ok = |y: f64| (0.005..0.95).contains(&(y * p.range / top));
                    if ratio > 1.01 && ok(hi) && ok(lo) {
                        out.push(Pair {
                            y_hi: hi,
                            y_lo: lo,
                            ratio,
                        });
                    }
                }
            }
        }
    }
    const BINS: usize = 12;
    let (lo_edge, hi_edge) = (0.02f64.ln(), 0.9f64.ln());
    for g in scene_groups(s) {
        let r = g[0];
        for b in &g[1..] {
            let ratio = r.exposure() / b.exposure();
            if ratio < 1.01 {
                continue;
            }
            let mut bins = [(0.0, 0.0, 0usize); BINS];
            for (vr, vb) in r.mean.iter().zip(&b.mean) {
                let (xr, xb) = ((vr - p.black) / top, (vb - p.black) / top);
                // Selected on the reference only: a threshold on the noisy x_b would bias its
                // mean upward at low signal.
                if xr > 0.02 && xr < 0.9 {
                    let k = ((xr.ln() - lo_edge) / (hi_edge - lo_edge) * BINS as f64) as usize;
                    let e = &mut bins[k.min(BINS - 1)];
                    e.0 += xr;
                    e.1 += xb;
                    e.2 += 1;
                }
            }
            for (sr, sb, n) in bins {
                if n >= 8 && sb / n as f64 > 0.003 {
                    let k = top / p.range / n as f64;
                    out.push(Pair {
                        y_hi: sr * k,
                        y_lo: sb * k,
                        ratio,
                    });
                }
            }
        }
    }
    out
}

/// RMS of the pairs' residuals ln f⁻¹(y_hi) − ln f⁻¹(y_lo) − ln ρ under `c`.
pub fn rms(c: &Curve, pairs: &[Pair]) -> f64 {
    let ss: f64 = pairs
        .iter()
        .map(|q| {
            let (a, b) = (c.inverse(q.y_hi), c.inverse(q.y_lo));
            if a <= 0.0 || b <= 0.0 || a >= MAX_LINEAR {
                return 1.0;
            }
            ((a / b).ln() - q.ratio.ln()).powi(2)
        })
        .sum();
    (ss / pairs.len().max(1) as f64).sqrt()
}

/// Minimise `f` over [lo, hi] on a log grid (48 points), then golden-section around the best.
fn min_1d(lo: f64, hi: f64, f: impl Fn(f64) -> f64) -> (f64, f64) {
    const N: usize = 48;
    let at = |k: f64| (lo.ln() + (hi.ln() - lo.ln()) * k / (N - 1) as f64).exp();
    let k = (0..N)
        .min_by(|&a, &b| f(at(a as f64)).total_cmp(&f(at(b as f64))))
        .unwrap_or(0) as f64;
    let (mut a, mut b) = (at((k - 1.0).max(0.0)), at((k + 1.0).min((N - 1) as f64)));
    let g = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..60 {
        let (x1, x2) = (b - g * (b - a), a + g * (b - a));
        if f(x1) < f(x2) {
            b = x2;
        } else {
            a = x1;
        }
    }
    let x = 0.5 * (a + b);
    (x, f(x))
}

/// Each candidate shape fitted to the pairs, with its RMS residual: power law, toe, shoulder,
/// toe + shoulder.
pub fn fit_shapes(pairs: &[Pair]) -> Vec<(Curve, f64)> {
    let top = pairs.iter().map(|q| q.y_hi).fold(0.0, f64::max);
    let ts = |t: f64, s: f64| Curve::ToeShoulder {
        toe: t,
        shoulder: s,
    };
    // Power law: ln f⁻¹(y) = ln y / p is linear in 1/p, so least squares is closed-form.
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for q in pairs {
        let d = (q.y_hi / q.y_lo).ln();
        sxy += d * q.ratio.ln();
        sxx += d * d;
    }
    let power = Curve::Power((sxx / sxy.max(1e-300)).clamp(0.2, 5.0));
    let (t, _) = min_1d(1e-4, 0.5, |t| rms(&ts(t, f64::INFINITY), pairs));
    // A shoulder below the highest signal cannot have produced it.
    let s_lo = (top * 1.0001).max(0.2);
    let (s, _) = min_1d(s_lo, 20.0, |s| rms(&ts(0.0, s), pairs));
    // Toe and shoulder: alternate 1-D searches from the single-parameter fits.
    let (mut t2, mut s2) = (t, s);
    for _ in 0..6 {
        t2 = min_1d(1e-4, 0.5, |t| rms(&ts(t, s2), pairs)).0;
        s2 = min_1d(s_lo, 20.0, |s| rms(&ts(t2, s), pairs)).0;
    }
    let mut fits: Vec<(Curve, f64)> = [power, ts(t, f64::INFINITY), ts(0.0, s), ts(t2, s2)]
        .into_iter()
        .map(|c| (c, rms(&c, pairs)))
        .collect();
    // The two-parameter family nests both: never report it worse than either.
    let knee = if fits[1].1 <= fits[2].1 {
        fits[1]
    } else {
        fits[2]
    };
    if knee.1 < fits[3].1 {
        fits[3] = knee;
    }
    fits
}

/// The shape named (module docs): the power law unless the best of toe and shoulder halves its
/// RMS residual, then toe + shoulder only if it halves that again; a step needs the simpler
/// shape's RMS over the pairs' precision (2·10⁻³), so pairs that cannot tell shapes apart
/// (e.g. one exposure ratio) keep the power law.
pub fn choose(fits: &[(Curve, f64)]) -> (Curve, f64) {
    let better = |new: (Curve, f64), old: (Curve, f64)| {
        if new.1 < 0.5 * old.1 && old.1 > 2e-3 {
            new
        } else {
            old
        }
    };
    let knee = if fits[1].1 <= fits[2].1 {
        fits[1]
    } else {
        fits[2]
    };
    let one = better(knee, fits[0]);
    match one.0 {
        Curve::Power(_) => one,
        _ => better(fits[3], one),
    }
}
