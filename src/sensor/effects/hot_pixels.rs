//! `hot_pixels`: a fraction of values (pixel × channel, from the pattern seed) carries a fixed
//! extra offset of `offset_dn` DN (offset stage).
//!
//! Statistic (dark bursts): the fraction of values whose fixed residual (temporal mean minus
//! row and column means) is above 8 robust σ (σ from the MAD, so DSNU and temporal noise set the
//! scale and are not counted). A temporal mean persists over the burst by construction; a
//! single-frame spike of s DN moves it by s/L only. Fit: fraction = measured − simulated;
//! offset = median residual of the measured hot values.

use super::not_fitted;
use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, hashed_unit};
use super::{seed_value, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::HOT_PIXELS;
const NAME: &str = "hot value fraction";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "a fraction of values with a fixed extra dark offset (offset_dn)",
    needs: "a dark burst",
    statistics,
    fit,
    adjust: None,
};

pub fn offset(fraction: f32, off: f32, seed: u64, x: usize, y: usize, c: usize) -> f32 {
    if hashed_unit(seed, &[x as u64, y as u64, c as u64, 0x40]) < fraction {
        off
    } else {
        0.0
    }
}

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s.iter().filter(|b| b.kind == BurstKind::Dark) {
        let n = b.hot.len().max(1) as f64;
        out.push(Stat {
            key: format!("{}: {NAME}", p.bursts[b.burst].name),
            effect: Some(ID),
            value: b.hot.iter().filter(|h| **h).count() as f64 / n,
            min_effect: 3.0 / n,
            sd_floor: 1.0 / n,
            unit: "",
        });
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let f = ctx.mean_excess(ID, NAME)?;
    let mut excess: Vec<f64> = ctx
        .summaries
        .iter()
        .filter(|b| b.kind == BurstKind::Dark)
        .flat_map(|b| {
            b.fixed
                .iter()
                .zip(&b.hot)
                .filter(|(_, h)| **h)
                .map(|(v, _)| *v)
        })
        .collect();
    if f <= 0.0 || excess.is_empty() {
        return Err(not_fitted(
            ID,
            format!("excess hot fraction {f:.2e} is not positive"),
        ));
    }
    let mid = excess.len() / 2;
    let off = *excess.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
    Ok(table(&[
        ("fraction", float(f)),
        ("offset_dn", float(off)),
        ("seed", seed_value(ctx.seed)),
    ]))
}
