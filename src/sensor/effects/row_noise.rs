//! `row_noise`: an offset per row, N(0, σ²) DN, drawn anew in every frame and shared by the
//! three channels of the row (offset stage).
//!
//! Statistic (dark bursts): the covariance over frames of the left-half and right-half means of
//! each row, averaged over rows. A row offset is in both halves; pixel-level noise (white,
//! heavy-tailed or short-range correlated) is not, and fixed patterns do not vary over frames,
//! so only per-frame row offsets make it non-zero: E = σ². Fit: σ² = measured − simulated.
//! The base model's b was fitted to temporal variances that include σ², so adding the effect
//! lowers b by σ² (in DN²) at every ISO.

use super::params::parse;
use super::plan::{RowNoise, id};
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;
use crate::sensor::profile::SensorProfile;

pub const ID: &str = id::ROW_NOISE;
const NAME: &str = "row offset covariance (left × right half)";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "row offsets N(0, sigma_dn²) drawn anew in every frame",
    needs: "a dark burst with ≥ 2 frames",
    statistics,
    fit,
    adjust: Some(adjust),
};

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s.iter().filter(|b| b.kind == BurstKind::Dark) {
        if let Some(r) = &b.resid {
            out.push(Stat::dark_dn2(p, b, ID, NAME, r.row_cov));
        }
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let s = ctx.excess_sigma(ID, NAME, "row covariance")?;
    Ok(table(&[("sigma_dn", float(s))]))
}

fn adjust(profile: &mut SensorProfile, params: &toml::Table) {
    let s = parse::<RowNoise>(ID, params).map_or(0.0, |p| p.sigma_dn.0);
    let range = profile.levels.white_level - profile.levels.black_level;
    for n in &mut profile.noise {
        for b in &mut n.b {
            *b = (*b - s * s / (range * range)).max(0.0);
        }
    }
}
