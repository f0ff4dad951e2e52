//! The shared trainer: learning on a small generated set, checkpoints (bit-identical reload,
//! kill -9 and resume equals an uninterrupted run), the NaN stop, config refusals, schedules.

mod common;

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Device, Tensor, TensorData};
use hdrsynth::config::parse_toml;
use hdrsynth::models::seeded_init;
use hdrsynth::models::{BlendUNetConfig, ModelConfig};
use hdrsynth::train::TrainOptions;
use hdrsynth::train::checkpoint::{self, CheckpointState};
use hdrsynth::train::config::{Schedule, ScheduleKind, TrainConfig};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// One small generated dataset (EV −3/0) shared by the tests of this file.
fn dataset() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().expect("tmp");
        common::generate(dir.path(), 21, 6, (96, 80), "[-3.0, 0.0]");
        dir
    })
    .path()
}

/// A tiny Network-1 run config (TOML text) writing to `out`.
fn config_text(out: &Path, steps: u64, extra_run: &str, lr: f64, batch_norm: bool) -> String {
    format!(
        "[run]\nout = {out:?}\nseed = 3\nsteps = {steps}\ncheckpoint_every = 4\nlog_every = 2\n\
         keep_checkpoints = 2\n{extra_run}\n\
         [model]\nkind = \"blend_unet\"\nbase_width = 4\ndepth = 2\nbatch_norm = {batch_norm}\n\
         [data]\ndataset = {:?}\npatch = 32\nbatch_size = 2\nworkers = 2\nprofile = \"pure\"\n\
         [optim]\nlr = {lr:e}\n[schedule]\nkind = \"cosine\"\nwarmup_steps = 2\n",
        dataset()
    )
}

fn parse(text: &str) -> TrainConfig {
    let cfg: TrainConfig = parse_toml(text, Path::new("train.toml")).expect("train config");
    cfg.validate().expect("valid");
    cfg
}

/// Every float parameter (weights, biases, BatchNorm statistics) in visiting order.
fn params<M: Module>(m: &M) -> Vec<Vec<f32>> {
    struct V(Vec<Vec<f32>>);
    impl ModuleVisitor for V {
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            self.0
                .push(p.val().into_data().try_to_vec::<f32>().expect("f32"));
        }
    }
    let mut v = V(Vec::new());
    m.visit(&mut v);
    v.0
}

fn load_final(run: &Path) -> Vec<Vec<f32>> {
    let dir = checkpoint::resolve(run).expect("checkpoint");
    let state = checkpoint::read_state(&dir).expect("state");
    let ModelConfig::BlendUnet(cfg) = state.model else {
        panic!("a Network-1 checkpoint expected");
    };
    let model = checkpoint::load_model(
        seeded_init(&Device::flex(), 0, || cfg.init(&Device::flex())).expect("init"),
        &dir,
    )
    .expect("load");
    params(&model)
}

fn log_losses(run: &Path) -> Vec<String> {
    std::fs::read_to_string(run.join("log.jsonl"))
        .expect("log")
        .lines()
        .filter(|l| !l.contains("validation"))
        .map(|l| {
            // {"step":N,"epoch":E,"loss":L,...}: step and loss, not the timings.
            let f: Vec<&str> = l.split(',').collect();
            format!("{} {}", f[0], f[2])
        })
        .collect()
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
}

/// Runs `train --config cfg`, kills it with SIGKILL as soon as its first checkpoint in `run` is
/// complete (mid-way through later steps), resumes it to the end, and returns the step of the
/// checkpoint it was killed after.
fn kill_after_first_checkpoint_and_resume(cfg: &Path, run: &Path) -> u64 {
    let mut child = bin()
        .args(["train", "--quiet", "--config"])
        .arg(cfg)
        .spawn()
        .expect("spawn");
    let began = Instant::now();
    while checkpoint::latest(run).expect("latest").is_none() {
        assert!(
            began.elapsed() < Duration::from_secs(300),
            "no checkpoint appeared"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().expect("SIGKILL");
    child.wait().expect("wait");
    let at_kill = checkpoint::read_state(&checkpoint::latest(run).unwrap().unwrap())
        .expect("state")
        .step;
    let st = bin()
        .args(["train", "--quiet", "--resume", "--config"])
        .arg(cfg)
        .status()
        .expect("resume");
    assert!(st.success());
    at_kill
}

#[test]
fn killed_with_sigkill_and_resumed_ends_with_the_same_weights() {
    let tmp = tempfile::tempdir().expect("tmp");
    let steps = 40;
    let write = |name: &str| -> (PathBuf, PathBuf) {
        let run = tmp.path().join(name);
        let cfg = tmp.path().join(format!("{name}.toml"));
        std::fs::write(&cfg, config_text(&run, steps, "", 3e-3, true)).expect("write");
        (run, cfg)
    };
    let (run_a, cfg_a) = write("uninterrupted");
    let st = bin()
        .args(["train", "--quiet", "--config"])
        .arg(&cfg_a)
        .status()
        .expect("run");
    assert!(st.success());

    let (run_b, cfg_b) = write("killed");
    let at_kill = kill_after_first_checkpoint_and_resume(&cfg_b, &run_b);
    assert!(
        at_kill < steps,
        "the run finished before the kill (step {at_kill})"
    );

    let (a, b) = (load_final(&run_a), load_final(&run_b));
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        assert!(
            x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()),
            "parameter {i} differs after kill at step {at_kill} and resume"
        );
    }
    // The resumed log holds every step once, with the same losses.
    assert_eq!(log_losses(&run_a), log_losses(&run_b));
    // Resuming a finished run, or starting over in a folder with checkpoints, is refused.
    let out = bin()
        .args(["train", "--quiet", "--config"])
        .arg(&cfg_b)
        .output()
        .expect("rerun");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--resume"), "{err}");
}

#[test]
fn checkpoint_reload_gives_bit_identical_outputs() {
    let dev = Device::flex();
    let cfg = BlendUNetConfig {
        base_width: 4,
        depth: 2,
        batch_norm: true,
        classes: 256,
    };
    // Non-trivial BatchNorm statistics: one training-mode forward on an autodiff device.
    let ad = dev.clone().autodiff();
    let model = seeded_init(&ad, 17, || cfg.init(&ad)).expect("init");
    let x: Vec<f32> = (0..2 * 6 * 32 * 32)
        .map(|i| ((i * 37) % 101) as f32 / 100.0)
        .collect();
    let _ = model.forward(Tensor::from_data(
        TensorData::new(x.clone(), [2, 6, 32, 32]),
        &ad,
    ));
    let model = model.valid();
    let tmp = tempfile::tempdir().expect("tmp");
    let state = CheckpointState {
        format: checkpoint::FORMAT.into(),
        step: 7,
        samples: 14,
        epoch: 2,
        rng_seed: 17,
        loss: Some(1.5),
        model: ModelConfig::BlendUnet(cfg.clone()),
    };
    let dir = checkpoint::save(tmp.path(), &state, &model, None, 1, |_| Ok(())).expect("save");
    assert_eq!(checkpoint::read_state(&dir).expect("state"), state);
    let other = seeded_init(&dev, 99, || cfg.init(&dev)).expect("init");
    let loaded = checkpoint::load_model(other, &dir).expect("load");
    let run = |m: &hdrsynth::models::BlendUNet| {
        m.forward(Tensor::from_data(
            TensorData::new(x.clone(), [2, 6, 32, 32]),
            &dev,
        ))
        .into_data()
        .try_to_vec::<f32>()
        .expect("f32")
    };
    let (a, b) = (run(&model), run(&loaded));
    assert!(a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()));
    // A model of another shape does not load, and says which file.
    let wide = BlendUNetConfig {
        base_width: 8,
        ..cfg
    };
    let err = checkpoint::load_model(
        seeded_init(&dev, 0, || wide.init(&dev)).expect("init"),
        &dir,
    )
    .expect_err("shape");
    assert!(err.to_string().contains("model.bpk"), "{err}");
}

#[test]
fn non_finite_loss_stops_with_a_clear_message_and_keeps_the_last_checkpoint() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = tmp.path().join("nan");
    // Without BatchNorm, a huge learning rate overflows the activations within a few steps.
    // A checkpoint every step: the step whose update leaves NaN weights behind a finite loss
    // would be saved if the weights were not checked.
    let mut cfg = parse(&config_text(&run, 60, "", 1e30, false));
    cfg.run.checkpoint_every = 1;
    cfg.schedule.warmup_steps = 0;
    cfg.schedule.kind = ScheduleKind::Constant;
    let err = hdrsynth::train::run(&cfg, &TrainOptions::default()).expect_err("NaN stop");
    let msg = err.to_string();
    assert!(msg.contains("non-finite"), "{msg}");
    let log = std::fs::read_to_string(run.join("log.jsonl")).expect("log");
    assert!(log.contains("\"error\":\"non-finite"), "{log}");
    // Whatever checkpoint exists is complete, from before the failure, and loads: the one the
    // message calls good holds finite weights.
    if let Some(dir) = checkpoint::latest(&run).expect("latest") {
        let s = checkpoint::read_state(&dir).expect("state");
        assert!(msg.contains(&dir.display().to_string()), "{msg}");
        let ModelConfig::BlendUnet(m) = s.model else {
            panic!("a Network-1 checkpoint expected");
        };
        let init = seeded_init(&Device::flex(), 0, || m.init(&Device::flex())).expect("init");
        checkpoint::load_model(init, &dir).expect("the last good checkpoint loads");
    }
    // lr 1e39 (infinite in f32): the first update leaves infinite weights behind a finite
    // loss; the run stops there, naming the parameter, and writes no checkpoint.
    let run = tmp.path().join("inf");
    cfg.run.out = run.clone();
    cfg.optim.lr = 1e39;
    let msg = hdrsynth::train::run(&cfg, &TrainOptions::default())
        .expect_err("inf stop")
        .to_string();
    assert!(
        msg.contains("step 0: parameter 'encoder.0.conv1.weight'")
            && msg.contains("no checkpoint was written yet"),
        "{msg}"
    );
    assert_eq!(checkpoint::latest(&run).expect("latest"), None);
    let log = std::fs::read_to_string(run.join("log.jsonl")).expect("log");
    assert!(log.contains("\"error\":\"non-finite weights\""), "{log}");
}

#[test]
fn resume_refuses_a_changed_config_and_a_missing_run() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = tmp.path().join("r");
    let cfg = parse(&config_text(&run, 4, "", 1e-3, true));
    let resume = TrainOptions {
        resume: true,
        progress: false,
    };
    let err = hdrsynth::train::run(&cfg, &resume).expect_err("nothing to resume");
    assert!(err.to_string().contains("no checkpoint"), "{err}");
    hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("train");
    // The folder records the whole config, which trains again: the same run, steps included.
    let recorded = hdrsynth::train::config::TrainConfig::load(&run.join("config.toml"))
        .expect("the recorded config loads");
    assert_eq!((recorded.run.steps, &recorded.run.out), (4, &run));
    let mut changed = cfg.clone();
    changed.optim.lr = 2e-3;
    changed.run.steps = 8;
    let err = hdrsynth::train::run(&changed, &resume).expect_err("changed config");
    assert!(
        err.to_string()
            .contains("different config (optim.lr: 0.001 → 0.002; only run.steps"),
        "{err}"
    );
    // A moved run folder: the key that differs is the run's own folder.
    let moved = tmp.path().join("moved");
    std::fs::rename(&run, &moved).expect("move");
    let mut there = cfg.clone();
    there.run.out = moved.clone();
    let err = hdrsynth::train::run(&there, &resume).expect_err("moved");
    assert!(
        err.to_string().contains(&format!(
            "run.out: {:?} → {:?}",
            run.display().to_string(),
            moved.display().to_string()
        )),
        "{err}"
    );
    std::fs::rename(&moved, &run).expect("move back");
    // Only the step count may change: extending a finished run continues it.
    let mut longer = cfg.clone();
    longer.run.steps = 6;
    let s = hdrsynth::train::run(&longer, &resume).expect("extend");
    assert_eq!((s.start_step, s.steps), (4, 6));
    // A folder written with `run.steps` blanked (as it once was) resumes as well.
    let blanked = std::fs::read_to_string(run.join("config.toml"))
        .expect("config")
        .replace("steps = 4\n", "steps = 0\n");
    assert!(blanked.contains("steps = 0\n"), "{blanked}");
    std::fs::write(run.join("config.toml"), blanked).expect("blank");
    longer.run.steps = 8;
    let s = hdrsynth::train::run(&longer, &resume).expect("extend a blanked folder");
    assert_eq!((s.start_step, s.steps), (6, 8));
}

/// The exposure rule a run trains with: `[data.metering]` where the config gives it (whole:
/// a key it leaves out is the default, not the profile's), else the profile's measured rule,
/// else the default. The run's `config.toml` holds the rule's values (as every run recorded
/// the default before), `data_source.txt` where it came from, and a profile whose rule changed
/// is a changed config on resume.
#[test]
fn the_exposure_rule_is_the_configs_else_the_profiles_else_the_default() {
    use hdrsynth::sensor::metering::{Metering, RuleOrigin};
    use hdrsynth::sensor::profile::SensorProfile;
    let tmp = tempfile::tempdir().expect("tmp");
    let mut p = SensorProfile::load(&SensorProfile::shipped_dir().join("canon_eos_550d.toml"))
        .expect("profile");
    let plain = tmp.path().join("plain.toml");
    p.save(&plain).expect("save");
    let rule = Metering {
        mid_grey: 0.2,
        max_clipped: 0.05,
    };
    p.set_metering(Some((rule, "by hand".into())));
    let measured = tmp.path().join("measured.toml");
    p.save(&measured).expect("save");
    let run = tmp.path().join("r");
    let cfg = |profile: &Path, metering: &str| {
        parse(&config_text(&run, 1, "", 1e-3, false).replace(
            "profile = \"pure\"\n",
            &format!("profile = {profile:?}\nisos = [100.0]\nnoise = \"none\"\n{metering}"),
        ))
    };
    let resolved = |c: &TrainConfig| {
        let r = c.data.metering().expect("resolve");
        (r.rule.mid_grey, r.rule.max_clipped, r.origin)
    };
    let given = "metering = { mid_grey = 0.1 }\n";
    assert_eq!(
        resolved(&cfg(&measured, given)),
        (0.1, 0.02, RuleOrigin::Given)
    );
    assert_eq!(
        resolved(&cfg(&measured, "")),
        (0.2, 0.05, RuleOrigin::Profile)
    );
    assert_eq!(
        resolved(&cfg(&plain, "")),
        (0.128, 0.02, RuleOrigin::Default)
    );
    assert_eq!(
        resolved(&parse(&config_text(&run, 1, "", 1e-3, false))),
        (0.128, 0.02, RuleOrigin::Default)
    );
    // What a run records: the default exactly as runs always wrote it.
    let text =
        toml::to_string(&cfg(&plain, "").with_resolved_metering().expect("resolve")).expect("toml");
    assert!(
        text.contains("[data.metering]\nmid_grey = 0.128\nmax_clipped = 0.02\n"),
        "{text}"
    );
    // A run with the profile's rule.
    let c = cfg(&measured, "");
    hdrsynth::train::run(&c, &TrainOptions::default()).expect("train");
    let saved = std::fs::read_to_string(run.join("config.toml")).expect("config");
    assert!(
        saved.contains("[data.metering]\nmid_grey = 0.2\nmax_clipped = 0.05\n"),
        "{saved}"
    );
    let source = std::fs::read_to_string(run.join("data_source.txt")).expect("source");
    assert!(
        source.contains("mid grey 0.2000, at most 5.00 % clipped; the profile's measured rule"),
        "{source}"
    );
    // The profile's rule changes: resuming would train with another rule.
    p.set_metering(Some((
        Metering {
            mid_grey: 0.15,
            ..rule
        },
        "by hand, again".into(),
    )));
    p.save(&measured).expect("save");
    let mut longer = c.clone();
    longer.run.steps = 2;
    let resume = TrainOptions {
        resume: true,
        progress: false,
    };
    let err = hdrsynth::train::run(&longer, &resume).expect_err("another rule");
    assert!(err.to_string().contains("different config"), "{err}");
}

#[test]
fn unknown_keys_and_bad_values_are_config_errors_naming_the_line() {
    let text = config_text(Path::new("/tmp/x"), 4, "colour = true", 1e-3, true);
    let err = parse_toml::<TrainConfig>(&text, Path::new("train.toml")).expect_err("unknown");
    assert!(err.to_string().contains("train.toml:"), "{err}");
    let text =
        config_text(Path::new("/tmp/x"), 4, "", 1e-3, true).replace("patch = 32", "patch = 30");
    let cfg: TrainConfig = parse_toml(&text, Path::new("train.toml")).expect("parses");
    let err = cfg.validate().expect_err("patch not a multiple of 4");
    assert!(err.to_string().contains("multiple"), "{err}");
    // A key given twice: both lines and the key in its table.
    let text = config_text(Path::new("/tmp/x"), 4, "", 1e-3, true)
        .replace("patch = 32\n", "patch = 32\nworkers = 1\n");
    let line = |k: &str| 1 + text.lines().position(|l| l.starts_with(k)).expect("line");
    let lines: Vec<&str> = text.lines().collect();
    let second = 1 + lines
        .iter()
        .rposition(|l| l.starts_with("workers"))
        .expect("line");
    let err = parse_toml::<TrainConfig>(&text, Path::new("train.toml")).expect_err("twice");
    assert_eq!(
        err.to_string(),
        format!(
            "train.toml:{second}: key 'data.workers' is given twice (lines {} and {second}); give \
             it once",
            line("workers")
        )
    );
}

/// `[data]` embeds the loader's `RealismConfig` (its keys written in `[data]` itself) and still
/// reports an unknown key at its own line with every valid key, and a mistyped one (own or
/// realism) at its line; a profile other than "pure" still needs ISOs.
#[test]
fn data_section_errors_name_the_key_line_and_the_valid_keys() {
    use hdrsynth::data::loader::SampleKind;
    let base = config_text(Path::new("/tmp/x"), 4, "", 1e-3, true);
    let with = |extra: &str| base.replace("profile = \"pure\"", extra);
    let err = |text: &str| {
        parse_toml::<TrainConfig>(text, Path::new("train.toml"))
            .expect_err("refused")
            .to_string()
    };
    // Line 19 is `profile`, so the added key is on line 20.
    let e = err(&with("profile = \"pure\"\nbogus = 1"));
    assert!(
        e.contains(
            "train.toml:20: unknown field `bogus`, expected one of `dataset`, `generate`, \
             `patch`, `batch_size`, `workers`, `augment`, `profile`, `isos`, `noise`, \
             `exposure`, `metering`, `ev_jitter`, `source`, `colour`, `target_space`, `target_sigma`, \
             `target_frames`"
        ),
        "{e}"
    );
    let e = err(&with("profile = \"pure\"\nev_jitter = \"x\""));
    assert!(
        e.contains("train.toml:20: key 'data.ev_jitter': invalid type"),
        "{e}"
    );
    let e = err(&base.replace("workers = 2", "workers = \"x\""));
    assert!(
        e.contains("train.toml:18: key 'data.workers': invalid type"),
        "{e}"
    );
    let e = err(&base.replace("patch = 32\n", ""));
    assert!(e.contains("missing field `patch`"), "{e}");
    let e = err(&with("isos = [100.0]"));
    assert!(e.contains("missing field `profile`"), "{e}");

    let pure = parse(&base);
    assert!(
        pure.data
            .loader(SampleKind::Network1, 1)
            .expect("pure")
            .realism
            .is_none()
    );
    // A profile without ISOs is refused when the config is checked, before any loader.
    let cfg: TrainConfig = parse_toml(
        &with("profile = \"p.toml\"\nev_jitter = 0.25"),
        Path::new("train.toml"),
    )
    .expect("parses");
    assert_eq!(cfg.data.realism.ev_jitter, 0.25);
    let e = cfg.validate().expect_err("no isos");
    assert!(
        e.key == "data.isos" && e.msg.contains("needs a non-empty `isos` list"),
        "{e}"
    );
    let cfg = parse(&with(
        "profile = \"p.toml\"\nisos = [100.0]\nsource = \"linear\"",
    ));
    let realism = cfg
        .data
        .loader(SampleKind::Network1, 1)
        .expect("loader")
        .realism;
    assert_eq!(realism.as_ref(), Some(&cfg.data.realism));
    // The resolved config (a run's identity on resume) reads back to the same value.
    let text = toml::to_string(&cfg).expect("serialise");
    assert_eq!(parse(&text), cfg, "{text}");
}

/// The defaults of every optional key (docs/training.md), pinned: a refactor of how serde fills
/// them must not change a value any shipped or user config relies on.
#[test]
fn omitted_keys_take_the_documented_defaults() {
    use hdrsynth::data::loader::Source;
    use hdrsynth::models::wu::{Linearise, MergePrior, WuOutput};
    use hdrsynth::models::{DeconvAlignment, WuConfig, WuVariant};
    use hdrsynth::sensor::metering::Metering;
    use hdrsynth::sensor::profile::Response;
    use hdrsynth::sensor::realism::NoiseModel;
    use hdrsynth::train::loss::Network1Reading;
    let minimal = |model: &str| {
        parse(&format!(
            "[run]\nout = \"r\"\nseed = 1\nsteps = 1\n[model]\nkind = \"{model}\"\n\
             [data]\ndataset = \"d\"\npatch = 64\nbatch_size = 2\nprofile = \"p.toml\"\n\
             isos = [100.0]\n"
        ))
    };
    let cfg = minimal("blend_unet");
    let r = &cfg.run;
    assert_eq!(r.backend, "flex");
    assert!(r.devices.is_empty());
    assert_eq!(
        (r.checkpoint_every, r.keep_checkpoints, r.log_every),
        (500, 3, 10)
    );
    let d = &cfg.data;
    assert_eq!((d.generate.clone(), d.workers, d.augment), (None, 2, true));
    assert_eq!(
        (d.realism.noise, d.realism.exposure, d.realism.ev_jitter),
        (NoiseModel::default(), 1.0, 0.5)
    );
    // No `[data.metering]`: not given, so the profile's rule or the default applies.
    assert_eq!(
        (d.realism.metering, d.realism.source, d.realism.colour),
        (None, Source::Auto, true)
    );
    assert_eq!(
        Metering::default(),
        Metering {
            mid_grey: 0.128,
            max_clipped: 0.02
        }
    );
    assert_eq!(d.target_sigma, 4.0);
    let o = &cfg.optim;
    assert_eq!(
        (o.lr, o.beta1, o.beta2, o.epsilon, o.weight_decay),
        (1e-4, 0.9, 0.999, 1e-8, 0.0)
    );
    assert_eq!(cfg.schedule, Schedule::default());
    assert_eq!(cfg.schedule.kind, ScheduleKind::Constant);
    assert_eq!((cfg.schedule.warmup_steps, cfg.schedule.every), (0, None));
    let l = &cfg.loss;
    assert_eq!((l.alpha.as_str(), l.alpha_samples), ("uniform", 64));
    assert_eq!(
        (l.reading, l.label_sigma),
        (Network1Reading::default(), 8.0)
    );
    assert!(cfg.init.is_none() && cfg.validation.is_none());
    assert_eq!(
        cfg.model,
        ModelConfig::BlendUnet(BlendUNetConfig {
            base_width: 32,
            depth: 4,
            batch_norm: true,
            classes: 256,
        })
    );
    assert_eq!(
        minimal("wu").model,
        ModelConfig::Wu(WuConfig {
            variant: WuVariant::Resnet,
            base_width: 64,
            res_blocks: 9,
            unet_merger_widths: vec![4, 8, 8],
            deconv_alignment: DeconvAlignment::Tensorflow,
            hdr_input_scale: 0.25,
            output: WuOutput::Image,
            merge_prior: MergePrior::Triangle,
            linearise: Linearise::Fixed,
            input_response: Response::Gamma { gamma: 2.2 },
        })
    );
    let with_validation = format!(
        "{}[validation]\ndataset = \"v\"\nevery = 5\n",
        config_text(Path::new("r"), 4, "", 1e-3, true)
    );
    let v = parse(&with_validation).validation.expect("validation");
    assert_eq!((v.generate, v.samples, v.patch), (None, 16, None));
    assert_eq!(v.target_sigma, 0.0);
}

/// Every training config shipped in configs/ (any depth: the files with a `[run]` table)
/// parses and validates.
#[test]
fn every_shipped_training_config_parses() {
    fn walk(dir: &Path, found: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).expect("configs") {
            let path = entry.expect("entry").path();
            if path.is_dir() {
                walk(&path, found);
            } else if path.extension().is_some_and(|e| e == "toml") {
                let text = std::fs::read_to_string(&path).expect("read");
                let table: toml::Table = text.parse().expect("toml");
                if table.contains_key("run") {
                    found.push(path);
                }
            }
        }
    }
    let mut found = Vec::new();
    walk(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("configs"),
        &mut found,
    );
    assert!(found.len() >= 9, "{found:?}");
    for path in found {
        TrainConfig::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
}

#[test]
fn schedules_by_hand() {
    let s = Schedule {
        kind: ScheduleKind::Cosine,
        warmup_steps: 4,
        min_lr: Some(0.0),
        ..Schedule::default()
    };
    // Warm-up: (step + 1)/4 of the base.
    assert_eq!(s.lr(1.0, 0, 104), 0.25);
    assert_eq!(s.lr(1.0, 3, 104), 1.0);
    // Cosine over the remaining 100 steps: half-way 0.5, a quarter 0.5(1 + cos(π/4)).
    assert!((s.lr(1.0, 54, 104) - 0.5).abs() < 1e-12);
    assert!((s.lr(1.0, 29, 104) - 0.5 * (1.0 + std::f64::consts::FRAC_1_SQRT_2)).abs() < 1e-12);
    let st = Schedule {
        kind: ScheduleKind::Step,
        every: Some(10),
        gamma: Some(0.5),
        ..Schedule::default()
    };
    assert_eq!(st.lr(2.0, 9, 100), 2.0);
    assert_eq!(st.lr(2.0, 25, 100), 0.5);
    let missing = Schedule {
        kind: ScheduleKind::Step,
        ..Schedule::default()
    };
    assert_eq!(missing.validate(1e-4).unwrap_err().key, "every");
    assert!(st.validate(1e-4).is_ok());
    // min_lr above the base learning rate (1e-4 here) is refused.
    let e = Schedule {
        min_lr: Some(1e-3),
        ..Schedule::default()
    }
    .validate(1e-4)
    .unwrap_err();
    assert_eq!(e.key, "min_lr");
}

/// Validation (Eq. 4 loss, blend-weight MAE) logged at `step`.
fn validation_at(run: &Path, step: u64) -> (f64, f64) {
    (
        common::validation_at(run, step, "loss"),
        common::validation_at(run, step, "weight_mae"),
    )
}

#[test]
fn a_short_run_learns_the_blend_weights() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = tmp.path().join("learn");
    // The paper's recipe (literal Eq. 4, stream α, per-pixel targets), pinned: the defaults
    // are tested in tests/network1_learning.rs.
    let text = config_text(&run, 300, "", 3e-3, true)
        .replace("batch_size = 2", "batch_size = 4")
        .replace(
            "profile = \"pure\"\n",
            "profile = \"pure\"\ntarget_sigma = 0.0\n",
        )
        + "[loss]\nreading = \"literal\"\nalpha = \"stream\"\n"
        + &format!(
            "[validation]\ndataset = {:?}\nevery = 300\nsamples = 6\npatch = 64\n",
            dataset()
        );
    let mut cfg = parse(&text);
    cfg.run.checkpoint_every = 300;
    let s = hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("train");
    let (loss0, mae0) = validation_at(&run, 0);
    let (loss1, mae1) = validation_at(&run, 300);
    println!(
        "train loss {:.4} → {:.4}; validation Eq. 4 loss {loss0:.4} → {loss1:.4}, blend-weight \
         MAE {mae0:.4} → {mae1:.4}",
        s.first_loss, s.last_loss
    );
    assert!(loss1 < loss0, "validation loss {loss0} → {loss1}");
    assert!(mae1 < 0.5 * mae0, "blend-weight MAE {mae0} → {mae1}");

    // `hdrsynth infer` on a whole generated frame pair (96×80: no multiple of the tile),
    // untiled and in 32-px tiles: the same output.
    let set = common::first_set(dataset());
    let infer = |out: &Path, tile: &str| {
        let st = bin()
            .args(["infer", "--checkpoint"])
            .arg(&run)
            .arg("--inputs")
            .arg(set.join("static/ev-3.png"))
            .arg(set.join("static/ev+0.png"))
            .arg("--out")
            .arg(out)
            .args(["--tile", tile])
            .status()
            .expect("infer");
        assert!(st.success());
        hdrsynth::io::read_image(&out.join("linear.exr")).expect("linear.exr")
    };
    // A missing input is an error naming it, and leaves no output folder behind.
    let missing = set.join("static/ev-9.png");
    let failed = tmp.path().join("failed");
    // `infer` on LOW and the set's EV0 frame into `failed`: (success, stderr).
    let infer_low = |low: &Path| {
        let o = bin()
            .args(["infer", "--checkpoint"])
            .arg(&run)
            .arg("--inputs")
            .arg(low)
            .arg(set.join("static/ev+0.png"))
            .arg("--out")
            .arg(&failed)
            .output()
            .expect("infer");
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).to_string(),
        )
    };
    let (ok, err) = infer_low(&missing);
    assert!(!ok && err.contains("ev-9.png"), "{err}");
    assert!(!failed.exists(), "a failed infer left {}", failed.display());
    // LOW and HIGH of different sizes: refused naming both and their sizes.
    let small = tmp.path().join("small.png");
    let ev0 = hdrsynth::io::read_image(&set.join("static/ev+0.png")).expect("png");
    let crop = hdrsynth::io::Image::from_vec(1, 1, ev0.data[..3].to_vec());
    hdrsynth::io::write_ldr(&small, &crop, hdrsynth::io::BitDepth::Eight).expect("write");
    let (ok, err) = infer_low(&small);
    assert!(
        !ok && err.contains("small.png is 1×1 but") && err.contains("96×80"),
        "{err}"
    );
    assert!(!failed.exists(), "a failed infer left {}", failed.display());
    let whole = infer(&tmp.path().join("whole"), "384");
    let tiled = infer(&tmp.path().join("tiled"), "32");
    assert_eq!((whole.width, whole.height), (96, 80));
    let worst = common::max_abs_diff(&whole.data, &tiled.data);
    assert!(worst <= 1e-4, "tiled vs untiled fused output: {worst}");
    for name in ["tonemapped.exr", "tonemapped.png", "blend_weight.png"] {
        assert!(tmp.path().join("tiled").join(name).is_file(), "{name}");
    }
}

/// One writer per run folder: while another holder has the run's lock, `train`
/// refuses with a message naming the lock, and writes no checkpoint.
#[test]
fn a_second_trainer_into_a_locked_run_folder_is_refused() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = tmp.path().join("run");
    let cfg = parse(&config_text(&run, 2, "", 1e-3, true));
    let held = hdrsynth::io::guard::OutputLock::acquire(&run, "another trainer").expect("lock");
    let e = hdrsynth::train::run(&cfg, &TrainOptions::default())
        .expect_err("a locked run folder")
        .to_string();
    assert!(e.contains("in use"), "{e}");
    assert!(!run.join("checkpoints").exists(), "wrote into a locked run");
    drop(held);
    hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("trains once released");
    assert!(run.join("checkpoints").is_dir());
}

/// Data-parallel gradients over two devices equal the single-device gradient
/// of the combined batch, for Network-1 without BatchNorm (with BatchNorm each shard is
/// normalised by its own statistics, as in PyTorch's DDP: not comparable; docs/training.md),
/// both loss readings. Odd batch sizes split unevenly (3 = 2 + 1) and are weighted by their
/// share: a missing or wrong weight changes the gradient and fails here (Adam would hide it).
#[test]
fn data_parallel_gradients_equal_the_combined_batch() {
    use burn::optim::GradientsParams;
    use hdrsynth::data::ground_truth::{ClassWeights, MertensWeights};
    use hdrsynth::data::loader::Sample;
    use hdrsynth::train::loss::Network1Reading;
    use hdrsynth::train::parallel_gradients;
    use hdrsynth::train::task::{Network1, Task};

    let size = 32;
    let samples = |n: usize| -> Vec<Sample> { common::samples(n, 6, size, false) };
    for reading in [Network1Reading::Literal, Network1Reading::Soft] {
        let task = Network1 {
            config: BlendUNetConfig {
                base_width: 4,
                depth: 2,
                batch_norm: false,
                ..Default::default()
            },
            alpha: ClassWeights::new(
                &std::array::from_fn(|i| 1 + (i as u64 * 7) % 13),
                MertensWeights::OPENCV_DEFAULT,
                1,
            ),
            reading,
            label_sigma: hdrsynth::train::config::DEFAULT_LABEL_SIGMA,
        };
        let ad = Device::flex().autodiff();
        let model = seeded_init(&ad, 5, || task.init(&ad)).expect("init");
        for n in [3usize, 4] {
            let batch = samples(n);
            let loss = task.loss(&model, &batch, &ad).expect("loss");
            let whole_loss = loss.clone().into_scalar::<f32>() as f64;
            let whole = GradientsParams::from_grads(loss.backward(), &model);
            let devices = [ad.clone(), ad.clone()];
            let (split, split_loss) =
                parallel_gradients(&task, &model, &batch, &devices).expect("parallel");
            assert!(
                (whole_loss - split_loss).abs() <= 1e-5 * whole_loss.abs(),
                "{reading:?}, batch {n}: loss {whole_loss} vs {split_loss} over 2 devices"
            );
            // Every parameter's gradient, compared relative to the largest of its tensor.
            struct V<'a>(&'a GradientsParams, &'a GradientsParams, Vec<(f32, f32)>);
            impl ModuleVisitor for V<'_> {
                fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
                    let get = |g: &GradientsParams| -> Vec<f32> {
                        g.get::<D>(p.id)
                            .expect("a gradient for every parameter")
                            .into_data()
                            .try_to_vec::<f32>()
                            .expect("f32")
                    };
                    let (a, b) = (get(self.0), get(self.1));
                    let scale = a.iter().fold(0f32, |m, v| m.max(v.abs()));
                    self.2.push((common::max_abs_diff(&a, &b), scale));
                }
            }
            let mut v = V(&whole, &split, Vec::new());
            model.visit(&mut v);
            assert!(!v.2.is_empty());
            for (i, (d, scale)) in v.2.iter().enumerate() {
                assert!(*scale > 0.0, "parameter {i}: a zero gradient tests nothing");
                assert!(
                    *d <= 1e-4 * scale,
                    "{reading:?}, batch {n}, parameter {i}: gradients differ by {d} (scale {scale})"
                );
            }
        }
        // More devices than samples is an error, not a panic.
        let three = [ad.clone(), ad.clone(), ad.clone()];
        assert!(parallel_gradients(&task, &model, &samples(2), &three).is_err());
    }
}

/// `[run] devices` through the trainer: a 2-device run's losses follow the 1-device run's
/// (same batches; per-step losses agree to rounding for a network without BatchNorm), and a
/// 2-device run killed with SIGKILL and resumed ends bit-identical to an uninterrupted one.
#[test]
fn two_device_training_matches_one_device_and_resumes_bit_identically() {
    let tmp = tempfile::tempdir().expect("tmp");
    let steps = 12;
    let devices = "devices = [\"flex\", \"flex\"]";
    let run = |name: &str, extra: &str| -> PathBuf {
        let out = tmp.path().join(name);
        let cfg = parse(&config_text(&out, steps, extra, 3e-3, false));
        hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("train");
        out
    };
    let one = run("one", "");
    let two = run("two", devices);
    // log_losses gives "{"step":N "loss":L" per line.
    let losses = |run: &Path| -> Vec<f64> {
        log_losses(run)
            .iter()
            .map(|l| {
                let v = l.rsplit(':').next().expect("a loss field");
                v.trim().parse().unwrap_or_else(|_| panic!("loss in {l}"))
            })
            .collect()
    };
    let (a, b) = (losses(&one), losses(&two));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() <= 1e-3 * x.abs(), "losses {a:?} vs {b:?}");
    }
    // Kill and resume with two devices.
    let out = tmp.path().join("killed");
    let cfg_path = tmp.path().join("killed.toml");
    std::fs::write(&cfg_path, config_text(&out, steps, devices, 3e-3, false)).expect("write");
    let at_kill = kill_after_first_checkpoint_and_resume(&cfg_path, &out);
    assert!(
        at_kill < steps,
        "the run finished before the kill (step {at_kill})"
    );
    let (x, y) = (load_final(&two), load_final(&out));
    for (i, (p, q)) in x.iter().zip(&y).enumerate() {
        assert!(
            p.iter().zip(q).all(|(a, b)| a.to_bits() == b.to_bits()),
            "parameter {i} differs after a 2-device kill and resume"
        );
    }
}

/// `[model] linearise = "data"`: the trainer writes the training frames' curve (the profile's
/// sRGB response) into the network's input curve, the checkpoint keeps it, and the loader's
/// HDR channels are that curve's inverse over t (sRGB decoding by hand, IEC 61966-2-1).
#[test]
fn linearise_data_records_the_training_curve_and_the_loader_feeds_it() {
    use hdrsynth::data::loader::{Loader, SampleKind};
    use hdrsynth::sensor::profile::{Response, SensorProfile};
    let tmp = tempfile::tempdir().expect("tmp");
    let data = tmp.path().join("n2");
    common::generate(&data, 5, 3, (64, 64), "[-2.0, 0.0, 2.0]");
    let profile = SensorProfile::shipped_dir().join("example_synthetic.toml");
    let run = tmp.path().join("run");
    let cfg = parse(&format!(
        "[run]\nout = {run:?}\nseed = 1\nsteps = 2\ncheckpoint_every = 2\nlog_every = 1\n\
         [model]\nkind = \"wu\"\nbase_width = 2\nres_blocks = 0\noutput = \"merge\"\n\
         linearise = \"data\"\n\
         [data]\ndataset = {data:?}\npatch = 32\nbatch_size = 2\nworkers = 1\n\
         profile = {profile:?}\nisos = [100.0]\n\
         [optim]\nlr = 1e-3\n[loss]\nhdr_unit = \"reference\"\n"
    ));
    hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("train");
    let state = checkpoint::read_state(&checkpoint::resolve(&run).expect("ckpt")).expect("state");
    let ModelConfig::Wu(m) = state.model else {
        panic!("a Network-2 checkpoint expected");
    };
    assert_eq!(
        m.input_response,
        Response::Srgb,
        "the profile's device curve"
    );
    let lc = cfg
        .with_resolved_model()
        .and_then(|c| c.loader(SampleKind::Network2))
        .expect("loader config");
    let s = Loader::new(&lc)
        .and_then(|l| l.stream_sample(0))
        .expect("sample");
    let n = 32 * 32;
    let mut checked = 0;
    for (f, t) in [0.25f32, 1.0, 4.0].into_iter().enumerate() {
        for c in 0..3 {
            for px in (0..n).step_by(7) {
                let v = s.input[(6 * f + c) * n + px];
                let lin = if v <= 0.04045 {
                    v / 12.92
                } else {
                    ((v + 0.055) / 1.055).powf(2.4)
                };
                let h = s.input[(6 * f + 3 + c) * n + px];
                assert!(
                    (h - lin / t).abs() <= 1e-5 * (1.0 + lin / t),
                    "frame {f} channel {c} pixel {px}: code {v} gave {h}, sRGB⁻¹/t = {}",
                    lin / t
                );
                checked += usize::from(v > 0.05 && v < 0.95);
            }
        }
    }
    assert!(checked > 100, "mid-range codes checked: {checked}");
}

#[test]
fn a_step_that_cannot_fit_in_memory_is_refused_naming_the_key_before_anything_is_written() {
    use hdrsynth::train::budget;
    let tmp = tempfile::tempdir().expect("tmp");
    // The lower bound against hand values and Burn's own count of the materialised network:
    // Network-1 base width 4, depth 2, batch 2 of 32² crops of its 6 input channels (two
    // frames of 3).
    let cfg = parse(&config_text(&tmp.path().join("small"), 4, "", 1e-3, false));
    let need = budget::step_memory(&cfg.model, 2, 32);
    let ModelConfig::BlendUnet(m) = &cfg.model else {
        panic!("Network-1 expected")
    };
    let net = seeded_init(&Device::flex(), 0, || m.init(&Device::flex())).expect("init");
    assert_eq!(need.parameters, net.num_params() as u64);
    assert_eq!(need.optimiser_bytes, 16.0 * net.num_params() as f64);
    assert_eq!(need.input_bytes, 4.0 * 2.0 * 32.0 * 32.0 * 6.0);
    // Over any machine's memory: the key is named and the run folder never appears (where
    // the host says how much it has: Linux's /proc/meminfo).
    let checked = budget::available_memory().is_some();
    for (key, from, to) in [
        (
            "data.batch_size",
            "batch_size = 2",
            "batch_size = 100000000",
        ),
        ("model.base_width", "base_width = 4", "base_width = 100000"),
    ]
    .into_iter()
    .filter(|_| checked)
    {
        let run = tmp.path().join(key);
        let cfg = parse(&config_text(&run, 4, "", 1e-3, false).replace(from, to));
        let err = hdrsynth::train::run(&cfg, &TrainOptions::default())
            .expect_err("refused")
            .to_string();
        assert!(err.contains(key) && err.contains("GB available"), "{err}");
        assert!(!run.exists(), "{key}: the run folder was created");
    }
    // A budget check against a given amount: 1 kB refuses even the small network.
    assert!(budget::check(&need, 1e3, "model.base_width").is_err());
    assert!(budget::check(&need, 1e12, "model.base_width").is_ok());
}

#[test]
fn a_fine_tune_draws_a_fresh_stream_not_its_pretrainings_first_samples() {
    use hdrsynth::data::loader::{Loader, SampleKind};
    let tmp = tempfile::tempdir().expect("tmp");
    let pre = parse(&config_text(&tmp.path().join("pre"), 4, "", 1e-3, false));
    let fine = parse(&format!(
        "{}[init]\ncheckpoint = {:?}\n",
        config_text(&tmp.path().join("fine"), 4, "", 1e-3, false),
        tmp.path().join("pre")
    ));
    let first = |cfg: &TrainConfig| {
        let l =
            Loader::new(&cfg.loader(SampleKind::Network1).expect("loader config")).expect("loader");
        (0..4)
            .map(|g| l.stream_sample(g).expect("sample").input)
            .collect::<Vec<_>>()
    };
    let (p, f) = (first(&pre), first(&fine));
    for (g, (a, b)) in p.iter().zip(&f).enumerate() {
        assert_ne!(
            a, b,
            "sample {g}: the fine-tune replays the pretraining's crop"
        );
    }
    assert_eq!(
        f,
        first(&fine),
        "the fine-tune's stream is a function of its seed"
    );
    assert_eq!(
        pre.stream_seed(),
        3,
        "a run without [init] streams from run.seed itself"
    );
}
