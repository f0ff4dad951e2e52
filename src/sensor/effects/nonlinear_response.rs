//! `nonlinear_response`: the signal is not proportional to exposure × ISO: I → R·(I/R)^p with
//! R = white − black (a power-law tone curve; p = 1 is linear), applied to the signal before
//! noise.
//!
//! Statistic (scene bursts): scene bursts of one frame size are one static scene at different
//! exposure × ISO. Against the burst of the largest exposure (the reference), each other burst
//! j gives the exponent p̂_j = ln(Σ s_ref / Σ s_j) / ln(E_ref / E_j), s = temporal mean − black
//! over pixels where the reference is below 90 % of the range and s_j above 2 % (1 for a linear
//! sensor; the measured ratio of a tone-mapped EV0/EV−3 pair is not 8). Fit: p = p_model ×
//! mean(measured / simulated).

use super::{Entry, FitCtx, Plan, Protocol, Stat, Summary, float, number, only, table};
use crate::sensor::captures::BurstKind;

pub const ID: &str = "nonlinear_response";
const NAME: &str = "response exponent";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "signal not proportional to exposure × ISO: I → R·(I/R)^exponent",
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

/// Scene bursts grouped by frame size; within a group the reference (largest exposure) first.
pub fn scene_groups(s: &[Summary]) -> Vec<Vec<&Summary>> {
    let mut groups: Vec<Vec<&Summary>> = Vec::new();
    for b in s.iter().filter(|b| b.kind == BurstKind::Scene) {
        match groups
            .iter_mut()
            .find(|g| (g[0].width, g[0].height) == (b.width, b.height))
        {
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

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    let top = p.white - p.black;
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
