//! The networks. Backend-agnostic Burn 0.22 modules: the `Device` passed to `init` (and the
//! device of the input tensors) picks the backend at run time.
//!
//! - [`blend_unet`]: Network-1, the U-Net that predicts a 256-class blend map from (EV−3, EV0).
//! - [`wu`]: Network-2, Wu et al. (ECCV 2018), three exposures → linear HDR; [`import`] moves
//!   weights to and from PyTorch-style SafeTensors files.
//! - [`conv`]: the layers' 2D convolutions and transposed convolutions, im2col + GEMM on flex.
//! - [`pad`]: reflection padding (Network-2's convolutions), one fused op on flex.
//! - [`activation`]: leaky ReLU (Network-2's encoders), one fused op on flex.
//! - [`pool`]: Network-1's 2×2 max-pool, one fused op on flex.
//! - `winograd` (flex): Winograd F(m×m, r×r) for the stride-1 3×3 and 5×5 convolutions.
//! - `direct` (flex): direct convolution for thin stride-1 layers (≤ 4 channels on one side).
//! - [`batch_norm`]: the layers' BatchNorm, fused and parallel on flex in training mode.
//! - [`ModelConfig`]: either network's config, tagged by `kind` (training configs, checkpoints).

pub mod activation;
pub mod batch_norm;
pub mod blend_unet;
pub mod conv;
#[cfg(feature = "flex")]
pub mod direct;
pub mod import;
pub mod pad;
#[cfg(feature = "flex")]
pub(crate) mod par;
pub mod pool;
#[cfg(feature = "flex")]
pub mod winograd;
pub mod wu;

use crate::data::loader::SampleKind;
use serde::{Deserialize, Serialize};

pub use blend_unet::{BlendUNet, BlendUNetConfig};
pub use wu::{DeconvAlignment, WuConfig, WuNet, WuVariant};

/// The network, tagged by `kind`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ModelConfig {
    /// Network-1, the blend-map U-Net.
    BlendUnet(BlendUNetConfig),
    /// Network-2, Wu et al.'s three-exposure merger.
    Wu(WuConfig),
}

impl ModelConfig {
    pub fn sample_kind(&self) -> SampleKind {
        match self {
            ModelConfig::BlendUnet(_) => SampleKind::Network1,
            ModelConfig::Wu(_) => SampleKind::Network2,
        }
    }

    /// The network's rules, keys relative to `[model]`.
    pub fn validate(&self) -> std::result::Result<(), crate::config::KeyError> {
        match self {
            ModelConfig::BlendUnet(m) => m.validate(),
            ModelConfig::Wu(m) => m.validate(),
        }
    }

    /// H and W of an input must be multiples of this.
    pub fn size_multiple(&self) -> usize {
        match self {
            ModelConfig::BlendUnet(m) => m.size_multiple(),
            ModelConfig::Wu(m) => m.size_multiple(),
        }
    }

    /// Receptive-field radius in input pixels: the overlap that makes tiling exact.
    pub fn receptive_radius(&self) -> usize {
        match self {
            ModelConfig::BlendUnet(m) => m.receptive_radius(),
            ModelConfig::Wu(m) => m.receptive_radius(),
        }
    }
}
