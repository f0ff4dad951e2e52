//! `hdrsynth ablate --config F`: the ablation grid (docs/experiments.md). Every cell fine-tunes
//! from the same base config with its own settings and is scored on the same test set; the
//! result is a table shaped like the paper's. Rerunning skips finished cells and resumes the
//! interrupted one.

use crate::experiments::ablate::{self, AblateConfig, AblateSummary};
use anyhow::{Context, Result};
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Ablation config (TOML), e.g. configs/experiments/exp1_network1.toml.
    #[arg(long)]
    pub config: PathBuf,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

pub fn execute(args: &Args) -> Result<(AblateConfig, AblateSummary)> {
    let cfg = AblateConfig::load(&args.config)?;
    let progress = !args.quiet;
    for tc in ablate::train_configs(&cfg, &args.config)? {
        crate::cli::train::ensure_data(&tc, progress)?;
    }
    let summary = ablate::run(&cfg, &args.config, progress)
        .with_context(|| format!("ablation {}", args.config.display()))?;
    Ok((cfg, summary))
}

pub fn run(args: &Args) -> Result<String> {
    let (cfg, s) = execute(args)?;
    Ok(ablate::report(&cfg, &s))
}
