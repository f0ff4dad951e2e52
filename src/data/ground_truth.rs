//! Ground truth for training: Mertens exposure fusion exactly as OpenCV's `MergeMertens` computes
//! it, the 256-class blend maps of Network-1 (class = round(255 · w_high)), class frequencies
//! and inverse-frequency class weights (paper Eq. 4), and the triangle-weight HDR merge.
//! Conventions and every OpenCV deviation from the Mertens paper that is copied here:
//! docs/ground_truth.md.
//!
//! Frames are [`Image`]s of LDR code values in [0, 1] (8-bit PNG / 255), RGB. OpenCV sees the
//! same bytes as BGR; where the channel order matters (the grey conversion) this module applies
//! OpenCV's coefficients to the channels OpenCV would apply them to.

use super::pyramid::{laplacian_blend, reflect101};
use crate::config::{KeyError, Range, each_in_range, in_range};
use crate::error::{Error, Result};
use crate::io::atomic::write_atomic;
use crate::io::{BitDepth, Image, read_image_info, write_ldr};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Number of blend classes (8-bit class maps).
pub const CLASSES: usize = 256;
/// Per-set class map file name (next to the set's frames).
pub const CLASS_MAP_FILE: &str = "blend_classes.png";
/// Class weights file at the dataset root.
pub const CLASS_WEIGHTS_FILE: &str = "class_weights.toml";
/// `format` of [`ClassWeights`] files.
pub const CLASS_WEIGHTS_FORMAT: &str = "hdrsynth-class-weights/1";
/// Additive smoothing: counts added to every class before inverting (keeps empty classes finite).
pub const SMOOTHING: f64 = 1.0;

/// OpenCV's `RGB2GRAY` coefficients (for channels 0, 1, 2 of the array it is given).
const GREY: [f32; 3] = [0.299, 0.587, 0.114];
/// Well-exposedness: exp(−(v − 0.5)² / 0.08), i.e. σ = 0.2 (OpenCV and the paper).
const WELL_EXPOSED_DENOM: f32 = 0.08;
/// Added to every weight before normalising (OpenCV: `+ 1e-12f`).
const WEIGHT_EPS: f32 = 1e-12;

/// Exponents of Mertens' three quality measures: weight = C^contrast · S^saturation ·
/// E^exposure (+1e-12).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MertensWeights {
    pub contrast: f32,
    pub saturation: f32,
    pub exposure: f32,
}

impl MertensWeights {
    /// `cv2.createMergeMertens()` defaults: contrast 1, saturation 1, exposure 0.
    pub const OPENCV_DEFAULT: MertensWeights = MertensWeights {
        contrast: 1.0,
        saturation: 1.0,
        exposure: 0.0,
    };
    /// Mertens et al. 2007: all three measures with exponent 1.
    pub const PAPER: MertensWeights = MertensWeights {
        contrast: 1.0,
        saturation: 1.0,
        exposure: 1.0,
    };
}

impl Default for MertensWeights {
    /// The OpenCV defaults ([`MertensWeights::OPENCV_DEFAULT`]): the blend classes use these.
    fn default() -> Self {
        MertensWeights::OPENCV_DEFAULT
    }
}

pub fn check_frames(what: &str, frames: &[&Image]) -> Result<(usize, usize)> {
    let Some(first) = frames.first() else {
        return Err(Error::Invalid(format!("{what}: no frames")));
    };
    let (w, h) = (first.width, first.height);
    for (i, f) in frames.iter().enumerate() {
        if (f.width, f.height) != (w, h) {
            return Err(Error::Invalid(format!(
                "{what}: frame {i} is {}×{}, frame 0 is {w}×{h}",
                f.width, f.height
            )));
        }
    }
    Ok((w, h))
}

/// `cv::pow` for the non-negative measures: exponent 0 gives 1 (also for 0^0), 1 the value.
#[inline]
fn pow(v: f32, e: f32) -> f32 {
    if e == 0.0 {
        1.0
    } else if e == 1.0 {
        v
    } else {
        v.powf(e)
    }
}

/// OpenCV's float for an 8-bit code value: `convertTo(CV_32F, 1/255.)` multiplies by 1/255 as
/// f32 and rounds once, which differs from `code / 255` by one ulp for 126 of the 256 codes.
/// Values within 1e-3 of a code (8-bit frames read as code / 255) are snapped to OpenCV's float;
/// anything else (16-bit code values, linear data) is returned unchanged.
#[inline]
pub fn opencv_code_value(v: f32) -> f32 {
    let scaled = v * 255.0;
    let code = scaled.round();
    if (0.0..=255.0).contains(&code) && (scaled - code).abs() < 1e-3 {
        code * INV_255
    } else {
        v
    }
}

/// 1/255 as OpenCV passes it to `convertTo` (a double rounded to f32).
const INV_255: f32 = (1.0f64 / 255.0) as f32;
/// 1/3 as OpenCV's `mean /= 3` applies it (`convertTo` with alpha = 1./3 as f32).
const INV_3: f32 = (1.0f64 / 3.0) as f32;
/// −1/0.08 as OpenCV's `-expo / 0.08f` applies it (a `convertTo` alpha, f32): −12.5.
const NEG_INV_WELL: f32 = (-1.0f64 / WELL_EXPOSED_DENOM as f64) as f32;

/// [`opencv_code_value`] of every sample: the frame as MergeMertens holds it after
/// `convertTo(CV_32F, 1/255.)`.
pub fn opencv_frame(img: &Image) -> Image {
    Image {
        width: img.width,
        height: img.height,
        data: img.data.par_iter().map(|&v| opencv_code_value(v)).collect(),
    }
}

/// Un-normalised Mertens weight of every pixel of one frame, as MergeMertens computes it:
/// |Laplacian(grey)|^c · saturation^s · well-exposedness^e + 1e-12, with the samples first
/// mapped by [`opencv_code_value`].
///
/// Bit-exact with OpenCV 5.0 (x86-64 wheels) in the parts where a rounding can flip a weight
/// between the 1e-12 floor and a tiny positive value (exact zeros of the contrast and the
/// saturation): the grey conversion uses OpenCV's SIMD order
/// `fma(ch2, 0.114, fma(ch0, 0.299, ch1 · 0.587))` on OpenCV's channels (ch0 = our blue), the
/// Laplacian sums the taps in filter2D's order `((up + left) + (−4·centre)) + right) + down`,
/// the channel mean is `((B + G) + R) · f32(1/3)` and the squared deviations add in the order
/// B, G, R. Such flips, at pixels where all frames have almost no weight, are what moves
/// OpenCV's output by up to 0.09 (docs/ground_truth.md).
pub fn raw_weights(img: &Image, w: MertensWeights) -> Vec<f32> {
    let (wd, ht) = (img.width, img.height);
    if wd == 0 || ht == 0 {
        return Vec::new();
    }
    let cv = opencv_frame(img);
    // OpenCV gets BGR bytes and converts with COLOR_RGB2GRAY: 0.299 goes to its channel 0,
    // which is our blue; grey = 0.299·B + 0.587·G + 0.114·R, in OpenCV's fma order.
    let grey: Vec<f32> = cv
        .data
        .par_chunks_exact(3)
        .map(|p| p[0].mul_add(GREY[2], p[2].mul_add(GREY[0], p[1] * GREY[1])))
        .collect();
    let mut out = vec![0f32; wd * ht];
    out.par_chunks_mut(wd).enumerate().for_each(|(y, row)| {
        let yi = y as isize;
        let up = &grey[reflect101(yi - 1, ht) * wd..][..wd];
        let mid = &grey[y * wd..][..wd];
        let down = &grey[reflect101(yi + 1, ht) * wd..][..wd];
        let px = &cv.data[y * wd * 3..(y + 1) * wd * 3];
        for (x, o) in row.iter_mut().enumerate() {
            let xi = x as isize;
            let l = mid[reflect101(xi - 1, wd)];
            let r = mid[reflect101(xi + 1, wd)];
            // Laplacian ksize=1: [0 1 0; 1 −4 1; 0 1 0], BORDER_REFLECT_101, filter2D's order.
            let contrast = ((((up[x] + l) + (-4.0 * mid[x])) + r) + down[x]).abs();
            // OpenCV's channel order: B, G, R.
            let bgr = [px[x * 3 + 2], px[x * 3 + 1], px[x * 3]];
            let mean = ((bgr[0] + bgr[1]) + bgr[2]) * INV_3;
            // Standard deviation over the channels without the 1/3 (OpenCV).
            let mut sq = 0f32;
            let mut well_exposed = 1f32;
            for &c in &bgr {
                let d = c - mean;
                sq += d * d;
                let e = c - 0.5;
                well_exposed *= ((e * e) * NEG_INV_WELL).exp();
            }
            let saturation = sq.sqrt();
            *o = pow(contrast, w.contrast)
                * pow(saturation, w.saturation)
                * pow(well_exposed, w.exposure)
                + WEIGHT_EPS;
        }
    });
    out
}

/// Per-frame Mertens weights normalised to sum 1 at every pixel (MergeMertens' `weights[i] /=
/// weight_sum`). Errors on no frames or differing sizes.
pub fn mertens_weights(frames: &[Image], w: MertensWeights) -> Result<Vec<Vec<f32>>> {
    let refs: Vec<&Image> = frames.iter().collect();
    check_frames("mertens", &refs)?;
    let mut raw: Vec<Vec<f32>> = frames.par_iter().map(|f| raw_weights(f, w)).collect();
    let n = raw[0].len();
    let mut sum = vec![0f32; n];
    for r in &raw {
        for (s, v) in sum.iter_mut().zip(r) {
            *s += v;
        }
    }
    for r in &mut raw {
        r.par_iter_mut().zip(&sum).for_each(|(v, s)| *v /= s);
    }
    Ok(raw)
}

/// Mertens exposure fusion as `cv2.createMergeMertens(contrast_w, saturation_w,
/// exposure_w).process(frames)`: normalised [`mertens_weights`], then Laplacian-pyramid
/// blending ([`laplacian_blend`]). Frames: code values in [0, 1], RGB, any order. The result
/// is not clipped (OpenCV's is not either; it can leave [0, 1] slightly). Errors on no frames
/// or differing sizes.
pub fn mertens(
    frames: &[Image],
    contrast_w: f32,
    saturation_w: f32,
    exposure_w: f32,
) -> Result<Image> {
    let w = MertensWeights {
        contrast: contrast_w,
        saturation: saturation_w,
        exposure: exposure_w,
    };
    let weights = mertens_weights(frames, w)?;
    let cv: Vec<Image> = frames.iter().map(opencv_frame).collect();
    laplacian_blend(&cv, &weights)
}

/// Per-pixel normalised Mertens weight w_high ∈ [0, 1] of the long exposure `high` in the pair
/// (`low`, `high`) (the paper's EV−3 and EV0 frames), with the OpenCV default exponents
/// (contrast 1, saturation 1, exposure 0). Full resolution, no pyramid.
pub fn blend_weights_high(low: &Image, high: &Image) -> Result<Vec<f32>> {
    blend_weights_high_with(low, high, MertensWeights::OPENCV_DEFAULT)
}

/// [`blend_weights_high`] with explicit exponents.
pub fn blend_weights_high_with(low: &Image, high: &Image, w: MertensWeights) -> Result<Vec<f32>> {
    check_frames("blend weights", &[low, high])?;
    let (wl, wh) = rayon::join(|| raw_weights(low, w), || raw_weights(high, w));
    Ok(wl.par_iter().zip(&wh).map(|(&l, &h)| h / (l + h)).collect())
}

/// Class of each weight: round(255 · w_high), clamped to 0..=255. Class 0: the long exposure
/// gets no weight (saturated there); 255: all weight on it (the short one is underexposed).
pub fn classes_from_weights(w_high: &[f32]) -> Vec<u8> {
    w_high
        .par_iter()
        .map(|&w| (255.0 * w).round().clamp(0.0, 255.0) as u8)
        .collect()
}

/// Blend classes of the pair (`low`, `high`): [`classes_from_weights`] of
/// [`blend_weights_high`] (OpenCV default exponents).
pub fn blend_classes(low: &Image, high: &Image) -> Result<Vec<u8>> {
    Ok(classes_from_weights(&blend_weights_high(low, high)?))
}

/// Separable Gaussian blur of a `width`×`height` map (row-major): taps exp(−k²/(2σ²)) for
/// |k| ≤ ⌈3σ⌉, normalised to sum 1, borders reflect-101 (OpenCV's default). σ ≤ 0 returns the
/// map unchanged. Used to smooth blend-map targets (see [`blend_weights_high_smoothed`]).
pub fn gaussian_blur(map: &[f32], width: usize, height: usize, sigma: f32) -> Vec<f32> {
    assert_eq!(
        map.len(),
        width * height,
        "gaussian_blur: {} values for {width}×{height}",
        map.len()
    );
    if sigma.is_nan() || sigma <= 0.0 || map.is_empty() {
        return map.to_vec();
    }
    let r = (3.0 * sigma).ceil() as isize;
    let taps: Vec<f64> = (-r..=r)
        .map(|k| (-((k * k) as f64) / (2.0 * (sigma as f64).powi(2))).exp())
        .collect();
    let sum: f64 = taps.iter().sum();
    let taps: Vec<f32> = taps.iter().map(|t| (t / sum) as f32).collect();
    let mut rows = vec![0f32; map.len()];
    rows.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        let src = &map[y * width..][..width];
        for (x, o) in row.iter_mut().enumerate() {
            *o = (-r..=r)
                .zip(&taps)
                .map(|(k, t)| t * src[reflect101(x as isize + k, width)])
                .sum();
        }
    });
    let mut out = vec![0f32; map.len()];
    out.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            *o = (-r..=r)
                .zip(&taps)
                .map(|(k, t)| t * rows[reflect101(y as isize + k, height) * width + x])
                .sum();
        }
    });
    out
}

/// [`blend_weights_high`] with each frame's raw Mertens weight Gaussian-blurred (σ pixels,
/// [`gaussian_blur`]) before normalising: w = G_σ∗W_high / (G_σ∗W_low + G_σ∗W_high). Blurring
/// the raw weights rather than the ratio lets a neighbourhood's well-exposed, textured pixels
/// decide, so near-grey or flat pixels (both weights ≈ 1e-12, where the per-pixel ratio flips
/// between 0 and 1 on a rounding) take their neighbours' weight. σ = 0: the per-pixel weights.
pub fn blend_weights_high_smoothed(low: &Image, high: &Image, sigma: f32) -> Result<Vec<f32>> {
    check_frames("blend weights", &[low, high])?;
    let w = MertensWeights::OPENCV_DEFAULT;
    let (wl, wh) = rayon::join(|| raw_weights(low, w), || raw_weights(high, w));
    Ok(smoothed_ratio(&wl, &wh, low.width, low.height, sigma))
}

/// G_σ∗`high` / (G_σ∗`low` + G_σ∗`high`) per pixel, for two raw weight maps (> 0).
pub fn smoothed_ratio(
    low: &[f32],
    high: &[f32],
    width: usize,
    height: usize,
    sigma: f32,
) -> Vec<f32> {
    let (l, h) = rayon::join(
        || gaussian_blur(low, width, height, sigma),
        || gaussian_blur(high, width, height, sigma),
    );
    l.par_iter().zip(&h).map(|(&l, &h)| h / (l + h)).collect()
}

/// Blend classes of the pair with targets smoothed by σ pixels
/// ([`blend_weights_high_smoothed`]); σ = 0 is exactly [`blend_classes`] (the paper's).
pub fn blend_classes_smoothed(low: &Image, high: &Image, sigma: f32) -> Result<Vec<u8>> {
    if sigma > 0.0 {
        Ok(classes_from_weights(&blend_weights_high_smoothed(
            low, high, sigma,
        )?))
    } else {
        blend_classes(low, high)
    }
}

/// Write a class map as an 8-bit PNG, grey replicated to RGB (code value = class), atomically.
pub fn write_class_map(path: &Path, classes: &[u8], width: usize, height: usize) -> Result<()> {
    if classes.len() != width * height {
        return Err(Error::encode(
            path,
            format!(
                "class map has {} values for {width}×{height} pixels",
                classes.len()
            ),
        ));
    }
    let data = classes
        .iter()
        .flat_map(|&c| [c as f32 / 255.0; 3])
        .collect();
    write_ldr(path, &Image::from_vec(width, height, data), BitDepth::Eight)
}

/// Read a class map written by [`write_class_map`]: (classes, width, height). The file must be
/// an 8-bit PNG with equal channels.
pub fn read_class_map(path: &Path) -> Result<(Vec<u8>, usize, usize)> {
    let (img, info) = read_image_info(path)?;
    if info.bit_depth != Some(BitDepth::Eight) {
        return Err(Error::unsupported(
            path,
            "class maps are 8-bit PNGs (code value = class)",
        ));
    }
    let mut classes = Vec::with_capacity(img.pixel_count());
    for (i, p) in img.pixels().enumerate() {
        if p[0] != p[1] || p[0] != p[2] {
            return Err(Error::decode(
                path,
                format!(
                    "class map pixel x={}, y={} is not grey",
                    i % img.width,
                    i / img.width
                ),
            ));
        }
        classes.push((p[0] * 255.0).round() as u8);
    }
    Ok((classes, img.width, img.height))
}

/// Count of every class over any number of class maps.
pub fn class_histogram<I>(maps: I) -> [u64; CLASSES]
where
    I: IntoIterator,
    I::Item: AsRef<[u8]>,
{
    let mut h = [0u64; CLASSES];
    for m in maps {
        for &c in m.as_ref() {
            h[c as usize] += 1;
        }
    }
    h
}

/// Inverse-frequency class weights (paper Eq. 4): α_i = k / (n_i + 1) (one count of additive
/// smoothing, so empty classes stay finite: they get the largest α), with k such that
/// Σ_i α_i · p_i = 1 for the observed frequencies p_i = n_i / N: the mean weight per training
/// pixel is 1 and the weighted loss keeps the scale of the unweighted one. α is strictly
/// decreasing in n_i. With no pixels at all every α is 1.
pub fn class_alpha(hist: &[u64; CLASSES]) -> [f64; CLASSES] {
    let total: u64 = hist.iter().sum();
    if total == 0 {
        return [1.0; CLASSES];
    }
    let n = total as f64;
    let denom: f64 = hist
        .iter()
        .map(|&c| c as f64 / (c as f64 + SMOOTHING))
        .sum();
    let k = n / denom;
    let mut a = [0f64; CLASSES];
    for (ai, &c) in a.iter_mut().zip(hist) {
        *ai = k / (c as f64 + SMOOTHING);
    }
    a
}

/// A dataset's class statistics and weights, saved as `DIR/class_weights.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClassWeights {
    /// [`CLASS_WEIGHTS_FORMAT`].
    pub format: String,
    /// Exponents of the Mertens weights behind the class maps.
    pub mertens: MertensWeights,
    /// Counts added to every class before inverting.
    pub smoothing: f64,
    /// How α is normalised (a sentence, for readers of the file).
    pub normalisation: String,
    /// Sets whose class maps were counted.
    pub sets: usize,
    /// Pixels counted (Σ counts).
    pub pixels: u64,
    /// Pixels per class, 256 values.
    pub counts: Vec<u64>,
    /// α per class, 256 values.
    pub alpha: Vec<f64>,
}

impl ClassWeights {
    pub fn new(hist: &[u64; CLASSES], mertens: MertensWeights, sets: usize) -> ClassWeights {
        ClassWeights {
            format: CLASS_WEIGHTS_FORMAT.into(),
            mertens,
            smoothing: SMOOTHING,
            normalisation:
                "alpha_i = k / (count_i + smoothing), sum_i alpha_i * count_i / pixels = 1".into(),
            sets,
            pixels: hist.iter().sum(),
            counts: hist.to_vec(),
            alpha: class_alpha(hist).to_vec(),
        }
    }

    /// Classes with no pixel.
    pub fn empty_classes(&self) -> Vec<usize> {
        (0..self.counts.len())
            .filter(|&i| self.counts[i] == 0)
            .collect()
    }

    /// Write as TOML, atomically.
    pub fn save(&self, path: &Path) -> Result<()> {
        let text = toml::to_string(self).map_err(|e| Error::encode(path, e))?;
        write_atomic(path, text.as_bytes())
    }

    /// Read and check: format, 256 counts and 256 finite positive α.
    pub fn load(path: &Path) -> Result<ClassWeights> {
        let text = crate::io::guard::read_text(path)?;
        Self::parse(&text, path)
    }

    /// The file's text, checked as [`ClassWeights::load`] checks `path` (named in errors).
    pub fn parse(text: &str, path: &Path) -> Result<ClassWeights> {
        crate::config::parse_checked(text, path, ClassWeights::validate)
    }

    /// Format, 256 counts and 256 α > 0, smoothing and Mertens exponents ≥ 0.
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        if self.format != CLASS_WEIGHTS_FORMAT {
            return Err(KeyError::new(
                "format",
                format!("'{}' is not '{CLASS_WEIGHTS_FORMAT}'", self.format),
            ));
        }
        for (key, n) in [("counts", self.counts.len()), ("alpha", self.alpha.len())] {
            if n != CLASSES {
                return Err(KeyError::new(
                    key,
                    format!("has {n} values, needs one per class ({CLASSES})"),
                ));
            }
        }
        each_in_range("alpha", &self.alpha, Range::POSITIVE)?;
        in_range("smoothing", self.smoothing, Range::NON_NEGATIVE)?;
        let m = &self.mertens;
        for (key, v) in [
            ("mertens.contrast", m.contrast),
            ("mertens.saturation", m.saturation),
            ("mertens.exposure", m.exposure),
        ] {
            in_range(key, v, Range::NON_NEGATIVE)?;
        }
        Ok(())
    }
}

/// Triangle-weight merge of a 3-exposure bracket (short, reference, long) into linear HDR:
/// H_i = L_i^γ / t_i per channel, weights from the middle frame's value I of that channel:
/// short max(0, I − ½)/½, middle I/½ below ½ else (1 − I)/½, long max(0, ½ − I)/½;
/// merged = Σ w·H / Σ w (the weights sum to 1 for I in [0, 1]; where Σ w ≤ 0, i.e. I outside
/// [0, 1], the middle frame's H is used). Computed in f64. Errors on differing sizes.
pub fn triangle_merge(frames: &[Image; 3], times: [f32; 3], gamma: f32) -> Result<Image> {
    let g = gamma as f64;
    triangle_merge_with(frames, times, |v| v.powf(g))
}

/// [`triangle_merge`] with any linearisation of the code values (a device's inverse response
/// instead of L^γ); the weights come from the middle frame's code value as there.
pub fn triangle_merge_with(
    frames: &[Image; 3],
    times: [f32; 3],
    linear: impl Fn(f64) -> f64 + Sync,
) -> Result<Image> {
    triangle_merge_weighted(frames, &frames[1], times, linear)
}

/// [`triangle_merge_with`] with the weights from `reference`'s values instead of the middle
/// frame's: the reference as the inputs store it, where `frames` encode the same light
/// another way (a test set's merge codes beside inputs written in the device's codes).
pub fn triangle_merge_weighted(
    frames: &[Image; 3],
    reference: &Image,
    times: [f32; 3],
    linear: impl Fn(f64) -> f64 + Sync,
) -> Result<Image> {
    let (w, h) = check_frames(
        "triangle merge",
        &[&frames[0], &frames[1], &frames[2], reference],
    )?;
    if times.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(Error::Invalid(format!(
            "triangle merge: exposure times {times:?} must be finite and positive"
        )));
    }
    let t = times.map(|t| t as f64);
    let data = frames[0]
        .data
        .par_iter()
        .zip(&frames[1].data)
        .zip(&frames[2].data)
        .zip(&reference.data)
        .map(|(((&l0, &l1), &l2), &r)| {
            let i = r as f64;
            let hdr = [
                linear(l0 as f64) / t[0],
                linear(l1 as f64) / t[1],
                linear(l2 as f64) / t[2],
            ];
            let wt = [
                (i - 0.5).max(0.0) / 0.5,
                if i < 0.5 { i / 0.5 } else { (1.0 - i) / 0.5 },
                (0.5 - i).max(0.0) / 0.5,
            ];
            let sw = wt[0] + wt[1] + wt[2];
            if sw > 0.0 {
                ((wt[0] * hdr[0] + wt[1] * hdr[1] + wt[2] * hdr[2]) / sw) as f32
            } else {
                hdr[1] as f32
            }
        })
        .collect();
    Ok(Image::from_vec(w, h, data))
}
