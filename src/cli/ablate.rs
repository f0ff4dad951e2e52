//! `hdrsynth ablate --config F`: the ablation grid (docs/experiments.md). Every cell fine-tunes
//! from the same base config with its own settings and is scored on the same test set; the
//! result is a table shaped like the paper's. Rerunning skips finished cells and resumes the
//! interrupted one.

use crate::eval::ablate::{self, AblateConfig, AblateSummary, CellStatus};
use anyhow::{Context, Result};
use std::fmt::Write as _;
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

pub fn report(cfg: &AblateConfig, s: &AblateSummary) -> String {
    let mut out = s.table.clone();
    out.push('\n');
    for c in &s.cells {
        let what = match c.status {
            CellStatus::Kept => "kept (finished before)".to_string(),
            CellStatus::Ran {
                resumed_at: Some(step),
            } => format!("resumed at step {step}"),
            CellStatus::Ran { resumed_at: None } => "ran".to_string(),
        };
        let _ = writeln!(out, "cell {:<32} {what:<24} {:.1} s", c.id, c.seconds);
    }
    let _ = write!(
        out,
        "{:.1} s; wrote {}/{{{}, {}{}}} and cells/<cell>/{}{{run, eval}}",
        s.seconds,
        cfg.out.display(),
        ablate::TABLE_MD,
        ablate::TABLE_CSV,
        if cfg.seeds.is_empty() {
            String::new()
        } else {
            format!(", {}", ablate::TABLE_SEEDS_CSV)
        },
        if cfg.seeds.is_empty() {
            ""
        } else {
            "[seed<k>/]"
        },
    );
    out
}

pub fn run(args: &Args) -> Result<String> {
    let (cfg, s) = execute(args)?;
    Ok(report(&cfg, &s))
}
