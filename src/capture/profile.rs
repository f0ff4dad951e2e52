//! `hdrsynth calibrate brackets DIR --out PROFILE`: a device profile from what a user has — a
//! folder of bracketed JPEG/PNG/TIFF frames of the device — in the device's **output** domain,
//! the frames a network sees after the device's processing (docs/your_device.md):
//! - the response: the linearisation of `testset --brackets` (Debevec by default, or a
//!   declared curve) as one curve ([`testset::table_response`] for an estimate);
//! - the noise per ISO (EXIF ISO of the frames): per frame and channel, on flat pixels, the
//!   robust (MAD) σ of Immerkær's noise-estimation residual (mask [1 −2 1; −2 4 −2; 1 −2 1],
//!   Σ mask² = 36, so σ² = σ²_residual / 36 for white noise), per code bin; less the 8-bit
//!   rounding the simulation adds back (1/12 code²); carried to the linear domain through the
//!   profile's own response as the simulation would carry it back (the linear variance v
//!   whose Var R(x + √v·z) over the bin's pixels is the measured code variance), so
//!   simulating with the profile puts the measured σ back at each code; then σ² = a·x + b by
//!   weighted least squares. Where sets
//!   hold repeated captures (`ScanOptions::repeats`), the same statistics are taken on the
//!   difference of each pair of captures of one exposure, /√2, binned by their mean code:
//!   temporal noise, with no scene texture in the residual (module `noise`);
//! - the spatial correlation of that noise: per bin the ratio of the variance of a low-order
//!   residual (pixel − 3×3 mean, 8/9 σ² for white noise) to Immerkær's, 1 for white noise and
//!   above 1 where the device's processing (denoising, demosaicking, compression) correlates
//!   it; fitted as the catalogue's `correlated_noise` (an isotropic Gaussian kernel whose
//!   ratio is the measured one, [`CorrelationFit`]) and, with `correlated`, written into the
//!   profile with a and b raised to the per-pixel variance ([`with_correlation`]);
//! - the exposure rule: the auto-exposed frame of each set (EXIF ExposureBiasValue 0, else the
//!   middle frame) gives where the device put its log-average luminance (fraction of white)
//!   and how much it let clip; where EXIF marks it, the rule is written into the profile's
//!   `[metering]` (and a rule measured before is removed where it marks none).
//!
//! Levels are 16-bit 0 … 65535 (the processed frames carry no raw levels; 16 bits add no
//! visible quantisation); colour is identity unless the profile already has one (the frames
//! are already rendered; `calibrate colour` or `calibrate dng` measure T).

use crate::capture::linearise::{linearise, resolve_linearisation};
use crate::capture::testset::{self};

use crate::capture::linearise::{Linearise, ResponseChoice};
use crate::capture::scan::{self, BracketFrame, FrameKind, ScanOptions};
use crate::error::{Error, Result};
use crate::sensor::effects::plan;
pub use crate::sensor::metering::{MeteredFrame, metering_rule};
use crate::sensor::profile::{Colour, Levels, Provenance, SensorProfile};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::noise::{self, NoiseBin, ROUNDING};

#[derive(Clone, Debug)]
pub struct BracketProfileOptions {
    pub scan: ScanOptions,
    /// How codes become linear (Debevec from the brackets unless declared).
    pub response: ResponseChoice,
    /// The profile to write (an existing one keeps its name, kind, colour and effects).
    pub out: PathBuf,
    pub name: Option<String>,
    /// Write the measured spatial correlation ([`with_correlation`]) and the channels'
    /// correlation ([`with_channel_correlation`]) into the profile where each reaches
    /// [`MIN_RHO`]; otherwise the profile's noise is white and independent per channel.
    pub correlated: bool,
}

/// Smallest lag-1 correlation written as an effect: `diagnose`'s minimum effect size for noise
/// correlations (docs/diagnose.md).
pub const MIN_RHO: f64 = 0.02;

/// The output noise's spatial correlation as the catalogue's `correlated_noise`: normal draws
/// filtered by a separable Gaussian kernel of width `width` (effects::plan::kernel), whose
/// low-order/Immerkær ratio equals the measured one.
#[derive(Clone, Debug, PartialEq)]
pub struct CorrelationFit {
    /// Per channel, the median over bins of the ratio with 8-bit rounding (white, in both
    /// residuals) taken out.
    pub ratio: [f64; 3],
    /// The kernel width whose ratio is the channels' mean, and its lag-1 correlation.
    pub width: f64,
    pub rho: f64,
    /// Immerkær's σ² as a fraction of the per-pixel variance under that kernel (1 for white
    /// noise): the measured a, b are divided by it to give the per-pixel variance.
    pub immerkaer_fraction: f64,
}

/// Σᵢⱼ hᵢ hⱼ c(i − j) of a 3-tap filter `h` on a field whose lag correlations are `c`.
fn filtered_variance(h: [f64; 3], c: [f64; 3]) -> f64 {
    let mut v = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            v += h[i] * h[j] * c[i.abs_diff(j)];
        }
    }
    v
}

/// (low-order/Immerkær ratio, Immerkær fraction) of unit-variance noise filtered by the kernel
/// of width `s`. Both residuals are separable: Immerkær's mask is m mᵀ, m = (1, −2, 1), so its
/// variance is (Σ m m c)²; the low-order residual is δ − b bᵀ/9, b = (1, 1, 1).
pub fn correlation_of_width(s: f64) -> (f64, f64) {
    let k = plan::kernel(s);
    let lag = |d| plan::lag_correlation(&k, d);
    let c = [1.0, lag(1), lag(2)];
    let imm = filtered_variance([1.0, -2.0, 1.0], c).powi(2) / 36.0;
    let box3 = filtered_variance([1.0, 1.0, 1.0], c);
    let low = (1.0 - 2.0 / 9.0 * (c[0] + 2.0 * c[1]).powi(2) + box3 * box3 / 81.0) / (8.0 / 9.0);
    (low / imm, imm)
}

/// `profile` with the channels' noise correlated by `rho` (`channel_correlation`, replacing one
/// it had); `None` below [`MIN_RHO`].
pub fn with_channel_correlation(profile: &SensorProfile, rho: f64) -> Option<SensorProfile> {
    if rho.is_nan() || rho < MIN_RHO {
        return None;
    }
    let mut p = profile.clone();
    set_rho(&mut p, plan::id::CHANNEL_CORRELATION, rho);
    let _ = write!(
        p.provenance.noise,
        "; the channels' noise correlated by {rho:.3} as measured (Immerkær residuals of \
         flat pixels, 8-bit rounding removed)"
    );
    Some(p)
}

/// Effect `id` with parameter `rho` in `p`, replacing one it had.
fn set_rho(p: &mut SensorProfile, id: &str, rho: f64) {
    p.effects.retain(|e| e.id != id);
    p.effects.push(plan::EffectSpec {
        id: id.into(),
        params: toml::Table::from_iter([("rho".to_string(), rho.into())]),
    });
}

/// Fit [`CorrelationFit`] to the bins: the width by bisection (the ratio grows with it).
fn fit_correlation(bins: &[NoiseBin]) -> CorrelationFit {
    let ratio = [0, 1, 2].map(|c| {
        let mut r: Vec<f64> = bins
            .iter()
            .filter(|b| b.channel == c && b.var_code > 0.0 && b.correlation_ratio.is_finite())
            .map(|b| (b.correlation_ratio * (b.var_code + ROUNDING) - ROUNDING) / b.var_code)
            .collect();
        crate::stats::median(&mut r)
    });
    let finite: Vec<f64> = ratio.iter().copied().filter(|r| r.is_finite()).collect();
    let target = finite.iter().sum::<f64>() / finite.len().max(1) as f64;
    let top = plan::width(plan::RHO_MAX);
    let width = if target.is_nan() || target <= 1.0 {
        0.0
    } else if correlation_of_width(top).0 <= target {
        top
    } else {
        crate::stats::bisect(0.0, top, 60, |s| correlation_of_width(s).0 < target)
    };
    let k = plan::kernel(width);
    CorrelationFit {
        ratio,
        width,
        rho: plan::lag_correlation(&k, 1),
        immerkaer_fraction: correlation_of_width(width).1,
    }
}

/// `profile` with the fitted correlation: the `correlated_noise` effect (lag-1 correlation
/// `fit.rho` on both axes, replacing one it had) and every noise row of `isos` divided by the
/// Immerkær fraction, so the per-pixel variance is what the correlated field has. `None`
/// below [`MIN_RHO`].
pub fn with_correlation(
    profile: &SensorProfile,
    fit: &CorrelationFit,
    isos: &[f64],
) -> Option<SensorProfile> {
    if fit.rho.is_nan() || fit.rho < MIN_RHO {
        return None;
    }
    let mut p = profile.clone();
    for row in p.noise.iter_mut().filter(|r| isos.contains(&r.iso)) {
        for c in 0..3 {
            row.a[c] /= fit.immerkaer_fraction;
            row.b[c] /= fit.immerkaer_fraction;
        }
    }
    set_rho(&mut p, plan::id::CORRELATED_NOISE, fit.rho);
    let _ = write!(
        p.provenance.noise,
        "; spatially correlated as measured (low-order/Immerkær ratio {:.3} {:.3} {:.3} → \
         Gaussian kernel width {:.3}, lag-1 correlation {:.3}; a, b divided by {:.4}, the \
         fraction of the per-pixel variance Immerkær's residual sees)",
        fit.ratio[0], fit.ratio[1], fit.ratio[2], fit.width, fit.rho, fit.immerkaer_fraction
    );
    Some(p)
}

#[derive(Clone, Debug)]
pub struct BracketCalibration {
    pub profile: SensorProfile,
    pub existed: bool,
    pub bins: Vec<NoiseBin>,
    /// Per channel, the median over bins of [`NoiseBin::correlation_ratio`].
    pub correlation_ratio: [f64; 3],
    pub correlation: CorrelationFit,
    /// The correlation of the channels' noise ([`noise::channel_correlation_of`]).
    pub channel_correlation: f64,
    /// Repeated-capture pairs the noise was measured on (0: each frame's flat regions).
    pub repeated_pairs: usize,
    /// Frames whose noise correlations were read from their residual against the other
    /// frames of their set (0: from the pairs, or each frame's flat regions).
    pub cross_frames: usize,
    pub metering: Vec<MeteredFrame>,
    pub notes: Vec<String>,
}

/// The sources of every frame of `sets`, refusing a DNG (linear raw, not the device's output)
/// and a set whose frames (the pixels read) differ in size, naming the frame and the set's
/// first.
fn one_size_sources(sets: &[scan::BracketSet]) -> Result<Vec<crate::io::source::Source>> {
    if let Some(f) = sets
        .iter()
        .flat_map(|s| s.all_frames())
        .find(|f| f.kind == FrameKind::Dng)
    {
        return Err(Error::layout(
            &f.path,
            "a DNG is linear raw, not the device's output; `hdrsynth calibrate dng` reads its \
             tags",
        ));
    }
    let mut all = Vec::new();
    for set in sets {
        let frames: Vec<&BracketFrame> = set.all_frames().collect();
        let size = |p: [usize; 4]| (p[2] - p[0], p[3] - p[1]);
        let start = all.len();
        for f in &frames {
            all.push((f.path.clone(), scan::frame_source(f)?));
        }
        let Some((p0, s0)) = all.get(start) else {
            continue;
        };
        let (w, h) = size(s0.pixels);
        if let Some((p, s)) = all[start..].iter().find(|(_, s)| size(s.pixels) != (w, h)) {
            return Err(scan::size_mismatch(p, size(s.pixels), p0, (w, h)));
        }
    }
    Ok(all.into_iter().map(|(_, s)| s).collect())
}

/// Calibrate a profile from the bracket folder `dir` and write it to `opts.out`.
pub fn calibrate_brackets(dir: &Path, opts: &BracketProfileOptions) -> Result<BracketCalibration> {
    // The profile is an output: never written into the folder it is measured from.
    crate::io::guard::refuse_output_inside(dir, &opts.out)?;
    calibrate_scanned(dir, scan::scan(dir, &opts.scan)?, opts)
}

/// [`calibrate_brackets`] on the sets of `dir` already scanned with `opts.scan` (a run that
/// reads the folder once: [`scan::FolderScan`]).
pub fn calibrate_scanned(
    dir: &Path,
    scan: scan::BracketScan,
    opts: &BracketProfileOptions,
) -> Result<BracketCalibration> {
    crate::io::guard::refuse_output_inside(dir, &opts.out)?;
    let mut notes = scan.notes;
    // Read first: a DNG, or a set whose frames differ in size, is refused before any
    // measurement.
    let sources = one_size_sources(&scan.sets)?;
    let lin = resolve_linearisation(&scan.sets, &opts.response, None, &mut notes)?;
    let response = match &lin {
        Linearise::Curve(r) => r.clone(),
        Linearise::Table(t) => testset::table_response(t),
    };
    let noise::Measured {
        bins,
        rows,
        channel_correlation,
        pairs,
        cross_frames,
    } = noise::measure_noise(&scan.sets, &response, &mut notes)?;
    let metering = scan
        .sets
        .iter()
        .map(|s| metered(s, &lin))
        .collect::<Result<Vec<_>>>()?;
    let (mut profile, existed) = SensorProfile::load_or_create(&opts.out, || {
        Ok::<_, Error>(SensorProfile::new_measured(
            opts.name
                .clone()
                .unwrap_or_else(|| format!("device of {}", dir.display())),
            Levels {
                black_level: 0.0,
                white_level: 65535.0,
                bit_depth: 16,
            },
            response.clone(),
            Provenance {
                colour: "identity: not measured from brackets (the frames are already \
                         rendered; `hdrsynth calibrate colour` or `calibrate dng` measure T)"
                    .into(),
                noise: String::new(),
                levels: "output domain: 16-bit 0 … 65535 (processed frames carry no raw \
                         levels; 16 bits add no visible quantisation)"
                    .into(),
                response: String::new(),
                metering: None,
                notes: None,
            },
        ))
    })?;
    if profile.colour.is_none() {
        profile.colour = Some(Colour {
            matrix: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            root_polynomial: None,
            use_root_polynomial: false,
        });
    }
    profile.response = response;
    profile.provenance.response = format!(
        "{} of bracket folder {} (`hdrsynth calibrate brackets`)",
        opts.response.describe(),
        dir.display()
    );
    for row in rows {
        profile.noise.retain(|r| r.iso != row.iso);
        profile.noise.push(row);
    }
    profile.noise.sort_by(|a, b| a.iso.total_cmp(&b.iso));
    profile.provenance.noise = noise_provenance(dir, pairs);
    // These frames' rule or none: a rule measured on other captures is not kept beside them.
    notes.extend(profile.record_measured_rule(dir, &metering));
    let correlation = fit_correlation(&bins);
    if opts.correlated {
        let isos: Vec<f64> = bins.iter().map(|b| b.iso).collect();
        if let Some(p) = with_correlation(&profile, &correlation, &isos) {
            profile = p;
        }
        if let Some(p) = with_channel_correlation(&profile, channel_correlation) {
            profile = p;
        }
    }
    for source in sources {
        if !profile.calibrated_on.contains(&source) {
            profile.calibrated_on.push(source);
        }
    }
    profile
        .validate()
        .map_err(|msg| Error::config(&opts.out, msg))?;
    profile.save(&opts.out)?;
    let correlation_ratio = [0, 1, 2].map(|c| {
        let mut r: Vec<f64> = bins
            .iter()
            .filter(|b| b.channel == c && b.correlation_ratio.is_finite())
            .map(|b| b.correlation_ratio)
            .collect();
        crate::stats::median(&mut r)
    });
    Ok(BracketCalibration {
        profile,
        existed,
        bins,
        correlation_ratio,
        correlation,
        channel_correlation,
        repeated_pairs: pairs,
        cross_frames,
        metering,
        notes,
    })
}

/// How the noise of bracket folder `dir` was measured (`pairs` repeated-capture pairs).
fn noise_provenance(dir: &Path, pairs: usize) -> String {
    let residual = if pairs > 0 {
        format!(
            "temporal noise: MAD σ of Immerkær's residual of the differences of {pairs} \
             repeated-capture pair(s), /√2, over each code bin's pixels"
        )
    } else {
        "MAD σ of Immerkær's residual on the flattest half of each code bin's pixels".into()
    };
    format!(
        "output-domain noise of bracket folder {} (`hdrsynth calibrate brackets`): {residual}, \
         8-bit rounding removed, carried to linear through the profile's response, \
         σ² = a·x + b by WLS",
        dir.display()
    )
}

/// The auto-exposed frame of `set` and where it put its signal.
fn metered(set: &scan::BracketSet, lin: &Linearise) -> Result<MeteredFrame> {
    // An auto-exposure bracket marks its metered frame by bias 0 and the others by their
    // offsets; frames that all record 0 (manual exposures) mark nothing.
    let zero: Vec<&BracketFrame> = set
        .frames
        .iter()
        .filter(|f| f.exif.bias_ev == Some(0.0))
        .collect();
    let marked = zero.len() == 1 && set.frames.iter().all(|f| f.exif.bias_ev.is_some());
    let (frame, how) = if marked {
        (zero[0], "the one frame with EXIF ExposureBiasValue 0")
    } else {
        (
            &set.frames[set.frames.len() / 2],
            "the middle frame (ExposureBiasValue marks no single frame)",
        )
    };
    let code = scan::read_frame_image(frame)?;
    testset::refuse_sceneless(set, frame, testset::clipped_or_dark(&code))?;
    let clipped = code
        .data
        .chunks_exact(3)
        .filter(|p| p.iter().any(|&v| f64::from(v) >= noise::HIGH_CODE))
        .count() as f64
        / code.pixel_count().max(1) as f64;
    let lum = linearise(frame, code, lin).luminance();
    let log_mean = lum
        .iter()
        .map(|&l| (f64::from(l).max(1e-6)).ln())
        .sum::<f64>()
        / lum.len().max(1) as f64;
    Ok(MeteredFrame {
        frame: frame.path.clone(),
        how: how.into(),
        log_average: log_mean.exp(),
        clipped,
        auto_exposed: marked,
    })
}

impl BracketCalibration {
    /// Whether the measured correlation `value` of effect `id` is in the profile, and why not.
    fn written(&self, id: &str, value: f64, otherwise: &str) -> String {
        if self.profile.effects.iter().any(|e| e.id == id) {
            format!("the profile's {id}")
        } else if value >= MIN_RHO {
            "not written: --correlated writes it".into()
        } else {
            format!("below {MIN_RHO}: {otherwise}")
        }
    }

    /// The command's report.
    pub fn report(&self, out: &Path) -> String {
        let mut s = String::new();
        for n in &self.notes {
            let _ = writeln!(s, "note: {n}");
        }
        let _ = writeln!(
            s,
            "{} profile {} ('{}'): response {}",
            if self.existed { "updated" } else { "new" },
            out.display(),
            self.profile.name,
            self.profile.response.label()
        );
        let _ = writeln!(
            s,
            "output-domain noise (per ISO, channel, code bin) {}: code, linear, σ_code (8-bit \
             codes), σ²_lin, low/high-order variance ratio (1 = white noise), pixels",
            if self.repeated_pairs > 0 {
                format!(
                    "from the differences of {} repeated-capture pair(s)",
                    self.repeated_pairs
                )
            } else if self.cross_frames > 0 {
                format!(
                    "from each frame's flat regions; the ratio from the residual of {} frame(s) \
                     against the merge of the other frames of their set (no scene texture)",
                    self.cross_frames
                )
            } else {
                "from each frame's flat regions".into()
            }
        );
        for b in &self.bins {
            let _ = writeln!(
                s,
                "  ISO {:<5} {} code {:.3} linear {:.4} σ {:.3} σ²_lin {:.3e} ratio {:.2} n {}",
                b.iso,
                ["R", "G", "B"][b.channel],
                b.code,
                b.linear,
                b.var_code.max(0.0).sqrt() * 255.0,
                b.var_linear,
                b.correlation_ratio,
                b.pixels
            );
        }
        for r in &self.profile.noise {
            let e = |v: [f64; 3]| format!("[{:.3e}, {:.3e}, {:.3e}]", v[0], v[1], v[2]);
            let _ = writeln!(s, "noise ISO {}: a {} b {}", r.iso, e(r.a), e(r.b));
        }
        let r = self.correlation_ratio;
        let f = &self.correlation;
        if r.iter().chain(&f.ratio).all(|v| v.is_finite()) {
            let _ = writeln!(
                s,
                "spatial correlation: low/high-order residual variance ratio, median over \
                 bins: R {:.2}, G {:.2}, B {:.2} (1 = white noise); without 8-bit rounding \
                 {:.3}, {:.3}, {:.3} → Gaussian kernel width {:.3}, lag-1 correlation {:.3} \
                 ({})",
                r[0],
                r[1],
                r[2],
                f.ratio[0],
                f.ratio[1],
                f.ratio[2],
                f.width,
                f.rho,
                self.written(
                    plan::id::CORRELATED_NOISE,
                    f.rho,
                    "the profile's noise is white"
                )
            );
        } else {
            let _ = writeln!(
                s,
                "spatial correlation: not measured (no code bin with enough flat pixels in \
                 every channel); none written"
            );
        }
        if self.channel_correlation.is_finite() {
            let _ = writeln!(
                s,
                "channel correlation of the noise: {:.3} ({})",
                self.channel_correlation,
                self.written(
                    plan::id::CHANNEL_CORRELATION,
                    self.channel_correlation,
                    "the channels' noise is independent"
                )
            );
        } else {
            let _ = writeln!(
                s,
                "channel correlation of the noise: not measured (no flat pixels); none written"
            );
        }
        for m in &self.metering {
            let _ = writeln!(
                s,
                "metering: {} ({}): log-average luminance {:.4} of white, {:.2} % clipped \
                 (the loader's [realism.metering] mid_grey and max_clipped)",
                m.frame.display(),
                m.how,
                m.log_average,
                100.0 * m.clipped
            );
        }
        let _ = writeln!(
            s,
            "exposure rule: {}",
            self.profile.metering.map_or(
                "none: no set marks its auto-exposed frame by EXIF ExposureBiasValue".into(),
                |m| format!("{m}, written into the profile's [metering]")
            )
        );
        s
    }
}
