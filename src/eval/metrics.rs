//! Evaluation metrics for HDR reconstruction, computed the way the field's Python evaluation
//! computes them (scikit-image 0.26 on float64), plus PU21 PSNR/SSIM (Mantiuk & Azimi 2021); the
//! bootstrap of their confidence intervals is in src/stats.rs. See docs/metrics.md.
//!
//! Conventions (checked against the oracle in shared/data/oracles/oracles.json to 1e-6):
//! - PSNR-L: `skimage.metrics.peak_signal_noise_ratio(gt, pred, data_range=1.0)` on the linear
//!   values, both cast to f64, no clipping. MSE = 0 gives +inf.
//! - PSNR-T: the same on μ-law tonemapped values `log(1 + 5000x) / log(5001)`, in f64.
//! - SSIM: both images `clip(x · 255, 0, 255)`, then `structural_similarity(channel_axis=-1,
//!   gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=255)`: 11-tap
//!   Gaussian (truncate 3.5), scipy 'reflect' borders, mean over the map cropped by 5 pixels on
//!   each side, mean over the three channels. SSIM-T is SSIM on `clip(T(x) · 255, 0, 255)`.
//! - PU21: pu21's MATLAB `pu21_metric` on absolute luminance: PSNR over RGB with peak 256, SSIM on
//!   luminance with MATLAB `ssim(..., 'DynamicRange', 256)` (replicate borders, no crop).
//! - ΔE2000: mean over pixels of CIEDE2000 (kL = kC = kH = 1) between the T images read as
//!   sRGB-encoded display RGB (Rec. 709 primaries, D65): sRGB decoding, the IEC 61966-2-1
//!   matrix, CIELAB relative to the sRGB white (Y = 1), colour-science's `delta_E(...,
//!   method='CIE 2000')` (oracle: tools/delta_e_reference.py, to 1e-6).
//! - PSNR-T dark: PSNR (range 1) of the T images over the pixels where the set's reference input
//!   frame is under-exposed (largest channel below [`DARK_CODE`]), all three channels; absent
//!   when fewer than [`MASK_MIN_FRACTION`] of the pixels are masked.
//! - PSNR-T moving: the same over the pixels a subject covers in any frame of the set, at its
//!   own time or the reference's (the union of the set's motion masks).

use crate::error::{Error, Result};
use crate::io::Image;
use crate::sensor::colour::cie;
use rayon::prelude::*;

pub use crate::io::mu_law::{MU, mu_law};

/// The clip(x · 255, 0, 255) that the field applies before SSIM.
#[inline]
fn to_255(x: f64) -> f64 {
    (x * 255.0).clamp(0.0, 255.0)
}

/// PSNR in dB from a mean squared error: `10 log10(range² / mse)`; +inf when `mse == 0`.
#[inline]
pub fn psnr_from_mse(mse: f64, data_range: f64) -> f64 {
    10.0 * (data_range * data_range / mse).log10()
}

/// Mean squared error in f64 of the two images' values (all channels), as skimage computes it.
pub fn mse(gt: &Image, pred: &Image) -> Result<f64> {
    check_pair(gt, pred)?;
    Ok(mse_by(&gt.data, &pred.data, |v| v as f64))
}

/// PSNR (dB) of linear values, skimage's `peak_signal_noise_ratio(gt, pred, data_range)`: no
/// clipping, f64 arithmetic; identical images give +inf.
pub fn psnr(gt: &Image, pred: &Image, data_range: f64) -> Result<f64> {
    check_pair(gt, pred)?;
    check_data_range(data_range)?;
    Ok(psnr_from_mse(
        mse_by(&gt.data, &pred.data, |v| v as f64),
        data_range,
    ))
}

/// PSNR-T: PSNR (range 1) of the μ-law tonemapped images, the tonemapping done in f64.
pub fn psnr_mu(gt: &Image, pred: &Image) -> Result<f64> {
    check_pair(gt, pred)?;
    check_mu_domain(gt, "ground truth")?;
    check_mu_domain(pred, "prediction")?;
    Ok(psnr_from_mse(
        mse_by(&gt.data, &pred.data, |v| mu_law(v as f64)),
        1.0,
    ))
}

/// SSIM in the field's convention: both images `clip(x · 255, 0, 255)` (so values above 1 are
/// saturated), then skimage's Gaussian SSIM with data_range 255, mean over R, G, B.
/// Images must be at least 11×11 (skimage's limit for its 11-pixel window).
pub fn ssim(gt: &Image, pred: &Image) -> Result<f64> {
    check_pair(gt, pred)?;
    check_ssim_size(gt)?;
    Ok(ssim_rgb(gt, pred, |v| to_255(v as f64)))
}

/// SSIM-T: [`ssim`] of the μ-law tonemapped images, i.e. on `clip(T(x) · 255, 0, 255)`.
pub fn ssim_mu(gt: &Image, pred: &Image) -> Result<f64> {
    check_pair(gt, pred)?;
    check_ssim_size(gt)?;
    check_mu_domain(gt, "ground truth")?;
    check_mu_domain(pred, "prediction")?;
    Ok(ssim_rgb(gt, pred, |v| to_255(mu_law(v as f64))))
}

// ---------------------------------------------------------------------------------------------
// PU21

/// PU21 'banding_glare' parameters p1..p7 (the default and recommended variant), from
/// gfxdisp/pu21 `pu21_encoder.m` (parameters dated 06/02/2020).
pub const PU21_BANDING_GLARE: [f64; 7] = [
    0.353487901,
    0.3734658629,
    8.277049286e-05,
    0.9062562627,
    0.09150303166,
    0.9099517204,
    596.3148142,
];
/// Luminance range the PU21 encoder is defined on (cd/m²); inputs are clamped to it.
pub const PU21_L_MIN: f64 = 0.005;
pub const PU21_L_MAX: f64 = 10000.0;
/// Peak value pu21_metric passes to PSNR and SSIM for PU-encoded values.
pub const PU21_PEAK: f64 = 256.0;

/// PU21 encoding of absolute luminance `y` (cd/m²), clamped to [0.005, 10000] first:
/// `p7 · (((p1 + p2 y^p4) / (1 + p3 y^p4))^p5 − p6)`. About 0 at 0.005 cd/m², 256 near 100 cd/m².
#[inline]
pub fn pu21_encode(y: f64) -> f64 {
    let p = &PU21_BANDING_GLARE;
    let y = y.clamp(PU21_L_MIN, PU21_L_MAX);
    // exp(a·ln x) rather than powf: about twice as fast here, and within ~1e-15 relative.
    let yp = (p[3] * y.ln()).exp();
    let r = (p[0] + p[1] * yp) / (1.0 + p[2] * yp);
    p[6] * ((p[4] * r.ln()).exp() - p[5])
}

/// How relative linear values become absolute luminance for PU21.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "snake_case")]
pub enum Pu21Scale {
    /// The ground truth's maximum value (over all pixels and channels) maps to the peak, and the
    /// prediction is scaled by the same factor: pu21's own HDR example (`ex_hdr_images.m`).
    #[default]
    ReferenceMax,
    /// Pixel value 1.0 maps to the peak, for both images.
    UnitValue,
}

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct MetricOptions {
    /// Display peak luminance (cd/m²) for PU21; pu21's examples use 4000.
    pub peak_luminance: f64,
    pub pu21_scale: Pu21Scale,
}

impl Default for MetricOptions {
    fn default() -> Self {
        MetricOptions {
            peak_luminance: 4000.0,
            pu21_scale: Pu21Scale::ReferenceMax,
        }
    }
}

/// Factor that turns the images' linear values into cd/m² for PU21.
pub fn pu21_scale_factor(gt: &Image, opts: &MetricOptions) -> Result<f64> {
    if !(opts.peak_luminance.is_finite() && opts.peak_luminance > 0.0) {
        return Err(Error::flag(
            "--peak-luminance",
            format!("{} must be positive and finite", opts.peak_luminance),
        ));
    }
    match opts.pu21_scale {
        Pu21Scale::UnitValue => Ok(opts.peak_luminance),
        Pu21Scale::ReferenceMax => {
            let max = gt.data.iter().fold(f32::NEG_INFINITY, |m, &v| m.max(v)) as f64;
            if max > 0.0 {
                Ok(opts.peak_luminance / max)
            } else {
                Err(Error::Invalid(format!(
                    "PU21 with reference-max scaling needs a ground truth with a positive \
                     maximum, got {max}"
                )))
            }
        }
    }
}

/// PU21-PSNR: PSNR (peak 256) over the PU-encoded R, G and B values of the absolute-luminance
/// images, as pu21_metric(…, 'PSNR').
pub fn pu21_psnr(gt: &Image, pred: &Image, opts: &MetricOptions) -> Result<f64> {
    check_pair(gt, pred)?;
    let s = pu21_scale_factor(gt, opts)?;
    Ok(psnr_from_mse(
        mse_by(&gt.data, &pred.data, |v| pu21_encode(v as f64 * s)),
        PU21_PEAK,
    ))
}

/// PU21-SSIM: MATLAB-style SSIM (11×11 Gaussian σ 1.5, replicate borders, mean over the whole
/// map, DynamicRange 256) of the PU-encoded luminance, as pu21_metric(…, 'SSIM').
pub fn pu21_ssim(gt: &Image, pred: &Image, opts: &MetricOptions) -> Result<f64> {
    check_pair(gt, pred)?;
    check_ssim_size(gt)?;
    let s = pu21_scale_factor(gt, opts)?;
    // pu21's get_luminance weights, applied to absolute RGB before encoding.
    let lum = |img: &Image, p: usize| {
        let d = &img.data[p * 3..p * 3 + 3];
        let l = (d[0] as f64 * s) * 0.212656
            + (d[1] as f64 * s) * 0.715158
            + (d[2] as f64 * s) * 0.072186;
        pu21_encode(l)
    };
    let spec = SsimSpec {
        data_range: PU21_PEAK,
        border: Border::Replicate,
        crop: 0,
    };
    Ok(ssim_plane(
        gt.width,
        gt.height,
        &|p| lum(gt, p),
        &|p| lum(pred, p),
        &spec,
    ))
}

// ---------------------------------------------------------------------------------------------
// Colour difference and the under-exposed region

/// A pixel of the reference input frame is under-exposed when its largest channel, as an LDR
/// code in [0, 1], is below this (8-bit codes 0..=25).
pub const DARK_CODE: f32 = 0.1;
/// PSNR-T over a mask (dark, moving) is reported only when at least this fraction of the
/// pixels is masked.
pub const MASK_MIN_FRACTION: f64 = 0.01;

/// A set of pixels a metric is restricted to: where the set's reference input frame is
/// under-exposed (largest channel below [`DARK_CODE`], where sensor noise dominates a
/// reconstruction: [`PixelMask::from_frame`]), or where a subject moved between the frames
/// ([`PixelMask::from_flags`] of the set's motion masks).
#[derive(Clone, Debug, PartialEq)]
pub struct PixelMask {
    pub width: usize,
    pub height: usize,
    mask: Vec<bool>,
    count: usize,
}

impl PixelMask {
    /// The mask of a reference frame's display codes as read.
    pub fn from_frame(frame: &Image) -> Result<PixelMask> {
        check_image(frame, "reference frame")?;
        let mask: Vec<bool> = frame
            .data
            .par_chunks_exact(3)
            .map(|p| p[0].max(p[1]).max(p[2]) < DARK_CODE)
            .collect();
        let count = mask.iter().filter(|&&m| m).count();
        Ok(PixelMask {
            width: frame.width,
            height: frame.height,
            mask,
            count,
        })
    }

    /// A mask of one flag per pixel, row-major.
    pub fn from_flags(width: usize, height: usize, mask: Vec<bool>) -> Result<PixelMask> {
        if mask.len() != width * height {
            return Err(Error::Invalid(format!(
                "a {width}x{height} mask needs {} flags, got {}",
                width * height,
                mask.len()
            )));
        }
        let count = mask.iter().filter(|&&m| m).count();
        Ok(PixelMask {
            width,
            height,
            mask,
            count,
        })
    }

    /// Masked pixels.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Masked pixels over all pixels.
    pub fn fraction(&self) -> f64 {
        self.count as f64 / self.mask.len() as f64
    }

    fn check(&self, img: &Image) -> Result<()> {
        if (self.width, self.height) != (img.width, img.height) {
            return Err(Error::Invalid(format!(
                "the pixel mask is {}x{}, the images scored are {}x{}",
                self.width, self.height, img.width, img.height
            )));
        }
        Ok(())
    }
}

/// Mean CIEDE2000 over pixels of two display images read as sRGB-encoded RGB
/// ([`cie::display_srgb_to_lab`]); lower is better, 0 for identical images.
pub fn delta_e2000(gt_t: &Image, pred_t: &Image) -> Result<f64> {
    check_pair(gt_t, pred_t)?;
    Ok(mean_delta_e_by(&gt_t.data, &pred_t.data, |v| v as f64))
}

/// [`delta_e2000`] of the μ-law tonemapped images (the T images of PSNR-T), tonemapped in f64.
pub fn delta_e2000_mu(gt: &Image, pred: &Image) -> Result<f64> {
    check_pair(gt, pred)?;
    check_mu_domain(gt, "ground truth")?;
    check_mu_domain(pred, "prediction")?;
    Ok(mean_delta_e_by(&gt.data, &pred.data, |v| mu_law(v as f64)))
}

/// PSNR (range 1) of display images over the masked pixels, all three channels; None when fewer
/// than [`MASK_MIN_FRACTION`] of the pixels are masked. +inf when they agree there.
pub fn psnr_masked(gt_t: &Image, pred_t: &Image, mask: &PixelMask) -> Result<Option<f64>> {
    check_pair(gt_t, pred_t)?;
    mask.check(gt_t)?;
    Ok(masked_psnr_by(&gt_t.data, &pred_t.data, mask, |v| v as f64))
}

/// [`psnr_masked`] of the μ-law tonemapped images: PSNR-T over the under-exposed pixels.
pub fn psnr_mu_masked(gt: &Image, pred: &Image, mask: &PixelMask) -> Result<Option<f64>> {
    check_pair(gt, pred)?;
    mask.check(gt)?;
    check_mu_domain(gt, "ground truth")?;
    check_mu_domain(pred, "prediction")?;
    Ok(masked_psnr_by(&gt.data, &pred.data, mask, |v| {
        mu_law(v as f64)
    }))
}

// ---------------------------------------------------------------------------------------------
// All at once

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Scores {
    pub psnr_l: f64,
    pub psnr_t: f64,
    pub ssim_l: f64,
    pub ssim_t: f64,
    pub pu21_psnr: f64,
    pub pu21_ssim: f64,
    /// Mean CIEDE2000 of the T images read as sRGB display values; lower is better.
    pub delta_e2000: f64,
    /// PSNR-T over the pixels where the reference input frame is under-exposed; None without a
    /// reference frame or when fewer than [`MASK_MIN_FRACTION`] of the pixels are masked.
    pub psnr_t_dark: Option<f64>,
    /// Fraction of the pixels in that mask; None without a reference frame.
    pub dark_fraction: Option<f64>,
    /// PSNR-T over the pixels where a subject moved between the frames (the set's motion
    /// masks); None for a set without motion masks or with fewer than [`MASK_MIN_FRACTION`]
    /// of its pixels moving.
    #[serde(default)]
    pub psnr_t_moving: Option<f64>,
    /// Fraction of the pixels in that mask; None for a set without motion masks.
    #[serde(default)]
    pub moving_fraction: Option<f64>,
}

/// All metrics of a linear prediction against its linear ground truth; T is the μ-law
/// tonemapping of the same images. `dark`: the set's under-exposed pixels, for PSNR-T dark.
pub fn score(
    gt: &Image,
    pred: &Image,
    dark: Option<&PixelMask>,
    opts: &MetricOptions,
) -> Result<Scores> {
    check_pair(gt, pred)?;
    check_ssim_size(gt)?;
    check_mu_domain(gt, "ground truth")?;
    check_mu_domain(pred, "prediction")?;
    let psnr_t_dark = match dark {
        Some(d) => psnr_mu_masked(gt, pred, d)?,
        None => None,
    };
    Ok(Scores {
        psnr_l: psnr(gt, pred, 1.0)?,
        psnr_t: psnr_mu(gt, pred)?,
        ssim_l: ssim(gt, pred)?,
        ssim_t: ssim_mu(gt, pred)?,
        pu21_psnr: pu21_psnr(gt, pred, opts)?,
        pu21_ssim: pu21_ssim(gt, pred, opts)?,
        delta_e2000: delta_e2000_mu(gt, pred)?,
        psnr_t_dark,
        dark_fraction: dark.map(PixelMask::fraction),
        psnr_t_moving: None,
        moving_fraction: None,
    })
}

/// All metrics when the caller has its own tonemapped pair (e.g. Network-1's pre-curve linear
/// and post-curve images): L metrics and PU21 on `gt_l`/`pred_l`, T metrics (PSNR range 1,
/// SSIM on clip(·255), ΔE2000, PSNR-T dark) on `gt_t`/`pred_t` as given, with no μ-law
/// applied.
pub fn score_pair(
    gt_l: &Image,
    pred_l: &Image,
    gt_t: &Image,
    pred_t: &Image,
    dark: Option<&PixelMask>,
    opts: &MetricOptions,
) -> Result<Scores> {
    check_pair(gt_l, pred_l)?;
    check_pair(gt_t, pred_t)?;
    if (gt_l.width, gt_l.height) != (gt_t.width, gt_t.height) {
        return Err(Error::Invalid(format!(
            "linear and tonemapped images differ in size: linear is {}x{}, tonemapped is {}x{}",
            gt_l.width, gt_l.height, gt_t.width, gt_t.height
        )));
    }
    let psnr_t_dark = match dark {
        Some(d) => psnr_masked(gt_t, pred_t, d)?,
        None => None,
    };
    Ok(Scores {
        psnr_l: psnr(gt_l, pred_l, 1.0)?,
        psnr_t: psnr(gt_t, pred_t, 1.0)?,
        ssim_l: ssim(gt_l, pred_l)?,
        ssim_t: ssim(gt_t, pred_t)?,
        pu21_psnr: pu21_psnr(gt_l, pred_l, opts)?,
        pu21_ssim: pu21_ssim(gt_l, pred_l, opts)?,
        delta_e2000: delta_e2000(gt_t, pred_t)?,
        psnr_t_dark,
        dark_fraction: dark.map(PixelMask::fraction),
        psnr_t_moving: None,
        moving_fraction: None,
    })
}

// ---------------------------------------------------------------------------------------------
// Checks

fn check_image(img: &Image, which: &str) -> Result<()> {
    if img.width == 0 || img.height == 0 {
        return Err(Error::Invalid(format!(
            "{which} image is empty ({}x{})",
            img.width, img.height
        )));
    }
    if img.data.len() != img.width * img.height * 3 {
        return Err(Error::Invalid(format!(
            "{which} image holds {} values, expected {}x{}x3 = {}",
            img.data.len(),
            img.width,
            img.height,
            img.width * img.height * 3
        )));
    }
    if let Some((count, x, y)) = img.non_finite() {
        return Err(Error::Invalid(format!(
            "{which} image has {count} non-finite values (NaN/Inf); first at x={x}, y={y}"
        )));
    }
    Ok(())
}

fn check_pair(gt: &Image, pred: &Image) -> Result<()> {
    if (gt.width, gt.height) != (pred.width, pred.height) {
        return Err(Error::Invalid(format!(
            "image sizes differ: ground truth is {}x{}, prediction is {}x{}",
            gt.width, gt.height, pred.width, pred.height
        )));
    }
    check_image(gt, "ground truth")?;
    check_image(pred, "prediction")
}

fn check_data_range(r: f64) -> Result<()> {
    if r.is_finite() && r > 0.0 {
        Ok(())
    } else {
        Err(Error::Invalid(format!(
            "PSNR data range must be positive and finite, got {r}"
        )))
    }
}

fn check_ssim_size(img: &Image) -> Result<()> {
    let win = 2 * RADIUS + 1;
    if img.width < win || img.height < win {
        return Err(Error::Invalid(format!(
            "SSIM needs images of at least {win}x{win} (its Gaussian window), got {}x{}",
            img.width, img.height
        )));
    }
    Ok(())
}

/// μ-law is undefined (NaN) at and below −1/μ; say so instead of returning NaN scores.
fn check_mu_domain(img: &Image, which: &str) -> Result<()> {
    let limit = (-1.0 / MU) as f32;
    if let Some(i) = img.data.iter().position(|&v| v <= limit) {
        let p = i / 3;
        return Err(Error::Invalid(format!(
            "{which} image has value {} at x={}, y={}: mu-law tonemapping is undefined at or \
             below -1/{MU}",
            img.data[i],
            p % img.width,
            p / img.width
        )));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Kernels

/// Sum of squared differences of `f(a) − f(b)` in f64, over fixed-size chunks in parallel and
/// added in chunk order, so the result does not depend on the thread count.
fn mse_by(a: &[f32], b: &[f32], f: impl Fn(f32) -> f64 + Sync) -> f64 {
    const CHUNK: usize = 1 << 16;
    let sums: Vec<f64> = a
        .par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(ca, cb)| {
            ca.iter()
                .zip(cb)
                .map(|(&x, &y)| {
                    let d = f(x) - f(y);
                    d * d
                })
                .sum::<f64>()
        })
        .collect();
    sums.iter().sum::<f64>() / a.len() as f64
}

/// Mean over pixels of CIEDE2000 between `f`-mapped display RGB values, over fixed-size chunks
/// in parallel and added in chunk order (independent of the thread count).
fn mean_delta_e_by(a: &[f32], b: &[f32], f: impl Fn(f32) -> f64 + Sync) -> f64 {
    const CHUNK: usize = 3 << 14;
    let lab = |p: &[f32]| cie::display_srgb_to_lab([f(p[0]), f(p[1]), f(p[2])]);
    let sums: Vec<f64> = a
        .par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(ca, cb)| {
            ca.chunks_exact(3)
                .zip(cb.chunks_exact(3))
                .map(|(x, y)| cie::delta_e_2000(lab(x), lab(y)))
                .sum::<f64>()
        })
        .collect();
    sums.iter().sum::<f64>() / (a.len() / 3) as f64
}

/// PSNR (range 1) of `f(a) − f(b)` over the masked pixels' three channels, summed like
/// [`mse_by`]; None below [`MASK_MIN_FRACTION`].
fn masked_psnr_by(
    a: &[f32],
    b: &[f32],
    mask: &PixelMask,
    f: impl Fn(f32) -> f64 + Sync,
) -> Option<f64> {
    if mask.count == 0 || mask.fraction() < MASK_MIN_FRACTION {
        return None;
    }
    const CHUNK: usize = 1 << 14;
    let sums: Vec<f64> = a
        .par_chunks(3 * CHUNK)
        .zip(b.par_chunks(3 * CHUNK))
        .zip(mask.mask.par_chunks(CHUNK))
        .map(|((ca, cb), cm)| {
            ca.chunks_exact(3)
                .zip(cb.chunks_exact(3))
                .zip(cm)
                .filter(|(_, m)| **m)
                .map(|((x, y), _)| {
                    (0..3)
                        .map(|c| {
                            let d = f(x[c]) - f(y[c]);
                            d * d
                        })
                        .sum::<f64>()
                })
                .sum::<f64>()
        })
        .collect();
    let mse = sums.iter().sum::<f64>() / (3 * mask.count) as f64;
    Some(psnr_from_mse(mse, 1.0))
}

/// Gaussian window radius: skimage's `int(truncate · sigma + 0.5)` with truncate 3.5, sigma 1.5;
/// equally MATLAB's `ceil(3 · sigma)`.
const RADIUS: usize = 5;
const SIGMA: f64 = 1.5;
/// Output rows per parallel task.
const BAND: usize = 64;

#[derive(Clone, Copy, Debug)]
enum Border {
    /// scipy.ndimage 'reflect' (half-sample symmetric, "dcba|abcd"), as skimage uses.
    Reflect,
    /// Edge value repeated, as MATLAB's ssim ('replicate') uses.
    Replicate,
}

struct SsimSpec {
    data_range: f64,
    border: Border,
    /// Pixels dropped on each side before averaging the SSIM map (skimage: (win − 1) / 2).
    crop: usize,
}

/// Half of scipy's normalised `_gaussian_kernel1d(1.5, 0, 5)`: taps 0..=5 from the centre.
fn gaussian_half() -> [f64; RADIUS + 1] {
    let s2 = SIGMA * SIGMA;
    let r = RADIUS as i64;
    let full: Vec<f64> = (-r..=r)
        .map(|x| (-0.5 / s2 * (x * x) as f64).exp())
        .collect();
    let sum: f64 = full.iter().sum();
    std::array::from_fn(|j| full[RADIUS + j] / sum)
}

/// Source index for position `i` (may be outside [0, n)) under a border rule; n > RADIUS.
#[inline]
fn border_index(i: isize, n: usize, border: Border) -> usize {
    let n = n as isize;
    let j = match border {
        Border::Reflect if i < 0 => -i - 1,
        Border::Reflect if i >= n => 2 * n - 1 - i,
        Border::Replicate => i.clamp(0, n - 1),
        Border::Reflect => i,
    };
    j as usize
}

/// skimage's SSIM of R, G and B separately (values mapped by `f`), averaged over channels.
fn ssim_rgb(gt: &Image, pred: &Image, f: impl Fn(f32) -> f64 + Sync) -> f64 {
    let spec = SsimSpec {
        data_range: 255.0,
        border: Border::Reflect,
        crop: RADIUS,
    };
    let per_channel: Vec<f64> = (0..3)
        .into_par_iter()
        .map(|c| {
            ssim_plane(
                gt.width,
                gt.height,
                &|p| f(gt.data[p * 3 + c]),
                &|p| f(pred.data[p * 3 + c]),
                &spec,
            )
        })
        .collect();
    per_channel.iter().sum::<f64>() / 3.0
}

/// Mean SSIM of one plane whose values at pixel index `y * w + x` are `fx(p)` and `fy(p)`.
/// Separable Gaussian (rows first, then columns, as scipy's gaussian_filter), in bands of rows
/// processed in parallel; the mean adds band sums in order, independent of the thread count.
fn ssim_plane<FX, FY>(w: usize, h: usize, fx: &FX, fy: &FY, spec: &SsimSpec) -> f64
where
    FX: Fn(usize) -> f64 + Sync,
    FY: Fn(usize) -> f64 + Sync,
{
    let k = gaussian_half();
    let bands: Vec<usize> = (0..h).step_by(BAND).collect();
    let sums: Vec<f64> = bands
        .par_iter()
        .map(|&r0| ssim_band(w, h, r0, (r0 + BAND).min(h), fx, fy, &k, spec))
        .collect();
    let n = (w - 2 * spec.crop) * (h - 2 * spec.crop);
    sums.iter().sum::<f64>() / n as f64
}

/// Sum of the SSIM map over output rows [r0, r1) and the uncropped columns.
#[allow(clippy::too_many_arguments)]
fn ssim_band<FX, FY>(
    w: usize,
    h: usize,
    r0: usize,
    r1: usize,
    fx: &FX,
    fy: &FY,
    k: &[f64; RADIUS + 1],
    spec: &SsimSpec,
) -> f64
where
    FX: Fn(usize) -> f64 + Sync,
    FY: Fn(usize) -> f64 + Sync,
{
    const R: usize = RADIUS;
    // A ring of the 2R + 1 input rows the current output row needs, each mapped once per band
    // (μ-law and PU are not cheap); small enough to stay in cache at 4032 wide.
    const TAPS: usize = 2 * R + 1;
    let mut xr = vec![0.0f64; TAPS * w];
    let mut yr = vec![0.0f64; TAPS * w];
    // Input rows are numbered from r0 − R; `loaded` of them are in the ring.
    let mut loaded = 0usize;
    let c1 = (0.01 * spec.data_range).powi(2);
    let c2 = (0.03 * spec.data_range).powi(2);
    // Vertically filtered rows with R border columns either side: x, y, xx, yy, xy.
    let wp = w + 2 * R;
    let mut vq: [Vec<f64>; 5] = std::array::from_fn(|_| vec![0.0; wp]);
    let mut hq: [Vec<f64>; 5] = std::array::from_fn(|_| vec![0.0; w]);
    let (col0, col1) = (spec.crop, w - spec.crop);
    let mut sum = 0.0;
    for i in 0..(r1 - r0) {
        let row = r0 + i;
        if row < spec.crop || row >= h - spec.crop {
            continue;
        }
        // Output row i needs input rows i ..= i + 2R (ring slot = number mod TAPS).
        loaded = loaded.max(i);
        while loaded <= i + 2 * R {
            let s = border_index(r0 as isize - R as isize + loaded as isize, h, spec.border) * w;
            let slot = (loaded % TAPS) * w;
            for c in 0..w {
                xr[slot + c] = fx(s + c);
                yr[slot + c] = fy(s + c);
            }
            loaded += 1;
        }
        let at = |t: usize| (t % TAPS) * w;
        // Vertical pass, in scipy's order: centre tap, then pairs from the outermost in.
        {
            // Slices of exactly w so the loops below carry no bounds checks and vectorise.
            let [mx, my, mxx, myy, mxy] = vq.each_mut().map(|v| &mut v[R..][..w]);
            let xc = &xr[at(i + R)..][..w];
            let yc = &yr[at(i + R)..][..w];
            let k0 = k[0];
            for c in 0..w {
                let (a, b) = (xc[c], yc[c]);
                mx[c] = a * k0;
                my[c] = b * k0;
                mxx[c] = (a * a) * k0;
                myy[c] = (b * b) * k0;
                mxy[c] = (a * b) * k0;
            }
            for j in (1..=R).rev() {
                let kj = k[j];
                let xu = &xr[at(i + R - j)..][..w];
                let xd = &xr[at(i + R + j)..][..w];
                let yu = &yr[at(i + R - j)..][..w];
                let yd = &yr[at(i + R + j)..][..w];
                for c in 0..w {
                    let (a1, a2, b1, b2) = (xu[c], xd[c], yu[c], yd[c]);
                    mx[c] += (a1 + a2) * kj;
                    my[c] += (b1 + b2) * kj;
                    mxx[c] += (a1 * a1 + a2 * a2) * kj;
                    myy[c] += (b1 * b1 + b2 * b2) * kj;
                    mxy[c] += (a1 * b1 + a2 * b2) * kj;
                }
            }
        }
        // Border columns, then the horizontal pass.
        for (v, o) in vq.iter_mut().zip(hq.iter_mut()) {
            for t in 0..R {
                v[t] = v[R + border_index(t as isize - R as isize, w, spec.border)];
                v[R + w + t] = v[R + border_index((w + t) as isize, w, spec.border)];
            }
            let o = &mut o[..w];
            let centre = &v[R..][..w];
            for c in 0..w {
                o[c] = centre[c] * k[0];
            }
            for j in (1..=R).rev() {
                let kj = k[j];
                let (left, right) = (&v[R - j..][..w], &v[R + j..][..w]);
                for c in 0..w {
                    o[c] += (left[c] + right[c]) * kj;
                }
            }
        }
        // skimage's expression, term for term (use_sample_covariance=False).
        let [ux, uy, uxx, uyy, uxy] = hq.each_ref().map(|v| &v[..w]);
        let mut row_sum = 0.0;
        for c in col0..col1 {
            let (ux, uy) = (ux[c], uy[c]);
            let vx = uxx[c] - ux * ux;
            let vy = uyy[c] - uy * uy;
            let vxy = uxy[c] - ux * uy;
            let a1 = 2.0 * ux * uy + c1;
            let a2 = 2.0 * vxy + c2;
            let b1 = ux * ux + uy * uy + c1;
            let b2 = vx + vy + c2;
            row_sum += (a1 * a2) / (b1 * b2);
        }
        sum += row_sum;
    }
    sum
}
