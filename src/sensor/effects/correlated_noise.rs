//! `correlated_noise`: spatially correlated noise (an ISP's demosaicing, denoising or binning):
//! the normal draws z of the noise are filtered by a separable discrete Gaussian kernel,
//! k(i) ∝ exp(−i²/(2s²)) for |i| ≤ ⌈3s⌉, one width per axis, normalised to Σk² = 1 so each
//! value keeps its variance (draws outside the frame are made too, so the field is stationary
//! up to the border). The lag-d correlation along an axis is Σ_i k(i)·k(i + d), which spans
//! [0, 1) as s grows (0.95 at s ≈ 2.2); the parameters are the lag-1 correlations
//! `rho_h`, `rho_v` ∈ [0, 0.95] (`rho` alone sets both; noise stage, Gaussian noise model).
//!
//! Statistics (dark bursts, temporal residuals x_f − M, same channel; fixed patterns cancel):
//! vertical lag-1 and lag-2 correlation, and horizontal lag-1 correlation less the row-offset
//! part (a row offset correlates a row at every horizontal lag; its variance is the row
//! statistic's covariance of half-row means). Fit (from the measured 2-D autocorrelation
//! directly, EMVA-style): per axis, the noise correlation at lags 1 and 2 is the residual
//! covariance over the residual variance without its uncorrelated parts (quantisation, and
//! horizontally the row offsets), and the kernel width minimises the squared error at both
//! lags.

use super::not_fitted;
use super::plan::{RHO_MAX, id, kernel, lag_correlation, width};
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::CORRELATED_NOISE;
const NAMES: [&str; 3] = [
    "vertical lag-1 correlation of temporal residuals",
    "vertical lag-2 correlation of temporal residuals",
    "horizontal lag-1 correlation of temporal residuals (row offsets removed)",
];

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "spatially correlated noise: separable Gaussian kernel, lag-1 correlation rho_h, rho_v",
    needs: "a dark burst with ≥ 2 frames",
    statistics,
    fit,
    adjust: None,
};

/// Residual noise correlations of a dark summary: (vertical lag 1, vertical lag 2, horizontal
/// lag 1 without row offsets), each over the residual variance without its uncorrelated parts
/// (quantisation, and for the horizontal lag the row offsets, which are also in m2).
fn correlations(b: &Summary) -> Option<[[f64; 2]; 2]> {
    let r = b.resid.as_ref()?;
    let l = b.frames as f64;
    let k = (l - 1.0) / l;
    let m2 = r.m2.iter().sum::<f64>() / 3.0;
    let row = k * r.row_cov.max(0.0);
    let denom = (m2 - k / 12.0 - row).max(1e-9);
    Some([
        [r.cov_v[0] / denom, r.cov_v[1] / denom],
        [(r.cov_h[0] - row) / denom, (r.cov_h[1] - row) / denom],
    ])
}

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s.iter().filter(|b| b.kind == BurstKind::Dark) {
        let Some(c) = correlations(b) else { continue };
        for (name, v) in NAMES.iter().zip([c[0][0], c[0][1], c[1][0]]) {
            out.push(Stat {
                key: format!("{}: {name}", p.bursts[b.burst].name),
                effect: Some(ID),
                value: v,
                min_effect: 0.02,
                sd_floor: 1e-4,
                unit: "",
            });
        }
    }
}

/// Lag-1 correlation of the kernel that best matches measured lag-1 and lag-2 correlations.
fn fit_axis(m1: f64, m2: f64) -> f64 {
    let err = |s: f64| {
        let k = kernel(s);
        (lag_correlation(&k, 1) - m1).powi(2) + (lag_correlation(&k, 2) - m2).powi(2)
    };
    // Grid, then a ternary search around the best node (the error is smooth in s).
    let (s_max, n) = (width(RHO_MAX), 200);
    let step = s_max / n as f64;
    let best = (0..=n)
        .map(|i| step * i as f64)
        .min_by(|a, b| err(*a).total_cmp(&err(*b)))
        .unwrap_or(0.0);
    let (mut lo, mut hi) = ((best - step).max(0.0), (best + step).min(s_max));
    for _ in 0..40 {
        let (a, b) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
        if err(a) < err(b) {
            hi = b;
        } else {
            lo = a;
        }
    }
    lag_correlation(&kernel(0.5 * (lo + hi)), 1)
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let cs: Vec<[[f64; 2]; 2]> = super::of_kind(ctx.summaries, BurstKind::Dark)
        .filter_map(correlations)
        .collect();
    if cs.is_empty() {
        return Err(not_fitted(ID, "no dark burst with ≥ 2 frames"));
    }
    let n = cs.len() as f64;
    let mean = |a: usize, l: usize| cs.iter().map(|c| c[a][l]).sum::<f64>() / n;
    let (v, h) = (
        fit_axis(mean(0, 0), mean(0, 1)),
        fit_axis(mean(1, 0), mean(1, 1)),
    );
    if v.max(h) <= 0.0 {
        return Err(not_fitted(
            ID,
            "no positive noise correlation at lags 1 and 2",
        ));
    }
    Ok(table(&[("rho_h", float(h)), ("rho_v", float(v))]))
}
