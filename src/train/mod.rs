//! Training: losses, batch assembly and the optimisation step.
//!
//! Burn 0.22: train on an autodiff device (`device.clone().autodiff()`); build the model and the
//! batch tensors on it; `loss.backward()` gives `Gradients`, `GradientsParams::from_grads`
//! ties them to the module's parameters, and `ModuleOptimizer::step` (from
//! `AdamConfig::new().init()`) returns the updated module.

pub mod loss;

use crate::models::BlendUNet;
use burn::optim::{GradientsParams, ModuleOptimizer};
use burn::tensor::activation::softmax;
use burn::tensor::{Int, Tensor};

/// One Network-1 optimisation step: forward, softmax, [`loss::weighted_l1`], backward, optimiser
/// update. `input`, `target` and `alpha` must be on the model's (autodiff) device. Returns the
/// updated model and the step's loss (detached, before the update; reading it with
/// `into_scalar` waits for the step to finish).
pub fn network1_step(
    model: BlendUNet,
    optim: &mut ModuleOptimizer,
    lr: f64,
    input: Tensor<4>,
    target: Tensor<3, Int>,
    alpha: Tensor<1>,
) -> (BlendUNet, Tensor<1>) {
    let probs = softmax(model.forward(input), 1);
    let loss = loss::weighted_l1(probs, target, alpha);
    let grads = GradientsParams::from_grads(loss.backward(), &model);
    let model = optim.step(lr, model, grads);
    (model, loss.detach())
}
