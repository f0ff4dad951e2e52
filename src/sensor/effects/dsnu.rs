//! `dsnu`: dark signal non-uniformity, a fixed offset N(0, σ²) DN per value without row or
//! column structure (offset stage, from the pattern seed).
//!
//! Statistic (dark bursts): the variance of the dark temporal mean after removing row and
//! column means (so column and row patterns do not count), hot values masked, corrected for the
//! removed degrees of freedom, minus the temporal part v̄/L (EMVA 1288). Fit: σ² = measured −
//! simulated.

use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, hashed_normal};
use super::{prnu::fixed_excess, seed_value, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::DSNU;
const NAME: &str = "fixed pixel variance (rows, columns removed)";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "fixed per-pixel dark offsets N(0, sigma_dn²) without row/column structure",
    needs: "a dark burst with ≥ 2 frames",
    statistics,
    fit,
    adjust: None,
};

pub fn offset(sigma: f32, seed: u64, x: usize, y: usize, c: usize) -> f32 {
    sigma * hashed_normal(seed, &[x as u64, y as u64, c as u64, 0xd5])
}

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s
        .iter()
        .filter(|b| b.kind == BurstKind::Dark && !b.var.is_empty())
    {
        out.push(Stat::dark_dn2(p, b, ID, NAME, fixed_excess(b)));
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let s = ctx.excess_sigma(ID, NAME, "fixed variance")?;
    Ok(table(&[
        ("sigma_dn", float(s)),
        ("seed", seed_value(ctx.seed)),
    ]))
}
