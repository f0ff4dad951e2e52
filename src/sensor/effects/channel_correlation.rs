//! `channel_correlation`: noise shared by a pixel's channels (chroma noise reduced harder than
//! luma, chroma subsampling, a demosaicker that spreads one photosite's noise into three
//! values): each pixel's three normal draws z are mixed as a·z_c + b·s, s = z̄√3, which keeps
//! each value's variance and correlates every two channels by `rho` ∈ [0, 0.95]
//! (`plan::channel_mix`; noise stage, Gaussian noise model, after the spatial filter of
//! `correlated_noise`; with heavy-tailed read noise only the draws z, the shot part, are
//! mixed).
//!
//! Statistic (dark bursts, temporal residuals x_f − M; fixed patterns cancel): the covariance
//! of a pixel's neighbouring channels (R·G and G·B pooled) less the row-offset part, over the
//! residual variance without its uncorrelated parts (quantisation, row offsets) — the
//! correlation of the channels' noise. Fit: that correlation directly.

use super::not_fitted;
use super::plan::{RHO_MAX, id};
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::CHANNEL_CORRELATION;

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "noise shared by a pixel's channels (chroma noise): correlation rho",
    needs: "a dark burst with ≥ 2 frames",
    statistics,
    fit,
    adjust: None,
};

/// The channels' noise correlation of a dark summary (row offsets and quantisation removed).
fn correlation(b: &Summary) -> Option<f64> {
    let r = b.resid.as_ref()?;
    let l = b.frames as f64;
    let k = (l - 1.0) / l;
    let m2 = r.m2.iter().sum::<f64>() / 3.0;
    // A row offset is one value for the whole row, all channels: in m2 and in the covariance.
    let row = k * r.row_cov.max(0.0);
    Some((r.cov_c - row) / (m2 - k / 12.0 - row).max(1e-9))
}

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s.iter().filter(|b| b.kind == BurstKind::Dark) {
        let Some(c) = correlation(b) else { continue };
        out.push(Stat {
            key: format!(
                "{}: correlation of neighbouring channels' temporal residuals",
                p.bursts[b.burst].name
            ),
            effect: Some(ID),
            value: c,
            min_effect: 0.02,
            sd_floor: 1e-4,
            unit: "",
        });
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let cs: Vec<f64> = super::of_kind(ctx.summaries, BurstKind::Dark)
        .filter_map(correlation)
        .collect();
    if cs.is_empty() {
        return Err(not_fitted(ID, "no dark burst with ≥ 2 frames"));
    }
    let rho = cs.iter().sum::<f64>() / cs.len() as f64;
    if rho <= 0.0 {
        return Err(not_fitted(
            ID,
            "no positive correlation between the channels' noise",
        ));
    }
    Ok(table(&[("rho", float(rho.min(RHO_MAX)))]))
}
