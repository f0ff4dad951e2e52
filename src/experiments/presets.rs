//! The main job's presets and their sizes: `cpu` (the main job), `long` (the recipe the sweep
//! chose on validation scenes), `long-still` (that recipe on still samples only) and `gpu` (Wu
//! et al.'s width).

use crate::error::{Error, Result};
use crate::models::wu::WuOutput;
use crate::train::config::LossAverage;
use std::borrow::Cow;

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Preset {
    /// About 10 minutes on 2 CPU cores: a narrow Network-2, short runs, small crops.
    Cpu,
    /// Wu et al.'s released width and longer runs, for a GPU (pass --backend cuda or wgpu).
    Gpu,
    /// About 50 minutes on 2 CPU cores: the recipe the sweep chose on validation scenes
    /// (docs/experiments.md, "the sweep"): moving training subjects with half the samples still,
    /// the kernel head, the PSNR-averaged loss and 2× the cpu preset's steps. It beats the
    /// triangle merge on the simulated test sets and loses to it on the real 550D capture.
    Long,
    /// `long` with every training sample still (the same training scenes, no subject moves
    /// between the frames): for static brackets. About 50 minutes on 2 CPU cores; it does not
    /// learn to avoid ghosts (docs/experiments.md, "The `long-still` preset").
    LongStill,
}

/// The sizes of one preset.
pub(crate) struct Sizes {
    pub(crate) train_sets: usize,
    pub(crate) train_size: (usize, usize),
    pub(crate) test_scenes: usize,
    pub(crate) test_size: (usize, usize),
    /// Test scenes with moving subjects (the dynamic test set).
    pub(crate) dynamic_scenes: usize,
    pub(crate) base_width: usize,
    pub(crate) res_blocks: usize,
    pub(crate) patch: usize,
    pub(crate) batch: usize,
    pub(crate) pretrain_steps: u64,
    pub(crate) finetune_steps: u64,
    pub(crate) pretrain_lr: f64,
    pub(crate) finetune_lr: f64,
    pub(crate) checkpoint_every: u64,
    pub(crate) seeds: Cow<'static, [u64]>,
    pub(crate) backend: &'static str,
    /// Training scenes with moving subjects, this share of the samples still; `None`: static
    /// training scenes.
    pub(crate) moving_still: Option<f64>,
    pub(crate) output: WuOutput,
    pub(crate) loss_average: LossAverage,
}

/// The cpu preset: static training scenes, the merge head, Wu's pooled loss.
const CPU: Sizes = Sizes {
    train_sets: 40,
    train_size: (160, 128),
    test_scenes: 24,
    test_size: (192, 144),
    dynamic_scenes: 16,
    base_width: 8,
    res_blocks: 2,
    patch: 64,
    batch: 8,
    pretrain_steps: 800,
    finetune_steps: 300,
    pretrain_lr: 1e-3,
    finetune_lr: 5e-4,
    checkpoint_every: 100,
    seeds: Cow::Borrowed(&[1, 2, 3]),
    backend: "flex",
    moving_still: None,
    output: WuOutput::Merge,
    loss_average: LossAverage::Pixels,
};

/// The sizes of `p` with `seeds` where asked (a claim about newly trained networks needs 5:
/// docs/protocol.md, "Statistics").
pub(crate) fn sizes_with_seeds(p: Preset, seeds: Option<&[u64]>) -> Result<Sizes> {
    let mut s = sizes(p);
    if let Some(seeds) = seeds {
        let list = || {
            let v: Vec<String> = seeds.iter().map(u64::to_string).collect();
            v.join(",")
        };
        if seeds.len() < 2 {
            return Err(Error::flag(
                "--seeds",
                format!(
                    "{}: at least two (an interval over training runs needs two)",
                    list()
                ),
            ));
        }
        if (1..seeds.len()).any(|i| seeds[..i].contains(&seeds[i])) {
            return Err(Error::flag(
                "--seeds",
                format!("{}: a seed named twice", list()),
            ));
        }
        s.seeds = Cow::Owned(seeds.to_vec());
    }
    Ok(s)
}

pub(crate) fn sizes(p: Preset) -> Sizes {
    match p {
        Preset::Cpu => CPU,
        // The sweep's point `8x2hkp`, built as tools/sweep.py builds it from the cpu preset.
        Preset::Long => Sizes {
            pretrain_steps: 2 * CPU.pretrain_steps,
            finetune_steps: 2 * CPU.finetune_steps,
            checkpoint_every: 2 * CPU.checkpoint_every,
            moving_still: Some(0.5),
            output: WuOutput::Kernel,
            loss_average: LossAverage::Psnr,
            ..CPU
        },
        Preset::LongStill => Sizes {
            moving_still: Some(1.0),
            ..sizes(Preset::Long)
        },
        Preset::Gpu => Sizes {
            train_sets: 256,
            train_size: (512, 384),
            test_scenes: 48,
            test_size: (512, 384),
            dynamic_scenes: 48,
            base_width: 64,
            res_blocks: 9,
            patch: 256,
            batch: 8,
            pretrain_steps: 20000,
            finetune_steps: 4000,
            pretrain_lr: 1e-4,
            finetune_lr: 5e-5,
            checkpoint_every: 1000,
            seeds: Cow::Borrowed(&[1, 2, 3]),
            backend: "cuda",
            moving_still: None,
            output: WuOutput::Merge,
            loss_average: LossAverage::Pixels,
        },
    }
}
