//! The networks. Backend-agnostic Burn 0.22 modules: the `Device` passed to `init` (and the
//! device of the input tensors) picks the backend at run time.
//!
//! - [`blend_unet`]: Network-1, the U-Net that predicts a 256-class blend map from (EV−3, EV0).

pub mod blend_unet;

pub use blend_unet::{BlendUNet, BlendUNetConfig};
