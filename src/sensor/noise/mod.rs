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
//!
//! Layout (EMVA 1288's data → statistics → results → report): `bursts` streams the frames of a
//! burst into per-pixel temporal statistics, `calibrate` bins them and fits the line, `report`
//! and `plot` present a [`NoiseCalibration`], `profile` writes it into a sensor profile
//! (`hdrsynth calibrate noise`).

pub mod bursts;
pub mod calibrate;
pub mod plot;
pub mod profile;
mod report;

use crate::error::Result;
use crate::sensor::captures::{BurstKind, CaptureSet};
use bursts::BurstFrames;
use calibrate::CalibrationPlan;

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

/// Bits needed to hold the white level: ceil(log2(white + 1)).
pub fn bits_for_white(white: f64) -> u32 {
    let mut bits = 1;
    while bits < 64 && ((1u64 << bits) - 1) as f64 + 1e-9 < white {
        bits += 1;
    }
    bits
}
