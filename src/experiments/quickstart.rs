//! The main job (`hdrsynth quickstart`): the primary comparison of docs/protocol.md at CPU
//! scale, on embedded defaults. Generate synthetic EV −2/0/+2 training sets; per seed, pretrain
//! a small Network-2 (Net_O) through a DSLR-class camera model (the Canon EOS 550D's colour,
//! noise and levels with a gamma-2.2 response at ISO 100–200) and fine-tune it for the target
//! device (default: the composite phone profile) four ways — the full device model (Net_S), the
//! device's response, levels and exposure rule only (Net_R, the fair pure baseline and the
//! reference), the scene engine's display frames (Net_P) and, as a control, its own DSLR data;
//! score every network on the primary test set (24 held-out scene-engine scenes through the
//! target model, test noise redrawn per seed), on real radiance and on a real capture where
//! they exist; print the tables with paired tests, the noise ceiling and the protocol's decision.
//!
//! Nothing is tuned on the test scenes (scene seed 7 is used for nothing else). Every stage
//! resumes: rerunning the command after an interruption keeps what is finished. The configs it
//! runs are written to OUT/configs/ so each stage can be rerun or changed by hand.

use crate::config::parse_checked;
use crate::data::generate::{GenerateConfig, generate};
use crate::data::loader::RealismConfig;
use crate::error::{Error, Result};
use crate::eval::evaluate::{self, EvalOptions, TriangleMerge};
use crate::experiments::ablate::{
    self, AblateConfig, Axis, AxisKind, DiffEntry, EvalSpec, TestsetSpec,
};
use crate::models::{ModelConfig, WuConfig, WuVariant};
use crate::sensor::metering::Metering;
use crate::sensor::profile::Response;
use crate::sensor::profile::SensorProfile;
use crate::sensor::realism::NoiseModel;
use crate::train;
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
    /// Real HDR radiance maps for the descriptive real-radiance table; default
    /// ../shared/data/real_hdr when it exists.
    pub radiance: Option<PathBuf>,
    /// A real bracket folder for the real-capture table; default
    /// ../shared/data/real_brackets/canon_550d_room when it exists.
    pub brackets: Option<PathBuf>,
    /// The target device's sensor profile; default the shipped composite phone.
    pub target: Option<PathBuf>,
    /// Also score every network on the held-out-simulator renderings of the primary scenes
    /// (docs/protocol.md, full protocol part 1).
    pub heldout: bool,
    pub progress: bool,
}

/// The sizes of one preset.
pub(crate) struct Sizes {
    pub(crate) train_sets: usize,
    pub(crate) train_size: (usize, usize),
    pub(crate) test_scenes: usize,
    pub(crate) test_size: (usize, usize),
    pub(crate) base_width: usize,
    pub(crate) res_blocks: usize,
    pub(crate) patch: usize,
    pub(crate) batch: usize,
    pub(crate) pretrain_steps: u64,
    pub(crate) finetune_steps: u64,
    pub(crate) pretrain_lr: f64,
    pub(crate) finetune_lr: f64,
    pub(crate) checkpoint_every: u64,
    pub(crate) seeds: &'static [u64],
    pub(crate) backend: &'static str,
}

pub(crate) fn sizes(p: Preset) -> Sizes {
    match p {
        Preset::Cpu => Sizes {
            train_sets: 40,
            train_size: (160, 128),
            test_scenes: 24,
            test_size: (192, 144),
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
            test_scenes: 48,
            test_size: (512, 384),
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

/// Seed of the training scenes, and of the primary test scenes (used for nothing else).
pub(crate) const TRAIN_SCENE_SEED: u64 = 2026;
pub(crate) const TEST_SCENE_SEED: u64 = 7;
/// Test scenes need at least this range (stops); an EV −2/0/+2 bracket holds about 12.
const TEST_MIN_DYNAMIC_RANGE: f32 = 10.0;

/// Sensor profiles shipped with the binary, so the main job needs no files but its own.
/// Net_O's camera: the Canon EOS 550D's measured colour, noise and levels with a gamma-2.2
/// response (Kalantari's Canon 5D data assume that curve).
pub(crate) const PRETRAIN_PROFILE: (&str, &str) = (
    "dslr_canon_550d_gamma22.toml",
    include_str!("../../configs/sensors/dslr_canon_550d_gamma22.toml"),
);
/// The default target device: phone-class noise (OnePlus 6) and colour (Galaxy S9), kind
/// `composite`.
const TARGET_PROFILE: (&str, &str) = (
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

/// The primary test scenes: the scene engine at another seed, static, with the dynamic range
/// a bracket can hold (docs/protocol.md, "Data").
fn test_scene_config(s: &Sizes) -> GenerateConfig {
    let mut cfg = generate_config(s, TEST_SCENE_SEED, s.test_scenes, s.test_size);
    cfg.scene.min_dynamic_range = TEST_MIN_DYNAMIC_RANGE;
    cfg.scene.subjects = [0, 0];
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

/// The control row: Net_O trained further on its own DSLR data for the same steps.
pub(crate) fn control_row() -> Axis {
    Axis {
        kind: AxisKind::Control,
        ..row(
            "control",
            "control (Net_O trained on its own DSLR data, same steps)",
            toml::Table::new(),
        )
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
const REFERENCE: &str = "net_r";

/// The held-out simulators: the primary scenes rendered through variants of the target model
/// that are not the training simulator (docs/protocol.md, full protocol part 1): (name, label,
/// the profile's response replaced, noise model, metering).
struct Heldout {
    name: &'static str,
    label: &'static str,
    response: Option<Response>,
    noise: NoiseModel,
    metering: Option<Metering>,
}

const HELDOUT: [Heldout; 4] = [
    Heldout {
        name: "heldout_gamma22",
        label: "held-out simulator: the target's response replaced by γ 2.2",
        response: Some(Response::Gamma { gamma: 2.2 }),
        noise: NoiseModel::Gaussian,
        metering: None,
    },
    Heldout {
        name: "heldout_filmic",
        label: "held-out simulator: the target's response replaced by the filmic curve",
        response: Some(Response::Filmic),
        noise: NoiseModel::Gaussian,
        metering: None,
    },
    Heldout {
        name: "heldout_poisson",
        label: "held-out simulator: Poisson shot noise plus Gaussian read noise",
        response: None,
        noise: NoiseModel::PoissonGaussian,
        metering: None,
    },
    Heldout {
        name: "heldout_metering",
        label: "held-out simulator: another metering rule (mid grey 0.18, 5 % clipped)",
        response: None,
        noise: NoiseModel::Gaussian,
        metering: Some(Metering {
            mid_grey: 0.18,
            max_clipped: 0.05,
        }),
    },
];

/// The held-out test sets' specs, writing each variant's profile beside the target's.
fn heldout_testsets(
    out: &Path,
    scenes: &Path,
    target: &SensorProfile,
    sensors: &Path,
) -> Result<Vec<TestsetSpec>> {
    HELDOUT
        .iter()
        .map(|h| {
            let mut profile = target.clone();
            if let Some(r) = &h.response {
                profile.response = r.clone();
            }
            let path = sensors.join(format!("{}.toml", h.name));
            write_config(&path, &profile)?;
            let mut options = crate::data::testset::TestsetOptions {
                isos: isos(&TARGET_ISOS),
                evs: vec![-2.0, 0.0, 2.0],
                noise: h.noise,
                ..Default::default()
            };
            if let Some(m) = h.metering {
                options.metering = m;
            }
            Ok(TestsetSpec {
                name: Some(h.name.into()),
                label: Some(h.label.into()),
                dir: out.join(format!("data/testset_{}", h.name)),
                radiance: Some(scenes.to_path_buf()),
                profile: Some(path),
                options,
                noise_per_seed: false,
                reference: None,
            })
        })
        .collect()
}

/// Where the test sets come from.
struct TestSources {
    /// Generated scenes' radiance (the primary test set).
    scenes: PathBuf,
    /// Real radiance maps, if any.
    real_radiance: Option<PathBuf>,
    /// A built real-capture test set, if any.
    real_capture: Option<PathBuf>,
}

fn experiment_config(
    s: &Sizes,
    out: &Path,
    base: &Path,
    src: &TestSources,
    target: &Path,
) -> AblateConfig {
    let mut options = crate::data::testset::TestsetOptions {
        isos: isos(&TARGET_ISOS),
        evs: vec![-2.0, 0.0, 2.0],
        ..Default::default()
    };
    let testset = TestsetSpec {
        name: None,
        label: None,
        dir: out.join("data/testset"),
        radiance: Some(src.scenes.clone()),
        profile: Some(target.to_path_buf()),
        options: options.clone(),
        noise_per_seed: true,
        reference: None,
    };
    let mut also = Vec::new();
    if let Some(r) = &src.real_radiance {
        options.seed = 0;
        also.push(TestsetSpec {
            name: Some("real_radiance".into()),
            label: Some("real radiance through the target model (descriptive)".into()),
            dir: out.join("data/testset_real_radiance"),
            radiance: Some(r.clone()),
            profile: Some(target.to_path_buf()),
            options,
            noise_per_seed: false,
            reference: None,
        });
    }
    if let Some(c) = &src.real_capture {
        also.push(TestsetSpec {
            name: Some("real_capture".into()),
            label: Some("a real capture (descriptive)".into()),
            dir: c.clone(),
            radiance: None,
            profile: None,
            options: Default::default(),
            noise_per_seed: false,
            reference: None,
        });
    }
    let target_row = |name: &str, label: &str, extra: &[(&str, toml::Value)]| {
        row(name, label, data_set(target, Some(&TARGET_ISOS), extra))
    };
    AblateConfig {
        title: "Main job — Network-2 for the target device: Net_S (full device model) vs Net_R \
                (response, levels and exposure rule only), Net_P, Net_O and the control"
            .into(),
        out: out.join("experiment"),
        base: base.to_path_buf(),
        seeds: s.seeds.to_vec(),
        pretrained_per_seed: Some(
            out.join("pretrain/seed{seed}")
                .to_string_lossy()
                .into_owned(),
        ),
        testset,
        also,
        eval: EvalSpec {
            resamples: 2000,
            reference: Some(REFERENCE.into()),
            ..EvalSpec::default()
        },
        rows: vec![
            net_o_row(),
            control_row(),
            target_row(
                REFERENCE,
                "Net_R (target response, levels, exposure rule; no colour, no noise)",
                &[("noise", "none".into()), ("colour", false.into())],
            ),
            row(
                "net_p",
                "Net_P (engine display frames, the paper's pure synthetic)",
                data_set(Path::new("pure"), None, &[]),
            ),
            target_row(
                "net_s",
                "Net_S (full target model: colour, noise, levels, response)",
                &[],
            ),
        ],
        columns: Vec::new(),
    }
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

/// The generated test scenes' linear radiance (`hdr_gt.exr` of each set), copied into one
/// folder, as `testset` reads a folder of maps.
fn test_scenes(opts: &Options, s: &Sizes) -> Result<PathBuf> {
    let scenes = opts.out.join("data/test_scenes");
    generate(&test_scene_config(s), &scenes, opts.progress)?;
    let dir = opts.out.join("data/test_radiance");
    std::fs::create_dir_all(&dir)
        .map_err(|e| Error::context(format!("creating {}", dir.display()), e))?;
    let entries = std::fs::read_dir(&scenes)
        .map_err(|e| Error::context(format!("reading {}", scenes.display()), e))?;
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
                let tmp = dir.join(format!(".{name}.exr.tmp"));
                std::fs::copy(&gt, &tmp).map_err(|e| {
                    Error::context(format!("copying {} to {}", gt.display(), tmp.display()), e)
                })?;
                std::fs::rename(&tmp, &to)
                    .map_err(|e| Error::context(format!("renaming {}", tmp.display()), e))?;
            }
        }
    }
    Ok(dir)
}

/// A flag's folder, else the shared data's default when it exists. Returns the folder or why
/// there is none.
fn optional_source(
    flag: Option<&PathBuf>,
    name: &str,
    default: &str,
) -> Result<std::result::Result<PathBuf, String>> {
    if let Some(p) = flag {
        return if p.exists() {
            Ok(Ok(p.clone()))
        } else {
            Err(Error::Invalid(format!(
                "--{name} {}: no such file or folder",
                p.display()
            )))
        };
    }
    let d = Path::new(default);
    Ok(if d.is_dir() {
        Ok(d.to_path_buf())
    } else {
        Err(format!("{default} is absent; pass --{name} DIR"))
    })
}

/// The real-capture test set: three frames two stops apart chosen by the frames' own metering,
/// ground truth merged from every frame, linearised by a Debevec response estimated from the
/// brackets (`hdrsynth testset --brackets --inputs auto --gt-frames all`).
fn real_capture(brackets: &Path, out: &Path) -> Result<PathBuf> {
    use crate::data::bracket_testset::{self, BracketOptions, GtFrames, InputChoice};
    use crate::data::brackets::ScanOptions;
    let dir = out.join("data/testset_real_capture");
    if !dir.is_dir() {
        // Built beside and renamed when complete, so an interrupted build is redone.
        let partial = out.join("data/testset_real_capture.partial");
        if partial.exists() {
            std::fs::remove_dir_all(&partial).map_err(|e| Error::io(&partial, e))?;
        }
        let opts = BracketOptions {
            // A tripod bracket may take minutes (the 550D's spans 101 s): frames group into a
            // set until an exposure repeats or an hour passes.
            scan: ScanOptions {
                max_gap_s: 3600.0,
                ..ScanOptions::default()
            },
            inputs: InputChoice::Auto,
            gt_frames: GtFrames::All,
            ..BracketOptions::default()
        };
        bracket_testset::build(brackets, &opts, &partial)?;
        std::fs::rename(&partial, &dir).map_err(|e| Error::io(&dir, e))?;
    }
    Ok(dir)
}

/// The noise ceiling of the primary test set: the triangle merge with the true response, of
/// the noisy frames and of the noise-free ones; mean over seeds of the mean over scenes of each
/// metric (`report::METRICS` order of `metrics`).
fn noise_ceiling(
    cfg: &AblateConfig,
    response: &Response,
    out: &Path,
    progress: bool,
) -> Result<[(f64, f64); 4]> {
    let mut sums = [(0.0, 0.0); 4];
    for &k in &cfg.seeds {
        let testset = cfg.testset.dir_for(Some(k));
        let mut pair = [0.0f64; 8];
        for (ci, clean) in [false, true].into_iter().enumerate() {
            let method = TriangleMerge {
                response: response.clone(),
                clean,
            };
            let dir = out.join(format!("seed{k}/{}", if clean { "clean" } else { "noisy" }));
            let partial = dir.with_extension("partial");
            if partial.exists() {
                std::fs::remove_dir_all(&partial).map_err(|e| Error::io(&partial, e))?;
            }
            let sum = evaluate::evaluate(
                &testset,
                &method,
                &partial,
                &EvalOptions {
                    progress: false,
                    ..EvalOptions::default()
                },
            )?;
            if dir.exists() {
                std::fs::remove_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
            }
            std::fs::rename(&partial, &dir).map_err(|e| Error::io(&dir, e))?;
            for (mi, m) in ["psnr_t", "psnr_l", "ssim_t", "ssim_l"].iter().enumerate() {
                let v = sum
                    .summary
                    .iter()
                    .find(|x| x.metric == *m)
                    .map_or(f64::NAN, |x| x.mean);
                pair[ci * 4 + mi] = v;
            }
        }
        for mi in 0..4 {
            sums[mi].0 += pair[mi] / cfg.seeds.len() as f64;
            sums[mi].1 += pair[4 + mi] / cfg.seeds.len() as f64;
        }
        if progress {
            eprintln!(
                "noise ceiling, seed {k}: triangle merge PSNR-T noisy {:.2} / noise-free {:.2}",
                pair[0], pair[4]
            );
        }
    }
    Ok(sums)
}

/// The protocol's decision on the primary comparison (docs/protocol.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    Better,
    Worse,
    Equivalent,
    Inconclusive,
}

impl Decision {
    pub fn from_diff(d: &DiffEntry, alpha: f64) -> Decision {
        let Some(t) = &d.t else {
            return Decision::Inconclusive;
        };
        let p = d.wilcoxon_p.unwrap_or(1.0);
        let all_seeds = d.sign_holds == d.n_seeds;
        if t.ci_lower > 0.0 && p < alpha && all_seeds {
            Decision::Better
        } else if t.ci_upper < 0.0 && p < alpha && all_seeds {
            Decision::Worse
        } else if d.tost_p.is_some_and(|p| p < alpha) {
            Decision::Equivalent
        } else {
            Decision::Inconclusive
        }
    }

    fn text(self, margin: f64) -> String {
        match self {
            Decision::Better => "Net_S is better than Net_R".into(),
            Decision::Worse => "Net_S is worse than Net_R".into(),
            Decision::Equivalent => {
                format!("no effect larger than {margin} dB: Net_S and Net_R are equivalent")
            }
            Decision::Inconclusive => "inconclusive at this size".into(),
        }
    }
}

/// A signed dB value with a typographic minus, as the tables print it.
fn signed_db(v: f64) -> String {
    format!("{}{:.2}", if v < 0.0 { "−" } else { "+" }, v.abs())
}

/// One comparison for the reading: "+x dB [lo, hi], Wilcoxon p …, TOST p …, sign in k/n seeds".
fn describe_diff(d: &DiffEntry) -> String {
    let mut text = format!("{} dB", signed_db(d.mean));
    if let Some(t) = &d.t {
        let _ = write!(
            text,
            " [{}, {}]",
            signed_db(t.ci_lower),
            signed_db(t.ci_upper)
        );
    }
    if let Some(p) = d.wilcoxon_p {
        let _ = write!(text, ", Wilcoxon p {}", ablate::format_p(p));
    }
    if let Some(p) = d.tost_p {
        let _ = write!(text, ", TOST (±{} dB) p {}", d.margin, ablate::format_p(p));
    }
    let _ = write!(text, ", sign in {}/{} seeds", d.sign_holds, d.n_seeds);
    text
}

/// Run the main job (every stage resumes) and return its report.
pub fn run(opts: &Options) -> Result<String> {
    let began = Instant::now();
    let progress = opts.progress;
    let s = sizes(opts.preset);
    let backend = opts.backend.as_deref().unwrap_or(s.backend);
    let out = &opts.out;
    // One main job per folder: a second would rewrite the configs the first is reading. The
    // commands it runs lock their own subfolders (data/…, pretrain, experiment).
    let _lock = crate::io::guard::OutputLock::acquire(out, "quickstart")?;
    if out.join("pretrain").join(train::RUN_CONFIG).is_file() {
        return Err(Error::Invalid(format!(
            "{} holds a main job of an earlier protocol (one pretraining for every seed); \
             choose another --out or delete it",
            out.display()
        )));
    }
    let configs = out.join("configs");
    let sensors = configs.join("sensors");
    std::fs::create_dir_all(&sensors)
        .map_err(|e| Error::context(format!("creating {}", sensors.display()), e))?;
    let pre_profile = sensors.join(PRETRAIN_PROFILE.0);
    let (target_file, target_text, target_profile) = target_profile(opts.target.as_deref())?;
    let target = sensors.join(target_file);
    write(&pre_profile, PRETRAIN_PROFILE.1)?;
    write(&target, &target_text)?;

    stage(progress, began, "1/5 synthetic training sets (EV −2/0/+2)");
    let data = out.join("data/train");
    let gen_path = configs.join("train_data.toml");
    write_config(
        &gen_path,
        &generate_config(&s, TRAIN_SCENE_SEED, s.train_sets, s.train_size),
    )?;
    generate(&GenerateConfig::load(&gen_path)?, &data, progress)?;

    stage(
        progress,
        began,
        "2/5 pretraining Network-2 (Net_O) per seed through a DSLR model (550D, gamma 2.2, ISO \
         100–200)",
    );
    for &k in s.seeds {
        let pre_run = out.join(format!("pretrain/seed{k}"));
        let pre_path = configs.join(format!("pretrain_seed{k}.toml"));
        write_config(
            &pre_path,
            &train_config(
                &s,
                backend,
                &data,
                &Stage {
                    run: &pre_run,
                    seed: k,
                    profile: &pre_profile,
                    isos: &DSLR_ISOS,
                    steps: s.pretrain_steps,
                    lr: s.pretrain_lr,
                    init: None,
                },
            ),
        )?;
        train_resumable(&pre_path, progress)
            .map_err(|e| Error::context(format!("pretraining ({})", pre_path.display()), e))?;
    }

    stage(
        progress,
        began,
        "3/5 test sets (held-out generated scenes; real radiance and a real capture where \
         present)",
    );
    let real_radiance = optional_source(
        opts.radiance.as_ref(),
        "radiance",
        "../shared/data/real_hdr",
    )?;
    let brackets = optional_source(
        opts.brackets.as_ref(),
        "brackets",
        "../shared/data/real_brackets/canon_550d_room",
    )?;
    let real_capture_dir = match &brackets {
        Ok(b) => Ok(real_capture(b, out)
            .map_err(|e| Error::context(format!("the real capture {}", b.display()), e))?),
        Err(why) => Err(why.clone()),
    };
    let sources = TestSources {
        scenes: test_scenes(opts, &s)?,
        real_radiance: real_radiance.as_ref().ok().cloned(),
        real_capture: real_capture_dir.as_ref().ok().cloned(),
    };
    let heldout = if opts.heldout {
        heldout_testsets(out, &sources.scenes, &target_profile, &sensors)?
    } else {
        Vec::new()
    };
    let base_path = configs.join("finetune.toml");
    write_config(
        &base_path,
        &train_config(
            &s,
            backend,
            &data,
            &Stage {
                run: &out.join("unused"),
                seed: 0,
                profile: Path::new("pure"),
                isos: &TARGET_ISOS,
                steps: s.finetune_steps,
                lr: s.finetune_lr,
                init: Some(&out.join("pretrain/seed1")),
            },
        ),
    )?;
    let exp_path = configs.join("experiment.toml");
    let mut exp_cfg = experiment_config(&s, out, &base_path, &sources, &target);
    exp_cfg.also.extend(heldout);
    write_config(&exp_path, &exp_cfg)?;

    stage(
        progress,
        began,
        "4/5 per seed: control, Net_R, Net_P and Net_S fine-tuned; every network scored on every \
         test set (hdrsynth ablate)",
    );
    let exp = AblateConfig::load(&exp_path)?;
    let summary = ablate::run(&exp, &exp_path, progress)
        .map_err(|e| Error::context("the main job's grid", e))?;

    stage(progress, began, "5/5 noise ceiling and decision");
    let mut device = target_profile.clone();
    device.source_response = Response::Linear;
    let ceiling = noise_ceiling(&exp, &device.response, &out.join("noise_ceiling"), progress)?;
    let tables = ablate::write_tables(&exp)?;
    let primary = &tables[0];

    let mut report = ablate::report(&exp, &summary);
    let alpha = 1.0 - exp.eval.level;
    let _ = write!(
        report,
        "\n\nNoise ceiling on the primary test set (triangle merge of each set's frames with \
         the true device response; mean over seeds): PSNR-T {:.2} from the noisy frames, {:.2} \
         from the noise-free frames (PSNR-L {:.2} / {:.2}).",
        ceiling[0].0, ceiling[0].1, ceiling[1].0, ceiling[1].1
    );
    let _ = write!(report, "\n\n## Reading (docs/protocol.md)\n\n");
    match primary
        .entry("net_s", "psnr_t")
        .and_then(|e| e.diff.as_ref())
    {
        Some(d) => {
            let decision = Decision::from_diff(d, alpha);
            // A difference can be both real and smaller than the margin: say both.
            let decided = decision == Decision::Better || decision == Decision::Worse;
            let _ = writeln!(
                report,
                "- Primary, Net_S − Net_R, PSNR-T over {} scenes: {} → **{}**{}.",
                primary.entry("net_s", "psnr_t").map_or(0, |e| e.n_scenes),
                describe_diff(d),
                decision.text(d.margin),
                if decided && d.tost_p.is_some_and(|p| p < alpha) {
                    format!(
                        ", by less than the {} dB margin (the TOST also declares equivalence)",
                        d.margin
                    )
                } else {
                    String::new()
                }
            );
        }
        None => {
            let _ = writeln!(report, "- Primary: not every run has finished.");
        }
    }
    for (name, what) in [
        (
            "net_o",
            "Net_O − Net_R (what fine-tuning for the target's response buys)",
        ),
        ("control", "control − Net_R"),
        (
            "net_p",
            "Net_P − Net_R (the engine's display curve instead of the target's)",
        ),
    ] {
        if let Some(d) = primary.entry(name, "psnr_t").and_then(|e| e.diff.as_ref()) {
            let _ = writeln!(report, "- Secondary, {what}: {}.", describe_diff(d));
        }
    }
    let seeds_mean = |t: &ablate::Table, row: &str| t.entry(row, "psnr_t").map(|e| e.mean);
    let descriptive = tables.iter().skip(1).filter(|t| {
        !t.testset
            .as_deref()
            .is_some_and(|n| n.starts_with("heldout_"))
    });
    for (t, what) in descriptive.map(|t| {
        (
            t,
            match t.testset.as_deref() {
                Some("real_radiance") => "real radiance through the target model",
                Some("real_capture") => "the real capture",
                _ => "another test set",
            },
        )
    }) {
        let cells: Vec<String> = exp
            .rows
            .iter()
            .filter_map(|r| seeds_mean(t, &r.name).map(|v| format!("{} {v:.2}", r.name)))
            .collect();
        let _ = writeln!(
            report,
            "- Descriptive, {what} (PSNR-T, mean over seeds; too few scenes for a test): {}.",
            cells.join(", ")
        );
    }
    let matrix: Vec<&ablate::Table> = std::iter::once(primary)
        .chain(tables.iter().filter(|t| {
            t.testset
                .as_deref()
                .is_some_and(|n| n.starts_with("heldout_"))
        }))
        .collect();
    if matrix.len() > 1 {
        let _ = write!(
            report,
            "\n### Held-out-simulator matrix (PSNR-T, mean over seeds; last column Net_S − Net_R)\n\n\
             | test rendering |"
        );
        for r in &exp.rows {
            let _ = write!(report, " {} |", r.name);
        }
        let _ = write!(report, " Net_S − Net_R |\n|---|");
        for _ in 0..=exp.rows.len() {
            let _ = write!(report, "---|");
        }
        report.push('\n');
        for t in matrix {
            let _ = write!(
                report,
                "| {} |",
                t.testset
                    .as_deref()
                    .unwrap_or("primary (the training simulator)")
            );
            for r in &exp.rows {
                let v = seeds_mean(t, &r.name).map_or("–".into(), |v| format!("{v:.2}"));
                let _ = write!(report, " {v} |");
            }
            let d = t
                .entry("net_s", "psnr_t")
                .and_then(|e| e.diff.as_ref())
                .map_or("–".into(), describe_diff);
            let _ = writeln!(report, " {d} |");
        }
        report.push('\n');
    }
    if let Err(why) = &real_radiance {
        let _ = writeln!(report, "- No real-radiance table: {why}.");
    }
    if let Err(why) = &real_capture_dir {
        let _ = writeln!(report, "- No real-capture table: {why}.");
    }
    let _ = write!(
        report,
        "\nTotal {:.1} s ({} preset, backend {backend}). Configs in {} (rerun a stage with \
         `hdrsynth train --config …` or `hdrsynth ablate --config {}`).",
        began.elapsed().as_secs_f64(),
        match opts.preset {
            Preset::Cpu => "cpu",
            Preset::Gpu => "gpu",
        },
        configs.display(),
        exp_path.display()
    );
    let report_path = out.join("report.md");
    write(&report_path, &report)?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::parse_toml;

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

    /// The configs the main job writes read back to the values it built and validate, for
    /// both presets, and they are the protocol's (docs/protocol.md): five rows with Net_R the
    /// reference, Net_R the target model without colour and noise, per-seed pretraining and
    /// test noise, 24 held-out test scenes at another seed (the full run is too long for the
    /// test suite; its output is in the README).
    #[test]
    fn the_configs_follow_the_protocol_and_read_back() {
        let root = Path::new("/r");
        let target = root.join(TARGET_PROFILE.0);
        for preset in [Preset::Cpu, Preset::Gpu] {
            let s = sizes(preset);
            let gen_cfg = generate_config(&s, TRAIN_SCENE_SEED, s.train_sets, s.train_size);
            assert_eq!(round_trip(&gen_cfg), gen_cfg);
            gen_cfg.validate().expect("valid generate config");
            let test_cfg = test_scene_config(&s);
            test_cfg.validate().expect("valid test scene config");
            assert_ne!(test_cfg.seed, gen_cfg.seed);
            assert!(test_cfg.count >= 20, "the protocol needs ≥ 20 test scenes");
            for seed in s.seeds {
                let st = Stage {
                    run: root,
                    seed: *seed,
                    profile: &target,
                    isos: &DSLR_ISOS,
                    steps: s.pretrain_steps,
                    lr: s.pretrain_lr,
                    init: None,
                };
                let cfg = train_config(&s, s.backend, &root.join("data"), &st);
                assert_eq!(round_trip(&cfg), cfg);
                cfg.validate().expect("valid train config");
                assert_eq!(cfg.run.seed, *seed);
            }
            let src = TestSources {
                scenes: root.join("scenes"),
                real_radiance: Some(root.join("hdr")),
                real_capture: Some(root.join("capture")),
            };
            let exp = experiment_config(&s, root, &root.join("ft.toml"), &src, &target);
            assert_eq!(round_trip(&exp), exp);
            assert_eq!(exp.eval.reference.as_deref(), Some(REFERENCE));
            let names: Vec<&str> = exp.rows.iter().map(|r| r.name.as_str()).collect();
            assert_eq!(names, ["net_o", "control", "net_r", "net_p", "net_s"]);
            let net_r = &exp.rows[2].set["data"];
            assert_eq!(net_r["noise"].as_str(), Some("none"));
            assert_eq!(net_r["colour"].as_bool(), Some(false));
            assert_eq!(
                net_r["profile"].as_str(),
                exp.rows[4].set["data"]["profile"].as_str()
            );
            assert!(exp.rows[4].set["data"].get("noise").is_none());
            assert!(exp.testset.noise_per_seed);
            assert!(
                exp.pretrained_per_seed
                    .as_deref()
                    .is_some_and(|p| p.contains("{seed}"))
            );
            let also: Vec<_> = exp.also.iter().filter_map(|t| t.name.as_deref()).collect();
            assert_eq!(also, ["real_radiance", "real_capture"]);
        }
    }

    /// Each held-out rendering differs from the target model in one part only.
    #[test]
    fn each_heldout_simulator_changes_one_part_of_the_target_model() {
        let tmp = tempfile::tempdir().expect("tmp");
        let (_, _, target) = target_profile(None).expect("target");
        let specs = heldout_testsets(tmp.path(), Path::new("/scenes"), &target, tmp.path())
            .expect("heldout");
        let base = crate::data::testset::TestsetOptions {
            isos: isos(&TARGET_ISOS),
            evs: vec![-2.0, 0.0, 2.0],
            ..Default::default()
        };
        let mut changed = Vec::new();
        for t in &specs {
            let p = SensorProfile::load(t.profile.as_ref().expect("profile")).expect("load");
            let mut what = Vec::new();
            if p.response != target.response {
                what.push(format!("{:?}", p.response));
            }
            if p.colour != target.colour || p.noise != target.noise || p.levels != target.levels {
                what.push("colour/noise/levels".into());
            }
            if t.options.noise != base.noise {
                what.push(format!("{:?}", t.options.noise));
            }
            if t.options.metering != base.metering {
                what.push("metering".into());
            }
            assert_eq!(t.options.isos, base.isos);
            changed.push(what.join(" + "));
        }
        assert_eq!(
            changed,
            [
                "Gamma { gamma: 2.2 }",
                "Filmic",
                "PoissonGaussian",
                "metering"
            ]
        );
    }

    fn diff(mean: f64, lo: f64, hi: f64, wilcoxon: f64, tost: f64, signs: usize) -> DiffEntry {
        DiffEntry {
            mean,
            sign_holds: signs,
            n_seeds: 3,
            t: Some(crate::stats::PairedT {
                n: 24,
                mean,
                sd: 1.0,
                se: 0.2,
                t: mean / 0.2,
                p: 0.5,
                level: 0.95,
                ci_lower: lo,
                ci_upper: hi,
            }),
            wilcoxon_p: Some(wilcoxon),
            margin: 0.2,
            tost_p: Some(tost),
        }
    }

    /// The decision rule of docs/protocol.md on hand-made cases.
    #[test]
    fn the_decision_follows_the_protocol() {
        let d = |x: DiffEntry| Decision::from_diff(&x, 0.05);
        assert_eq!(d(diff(0.5, 0.2, 0.8, 0.01, 0.9, 3)), Decision::Better);
        // One seed against: not "better", and not equivalent either.
        assert_eq!(d(diff(0.5, 0.2, 0.8, 0.01, 0.9, 2)), Decision::Inconclusive);
        assert_eq!(d(diff(-0.5, -0.8, -0.2, 0.01, 0.9, 3)), Decision::Worse);
        // The interval excludes 0 but Wilcoxon does not reject: not decided by the t alone.
        assert_eq!(d(diff(0.5, 0.2, 0.8, 0.2, 0.9, 3)), Decision::Inconclusive);
        assert_eq!(
            d(diff(0.02, -0.1, 0.14, 0.6, 0.01, 2)),
            Decision::Equivalent
        );
        assert_eq!(
            d(diff(0.02, -0.3, 0.34, 0.6, 0.3, 2)),
            Decision::Inconclusive
        );
        let few = DiffEntry {
            t: None,
            ..diff(3.0, 2.0, 4.0, 0.001, 0.9, 3)
        };
        assert_eq!(d(few), Decision::Inconclusive);
    }
}
