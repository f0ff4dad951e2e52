//! `black_level`: the pedestal differs from the declared black level by `offset_dn` DN (an
//! undeclared or wrong pedestal); added after the black level (offset stage).
//!
//! Statistic (dark bursts): the mean of the temporal mean over non-hot values. Zero-mean fixed
//! patterns and noise leave it alone; hot values are masked. Fit: offset = measured −
//! simulated, averaged over dark bursts. A photon-transfer fit made with the wrong black level
//! measured every signal `offset` too high, which lowered its b by a·offset; adding the effect
//! gives that back.

use super::{Entry, FitCtx, Plan, Protocol, Stat, Summary, float, number, only, table};
use crate::sensor::captures::BurstKind;

pub const ID: &str = "black_level";
const NAME: &str = "mean dark level";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "pedestal offset from the declared black level (DN)",
    install,
    statistics,
    fit,
    adjust: Some(adjust),
};

fn install(p: &toml::Table, plan: &mut Plan) -> Result<(), String> {
    only(p, &["offset_dn"])?;
    plan.black_offset += number(p, "offset_dn")? as f32;
    Ok(())
}

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

fn fit(ctx: &FitCtx) -> Result<toml::Table, String> {
    let d = ctx.mean_excess(ID, NAME)?;
    Ok(table(&[("offset_dn", float(d))]))
}

fn adjust(profile: &mut crate::sensor::profile::SensorProfile, params: &toml::Table) {
    let off = number(params, "offset_dn").unwrap_or(0.0);
    let range = profile.levels.white_level - profile.levels.black_level;
    for n in &mut profile.noise {
        for c in 0..3 {
            n.b[c] = (n.b[c] + n.a[c] * off / range).max(0.0);
        }
    }
}
