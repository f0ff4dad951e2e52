//! `hdrsynth generate --config F --out DIR`: render a pure synthetic dataset (data::generate).

use crate::data::generate::{GenerateConfig, Summary, generate};
use anyhow::Result;
use std::path::Path;

pub fn run(config: &Path, out: &Path, progress: bool) -> Result<Summary> {
    let cfg = GenerateConfig::load(config)?;
    Ok(generate(&cfg, out, progress)?)
}
