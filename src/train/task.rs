//! What the one trainer needs to know about a network: how to build it, its loss on a batch of
//! loader samples, its validation scores, and what else a checkpoint must carry. Network-1 and
//! Network-2 each implement [`Task`]; the loop in `train::run` is shared.

use crate::data::ground_truth::{CLASSES, ClassWeights, blend_weights_high};
use crate::data::loader::{Sample, Target};
use crate::error::Result;
use crate::io::Image;
use crate::models::{BlendUNet, BlendUNetConfig, ModelConfig, WuConfig, WuNet};
use crate::train::config::{HdrUnit, LossAverage};
use crate::train::loss::{
    MU, Network1Reading, alpha_tensor, expected_weight, mu_law, mu_law_l2, mu_law_psnr_loss,
    network1_batch, network1_loss, network2_batch, weighted_l1,
};
use burn::module::Module;
use burn::tensor::activation::softmax;
use burn::tensor::{Device, Tensor};
use std::path::Path;

/// File of Network-1's class weights inside a checkpoint.
pub const CHECKPOINT_ALPHA_FILE: &str = "class_weights.toml";

pub trait Task {
    type Model: Module + Clone + std::fmt::Debug + Send;

    /// The `[model]` table that rebuilds this network (stored in every checkpoint).
    fn model_config(&self) -> ModelConfig;

    /// A freshly initialised network (seed the device first for a reproducible one).
    fn init(&self, device: &Device) -> Result<Self::Model>;

    /// Scalar training loss of a batch; `device` is the (autodiff) device of `model`.
    fn loss(&self, model: &Self::Model, batch: &[Sample], device: &Device) -> Result<Tensor<1>>;

    /// Validation scores of a batch on the inference model: (name, sum over the batch's
    /// samples), averaged over all validation samples by the trainer.
    fn validate(
        &self,
        model: &Self::Model,
        batch: &[Sample],
        device: &Device,
    ) -> Result<Vec<(&'static str, f64)>>;

    /// Scores of the best input-independent prediction on the whole validation set (logged
    /// with every validation line, so a learning curve can be read against it).
    fn validation_baseline(&self, _samples: &[Sample]) -> Result<Vec<(&'static str, f64)>> {
        Ok(Vec::new())
    }

    /// Task state a checkpoint must carry besides weights (Network-1: α).
    fn save_extra(&self, _dir: &Path) -> Result<()> {
        Ok(())
    }
}

/// Network-1: the blend-map U-Net, trained with the loss reading of `[loss] reading`.
pub struct Network1 {
    pub config: BlendUNetConfig,
    pub alpha: ClassWeights,
    pub reading: Network1Reading,
    /// σ of the soft labels in classes (`Network1Reading::Soft`).
    pub label_sigma: f32,
}

/// The blend-weight MAE of the best constant predictor on `samples`' targets: the median of
/// all target weights t/255 (the constant that minimises the mean absolute error), and that
/// error. `None` when there are no class targets.
pub fn best_constant_weight_mae(samples: &[Sample]) -> Option<(f64, f64)> {
    let mut hist = [0u64; CLASSES];
    for s in samples {
        if let Target::Classes(c) = &s.target {
            for &k in c {
                hist[k as usize] += 1;
            }
        }
    }
    let n: u64 = hist.iter().sum();
    if n == 0 {
        return None;
    }
    // The lower median class: half of the pixels or more lie at or below it.
    let mut acc = 0;
    let median = (0..CLASSES)
        .find(|&k| {
            acc += hist[k];
            2 * acc >= n
        })
        .unwrap_or(0);
    let m = median as f64 / 255.0;
    let mae = (0..CLASSES)
        .map(|k| hist[k] as f64 * (k as f64 / 255.0 - m).abs())
        .sum::<f64>()
        / n as f64;
    Some((m, mae))
}

/// The blend-weight MAE of the Mertens weights of each sample's own input pair (the frames the
/// network sees, noise included) against its targets: what Mertens fusion without a network
/// would predict. `None` without Network-1 samples.
pub fn mertens_weight_mae(samples: &[Sample]) -> Result<Option<f64>> {
    let (mut sum, mut n) = (0.0, 0usize);
    for s in samples {
        let Target::Classes(classes) = &s.target else {
            continue;
        };
        let plane = s.size * s.size;
        // Channel-major input (low RGB, high RGB) back into two interleaved frames.
        let frame = |k: usize| {
            let mut img = Image::new(s.size, s.size);
            for (i, px) in img.data.chunks_exact_mut(3).enumerate() {
                for (c, v) in px.iter_mut().enumerate() {
                    *v = s.input[(k * 3 + c) * plane + i];
                }
            }
            img
        };
        let w = blend_weights_high(&frame(0), &frame(1))?;
        for (&wi, &ci) in w.iter().zip(classes) {
            sum += (wi as f64 - ci as f64 / 255.0).abs();
            n += 1;
        }
    }
    Ok((n > 0).then(|| sum / n as f64))
}

impl Task for Network1 {
    type Model = BlendUNet;

    fn model_config(&self) -> ModelConfig {
        ModelConfig::BlendUnet(self.config.clone())
    }

    fn init(&self, device: &Device) -> Result<BlendUNet> {
        self.config.init(device)
    }

    fn loss(&self, model: &BlendUNet, batch: &[Sample], device: &Device) -> Result<Tensor<1>> {
        let (input, target) = network1_batch(batch, device)?;
        Ok(network1_loss(
            self.reading,
            model.forward(input),
            target,
            alpha_tensor(&self.alpha, device)?,
            self.label_sigma,
        ))
    }

    /// `loss` (the configured reading), `eq4` (paper Eq. 4 as written, whatever the reading)
    /// and `weight_mae`: mean |w − w_target| of the expected blend weight Σ p_c·c/255 against
    /// the target class/255; each summed over the batch's samples.
    fn validate(
        &self,
        model: &BlendUNet,
        batch: &[Sample],
        device: &Device,
    ) -> Result<Vec<(&'static str, f64)>> {
        let (input, target) = network1_batch(batch, device)?;
        let b = batch.len() as f64;
        let alpha = alpha_tensor(&self.alpha, device)?;
        let logits = model.forward(input);
        let loss = network1_loss(
            self.reading,
            logits.clone(),
            target.clone(),
            alpha.clone(),
            self.label_sigma,
        );
        let probs = softmax(logits, 1);
        let eq4 = weighted_l1(probs.clone(), target.clone(), alpha);
        let w = expected_weight(probs);
        let mae = (w - target.float().div_scalar(255.0)).abs().mean();
        Ok(vec![
            ("loss", loss.into_scalar::<f32>() as f64 * b),
            ("eq4", eq4.into_scalar::<f32>() as f64 * b),
            ("weight_mae", mae.into_scalar::<f32>() as f64 * b),
        ])
    }

    /// `weight_mae_const`: the blend-weight MAE of the best constant prediction (the median
    /// target weight of the validation set) — the score a network must beat to have learnt
    /// anything from its input; `weight_mae_mertens`: that of the Mertens weights of the noisy
    /// input pair (`mertens_weight_mae`).
    fn validation_baseline(&self, samples: &[Sample]) -> Result<Vec<(&'static str, f64)>> {
        let mut out: Vec<(&'static str, f64)> = best_constant_weight_mae(samples)
            .map(|(_, mae)| ("weight_mae_const", mae))
            .into_iter()
            .collect();
        out.extend(mertens_weight_mae(samples)?.map(|m| ("weight_mae_mertens", m)));
        Ok(out)
    }

    fn save_extra(&self, dir: &Path) -> Result<()> {
        self.alpha.save(&dir.join(CHECKPOINT_ALPHA_FILE))
    }
}

/// Network-2: Wu et al.'s merger with the μ-law L2 loss. Targets (linear HDR relative to the
/// reference exposure's white, as the loader gives them) are multiplied by the network's
/// `hdr_input_scale` (its output unit) and clipped to [0, 1], the range of its tanh output.
pub struct Network2 {
    pub config: WuConfig,
    /// The unit the loss and the validation scores are taken in.
    pub unit: HdrUnit,
    /// How the loss is averaged over the batch.
    pub average: LossAverage,
}

impl Network2 {
    /// The task of `config` with the loss `[loss]` asks for.
    pub fn new(config: WuConfig, loss: &crate::train::config::LossConfig) -> Network2 {
        Network2 {
            config,
            unit: loss.hdr_unit,
            average: loss.average,
        }
    }

    /// Input and target, the target in the network's output unit clipped to its range.
    fn batch(&self, batch: &[Sample], device: &Device) -> Result<(Tensor<4>, Tensor<4>)> {
        let (x, t) = network2_batch(batch, device)?;
        let t = t.mul_scalar(self.config.hdr_input_scale).clamp(0.0, 1.0);
        Ok((x, t))
    }

    /// A prediction or target in the output unit, in the loss's unit.
    fn in_unit(&self, y: Tensor<4>) -> Tensor<4> {
        match self.unit {
            HdrUnit::Output => y,
            HdrUnit::Reference => y.div_scalar(self.config.hdr_input_scale),
        }
    }
}

/// Per-sample PSNR (data range 1) of two [B, C, H, W] tensors, summed over the batch.
fn psnr_sum(a: Tensor<4>, b: Tensor<4>) -> Result<f64> {
    let [n, ..] = a.dims();
    let mse = (a - b).square().reshape([n as i32, -1]).mean_dim(1);
    let v = mse
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| crate::error::Error::Invalid(format!("reading the MSE: {e:?}")))?;
    Ok(v.iter()
        .map(|&m| -10.0 * (m.max(1e-20) as f64).log10())
        .sum())
}

impl Task for Network2 {
    type Model = WuNet;

    fn model_config(&self) -> ModelConfig {
        ModelConfig::Wu(self.config.clone())
    }

    fn init(&self, device: &Device) -> Result<WuNet> {
        self.config.init(device)
    }

    fn loss(&self, model: &WuNet, batch: &[Sample], device: &Device) -> Result<Tensor<1>> {
        let (x, t) = self.batch(batch, device)?;
        let (y, t) = (self.in_unit(model.forward(x)), self.in_unit(t));
        Ok(match self.average {
            LossAverage::Pixels => mu_law_l2(y, t),
            LossAverage::Psnr => mu_law_psnr_loss(y, t),
        })
    }

    /// `loss`, `psnr_t` (μ-law, per sample, dB) and `psnr_l` (linear), in the loss's unit,
    /// each summed over the batch's samples.
    fn validate(
        &self,
        model: &WuNet,
        batch: &[Sample],
        device: &Device,
    ) -> Result<Vec<(&'static str, f64)>> {
        let (x, t) = self.batch(batch, device)?;
        let b = batch.len() as f64;
        let (y, t) = (self.in_unit(model.forward(x)), self.in_unit(t));
        let loss = mu_law_l2(y.clone(), t.clone()).into_scalar::<f32>() as f64;
        let psnr_t = psnr_sum(mu_law(y.clone(), MU), mu_law(t.clone(), MU))?;
        let psnr_l = psnr_sum(y, t)?;
        Ok(vec![
            ("loss", loss * b),
            ("psnr_t", psnr_t),
            ("psnr_l", psnr_l),
        ])
    }
}
