//! `correlated_noise`: spatially correlated noise (e.g. from an ISP's demosaicing or
//! denoising): the normal draws z of the noise are filtered as
//! z' = (z + α·Σ of the 4 neighbours) / √(1 + n·α²) (n neighbours inside the frame), which keeps
//! each value's variance and gives lag-1 correlation ρ = 2α / (1 + 4α²) horizontally and
//! vertically; the parameter is ρ (noise stage; the Gaussian noise model).
//!
//! Statistic (dark bursts): lag-1 vertical correlation of the temporal residuals x_f − M
//! (vertical, because row offsets correlate a row horizontally at every lag; fixed patterns
//! cancel in the residual). Fit: ρ = (measured − simulated) × m2 / (m2 − q − row), the residual
//! variance without the uncorrelated parts (quantisation q = (L − 1)/(12 L), row offsets).

use super::{Entry, FitCtx, Plan, Protocol, Stat, Summary, float, number, only, table};
use crate::sensor::captures::BurstKind;

pub const ID: &str = "correlated_noise";
const NAME: &str = "vertical lag-1 correlation of temporal residuals";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "spatially correlated noise, lag-1 correlation rho (filtered normal draws)",
    install,
    statistics,
    fit,
    adjust: None,
};

/// Filter weight α giving lag-1 correlation ρ ∈ [0, 0.5).
pub fn alpha(rho: f64) -> f64 {
    if rho <= 0.0 {
        0.0
    } else {
        (1.0 - (1.0 - 4.0 * rho * rho).sqrt()) / (4.0 * rho)
    }
}

fn install(p: &toml::Table, plan: &mut Plan) -> Result<(), String> {
    only(p, &["rho"])?;
    let r = number(p, "rho")?;
    if !(0.0..0.5).contains(&r) {
        return Err(format!("rho {r} must be in [0, 0.5)"));
    }
    plan.corr_alpha = alpha(r) as f32;
    Ok(())
}

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s.iter().filter(|b| b.kind == BurstKind::Dark) {
        if let Some(r) = &b.resid {
            out.push(Stat {
                key: format!("{}: {NAME}", p.bursts[b.burst].name),
                effect: Some(ID),
                value: r.vcorr,
                min_effect: 0.02,
                sd_floor: 1e-4,
                unit: "",
            });
        }
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table, String> {
    let plan = super::Plan::from_effects(&ctx.profile.effects)?;
    let mut rhos = Vec::new();
    for (st, sim, b) in ctx.per_burst(ID) {
        let Some(r) = &b.resid else { continue };
        let l = b.frames as f64;
        let k = (l - 1.0) / l;
        let uncorrelated = k / 12.0 + k * (plan.row_sigma as f64).powi(2);
        let m2 = r.m2.iter().sum::<f64>() / 3.0;
        rhos.push((st.value - sim) * m2 / (m2 - uncorrelated).max(1e-9));
    }
    if rhos.is_empty() {
        return Err("no dark burst with ≥ 2 frames".into());
    }
    let rho = rhos.iter().sum::<f64>() / rhos.len() as f64;
    if !(rho > 0.0 && rho < 0.5) {
        return Err(format!("fitted correlation {rho:.4} is outside (0, 0.5)"));
    }
    Ok(table(&[("rho", float(rho))]))
}
