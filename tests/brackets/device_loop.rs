//! The device loop: a capture never both calibrates and is scored, the metering step alone
//! trains the device's rule, and calibration scenes without noise are refused.

use crate::common::{self, TestNoise};
use crate::helpers::{
    Spatial, bracket_jpeg, calibrate_srgb, noisy_bracket_jpeg, noisy_png_bracket, tags,
    train_tiny_with,
};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::scan::{self, ScanOptions};
use hdrsynth::capture::testset::{self, BracketOptions, GtFrames, InputChoice};
use hdrsynth::sensor::profile::{Response, SensorProfile};
use std::path::{Path, PathBuf};

#[test]
fn a_network_is_never_scored_on_captures_that_calibrated_its_profile() {
    use hdrsynth::eval::evaluate::{self, EvalOptions};
    use hdrsynth::eval::infer::NetworkOptions;
    use hdrsynth::runner::method::from_checkpoint;
    let tmp = tempfile::tempdir().expect("tmp");
    noisy_png_bracket(
        &tmp.path().join("scene"),
        4e-4,
        1e-5,
        &[-2.0, 0.0, 2.0],
        Spatial::White,
    );
    let beside = tempfile::tempdir().expect("tmp");
    let scan = |region| ScanOptions {
        region,
        ..ScanOptions::default()
    };
    // Calibrated on the left half of the frames.
    let profile = beside.path().join("phone.toml");
    calibrate_srgb(tmp.path(), scan(Some(scan::Region::Left)), &profile, false);
    let p = SensorProfile::load(&profile).expect("load");
    assert_eq!(p.calibrated_on.len(), 3);
    assert!(p.calibrated_on.iter().all(|s| s.pixels == [0, 0, 96, 144]));
    let run = beside.path().join("run");
    train_tiny_with(
        &run,
        "kind = \"wu\"\nbase_width = 4\nres_blocks = 1",
        "[-2.0, 0.0, 2.0]",
        &format!("profile = {profile:?}\nisos = [100.0]"),
    );
    let testset = |region, name: &str| -> PathBuf {
        let out = beside.path().join(name);
        let opts = BracketOptions {
            scan: scan(region),
            response: ResponseChoice::Declared(Response::Srgb),
            ..BracketOptions::default()
        };
        testset::build(tmp.path(), &opts, &out).expect("build");
        out
    };
    let device = hdrsynth::device::device_from_name("flex").expect("flex");
    let method = from_checkpoint(&run, &NetworkOptions::default(), &device).expect("load");
    let eval = |set: &Path, name: &str| {
        evaluate::evaluate(
            set,
            method.as_ref(),
            &beside.path().join(name),
            &EvalOptions::default(),
        )
    };
    // The whole frames hold the calibration's pixels: refused, naming the set and the frame,
    // and nothing is written.
    let whole = testset(None, "whole");
    let e = eval(&whole, "e_whole").expect_err("scored on its calibration captures");
    let msg = e.to_string();
    assert!(
        msg.contains("scene") && msg.contains(".png") && msg.contains("calibrat"),
        "{msg}"
    );
    assert!(!beside.path().join("e_whole").exists());
    // The right half is other pixels of the same frames: scored.
    let right = testset(Some(scan::Region::Right), "right");
    let scored = eval(&right, "e_right").expect("disjoint regions are scored");
    assert_eq!(scored.rows.len(), 1);
    // A network trained on the frames themselves (a set built from the left half, no
    // profile: the loop's `real` row) is held to the same split, and linearises its inputs
    // through the curve that set records.
    let left = testset(Some(scan::Region::Left), "left");
    let real = beside.path().join("real");
    let text = format!(
        "[run]\nout = {real:?}\nseed = 4\nsteps = 2\ncheckpoint_every = 2\nlog_every = 1\n\
         [model]\nkind = \"wu\"\nbase_width = 4\nres_blocks = 1\noutput = \"merge\"\n\
         linearise = \"data\"\n[data]\ndataset = {left:?}\npatch = 32\nbatch_size = 2\n\
         workers = 1\nprofile = \"pure\"\n[optim]\nlr = 1e-3\n"
    );
    let cfg: hdrsynth::train::config::TrainConfig =
        hdrsynth::config::parse_toml(&text, Path::new("real.toml")).expect("config");
    hdrsynth::train::run(&cfg, &hdrsynth::train::TrainOptions::default()).expect("train");
    let trained: hdrsynth::train::config::TrainConfig =
        hdrsynth::config::load_toml(&real.join("config.toml")).expect("run config");
    let hdrsynth::models::ModelConfig::Wu(m) = &trained.model else {
        panic!("a Wu model")
    };
    assert_eq!(
        m.input_response,
        Response::Srgb,
        "the left set's recorded curve"
    );
    let method = from_checkpoint(&real, &NetworkOptions::default(), &device).expect("load");
    let e = evaluate::evaluate(
        &whole,
        method.as_ref(),
        &beside.path().join("r_whole"),
        &EvalOptions::default(),
    )
    .expect_err("scored on the captures it was trained on");
    assert!(
        e.to_string().contains("scene") && e.to_string().contains(".png"),
        "{e}"
    );
    assert!(!beside.path().join("r_whole").exists());
    evaluate::evaluate(
        &right,
        method.as_ref(),
        &beside.path().join("r_right"),
        &EvalOptions::default(),
    )
    .expect("disjoint regions are scored");
}

/// The loop on `brackets` with every option at its default, seed 1, writing into `beside`
/// and pointed at a main job that does not exist there (what a split refusal comes before).
fn loop_without_main_job(
    brackets: &Path,
    beside: &Path,
) -> hdrsynth::experiments::device_loop::LoopOptions {
    hdrsynth::experiments::device_loop::LoopOptions {
        brackets: brackets.to_path_buf(),
        calibration: Vec::new(),
        calibration_region: None,
        test_region: None,
        scan: ScanOptions::default(),
        inputs: InputChoice::default(),
        gt_frames: GtFrames::default(),
        quickstart: beside.join("no_quickstart"),
        seeds: vec![1],
        out: beside.join("loop"),
        progress: false,
    }
}

#[test]
fn the_loop_refuses_a_split_in_which_a_capture_both_calibrates_and_is_scored() {
    use hdrsynth::capture::scan::Region;
    use hdrsynth::experiments::device_loop::{LoopOptions, run};
    let tmp = tempfile::tempdir().expect("tmp");
    noisy_png_bracket(
        &tmp.path().join("scene"),
        4e-4,
        1e-5,
        &[-2.0, 0.0, 2.0],
        Spatial::White,
    );
    let beside = tempfile::tempdir().expect("tmp");
    let opts = |calibration: &[&str], cal: Option<Region>, test: Option<Region>| LoopOptions {
        calibration: calibration.iter().map(|s| s.to_string()).collect(),
        calibration_region: cal,
        test_region: test,
        ..loop_without_main_job(tmp.path(), beside.path())
    };
    let err = |o: LoopOptions| run(&o).err().expect("refused").to_string();
    // One scene and no regions: nothing to score on.
    let e = err(opts(&[], None, None));
    assert!(e.contains("--calibration") && e.contains("scene"), "{e}");
    let e = err(opts(&["scene"], None, None));
    assert!(e.contains("every set"), "{e}");
    // Overlapping regions of the same frames.
    let e = err(opts(&[], Some(Region::Left), Some(Region::Top)));
    assert!(e.contains("both calibrate") && e.contains(".png"), "{e}");
    let e = err(opts(&["nowhere"], None, None));
    assert!(e.contains("nowhere"), "{e}");
    // Disjoint halves pass the split; the missing main job is what stops it then.
    let e = err(opts(&[], Some(Region::Left), Some(Region::Right)));
    assert!(e.contains("quickstart"), "{e}");
    assert!(!beside.path().join("loop").exists());
    // A main job whose fine-tune config is not one, or whose pretrained network is missing, is
    // refused before any work, naming what is wrong.
    let configs = beside.path().join("qs/configs");
    std::fs::create_dir_all(&configs).expect("mkdir");
    std::fs::write(configs.join("finetune.toml"), "not a training config").expect("write");
    let with_main_job = |q: &str| LoopOptions {
        quickstart: beside.path().join(q),
        ..opts(&[], Some(Region::Left), Some(Region::Right))
    };
    let e = err(with_main_job("qs"));
    assert!(e.contains("finetune.toml"), "{e}");
    let q = tiny_main_job(&beside.path().join("qs2"), &[]);
    let e = err(with_main_job("qs2"));
    assert!(
        e.contains("seed 1") && e.contains(&q.join("pretrain/seed1").display().to_string()),
        "{e}"
    );
    assert!(!beside.path().join("loop").exists(), "nothing written");
}

#[test]
fn the_loop_refuses_a_calibration_frame_resaved_under_another_name_in_a_test_scene() {
    use hdrsynth::experiments::device_loop::{LoopOptions, run};
    let tmp = tempfile::tempdir().expect("tmp");
    let white = Spatial::White;
    noisy_png_bracket(
        &tmp.path().join("cal"),
        4e-4,
        1e-5,
        &[-2.0, 0.0, 2.0],
        white,
    );
    noisy_png_bracket(
        &tmp.path().join("test"),
        4e-4,
        1e-5,
        &[-3.0, -1.0, 1.0],
        white,
    );
    let beside = tempfile::tempdir().expect("tmp");
    let opts = LoopOptions {
        calibration: vec!["cal".to_string()],
        ..loop_without_main_job(tmp.path(), beside.path())
    };
    // Different captures pass the split; the missing main job is what stops the loop then.
    let e = run(&opts).err().expect("refused").to_string();
    assert!(e.contains("quickstart"), "{e}");
    // The test scene's f0.png becomes the calibration scene's f1.png, re-encoded losslessly
    // (other compression and filter, so other bytes, the same pixels).
    let src = image::open(tmp.path().join("cal/f1.png"))
        .expect("png")
        .to_rgb8();
    let dst = tmp.path().join("test/f0.png");
    let file = std::fs::File::create(&dst).expect("create");
    let encoder = image::codecs::png::PngEncoder::new_with_quality(
        file,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::NoFilter,
    );
    src.write_with_encoder(encoder).expect("re-encode");
    let (a, b) = (
        std::fs::read(tmp.path().join("cal/f1.png")).expect("read"),
        std::fs::read(&dst).expect("read"),
    );
    assert_ne!(a, b, "the re-save must differ byte for byte");
    let e = run(&opts).err().expect("refused").to_string();
    assert!(e.contains("f0.png") && e.contains("both calibrate"), "{e}");
    assert!(!beside.path().join("loop").exists(), "nothing written");
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("mkdir");
    for e in std::fs::read_dir(from).expect("read_dir") {
        let e = e.expect("entry");
        let dst = to.join(e.file_name());
        if e.file_type().expect("type").is_dir() {
            copy_dir(&e.path(), &dst);
        } else {
            std::fs::copy(e.path(), &dst).expect("copy");
        }
    }
}

/// A main job the loop can start from, made small: a generated training set, a Network-2
/// (merge head, the training curve) pretrained for 1 step per seed in `seeds`, and its
/// fine-tune config (2 steps). The folder.
fn tiny_main_job(dir: &Path, seeds: &[u64]) -> PathBuf {
    let data = dir.join("data/train");
    common::generate(&data, 5, 3, (64, 64), "[-2.0, 0.0, 2.0]");
    let config = |out: &Path, steps: u64| {
        format!(
            "[run]\nout = {out:?}\nseed = 1\nsteps = {steps}\ncheckpoint_every = {steps}\n\
             log_every = 1\n[model]\nkind = \"wu\"\nbase_width = 2\nres_blocks = 0\n\
             output = \"merge\"\nlinearise = \"data\"\n[data]\ndataset = {data:?}\n\
             patch = 32\nbatch_size = 2\nworkers = 1\nprofile = \"pure\"\n\
             isos = [100.0]\n[optim]\nlr = 1e-3\n"
        )
    };
    for seed in seeds {
        let text = config(&dir.join(format!("pretrain/seed{seed}")), 1);
        let cfg: hdrsynth::train::config::TrainConfig =
            hdrsynth::config::parse_toml(&text, Path::new("pretrain.toml")).expect("config");
        hdrsynth::train::run(&cfg, &hdrsynth::train::TrainOptions::default()).expect("pretrain");
    }
    std::fs::create_dir_all(dir.join("configs")).expect("mkdir");
    std::fs::write(
        dir.join("configs/finetune.toml"),
        config(&dir.join("unused"), 2),
    )
    .expect("write");
    dir.to_path_buf()
}

/// The loop's steps are an ablation: the profiles of the steps before "metering" hold no
/// exposure rule and their rows give none (they train with the default), the metering row gives
/// the device's rule measured on the calibration scene.
#[test]
fn the_loop_trains_the_device_rule_in_its_metering_step_only() {
    use hdrsynth::capture::profile::metering_rule;
    use hdrsynth::experiments::device_loop::{LoopOptions, run};
    use hdrsynth::sensor::profile::SensorProfile;
    let tmp = tempfile::tempdir().expect("tmp");
    // Two scenes (another light, another time), each a noisy auto-exposure bracket; the
    // calibration scene holds a fourth frame, so its ground truth holds more than the inputs
    // and the loop makes its `real` row.
    let mut rng = TestNoise(3);
    for (scene, light, time) in [("park", 1.0, "10:00:00"), ("kitchen", 0.5, "11:00:00")] {
        let d = tmp.path().join(scene);
        std::fs::create_dir_all(&d).expect("mkdir");
        let frames: &[(u32, i32)] = if scene == "park" {
            &[(100, 0), (400, -2), (25, 2), (200, -1)]
        } else {
            &[(100, 0), (400, -2), (25, 2)]
        };
        for (i, (den, b)) in frames.iter().enumerate() {
            let date = format!("2026:11:24 {time}");
            let mut t = tags((1, *den), 100, &date, &format!("{i}"));
            t.bias = Some((*b, 1));
            let file = d.join(format!("IMG_{i}.jpg"));
            noisy_bracket_jpeg(&file, light / *den as f64, Some(&t), Some(&mut rng));
        }
    }
    let beside = tempfile::tempdir().expect("tmp");
    // The whole loop, from a main job made small; its Net_S here is its pretrained network,
    // where the main job's grid keeps it.
    let q = tiny_main_job(&beside.path().join("qs"), &[1]);
    copy_dir(
        &q.join("pretrain/seed1"),
        &q.join("experiment/cells/net_s/seed1/run"),
    );
    // The main job's stock phone profile, as quickstart copies it.
    std::fs::create_dir_all(q.join("configs/sensors")).expect("mkdir");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/sensors/composite_phone.toml"),
        q.join("configs/sensors/composite_phone.toml"),
    )
    .expect("copy");
    // The main job's dynamic test set, as its grid declares it: built by the loop from the
    // generated moving scenes through the stock profile, noise per seed.
    common::generate(&q.join("data/moving"), 9, 2, (64, 64), "[-2.0, 0.0, 2.0]");
    std::fs::write(
        q.join("configs/experiment.toml"),
        format!(
            "title = \"main job\"\nout = {:?}\nbase = {:?}\nseeds = [1]\nrows = []\n\
             [testset]\ndir = {:?}\n[[also]]\nname = \"dynamic\"\ndir = {:?}\nradiance = {:?}\n\
             profile = {:?}\nnoise_per_seed = true\n[also.options]\nisos = [100.0]\n\
             evs = [-2.0, 0.0, 2.0]\n",
            q.join("experiment"),
            q.join("configs/finetune.toml"),
            q.join("data/testset"),
            q.join("data/testset_dynamic"),
            q.join("data/moving"),
            q.join("configs/sensors/composite_phone.toml"),
        ),
    )
    .expect("experiment.toml");
    let out = beside.path().join("loop");
    let opts = LoopOptions {
        brackets: tmp.path().to_path_buf(),
        calibration: vec!["park".into()],
        calibration_region: None,
        test_region: None,
        scan: ScanOptions::default(),
        inputs: InputChoice::default(),
        gt_frames: GtFrames::default(),
        quickstart: q.clone(),
        seeds: vec![1],
        out: out.clone(),
        progress: false,
    };
    let summary = run(&opts).expect("loop");
    let report = std::fs::read_to_string(out.join("loop.md")).expect("loop.md");
    for row in [
        "| copy: the reference frame, linearised (no network) |",
        "| triangle merge of the inputs (no network) |",
        "| Net_S (the main job's network for a stock sRGB phone profile; no calibration) |",
        "| generic: a stock sRGB phone profile (the main job's composite), fine-tuned here as \
         the steps are; no calibration |",
        "| real: fine-tuned on the calibration scenes' own frames against their ground truth \
         (every frame merged); no simulation |",
    ] {
        assert!(report.contains(row), "{row}: {report}");
    }
    // Its reading names, for each network, whether it beats what the user has; one seed and
    // one scene: by the sign of that seed's difference. Copying the reference loses to every
    // network here (the test's frames are clean and the merge head starts as the triangle
    // merge): every row is listed as beating it.
    let reading = report
        .lines()
        .find(|l| l.starts_with("- Against the copied reference frame:"))
        .unwrap_or_else(|| panic!("{report}"));
    assert!(
        reading.contains("beat it net_o (+")
            && reading.contains("generic (+")
            && reading.ends_with("no difference shown none."),
        "{reading}"
    );
    // Calibrating against not calibrating at equal training: each step against the generic
    // row, in the table of gains.
    assert!(
        report.contains("| response | generic | psnr_t |"),
        "{report}"
    );
    assert!(
        report
            .lines()
            .any(|l| l.starts_with("- Against the triangle merge of the inputs: beat it")),
        "{report}"
    );
    // The output-domain effects the device-output check reads, each said taken or not and
    // why.
    for id in ["`floor`: floor: mean code", "`jpeg`: blockiness"] {
        assert!(report.contains(id), "{id}: {report}");
    }
    // A picture per test scene, linked from the report.
    assert!(
        report.contains("- [kitchen](pictures/kitchen.png)"),
        "{report}"
    );
    let strip = image::open(out.join("pictures/kitchen.png")).expect("picture");
    assert!(
        strip.width() > 2 * 96 && strip.height() > 96,
        "{}×{}",
        strip.width(),
        strip.height()
    );
    // The device-output check's plots: the gap per step, and each step's statistics.
    assert!(
        report.contains("[the gap of every step](pictures/device_output_gap.png)"),
        "{report}"
    );
    for name in ["gap", "response", "noise"] {
        let file = out.join(format!("pictures/device_output_{name}.png"));
        let plot = image::open(&file).expect("plot");
        assert_eq!(
            (plot.width(), plot.height()),
            (520, 340),
            "{}",
            file.display()
        );
        assert!(
            report.contains(&format!("(pictures/device_output_{name}.png)")),
            "{report}"
        );
    }
    // Every network scored where subjects move too, against the triangle merge.
    let moving = report
        .split("## Where subjects move")
        .nth(1)
        .unwrap_or_else(|| panic!("{report}"));
    for row in ["| net_o | ", "| response | ", "| real | ", "| real_mix | "] {
        assert!(moving.contains(row), "{row}: {moving}");
    }
    // The network handed over: the `real_mix` row, by rule (its calibration-scene score is
    // in-sample), whatever scores best there.
    assert!(
        report.contains("## The network the loop hands over")
            && report.contains("the `real_mix` row"),
        "{report}"
    );
    let handed: toml::Table = std::fs::read_to_string(out.join("handover.toml"))
        .expect("handover.toml")
        .parse()
        .expect("handover.toml parses");
    let seed1 = handed["seed1"].as_table().expect("[seed1]");
    assert_eq!(seed1["row"].as_str(), Some("real_mix"), "{handed}");
    let checkpoint = Path::new(seed1["checkpoint"].as_str().expect("checkpoint"));
    assert!(
        checkpoint.ends_with("cells/real_mix/seed1/run"),
        "{}",
        checkpoint.display()
    );
    assert!(checkpoint.is_dir(), "{}", checkpoint.display());
    // It trained on the calibration scene's own frames (no profile), through their curve, and
    // half its samples on the main job's training scenes through the last step's profile.
    let mixed: hdrsynth::train::config::TrainConfig =
        hdrsynth::config::load_toml(&checkpoint.join("config.toml")).expect("config");
    assert_eq!(mixed.data.dataset, out.join("validation"));
    assert_eq!(mixed.data.realism.profile, Path::new("pure"));
    let mix = mixed.mix.as_ref().expect("[mix]");
    assert_eq!(mix.fraction, 0.5);
    assert_eq!(mix.data.dataset, q.join("data/train"));
    let grid_text = std::fs::read_to_string(out.join("loop_ablate.toml")).expect("grid");
    let grid: toml::Table = toml::from_str(&grid_text).expect("toml");
    let rows = grid["rows"].as_array().expect("rows");
    let real_at = rows
        .iter()
        .position(|r| r["name"].as_str() == Some("real"))
        .expect("real");
    // The row before `real` is the last step.
    let last_step = rows[real_at - 1]["set"]["data"]["profile"].as_str();
    assert_eq!(mix.data.realism.profile.to_str(), last_step, "{grid_text}");
    // The same folders spelled another way resume it (every cell kept); another split is
    // refused.
    let respelled = LoopOptions {
        quickstart: q.join("configs/.."),
        out: out.join("../loop/."),
        ..opts.clone()
    };
    let again = run(&respelled).expect("resumed with another spelling");
    assert_eq!(again.report, summary.report);
    let e = run(&LoopOptions {
        calibration: vec!["kitchen".into()],
        ..opts.clone()
    })
    .err()
    .expect("another split")
    .to_string();
    assert!(e.contains("another split"), "{e}");
    // The rule of the calibration scene, as `calibrate brackets` measures it.
    let cal = calibrate_srgb(
        tmp.path(),
        ScanOptions {
            sets: vec!["park".into()],
            ..ScanOptions::default()
        },
        &beside.path().join("park.toml"),
        false,
    );
    let rule = metering_rule(&cal.metering).expect("marked");
    let calibrated =
        SensorProfile::load(&out.join("profiles/calibrated.toml")).expect("the calibrated profile");
    assert_eq!(
        (calibrated.metering, calibrated.provenance.metering),
        (None, None)
    );
    let text = std::fs::read_to_string(out.join("loop_ablate.toml")).expect("grid");
    let grid: toml::Table = toml::from_str(&text).expect("toml");
    let rows = grid["rows"].as_array().expect("rows");
    let metering_of = |name: &str| {
        let row = rows
            .iter()
            .find(|r| r["name"].as_str() == Some(name))
            .unwrap_or_else(|| panic!("row {name}: {text}"));
        row.get("set")
            .and_then(|s| s.get("data"))
            .and_then(|d| d.get("metering"))
            .cloned()
    };
    assert_eq!(metering_of("response"), None, "{text}");
    assert_eq!(metering_of("noise"), None, "{text}");
    let m = metering_of("metering").expect("the metering step gives the rule");
    // The loop measures on the Debevec-linearised frames, this calibration on sRGB ones: the
    // clipped fraction is of the codes and agrees; mid grey is the same order.
    assert_eq!(
        m["max_clipped"].as_float(),
        Some(rule.max_clipped),
        "{text}"
    );
    let mid = m["mid_grey"].as_float().expect("mid_grey");
    assert!(mid > 0.0 && mid < 1.0, "{text}");
}

#[test]
fn the_loop_refuses_calibration_scenes_that_give_no_noise_naming_why() {
    use hdrsynth::experiments::device_loop::{LoopOptions, run};
    let tmp = tempfile::tempdir().expect("tmp");
    // Noise-free frames of a steep ramp: no flat pixels, no noise to measure.
    for (scene, light) in [("park", 1.0), ("kitchen", 0.5)] {
        let d = tmp.path().join(scene);
        std::fs::create_dir_all(&d).expect("mkdir");
        for (i, den) in [400u32, 100, 25].iter().enumerate() {
            let t = tags((1, *den), 100, "2026:11:24 10:00:00", &format!("{i}"));
            bracket_jpeg(
                &d.join(format!("IMG_{i}.jpg")),
                light / *den as f64,
                Some(&t),
            );
        }
    }
    let beside = tempfile::tempdir().expect("tmp");
    let q = tiny_main_job(&beside.path().join("qs"), &[1]);
    let out = beside.path().join("loop");
    let e = run(&LoopOptions {
        brackets: tmp.path().to_path_buf(),
        calibration: vec!["park".into()],
        calibration_region: None,
        test_region: None,
        scan: ScanOptions::default(),
        inputs: InputChoice::default(),
        gt_frames: GtFrames::default(),
        quickstart: q,
        seeds: vec![1],
        out: out.clone(),
        progress: false,
    })
    .err()
    .expect("no noise")
    .to_string();
    assert!(
        e.contains("gave no noise measurement") && e.contains("too few flat pixels"),
        "{e}"
    );
    assert!(!out.join("testset").exists() && !out.join("experiment").exists());
}
