//! What the one trainer needs to know about a network: how to build it, its loss on a batch of
//! loader samples, its validation scores, and what else a checkpoint must carry. Network-1 and
//! Network-2 each implement [`Task`]; the loop in `train::run` is shared.

use crate::data::ground_truth::{CLASSES, ClassWeights};
use crate::data::loader::Sample;
use crate::error::Result;
use crate::models::{BlendUNet, BlendUNetConfig, WuConfig, WuNet};
use crate::train::config::ModelConfig;
use crate::train::loss::{
    MU, alpha_tensor, mu_law, mu_law_l2, network1_batch, network2_batch, weighted_l1,
};
use burn::module::Module;
use burn::tensor::activation::softmax;
use burn::tensor::{Device, Tensor, TensorData};
use std::path::Path;

/// File of Network-1's class weights inside a checkpoint.
pub const CHECKPOINT_ALPHA_FILE: &str = "class_weights.toml";

pub trait Task {
    type Model: Module + Clone + std::fmt::Debug;

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

    /// Task state a checkpoint must carry besides weights (Network-1: α).
    fn save_extra(&self, _dir: &Path) -> Result<()> {
        Ok(())
    }
}

/// Network-1: the blend-map U-Net with paper Eq. 4.
pub struct Network1 {
    pub config: BlendUNetConfig,
    pub alpha: ClassWeights,
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
        let probs = softmax(model.forward(input), 1);
        Ok(weighted_l1(
            probs,
            target,
            alpha_tensor(&self.alpha, device)?,
        ))
    }

    /// `loss` (Eq. 4, summed per sample) and `weight_mae`: mean |w − w_target| of the expected
    /// blend weight Σ p_c·c/255 against the target class/255.
    fn validate(
        &self,
        model: &BlendUNet,
        batch: &[Sample],
        device: &Device,
    ) -> Result<Vec<(&'static str, f64)>> {
        let (input, target) = network1_batch(batch, device)?;
        let b = batch.len() as f64;
        let probs = softmax(model.forward(input), 1);
        let loss = weighted_l1(
            probs.clone(),
            target.clone(),
            alpha_tensor(&self.alpha, device)?,
        );
        let levels: Vec<f32> = (0..CLASSES).map(|c| c as f32 / 255.0).collect();
        let levels = Tensor::<1>::from_data(TensorData::new(levels, [CLASSES]), device).reshape([
            1,
            CLASSES as i32,
            1,
            1,
        ]);
        let w = (probs * levels).sum_dim(1).squeeze_dim::<3>(1);
        let mae = (w - target.float().div_scalar(255.0)).abs().mean();
        Ok(vec![
            ("loss", loss.into_scalar::<f32>() as f64 * b),
            ("weight_mae", mae.into_scalar::<f32>() as f64 * b),
        ])
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
}

impl Network2 {
    fn batch(&self, batch: &[Sample], device: &Device) -> Result<(Tensor<4>, Tensor<4>)> {
        let (x, t) = network2_batch(batch, device)?;
        let t = t.mul_scalar(self.config.hdr_input_scale).clamp(0.0, 1.0);
        Ok((x, t))
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
        Ok(mu_law_l2(model.forward(x), t))
    }

    /// `loss`, `psnr_t` (μ-law, per sample, dB) and `psnr_l` (linear, in the network's output
    /// unit), each summed over the batch's samples.
    fn validate(
        &self,
        model: &WuNet,
        batch: &[Sample],
        device: &Device,
    ) -> Result<Vec<(&'static str, f64)>> {
        let (x, t) = self.batch(batch, device)?;
        let b = batch.len() as f64;
        let y = model.forward(x);
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
