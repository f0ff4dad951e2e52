//! Network-1's output stage: blend map → weight of the long exposure → Laplacian-pyramid blend
//! of the two input frames (the data pipeline's pyramid code) → exponential tone curve.
//!
//! - Weight from class probabilities: the expected class, w = Σ_c p_c · c / 255 (default; smooth
//!   where the network is unsure), or the argmax class / 255.
//! - The fused frame before the curve is the "linear" (L) output of the metrics; after the
//!   curve, the "tone-mapped" (T) output.
//! - Tone curve: T(x) = (1 − e^(−k·x)) / (1 − e^(−k)) for x ≥ 0 (k > 0; T(0) = 0, T(1) = 1,
//!   slope k/(1 − e^(−k)) at 0: k lifts shadows); k = 0 means identity.

use crate::data::pyramid::laplacian_blend;
use crate::error::{Error, Result};
use crate::io::Image;

/// Default k of the tone curve. The paper names an exponential curve without its parameter;
/// k = 2 lifts the darkest tones 2.3× (slope k/(1 − e^−k) at 0) and leaves T(1) = 1.
pub const DEFAULT_TONE_K: f32 = 2.0;

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
#[serde(rename_all = "lowercase")]
pub enum BlendWeight {
    /// Σ_c p_c · c / 255.
    #[default]
    Expected,
    /// argmax_c p_c / 255.
    Argmax,
}

/// Long-exposure weight per pixel from class probabilities laid out C×H×W (C = 256).
pub fn weight_from_probabilities(
    probs: &[f32],
    classes: usize,
    pixels: usize,
    mode: BlendWeight,
) -> Result<Vec<f32>> {
    if classes < 2 || probs.len() != classes * pixels {
        return Err(Error::Invalid(format!(
            "blend map: {} values for {classes} classes × {pixels} pixels",
            probs.len()
        )));
    }
    let top = (classes - 1) as f32;
    Ok((0..pixels)
        .map(|p| match mode {
            BlendWeight::Expected => {
                (0..classes)
                    .map(|c| probs[c * pixels + p] * c as f32)
                    .sum::<f32>()
                    / top
            }
            BlendWeight::Argmax => {
                let best = (0..classes)
                    .max_by(|&a, &b| probs[a * pixels + p].total_cmp(&probs[b * pixels + p]))
                    .unwrap_or(0);
                best as f32 / top
            }
        })
        .collect())
}

/// Long-exposure weight per pixel straight from class logits laid out C×H×W: the softmax's
/// expected class (or the argmax) / (C − 1), computed on the host in f32 with the usual max
/// subtraction. Same result as softmax followed by [`weight_from_probabilities`], without
/// materialising the C×H×W probabilities: at 256 classes the on-device softmax cost more than
/// the whole U-Net forward.
pub fn weight_from_logits(
    logits: &[f32],
    classes: usize,
    pixels: usize,
    mode: BlendWeight,
) -> Result<Vec<f32>> {
    use rayon::prelude::*;
    if classes < 2 || logits.len() != classes * pixels {
        return Err(Error::Invalid(format!(
            "blend map: {} logits for {classes} classes × {pixels} pixels",
            logits.len()
        )));
    }
    let top = (classes - 1) as f32;
    let mut out = vec![0.0f32; pixels];
    // Pixel chunks in parallel; inside a chunk the class loop is outer so the inner loop runs
    // over contiguous memory.
    const CHUNK: usize = 4096;
    out.par_chunks_mut(CHUNK).enumerate().for_each(|(k, w)| {
        let p0 = k * CHUNK;
        let n = w.len();
        let plane = |c: usize| &logits[c * pixels + p0..c * pixels + p0 + n];
        let mut best = plane(0).to_vec();
        let mut arg = vec![0u32; n];
        for c in 1..classes {
            for ((b, a), &z) in best.iter_mut().zip(&mut arg).zip(plane(c)) {
                if z > *b {
                    *b = z;
                    *a = c as u32;
                }
            }
        }
        match mode {
            BlendWeight::Argmax => {
                for (o, &a) in w.iter_mut().zip(&arg) {
                    *o = a as f32 / top;
                }
            }
            BlendWeight::Expected => {
                let (mut s0, mut s1) = (vec![0.0f32; n], vec![0.0f32; n]);
                for c in 0..classes {
                    let cf = c as f32;
                    for (((z, m), a), b) in plane(c).iter().zip(&best).zip(&mut s0).zip(&mut s1) {
                        let e = (z - m).exp();
                        *a += e;
                        *b += e * cf;
                    }
                }
                for ((o, a), b) in w.iter_mut().zip(&s0).zip(&s1) {
                    *o = b / a / top;
                }
            }
        }
    });
    Ok(out)
}

/// The exponential tone curve (module docs).
#[inline]
pub fn tone_curve(x: f32, k: f32) -> f32 {
    if k == 0.0 {
        return x;
    }
    (1.0 - (-k * x.max(0.0)).exp()) / (1.0 - (-k).exp())
}

/// Laplacian-pyramid blend of the (low, high) frames with per-pixel long-exposure weights
/// (the low frame gets 1 − w): the output stage's L.
pub fn blend_pair(low: &Image, high: &Image, w_high: &[f32]) -> Result<Image> {
    let w_low: Vec<f32> = w_high.iter().map(|w| 1.0 - w).collect();
    laplacian_blend(&[low.clone(), high.clone()], &[w_low, w_high.to_vec()])
}

/// Fuse the (low, high) frames with per-pixel long-exposure weights: (L, T) outputs.
pub fn fuse(low: &Image, high: &Image, w_high: &[f32], k: f32) -> Result<(Image, Image)> {
    let linear = blend_pair(low, high, w_high)?;
    let toned = linear.map(|v| tone_curve(v, k));
    Ok((linear, toned))
}
