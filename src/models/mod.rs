//! The networks. Backend-agnostic Burn 0.22 modules: the `Device` passed to `init` (and the
//! device of the input tensors) picks the backend at run time.
//!
//! - [`blend_unet`]: Network-1, the U-Net that predicts a 256-class blend map from (EV−3, EV0).
//! - [`wu`]: Network-2, Wu et al. (ECCV 2018), three exposures → linear HDR; [`import`] moves
//!   weights to and from PyTorch-style SafeTensors files.
//! - The layers' operations (convolution, padding, activation, pooling, BatchNorm) come from
//!   [`crate::kernels`], which picks the hand-written flex kernels or Burn's ops.
//! - [`ModelConfig`]: either network's config, tagged by `kind` (training configs, checkpoints).
//! - [`seeded_init`]: a reproducible initialisation, whatever other threads draw.

pub mod blend_unet;
pub mod import;
mod init;
mod merge_head;
pub mod wu;

use crate::data::loader::SampleKind;
use serde::{Deserialize, Serialize};

pub use blend_unet::{BlendUNet, BlendUNetConfig};
pub use init::seeded_init;
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

    /// Trainable parameters, counted from the architecture (nothing is allocated).
    pub fn trainable_parameters(&self) -> usize {
        match self {
            ModelConfig::BlendUnet(m) => m.trainable_parameters(),
            ModelConfig::Wu(m) => m.trainable_parameters(),
        }
    }

    /// Channels of one input sample.
    pub fn input_channels(&self) -> usize {
        match self {
            ModelConfig::BlendUnet(_) => blend_unet::INPUT_CHANNELS,
            ModelConfig::Wu(_) => wu::INPUT_CHANNELS,
        }
    }

    /// Network-2's input curve (`None` for Network-1), for the loader.
    pub fn input_response(&self) -> Option<crate::sensor::profile::Response> {
        match self {
            ModelConfig::BlendUnet(_) => None,
            ModelConfig::Wu(m) => Some(m.input_response.clone()),
        }
    }

    /// Whether a checkpoint of `other` holds weights this network can start from: the same
    /// layers. Network-2's input curve is not a weight (fine-tuning for another device's curve
    /// starts from a network trained on another one).
    pub fn same_layers(&self, other: &ModelConfig) -> bool {
        let plain = |m: &ModelConfig| match m {
            ModelConfig::Wu(w) => ModelConfig::Wu(crate::models::wu::WuConfig {
                input_response: crate::models::wu::wu_input_response(),
                linearise: Default::default(),
                ..w.clone()
            }),
            m => m.clone(),
        };
        plain(self) == plain(other)
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
