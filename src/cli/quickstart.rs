//! `hdrsynth quickstart`: the paper's central claim once, on embedded defaults, in about ten
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

use crate::cli::ablate as ablate_cli;
use crate::config::parse_toml;
use crate::eval::ablate::{self, AblateConfig};
use crate::sensor::profile::SensorProfile;
use crate::train::config::TrainConfig;
use crate::train::{TrainOptions, checkpoint};
use anyhow::{Context, Result, bail};
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

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Output folder (resumes if it holds an interrupted quickstart of the same preset).
    #[arg(long, default_value = "runs/quickstart")]
    pub out: PathBuf,
    #[arg(long, value_enum, default_value_t = Preset::Cpu)]
    pub preset: Preset,
    /// Compute device: flex (CPU), ndarray, wgpu, cuda (as compiled in). Default: flex for the
    /// cpu preset, cuda for the gpu preset.
    #[arg(long)]
    pub backend: Option<String>,
    /// Folder of real HDR radiance maps (.exr/.hdr) for the test set; default
    /// ../shared/data/real_hdr when it exists, else scenes generated here.
    #[arg(long)]
    pub radiance: Option<PathBuf>,
    /// The target device's sensor profile (TOML) for Net_S and the test set; default the
    /// shipped composite phone (configs/sensors/composite_phone.toml). E.g. your own phone's
    /// calibrated profile.
    #[arg(long)]
    pub target: Option<PathBuf>,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
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

/// The target profile's file name and text: `--target`, else the shipped composite phone.
fn target_profile(args: &Args) -> Result<(String, String, String)> {
    let (file, text) = match &args.target {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("--target {}: cannot read", p.display()))?;
            let file = p
                .file_name()
                .map(|f| f.to_string_lossy().into_owned())
                .unwrap_or_else(|| "target.toml".into());
            (file, text)
        }
        None => (TARGET_PROFILE.0.to_string(), TARGET_PROFILE.1.to_string()),
    };
    let at = args
        .target
        .as_deref()
        .unwrap_or(Path::new(TARGET_PROFILE.0));
    let profile: SensorProfile = parse_toml(&text, at)?;
    let name = profile.name.clone();
    let file = if file == PRETRAIN_PROFILE.0 {
        format!("target_{file}")
    } else {
        file
    };
    Ok((file, text, name))
}

/// A path as a TOML string literal.
fn lit(p: &Path) -> String {
    toml::Value::String(p.to_string_lossy().into_owned()).to_string()
}

fn generate_toml(s: &Sizes, seed: u64, count: usize, (w, h): (usize, usize)) -> String {
    format!(
        "# Pure synthetic EV −2/0/+2 sets with linear EXRs (hdrsynth generate).\n\
         seed = {seed}\ncount = {count}\nwidth = {w}\nheight = {h}\nevs = [-2.0, 0.0, 2.0]\n\
         write_linear = true\n[camera]\ncandidates = {}\n",
        if s.train_sets > 64 { 24 } else { 8 }
    )
}

/// What differs between the pretraining and the fine-tuning config.
struct Stage<'a> {
    run: &'a Path,
    /// A TOML string literal: a profile path or "pure".
    profile: String,
    isos: &'a str,
    steps: u64,
    lr: f64,
    init: Option<&'a Path>,
}

fn train_toml(s: &Sizes, backend: &str, data: &Path, st: &Stage) -> String {
    let Stage {
        run,
        profile,
        isos,
        steps,
        lr,
        init,
    } = st;
    let mut t = format!(
        "[run]\nout = {}\nseed = 2026\nsteps = {steps}\nbackend = {backend:?}\n\
         checkpoint_every = {}\nkeep_checkpoints = 2\nlog_every = 10\n\n\
         [model]\nkind = \"wu\"\nvariant = \"resnet\"\nbase_width = {}\nres_blocks = {}\n\
         hdr_input_scale = 0.25\n\n\
         [data]\ndataset = {}\npatch = {}\nbatch_size = {}\nworkers = 2\naugment = true\n\
         profile = {profile}\nisos = {isos}\nnoise = \"gaussian\"\n\n\
         [optim]\nlr = {lr:e}\n\n[schedule]\nkind = \"cosine\"\nwarmup_steps = {}\n\
         min_lr = {:e}\n",
        lit(run),
        s.checkpoint_every,
        s.base_width,
        s.res_blocks,
        lit(data),
        s.patch,
        s.batch,
        steps / 10,
        lr / 50.0,
    );
    if let Some(i) = init {
        let _ = write!(t, "\n[init]\ncheckpoint = {}\n", lit(i));
    }
    t
}

/// ISOs of the phone target (fine-tuning and test set) and of the DSLR (pretraining).
const TARGET_ISOS: &str = "[100, 800, 3200]";
const DSLR_ISOS: &str = "[100, 200]";

fn experiment_toml(
    s: &Sizes,
    out: &Path,
    base: &Path,
    testset: &Path,
    radiance: &Path,
    target: &Path,
) -> String {
    let seeds: Vec<String> = s.seeds.iter().map(|k| k.to_string()).collect();
    format!(
        "title = \"Quickstart — Experiment 2 shape: Network-2 Net_O (pretrained through a DSLR) vs \
         control vs Net_P vs Net_S for the target device\"\n\
         out = {}\nbase = {}\nseeds = [{}]\n\n\
         [testset]\ndir = {}\nradiance = {}\nprofile = {}\n\
         [testset.options]\nisos = {TARGET_ISOS}\nevs = [-2.0, 0.0, 2.0]\n\n\
         [eval]\nresamples = 2000\nreference = \"net_p\"\n\n\
         [[rows]]\nname = \"net_o\"\nlabel = \"Net_O (pretrained through the DSLR, no fine-tuning)\"\n\
         train = false\n\n\
         [[rows]]\nname = \"control\"\nlabel = \"Net_O trained on (its own DSLR data, same steps)\"\n\
         kind = \"control\"\n\n\
         [[rows]]\nname = \"net_p\"\nlabel = \"Net_P (fine-tuned, pure synthetic)\"\n\
         set = {{ data = {{ profile = \"pure\" }} }}\n\n\
         [[rows]]\nname = \"net_s\"\nlabel = \"Net_S (fine-tuned, sensor-realistic target)\"\n\
         set = {{ data = {{ profile = {}, isos = {TARGET_ISOS} }} }}\n",
        lit(&out.join("experiment")),
        lit(base),
        seeds.join(", "),
        lit(testset),
        lit(radiance),
        lit(target),
        lit(target),
    )
}

fn write(path: &Path, text: &str) -> Result<()> {
    crate::io::atomic::write_atomic(path, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

fn stage(progress: bool, began: Instant, what: &str) {
    if progress {
        eprintln!("[{:>6.1} s] {what}", began.elapsed().as_secs_f64());
    }
}

/// Real radiance for the test set: the flag, ../shared/data/real_hdr, or generated scenes'
/// linear ground truth (copied into one folder, as `testset` reads a folder of maps).
fn radiance_source(
    args: &Args,
    s: &Sizes,
    target: &str,
    progress: bool,
) -> Result<(PathBuf, String)> {
    if let Some(r) = &args.radiance {
        if !r.exists() {
            bail!("--radiance {}: no such file or folder", r.display());
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
    let scenes = args.out.join("data/scenes");
    let cfg: crate::data::generate::GenerateConfig = parse_toml(
        &generate_toml(s, 77, 3, (s.train_size.0 * 2, s.train_size.1 * 2)),
        Path::new("scenes.toml"),
    )?;
    crate::data::generate::generate(&cfg, &scenes, progress)?;
    let dir = args.out.join("data/radiance");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    for e in std::fs::read_dir(&scenes).with_context(|| format!("reading {}", scenes.display()))? {
        let set = e?.path();
        let gt = set.join("hdr_gt.exr");
        if gt.is_file() {
            let name = set
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            let to = dir.join(format!("{name}.exr"));
            if !to.is_file() {
                std::fs::copy(&gt, &to)
                    .with_context(|| format!("copying {} to {}", gt.display(), to.display()))?;
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

pub fn run(args: &Args) -> Result<String> {
    let began = Instant::now();
    let progress = !args.quiet;
    let s = sizes(args.preset);
    let backend = args.backend.as_deref().unwrap_or(s.backend);
    let out = &args.out;
    // One quickstart per folder: a second would rewrite the configs the first is reading. The
    // commands it runs lock their own subfolders (data/…, pretrain, experiment).
    let _lock = crate::io::guard::OutputLock::acquire(out, "quickstart")?;
    let configs = out.join("configs");
    let sensors = configs.join("sensors");
    std::fs::create_dir_all(&sensors).with_context(|| format!("creating {}", sensors.display()))?;
    let pre_profile = sensors.join(PRETRAIN_PROFILE.0);
    let (target_file, target_text, target_name) = target_profile(args)?;
    let target = sensors.join(target_file);
    write(&pre_profile, PRETRAIN_PROFILE.1)?;
    write(&target, &target_text)?;

    stage(progress, began, "1/4 synthetic training sets (EV −2/0/+2)");
    let data = out.join("data/train");
    let gen_path = configs.join("train_data.toml");
    write(
        &gen_path,
        &generate_toml(&s, 2026, s.train_sets, s.train_size),
    )?;
    crate::cli::generate::run(&gen_path, &data, progress)?;

    stage(
        progress,
        began,
        "2/4 pretraining Network-2 (Net_O) through a DSLR model (550D, gamma 2.2, ISO 100–200)",
    );
    let pre_run = out.join("pretrain");
    let pre_path = configs.join("pretrain.toml");
    write(
        &pre_path,
        &train_toml(
            &s,
            backend,
            &data,
            &Stage {
                run: &pre_run,
                profile: lit(&pre_profile),
                isos: DSLR_ISOS,
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
        .with_context(|| format!("pretraining ({})", pre_path.display()))?;
    }

    stage(
        progress,
        began,
        "3/4 test set (real radiance; generated scenes without it)",
    );
    let (radiance, test_note) = radiance_source(args, &s, &target_name, progress)?;
    let base_path = configs.join("finetune.toml");
    write(
        &base_path,
        &train_toml(
            &s,
            backend,
            &data,
            &Stage {
                run: &out.join("unused"),
                profile: "\"pure\"".into(),
                isos: TARGET_ISOS,
                steps: s.finetune_steps,
                lr: s.finetune_lr,
                init: Some(&pre_run),
            },
        ),
    )?;
    let exp_path = configs.join("experiment.toml");
    write(
        &exp_path,
        &experiment_toml(
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
    let summary = ablate::run(&exp, &exp_path, progress).context("the Experiment-2 grid")?;
    let mut report = ablate_cli::report(&exp, &summary);
    let _ = write!(
        report,
        "\n\nTest set: {test_note}.\nTotal {:.1} s ({} preset, backend {backend}). Configs in {} \
         (rerun a stage with `hdrsynth train --config …` or `hdrsynth ablate --config {}`).",
        began.elapsed().as_secs_f64(),
        match args.preset {
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

    /// The configs the quickstart writes are valid for both presets (the full run is too long
    /// for the test suite; its table and time are in the README).
    #[test]
    fn every_config_the_quickstart_writes_parses_and_validates() {
        let tmp = tempfile::tempdir().expect("tmp");
        let root = tmp.path();
        // The shipped DSLR profile is the 550D's with only its response replaced.
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
        for preset in [Preset::Cpu, Preset::Gpu] {
            let s = sizes(preset);
            let gen_cfg: crate::data::generate::GenerateConfig = parse_toml(
                &generate_toml(&s, 1, s.train_sets, s.train_size),
                Path::new("gen.toml"),
            )
            .expect("generate config");
            gen_cfg.validate().expect("valid generate config");
            let profile = root.join(TARGET_PROFILE.0);
            write(&profile, TARGET_PROFILE.1).expect("profile");
            for st in [
                Stage {
                    run: &root.join("pre"),
                    profile: lit(&profile),
                    isos: DSLR_ISOS,
                    steps: s.pretrain_steps,
                    lr: s.pretrain_lr,
                    init: None,
                },
                Stage {
                    run: &root.join("ft"),
                    profile: "\"pure\"".into(),
                    isos: TARGET_ISOS,
                    steps: s.finetune_steps,
                    lr: s.finetune_lr,
                    init: Some(&root.join("pre")),
                },
            ] {
                let text = train_toml(&s, s.backend, &root.join("data"), &st);
                let cfg: TrainConfig = parse_toml(&text, Path::new("train.toml")).expect(&text);
                cfg.validate().expect("valid train config");
                assert_eq!(cfg.run.steps, st.steps);
            }
            let base = root.join("finetune.toml");
            let exp = root.join("experiment.toml");
            write(
                &exp,
                &experiment_toml(&s, root, &base, root, root, &profile),
            )
            .expect("write");
            let cfg = AblateConfig::load(&exp).expect("experiment config");
            assert_eq!(cfg.eval.reference.as_deref(), Some("net_p"));
            assert_eq!(cfg.rows.len(), 4);
        }
    }
}
