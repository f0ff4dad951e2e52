//! The parametric bootstrap: the capture protocol simulated K times under a model, and the
//! measured statistics compared with the simulated ones.

use super::{DiagnoseOptions, Evaluation, Row, protocol};
use crate::error::Result;
use crate::io::Image;
use crate::rng::hash;
use crate::sensor::captures::{BurstKind, CaptureSet};
use crate::sensor::effects::summary::Accumulator;
use crate::sensor::effects::{self, Plan, Protocol, Stat, Summary};
use crate::sensor::profile::{Response, SensorProfile};
use crate::sensor::realism::{NoiseModel, Realism, RealismOptions};

/// Simulation targets (linear input images, normalised so 1 = the range) per burst; None for
/// bursts that no statistic uses (charts, lone scene bursts).
fn targets(proto: &Protocol, measured: &[Summary], plan: &Plan) -> Vec<Option<Image>> {
    let range = proto.range;
    let lin = |s: f64| range * proto.linearise(s / range);
    let groups = effects::nonlinear_response::scene_groups(measured);
    let flat_series: Vec<(Vec<&Summary>, Option<&Summary>)> =
        effects::nonlinear_response::flat_series(measured)
            .into_iter()
            .map(|g| {
                let zero =
                    effects::summary::dark_mean(measured, g[0].iso).unwrap_or([proto.black; 3]);
                let r = effects::nonlinear_response::flat_reference(
                    &g,
                    zero,
                    proto.white - proto.black,
                );
                (g, r)
            })
            .collect();
    measured
        .iter()
        .map(|m| {
            let (w, h) = (m.width, m.height);
            match m.kind {
                BurstKind::Dark => Some(Image::new(w, h)),
                BurstKind::Flat => {
                    let mut g = 0.0;
                    for &y in &m.rows {
                        for x in 0..w {
                            g += effects::vignetting::gain(
                                plan.vignetting_k,
                                x,
                                y,
                                w,
                                m.full_height,
                            ) as f64;
                        }
                    }
                    g /= (w * h) as f64;
                    // In a flat series (one illumination, several exposure times) the level
                    // is the reference's scaled by exposure, so the model's response is
                    // tested (EMVA 1288); otherwise the flat's own measured level.
                    let (src, scale) = flat_series
                        .iter()
                        .find(|(g, _)| g.iter().any(|b| b.burst == m.burst))
                        .and_then(|(_, r)| *r)
                        .map_or((m, 1.0), |r| (r, m.exposure_s / r.exposure_s));
                    let level: [f64; 3] = std::array::from_fn(|c| {
                        let s = effects::masked_mean(&src.mean, |i| i % 3 == c && src.not_hot(i));
                        lin((s - proto.black) / g) * scale / range
                    });
                    Some(Image::from_fn(w, h, |_, _| level.map(|v| v as f32)))
                }
                BurstKind::Scene => {
                    let g = groups
                        .iter()
                        .find(|g| g.iter().any(|b| b.burst == m.burst))?;
                    let top = 0.9 * (proto.white - proto.black);
                    let data = (0..w * h * 3)
                        .map(|i| {
                            // Radiance from the longest exposure that is not saturated there.
                            let src = g
                                .iter()
                                .find(|b| b.mean[i] - proto.black < top)
                                .unwrap_or(&g[g.len() - 1]);
                            let x = lin(src.mean[i] - proto.black) / src.exposure();
                            (x * m.exposure() / range) as f32
                        })
                        .collect();
                    Some(Image::from_vec(w, h, data))
                }
                BurstKind::Chart => None,
            }
        })
        .collect()
}

/// All catalogue statistics of a set of summaries.
pub fn statistics(proto: &Protocol, summaries: &[Summary]) -> Vec<Stat> {
    let mut out = Vec::new();
    for e in &effects::CATALOGUE {
        (e.statistics)(proto, summaries, &mut out);
    }
    // Base-model checks: the temporal variance itself (no catalogue effect explains it).
    for b in summaries
        .iter()
        .filter(|b| matches!(b.kind, BurstKind::Dark | BurstKind::Flat) && !b.var.is_empty())
    {
        out.push(Stat {
            key: format!("{}: mean temporal variance", proto.bursts[b.burst].name),
            effect: None,
            value: b.temporal_mean(),
            min_effect: 0.05 * b.temporal_mean(),
            sd_floor: 1e-4,
            unit: "DN²",
        });
    }
    out
}

/// One replicate of the protocol under `profile`: summaries of the simulated bursts.
fn simulate(
    profile: &SensorProfile,
    proto: &Protocol,
    targets: &[Option<Image>],
    seed: u64,
    k: usize,
) -> Result<Vec<Summary>> {
    let mut p = profile.clone();
    p.source_response = Response::Linear;
    for (i, e) in p.effects.iter_mut().enumerate() {
        if e.params.contains_key("seed") {
            e.params.insert(
                "seed".into(),
                effects::seed_value(hash(seed, &[k as u64, i as u64, 0x5eed])),
            );
        }
    }
    let lo = p.noise.first().map_or(0.0, |n| n.iso);
    let hi = p.noise.last().map_or(0.0, |n| n.iso);
    let mut out = Vec::new();
    let mut frame = Image::new(0, 0);
    for (i, (info, t)) in proto.bursts.iter().zip(targets).enumerate() {
        let Some(t) = t else { continue };
        let mut opts = RealismOptions::new(info.iso.clamp(lo, hi));
        opts.colour = false;
        opts.noise = NoiseModel::Gaussian;
        opts.output_bits = 16;
        let r = Realism::new(&p, &opts)?;
        let mut acc = Accumulator::new(info, false);
        for j in 0..info.frames {
            let seed = hash(seed, &[k as u64, i as u64, j as u64]);
            r.to_dn_rows_into(t, &info.rows, info.height, seed, &mut frame);
            acc.add(&frame);
        }
        out.push(acc.finish(i, info).0);
    }
    Ok(out)
}

pub(super) struct Context<'a> {
    pub(super) set: &'a CaptureSet,
    pub(super) measured: &'a [Summary],
    pub(super) opts: &'a DiagnoseOptions,
    pub(super) threshold: f64,
}

/// Compare the measured statistics with K simulated replicates of `profile`.
pub(super) fn evaluate(ctx: &Context, profile: &SensorProfile) -> Result<Evaluation> {
    let proto = protocol(ctx.set, profile, ctx.opts.max_pixels)?;
    let plan = Plan::from_effects(&profile.effects)?;
    let measured = statistics(&proto, ctx.measured);
    let tg = targets(&proto, ctx.measured, &plan);
    let k = ctx.opts.replicates;
    let mut sims: Vec<Vec<Stat>> = Vec::with_capacity(k);
    for r in 0..k {
        let s = simulate(profile, &proto, &tg, ctx.opts.seed, r)?;
        sims.push(statistics(&proto, &s));
    }
    let mut rows = Vec::new();
    for st in measured {
        let vals: Vec<f64> = sims
            .iter()
            .filter_map(|s| s.iter().find(|x| x.key == st.key).map(|x| x.value))
            .filter(|v| v.is_finite())
            .collect();
        if vals.len() < 2 || !st.value.is_finite() {
            continue;
        }
        let n = vals.len() as f64;
        let mean = vals.iter().sum::<f64>() / n;
        let sd = (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let z = (st.value - mean) / (sd.max(st.sd_floor) * (1.0 + 1.0 / n).sqrt());
        let large = (st.value - mean).abs() > st.min_effect;
        rows.push(Row {
            significant: large && z.abs() > ctx.threshold,
            large,
            sim_mean: mean,
            sim_sd: sd,
            z,
            stat: st,
        });
    }
    let gap = rows
        .iter()
        .filter(|r| r.large)
        .map(|r| r.z.abs())
        .fold(0.0, f64::max);
    Ok(Evaluation { rows, gap })
}
