//! Noise calibration from a capture set: photon-transfer analysis of bursts of frames.
//!
//! Model, per ISO and channel, in DN: σ²(I) = a·I + b, I = temporal mean − black level (DN
//! above black). Outputs are converted to the profile's normalised convention (x = I / (W − B)):
//! a_norm = a / (W − B), b_norm = b / (W − B)². docs/noise.md has the method in full:
//!
//! 1. Per burst with ≥ 2 frames: per-pixel temporal mean and unbiased temporal variance (n − 1).
//! 2. Exclusions, per pixel and channel, in this order of precedence: *saturated* (any frame at
//!    or above the white level); *defective* (temporal mean more than 6 robust σ from the
//!    median of its 5×5 neighbourhood, in units of the local expected standard error of a mean);
//!    *clipped low* (any frame at 0 DN); then, within its bin, *defective* again for a temporal
//!    variance more than 6 robust σ above the bin's median variance, or a variance of exactly 0
//!    where the bin's median variance is ≥ 1 DN² (a stuck pixel).
//! 3. Bins per burst and channel on an asinh grid of the signal of the pixel's neighbours (5×5
//!    median, the pixel itself left out, so that binning does not select on the pixel's own
//!    noise): ≈ 10 % wide above s_lin = (W − B)/200 DN, 0.1·s_lin wide near 0; bins with < 32
//!    pixels are dropped. Each bin gives mean signal, mean variance (less the 1/12 DN² of
//!    integer quantisation, Sheppard's correction) and its standard error s/√n.
//! 4. All bins of all bursts of one ISO: weighted least squares of variance against signal,
//!    weights 1/SE² with SE modelled as c·ŷ/√n (c the median relative spread of per-pixel
//!    variances, ŷ the current fit; iterated from the empirical SEs), standard errors from the
//!    inverse normal matrix scaled by √max(1, χ²/(K − 2)). Dark bursts (I ≈ 0) anchor b.

use crate::error::{Error, Result};
use crate::io::Image;
use crate::sensor::captures::{BurstKind, CaptureSet};
use crate::sensor::profile::{
    Levels, NoiseAtIso, PROFILE_FORMAT, ProfileKind, Provenance, Response, SensorProfile,
};
use crate::stats::{self, median};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// Outlier threshold for defect detection, in robust standard deviations.
pub const DEFECT_SIGMAS: f64 = 6.0;
/// Half-width of the local-median window (5×5).
pub const WINDOW_RADIUS: usize = 2;
/// Bins with fewer pixels are dropped.
pub const MIN_BIN_PIXELS: usize = 32;
/// Bin width on the asinh(signal / s_lin) grid.
pub const BIN_STEP: f64 = 0.1;
/// Variance of uniform quantisation to integer DN (Sheppard's correction).
pub const QUANTISATION_VARIANCE: f64 = 1.0 / 12.0;
/// Scale from the median absolute deviation to σ for a normal distribution.
const MAD_TO_SIGMA: f64 = 1.4826;

pub const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// Overrides of the capture set's declared levels.
#[derive(Clone, Debug, Default)]
pub struct CalibrateOptions {
    /// White level in DN; overrides `[sensor].white_level`.
    pub white_level: Option<f64>,
    /// Black level in DN; overrides `[sensor].black_level` and the dark-frame estimate.
    pub black_level: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelSource {
    /// Passed by the caller (`--white-level` / `--black-level`).
    Override,
    /// The capture set's `[sensor]` table.
    Declared,
    /// Median over dark frames of each frame's outlier-clipped mean.
    EstimatedFromDark,
}

impl LevelSource {
    pub fn describe(self) -> &'static str {
        match self {
            LevelSource::Override => "given on the command line",
            LevelSource::Declared => "declared in [sensor]",
            LevelSource::EstimatedFromDark => "estimated from the dark frames",
        }
    }
}

/// One bin of pixels of one burst and channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Bin {
    /// Index of the burst in the capture set.
    pub burst: usize,
    /// Mean over the bin's pixels of (temporal mean − black), DN.
    pub signal: f64,
    /// Mean over the bin's pixels of the unbiased temporal variance, less 1/12 DN², DN².
    pub variance: f64,
    /// Standard error of `variance`: sample SD of the per-pixel variances / √pixels.
    pub stderr: f64,
    pub pixels: usize,
}

/// Per-channel pixel accounting (pixel-channel samples, summed over the bursts of an ISO).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Samples in bins that entered the fit.
    pub used: usize,
    /// Some frame at or above the white level.
    pub saturated: usize,
    /// Hot, dead, stuck or abnormally noisy (mean or variance outliers).
    pub defective: usize,
    /// Some frame at 0 DN (clipped at the bottom).
    pub clipped_low: usize,
    /// In bins with fewer than [`MIN_BIN_PIXELS`] pixels.
    pub sparse: usize,
}

impl Counts {
    fn add(&mut self, o: &Counts) {
        self.used += o.used;
        self.saturated += o.saturated;
        self.defective += o.defective;
        self.clipped_low += o.clipped_low;
        self.sparse += o.sparse;
    }
}

/// The fit of one channel at one ISO, in DN.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelFit {
    /// σ² = a·I + b, I in DN above black, σ² in DN².
    pub a: f64,
    pub b: f64,
    pub a_stderr: f64,
    pub b_stderr: f64,
    /// χ² / (K − 2) of the final weighted fit (K bins); NaN when K = 2.
    pub chi2_reduced: f64,
    pub bins: Vec<Bin>,
    pub counts: Counts,
}

#[derive(Clone, Debug, PartialEq)]
pub struct IsoFit {
    pub iso: f64,
    /// Indices of the bursts used at this ISO.
    pub bursts: Vec<usize>,
    pub channels: [ChannelFit; 3],
}

/// Per-burst accounting, for reports and tests.
#[derive(Clone, Debug, PartialEq)]
pub struct BurstSummary {
    pub burst: usize,
    pub name: String,
    pub kind: BurstKind,
    pub iso: f64,
    pub frames: usize,
    pub counts: [Counts; 3],
}

#[derive(Clone, Debug, PartialEq)]
pub struct NoiseCalibration {
    /// The capture set's directory (for provenance).
    pub source: String,
    pub white_level: f64,
    pub white_source: LevelSource,
    /// Black level used for the signal I = mean − black.
    pub black_level: f64,
    pub black_source: LevelSource,
    pub black_declared: Option<f64>,
    pub black_estimated: Option<f64>,
    /// Ascending ISO.
    pub isos: Vec<IsoFit>,
    pub bursts: Vec<BurstSummary>,
    /// Bursts left out, with the reason.
    pub skipped: Vec<String>,
}

/// Calibrate the noise model from every burst of the set with at least two frames. Dark and
/// flat bursts with fewer are an error; chart and scene bursts with fewer are skipped (they may
/// be there for colour calibration).
pub fn calibrate(set: &CaptureSet, opts: &CalibrateOptions) -> Result<NoiseCalibration> {
    let plan = CalibrationPlan::new(set, opts)?;
    let mut stats = Vec::new();
    for &i in &plan.used {
        let b = &set.bursts()[i];
        let mut acc = BurstFrames::new(b.kind == BurstKind::Dark, usize::MAX);
        for j in 0..b.frames.len() {
            acc.add(&set.read_frame(i, j)?);
        }
        stats.push(acc);
    }
    plan.finish(set, opts, stats)
}

/// What a calibration of a set will use, checked before any frame is read: the white level and
/// the bursts with ≥ 2 frames (`used`, in set order).
pub struct CalibrationPlan {
    white_level: f64,
    white_source: LevelSource,
    pub used: Vec<usize>,
    skipped: Vec<String>,
}

impl CalibrationPlan {
    pub fn new(set: &CaptureSet, opts: &CalibrateOptions) -> Result<CalibrationPlan> {
        let manifest_err = |m: String| Error::config(&set.manifest_path, m);
        let (white_level, white_source) = match (opts.white_level, set.manifest.sensor.white_level)
        {
            (Some(w), _) => (w, LevelSource::Override),
            (None, Some(w)) => (w, LevelSource::Declared),
            (None, None) => {
                return Err(manifest_err(
                    "white level unknown: declare [sensor].white_level or pass --white-level"
                        .into(),
                ));
            }
        };
        if !(white_level.is_finite() && white_level > 0.0) {
            return Err(manifest_err(format!(
                "white level {white_level} must be > 0"
            )));
        }
        let mut skipped = Vec::new();
        let mut used = Vec::new();
        for (i, b) in set.bursts().iter().enumerate() {
            if b.frames.len() >= 2 {
                used.push(i);
            } else if matches!(b.kind, BurstKind::Dark | BurstKind::Flat) {
                set.require_frames(i, 2)?;
            } else {
                skipped.push(format!(
                    "{}: {} burst with {} frame; temporal statistics need ≥ 2",
                    set.burst_label(i),
                    b.kind.as_str(),
                    b.frames.len()
                ));
            }
        }
        if used.is_empty() {
            return Err(manifest_err(
                "no burst with ≥ 2 frames: noise calibration needs dark and/or flat bursts".into(),
            ));
        }
        Ok(CalibrationPlan {
            white_level,
            white_source,
            used,
            skipped,
        })
    }

    /// The calibration from the frames of the `used` bursts (`stats[k]` of burst `used[k]`).
    pub fn finish(
        self,
        set: &CaptureSet,
        opts: &CalibrateOptions,
        stats: Vec<BurstFrames>,
    ) -> Result<NoiseCalibration> {
        let manifest_err = |m: String| Error::config(&set.manifest_path, m);
        let CalibrationPlan {
            white_level,
            white_source,
            used,
            skipped,
        } = self;
        // Black level: override > declared > dark-frame estimate (median over dark frames of
        // each frame's outlier-clipped mean).
        let mut means: Vec<f64> = stats.iter().flat_map(|s| s.frame_means.clone()).collect();
        let black_estimated = (!means.is_empty()).then(|| median(&mut means));
        let black_declared = set.manifest.sensor.black_level;
        let (black_level, black_source) = match (opts.black_level, black_declared, black_estimated)
        {
            (Some(b), _, _) => (b, LevelSource::Override),
            (None, Some(b), _) => (b, LevelSource::Declared),
            (None, None, Some(b)) => (b, LevelSource::EstimatedFromDark),
            (None, None, None) => {
                return Err(manifest_err(
                    "black level unknown: declare [sensor].black_level, pass --black-level, or \
                     include a dark burst"
                        .into(),
                ));
            }
        };
        if !(black_level.is_finite() && black_level >= 0.0 && black_level < white_level) {
            return Err(manifest_err(format!(
                "black level {black_level} must be ≥ 0 and below the white level {white_level}"
            )));
        }

        // Per-burst statistics and bins (bins of every band of a burst together).
        let s_lin = ((white_level - black_level) / 200.0).max(1.0);
        let mut per_burst = Vec::new();
        let mut summaries = Vec::new();
        for (&i, acc) in used.iter().zip(stats) {
            let frames = acc.frames;
            let mut bins: [Vec<Bin>; 3] = Default::default();
            let mut counts = [Counts::default(); 3];
            for band in acc.finish(white_level) {
                for c in 0..3 {
                    let (b, n) = channel_bins(&band, c, i, black_level, s_lin);
                    bins[c].extend(b);
                    counts[c].add(&n);
                }
            }
            let b = &set.bursts()[i];
            summaries.push(BurstSummary {
                burst: i,
                name: b.name.clone(),
                kind: b.kind,
                iso: b.iso,
                frames,
                counts,
            });
            per_burst.push((i, bins, counts));
        }

        // Group by ISO and fit.
        let mut iso_values: Vec<f64> = used.iter().map(|&i| set.bursts()[i].iso).collect();
        iso_values.sort_by(f64::total_cmp);
        iso_values.dedup();
        let mut isos = Vec::new();
        for iso in iso_values {
            let group: Vec<_> = per_burst
                .iter()
                .filter(|(i, _, _)| set.bursts()[*i].iso == iso)
                .collect();
            let bursts: Vec<usize> = group.iter().map(|(i, _, _)| *i).collect();
            let mut channels = Vec::new();
            for (c, cname) in CHANNELS.iter().enumerate() {
                let mut bins = Vec::new();
                let mut counts = Counts::default();
                for (_, b, n) in &group {
                    bins.extend(b[c].iter().cloned());
                    counts.add(&n[c]);
                }
                let fit = fit_bins(&bins).map_err(|m| {
                    manifest_err(format!(
                        "ISO {iso}, channel {cname} (bursts {}): {m}",
                        bursts
                            .iter()
                            .map(|&i| format!("'{}'", set.bursts()[i].name))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ))
                })?;
                channels.push(ChannelFit {
                    a: fit.a,
                    b: fit.b,
                    a_stderr: fit.a_se,
                    b_stderr: fit.b_se,
                    chi2_reduced: fit.chi2_reduced,
                    bins,
                    counts,
                });
            }
            let channels: [ChannelFit; 3] = channels.try_into().expect("three channels");
            isos.push(IsoFit {
                iso,
                bursts,
                channels,
            });
        }

        Ok(NoiseCalibration {
            source: set.dir.display().to_string(),
            white_level,
            white_source,
            black_level,
            black_source,
            black_declared,
            black_estimated,
            isos,
            bursts: summaries,
            skipped,
        })
    }
}

// ---------------------------------------------------------------------------------------------
// Per-burst statistics

struct BurstStats {
    width: usize,
    height: usize,
    frames: usize,
    /// Interleaved RGB, like `Image::data`.
    mean: Vec<f32>,
    var: Vec<f32>,
    min: Vec<u16>,
    max: Vec<u16>,
    white: f64,
}

/// Temporal mean and unbiased variance per pixel and channel of one burst, frame by frame (the
/// gap workflow feeds the frames it decodes anyway). Sums are exact: integer DN offsets from
/// the first frame in i32/u64. Frames may be bands of `band` rows of a larger frame stacked
/// (`summary::crop_rows`): neighbourhoods then stay inside a band.
pub struct BurstFrames {
    dark: bool,
    band: usize,
    width: usize,
    height: usize,
    frames: usize,
    k: Vec<u16>,
    s1: Vec<i32>,
    s2: Vec<u64>,
    min: Vec<u16>,
    max: Vec<u16>,
    /// Dark bursts: each frame's outlier-clipped mean (the black-level estimate).
    frame_means: Vec<f64>,
}

fn to_u16(v: f32) -> u16 {
    v.clamp(0.0, 65535.0) as u16
}

impl BurstFrames {
    pub fn new(dark: bool, band: usize) -> BurstFrames {
        BurstFrames {
            dark,
            band: band.max(1),
            width: 0,
            height: 0,
            frames: 0,
            k: Vec::new(),
            s1: Vec::new(),
            s2: Vec::new(),
            min: Vec::new(),
            max: Vec::new(),
            frame_means: Vec::new(),
        }
    }

    /// Add one frame (every frame of a burst has the burst's size: `CaptureSet::read_frame`).
    pub fn add(&mut self, f: &Image) {
        if self.dark {
            self.frame_means.push(robust_frame_mean(f));
        }
        self.frames += 1;
        if self.frames == 1 {
            self.width = f.width;
            self.height = f.height;
            self.k = f.data.iter().map(|&v| to_u16(v)).collect();
            self.s1 = vec![0; self.k.len()];
            self.s2 = vec![0; self.k.len()];
            self.min = self.k.clone();
            self.max = self.k.clone();
            return;
        }
        (self.s1.par_iter_mut(), self.s2.par_iter_mut())
            .into_par_iter()
            .zip((self.min.par_iter_mut(), self.max.par_iter_mut()))
            .zip((self.k.par_iter(), f.data.par_iter()))
            .for_each(|(((s1, s2), (lo, hi)), (&k, &v))| {
                let v = to_u16(v);
                let d = v as i32 - k as i32;
                *s1 += d;
                *s2 += (d as i64 * d as i64) as u64;
                *lo = (*lo).min(v);
                *hi = (*hi).max(v);
            });
    }

    /// Per-band statistics.
    fn finish(self, white: f64) -> Vec<BurstStats> {
        let nf = self.frames as f64;
        let (mean, var): (Vec<f32>, Vec<f32>) =
            (self.k.par_iter(), self.s1.par_iter(), self.s2.par_iter())
                .into_par_iter()
                .map(|(&k, &s1, &s2)| {
                    let s1 = s1 as f64;
                    let m = k as f64 + s1 / nf;
                    let v = ((s2 as f64 - s1 * s1 / nf) / (nf - 1.0)).max(0.0);
                    (m as f32, v as f32)
                })
                .unzip();
        let w3 = self.width * 3;
        (0..self.height)
            .step_by(self.band)
            .map(|y0| {
                let y1 = (y0 + self.band).min(self.height);
                let r = y0 * w3..y1 * w3;
                BurstStats {
                    width: self.width,
                    height: y1 - y0,
                    frames: self.frames,
                    mean: mean[r.clone()].to_vec(),
                    var: var[r.clone()].to_vec(),
                    min: self.min[r.clone()].to_vec(),
                    max: self.max[r].to_vec(),
                    white,
                }
            })
            .collect()
    }
}

const OK: u8 = 0;
const SATURATED: u8 = 1;
const DEFECTIVE: u8 = 2;
const CLIPPED_LOW: u8 = 3;

/// Exclusions and bins for one channel of one burst.
fn channel_bins(
    st: &BurstStats,
    c: usize,
    burst: usize,
    black: f64,
    s_lin: f64,
) -> (Vec<Bin>, Counts) {
    let (w, h) = (st.width, st.height);
    let np = w * h;
    let idx = |p: usize| p * 3 + c;
    let mut status: Vec<u8> = (0..np)
        .map(|p| {
            if st.max[idx(p)] as f64 >= st.white {
                SATURATED
            } else {
                OK
            }
        })
        .collect();

    // Per pixel the median temporal mean and variance of its 5×5 neighbours (the pixel itself
    // left out, so that they are independent of its own temporal noise). The neighbour median
    // is the binning variable; the mean-outlier score is z = (mean − neighbour median) /
    // √(neighbour median variance / n), robustly rescaled below.
    let nf = st.frames as f64;
    let (z, nb): (Vec<f32>, Vec<f32>) = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let status = &status;
            (0..w).map(move |x| {
                let p = y * w + x;
                if status[p] != OK {
                    return (f32::NAN, f32::NAN);
                }
                let mut means = [0f32; 25];
                let mut vars = [0f32; 25];
                let mut k = 0;
                let (x0, x1) = (
                    x.saturating_sub(WINDOW_RADIUS),
                    (x + WINDOW_RADIUS).min(w - 1),
                );
                let (y0, y1) = (
                    y.saturating_sub(WINDOW_RADIUS),
                    (y + WINDOW_RADIUS).min(h - 1),
                );
                for yy in y0..=y1 {
                    for xx in x0..=x1 {
                        let q = yy * w + xx;
                        if q != p && status[q] == OK {
                            means[k] = st.mean[idx(q)];
                            vars[k] = st.var[idx(q)];
                            k += 1;
                        }
                    }
                }
                if k == 0 {
                    return (f32::NAN, f32::NAN);
                }
                let med_mean = median(&mut means[..k]);
                let med_var = (median(&mut vars[..k]) as f64).max(QUANTISATION_VARIANCE);
                let z = (st.mean[idx(p)] as f64 - med_mean as f64) / (med_var / nf).sqrt();
                (z as f32, med_mean)
            })
        })
        .unzip();
    let mut finite: Vec<f64> = z
        .iter()
        .filter(|v| v.is_finite())
        .map(|&v| v as f64)
        .collect();
    if !finite.is_empty() {
        let med = median(&mut finite);
        let mut dev: Vec<f64> = finite.iter().map(|v| (v - med).abs()).collect();
        let sigma = (MAD_TO_SIGMA * median(&mut dev)).max(0.5);
        for (s, &z) in status.iter_mut().zip(&z) {
            if *s == OK && (z as f64 - med).abs() > DEFECT_SIGMAS * sigma {
                *s = DEFECTIVE;
            }
        }
    }
    for (p, s) in status.iter_mut().enumerate() {
        if *s == OK && st.min[idx(p)] == 0 {
            *s = CLIPPED_LOW;
        }
    }

    // Bins on the asinh grid of the neighbour-median signal; variance outliers and stuck
    // pixels within each bin.
    let mut counts = Counts::default();
    let mut groups: BTreeMap<i64, Vec<usize>> = BTreeMap::new();
    for p in 0..np {
        if status[p] == OK {
            if !nb[p].is_finite() {
                counts.sparse += 1;
                continue;
            }
            let s = nb[p] as f64 - black;
            let key = ((s / s_lin).asinh() / BIN_STEP).floor() as i64;
            groups.entry(key).or_default().push(p);
        }
    }
    let mut bins = Vec::new();
    for pixels in groups.values() {
        let mut vars: Vec<f64> = pixels.iter().map(|&p| st.var[idx(p)] as f64).collect();
        let med = median(&mut vars);
        let mut dev: Vec<f64> = vars.iter().map(|v| (v - med).abs()).collect();
        let sigma = (MAD_TO_SIGMA * median(&mut dev)).max(0.1 * med).max(0.1);
        let limit = med + DEFECT_SIGMAS * sigma;
        let keep: Vec<usize> = pixels
            .iter()
            .copied()
            .filter(|&p| {
                let v = st.var[idx(p)] as f64;
                let bad = v > limit || (v == 0.0 && med >= 1.0);
                if bad {
                    status[p] = DEFECTIVE;
                }
                !bad
            })
            .collect();
        if keep.len() < MIN_BIN_PIXELS {
            counts.sparse += keep.len();
            continue;
        }
        let n = keep.len() as f64;
        let signal = keep
            .iter()
            .map(|&p| st.mean[idx(p)] as f64 - black)
            .sum::<f64>()
            / n;
        let vmean = keep.iter().map(|&p| st.var[idx(p)] as f64).sum::<f64>() / n;
        let vsd = (keep
            .iter()
            .map(|&p| (st.var[idx(p)] as f64 - vmean).powi(2))
            .sum::<f64>()
            / (n - 1.0))
            .sqrt();
        counts.used += keep.len();
        bins.push(Bin {
            burst,
            signal,
            variance: vmean - QUANTISATION_VARIANCE,
            stderr: vsd / n.sqrt(),
            pixels: keep.len(),
        });
    }
    for &s in &status {
        match s {
            SATURATED => counts.saturated += 1,
            DEFECTIVE => counts.defective += 1,
            CLIPPED_LOW => counts.clipped_low += 1,
            _ => {}
        }
    }
    (bins, counts)
}

/// Mean of a frame's samples within 8 robust σ of its median (hot pixels and other outliers
/// left out); samples are integer DN, so median and MAD come from a histogram.
fn robust_frame_mean(img: &Image) -> f64 {
    let mut hist = vec![0u64; 65536];
    for &v in &img.data {
        hist[v.clamp(0.0, 65535.0) as usize] += 1;
    }
    let n = img.data.len() as u64;
    let quantile = |hist: &[u64], target: u64| -> usize {
        let mut acc = 0;
        for (i, &c) in hist.iter().enumerate() {
            acc += c;
            if acc > target {
                return i;
            }
        }
        hist.len() - 1
    };
    let med = quantile(&hist, n / 2);
    let mut dev = vec![0u64; 65536];
    for (i, &c) in hist.iter().enumerate() {
        dev[i.abs_diff(med)] += c;
    }
    let mad = quantile(&dev, n / 2) as f64;
    let limit = (8.0 * MAD_TO_SIGMA * mad).max(2.0);
    let (mut sum, mut cnt) = (0.0, 0u64);
    for (i, &c) in hist.iter().enumerate() {
        if (i as f64 - med as f64).abs() <= limit {
            sum += i as f64 * c as f64;
            cnt += c;
        }
    }
    sum / cnt.max(1) as f64
}

/// The straight-line WLS of variance on signal over `bins` ([`stats::wls`]), with the reasons
/// it cannot be fitted in the words of a noise calibration.
pub(crate) fn fit_bins(bins: &[Bin]) -> std::result::Result<stats::LineFit, String> {
    if bins.len() < 2 {
        return Err(format!(
            "{} usable bin(s); the fit needs ≥ 2 at different signal levels (a dark burst and \
             flat bursts at one or more levels)",
            bins.len()
        ));
    }
    let points: Vec<stats::Point> = bins
        .iter()
        .map(|b| stats::Point {
            x: b.signal,
            y: b.variance,
            se: b.stderr,
            n: b.pixels,
        })
        .collect();
    stats::wls(&points).ok_or_else(|| {
        let lo = bins.iter().map(|b| b.signal).fold(f64::INFINITY, f64::min);
        let hi = bins
            .iter()
            .map(|b| b.signal)
            .fold(f64::NEG_INFINITY, f64::max);
        format!(
            "the {} bins span signal {lo:.1}..{hi:.1} DN only; the fit needs bins at different \
             levels (a dark burst and flat bursts, or flats at ≥ 2 levels)",
            bins.len()
        )
    })
}

// ---------------------------------------------------------------------------------------------
// Conversion, report, provenance

impl NoiseCalibration {
    /// The fits in the profile's normalised convention for levels (white, black):
    /// a_norm = a / (W − B), b_norm = b / (W − B)²; standard errors likewise. Negative values
    /// (possible for b when read noise is tiny) are clamped to 0; [`Self::clamped`] lists them.
    pub fn to_noise(&self, white: f64, black: f64) -> Vec<NoiseAtIso> {
        let r = white - black;
        self.isos
            .iter()
            .map(|f| NoiseAtIso {
                iso: f.iso,
                a: std::array::from_fn(|c| (f.channels[c].a / r).max(0.0)),
                b: std::array::from_fn(|c| (f.channels[c].b / (r * r)).max(0.0)),
                a_stderr: Some(std::array::from_fn(|c| f.channels[c].a_stderr / r)),
                b_stderr: Some(std::array::from_fn(|c| f.channels[c].b_stderr / (r * r))),
            })
            .collect()
    }

    /// "ISO 100 R: b = −0.3 DN²" for each fitted value below 0 (clamped by `to_noise`).
    pub fn clamped(&self) -> Vec<String> {
        let mut out = Vec::new();
        for f in &self.isos {
            for (c, ch) in f.channels.iter().enumerate() {
                for (p, v) in [("a", ch.a), ("b", ch.b)] {
                    if v < 0.0 {
                        out.push(format!(
                            "ISO {} {}: {p} = {v:.4} (DN units) < 0, written as 0",
                            f.iso, CHANNELS[c]
                        ));
                    }
                }
            }
        }
        out
    }

    /// Text for `provenance.noise`.
    pub fn provenance(&self) -> String {
        let isos: Vec<String> = self.isos.iter().map(|f| format!("{}", f.iso)).collect();
        let kinds = |k: BurstKind| self.bursts.iter().filter(|b| b.kind == k).count();
        format!(
            "hdrsynth {} calibrate noise on capture set {} ({} bursts: {} dark, {} flat, {} chart, \
             {} scene; ISO {}); black level {} DN ({}), white level {} DN ({}); per-pixel \
             temporal variance binned by mean, saturated/defective pixels excluded, weighted \
             least squares σ² = a·I + b per ISO and channel (docs/noise.md), converted to the \
             normalised convention with this profile's levels",
            env!("CARGO_PKG_VERSION"),
            self.source,
            self.bursts.len(),
            kinds(BurstKind::Dark),
            kinds(BurstKind::Flat),
            kinds(BurstKind::Chart),
            kinds(BurstKind::Scene),
            isos.join(", "),
            fmt_level(self.black_level),
            self.black_source.describe(),
            fmt_level(self.white_level),
            self.white_source.describe(),
        )
    }

    /// The report: levels, then a table per ISO and channel in DN and normalised with the
    /// levels (white, black) the profile uses.
    pub fn report(&self, white: f64, black: f64) -> String {
        let mut s = String::new();
        let frames: usize = self.bursts.iter().map(|b| b.frames).sum();
        let _ = writeln!(
            s,
            "Noise calibration of {}: {} bursts, {} frames",
            self.source,
            self.bursts.len(),
            frames
        );
        let _ = writeln!(
            s,
            "white level {} DN ({}); black level {} DN ({})",
            fmt_level(self.white_level),
            self.white_source.describe(),
            fmt_level(self.black_level),
            self.black_source.describe()
        );
        match (self.black_declared, self.black_estimated) {
            (Some(d), Some(e)) if (d - e).abs() > 0.5 => {
                let _ = writeln!(
                    s,
                    "WARNING: declared black level {} DN and the dark-frame estimate {e:.2} DN \
                     differ by {:+.2} DN",
                    fmt_level(d),
                    e - d
                );
            }
            (Some(d), Some(e)) => {
                let _ = writeln!(
                    s,
                    "declared black level {} DN agrees with the dark-frame estimate {e:.2} DN",
                    fmt_level(d)
                );
            }
            (None, Some(e)) if self.black_source != LevelSource::EstimatedFromDark => {
                let _ = writeln!(s, "dark-frame estimate of the black level: {e:.2} DN");
            }
            _ => {}
        }
        let r = white - black;
        let _ = writeln!(
            s,
            "model σ² = a·I + b, I = mean − black in DN; profile convention x = I/(W − B) with \
             W − B = {} DN: a_norm = a/(W − B), b_norm = b/(W − B)²",
            fmt_level(r)
        );
        if (white - self.white_level).abs() > 1e-9 || (black - self.black_level).abs() > 1e-9 {
            let _ = writeln!(
                s,
                "NOTE: normalised with the profile's levels (white {}, black {}), not the \
                 calibration's (white {}, black {})",
                fmt_level(white),
                fmt_level(black),
                fmt_level(self.white_level),
                fmt_level(self.black_level)
            );
        }
        let _ = writeln!(
            s,
            "\n{:>7} {:>2} {:>11} {:>10} {:>11} {:>10} {:>5} {:>8} {:>7} {:>7} {:>6} {:>7} {:>11} {:>11}",
            "ISO",
            "ch",
            "a [DN]",
            "± a",
            "b [DN²]",
            "± b",
            "bins",
            "pixels",
            "satur.",
            "defect",
            "zero",
            "χ²/dof",
            "a_norm",
            "b_norm"
        );
        for f in &self.isos {
            for (c, ch) in f.channels.iter().enumerate() {
                let _ = writeln!(
                    s,
                    "{:>7} {:>2} {:>11.5} {:>10.5} {:>11.4} {:>10.4} {:>5} {:>8} {:>7} {:>7} {:>6} {:>7.2} {:>11.4e} {:>11.4e}",
                    f.iso,
                    CHANNELS[c],
                    ch.a,
                    ch.a_stderr,
                    ch.b,
                    ch.b_stderr,
                    ch.bins.len(),
                    ch.counts.used,
                    ch.counts.saturated,
                    ch.counts.defective,
                    ch.counts.clipped_low,
                    ch.chi2_reduced,
                    ch.a.max(0.0) / r,
                    ch.b.max(0.0) / (r * r)
                );
            }
        }
        let _ = writeln!(
            s,
            "(pixels = pixel samples used; satur./defect/zero = excluded as saturated, defective \
             (hot, dead, stuck, noisy), clipped at 0 DN; summed over the ISO's bursts)"
        );
        for note in self.clamped() {
            let _ = writeln!(s, "clamped: {note}");
        }
        for note in &self.skipped {
            let _ = writeln!(s, "skipped: {note}");
        }
        s
    }
}

fn fmt_level(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{}", v as i64)
    } else {
        format!("{v:.3}")
    }
}

/// A new measured profile with no colour calibration and default responses, for the
/// calibrate/import commands when the output profile does not exist yet.
pub fn new_measured_profile(
    name: &str,
    levels: Levels,
    levels_source: &str,
    noise: Vec<NoiseAtIso>,
    noise_source: &str,
) -> SensorProfile {
    SensorProfile {
        format: PROFILE_FORMAT.to_string(),
        name: name.to_string(),
        kind: ProfileKind::Measured,
        provenance: Provenance {
            colour: "not calibrated yet (run `hdrsynth calibrate colour`)".into(),
            noise: noise_source.to_string(),
            levels: levels_source.to_string(),
            response: "defaults, not measured: response = srgb, source_response = filmic (the \
                       scene engine's display curve)"
                .into(),
            notes: None,
        },
        colour: None,
        levels,
        noise,
        response: Response::Srgb,
        source_response: Response::Filmic,
        effects: Vec::new(),
    }
}

/// Bits needed to hold the white level: ceil(log2(white + 1)).
pub fn bits_for_white(white: f64) -> u32 {
    let mut bits = 1;
    while bits < 64 && ((1u64 << bits) - 1) as f64 + 1e-9 < white {
        bits += 1;
    }
    bits
}

// ---------------------------------------------------------------------------------------------
// Photon-transfer-curve plot

/// Panel size of the PTC plot, one panel per ISO.
pub const PTC_PANEL: (usize, usize) = (420, 320);
/// Height of the title strip above the panels.
pub const PTC_HEADER: usize = 30;
/// Panels per row.
pub const PTC_COLUMNS: usize = 3;

/// Size (width, height) of the PTC plot for `n_isos` panels: columns = min(n, 3), rows =
/// ceil(n / 3); width = 420·columns, height = 30 + 320·rows.
pub fn ptc_plot_size(n_isos: usize) -> (usize, usize) {
    let n = n_isos.max(1);
    let cols = n.min(PTC_COLUMNS);
    let rows = n.div_ceil(PTC_COLUMNS);
    (PTC_PANEL.0 * cols, PTC_HEADER + PTC_PANEL.1 * rows)
}

impl NoiseCalibration {
    /// Render the photon-transfer curves: per ISO a log–log panel of bin variance (DN²)
    /// against bin signal (DN above black), points with ±1 SE bars and the fitted lines, one
    /// colour per channel. Bins at or below the axis' left edge (dark bursts) are drawn on the
    /// edge as hollow squares. Returns display code values in [0, 1].
    pub fn render_ptc(&self) -> Image {
        plot::render(self)
    }

    /// Write [`Self::render_ptc`] as an 8-bit PNG, atomically.
    pub fn write_ptc_plot(&self, path: &Path) -> Result<()> {
        crate::io::write_ldr(path, &self.render_ptc(), crate::io::BitDepth::Eight)
    }
}

mod plot {
    use super::{CHANNELS, NoiseCalibration, PTC_COLUMNS, PTC_HEADER, PTC_PANEL, ptc_plot_size};
    use crate::io::Image;
    use embedded_graphics::mono_font::MonoTextStyle;
    use embedded_graphics::mono_font::iso_8859_1::{FONT_6X10, FONT_7X13_BOLD};
    use embedded_graphics::pixelcolor::Rgb888;
    use embedded_graphics::prelude::*;
    use embedded_graphics::primitives::{Circle, Line, PrimitiveStyle, Rectangle};
    use embedded_graphics::text::{Alignment, Text};

    use crate::plot::Canvas;

    const COLOURS: [Rgb888; 3] = [
        Rgb888::new(210, 40, 40),
        Rgb888::new(30, 150, 50),
        Rgb888::new(40, 80, 220),
    ];
    const INK: Rgb888 = Rgb888::new(20, 20, 20);
    const GRID: Rgb888 = Rgb888::new(222, 222, 222);

    // Plot area inside a panel.
    const LEFT: i32 = 56;
    const RIGHT: i32 = 14;
    const TOP: i32 = 30;
    const BOTTOM: i32 = 40;

    fn decade_label(k: i32) -> String {
        match k {
            0..=4 => format!("{}", 10i64.pow(k as u32)),
            -2..=-1 => format!("{}", 10f64.powi(k)),
            _ => format!("1e{k}"),
        }
    }

    pub(super) fn render(cal: &NoiseCalibration) -> Image {
        let (w, h) = ptc_plot_size(cal.isos.len());
        let mut cv = Canvas::new(w, h);
        let ink = MonoTextStyle::new(&FONT_6X10, INK);
        let bold = MonoTextStyle::new(&FONT_7X13_BOLD, INK);
        let _ = Text::new(
            "Photon transfer: temporal variance [DN²] vs signal above black [DN], log-log; \
             points = bins ±1 SE, lines = WLS fits",
            Point::new(8, 19),
            ink,
        )
        .draw(&mut cv);

        // Shared axis ranges (decades) so that panels compare at a glance.
        let bins = || {
            cal.isos
                .iter()
                .flat_map(|f| f.channels.iter().flat_map(|c| &c.bins))
        };
        let min_x = bins()
            .map(|b| b.signal)
            .filter(|&x| x >= 1.0)
            .fold(f64::INFINITY, f64::min);
        let max_x = bins().map(|b| b.signal).fold(1.0, f64::max);
        let x_lo = if min_x.is_finite() {
            min_x.log10().floor().min(0.0) as i32
        } else {
            0
        };
        let x_hi = (max_x.log10().ceil() as i32).max(x_lo + 1);
        let min_y = bins()
            .map(|b| b.variance - b.stderr)
            .filter(|&y| y > 0.0)
            .fold(f64::INFINITY, f64::min);
        let max_y = bins()
            .map(|b| b.variance + b.stderr)
            .fold(f64::NEG_INFINITY, f64::max);
        let y_lo = if min_y.is_finite() {
            min_y.log10().floor() as i32
        } else {
            -1
        };
        let y_hi = if max_y.is_finite() && max_y > 0.0 {
            (max_y.log10().ceil() as i32).max(y_lo + 1)
        } else {
            y_lo + 1
        };

        for (k, fit) in cal.isos.iter().enumerate() {
            let ox = (k % PTC_COLUMNS * PTC_PANEL.0) as i32;
            let oy = (PTC_HEADER + k / PTC_COLUMNS * PTC_PANEL.1) as i32;
            let (pw, ph) = (PTC_PANEL.0 as i32, PTC_PANEL.1 as i32);
            let (ax0, ax1) = (ox + LEFT, ox + pw - RIGHT);
            let (ay0, ay1) = (oy + TOP, oy + ph - BOTTOM);
            let map_x = |x: f64| {
                let t = (x.max(10f64.powi(x_lo)).log10() - x_lo as f64) / (x_hi - x_lo) as f64;
                ax0 as f64 + t * (ax1 - ax0) as f64
            };
            let map_y = |y: f64| {
                let t = (y.log10() - y_lo as f64) / (y_hi - y_lo) as f64;
                ay1 as f64 - t * (ay1 - ay0) as f64
            };
            let clip_y = |y: f64| y.clamp(ay0 as f64, ay1 as f64);

            // Grid and ticks.
            for d in x_lo..=x_hi {
                let x = map_x(10f64.powi(d)).round() as i32;
                let _ = Line::new(Point::new(x, ay0), Point::new(x, ay1))
                    .into_styled(PrimitiveStyle::with_stroke(GRID, 1))
                    .draw(&mut cv);
                let _ = Text::with_alignment(
                    &decade_label(d),
                    Point::new(x, ay1 + 13),
                    ink,
                    Alignment::Center,
                )
                .draw(&mut cv);
            }
            for d in y_lo..=y_hi {
                let y = map_y(10f64.powi(d)).round() as i32;
                let _ = Line::new(Point::new(ax0, y), Point::new(ax1, y))
                    .into_styled(PrimitiveStyle::with_stroke(GRID, 1))
                    .draw(&mut cv);
                let _ = Text::with_alignment(
                    &decade_label(d),
                    Point::new(ax0 - 4, y + 3),
                    ink,
                    Alignment::Right,
                )
                .draw(&mut cv);
            }
            let _ = Rectangle::new(
                Point::new(ax0, ay0),
                Size::new((ax1 - ax0 + 1) as u32, (ay1 - ay0 + 1) as u32),
            )
            .into_styled(PrimitiveStyle::with_stroke(INK, 1))
            .draw(&mut cv);
            let _ = Text::new(&format!("ISO {}", fit.iso), Point::new(ax0, oy + 14), bold)
                .draw(&mut cv);
            let _ = Text::with_alignment(
                "variance [DN²]",
                Point::new(ax1, oy + 14),
                ink,
                Alignment::Right,
            )
            .draw(&mut cv);
            let _ = Text::with_alignment(
                "signal above black [DN]",
                Point::new((ax0 + ax1) / 2, ay1 + 28),
                ink,
                Alignment::Center,
            )
            .draw(&mut cv);

            // Fitted lines.
            for (c, ch) in fit.channels.iter().enumerate() {
                let style = PrimitiveStyle::with_stroke(COLOURS[c], 1);
                let n = 120;
                let mut prev: Option<Point> = None;
                for i in 0..=n {
                    let lx = x_lo as f64 + (x_hi - x_lo) as f64 * i as f64 / n as f64;
                    let x = 10f64.powf(lx);
                    let y = ch.a * x + ch.b;
                    let pt = if y > 0.0 {
                        let py = map_y(y);
                        (py >= ay0 as f64 && py <= ay1 as f64)
                            .then(|| Point::new(map_x(x).round() as i32, py.round() as i32))
                    } else {
                        None
                    };
                    if let (Some(p0), Some(p1)) = (prev, pt) {
                        let _ = Line::new(p0, p1).into_styled(style).draw(&mut cv);
                    }
                    prev = pt;
                }
            }
            // Bins with error bars.
            for (c, ch) in fit.channels.iter().enumerate() {
                let colour = COLOURS[c];
                for b in &ch.bins {
                    if b.variance <= 0.0 {
                        continue;
                    }
                    let x = map_x(b.signal).round() as i32;
                    let y = clip_y(map_y(b.variance)).round() as i32;
                    let hi = clip_y(map_y(b.variance + b.stderr)).round() as i32;
                    let lo_v = b.variance - b.stderr;
                    let lo = if lo_v > 0.0 {
                        clip_y(map_y(lo_v)).round() as i32
                    } else {
                        ay1
                    };
                    let bar = PrimitiveStyle::with_stroke(colour, 1);
                    let _ = Line::new(Point::new(x, lo), Point::new(x, hi))
                        .into_styled(bar)
                        .draw(&mut cv);
                    for e in [lo, hi] {
                        let _ = Line::new(Point::new(x - 2, e), Point::new(x + 2, e))
                            .into_styled(bar)
                            .draw(&mut cv);
                    }
                    if b.signal < 10f64.powi(x_lo) {
                        let _ = Rectangle::new(Point::new(x - 3, y - 3), Size::new(7, 7))
                            .into_styled(PrimitiveStyle::with_stroke(colour, 1))
                            .draw(&mut cv);
                    } else {
                        let _ = Circle::new(Point::new(x - 2, y - 2), 5)
                            .into_styled(PrimitiveStyle::with_fill(colour))
                            .draw(&mut cv);
                    }
                }
            }
            // Legend.
            for (c, ch) in fit.channels.iter().enumerate() {
                let txt = format!("{} a={:.4} b={:.3}", CHANNELS[c], ch.a, ch.b);
                let _ = Text::new(
                    &txt,
                    Point::new(ax0 + 6, ay0 + 12 + 11 * c as i32),
                    MonoTextStyle::new(&FONT_6X10, COLOURS[c]),
                )
                .draw(&mut cv);
            }
        }

        cv.into_image()
    }
}
