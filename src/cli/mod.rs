//! Subcommands, one file each. The binary (src/main.rs) only parses and dispatches.
pub mod ablate;
pub mod calibrate;
pub mod dataset;
pub mod diagnose;
pub mod eval;
pub mod export;
pub mod generate;
pub mod infer;
pub mod preview;
pub mod profile;
pub mod quickstart;
pub mod realism;
pub mod testset;
pub mod train;
pub mod weights;
