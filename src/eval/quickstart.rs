//! The quickstart (`hdrsynth quickstart`): the paper's central claim once, on embedded defaults, in about ten
//! minutes on two CPU cores (README, docs/experiments.md). Generate synthetic EV −2/0/+2 sets;
//! pretrain a small Network-2 (Net_O) through a DSLR-class camera model (the Canon EOS 550D's
//! colour, noise and levels with a gamma-2.2 response at ISO 100–200: the setting of
//! Kalantari's Canon 5D data, from which the paper's Net_O came); fine-tune it for a
//! phone-class target (the composite phone profile) on pure synthetic data (Net_P), on
//! sensor-realistic data (Net_S) and, as a control, on its own pretraining data; once per seed;
//! build a test set from real scene radiance (../shared/data/real_hdr, else generated scenes)
//! through the phone model; evaluate every network and print the seed-aware Experiment-2 table.
//!
//! Training scenes are generated (seed 2026); test scenes are real radiance (or, without it,
//! generated with another seed, 77): nothing is tuned on the test scenes.
//! Every stage resumes: rerunning the command after an interruption keeps what is finished.
//! The configs it runs are written to OUT/configs/ so each stage can be rerun or changed by hand.

use crate::config::parse_toml;
use crate::data::generate::{GenerateConfig, generate};
use crate::data::loader::RealismConfig;
use crate::error::{Error, Result};
use crate::eval::ablate::{self, AblateConfig, Axis, AxisKind, EvalSpec, TestsetSpec};
use crate::models::{ModelConfig, WuConfig, WuVariant};
use crate::sensor::profile::SensorProfile;
use crate::sensor::realism::NoiseModel;
use crate::train::config::{
    DataConfig, InitConfig, LossConfig, OptimConfig, RunConfig, Schedule, ScheduleKind, TrainConfig,
};
use crate::train::{TrainOptions, checkpoint};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Preset {
    /// About 10 minutes on 2 CPU cores: a narrow Network-2, short runs, small crops.
    Cpu,
    /// Wu et al.'s released width and longer runs, for a GPU (pass --backend cuda or wgpu).
    Gpu,
}

/// What a quickstart run is asked for (the command's flags).
#[derive(Clone, Debug)]
pub struct Options {
    /// Output folder (resumes an interrupted quickstart of the same preset).
    pub out: PathBuf,
    pub preset: Preset,
    /// Compute device; default the preset's (flex for cpu, cuda for gpu).
    pub backend: Option<String>,
    /// Real HDR radiance maps for the test set; default ../shared/data/real_hdr when it
    /// exists, else scenes generated here.
    pub radiance: Option<PathBuf>,
    /// The target device's sensor profile; default the shipped composite phone.
    pub target: Option<PathBuf>,
    pub progress: bool,
}

/// The sizes of one preset.
struct Sizes {
    train_sets: usize,
    train_size: (usize, usize),
    base_width: usize,
    res_blocks: usize,
    patch: usize,
    batch: usize,
    pretrain_steps: u64,
    finetune_steps: u64,
    pretrain_lr: f64,
    finetune_lr: f64,
    checkpoint_every: u64,
    seeds: &'static [u64],
    backend: &'static str,
}

fn sizes(p: Preset) -> Sizes {
    match p {
        Preset::Cpu => Sizes {
            train_sets: 40,
            train_size: (160, 128),
            base_width: 8,
            res_blocks: 2,
            patch: 64,
            batch: 8,
            pretrain_steps: 800,
            finetune_steps: 300,
            pretrain_lr: 1e-3,
            finetune_lr: 5e-4,
            checkpoint_every: 100,
            seeds: &[1, 2, 3],
            backend: "flex",
        },
        Preset::Gpu => Sizes {
            train_sets: 256,
            train_size: (512, 384),
            base_width: 64,
            res_blocks: 9,
            patch: 256,
            batch: 8,
            pretrain_steps: 20000,
            finetune_steps: 4000,
            pretrain_lr: 1e-4,
            finetune_lr: 5e-5,
            checkpoint_every: 1000,
            seeds: &[1, 2, 3],
            backend: "cuda",
        },
    }
}

/// Sensor profiles shipped with the binary, so the quickstart needs no files but its own.
/// Net_O's camera: the Canon EOS 550D's measured colour, noise and levels with a gamma-2.2
/// response (Kalantari's Canon 5D data assume that curve).
const PRETRAIN_PROFILE: (&str, &str) = (
    "dslr_canon_550d_gamma22.toml",
    include_str!("../../configs/sensors/dslr_canon_550d_gamma22.toml"),
);
/// The default target device: phone-class noise (OnePlus 6) and colour (Galaxy S9), kind
/// `composite`.
const TARGET_PROFILE: (&str, &str) = (
    "composite_phone.toml",
    include_str!("../../configs/sensors/composite_phone.toml"),
);

/// The target profile's file name, text and profile name: `target`, else the shipped
/// composite phone.
fn target_profile(target: Option<&Path>) -> Result<(String, String, String)> {
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
    let profile: SensorProfile = parse_toml(&text, at)?;
    let name = profile.name.clone();
    let file = if file == PRETRAIN_PROFILE.0 {
        format!("target_{file}")
    } else {
        file
    };
    Ok((file, text, name))
}

/// Pure synthetic EV −2/0/+2 sets with linear EXRs.
fn generate_config(s: &Sizes, seed: u64, count: usize, size: (usize, usize)) -> GenerateConfig {
    let mut cfg = GenerateConfig::new(seed, count, size, vec![-2.0, 0.0, 2.0]);
    cfg.camera.candidates = if s.train_sets > 64 { 24 } else { 8 };
    cfg
}

/// What differs between the pretraining and the fine-tuning config.
struct Stage<'a> {
    run: &'a Path,
    /// A profile path or "pure".
    profile: &'a Path,
    isos: &'a [u32],
    steps: u64,
    lr: f64,
    init: Option<&'a Path>,
}

fn train_config(s: &Sizes, backend: &str, data: &Path, st: &Stage) -> TrainConfig {
    let mut realism = RealismConfig::new(st.profile.to_path_buf(), isos(st.isos));
    realism.noise = NoiseModel::Gaussian;
    TrainConfig {
        run: RunConfig {
            out: st.run.to_path_buf(),
            seed: 2026,
            steps: st.steps,
            backend: backend.to_string(),
            devices: Vec::new(),
            checkpoint_every: s.checkpoint_every,
            keep_checkpoints: 2,
            log_every: 10,
        },
        model: ModelConfig::Wu(WuConfig {
            variant: WuVariant::Resnet,
            base_width: s.base_width,
            res_blocks: s.res_blocks,
            hdr_input_scale: 0.25,
            ..WuConfig::default()
        }),
        data: DataConfig::new(data.to_path_buf(), s.patch, s.batch, realism),
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
        loss: LossConfig::default(),
        validation: None,
    }
}

/// ISOs of the phone target (fine-tuning and test set) and of the DSLR (pretraining).
const TARGET_ISOS: [u32; 3] = [100, 800, 3200];
const DSLR_ISOS: [u32; 2] = [100, 200];

fn isos(list: &[u32]) -> Vec<f64> {
    list.iter().map(|&i| f64::from(i)).collect()
}

/// An ablation row: its name, label and the `set` laid over the fine-tuning config.
fn row(name: &str, label: &str, set: toml::Table) -> Axis {
    Axis {
        name: name.into(),
        label: Some(label.into()),
        set,
        train: true,
        checkpoint: None,
        kind: AxisKind::Finetune,
    }
}

/// `{ data = { profile = …, isos = … } }` as an ablation row's `set`.
fn data_set(profile: &Path, isos: Option<&[u32]>) -> toml::Table {
    let mut data = toml::Table::new();
    data.insert(
        "profile".into(),
        profile.to_string_lossy().into_owned().into(),
    );
    if let Some(isos) = isos {
        let list: Vec<toml::Value> = isos.iter().map(|&i| i64::from(i).into()).collect();
        data.insert("isos".into(), list.into());
    }
    toml::Table::from_iter([("data".to_string(), data.into())])
}

fn experiment_config(
    s: &Sizes,
    out: &Path,
    base: &Path,
    testset: &Path,
    radiance: &Path,
    target: &Path,
) -> AblateConfig {
    let mut testset = TestsetSpec {
        dir: testset.to_path_buf(),
        radiance: Some(radiance.to_path_buf()),
        profile: Some(target.to_path_buf()),
        options: Default::default(),
    };
    testset.options.isos = isos(&TARGET_ISOS);
    testset.options.evs = vec![-2.0, 0.0, 2.0];
    AblateConfig {
        title: "Quickstart — Experiment 2 shape: Network-2 Net_O (pretrained through a DSLR) vs \
                control vs Net_P vs Net_S for the target device"
            .into(),
        out: out.join("experiment"),
        base: base.to_path_buf(),
        seeds: s.seeds.to_vec(),
        testset,
        eval: EvalSpec {
            resamples: 2000,
            reference: Some("net_p".into()),
            ..EvalSpec::default()
        },
        rows: vec![
            Axis {
                train: false,
                ..row(
                    "net_o",
                    "Net_O (pretrained through the DSLR, no fine-tuning)",
                    toml::Table::new(),
                )
            },
            Axis {
                kind: AxisKind::Control,
                ..row(
                    "control",
                    "Net_O trained on (its own DSLR data, same steps)",
                    toml::Table::new(),
                )
            },
            row(
                "net_p",
                "Net_P (fine-tuned, pure synthetic)",
                data_set(Path::new("pure"), None),
            ),
            row(
                "net_s",
                "Net_S (fine-tuned, sensor-realistic target)",
                data_set(target, Some(&TARGET_ISOS)),
            ),
        ],
        columns: Vec::new(),
    }
}

fn write(path: &Path, text: &str) -> Result<()> {
    crate::io::atomic::write_atomic(path, text.as_bytes())
        .map_err(|e| Error::context(format!("writing {}", path.display()), e))
}

/// Write a config as TOML: what the stage then loads, and what a user reruns by hand.
fn write_config(path: &Path, cfg: &impl Serialize) -> Result<()> {
    write(
        path,
        &toml::to_string(cfg).map_err(|e| Error::encode(path, e))?,
    )
}

fn stage(progress: bool, began: Instant, what: &str) {
    if progress {
        eprintln!("[{:>6.1} s] {what}", began.elapsed().as_secs_f64());
    }
}

fn io_context(what: String) -> impl FnOnce(std::io::Error) -> Error {
    move |e| Error::context(what, e)
}

/// Real radiance for the test set: `opts.radiance`, ../shared/data/real_hdr, or generated
/// scenes' linear ground truth (copied into one folder, as `testset` reads a folder of maps).
fn radiance_source(opts: &Options, s: &Sizes, target: &str) -> Result<(PathBuf, String)> {
    if let Some(r) = &opts.radiance {
        if !r.exists() {
            return Err(Error::Invalid(format!(
                "--radiance {}: no such file or folder",
                r.display()
            )));
        }
        return Ok((r.clone(), format!("real radiance from {}", r.display())));
    }
    let shared = Path::new("../shared/data/real_hdr");
    if shared.is_dir() {
        return Ok((
            shared.to_path_buf(),
            format!(
                "real scene radiance ({}: Carrots, Desk, MtTamNorth) through the target's \
                 model ({target}); training scenes are generated",
                shared.display()
            ),
        ));
    }
    let scenes = opts.out.join("data/scenes");
    let cfg = generate_config(s, 77, 3, (s.train_size.0 * 2, s.train_size.1 * 2));
    generate(&cfg, &scenes, opts.progress)?;
    let dir = opts.out.join("data/radiance");
    std::fs::create_dir_all(&dir).map_err(io_context(format!("creating {}", dir.display())))?;
    let entries =
        std::fs::read_dir(&scenes).map_err(io_context(format!("reading {}", scenes.display())))?;
    for e in entries {
        let set = e
            .map_err(|e| Error::context(format!("reading {}", scenes.display()), e))?
            .path();
        let gt = set.join("hdr_gt.exr");
        if gt.is_file() {
            let name = set
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            let to = dir.join(format!("{name}.exr"));
            if !to.is_file() {
                std::fs::copy(&gt, &to).map_err(io_context(format!(
                    "copying {} to {}",
                    gt.display(),
                    to.display()
                )))?;
            }
        }
    }
    Ok((
        dir,
        format!(
            "generated scenes' radiance (../shared/data/real_hdr is absent; scene seed 77, \
             training seed 2026) through the target's model ({target})"
        ),
    ))
}

/// Run the quickstart (every stage resumes) and return its report: the Experiment-2 table.
pub fn run(opts: &Options) -> Result<String> {
    let began = Instant::now();
    let progress = opts.progress;
    let s = sizes(opts.preset);
    let backend = opts.backend.as_deref().unwrap_or(s.backend);
    let out = &opts.out;
    // One quickstart per folder: a second would rewrite the configs the first is reading. The
    // commands it runs lock their own subfolders (data/…, pretrain, experiment).
    let _lock = crate::io::guard::OutputLock::acquire(out, "quickstart")?;
    let configs = out.join("configs");
    let sensors = configs.join("sensors");
    std::fs::create_dir_all(&sensors)
        .map_err(io_context(format!("creating {}", sensors.display())))?;
    let pre_profile = sensors.join(PRETRAIN_PROFILE.0);
    let (target_file, target_text, target_name) = target_profile(opts.target.as_deref())?;
    let target = sensors.join(target_file);
    write(&pre_profile, PRETRAIN_PROFILE.1)?;
    write(&target, &target_text)?;

    stage(progress, began, "1/4 synthetic training sets (EV −2/0/+2)");
    let data = out.join("data/train");
    let gen_path = configs.join("train_data.toml");
    write_config(
        &gen_path,
        &generate_config(&s, 2026, s.train_sets, s.train_size),
    )?;
    generate(&GenerateConfig::load(&gen_path)?, &data, progress)?;

    stage(
        progress,
        began,
        "2/4 pretraining Network-2 (Net_O) through a DSLR model (550D, gamma 2.2, ISO 100–200)",
    );
    let pre_run = out.join("pretrain");
    let pre_path = configs.join("pretrain.toml");
    write_config(
        &pre_path,
        &train_config(
            &s,
            backend,
            &data,
            &Stage {
                run: &pre_run,
                profile: &pre_profile,
                isos: &DSLR_ISOS,
                steps: s.pretrain_steps,
                lr: s.pretrain_lr,
                init: None,
            },
        ),
    )?;
    let pre_cfg = TrainConfig::load(&pre_path)?;
    let done = match checkpoint::latest(&pre_run)? {
        Some(d) => Some(checkpoint::read_state(&d)?.step),
        None => None,
    };
    if done.is_none_or(|step| step < s.pretrain_steps) {
        crate::train::run(
            &pre_cfg,
            &TrainOptions {
                resume: done.is_some(),
                progress,
            },
        )
        .map_err(|e| Error::context(format!("pretraining ({})", pre_path.display()), e))?;
    }

    stage(
        progress,
        began,
        "3/4 test set (real radiance; generated scenes without it)",
    );
    let (radiance, test_note) = radiance_source(opts, &s, &target_name)?;
    let base_path = configs.join("finetune.toml");
    write_config(
        &base_path,
        &train_config(
            &s,
            backend,
            &data,
            &Stage {
                run: &out.join("unused"),
                profile: Path::new("pure"),
                isos: &TARGET_ISOS,
                steps: s.finetune_steps,
                lr: s.finetune_lr,
                init: Some(&pre_run),
            },
        ),
    )?;
    let exp_path = configs.join("experiment.toml");
    write_config(
        &exp_path,
        &experiment_config(
            &s,
            out,
            &base_path,
            &out.join("data/testset"),
            &radiance,
            &target,
        ),
    )?;

    stage(
        progress,
        began,
        "4/4 per seed: control, Net_P and Net_S fine-tuned; all four evaluated (hdrsynth ablate)",
    );
    let exp = AblateConfig::load(&exp_path)?;
    let summary = ablate::run(&exp, &exp_path, progress)
        .map_err(|e| Error::context("the Experiment-2 grid", e))?;
    let mut report = ablate::report(&exp, &summary);
    let _ = write!(
        report,
        "\n\nTest set: {test_note}.\nTotal {:.1} s ({} preset, backend {backend}). Configs in {} \
         (rerun a stage with `hdrsynth train --config …` or `hdrsynth ablate --config {}`).",
        began.elapsed().as_secs_f64(),
        match opts.preset {
            Preset::Cpu => "cpu",
            Preset::Gpu => "gpu",
        },
        configs.display(),
        exp_path.display()
    );
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::profile::Response;

    /// The shipped DSLR profile is the 550D's with only its response replaced.
    #[test]
    fn the_dslr_profile_is_the_550d_with_a_gamma_response() {
        let dslr: SensorProfile =
            parse_toml(PRETRAIN_PROFILE.1, Path::new("d.toml")).expect("dslr profile parses");
        assert_eq!(dslr.response, Response::Gamma { gamma: 2.2 });
        let canon: SensorProfile = parse_toml(
            include_str!("../../configs/sensors/canon_eos_550d.toml"),
            Path::new("c.toml"),
        )
        .expect("550D profile parses");
        assert_eq!(dslr.colour, canon.colour);
        assert_eq!(dslr.noise, canon.noise);
        assert_eq!(dslr.levels, canon.levels);
        assert_eq!(dslr.provenance.noise, canon.provenance.noise);
    }

    /// Serialise, parse back: the value the stage will load.
    fn round_trip<T: Serialize + serde::de::DeserializeOwned>(cfg: &T) -> T {
        let text = toml::to_string(cfg).expect("serialise");
        parse_toml(&text, Path::new("written.toml")).expect(&text)
    }

    /// The configs the quickstart writes read back to the values it built, and validate, for
    /// both presets (the full run is too long for the test suite; its table and time are in
    /// the README).
    #[test]
    fn every_config_the_quickstart_writes_reads_back_and_validates() {
        let root = Path::new("/r");
        let profile = root.join(TARGET_PROFILE.0);
        for preset in [Preset::Cpu, Preset::Gpu] {
            let s = sizes(preset);
            let gen_cfg = generate_config(&s, 1, s.train_sets, s.train_size);
            assert_eq!(round_trip(&gen_cfg), gen_cfg);
            gen_cfg.validate().expect("valid generate config");
            for st in stages(&s, &root.join("pre"), &root.join("ft"), &profile) {
                let cfg = train_config(&s, s.backend, &root.join("data"), &st);
                assert_eq!(round_trip(&cfg), cfg);
                cfg.validate().expect("valid train config");
                assert_eq!(cfg.run.steps, st.steps);
            }
            let exp = experiment_config(&s, root, &root.join("ft.toml"), root, root, &profile);
            assert_eq!(round_trip(&exp), exp);
            assert_eq!(exp.eval.reference.as_deref(), Some("net_p"));
            assert_eq!(exp.rows.len(), 4);
        }
    }

    /// The pretraining and fine-tuning stages as `run` builds them.
    fn stages<'a>(s: &Sizes, pre: &'a Path, unused: &'a Path, profile: &'a Path) -> [Stage<'a>; 2] {
        [
            Stage {
                run: pre,
                profile,
                isos: &DSLR_ISOS,
                steps: s.pretrain_steps,
                lr: s.pretrain_lr,
                init: None,
            },
            Stage {
                run: unused,
                profile: Path::new("pure"),
                isos: &TARGET_ISOS,
                steps: s.finetune_steps,
                lr: s.finetune_lr,
                init: Some(pre),
            },
        ]
    }

    /// The cpu preset's configs are the values of the files the quickstart wrote before it
    /// built them as values (its `format!` text, kept here as the oracle), so its results and
    /// a resumed run's identity are unchanged.
    #[test]
    fn the_cpu_configs_are_the_ones_written_before() {
        let s = sizes(Preset::Cpu);
        let root = Path::new("/r");
        let dslr = root.join("configs/sensors").join(PRETRAIN_PROFILE.0);
        let target = root.join("configs/sensors").join(TARGET_PROFILE.0);
        let old_gen: GenerateConfig = parse_toml(
            "# Pure synthetic EV −2/0/+2 sets with linear EXRs (hdrsynth generate).\n\
             seed = 2026\ncount = 40\nwidth = 160\nheight = 128\nevs = [-2.0, 0.0, 2.0]\n\
             write_linear = true\n[camera]\ncandidates = 8\n",
            Path::new("train_data.toml"),
        )
        .expect("old generate config");
        assert_eq!(
            generate_config(&s, 2026, s.train_sets, s.train_size),
            old_gen
        );
        let old_train = |out: &str, profile: &str, isos: &str, steps, lr, min_lr, init: &str| {
            let text = format!(
                "[run]\nout = \"{out}\"\nseed = 2026\nsteps = {steps}\nbackend = \"flex\"\n\
                 checkpoint_every = 100\nkeep_checkpoints = 2\nlog_every = 10\n\n\
                 [model]\nkind = \"wu\"\nvariant = \"resnet\"\nbase_width = 8\n\
                 res_blocks = 2\nhdr_input_scale = 0.25\n\n\
                 [data]\ndataset = \"/r/data/train\"\npatch = 64\nbatch_size = 8\n\
                 workers = 2\naugment = true\nprofile = \"{profile}\"\nisos = {isos}\n\
                 noise = \"gaussian\"\n\n[optim]\nlr = {lr}\n\n[schedule]\n\
                 kind = \"cosine\"\nwarmup_steps = {}\nmin_lr = {min_lr}\n{init}",
                steps / 10
            );
            parse_toml::<TrainConfig>(&text, Path::new("train.toml")).expect(&text)
        };
        let (pre_run, unused) = (root.join("pretrain"), root.join("unused"));
        let [pre, ft] = stages(&s, &pre_run, &unused, &dslr);
        let data = root.join("data/train");
        assert_eq!(
            train_config(&s, "flex", &data, &pre),
            old_train(
                "/r/pretrain",
                "/r/configs/sensors/dslr_canon_550d_gamma22.toml",
                "[100, 200]",
                800,
                "1e-3",
                "2e-5",
                ""
            )
        );
        assert_eq!(
            train_config(&s, "flex", &data, &ft),
            old_train(
                "/r/unused",
                "pure",
                "[100, 800, 3200]",
                300,
                "5e-4",
                "1e-5",
                "\n[init]\ncheckpoint = \"/r/pretrain\"\n"
            )
        );
        let old_exp: AblateConfig = parse_toml(
            "title = \"Quickstart — Experiment 2 shape: Network-2 Net_O (pretrained through a \
             DSLR) vs control vs Net_P vs Net_S for the target device\"\n\
             out = \"/r/experiment\"\nbase = \"/r/configs/finetune.toml\"\nseeds = [1, 2, 3]\n\n\
             [testset]\ndir = \"/r/data/testset\"\nradiance = \"/rad\"\n\
             profile = \"/r/configs/sensors/composite_phone.toml\"\n\
             [testset.options]\nisos = [100, 800, 3200]\nevs = [-2.0, 0.0, 2.0]\n\n\
             [eval]\nresamples = 2000\nreference = \"net_p\"\n\n\
             [[rows]]\nname = \"net_o\"\n\
             label = \"Net_O (pretrained through the DSLR, no fine-tuning)\"\ntrain = false\n\n\
             [[rows]]\nname = \"control\"\n\
             label = \"Net_O trained on (its own DSLR data, same steps)\"\nkind = \"control\"\n\n\
             [[rows]]\nname = \"net_p\"\nlabel = \"Net_P (fine-tuned, pure synthetic)\"\n\
             set = { data = { profile = \"pure\" } }\n\n\
             [[rows]]\nname = \"net_s\"\nlabel = \"Net_S (fine-tuned, sensor-realistic target)\"\n\
             set = { data = { profile = \"/r/configs/sensors/composite_phone.toml\", \
             isos = [100, 800, 3200] } }\n",
            Path::new("experiment.toml"),
        )
        .expect("old experiment config");
        assert_eq!(
            experiment_config(
                &s,
                root,
                &root.join("configs/finetune.toml"),
                &root.join("data/testset"),
                Path::new("/rad"),
                &target
            ),
            old_exp
        );
    }
}
