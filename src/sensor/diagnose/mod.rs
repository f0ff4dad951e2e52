//! The sim-to-real gap workflow (docs/diagnose.md): measured captures against the same capture
//! protocol simulated by the current model, through the realism operator itself.
//!
//! 1. Base model: the given profile, or (none given) the paper's model fitted from the
//!    captures: one (a, b) per ISO shared by the channels (mean of the per-channel photon-
//!    transfer fits of src/sensor/noise/), the declared black and white levels, T from the
//!    chart burst (`colour::fit::fit_chart`, as `calibrate colour`); no extra effects.
//! 2. Parametric bootstrap: K replicates of the whole protocol (same bursts, ISOs, exposures,
//!    frame counts and sizes) simulated with `Realism::to_dn`; targets: dark = nothing, flat =
//!    the measured level (per channel, linearised by the model), scene = the radiance measured
//!    from the longest unsaturated exposure of the same scene, scaled to each exposure.
//!    Fixed-pattern seeds change per replicate (the real sensor's pattern is one realisation),
//!    and stay fixed over the frames and bursts of a replicate.
//! 3. Every catalogue statistic on the measured and simulated summaries → z = (measured − mean)
//!    / (sd·√(1 + 1/K)). The gap is the largest |z| among statistics whose |measured − mean|
//!    also exceeds their minimum effect size; the threshold is Bonferroni over the m statistics,
//!    Φ⁻¹(1 − α/(2m)) with α = 0.05, at least 3.
//! 4. While the gap is over the threshold: the effect of the statistic with the largest
//!    significant |z| (not yet in the model) is named, fitted and added; the step is kept when
//!    the gap shrinks, otherwise undone and the effect set aside. When no catalogue effect
//!    explains what is left, the loop stops and the report lists those statistics.

mod bootstrap;
mod notes;
mod plots;
mod report;

use crate::error::{Error, Result};
use crate::io::Image;
use crate::rng::hash;
use crate::sensor::captures::{BurstKind, CaptureSet};
use crate::sensor::colour::chart::reference_linear_srgb;
use crate::sensor::colour::fit::{ChartFitError, WhiteBalance, fit_chart};
use crate::sensor::effects::summary::{Accumulator, BurstInfo};
use crate::sensor::effects::{self, FitCtx, Plan, Protocol, Stat, Summary};
use crate::sensor::noise::{self, CalibrateOptions, NoiseCalibration};
use crate::sensor::profile::{Colour, EffectSpec, Levels, SensorProfile};
use bootstrap::{Context, evaluate, statistics};
pub use notes::Note;
use plots::radial_profile;
use rayon::prelude::*;
use report::evidence;
use std::path::Path;

pub const REPORT_FORMAT: &str = "hdrsynth-diagnosis/1";

#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    /// Bootstrap replicates per evaluation.
    pub replicates: usize,
    pub seed: u64,
    /// Family-wise false-alarm rate of the Bonferroni threshold.
    pub alpha: f64,
    /// Bursts of more pixels are analysed on bands of rows of about this many pixels
    /// (`summary::analysed_rows`), measured and simulated alike; 0: every row.
    pub max_pixels: usize,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            replicates: 30,
            seed: 1,
            alpha: 0.05,
            max_pixels: 1 << 16,
        }
    }
}

/// One statistic compared.
#[derive(Clone, Debug)]
pub struct Row {
    pub stat: Stat,
    pub sim_mean: f64,
    pub sim_sd: f64,
    pub z: f64,
    /// |z| over the threshold and |measured − simulated| over the minimum effect size.
    pub significant: bool,
    /// |measured − simulated| over the minimum effect size (counts towards the gap).
    pub large: bool,
}

#[derive(Clone, Debug)]
pub struct Evaluation {
    pub rows: Vec<Row>,
    pub gap: f64,
}

#[derive(Clone, Debug)]
pub struct Step {
    pub effect: String,
    pub params: toml::Table,
    pub gap_before: f64,
    pub gap_after: f64,
    pub evidence: String,
    /// The comparison that named the effect (before) and the one after adding it.
    pub before: Evaluation,
    pub after: Evaluation,
}

#[derive(Clone, Debug)]
pub struct Diagnosis {
    pub threshold: f64,
    pub replicates: usize,
    pub base: String,
    pub initial: Evaluation,
    pub steps: Vec<Step>,
    pub last: Evaluation,
    pub unexplained: Vec<String>,
    /// Effects named but not kept, and why; how scenes were grouped; what is not modelled.
    pub notes: Vec<Note>,
    /// Statistics the captures do not support, and the bursts they need.
    pub skipped: Vec<String>,
    pub profile: SensorProfile,
    pub calibration: Option<NoiseCalibration>,
    /// Measured flat summaries' radial profiles for the plot: (burst name, [(r², mean)]).
    pub radial: Vec<(String, Vec<(f64, f64)>)>,
}

/// The capture protocol of a set under `profile`'s levels and effects.
pub fn protocol(set: &CaptureSet, profile: &SensorProfile, max_pixels: usize) -> Result<Protocol> {
    let plan = Plan::from_effects(&profile.effects)?;
    Ok(Protocol {
        bursts: burst_infos(set, max_pixels),
        black: profile.levels.black_level + plan.black_offset as f64,
        white: profile.levels.white_level,
        range: profile.levels.white_level - profile.levels.black_level,
        response: plan.response,
    })
}

/// What each burst is, analysing rows of at most about `max_pixels` per burst (0: all); chart
/// bursts are always whole (their patches are located in the whole frame).
fn burst_infos(set: &CaptureSet, max_pixels: usize) -> Vec<BurstInfo> {
    set.bursts()
        .iter()
        .zip(&set.sizes)
        .map(|(b, &(w, h))| BurstInfo {
            name: b.name.clone(),
            kind: b.kind,
            iso: b.iso,
            exposure_s: b.exposure_s,
            width: w,
            height: h,
            frames: b.frames.len(),
            scene: b.scene.clone(),
            rows: if b.kind == BurstKind::Chart {
                (0..h).collect()
            } else {
                effects::summary::analysed_rows(w, h, max_pixels)
            },
        })
        .collect()
}

/// Summaries of the measured bursts (frames decoded in parallel batches, their analysed rows
/// accumulated in order), and in the same pass the noise calibration of the photon-transfer
/// bursts (`ptc_bursts`) on those rows, so no frame is decoded twice.
pub fn measure(
    set: &CaptureSet,
    infos: &[BurstInfo],
    cal_opts: &CalibrateOptions,
) -> Result<(Vec<Summary>, Result<NoiseCalibration>)> {
    let ptc = ptc_bursts(set);
    let plan = noise::calibrate::CalibrationPlan::new(&ptc.set, cal_opts);
    // The measured bursts whose sums the calibration bins too.
    let calibrated: Vec<usize> = match &plan {
        Ok(p) => p.used.iter().map(|&k| ptc.index[k]).collect(),
        Err(_) => Vec::new(),
    };
    let mut out = Vec::new();
    let mut cal = Vec::new();
    for (i, info) in infos.iter().enumerate() {
        let mut acc = Accumulator::new(info, calibrated.contains(&i));
        let n = info.frames;
        let batch = rayon::current_num_threads().max(2);
        for start in (0..n).step_by(batch) {
            let frames: Vec<Image> = (start..(start + batch).min(n))
                .into_par_iter()
                .map(|j| {
                    Ok(effects::summary::crop_rows(
                        set.read_frame(i, j)?,
                        &info.rows,
                    ))
                })
                .collect::<Result<_>>()?;
            for f in &frames {
                acc.add(f);
            }
        }
        let (summary, sums) = acc.finish(i, info);
        out.push(summary);
        if calibrated.contains(&i) {
            cal.push(sums);
        }
    }
    let calibration = plan.and_then(|p| p.finish(&ptc.set, cal_opts, cal));
    Ok((out, calibration))
}

/// The dark and flat bursts of a set (when it has any flat): the photon-transfer targets, with
/// each one's index in `set`. Scene and chart bursts with fine detail break the calibration's
/// neighbour-median binning (a pixel's neighbours no longer share its signal), which biases a.
struct PtcBursts {
    set: CaptureSet,
    index: Vec<usize>,
}

fn ptc_bursts(set: &CaptureSet) -> PtcBursts {
    let any_flat = set.bursts().iter().any(|b| b.kind == BurstKind::Flat);
    let index: Vec<usize> = (0..set.bursts().len())
        .filter(|&i| !any_flat || matches!(set.bursts()[i].kind, BurstKind::Dark | BurstKind::Flat))
        .collect();
    let mut s = set.clone();
    s.manifest.bursts = index.iter().map(|&i| set.bursts()[i].clone()).collect();
    s.sizes = index.iter().map(|&i| set.sizes[i]).collect();
    PtcBursts { set: s, index }
}

/// The paper's base model from the captures (no profile given).
pub fn base_profile(
    set: &CaptureSet,
    cal: Option<&NoiseCalibration>,
    measured: &[Summary],
) -> Result<SensorProfile> {
    let (white, black, levels_src) = match cal {
        Some(cal) => (
            cal.white_level,
            cal.black_level,
            format!(
                "white {} ({}), black {} ({})",
                cal.white_level,
                cal.white_source.describe(),
                cal.black_level,
                cal.black_source.describe()
            ),
        ),
        None => {
            let (w, b) = declared_levels(set).ok_or_else(|| {
                Error::config(
                    &set.manifest_path,
                    "no declared [sensor] white_level, black_level",
                )
            })?;
            (w, b, format!("white {w}, black {b} (declared)"))
        }
    };
    // Without a calibration (no dark or flat bursts with ≥ 2 frames) the model is noise-free
    // at every ISO of the set: only statistics of means (response, exposure ratios) compare.
    let mut noise = match cal {
        Some(cal) => cal.to_noise(white, black),
        None => {
            let mut isos: Vec<f64> = set.bursts().iter().map(|b| b.iso).collect();
            isos.sort_by(f64::total_cmp);
            isos.dedup();
            isos.into_iter()
                .map(|iso| crate::sensor::profile::NoiseAtIso {
                    iso,
                    a: [0.0; 3],
                    b: [0.0; 3],
                    a_stderr: None,
                    b_stderr: None,
                })
                .collect()
        }
    };
    for n in &mut noise {
        let a = n.a.iter().sum::<f64>() / 3.0;
        let b = n.b.iter().sum::<f64>() / 3.0;
        n.a = [a; 3];
        n.b = [b; 3];
        n.a_stderr = None;
        n.b_stderr = None;
    }
    let name = set
        .manifest
        .sensor
        .name
        .clone()
        .unwrap_or_else(|| "diagnosed sensor".into());
    let mut p = SensorProfile::from_noise(
        &name,
        Levels {
            black_level: black,
            white_level: white,
            bit_depth: noise::bits_for_white(white),
        },
        &format!("{levels_src}, from {}", set.manifest_path.display()),
        noise,
        &if cal.is_some() {
            format!(
                "hdrsynth diagnose base model: one (a, b) per ISO shared by the channels \
                 (temporal photon transfer of the dark and flat bursts of {})",
                set.manifest_path.display()
            )
        } else {
            format!(
                "none: {} has no dark or flat bursts with ≥ 2 frames (noise-free model)",
                set.manifest_path.display()
            )
        },
    );
    refit_noise(&mut p, measured)?;
    if let Some(chart) = measured.iter().find(|s| s.kind == BurstKind::Chart) {
        let img = Image::from_vec(
            chart.width,
            chart.height,
            chart.mean.iter().map(|&v| (v - black) as f32).collect(),
        );
        let raw = crate::sensor::captures::chart_patch_means(&img);
        // No synthetic capture here: the burst is fitted to the reference chart itself. A
        // refused white balance reads as `neutral_gains` words it (it names white balance).
        let fit = fit_chart(&raw, &reference_linear_srgb(), WhiteBalance::Neutral, false).map_err(
            |e| match e {
                ChartFitError::WhiteBalance(e) | ChartFitError::Fit(e) => e,
                e => Error::Invalid(e.to_string()),
            },
        )?;
        p.colour = Some(Colour {
            matrix: fit.t(),
            root_polynomial: None,
            use_root_polynomial: false,
        });
        p.provenance.colour = format!(
            "T fitted by hdrsynth diagnose on chart burst '{}' of {} (neutral white balance)",
            set.bursts()[chart.burst].name,
            set.manifest_path.display()
        );
    }
    Ok(p)
}

/// Refit the model's shared (a, b) per ISO from the measured summaries' temporal photon
/// transfer (`summary::temporal_ptc`) under the model's effects: signals above the dark mean
/// (a pedestal cannot bias a or b), the row-offset variance the model draws separately taken
/// out of b, channel-noise scales divided out (so shared × scale is each channel's fit). ISOs
/// without a flat keep their a; ISOs without dark or flat keep both. Used for the base model
/// and after every step (never on a given profile, whose noise is the user's).
pub fn refit_noise(profile: &mut SensorProfile, measured: &[Summary]) -> Result<()> {
    let plan = Plan::from_effects(&profile.effects)?;
    let range = profile.levels.white_level - profile.levels.black_level;
    let black = profile.levels.black_level + plan.black_offset as f64;
    let ptc = effects::summary::temporal_ptc(measured, black, (plan.row_sigma as f64).powi(2));
    for n in &mut profile.noise {
        let Some(f) = ptc
            .iter()
            .find(|f| (f.iso - n.iso).abs() <= 1e-9 * n.iso.abs())
        else {
            continue;
        };
        let b = (0..3).map(|c| f.b[c] / plan.b_scale[c] as f64).sum::<f64>() / 3.0;
        n.b = [b / (range * range); 3];
        if let Some(a) = f.a {
            let a = (0..3).map(|c| a[c] / plan.a_scale[c] as f64).sum::<f64>() / 3.0;
            n.a = [a / range; 3];
        }
        n.a_stderr = None;
        n.b_stderr = None;
    }
    Ok(())
}

/// The capture set's declared (white, black) levels, when both are declared.
fn declared_levels(set: &CaptureSet) -> Option<(f64, f64)> {
    let s = &set.manifest.sensor;
    Some((s.white_level?, s.black_level?))
}

/// Bonferroni threshold on |z| for m statistics.
pub fn threshold(m: usize, alpha: f64) -> f64 {
    crate::stats::normal_quantile(1.0 - alpha / (2.0 * m.max(1) as f64)).max(3.0)
}

/// Run the workflow. `profile`: the starting model (None: fit the base model from the
/// captures). Stages: measure, base model, gap steps, diagnosis.
pub fn diagnose(
    set: &CaptureSet,
    profile: Option<SensorProfile>,
    opts: &DiagnoseOptions,
) -> Result<Diagnosis> {
    if opts.replicates < 2 {
        return Err(Error::flag(
            "--replicates",
            format!(
                "{}: at least 2 bootstrap replicates are needed",
                opts.replicates
            ),
        ));
    }
    let m = Measurement::take(set, profile.as_ref(), opts)?;
    let mut notes = m.banded_note(set, opts).into_iter().collect::<Vec<_>>();
    let fitted_base = profile.is_none();
    let (model, base) = base_model(set, profile, &m, &mut notes)?;
    let proto0 = protocol(set, &model, opts.max_pixels)?;
    let measured_stats = statistics(&proto0, &m.summaries);
    let ctx = Context {
        set,
        measured: &m.summaries,
        opts,
        threshold: threshold(measured_stats.len(), opts.alpha),
    };
    let initial = evaluate(&ctx, &model)?;
    let skipped = untested(&measured_stats);
    notes.extend(grouped_by_size(set, &m.summaries));
    let mut search = Search {
        model,
        current: initial.clone(),
        steps: Vec::new(),
        tried: Vec::new(),
        fitted_base,
    };
    while search.current.gap > ctx.threshold {
        match search.step(&ctx)? {
            StepOutcome::Done => break,
            StepOutcome::Kept => {}
            StepOutcome::Noted(n) => notes.push(n),
        }
    }
    let Search {
        mut model,
        current,
        steps,
        ..
    } = search;
    let unexplained = current
        .rows
        .iter()
        .filter(|r| r.significant)
        .map(evidence)
        .collect();
    notes.extend(tone_curve_notes(&current));
    if !steps.is_empty() {
        add_provenance(&mut model, &steps, set);
    }
    let radial = m
        .summaries
        .iter()
        .filter(|s| s.kind == BurstKind::Flat)
        .map(|s| {
            (
                set.bursts()[s.burst].name.clone(),
                radial_profile(s, &proto0),
            )
        })
        .collect();
    Ok(Diagnosis {
        threshold: ctx.threshold,
        replicates: opts.replicates,
        base,
        initial,
        steps,
        last: current,
        unexplained,
        notes,
        skipped,
        profile: model,
        calibration: m.calibration.ok(),
        radial,
    })
}

/// The measure stage: the measured bursts' summaries and, from the same pass, the noise
/// calibration of the photon-transfer bursts.
struct Measurement {
    summaries: Vec<Summary>,
    calibration: Result<NoiseCalibration>,
}

impl Measurement {
    fn take(
        set: &CaptureSet,
        profile: Option<&SensorProfile>,
        opts: &DiagnoseOptions,
    ) -> Result<Self> {
        // Levels for the per-channel calibration: the profile's when given.
        let cal_opts = CalibrateOptions {
            white_level: profile.map(|p| p.levels.white_level),
            black_level: profile.map(|p| p.levels.black_level),
        };
        let (summaries, calibration) = measure(set, &burst_infos(set, opts.max_pixels), &cal_opts)?;
        // The base model takes its levels from the calibration or, for a set without darks and
        // flats (e.g. scene pairs), the declared ones.
        if let (None, Err(e), None) = (profile, &calibration, declared_levels(set)) {
            return Err(Error::config(
                &set.manifest_path,
                format!(
                    "the base model needs a noise calibration of the captures ({e}), or, for a \
                     set without dark and flat bursts, declared [sensor] white_level and \
                     black_level (or --profile)"
                ),
            ));
        }
        Ok(Measurement {
            summaries,
            calibration,
        })
    }

    /// The note on bursts analysed on bands of rows, if any was.
    fn banded_note(&self, set: &CaptureSet, opts: &DiagnoseOptions) -> Option<Note> {
        let bursts: Vec<String> = self
            .summaries
            .iter()
            .filter(|m| m.height < m.full_height)
            .map(|m| {
                format!(
                    "'{}' {} of {}",
                    set.bursts()[m.burst].name,
                    m.height,
                    m.full_height
                )
            })
            .collect();
        (!bursts.is_empty()).then_some(Note::Banded {
            max_pixels: opts.max_pixels,
            bursts,
        })
    }
}

/// The base-model stage: the given profile, or the paper's base model fitted from the
/// captures (noise-free without a calibration, noted); with the report's words for it.
fn base_model(
    set: &CaptureSet,
    profile: Option<SensorProfile>,
    m: &Measurement,
    notes: &mut Vec<Note>,
) -> Result<(SensorProfile, String)> {
    Ok(match profile {
        Some(p) => {
            let name = p.name.clone();
            (p, format!("the given profile '{name}'"))
        }
        None => match &m.calibration {
            Ok(cal) => (
                base_profile(set, Some(cal), &m.summaries)?,
                "the paper's base model fitted from the captures (T from the chart, one (a, b) \
                 per ISO shared by the channels from the temporal photon transfer, declared \
                 levels)"
                    .to_string(),
            ),
            Err(e) => {
                notes.push(Note::NoCalibration(e.to_string()));
                (
                    base_profile(set, None, &m.summaries)?,
                    "the paper's base model without noise (declared levels, T from the chart if \
                     any)"
                        .to_string(),
                )
            }
        },
    })
}

/// The catalogue effects (and the base-model check) these captures cannot test, and why.
fn untested(measured_stats: &[Stat]) -> Vec<String> {
    let mut skipped: Vec<String> = effects::CATALOGUE
        .iter()
        .filter(|e| !measured_stats.iter().any(|s| s.effect == Some(e.id)))
        .map(|e| format!("{}: not tested, needs {}", e.id, e.needs))
        .collect();
    if !measured_stats.iter().any(|s| s.effect.is_none()) {
        skipped.push(
            "mean temporal variance (base-model check): not tested, needs a dark or flat burst \
             with ≥ 2 frames"
                .into(),
        );
    }
    skipped
}

/// The note on scene bursts grouped by frame size for want of `scene` keys, if any were.
fn grouped_by_size(set: &CaptureSet, measured: &[Summary]) -> Option<Note> {
    let groups: Vec<String> = effects::nonlinear_response::scene_groups(measured)
        .iter()
        .filter(|g| g[0].scene.is_none())
        .map(|g| {
            g.iter()
                .map(|b| set.bursts()[b.burst].name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        })
        .collect();
    (!groups.is_empty()).then_some(Note::GroupedBySize(groups))
}

/// The gap-step stage's state: the model so far, its comparison, the steps kept and the
/// effects tried.
struct Search {
    model: SensorProfile,
    current: Evaluation,
    steps: Vec<Step>,
    tried: Vec<&'static str>,
    /// The base noise was fitted from the captures (refit it after each step).
    fitted_base: bool,
}

/// What one gap step did.
enum StepOutcome {
    /// No untried effect explains a significant statistic.
    Done,
    /// The effect was added and the model and comparison moved on.
    Kept,
    /// The effect was not added, and why.
    Noted(Note),
}

impl Search {
    /// Name the effect of the statistic with the largest significant |z| not yet tried or in
    /// the model, fit it, and keep it when the gap shrinks.
    fn step(&mut self, ctx: &Context) -> Result<StepOutcome> {
        let in_model: Vec<String> = self.model.effects.iter().map(|e| e.id.clone()).collect();
        let mut cands: Vec<&Row> = self
            .current
            .rows
            .iter()
            .filter(|r| r.significant)
            .filter(|r| {
                r.stat
                    .effect
                    .is_some_and(|e| !self.tried.contains(&e) && !in_model.iter().any(|m| m == e))
            })
            .collect();
        cands.sort_by(|a, b| b.z.abs().total_cmp(&a.z.abs()));
        let Some(top) = cands.first().map(|r| (*r).clone()) else {
            return Ok(StepOutcome::Done);
        };
        let id = top.stat.effect.expect("filtered");
        self.tried.push(id);
        let entry = effects::entry(id).expect("catalogue id");
        let proto = protocol(ctx.set, &self.model, ctx.opts.max_pixels)?;
        let params = match self.fit(ctx, &proto, entry) {
            Ok(p) => p,
            Err(e) => {
                return Ok(StepOutcome::Noted(Note::NotFitted {
                    effect: id.to_string(),
                    key: top.stat.key.clone(),
                    why: effects::why_not_fitted(id, e),
                }));
            }
        };
        let mut next = self.model.clone();
        next.effects.push(EffectSpec {
            id: id.to_string(),
            params: params.clone(),
        });
        if self.fitted_base {
            // The base noise was fitted from the captures: refit it under the new model
            // (corrected black, row variance drawn separately, channel scales).
            refit_noise(&mut next, ctx.measured)?;
        } else if let Some(adjust) = entry.adjust {
            adjust(&mut next, &params);
        }
        if let Err(m) = next.validate() {
            return Ok(StepOutcome::Noted(Note::Rejected {
                effect: id.to_string(),
                why: m.to_string(),
            }));
        }
        let after = evaluate(ctx, &next)?;
        let ev = evidence(&top);
        if after.gap >= self.current.gap {
            return Ok(StepOutcome::Noted(Note::NotKept {
                effect: id.to_string(),
                evidence: ev,
                gap_before: self.current.gap,
                gap_after: after.gap,
            }));
        }
        let before = std::mem::replace(&mut self.current, after.clone());
        self.steps.push(Step {
            effect: id.to_string(),
            params,
            gap_before: before.gap,
            gap_after: after.gap,
            evidence: ev,
            before,
            after,
        });
        self.model = next;
        Ok(StepOutcome::Kept)
    }

    /// The named effect's parameters fitted under the current model (the error says why not).
    fn fit(&self, ctx: &Context, proto: &Protocol, entry: &effects::Entry) -> Result<toml::Table> {
        let meas: Vec<Stat> = self.current.rows.iter().map(|r| r.stat.clone()).collect();
        let sim_mean: Vec<f64> = self.current.rows.iter().map(|r| r.sim_mean).collect();
        let fctx = FitCtx {
            measured: &meas,
            simulated_mean: &sim_mean,
            summaries: ctx.measured,
            protocol: proto,
            profile: &self.model,
            seed: hash(ctx.opts.seed, &[self.steps.len() as u64, 0xf17]),
        };
        (entry.fit)(&fctx)
    }
}

/// Exposure pairs that do not scale with exposure, left unexplained: what it means.
fn tone_curve_notes(current: &Evaluation) -> Vec<Note> {
    current
        .rows
        .iter()
        .filter(|r| r.significant && r.stat.effect == Some(effects::nonlinear_response::ID))
        .map(|r| Note::ToneCurve {
            key: r.stat.key.clone(),
            measured: r.stat.value,
            simulated: r.sim_mean,
        })
        .collect()
}

/// The effects added, in the profile's provenance notes.
fn add_provenance(model: &mut SensorProfile, steps: &[Step], set: &CaptureSet) {
    let ids: Vec<&str> = steps.iter().map(|s| s.effect.as_str()).collect();
    let note = format!(
        "effects {} added by hdrsynth diagnose of {}",
        ids.join(", "),
        set.manifest_path.display()
    );
    model.provenance.notes = Some(match model.provenance.notes.take() {
        Some(n) if !n.is_empty() => format!("{n}; {note}"),
        _ => note,
    });
}

/// `hdrsynth diagnose CAPTURES [--profile P] --out DIR`: load the capture set (a folder with
/// captures.toml, or the manifest) and the starting profile, run the workflow and write its
/// files to `out` under the output lock.
pub fn diagnose_folder(
    captures: &Path,
    profile: Option<&Path>,
    opts: &DiagnoseOptions,
    out: &Path,
) -> Result<Diagnosis> {
    // One writer per output, refused before the (long) analysis rather than after it.
    let _lock = crate::io::guard::OutputLock::acquire(out, "diagnose")?;
    let set = CaptureSet::load(captures)?;
    let profile = profile.map(SensorProfile::load).transpose()?;
    let d = diagnose(&set, profile, opts)
        .map_err(|e| Error::context(format!("diagnosing {}", captures.display()), e))?;
    d.write(out)
        .map_err(|e| Error::context(format!("writing the diagnosis to {}", out.display()), e))?;
    Ok(d)
}

impl Diagnosis {
    pub fn initial_gap(&self) -> f64 {
        self.initial.gap
    }

    pub fn final_gap(&self) -> f64 {
        self.last.gap
    }
}
