//! `hdrsynth eval --testset DIR --out OUT (--predictions DIR | --checkpoint C)`: score outputs
//! on a test set in any known layout — predictions made elsewhere (`<set>.exr`/`.hdr`, linear),
//! or a checkpoint's network run here at full resolution with tiles — and write per-image and
//! summary tables with bootstrap intervals, outputs, previews and a report (docs/evaluation.md).

use crate::eval::evaluate::{
    Classical, EvalOptions, Network1Reference, NetworkOptions, ScoreUnit, evaluate,
};
use crate::eval::metrics::{MetricOptions, Pu21Scale};
use crate::eval::report;
use crate::runner::method::{Source, method_for};
use crate::train::config::TrainConfig;
use anyhow::{Result, bail};
use std::fmt::Write as _;
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["predictions", "checkpoint", "config", "baseline"])))]
pub struct Args {
    /// Test set folder in any known layout (hdrsynth, Kalantari, Wu, paper Dataset-1).
    #[arg(long)]
    pub testset: PathBuf,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Folder of linear HDR predictions named `<set name>.exr` (or `.hdr`).
    #[arg(long)]
    pub predictions: Option<PathBuf>,
    /// A checkpoint folder, or a run folder (its latest checkpoint): run its network here.
    #[arg(long)]
    pub checkpoint: Option<PathBuf>,
    /// A training config: evaluate its run's latest checkpoint (`run.out`) on its `run.backend`
    /// (unless --checkpoint or --backend say otherwise).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A classical baseline instead of a network: copy (the reference frame linearised),
    /// triangle (Kalantari's triangle merge), debevec or robertson (OpenCV's MergeDebevec,
    /// MergeRobertson), each with the curve the test set records for its frames (refused where it records none).
    #[arg(long)]
    pub baseline: Option<Classical>,
    /// Skip sets without a prediction (listed in the summary) instead of failing.
    #[arg(long)]
    pub allow_missing: bool,
    /// How to run the checkpoint's network (--checkpoint only).
    #[command(flatten)]
    pub network: NetworkOptions,
    /// Compute device for --checkpoint: flex (CPU), ndarray, wgpu, cuda (default: the
    /// config's run.backend, else flex).
    #[arg(long)]
    pub backend: Option<String>,
    /// Bootstrap resamples for the confidence intervals.
    #[arg(long, default_value_t = 2000)]
    pub resamples: usize,
    /// Bootstrap seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Confidence level.
    #[arg(long, default_value_t = 0.95)]
    pub level: f64,
    /// Unit of HDR scoring: reference (1 = the reference exposure's white, for every layout)
    /// or file (each set's ground-truth file as written, as the field's code scores).
    #[arg(long, value_enum, default_value_t = ScoreUnit::Reference)]
    pub unit: ScoreUnit,
    /// Network-1's reference: clean-weights (blend of the noisy pair with Mertens weights of
    /// the noise-free frames) or noisy-mertens (Mertens fusion of the noisy pair).
    #[arg(long, value_enum, default_value_t = Network1Reference::CleanWeights)]
    pub net1_reference: Network1Reference,
    /// PU21 absolute scale: reference-max (ground truth max → peak) or unit-value (1.0 → peak).
    #[arg(long, value_enum, default_value = "reference-max")]
    pub pu21_scale: Pu21Scale,
    /// PU21 peak luminance in cd/m².
    #[arg(long, default_value_t = 4000.0)]
    pub peak_luminance: f64,
    /// Largest side of the report's thumbnails in pixels.
    #[arg(long, default_value_t = 512)]
    pub thumb: usize,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl Args {
    fn options(&self) -> EvalOptions {
        EvalOptions {
            metrics: MetricOptions {
                peak_luminance: self.peak_luminance,
                pu21_scale: self.pu21_scale,
            },
            unit: self.unit,
            network1_reference: self.net1_reference,
            resamples: self.resamples,
            seed: self.seed,
            level: self.level,
            allow_missing: self.allow_missing,
            thumb: self.thumb.max(16),
            progress: !self.quiet,
            frame_curve: None,
            validation: false,
        }
    }

    /// The flags as a source: --config supplies the checkpoint (its run.out) and the backend
    /// (its run.backend) where --checkpoint and --backend do not.
    fn source(&self) -> Result<Source> {
        let train = match &self.config {
            Some(path) => Some(TrainConfig::load(path)?),
            None => None,
        };
        let checkpoint = self
            .checkpoint
            .clone()
            .or_else(|| train.as_ref().map(|t| t.run.out.clone()));
        Ok(match (&self.predictions, checkpoint) {
            _ if self.baseline.is_some()
                && (self.predictions.is_some() || self.config.is_some()) =>
            {
                bail!(
                    "--baseline scores a classical merge: give it without --predictions, --checkpoint or --config"
                )
            }
            (None, None) if self.baseline.is_some() => {
                Source::Baseline(self.baseline.expect("checked"), self.testset.clone())
            }
            (Some(dir), None) => Source::Predictions(dir.clone()),
            (None, Some(path)) => Source::Checkpoint {
                path,
                backend: self
                    .backend
                    .clone()
                    .or_else(|| train.as_ref().map(|t| t.run.backend.clone()))
                    .unwrap_or_else(|| "flex".into()),
                network: self.network.clone(),
            },
            _ => bail!("give --predictions, or a network (--checkpoint and/or --config), not both"),
        })
    }
}

pub fn run(args: &Args) -> Result<String> {
    let method = method_for(&args.source()?)?;
    let r = evaluate(&args.testset, method.as_ref(), &args.out, &args.options())?;
    let mut s = String::new();
    for w in &r.warnings {
        let _ = writeln!(s, "warning: {w}\n");
    }
    let _ = write!(
        s,
        "{} set(s) scored in {:.1} s; {}\n\n{}",
        r.rows.len(),
        r.seconds,
        r.method,
        report::summary_table(&r.summary, args.level)
    );
    if !r.missing.is_empty() {
        let _ = writeln!(s, "\n{} set(s) skipped (no output):", r.missing.len());
        for (set, looked) in &r.missing {
            let _ = writeln!(s, "  {set}: looked for {looked}");
        }
    }
    let _ = write!(
        s,
        "\nwrote {}/{{per_image.csv, summary.csv, summary.md, report.md}}, <set>.exr, <set>.png, \
         grids/<set>.png",
        r.out.display()
    );
    Ok(s)
}
