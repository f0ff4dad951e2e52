//! The main job (`hdrsynth quickstart`): the primary comparison of docs/protocol.md at CPU
//! scale, on embedded defaults. Generate synthetic EV −2/0/+2 training sets; per seed, pretrain
//! a small Network-2 (Net_O) through a DSLR-class camera model (the Canon EOS 550D's colour,
//! noise and levels with a gamma-2.2 response at ISO 100–200) and fine-tune it for the target
//! device (default: the composite phone profile) four ways — the full device model (Net_S), the
//! device's response, levels and exposure rule only (Net_R, the fair pure baseline and the
//! reference), the scene engine's display frames (Net_P) and, as a control, its own DSLR data;
//! score every network on the primary test set (24 held-out scene-engine scenes through the
//! target model, test noise redrawn per seed), on a dynamic test set (16 scenes with moving
//! subjects), on real radiance and on a real capture where they exist; print the tables with
//! paired tests, the noise ceiling and the protocol's decision.
//!
//! Nothing is tuned on the test scenes (scene seed 7 is used for nothing else). Every stage
//! resumes: rerunning the command after an interruption keeps what is finished. The configs it
//! runs are written to OUT/configs/ so each stage can be rerun or changed by hand.

use crate::data::generate::{GenerateConfig, generate};
use crate::error::{Error, Result};
use crate::eval::evaluate::{self, Classical, ClassicalMerge, EvalOptions};
use crate::experiments::ablate::{self, AblateConfig, Axis, AxisKind, EvalSpec, TestsetSpec};
use crate::sensor::metering::Metering;
use crate::sensor::profile::Response;
use crate::sensor::profile::SensorProfile;
use crate::sensor::realism::NoiseModel;
use crate::train;
use crate::train::config::TrainConfig;

mod reading;
mod test_sets;
pub use crate::experiments::presets::Preset;
pub(crate) use crate::experiments::presets::{Sizes, sizes, sizes_with_seeds};
use crate::experiments::recipe::{
    CONTROL_LABEL, DSLR_ISOS, PRETRAIN_PROFILE, REFERENCE, Stage, TARGET_ISOS, TEST_SCENE_SEED,
    TRAIN_SCENE_SEED, data_set, generate_config, isos, net_o_row, net_p_row, net_r_row, net_s_row,
    row, stage, target_profile, train_config, train_resumable, write, write_config,
};
pub(crate) use reading::DYNAMIC;
pub use reading::Decision;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;
use test_sets::{noise_ceiling, optional_source, real_capture, test_scenes};

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
    /// These seeds instead of the preset's 1, 2, 3; a folder that holds some of them keeps
    /// those and gains the others.
    pub seeds: Option<Vec<u64>>,
    pub progress: bool,
}

/// Seed of the dynamic test scenes (used for nothing else).
const TEST_DYNAMIC_SCENE_SEED: u64 = 77;
/// Test scenes need at least this range (stops); an EV −2/0/+2 bracket holds about 12.
const TEST_MIN_DYNAMIC_RANGE: f32 = 10.0;

/// The main job's training sets: static (subjects, no motion between the frames), as its
/// primary test scenes are, or with the scene engine's motion where the preset trains on
/// moving subjects (`long`). Trained on moving subjects with the pooled loss, a merging
/// network learns to distrust the other frames where they disagree with the reference, which
/// costs it on static scenes (docs/experiments.md, "Recipe", "the sweep").
pub(crate) fn train_data_config(s: &Sizes) -> GenerateConfig {
    let mut cfg = generate_config(s, TRAIN_SCENE_SEED, s.train_sets, s.train_size);
    cfg.scene.motion_scale = if s.moving_still.is_some() { 1.0 } else { 0.0 };
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
                options.metering = Some(m);
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
                validation: false,
            })
        })
        .collect()
}

/// Where the test sets come from.
struct TestSources {
    /// Generated scenes' radiance (the primary test set).
    scenes: PathBuf,
    /// Generated scenes with moving subjects (the dynamic test set).
    dynamic: PathBuf,
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
    [dslr, target]: [&Path; 2],
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
        validation: false,
    };
    let mut also = vec![TestsetSpec {
        name: Some(reading::DYNAMIC.into()),
        label: Some("moving subjects (ground truth: the reference frame's radiance)".into()),
        dir: out.join("data/testset_dynamic"),
        radiance: Some(src.dynamic.clone()),
        ..testset.clone()
    }];
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
            validation: false,
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
            validation: false,
        });
    }
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
            // The control spelled out (the pretraining's data through the DSLR) rather than
            // read from the pretrained run, which the grid itself trains.
            row(
                "control",
                CONTROL_LABEL,
                data_set(dslr, Some(&DSLR_ISOS), &[]),
            ),
            net_r_row(target),
            net_p_row(),
            net_s_row(target),
        ]
        .into_iter()
        .chain(Axis::classical_rows())
        .collect(),
        columns: Vec::new(),
        jobs: ablate::GRID_JOBS,
    }
}

/// What stages 1–2 leave for the grid: the configs folder, the grid's config, the target's
/// profile, and the real test sets' folders or why there are none.
struct Prepared {
    configs: PathBuf,
    exp_path: PathBuf,
    target_profile: SensorProfile,
    real_radiance: reading::Optional,
    real_capture: reading::Optional,
}

/// Run the main job (every stage resumes) and return its report.
pub fn run(opts: &Options) -> Result<String> {
    // The configs it writes name files by absolute path: usable from any working directory.
    let opts = &Options {
        out: crate::io::guard::resolve(&opts.out)?,
        ..opts.clone()
    };
    let began = Instant::now();
    let progress = opts.progress;
    let s = sizes_with_seeds(opts.preset, opts.seeds.as_deref())?;
    let backend = opts.backend.as_deref().unwrap_or(s.backend);
    let out = &opts.out;
    // One main job per folder: a second would rewrite the configs the first is reading. The
    // commands it runs lock their own subfolders (data/…, pretrain, experiment).
    let _lock = crate::io::guard::OutputLock::acquire(out, "quickstart")?;
    if out.join("pretrain").join(train::RUN_CONFIG).is_file() {
        return Err(Error::flag(
            "--out",
            format!(
                "{} holds a main job of an earlier protocol (one pretraining for every seed); \
                 choose another --out or delete it",
                out.display()
            ),
        ));
    }
    let p = prepare(opts, &s, backend, began)?;

    stage(
        progress,
        began,
        "3/4 per seed: Net_O pretrained through a DSLR model (550D, gamma 2.2, ISO 100–200), \
         then control, Net_R, Net_P and Net_S fine-tuned; every network scored on every test \
         set (hdrsynth ablate)",
    );
    let exp = AblateConfig::load(&p.exp_path)?;
    let pretrain = |k: u64| {
        let path = p.configs.join(pretrain_file(k));
        train_resumable(&path, false)
            .map_err(|e| Error::context(format!("pretraining ({})", path.display()), e))?;
        if progress {
            eprintln!("  pretrained {}", path.display());
        }
        Ok(())
    };
    let summary = ablate::run_with(&exp, &p.exp_path, progress, &pretrain)
        .map_err(|e| Error::context("the main job's grid", e))?;

    stage(progress, began, "4/4 noise ceiling and decision");
    let mut device = p.target_profile.clone();
    device.source_response = Response::Linear;
    let ceiling = noise_ceiling(&exp, &device.response, &out.join("noise_ceiling"), progress)?;
    let tables = ablate::write_tables(&exp)?;
    let mut report = reading::report(
        &exp,
        &summary,
        &tables,
        &ceiling,
        &p.real_radiance,
        &p.real_capture,
    );
    let _ = write!(
        report,
        "\nTotal {:.1} s ({} preset, backend {backend}). Configs in {} (rerun a stage with \
         `hdrsynth train --config …` or `hdrsynth ablate --config {}`).",
        began.elapsed().as_secs_f64(),
        match opts.preset {
            Preset::Cpu => "cpu",
            Preset::Gpu => "gpu",
            Preset::Long => "long",
            Preset::LongStill => "long-still",
        },
        p.configs.display(),
        p.exp_path.display()
    );
    let report_path = out.join("report.md");
    write(&report_path, &report)?;
    Ok(report)
}

/// Stages 1–2: the sensor profiles, the training sets, the pretraining configs, the test sets
/// and the grid's config.
fn prepare(opts: &Options, s: &Sizes, backend: &str, began: Instant) -> Result<Prepared> {
    let (progress, out) = (opts.progress, &opts.out);
    let configs = out.join("configs");
    let sensors = configs.join("sensors");
    std::fs::create_dir_all(&sensors)
        .map_err(|e| Error::context(format!("creating {}", sensors.display()), e))?;
    let pre_profile = sensors.join(PRETRAIN_PROFILE.0);
    let (target_file, target_text, target_profile) = target_profile(opts.target.as_deref())?;
    let target = sensors.join(target_file);
    write(&pre_profile, PRETRAIN_PROFILE.1)?;
    write(&target, &target_text)?;

    stage(progress, began, "1/4 synthetic training sets (EV −2/0/+2)");
    let data = out.join("data/train");
    let gen_path = configs.join("train_data.toml");
    write_config(&gen_path, &train_data_config(s))?;
    generate(&GenerateConfig::load(&gen_path)?, &data, progress)?;

    for &k in s.seeds.iter() {
        let run = out.join(format!("pretrain/seed{k}"));
        let cfg = pretrain_config(opts.preset, backend, &data, &pre_profile, &run, k);
        write_config(&configs.join(pretrain_file(k)), &cfg)?;
    }

    stage(
        progress,
        began,
        "2/4 test sets (held-out generated scenes, static and with moving subjects; real \
         radiance and a real capture where present)",
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
        scenes: test_scenes(opts, s)?,
        dynamic: test_sets::dynamic_scenes(opts, s)?,
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
            s,
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
    let mut exp_cfg = experiment_config(s, out, &base_path, &sources, [&pre_profile, &target]);
    exp_cfg.also.extend(heldout);
    write_config(&exp_path, &exp_cfg)?;
    Ok(Prepared {
        configs,
        exp_path,
        target_profile,
        real_radiance,
        real_capture: real_capture_dir,
    })
}

/// The pretraining config (Net_O of seed `seed`) that `preset`'s main job writes: its network,
/// optimiser, schedule and crops, on `data` through `profile` into `run`. Public so that a
/// preset's config can be started on a backend without the whole job (tests/wgpu.rs).
pub fn pretrain_config(
    preset: Preset,
    backend: &str,
    data: &Path,
    profile: &Path,
    run: &Path,
    seed: u64,
) -> TrainConfig {
    let s = sizes(preset);
    let stage = Stage {
        run,
        seed,
        profile,
        isos: &DSLR_ISOS,
        steps: s.pretrain_steps,
        lr: s.pretrain_lr,
        init: None,
    };
    train_config(&s, backend, data, &stage)
}

/// The pretraining config of seed `k` in the configs folder: what the grid trains before
/// that seed's first cell.
fn pretrain_file(k: u64) -> String {
    format!("pretrain_seed{k}.toml")
}

#[cfg(test)]
mod tests;
