//! `hdrsynth train --config F [--resume]`: train Network-1 or Network-2 as the config says
//! (docs/training.md). Datasets named with a `generate` config are generated (or completed)
//! first, so the shipped configs run on a fresh machine.

use crate::train::config::TrainConfig;
use crate::train::{TrainOptions, TrainSummary};
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Training config (TOML), e.g. configs/net1_pretrain.toml.
    #[arg(long)]
    pub config: PathBuf,
    /// Continue the run in `run.out` from its latest checkpoint.
    #[arg(long)]
    pub resume: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

fn ensure_dataset(dataset: &Path, generate: Option<&Path>, progress: bool) -> Result<()> {
    if let Some(g) = generate {
        crate::cli::generate::run(g, dataset, progress)
            .with_context(|| format!("generating {} from {}", dataset.display(), g.display()))?;
    }
    Ok(())
}

/// Generate (or complete) the datasets a config names with a `generate` config.
pub fn ensure_data(cfg: &TrainConfig, progress: bool) -> Result<()> {
    ensure_dataset(&cfg.data.dataset, cfg.data.generate.as_deref(), progress)?;
    if let Some(v) = &cfg.validation {
        ensure_dataset(&v.dataset, v.generate.as_deref(), progress)?;
    }
    Ok(())
}

pub fn run(args: &Args) -> Result<TrainSummary> {
    let cfg = TrainConfig::load(&args.config)?;
    let progress = !args.quiet;
    ensure_data(&cfg, progress)?;
    let opts = TrainOptions {
        resume: args.resume,
        progress,
    };
    crate::train::run(&cfg, &opts).with_context(|| format!("training {}", args.config.display()))
}

pub fn report(s: &TrainSummary) -> String {
    let mut r = String::new();
    if s.already_finished {
        let _ = write!(
            r,
            "{} is already finished at step {}; nothing to do (raise run.steps to train \
             further)\ncheckpoint: {}",
            s.run.display(),
            s.start_step,
            s.checkpoint.display()
        );
        return r;
    }
    let _ = writeln!(
        r,
        "trained steps {}..{} in {}: loss {:.5} → {:.5} (mean of the first and last logged \
         intervals), {:.2} samples/s",
        s.start_step,
        s.steps,
        s.run.display(),
        s.first_loss,
        s.last_loss,
        s.samples_per_s
    );
    for (k, v) in &s.validation {
        let _ = writeln!(r, "validation {k}: {v:.5}");
    }
    let _ = write!(r, "checkpoint: {}", s.checkpoint.display());
    r
}
