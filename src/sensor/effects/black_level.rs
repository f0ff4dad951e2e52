//! `black_level`: the pedestal differs from the declared black level by `offset_dn` DN (an
//! undeclared or wrong pedestal); added after the black level (offset stage).
//!
//! Statistic (dark bursts): the mean of the temporal mean over non-hot values. Zero-mean fixed
//! patterns and noise leave it alone; hot values are masked. Fit: offset = measured −
//! simulated, averaged over dark bursts. No adjustment of the noise: the base model's (a, b)
//! are measured from the dark mean (`summary::temporal_ptc`) and refitted after every step, and
//! a given profile's noise is the user's. (The old rule b += a·offset assumed an unclamped
//! photon-transfer fit without darks; with b clamped at 0 it breaks.)

use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::BLACK_LEVEL;
const NAME: &str = "mean dark level";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "pedestal offset from the declared black level (DN)",
    needs: "a dark burst",
    statistics,
    fit,
    adjust: None,
};

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s.iter().filter(|b| b.kind == BurstKind::Dark) {
        out.push(Stat {
            key: format!("{}: {NAME}", p.bursts[b.burst].name),
            effect: Some(ID),
            value: super::masked_mean(&b.mean, |i| b.not_hot(i)),
            min_effect: 0.5,
            sd_floor: 0.01,
            unit: "DN",
        });
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let d = ctx.mean_excess(ID, NAME)?;
    Ok(table(&[("offset_dn", float(d))]))
}
