//! Losses and batch assembly for training.
//!
//! Network-1 (paper Eq. 4): the class-weighted L1 distance between the predicted class
//! distribution and the one-hot target, per pixel
//!
//! ```text
//!   ℓᵢ = α[tᵢ] · Σ_c |p_c(i) − 1[c = tᵢ]|,      L = mean over batch and pixels of ℓᵢ
//! ```
//!
//! with α the inverse-frequency class weights of `data::ground_truth::ClassWeights`. Because
//! the probabilities sum to 1, Σ_c |p_c − onehot_c| = (1 − p_t) + Σ_{c≠t} p_c = 2(1 − p_t):
//! [`weighted_l1`] uses that closed form (one gather instead of a B×C×H×W one-hot);
//! [`weighted_l1_explicit`] is the literal sum. Their gradients through a softmax agree too
//! (the softmax Jacobian annihilates the constant vector), so either can train.
//! The mean divides by the pixel count B·H·W, not by Σα.

use crate::data::ground_truth::{CLASSES, ClassWeights};
use crate::data::loader::{Sample, Target};
use crate::error::{Error, Result};
use burn::tensor::activation::{log_softmax, softmax};
use burn::tensor::{Device, Int, Tensor, TensorData};

fn check_shapes(probs: &Tensor<4>, target: &Tensor<3, Int>, alpha: &Tensor<1>) -> [usize; 4] {
    let [b, c, h, w] = probs.dims();
    let [tb, th, tw] = target.dims();
    let [ac] = alpha.dims();
    assert!(
        tb == b && th == h && tw == w,
        "Network-1 loss: target is {tb}×{th}×{tw}, probabilities are {b}×{c}×{h}×{w}"
    );
    assert!(
        ac == c,
        "Network-1 loss: alpha has {ac} entries for {c} classes"
    );
    [b, c, h, w]
}

/// α of each pixel's target class, [B, 1, H, W].
fn alpha_of_target(
    target: Tensor<3, Int>,
    alpha: Tensor<1>,
    [b, _, h, w]: [usize; 4],
) -> Tensor<4> {
    alpha
        .select(0, target.reshape([b * h * w]))
        .reshape([b, 1, h, w])
}

/// Paper Eq. 4 via the closed form 2·(1 − p_target): `probs` [B, C, H, W] (a softmax over dim
/// 1), `target` [B, H, W] class indices in 0..C, `alpha` [C]. Returns the scalar loss, shape [1].
///
/// # Panics
/// On mismatched shapes. Class indices outside 0..C are not checked here (the batch builders
/// produce u8 classes, and C = 256).
pub fn weighted_l1(probs: Tensor<4>, target: Tensor<3, Int>, alpha: Tensor<1>) -> Tensor<1> {
    let dims = check_shapes(&probs, &target, &alpha);
    let p_t = probs.gather(1, target.clone().unsqueeze_dim::<4>(1));
    let a_t = alpha_of_target(target, alpha, dims);
    (p_t.neg().add_scalar(1.0).mul_scalar(2.0) * a_t).mean()
}

/// Paper Eq. 4 literally: α[t] · Σ_c |p_c − onehot_c|, averaged over batch and pixels. Same
/// arguments and result as [`weighted_l1`] for probabilities that sum to 1; builds a
/// B×C×H×W one-hot, so it is the slower of the two.
pub fn weighted_l1_explicit(
    probs: Tensor<4>,
    target: Tensor<3, Int>,
    alpha: Tensor<1>,
) -> Tensor<1> {
    let dims = check_shapes(&probs, &target, &alpha);
    let onehot = target
        .clone()
        .one_hot_fill::<4>(dims[1], 1.0, 0.0, 1)
        .float();
    let l1 = (probs - onehot).abs().sum_dim(1);
    let a_t = alpha_of_target(target, alpha, dims);
    (l1 * a_t).mean()
}

pub use crate::kernels::fused_loss::Network1Reading;

/// The class index of every class as a weight c/(C−1), shaped [1, C, 1, 1].
fn class_levels(c: usize, device: &Device) -> Tensor<4> {
    let levels: Vec<f32> = (0..c).map(|k| k as f32 / (c - 1).max(1) as f32).collect();
    Tensor::<1>::from_data(TensorData::new(levels, [c]), device).reshape([1, c as i32, 1, 1])
}

/// Expected blend weight Σ_c p_c·c/(C−1) of `probs` [B, C, H, W]: [B, H, W].
pub fn expected_weight(probs: Tensor<4>) -> Tensor<3> {
    let [_, c, _, _] = probs.dims();
    let levels = class_levels(c, &probs.device());
    (probs * levels).sum_dim(1).squeeze_dim::<3>(1)
}

/// Ordinal reading: α_t · |Σ_c p_c·c/(C−1) − t/(C−1)| averaged over batch and pixels. Same
/// arguments as [`weighted_l1`]. The gradient with respect to p_c is ±α_t·c/(C−1): every
/// class gets one, not only the target (whose p_t may be ≈ 1/256).
pub fn ordinal_l1(probs: Tensor<4>, target: Tensor<3, Int>, alpha: Tensor<1>) -> Tensor<1> {
    let dims = check_shapes(&probs, &target, &alpha);
    let scale = (dims[1] - 1).max(1) as f64;
    let t = target.clone().float().div_scalar(scale);
    let a_t = alpha_of_target(target, alpha, dims).squeeze_dim::<3>(1);
    ((expected_weight(probs) - t).abs() * a_t).mean()
}

/// Class-weighted cross-entropy α_t · (−log p_t) of `logits` [B, C, H, W] (log-softmax over
/// dim 1, so no probability underflows), averaged over batch and pixels.
pub fn weighted_cross_entropy(
    logits: Tensor<4>,
    target: Tensor<3, Int>,
    alpha: Tensor<1>,
) -> Tensor<1> {
    let dims = check_shapes(&logits, &target, &alpha);
    let logp_t = log_softmax(logits, 1).gather(1, target.clone().unsqueeze_dim::<4>(1));
    (logp_t.neg() * alpha_of_target(target, alpha, dims)).mean()
}

/// Cross-entropy against soft labels: q_c ∝ exp(−(c − t)²/(2σ²)) over the class indices
/// (normalised over the C classes), loss α_t · (−Σ_c q_c log p_c) averaged over batch and
/// pixels. `sigma` in classes; σ → 0 gives [`weighted_cross_entropy`]. A prediction a few
/// classes off then costs little, one far off costs much: the classes are ordered.
pub fn soft_cross_entropy(
    logits: Tensor<4>,
    target: Tensor<3, Int>,
    alpha: Tensor<1>,
    sigma: f32,
) -> Tensor<1> {
    let dims = check_shapes(&logits, &target, &alpha);
    let [_, c, _, _] = dims;
    let device = logits.device();
    let idx: Vec<f32> = (0..c).map(|k| k as f32).collect();
    let idx =
        Tensor::<1>::from_data(TensorData::new(idx, [c]), &device).reshape([1, c as i32, 1, 1]);
    let t = target.clone().float().unsqueeze_dim::<4>(1);
    let d = idx - t;
    let q = d
        .clone()
        .mul(d)
        .div_scalar(-2.0 * (sigma.max(1e-3) as f64).powi(2))
        .exp();
    let q = q.clone() / q.sum_dim(1);
    let ce = (q * log_softmax(logits, 1)).sum_dim(1).neg();
    (ce * alpha_of_target(target, alpha, dims)).mean()
}

/// The Network-1 training loss of `logits` [B, C, H, W] in the chosen reading (`label_sigma`
/// is used by [`Network1Reading::Soft`] only). On flex it is one fused operation
/// (`fused_loss`), elsewhere the composition below.
pub fn network1_loss(
    reading: Network1Reading,
    logits: Tensor<4>,
    target: Tensor<3, Int>,
    alpha: Tensor<1>,
    label_sigma: f32,
) -> Tensor<1> {
    #[cfg(feature = "flex")]
    if let Some(per_pixel) = crate::kernels::fused_loss::class_loss(
        &logits,
        &target,
        &alpha,
        crate::kernels::fused_loss::ClassLoss {
            reading,
            sigma: label_sigma,
        },
    ) {
        return per_pixel.mean();
    }
    match reading {
        Network1Reading::Literal => weighted_l1(softmax(logits, 1), target, alpha),
        Network1Reading::Ordinal => ordinal_l1(softmax(logits, 1), target, alpha),
        Network1Reading::CrossEntropy => weighted_cross_entropy(logits, target, alpha),
        Network1Reading::Soft => soft_cross_entropy(logits, target, alpha, label_sigma),
    }
}

/// The class weights α as a [CLASSES] tensor on `device`.
pub fn alpha_tensor(weights: &ClassWeights, device: &Device) -> Result<Tensor<1>> {
    if weights.alpha.len() != CLASSES {
        return Err(Error::Invalid(format!(
            "class weights hold {} α values, expected {CLASSES}",
            weights.alpha.len()
        )));
    }
    let a: Vec<f32> = weights.alpha.iter().map(|&a| a as f32).collect();
    Ok(Tensor::from_data(TensorData::new(a, [CLASSES]), device))
}

/// The samples' inputs stacked as [B, C, S, S] data, checking that all share one shape (and
/// `channels`, when given): (data, C, S).
fn stacked_inputs(
    what: &str,
    samples: &[Sample],
    channels: Option<usize>,
) -> Result<(Vec<f32>, usize, usize)> {
    let first = samples
        .first()
        .ok_or_else(|| Error::Invalid(format!("{what}: no samples")))?;
    let (c, s) = (channels.unwrap_or(first.channels), first.size);
    let mut input = Vec::with_capacity(samples.len() * c * s * s);
    for sample in samples {
        if sample.channels != c || sample.size != s || sample.input.len() != c * s * s {
            return Err(Error::Invalid(format!(
                "{what}: sample of set '{}' is {}×{}×{} with {} values; the batch is \
                 {c}×{s}×{s}",
                sample.set,
                sample.channels,
                sample.size,
                sample.size,
                sample.input.len()
            )));
        }
        input.extend_from_slice(&sample.input);
    }
    Ok((input, c, s))
}

/// A Network-1 batch from loader samples: input [B, C, H, W] (the samples' C×H×W data
/// stacked) and target [B, H, W] (the class maps). All samples must have the same channel count
/// and size and a [`Target::Classes`] target of size×size entries.
pub fn network1_batch(samples: &[Sample], device: &Device) -> Result<(Tensor<4>, Tensor<3, Int>)> {
    let (input, c, s) = stacked_inputs("network1_batch", samples, None)?;
    let mut target = Vec::with_capacity(samples.len() * s * s);
    for sample in samples {
        match &sample.target {
            Target::Classes(classes) if classes.len() == s * s => {
                target.extend(classes.iter().map(|&k| k as i32));
            }
            Target::Classes(classes) => {
                return Err(Error::Invalid(format!(
                    "network1_batch: sample of set '{}' has {} classes for {s}×{s} pixels",
                    sample.set,
                    classes.len()
                )));
            }
            Target::Hdr(_) => {
                return Err(Error::Invalid(format!(
                    "network1_batch: sample of set '{}' has an HDR target (a Network-2 sample)",
                    sample.set
                )));
            }
        }
    }
    let b = samples.len();
    Ok((
        Tensor::from_data(TensorData::new(input, [b, c, s, s]), device),
        Tensor::from_data(TensorData::new(target, [b, s, s]), device),
    ))
}

// ═════════════════════════════════════════════════════════════════════════════════════════════
// Network-2 (Wu et al., ECCV 2018): L2 between μ-law tone-mapped images.
// ═════════════════════════════════════════════════════════════════════════════════════════════
//
//   T(x) = log(1 + μx) / log(1 + μ),  μ = 5000,   L = mean over B·3·H·W of (T(pred) − T(target))²
//
// The authors' `model.py` takes `tf.reduce_mean` (a mean, not a sum) of the squared difference
// of their `tonemap`, which returns 2·T − 1 (images in [−1, 1]): their loss is 4 × this one,
// with the same minimiser (Adam is insensitive to that scale apart from its ε).

pub use crate::io::mu_law::MU;

/// The tensor form of [`crate::io::mu_law::mu_law`], element-wise (T(0) = 0, T(1) = 1), with
/// negative values clamped to 0 first.
pub fn mu_law<const D: usize>(t: Tensor<D>, mu: f64) -> Tensor<D> {
    t.clamp_min(0.0)
        .mul_scalar(mu)
        .log1p()
        .div_scalar((1.0 + mu).ln())
}

/// The Network-2 loss: mean of (T(pred) − T(target))² over all elements, μ = [`MU`]. `pred`
/// and `target` are linear HDR `[B, 3, H, W]`; returns the scalar loss, shape [1].
///
/// # Panics
/// If the shapes differ.
pub fn mu_law_l2(pred: Tensor<4>, target: Tensor<4>) -> Tensor<1> {
    assert_eq!(
        pred.dims(),
        target.dims(),
        "mu_law_l2: prediction and target shapes differ"
    );
    (mu_law(pred, MU) - mu_law(target, MU)).square().mean()
}

/// The floor of [`mu_law_psnr_loss`]'s per-crop MSE: a crop scores at most 60 dB, so that a
/// crop merged exactly (a flat one) does not dominate the batch.
pub const PSNR_LOSS_FLOOR: f64 = 1e-6;

/// The Network-2 loss as PSNR-T averages it: per crop, the μ-law MSE over its elements; then
/// the mean over the batch of 10·log10(MSE + [`PSNR_LOSS_FLOOR`]) — minus the crops' mean
/// PSNR-T (data range 1). Unlike [`mu_law_l2`], which pools every pixel of the batch, it
/// weighs a crop's error relative to that crop's own, as a per-image mean of PSNR does.
///
/// # Panics
/// If the shapes differ.
pub fn mu_law_psnr_loss(pred: Tensor<4>, target: Tensor<4>) -> Tensor<1> {
    assert_eq!(
        pred.dims(),
        target.dims(),
        "mu_law_psnr_loss: prediction and target shapes differ"
    );
    let n = pred.dims()[0] as i32;
    let mse = (mu_law(pred, MU) - mu_law(target, MU))
        .square()
        .reshape([n, -1])
        .mean_dim(1);
    mse.add_scalar(PSNR_LOSS_FLOOR)
        .log()
        .mean()
        .mul_scalar(10.0 / std::f64::consts::LN_10)
        .reshape([1])
}

/// A Network-2 batch from loader samples: input `[B, 18, H, W]` (the samples' 18×H×W data
/// stacked) and target `[B, 3, H, W]` (the linear HDR ground truth). All samples must have 18
/// channels, the same size and a [`Target::Hdr`] target of 3·size² values.
pub fn network2_batch(samples: &[Sample], device: &Device) -> Result<(Tensor<4>, Tensor<4>)> {
    use crate::models::wu::{INPUT_CHANNELS, OUTPUT_CHANNELS};
    let (input, c, s) = stacked_inputs("network2_batch", samples, Some(INPUT_CHANNELS))?;
    let mut target = Vec::with_capacity(samples.len() * OUTPUT_CHANNELS * s * s);
    for sample in samples {
        match &sample.target {
            Target::Hdr(hdr) if hdr.len() == OUTPUT_CHANNELS * s * s => {
                target.extend_from_slice(hdr);
            }
            Target::Hdr(hdr) => {
                return Err(Error::Invalid(format!(
                    "network2_batch: sample of set '{}' has {} HDR values for 3×{s}×{s}",
                    sample.set,
                    hdr.len()
                )));
            }
            Target::Classes(_) => {
                return Err(Error::Invalid(format!(
                    "network2_batch: sample of set '{}' has a class-map target (a Network-1 \
                     sample)",
                    sample.set
                )));
            }
        }
    }
    let b = samples.len();
    Ok((
        Tensor::from_data(TensorData::new(input, [b, c, s, s]), device),
        Tensor::from_data(TensorData::new(target, [b, OUTPUT_CHANNELS, s, s]), device),
    ))
}
