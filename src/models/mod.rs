//! The networks. Backend-agnostic Burn 0.22 modules: the `Device` passed to `init` (and the
//! device of the input tensors) picks the backend at run time.
//!
//! - [`blend_unet`]: Network-1, the U-Net that predicts a 256-class blend map from (EV−3, EV0).
//! - [`wu`]: Network-2, Wu et al. (ECCV 2018), three exposures → linear HDR; [`import`] moves
//!   weights to and from PyTorch-style SafeTensors files.
//! - [`conv`]: the layers' 2D convolution, with a faster weight gradient on flex.

pub mod blend_unet;
pub mod conv;
pub mod import;
pub mod wu;

pub use blend_unet::{BlendUNet, BlendUNetConfig};
pub use wu::{DeconvAlignment, WuConfig, WuNet, WuVariant};
