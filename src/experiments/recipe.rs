//! What the main job and the full protocol build alike: the scene seeds, the shipped
//! profiles, the training configs, the grid's rows (one definition of each of Net_O, the
//! control, Net_R, Net_P and Net_S) and the stages' writing and resuming.

use crate::config::parse_checked;
use crate::data::generate::GenerateConfig;
use crate::data::loader::RealismConfig;
use crate::error::{Error, Result};
use crate::experiments::ablate::{Axis, AxisKind};
use crate::experiments::presets::Sizes;
use crate::models::wu::Linearise;
use crate::models::{ModelConfig, WuConfig, WuVariant};
use crate::sensor::profile::SensorProfile;
use crate::sensor::realism::NoiseModel;
use crate::train::config::{
    DataConfig, InitConfig, LossConfig, OptimConfig, RunConfig, Schedule, ScheduleKind, TrainConfig,
};
use crate::train::{TrainOptions, checkpoint};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Seed of the training scenes, and of the primary test scenes (used for nothing else).
pub(crate) const TRAIN_SCENE_SEED: u64 = 2026;
pub(crate) const TEST_SCENE_SEED: u64 = 7;
/// Sensor profiles shipped with the binary, so the main job needs no files but its own.
/// Net_O's camera: the Canon EOS 550D's measured colour, noise and levels with a gamma-2.2
/// response (Kalantari's Canon 5D data assume that curve).
pub(crate) const PRETRAIN_PROFILE: (&str, &str) = (
    "dslr_canon_550d_gamma22.toml",
    include_str!("../../configs/sensors/dslr_canon_550d_gamma22.toml"),
);
/// The default target device: phone-class noise (OnePlus 6) and colour (Galaxy S9), kind
/// `composite`.
pub(crate) const TARGET_PROFILE: (&str, &str) = (
    "composite_phone.toml",
    include_str!("../../configs/sensors/composite_phone.toml"),
);

/// The target profile's file name, text and profile: `target`, else the shipped composite
/// phone.
pub(crate) fn target_profile(target: Option<&Path>) -> Result<(String, String, SensorProfile)> {
    let (file, text) = match target {
        Some(p) => {
            let text = crate::io::guard::read_text(p)
                .map_err(|e| Error::context(format!("--target {}: cannot read", p.display()), e))?;
            let file = p
                .file_name()
                .map(|f| f.to_string_lossy().into_owned())
                .unwrap_or_else(|| "target.toml".into());
            (file, text)
        }
        None => (TARGET_PROFILE.0.to_string(), TARGET_PROFILE.1.to_string()),
    };
    let at = target.unwrap_or(Path::new(TARGET_PROFILE.0));
    let profile = parse_checked(&text, at, SensorProfile::validate)?;
    let file = if file == PRETRAIN_PROFILE.0 {
        format!("target_{file}")
    } else {
        file
    };
    Ok((file, text, profile))
}

/// Pure synthetic EV −2/0/+2 sets with linear EXRs.
pub(crate) fn generate_config(
    s: &Sizes,
    seed: u64,
    count: usize,
    size: (usize, usize),
) -> GenerateConfig {
    let mut cfg = GenerateConfig::new(seed, count, size, vec![-2.0, 0.0, 2.0]);
    cfg.camera.candidates = if s.train_sets > 64 { 24 } else { 8 };
    cfg
}

/// What differs between the pretraining and the fine-tuning config.
pub(crate) struct Stage<'a> {
    pub(crate) run: &'a Path,
    pub(crate) seed: u64,
    /// A profile path or "pure".
    pub(crate) profile: &'a Path,
    pub(crate) isos: &'a [u32],
    pub(crate) steps: u64,
    pub(crate) lr: f64,
    pub(crate) init: Option<&'a Path>,
}

pub(crate) fn train_config(s: &Sizes, backend: &str, data: &Path, st: &Stage) -> TrainConfig {
    let mut realism = RealismConfig::new(st.profile.to_path_buf(), isos(st.isos));
    realism.noise = NoiseModel::Gaussian;
    TrainConfig {
        run: RunConfig {
            out: st.run.to_path_buf(),
            seed: st.seed,
            steps: st.steps,
            backend: backend.to_string(),
            devices: Vec::new(),
            checkpoint_every: s.checkpoint_every,
            keep_checkpoints: 2,
            log_every: 10,
        },
        // Wu's network with the recipe measured in docs/experiments.md ("Recipe"): the merge
        // head and inputs linearised through the training frames' own curve (the loss stays in
        // Wu's unit: the reference unit measured no gain).
        model: ModelConfig::Wu(WuConfig {
            variant: WuVariant::Resnet,
            base_width: s.base_width,
            res_blocks: s.res_blocks,
            hdr_input_scale: 0.25,
            output: s.output,
            linearise: Linearise::Data,
            ..WuConfig::default()
        }),
        data: DataConfig {
            static_fraction: s.moving_still.unwrap_or(0.0),
            ..DataConfig::new(data.to_path_buf(), s.patch, s.batch, realism)
        },
        optim: OptimConfig {
            lr: st.lr,
            ..OptimConfig::default()
        },
        schedule: Schedule {
            kind: ScheduleKind::Cosine,
            warmup_steps: st.steps / 10,
            min_lr: Some(st.lr / 50.0),
            ..Schedule::default()
        },
        init: st.init.map(|i| InitConfig {
            checkpoint: Some(i.to_path_buf()),
            safetensors: None,
        }),
        loss: LossConfig {
            average: s.loss_average,
            ..LossConfig::default()
        },
        validation: None,
        mix: None,
    }
}

/// ISOs of the target (fine-tuning and test set) and of the DSLR (pretraining).
pub(crate) const TARGET_ISOS: [u32; 3] = [100, 800, 3200];
pub(crate) const DSLR_ISOS: [u32; 2] = [100, 200];

pub(crate) fn isos(list: &[u32]) -> Vec<f64> {
    list.iter().map(|&i| f64::from(i)).collect()
}

/// An ablation row: its name, label and the `set` laid over the fine-tuning config.
pub(crate) fn row(name: &str, label: &str, set: toml::Table) -> Axis {
    Axis {
        name: name.into(),
        label: Some(label.into()),
        set,
        train: true,
        checkpoint: None,
        kind: AxisKind::Finetune,
    }
}

/// Net_O as a grid row: the per-seed pretraining scored as it is.
pub(crate) fn net_o_row() -> Axis {
    Axis {
        train: false,
        ..row(
            "net_o",
            "Net_O (pretrained through the DSLR, no fine-tuning)",
            toml::Table::new(),
        )
    }
}

pub(crate) const CONTROL_LABEL: &str = "control (Net_O trained on its own DSLR data, same steps)";

/// The control row: Net_O trained further on its own pretraining data for the same steps.
pub(crate) fn control_row() -> Axis {
    Axis {
        kind: AxisKind::Control,
        ..row("control", CONTROL_LABEL, toml::Table::new())
    }
}

/// `{ data = { profile = …, isos = …, … } }` as an ablation row's `set`.
pub(crate) fn data_set(
    profile: &Path,
    isos: Option<&[u32]>,
    extra: &[(&str, toml::Value)],
) -> toml::Table {
    let mut data = toml::Table::new();
    data.insert(
        "profile".into(),
        profile.to_string_lossy().into_owned().into(),
    );
    if let Some(isos) = isos {
        let list: Vec<toml::Value> = isos.iter().map(|&i| i64::from(i).into()).collect();
        data.insert("isos".into(), list.into());
    }
    for (k, v) in extra {
        data.insert((*k).into(), v.clone());
    }
    toml::Table::from_iter([("data".to_string(), data.into())])
}

/// The reference row of the primary comparison.
pub(crate) const REFERENCE: &str = "net_r";

/// The primary comparison's reference row: the target's response, levels and exposure rule,
/// no colour and no noise (the fair pure baseline).
pub(crate) fn net_r_row(target: &Path) -> Axis {
    row(
        REFERENCE,
        "Net_R (target response, levels, exposure rule; no colour, no noise)",
        data_set(
            target,
            Some(&TARGET_ISOS),
            &[("noise", "none".into()), ("colour", false.into())],
        ),
    )
}

/// The scene engine's display frames, the paper's pure synthetic data.
pub(crate) fn net_p_row() -> Axis {
    row(
        "net_p",
        "Net_P (engine display frames, the paper's pure synthetic)",
        data_set(Path::new("pure"), None, &[]),
    )
}

/// The full target model: colour, noise, levels and response.
pub(crate) fn net_s_row(target: &Path) -> Axis {
    row(
        "net_s",
        "Net_S (full target model: colour, noise, levels, response)",
        data_set(target, Some(&TARGET_ISOS), &[]),
    )
}

pub(crate) fn write(path: &Path, text: &str) -> Result<()> {
    crate::io::atomic::write_atomic(path, text.as_bytes())
        .map_err(|e| Error::context(format!("writing {}", path.display()), e))
}

/// Write a config as TOML: what the stage then loads, and what a user reruns by hand.
pub(crate) fn write_config(path: &Path, cfg: &impl Serialize) -> Result<()> {
    write(
        path,
        &toml::to_string(cfg).map_err(|e| Error::encode(path, e))?,
    )
}

/// Train the config at `path` to its `run.steps`: from scratch, resumed from its latest
/// checkpoint, or not at all when it got there before.
pub(crate) fn train_resumable(path: &Path, progress: bool) -> Result<()> {
    let cfg = TrainConfig::load(path)?;
    let done = match checkpoint::latest(&cfg.run.out)? {
        Some(d) => Some(checkpoint::read_state(&d)?.step),
        None => None,
    };
    if done.is_none_or(|step| step < cfg.run.steps) {
        crate::train::run(
            &cfg,
            &TrainOptions {
                resume: done.is_some(),
                progress,
            },
        )?;
    }
    Ok(())
}

pub(crate) fn stage(progress: bool, began: Instant, what: &str) {
    if progress {
        eprintln!("[{:>6.1} s] {what}", began.elapsed().as_secs_f64());
    }
}
