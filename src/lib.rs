//! hdrsynth: sensor-realistic synthetic data for multi-frame HDR networks.
//! See ARCHITECTURE in docs/architecture.md for the one-way flow and where things live.

pub mod capture;
pub mod cli;
pub mod config;
pub mod data;
pub mod device;
pub mod error;
pub mod eval;
pub mod experiments;
pub mod io;
pub mod kernels;
pub mod linalg;
pub mod models;
#[cfg(feature = "onnx")]
pub mod onnx;
pub mod plot;
pub mod rng;
pub mod runner;
pub mod sensor;
pub mod stats;
pub mod train;

pub use error::{Error, Result};
