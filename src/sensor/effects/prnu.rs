//! `prnu`: photo-response non-uniformity, a fixed per-value gain 1 + σ·z (z standard normal
//! from the pattern seed and the coordinates), applied to the signal before noise.
//!
//! Statistic (flat bursts): the fixed residual variance of the flat mean (a quadratic surface
//! removed, so vignetting does not count; row and column means removed, so column offsets do
//! not count; hot values masked) minus the temporal part v̄/L (EMVA 1288), minus the same
//! offset-only excess of a dark burst at the same ISO (DSNU), divided by the squared mean
//! signal: an estimate of σ². Fit: σ² = measured − simulated.

use super::not_fitted;
use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, hashed_normal};
use super::{seed_value, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::PRNU;
const NAME: &str = "PRNU variance (relative²)";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "fixed per-pixel gain 1 + σ·z (high-frequency photo-response non-uniformity)",
    needs: "a flat burst with ≥ 2 frames",
    statistics,
    fit,
    adjust: None,
};

pub fn gain(sigma: f32, seed: u64, x: usize, y: usize, c: usize) -> f32 {
    1.0 + sigma * hashed_normal(seed, &[x as u64, y as u64, c as u64, 0x9d])
}

/// Offset-only fixed excess of a dark or flat burst: fixed residual variance − v̄/L.
pub fn fixed_excess(b: &Summary) -> f64 {
    b.fixed_var - b.temporal_mean() / b.frames as f64
}

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s
        .iter()
        .filter(|b| b.kind == BurstKind::Flat && !b.var.is_empty())
    {
        let dark = s
            .iter()
            .find(|d| d.kind == BurstKind::Dark && d.iso == b.iso && !d.var.is_empty())
            .map_or(0.0, fixed_excess);
        let signal = super::masked_mean(&b.mean, |i| b.not_hot(i)) - p.black;
        out.push(Stat {
            key: format!("{}: {NAME}", p.bursts[b.burst].name),
            effect: Some(ID),
            value: (fixed_excess(b) - dark) / (signal * signal).max(1e-12),
            min_effect: 0.003f64.powi(2),
            sd_floor: 1e-10,
            unit: "",
        });
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let v = ctx.mean_excess(ID, NAME)?;
    if v <= 0.0 {
        return Err(not_fitted(
            ID,
            format!("excess PRNU variance {v:.3e} is not positive"),
        ));
    }
    Ok(table(&[
        ("sigma", float(v.sqrt())),
        ("seed", seed_value(ctx.seed)),
    ]))
}
