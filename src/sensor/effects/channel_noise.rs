//! `channel_noise`: the noise parameters differ per colour channel: a and b of the profile are
//! multiplied by `a_scale[c]`, `b_scale[c]` (the base model fitted without a profile shares one
//! (a, b) per ISO across channels). Changes the noise process itself (noise stage).
//!
//! Statistic (dark and flat bursts): each channel's mean temporal variance over the mean of the
//! three (non-hot values); effects shared by the channels (row offsets, correlated or heavy-
//! tailed noise of equal variance) leave these ratios alone. Fit: the captures' per-channel
//! temporal photon transfer (`summary::temporal_ptc`, row-offset variance taken out of b) over
//! the model's a, b at each ISO with dark and flat bursts, averaged over ISOs.

use super::not_fitted;
use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::CHANNEL_NOISE;
const NAMES: [&str; 3] = [
    "temporal variance ratio R",
    "temporal variance ratio G",
    "temporal variance ratio B",
];

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "different noise a, b per colour channel (multipliers on the profile's a, b)",
    needs: "a dark or flat burst with ≥ 2 frames",
    statistics,
    fit,
    adjust: None,
};

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s
        .iter()
        .filter(|b| matches!(b.kind, BurstKind::Dark | BurstKind::Flat) && !b.var.is_empty())
    {
        let m = b.temporal_mean();
        for (c, name) in NAMES.iter().enumerate() {
            out.push(Stat {
                key: format!("{}: {name}", p.bursts[b.burst].name),
                effect: Some(ID),
                value: b.temporal_var[c] / m,
                min_effect: 0.05,
                sd_floor: 1e-4,
                unit: "",
            });
        }
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let range = ctx.profile.levels.white_level - ctx.profile.levels.black_level;
    let plan = super::Plan::from_effects(&ctx.profile.effects)?;
    let row_var = (plan.row_sigma as f64).powi(2);
    let ptc = super::summary::temporal_ptc(ctx.summaries, ctx.protocol.black, row_var);
    let (mut sa, mut sb, mut n) = ([0.0; 3], [0.0; 3], 0.0);
    for f in &ptc {
        let (Some(fa), Ok((a, b))) = (f.a, ctx.profile.noise_at(f.iso)) else {
            continue;
        };
        for c in 0..3 {
            let (am, bm) = (a[c] * range, b[c] * range * range);
            if am <= 0.0 || bm <= 0.0 {
                return Err(not_fitted(
                    ID,
                    format!("model a or b is 0 at ISO {}", f.iso),
                ));
            }
            sa[c] += fa[c] / am;
            sb[c] += f.b[c] / bm;
        }
        n += 1.0;
    }
    if n == 0.0 {
        return Err(not_fitted(
            ID,
            "no ISO with dark and flat bursts inside the model's range",
        ));
    }
    let arr = |s: [f64; 3]| toml::Value::Array(s.iter().map(|v| float(v / n)).collect());
    Ok(table(&[("a_scale", arr(sa)), ("b_scale", arr(sb))]))
}
