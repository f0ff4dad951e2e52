//! One Network-2 fine-tuning step from a training config, as a researcher's own loop would take
//! it: the config's loader (scenes through the config's sensor profile, online), Wu et al.'s
//! merger from its `[model]` section (or its `[init]` checkpoint), Adam, one step of the μ-law
//! L2 loss.
//!
//!     cargo run --release --example network2_step -- [CONFIG.toml]
//!
//! CONFIG defaults to examples/network2_step.toml (a width-8 network on a 4-scene dataset it
//! generates into runs/example_data on first use; run from the repository root). Any
//! Network-2 config works, e.g. configs/net2_finetune.toml once its pretraining has run.
use anyhow::{Context, Result, bail};
use hdrsynth::data::loader::Loader;
use hdrsynth::device::device_from_name;
use hdrsynth::models::ModelConfig;
use hdrsynth::train::config::TrainConfig;
use hdrsynth::train::task::{Network2, Task};
use hdrsynth::train::{initial_model, optimizer, train_step};
use std::path::PathBuf;
use std::sync::Arc;

fn main() -> Result<()> {
    let path = std::env::args().nth(1).map_or_else(
        || PathBuf::from("examples/network2_step.toml"),
        PathBuf::from,
    );
    // As the trainer: Network-2's input curve resolved (linearise = "data").
    let cfg = TrainConfig::load(&path)?.with_resolved_model()?;
    let ModelConfig::Wu(model) = &cfg.model else {
        bail!(
            "{}: [model] kind must be \"wu\" (Network-2)",
            path.display()
        );
    };
    // The dataset the config names, generated first when it has a `generate` config.
    hdrsynth::cli::train::ensure_data(&cfg, true)?;
    let loader = Arc::new(Loader::new(&cfg.loader(cfg.model.sample_kind())?)?);

    let device = device_from_name(&cfg.run.backend)?.autodiff();
    let task = Network2::new(model.clone(), &cfg.loss);
    // As the trainer starts a new run: seeded weights, then [init]'s weights if any; Adam as
    // [optim] says.
    let net = initial_model(&task, &cfg, &device)?;
    let mut optim = optimizer(&cfg.optim);

    let batch = loader.epoch(0).next().context("the dataset is empty")??;
    let (net, before) = train_step(&task, net, &mut optim, cfg.optim.lr, &batch, &device)?;
    // The same batch after the update: one step at this learning rate lowers its loss.
    let after = task.loss(&net, &batch, &device)?.into_scalar::<f32>();
    println!(
        "{} samples of {}×{} px: μ-law L2 {before:.6} → {after:.6} after one step",
        batch.len(),
        batch[0].size,
        batch[0].size
    );
    Ok(())
}
