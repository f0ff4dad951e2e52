//! Bins of pixels per burst and channel, and the weighted straight-line fit per ISO.

use super::bursts::{BurstFrames, BurstStats};
use super::{
    BIN_STEP, Bin, BurstSummary, CHANNELS, CalibrateOptions, ChannelFit, Counts, DEFECT_SIGMAS,
    IsoFit, LevelSource, MAD_TO_SIGMA, MIN_BIN_PIXELS, NoiseCalibration, QUANTISATION_VARIANCE,
    WINDOW_RADIUS,
};
use crate::error::{Error, Result};
use crate::sensor::captures::{BurstKind, CaptureSet};
use crate::stats::{self, median};
use rayon::prelude::*;
use std::collections::BTreeMap;

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
        let CalibrationPlan {
            white_level,
            white_source,
            used,
            skipped,
        } = self;
        let black_declared = set.manifest.sensor.black_level;
        let (black_level, black_source, black_estimated) =
            black_level(set, opts, &stats, white_level)?;

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
            per_burst.push(BurstBins {
                burst: i,
                bins,
                counts,
            });
        }

        // Group by ISO and fit.
        let mut iso_values: Vec<f64> = used.iter().map(|&i| set.bursts()[i].iso).collect();
        iso_values.sort_by(f64::total_cmp);
        iso_values.dedup();
        let isos = iso_values
            .into_iter()
            .map(|iso| fit_iso(set, iso, &per_burst))
            .collect::<Result<_>>()?;

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

/// The black level, where it came from, and the dark-frame estimate: override > declared >
/// estimate (median over dark frames of each frame's outlier-clipped mean). It must lie in
/// [0, white).
fn black_level(
    set: &CaptureSet,
    opts: &CalibrateOptions,
    stats: &[BurstFrames],
    white_level: f64,
) -> Result<(f64, LevelSource, Option<f64>)> {
    let manifest_err = |m: String| Error::config(&set.manifest_path, m);
    let mut means: Vec<f64> = stats.iter().flat_map(|s| s.frame_means.clone()).collect();
    let black_estimated = (!means.is_empty()).then(|| median(&mut means));
    let black_declared = set.manifest.sensor.black_level;
    let (black_level, black_source) = match (opts.black_level, black_declared, black_estimated) {
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
    Ok((black_level, black_source, black_estimated))
}

/// One burst's bins and exclusion counts, per channel.
struct BurstBins {
    burst: usize,
    bins: [Vec<Bin>; 3],
    counts: [Counts; 3],
}

/// The fit of one ISO: per channel, the bins and counts of its bursts together.
fn fit_iso(set: &CaptureSet, iso: f64, per_burst: &[BurstBins]) -> Result<IsoFit> {
    let group: Vec<&BurstBins> = per_burst
        .iter()
        .filter(|b| set.bursts()[b.burst].iso == iso)
        .collect();
    let bursts: Vec<usize> = group.iter().map(|b| b.burst).collect();
    let mut channels = Vec::new();
    for (c, cname) in CHANNELS.iter().enumerate() {
        let mut bins = Vec::new();
        let mut counts = Counts::default();
        for b in &group {
            bins.extend(b.bins[c].iter().cloned());
            counts.add(&b.counts[c]);
        }
        let fit = fit_bins(&bins).map_err(|m| {
            Error::config(
                &set.manifest_path,
                format!(
                    "ISO {iso}, channel {cname} (bursts {}): {m}",
                    bursts
                        .iter()
                        .map(|&i| format!("'{}'", set.bursts()[i].name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )
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
    Ok(IsoFit {
        iso,
        bursts,
        channels,
    })
}

const OK: u8 = 0;
const SATURATED: u8 = 1;
const DEFECTIVE: u8 = 2;
const CLIPPED_LOW: u8 = 3;

/// Exclusions and bins for one channel of one burst: saturated pixels, mean outliers against
/// their neighbours, pixels clipped at 0, then per signal bin the variance outliers.
fn channel_bins(
    st: &BurstStats,
    c: usize,
    burst: usize,
    black: f64,
    s_lin: f64,
) -> (Vec<Bin>, Counts) {
    let np = st.width * st.height;
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
    let (z, nb) = neighbour_scores(st, c, &status);
    mark_mean_outliers(&mut status, &z);
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
        let keep = without_variance_outliers(st, c, pixels, &mut status);
        if keep.len() < MIN_BIN_PIXELS {
            counts.sparse += keep.len();
            continue;
        }
        counts.used += keep.len();
        bins.push(bin_of(st, c, &keep, burst, black));
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

/// Per pixel the mean-outlier score and the median temporal mean of its 5×5 neighbours (the
/// pixel itself left out, so that they are independent of its own temporal noise); NaN for a
/// pixel already excluded or without usable neighbours. The neighbour median is the binning
/// variable; the score is z = (mean − neighbour median) / √(neighbour median variance / n),
/// robustly rescaled by [`mark_mean_outliers`].
fn neighbour_scores(st: &BurstStats, c: usize, status: &[u8]) -> (Vec<f32>, Vec<f32>) {
    let (w, h) = (st.width, st.height);
    let idx = |p: usize| p * 3 + c;
    let nf = st.frames as f64;
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
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
        .unzip()
}

/// Mark as defective the pixels whose score `z` is more than [`DEFECT_SIGMAS`] robust σ
/// (from the MAD, at least 0.5) from the median score.
fn mark_mean_outliers(status: &mut [u8], z: &[f32]) {
    let mut finite: Vec<f64> = z
        .iter()
        .filter(|v| v.is_finite())
        .map(|&v| v as f64)
        .collect();
    if finite.is_empty() {
        return;
    }
    let med = median(&mut finite);
    let mut dev: Vec<f64> = finite.iter().map(|v| (v - med).abs()).collect();
    let sigma = (MAD_TO_SIGMA * median(&mut dev)).max(0.5);
    for (s, &z) in status.iter_mut().zip(z) {
        if *s == OK && (z as f64 - med).abs() > DEFECT_SIGMAS * sigma {
            *s = DEFECTIVE;
        }
    }
}

/// The bin's pixels less its variance outliers (above the median by [`DEFECT_SIGMAS`] robust
/// σ) and stuck pixels (variance 0 where the median is ≥ 1), which are marked defective.
fn without_variance_outliers(
    st: &BurstStats,
    c: usize,
    pixels: &[usize],
    status: &mut [u8],
) -> Vec<usize> {
    let idx = |p: usize| p * 3 + c;
    let mut vars: Vec<f64> = pixels.iter().map(|&p| st.var[idx(p)] as f64).collect();
    let med = median(&mut vars);
    let mut dev: Vec<f64> = vars.iter().map(|v| (v - med).abs()).collect();
    let sigma = (MAD_TO_SIGMA * median(&mut dev)).max(0.1 * med).max(0.1);
    let limit = med + DEFECT_SIGMAS * sigma;
    pixels
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
        .collect()
}

/// One bin of the fit: mean signal above black, mean temporal variance less quantisation, and
/// the standard error of that mean.
fn bin_of(st: &BurstStats, c: usize, keep: &[usize], burst: usize, black: f64) -> Bin {
    let idx = |p: usize| p * 3 + c;
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
    Bin {
        burst,
        signal,
        variance: vmean - QUANTISATION_VARIANCE,
        stderr: vsd / n.sqrt(),
        pixels: keep.len(),
    }
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
