//! `heavy_tailed_read_noise`: the read noise (the b part of σ² = a·I + b) is Student-t with
//! `dof` degrees of freedom scaled to the same variance b, instead of Gaussian (noise stage).
//!
//! Statistic (dark bursts): excess kurtosis m4/m2² − 3 of the temporal residuals x_f − M, per
//! channel, averaged over the channels (pooling channels of different noise — channel noise — is
//! a scale mixture and has excess kurtosis of its own). Fixed patterns cancel in the residual
//! and row offsets and correlated noise are Gaussian, so only a non-Gaussian noise process moves
//! it.
//! Fit: for L frames a residual's fourth cumulant is κ4·((L − 1)⁴ + L − 1)/L⁴ of the sample's;
//! the excess over the simulated value, times m2², gives κ4 of the read noise, its excess
//! kurtosis κ = κ4 / b², and the Student-t with that kurtosis has dof = 4 + 6/κ.

use super::not_fitted;
use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::HEAVY_TAILED_READ_NOISE;
const NAME: &str = "excess kurtosis of temporal residuals";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "Student-t read noise (dof degrees of freedom) of the profile's variance b",
    needs: "a dark burst with ≥ 2 frames",
    statistics,
    fit,
    adjust: None,
};

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s.iter().filter(|b| b.kind == BurstKind::Dark) {
        if let Some(r) = &b.resid {
            out.push(Stat {
                key: format!("{}: {NAME}", p.bursts[b.burst].name),
                effect: Some(ID),
                value: (0..3)
                    .map(|c| r.m4[c] / (r.m2[c] * r.m2[c]) - 3.0)
                    .sum::<f64>()
                    / 3.0,
                min_effect: 0.1,
                sd_floor: 1e-3,
                unit: "",
            });
        }
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let range = ctx.profile.levels.white_level - ctx.profile.levels.black_level;
    let plan = super::Plan::from_effects(&ctx.profile.effects)?;
    let mut kappas = Vec::new();
    for (st, sim, b) in ctx.per_burst(ID) {
        let (Some(r), Ok((_, bn))) = (&b.resid, ctx.profile.noise_at(b.iso)) else {
            continue;
        };
        let l = b.frames as f64;
        // Per channel: κ4 of the residuals = Δ(excess kurtosis)·m2²; of one sample ×
        // L⁴/((L − 1)⁴ + L − 1); over the read variance² → the read noise's excess kurtosis.
        let k = (0..3)
            .map(|c| {
                let read = bn[c] * range * range * plan.b_scale[c] as f64;
                let k4_resid = (st.value - sim) * r.m2[c] * r.m2[c];
                k4_resid * l.powi(4) / ((l - 1.0).powi(4) + l - 1.0) / (read * read)
            })
            .sum::<f64>()
            / 3.0;
        kappas.push(k);
    }
    if kappas.is_empty() {
        return Err(not_fitted(ID, "no dark burst with ≥ 2 frames"));
    }
    let k = kappas.iter().sum::<f64>() / kappas.len() as f64;
    if k <= 0.0 {
        return Err(not_fitted(
            ID,
            format!("read-noise excess kurtosis {k:.3} is not positive"),
        ));
    }
    Ok(table(&[("dof", float(4.0 + 6.0 / k))]))
}
