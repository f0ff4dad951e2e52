//! `nonlinear_response`: the signal is not proportional to exposure × ISO: I → R·(I/R)^p with
//! R = white − black (a power-law tone curve; p = 1 is linear), applied to the signal before
//! noise.
//!
//! Statistic (scene bursts): scene bursts of one frame size are one static scene at different
//! exposure × ISO. Against the burst of the largest exposure (the reference), each other burst
//! j gives the exponent p̂_j = ln(Σ s_ref / Σ s_j) / ln(E_ref / E_j), s = temporal mean − black
//! over pixels where the reference is below 90 % of the range and s_j above 2 % (1 for a linear
//! sensor; the measured ratio of a tone-mapped EV0/EV−3 pair is not 8). Flat series (EMVA
//! 1288 linearity): flats of one ISO and size at several exposure times, one illumination;
//! each flat's mean signal above the dark mean against the longest unsaturated exposure's,
//! p̂ = ln(μ_ref / μ_j) / ln(t_ref / t_j). Fit: p = p_model × mean(measured / simulated) over
//! all these statistics.

use super::{Entry, FitCtx, Plan, Protocol, Stat, Summary, float, number, only, table};
use crate::sensor::captures::BurstKind;

pub const ID: &str = "nonlinear_response";
const NAME: &str = "response exponent";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "signal not proportional to exposure × ISO: I → R·(I/R)^exponent",
    needs: "scene bursts of one scene at two exposures, or flats of one ISO at two exposure times",
    install,
    statistics,
    fit,
    adjust: None,
};

fn install(p: &toml::Table, plan: &mut Plan) -> Result<(), String> {
    only(p, &["exponent"])?;
    let e = number(p, "exponent")?;
    if !(0.2..=5.0).contains(&e) {
        return Err(format!("exponent {e} must be in [0.2, 5]"));
    }
    plan.exponent = Some(e as f32);
    Ok(())
}

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

fn fit(ctx: &FitCtx) -> Result<toml::Table, String> {
    let pairs = ctx.pairs(ID, "");
    if pairs.is_empty() {
        return Err("no scene bursts at two exposures".into());
    }
    let ratio = pairs.iter().map(|(m, s)| m / s).sum::<f64>() / pairs.len() as f64;
    let e = ctx.protocol.exponent * ratio;
    if !(0.2..=5.0).contains(&e) {
        return Err(format!("fitted exponent {e:.4} is outside [0.2, 5]"));
    }
    Ok(table(&[("exponent", float(e))]))
}
