//! `hdrsynth eval` (predictions and checkpoints) and `hdrsynth testset` on small images:
//! hand-checked scores, inf handling, the output files, error messages, and test sets that read
//! back through the layout detection.

mod common;

use hdrsynth::config::parse_toml;
use hdrsynth::data::generate::GenerateConfig;
use hdrsynth::data::layout::{self, LayoutKind};
use hdrsynth::data::testset::{self, TestsetOptions};
use hdrsynth::eval::blend::{DEFAULT_TONE_K, fuse};
use hdrsynth::eval::evaluate::{EvalOptions, EvalSummary, NetworkOptions};
use hdrsynth::eval::metrics;
use hdrsynth::io::{BitDepth, ExrPrecision, Image, read_image, read_image_info, write_exr};
use hdrsynth::runner::method::{Source, method_for};
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::sensor::realism::NoiseModel;
use hdrsynth::train::TrainOptions;
use hdrsynth::train::config::TrainConfig;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// What `hdrsynth eval --testset T --out OUT` does for `source`, with `opts`.
fn score(
    testset: &Path,
    source: Source,
    out: &Path,
    opts: &EvalOptions,
) -> hdrsynth::Result<EvalSummary> {
    let method = method_for(&source)?;
    hdrsynth::eval::evaluate::evaluate(testset, method.as_ref(), out, opts)
}

/// The predictions in `dir`, scored with the defaults.
fn score_predictions(testset: &Path, dir: &Path, out: &Path) -> hdrsynth::Result<EvalSummary> {
    let source = Source::Predictions(dir.to_path_buf());
    score(testset, source, out, &EvalOptions::default())
}

/// A checkpoint (or run folder) run on the CPU with tiles of 32 (a multiple of 2^depth = 4).
fn checkpoint(path: &Path, backend: &str) -> Source {
    Source::Checkpoint {
        path: path.to_path_buf(),
        backend: backend.into(),
        network: NetworkOptions {
            tile: Some(32),
            ..NetworkOptions::default()
        },
    }
}

/// A small generated test set (EV −3/0, linear ground truth), shared by the tests.
fn dataset() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().expect("tmp");
        common::generate(dir.path(), 5, 4, (64, 48), "[-3.0, 0.0]");
        dir
    })
    .path()
}

fn set_names() -> Vec<String> {
    layout::detect(dataset())
        .expect("detect")
        .sets
        .into_iter()
        .map(|s| s.name)
        .collect()
}

fn gt_path(set: &str) -> PathBuf {
    dataset().join(set).join("hdr_gt.exr")
}

/// Per pixel, whether the set's reference (EV 0, static) frame has its largest channel below
/// 0.1: the under-exposed region of PSNR-T dark.
fn dark_pixels(set: &str) -> Vec<bool> {
    let frame = read_image(&dataset().join(set).join("static/ev+0.png")).expect("frame");
    frame
        .data
        .chunks_exact(3)
        .map(|p| p.iter().all(|&v| v < 0.1))
        .collect()
}

fn dark_fraction_of(set: &str) -> f64 {
    let m = dark_pixels(set);
    m.iter().filter(|d| **d).count() as f64 / m.len() as f64
}

/// Predictions = ground truth × `factor`, one EXR per set.
fn predictions(dir: &Path, factor: f32) {
    std::fs::create_dir_all(dir).expect("mkdir");
    for s in set_names() {
        let gt = read_image(&gt_path(&s)).expect("gt");
        write_exr(
            &dir.join(format!("{s}.exr")),
            &gt.map(|v| v * factor),
            ExrPrecision::Float,
        )
        .expect("write");
    }
}

/// per_image.csv as (header, rows of fields).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).expect("csv");
    let mut lines = text.lines();
    let header = lines
        .next()
        .expect("header")
        .split(',')
        .map(String::from)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    (header, rows)
}

fn num(s: &str) -> f64 {
    s.parse().unwrap_or_else(|_| panic!("not a number: {s}"))
}

fn check_outputs(out: &Path, sets: &[String]) {
    for f in ["per_image.csv", "summary.csv", "summary.md", "report.md"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let report = std::fs::read_to_string(out.join("report.md")).expect("report");
    for s in sets {
        assert!(out.join(format!("{s}.exr")).is_file(), "{s}.exr");
        assert!(out.join(format!("{s}.png")).is_file(), "{s}.png");
        let grid = out.join("grids").join(format!("{s}.png"));
        let (img, info) = read_image_info(&grid).expect("grid");
        assert_eq!(info.bit_depth, Some(BitDepth::Eight));
        assert!(img.width > 2 * 64 && img.height > 2 * 48, "grid too small");
        assert!(
            report.contains(&format!("grids/{s}.png")),
            "report lacks {s}"
        );
    }
}

#[test]
fn predictions_equal_to_the_ground_truth_give_inf_psnr_and_ssim_1() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (pred, out) = (tmp.path().join("pred"), tmp.path().join("out"));
    predictions(&pred, 1.0);
    let r = score_predictions(dataset(), &pred, &out).expect("eval");
    let sets = set_names();
    assert_eq!(r.rows.len(), sets.len());
    let (header, rows) = read_csv(&out.join("per_image.csv"));
    assert_eq!(
        header,
        [
            "set",
            "psnr_l",
            "psnr_t",
            "ssim_l",
            "ssim_t",
            "pu21_psnr",
            "pu21_ssim",
            "width",
            "height",
            "seconds",
            "delta_e2000",
            "psnr_t_dark",
            "dark_fraction",
            "psnr_t_moving",
            "moving_fraction"
        ]
    );
    for row in &rows {
        // The generated sets carry motion masks: over their moving pixels too, the identical
        // prediction is exact.
        if !row[13].is_empty() {
            assert_eq!(row[13], "inf", "{}", row[0]);
        }
        assert_eq!(row[1], "inf");
        assert_eq!(row[2], "inf");
        assert_eq!(num(&row[3]), 1.0);
        assert_eq!(num(&row[4]), 1.0);
        assert_eq!(row[5], "inf");
        assert!((num(&row[6]) - 1.0).abs() < 1e-12);
        assert_eq!((num(&row[7]), num(&row[8])), (64.0, 48.0));
        assert_eq!(num(&row[10]), 0.0, "ΔE00 of identical images");
        let fraction = dark_fraction_of(&row[0]);
        assert_eq!(num(&row[12]), fraction, "{}", row[0]);
        if fraction >= 0.01 {
            assert_eq!(row[11], "inf");
        } else {
            assert_eq!(row[11], "", "{}: too few dark pixels for a value", row[0]);
        }
    }
    // Summary: +inf values are counted and left out; all +inf gives an infinite mean.
    let (h, summary) = read_csv(&out.join("summary.csv"));
    assert_eq!(
        h,
        [
            "metric", "n", "n_inf", "mean", "ci_lo", "ci_hi", "n_scenes", "n_absent"
        ]
    );
    for r in &summary {
        assert_eq!(
            r.len(),
            8,
            "every summary row has n_scenes and n_absent: {r:?}"
        );
    }
    let de = summary.iter().find(|r| r[0] == "delta_e2000").expect("ΔE");
    assert_eq!((num(&de[1]) as usize, num(&de[3])), (sets.len(), 0.0));
    let dark = summary
        .iter()
        .find(|r| r[0] == "psnr_t_dark")
        .expect("dark");
    let with_value = rows.iter().filter(|r| !r[11].is_empty()).count();
    assert!(with_value > 0, "the test set has dark pixels");
    assert_eq!(
        (num(&dark[1]) as usize, num(&dark[7]) as usize),
        (with_value, sets.len() - with_value)
    );
    let psnr_l = summary.iter().find(|r| r[0] == "psnr_l").expect("psnr_l");
    assert_eq!(num(&psnr_l[1]) as usize, sets.len());
    assert_eq!(num(&psnr_l[2]) as usize, sets.len());
    assert_eq!(psnr_l[3], "inf");
    let ssim_t = summary.iter().find(|r| r[0] == "ssim_t").expect("ssim_t");
    assert_eq!(num(&ssim_t[2]), 0.0);
    assert_eq!(
        (num(&ssim_t[3]), num(&ssim_t[4]), num(&ssim_t[5])),
        (1.0, 1.0, 1.0)
    );
    let md = std::fs::read_to_string(out.join("summary.md")).expect("md");
    assert!(md.contains("+inf (excluded)"), "{md}");
    check_outputs(&out, &sets);
    // The written output is the prediction, bit for bit.
    let s = &sets[0];
    assert_eq!(
        read_image(&out.join(format!("{s}.exr"))).expect("out"),
        read_image(&gt_path(s)).expect("gt")
    );
}

#[test]
fn predictions_scaled_by_1_1_give_the_hand_computed_psnr_l() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (pred, out) = (tmp.path().join("pred"), tmp.path().join("out"));
    predictions(&pred, 1.1);
    // Through the binary: the CLI wiring is part of what is tested.
    let st = Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
        .args(["eval", "--quiet", "--resamples", "500", "--predictions"])
        .arg(&pred)
        .arg("--testset")
        .arg(dataset())
        .arg("--out")
        .arg(&out)
        .status()
        .expect("run");
    assert!(st.success());
    let (_, rows) = read_csv(&out.join("per_image.csv"));
    assert_eq!(rows.len(), set_names().len());
    for row in &rows {
        let gt = read_image(&gt_path(&row[0])).expect("gt");
        // PSNR-L = 10 log10(1 / MSE), MSE = mean((1.1 gt − gt)²) = (0.1 · rms(gt))².
        let rms = (gt.data.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / gt.data.len() as f64)
            .sqrt();
        let hand = 20.0 * (1.0 / (0.1 * rms)).log10();
        let got = num(&row[1]);
        // The prediction is 1.1·gt rounded to f32: ≈1e-7 relative per value.
        assert!(
            (got - hand).abs() < 1e-4,
            "{}: PSNR-L {got} vs hand {hand}",
            row[0]
        );
        for v in &row[1..7] {
            assert!(num(v).is_finite(), "{}: {v}", row[0]);
        }
        // PSNR-T over the pixels where the reference (EV 0) frame is dark, by hand.
        let mask = dark_pixels(&row[0]);
        let n = mask.iter().filter(|m| **m).count();
        let (mut sum, pred) = (0.0, gt.map(|v| v * 1.1));
        for (p, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
            for c in 0..3 {
                let d = metrics::mu_law(pred.data[3 * p + c] as f64)
                    - metrics::mu_law(gt.data[3 * p + c] as f64);
                sum += d * d;
            }
        }
        if n as f64 >= 0.01 * mask.len() as f64 {
            let hand = 10.0 * (3.0 * n as f64 / sum).log10();
            assert!(
                (num(&row[11]) - hand).abs() < 1e-9,
                "{}: {} vs {hand}",
                row[0],
                row[11]
            );
        }
        assert!(num(&row[10]) > 0.0 && num(&row[10]).is_finite());
    }
    let (_, summary) = read_csv(&out.join("summary.csv"));
    // Every metric, PSNR-T over the moving pixels included: each set counted once, with a
    // value or absent.
    assert_eq!(summary.len(), 9);
    let moving = summary
        .iter()
        .find(|r| r[0] == "psnr_t_moving")
        .expect("moving");
    assert_eq!(
        num(&moving[1]) as usize + num(&moving[7]) as usize,
        set_names().len(),
        "{moving:?}"
    );
    for r in summary.iter().filter(|r| num(&r[1]) > 0.0) {
        let (mean, lo, hi) = (num(&r[3]), num(&r[4]), num(&r[5]));
        assert!(lo <= mean && mean <= hi, "{}: {lo} {mean} {hi}", r[0]);
        assert_eq!(num(&r[2]), 0.0);
    }
    // The mean is the mean of the per-image values.
    let mean_l = rows.iter().map(|r| num(&r[1])).sum::<f64>() / rows.len() as f64;
    assert!((num(&summary[0][3]) - mean_l).abs() < 1e-9);
    check_outputs(&out, &set_names());
}

#[test]
fn a_missing_prediction_is_an_error_naming_the_set_unless_allowed() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (pred, out) = (tmp.path().join("pred"), tmp.path().join("out"));
    predictions(&pred, 1.0);
    let sets = set_names();
    let gone = &sets[1];
    std::fs::remove_file(pred.join(format!("{gone}.exr"))).expect("rm");
    let err = score_predictions(dataset(), &pred, &out).expect_err("missing");
    let msg = format!("{err:#}");
    assert!(msg.contains(&format!("set '{gone}'")), "{msg}");
    assert!(
        msg.contains(&pred.join(format!("{gone}.exr")).display().to_string()),
        "{msg}"
    );
    assert!(!out.join("per_image.csv").exists(), "nothing is written");

    let allowed = EvalOptions {
        allow_missing: true,
        ..EvalOptions::default()
    };
    let source = Source::Predictions(pred.clone());
    let r = score(dataset(), source, &out, &allowed).expect("allowed");
    assert_eq!(r.rows.len(), sets.len() - 1);
    assert_eq!(r.missing.len(), 1);
    assert_eq!(&r.missing[0].0, gone);
    let md = std::fs::read_to_string(out.join("summary.md")).expect("md");
    assert!(md.contains(gone.as_str()), "{md}");
}

#[test]
fn a_prediction_of_the_wrong_size_is_an_error_naming_the_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (pred, out) = (tmp.path().join("pred"), tmp.path().join("out"));
    predictions(&pred, 1.0);
    let s = &set_names()[0];
    let bad = pred.join(format!("{s}.exr"));
    write_exr(&bad, &Image::new(32, 24), ExrPrecision::Float).expect("write");
    let err = score_predictions(dataset(), &pred, &out).expect_err("size");
    let msg = format!("{err:#}");
    assert!(msg.contains(&bad.display().to_string()), "{msg}");
    assert!(msg.contains("32×24") && msg.contains("64×48"), "{msg}");
}

/// The Network-1 reference is the pair's Mertens fusion: a network that predicted the Mertens
/// weights exactly would score (nearly) perfectly, so the comparison measures the blend map.
#[test]
fn network1_reference_is_what_perfect_blend_weights_reproduce() {
    let set = &layout::detect(dataset()).expect("detect").sets[0];
    let low = read_image(&set.static_frames[0]).expect("low");
    let high = read_image(&set.static_frames[1]).expect("high");
    let w = hdrsynth::data::ground_truth::blend_weights_high(&low, &high).expect("w");
    let (l, _) = fuse(&low, &high, &w, DEFAULT_TONE_K).expect("fuse");
    let reference =
        hdrsynth::data::ground_truth::mertens(&[low, high], 1.0, 1.0, 0.0).expect("mertens");
    let p = metrics::psnr(&reference, &l, 1.0).expect("psnr");
    assert!(p > 60.0, "oracle weights give PSNR-L {p}");
}

fn train_config(run: &Path) -> TrainConfig {
    let text = format!(
        "[run]\nout = {run:?}\nseed = 3\nsteps = 2\ncheckpoint_every = 2\nlog_every = 1\n\
         [model]\nkind = \"blend_unet\"\nbase_width = 4\ndepth = 2\nbatch_norm = true\n\
         [data]\ndataset = {:?}\npatch = 32\nbatch_size = 2\nworkers = 1\nprofile = \"pure\"\n\
         [optim]\nlr = 1e-3\n",
        dataset()
    );
    let cfg: TrainConfig = parse_toml(&text, Path::new("train.toml")).expect("train config");
    cfg.validate().expect("valid");
    cfg
}

#[test]
fn a_tiny_network1_checkpoint_is_evaluated_at_full_resolution() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = tmp.path().join("run");
    hdrsynth::train::run(&train_config(&run), &TrainOptions::default()).expect("train");
    let out = tmp.path().join("out");
    // Tiles of 32 on 64×48 frames: several windows per set.
    let opts = EvalOptions::default();
    let r = score(dataset(), checkpoint(&run, "flex"), &out, &opts).expect("eval");
    assert_eq!(r.rows.len(), set_names().len());
    assert!(r.method.contains("Mertens"), "{}", r.method);
    for row in &r.rows {
        let v = [
            row.scores.psnr_l,
            row.scores.psnr_t,
            row.scores.ssim_l,
            row.scores.ssim_t,
            row.scores.pu21_psnr,
            row.scores.pu21_ssim,
        ];
        assert!(v.iter().all(|x| x.is_finite()), "{}: {v:?}", row.set);
        assert!(row.scores.ssim_t > 0.0 && row.scores.ssim_t <= 1.0);
        // Network-1's T images give ΔE00 and the dark region's PSNR; the mask is the pair's
        // long (EV 0) frame's.
        assert!(row.scores.delta_e2000.is_finite() && row.scores.delta_e2000 > 0.0);
        let fraction = dark_fraction_of(&row.set);
        assert_eq!(row.scores.dark_fraction, Some(fraction));
        assert_eq!(
            row.scores.psnr_t_dark.is_some(),
            fraction >= 0.01,
            "{}",
            row.set
        );
    }
    check_outputs(&out, &set_names());
    // The preview is T of the written L output.
    let s = &set_names()[0];
    let l = read_image(&out.join(format!("{s}.exr"))).expect("L");
    let t = read_image(&out.join(format!("{s}.png"))).expect("T");
    let want = hdrsynth::eval::blend::tone_curve(l.data[0], DEFAULT_TONE_K);
    assert!((t.data[0] - want).abs() <= 0.5 / 255.0 + 1e-6);
    for summary in r.summary.iter().filter(|m| m.n > 0) {
        assert!(summary.lo <= summary.mean && summary.mean <= summary.hi);
    }
}

#[test]
fn eval_with_a_training_config_scores_that_runs_latest_checkpoint() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = tmp.path().join("run");
    let cfg = train_config(&run);
    hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("train");
    let path = tmp.path().join("train.toml");
    std::fs::write(&path, toml::to_string(&cfg).expect("toml")).expect("write");
    let scores = |source: Source, out: &str| {
        let opts = EvalOptions::default();
        let r = score(dataset(), source, &tmp.path().join(out), &opts).expect("eval");
        r.rows.iter().map(|r| r.scores.psnr_t).collect::<Vec<_>>()
    };
    // What `hdrsynth eval --config` resolves: the run's folder (its latest checkpoint) on its
    // backend.
    let read = TrainConfig::load(&path).expect("config");
    let by_config = scores(checkpoint(&read.run.out, &read.run.backend), "a");
    let by_run = scores(checkpoint(&run, "flex"), "b");
    assert_eq!(by_config, by_run);
    assert_eq!(by_run.len(), set_names().len());
}

/// A synthetic linear radiance map with a wide range (a horizontal ramp over 12 stops, tinted).
fn radiance_map(w: usize, h: usize) -> Image {
    Image::from_fn(w, h, |x, y| {
        let v = (x as f32 / (w - 1) as f32 * 12.0 - 8.0).exp2();
        let t = y as f32 / (h - 1) as f32;
        [v * (0.6 + 0.4 * t), v, v * (1.0 - 0.3 * t)]
    })
}

fn canon() -> SensorProfile {
    SensorProfile::load(&SensorProfile::shipped_dir().join("canon_eos_550d.toml")).expect("profile")
}

#[test]
fn a_testset_from_a_linear_exr_reads_back_with_the_radiance_in_device_space() {
    let tmp = tempfile::tempdir().expect("tmp");
    let src = tmp.path().join("ramp scene.exr");
    let radiance = radiance_map(40, 30);
    write_exr(&src, &radiance, ExrPrecision::Float).expect("write");
    let out = tmp.path().join("ts");
    let opts = TestsetOptions {
        isos: vec![100.0, 1600.0],
        evs: vec![-2.0, 0.0, 2.0],
        noise: NoiseModel::None,
        colour: false,
        ..TestsetOptions::default()
    };
    let summary = testset::build(&src, &canon(), &opts, &out).expect("build");
    assert_eq!(summary.sets.len(), 2);
    let info = layout::detect(&out).expect("detect");
    assert_eq!(info.layout, LayoutKind::Hdrsynth);
    let names: Vec<&str> = info.sets.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["ramp_scene_iso100", "ramp_scene_iso1600"]);

    // Hand key (the metering rule): log-average Rec. 709 luminance at 0.128 of white, unless
    // more than 2 % of the pixels would clip: then the 98th percentile (nearest rank, 1200
    // pixels → the 1176th) of the per-pixel maximum channel sits at white.
    let lum: Vec<f64> = radiance
        .pixels()
        .map(|p| 0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64)
        .collect();
    let log_avg = (lum.iter().map(|l| l.ln()).sum::<f64>() / lum.len() as f64).exp();
    let mut peak: Vec<f32> = radiance
        .pixels()
        .map(|p| p[0].max(p[1]).max(p[2]))
        .collect();
    peak.sort_by(f32::total_cmp);
    let k = (0.128 / log_avg).min(1.0 / peak[1175] as f64) as f32;
    assert!(
        (summary.sets[0].key - k).abs() <= 1e-5 * k,
        "{} vs {k}",
        summary.sets[0].key
    );

    let profile = canon();
    let l = &profile.levels;
    for set in &info.sets {
        assert_eq!(set.evs, [-2.0, 0.0, 2.0]);
        assert_eq!(set.reference, 1);
        assert_eq!((set.width, set.height), (40, 30));
        for f in set.static_frames.iter().chain(&set.dynamic_frames) {
            let (_, i) = read_image_info(f).expect("frame");
            assert_eq!(i.bit_depth, Some(BitDepth::Eight), "{}", f.display());
        }
        // hdr_gt.exr = radiance · k (colour off: T = identity), 1 = sensor white at EV0.
        let gt = read_image(&set.ground_truth.as_ref().expect("gt").path).expect("gt");
        let (x, y) = (17, 11);
        let (r, g) = (radiance.get(x, y), gt.get(x, y));
        for c in 0..3 {
            assert!(
                (g[c] - r[c] * k).abs() <= 1e-6 * r[c] * k,
                "{g:?} vs {r:?}·{k}"
            );
        }
        // A frame pixel by hand: DN = round(black + v·k·2^ev·(white − black)) clipped to white,
        // code = round(255 · sRGB((DN − black)/(white − black))) / 255 (noise off).
        for (i, &ev) in set.evs.iter().enumerate() {
            let frame = read_image(&set.static_frames[i]).expect("frame");
            let range = l.white_level - l.black_level;
            let px = frame.get(x, y);
            for (c, (&v, &got)) in r.iter().zip(&px).enumerate() {
                let dn = (l.black_level + v as f64 * k as f64 * (ev as f64).exp2() * range)
                    .min(l.white_level.floor())
                    .round();
                let signal = ((dn - l.black_level) / range) as f32;
                let want = (hdrsynth::io::srgb_encode(signal) * 255.0).round() / 255.0;
                assert!(
                    (got - want).abs() <= 1.0 / 255.0 + 1e-6,
                    "ev {ev} channel {c}: {got} vs {want}"
                );
            }
        }
    }
    // The same recipe again keeps the sets; another recipe in the same folder is refused.
    let again = testset::build(&src, &profile, &opts, &out).expect("rebuild");
    assert!(again.sets.iter().all(|s| !s.written));
    let other = TestsetOptions {
        seed: 9,
        ..opts.clone()
    };
    let err = testset::build(&src, &profile, &other, &out).expect_err("other recipe");
    assert!(err.to_string().contains("different recipe"), "{err}");
}

/// The ground truth holds what the bracket can: clipped per channel at the shortest frame's
/// white, 2^−EV_min in EV0 units (4 for EV −2/0/+2, 8 for EV −3/0, 1 when no frame is shorter);
/// below it, radiance · k as before.
#[test]
fn the_ground_truth_is_clipped_at_the_shortest_frames_white() {
    let tmp = tempfile::tempdir().expect("tmp");
    let src = tmp.path().join("sun.exr");
    // A dim grey field with a 4×4 "sun" 2^12 brighter (1 % of the pixels: below the metering's
    // 2 % highlight allowance, so the key comes from the grey).
    let radiance = Image::from_fn(40, 40, |x, y| {
        let v = if x < 4 && y < 4 { 0.1 * 4096.0 } else { 0.1 };
        [v, v, v]
    });
    write_exr(&src, &radiance, ExrPrecision::Float).expect("write");
    for (evs, white) in [
        (vec![-2.0, 0.0, 2.0], 4.0f32),
        (vec![-3.0, 0.0], 8.0),
        (vec![0.0, 2.0], 1.0),
    ] {
        let out = tmp.path().join(format!("ts{white}"));
        let opts = TestsetOptions {
            isos: vec![100.0],
            evs,
            noise: NoiseModel::None,
            colour: false,
            ..TestsetOptions::default()
        };
        let built = testset::build(&src, &canon(), &opts, &out).expect("build");
        let k = built.sets[0].key;
        // Log-average of 1 % at 0.1·4096 and 99 % at 0.1: the grey sits at 0.128·(…)/0.1.
        let log_avg = (0.01 * (409.6f64).ln() + 0.99 * (0.1f64).ln()).exp();
        assert!(
            ((k as f64) - 0.128 / log_avg).abs() < 1e-5 * k as f64,
            "key {k}"
        );
        let info = layout::detect(&out).expect("detect");
        let gt = read_image(&info.sets[0].ground_truth.as_ref().expect("gt").path).expect("gt");
        assert_eq!(gt.get(0, 0), [white; 3], "the sun is clipped at {white}");
        let grey = 0.1 * k;
        assert!(
            (gt.get(20, 20)[1] - grey).abs() < 1e-6 * grey,
            "below it: radiance · k"
        );
    }
}

/// The classical rows need the curve the frames were made with: a rendered test set records
/// it (its recipe's profile); a folder that records none is refused, named, before any work.
/// On clean frames the triangle merge, which also reads the frames the reference clips or
/// crushes, scores at least as well as the copied reference.
#[test]
fn classical_rows_read_the_sets_curve_or_refuse() {
    use hdrsynth::eval::evaluate::{self, Classical, ClassicalMerge};
    let tmp = tempfile::tempdir().expect("tmp");
    let plain = tmp.path().join("plain");
    common::generate(&plain, 3, 1, (64, 48), "[-2.0, 0.0, 2.0]");
    let e = ClassicalMerge::for_testset(Classical::Copy, &plain)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("plain") && e.contains("records none"),
        "names the folder: {e}"
    );
    let src = tmp.path().join("ramp.exr");
    write_exr(&src, &radiance_map(64, 32), ExrPrecision::Float).expect("write");
    let out = tmp.path().join("ts");
    let opts = TestsetOptions {
        isos: vec![100.0],
        evs: vec![-2.0, 0.0, 2.0],
        ..TestsetOptions::default()
    };
    testset::build(&src, &canon(), &opts, &out).expect("build");
    let score = |kind: Classical| {
        let mut m = ClassicalMerge::for_testset(kind, &out).expect("curve recorded");
        m.clean = true;
        let dir = tmp.path().join(kind.name());
        evaluate::evaluate(&out, &m, &dir, &EvalOptions::default())
            .expect("eval")
            .rows[0]
            .scores
    };
    let (copy, triangle) = (score(Classical::Copy), score(Classical::Triangle));
    assert!(
        triangle.psnr_t >= copy.psnr_t,
        "triangle {} vs copy {}",
        triangle.psnr_t,
        copy.psnr_t
    );
}

/// A network trained with `linearise = "data"` merges its inputs through the curve a test set
/// records for its frames (here γ 2.2, where it was trained on sRGB frames), as the classical
/// rows do. Checked with an untrained merge head (1 step at lr 1e-12), which is the triangle
/// merge: it scores as the triangle merge through the set's curve, not through its own.
#[test]
fn a_data_linearised_network_takes_the_test_sets_curve() {
    use hdrsynth::eval::evaluate::{self, Classical, ClassicalMerge, NetworkOptions};
    use hdrsynth::runner::method::{Source, method_for};
    use hdrsynth::sensor::profile::Response;
    let tmp = tempfile::tempdir().expect("tmp");
    let data = tmp.path().join("train");
    common::generate(&data, 5, 2, (64, 64), "[-2.0, 0.0, 2.0]");
    let run = tmp.path().join("run");
    let srgb = SensorProfile::shipped_dir().join("example_synthetic.toml");
    let cfg: hdrsynth::train::config::TrainConfig = hdrsynth::config::parse_toml(
        &format!(
            "[run]\nout = {run:?}\nseed = 1\nsteps = 1\ncheckpoint_every = 1\n\
             [model]\nkind = \"wu\"\nbase_width = 2\nres_blocks = 0\noutput = \"merge\"\n\
             linearise = \"data\"\n\
             [data]\ndataset = {data:?}\npatch = 32\nbatch_size = 1\nworkers = 1\n\
             profile = {srgb:?}\nisos = [100.0]\n[optim]\nlr = 1e-12\n"
        ),
        Path::new("t.toml"),
    )
    .expect("config");
    hdrsynth::train::run(&cfg, &Default::default()).expect("train");
    let src = tmp.path().join("ramp.exr");
    write_exr(&src, &radiance_map(64, 32), ExrPrecision::Float).expect("write");
    let out = tmp.path().join("ts");
    let gamma =
        SensorProfile::load(&SensorProfile::shipped_dir().join("dslr_canon_550d_gamma22.toml"))
            .expect("profile");
    let opts = TestsetOptions {
        isos: vec![100.0],
        evs: vec![-2.0, 0.0, 2.0],
        ..TestsetOptions::default()
    };
    testset::build(&src, &gamma, &opts, &out).expect("build");
    let psnr_t = |m: &dyn evaluate::Method, name: &str| {
        let dir = tmp.path().join(name);
        evaluate::evaluate(&out, m, &dir, &EvalOptions::default())
            .expect("eval")
            .rows[0]
            .scores
            .psnr_t
    };
    let net = method_for(&Source::Checkpoint {
        path: run,
        backend: "flex".into(),
        network: NetworkOptions::default(),
    })
    .expect("network");
    let merge = |response: Response| ClassicalMerge {
        kind: Classical::Triangle,
        response,
        clean: false,
    };
    let got = psnr_t(net.as_ref(), "net");
    let set_curve = psnr_t(&merge(Response::Gamma { gamma: 2.2 }), "gamma");
    let own_curve = psnr_t(&merge(Response::Srgb), "srgb");
    assert!(
        (got - set_curve).abs() < 0.05,
        "network {got} vs the triangle merge through the set's curve {set_curve}"
    );
    assert!(
        (got - own_curve).abs() > 0.5,
        "the network's own sRGB curve would score {own_curve}, it scored {got}"
    );
}

/// The noise ceiling's merge: with the true device response and noise-free frames it recovers
/// the ground truth (up to 8-bit quantisation); noisy frames at ISO 3200 score lower.
#[test]
fn the_triangle_merge_with_the_true_response_recovers_the_ground_truth() {
    use hdrsynth::eval::evaluate::{self, Classical, ClassicalMerge};
    let tmp = tempfile::tempdir().expect("tmp");
    let src = tmp.path().join("ramp.exr");
    write_exr(&src, &radiance_map(64, 32), ExrPrecision::Float).expect("write");
    let out = tmp.path().join("ts");
    let profile = canon();
    let opts = TestsetOptions {
        isos: vec![3200.0],
        evs: vec![-2.0, 0.0, 2.0],
        ..TestsetOptions::default()
    };
    testset::build(&src, &profile, &opts, &out).expect("build");
    let score = |clean: bool| {
        let m = ClassicalMerge {
            kind: Classical::Triangle,
            response: profile.response.clone(),
            clean,
        };
        let dir = tmp.path().join(format!("eval_{clean}"));
        let s = evaluate::evaluate(&out, &m, &dir, &EvalOptions::default()).expect("eval");
        s.rows[0].scores
    };
    let (clean, noisy) = (score(true), score(false));
    // 8-bit sRGB codes: the relative step near code c is ≈ 2.4 / (255 c^…): a few % in the
    // shadows; in the linear domain the error is tiny next to the ground truth's peak of ~1.
    assert!(clean.psnr_l > 45.0, "clean merge PSNR-L {}", clean.psnr_l);
    assert!(clean.psnr_t > 30.0, "clean merge PSNR-T {}", clean.psnr_t);
    assert!(
        noisy.psnr_t < clean.psnr_t - 1.0,
        "noise costs the merge: {} vs {}",
        noisy.psnr_t,
        clean.psnr_t
    );
}

#[test]
#[ignore = "needs ../shared/data"]
fn a_testset_from_real_radiance_has_noise_colour_and_scores_through_eval() {
    let desk = common::shared_data("real_hdr/Desk.exr");
    let tmp = tempfile::tempdir().expect("tmp");
    let out = tmp.path().join("ts");
    // Through the binary, the Network-1 bracket; resized small for speed.
    let st = Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
        .args(["testset", "--radiance"])
        .arg(&desk)
        .arg("--profile")
        .arg(SensorProfile::shipped_dir().join("canon_eos_550d.toml"))
        .arg("--out")
        .arg(&out)
        .args([
            "--isos",
            "100,3200",
            "--evs=-3,0",
            "--resize",
            "96x128",
            "--seed",
            "4",
        ])
        .status()
        .expect("run");
    assert!(st.success());
    let info = layout::detect(&out).expect("detect");
    let names: Vec<&str> = info.sets.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["Desk_iso100", "Desk_iso3200"]);
    let a = read_image(&info.sets[0].static_frames[1]).expect("a");
    let b = read_image(&info.sets[1].static_frames[1]).expect("b");
    assert_eq!((a.width, a.height), (96, 128));
    // Different ISOs: different noise on the same scene, same ground truth.
    assert_ne!(a, b);
    let ga = read_image(&info.sets[0].ground_truth.as_ref().unwrap().path).expect("gt");
    let gb = read_image(&info.sets[1].ground_truth.as_ref().unwrap().path).expect("gt");
    assert_eq!(ga, gb);
    // The static scene's dynamic frames are the static ones.
    assert_eq!(
        std::fs::read(&info.sets[0].static_frames[0]).unwrap(),
        std::fs::read(&info.sets[0].dynamic_frames[0]).unwrap()
    );
    // Scoring the ground truth against itself through eval works on this layout.
    let pred = tmp.path().join("pred");
    std::fs::create_dir_all(&pred).unwrap();
    for s in &info.sets {
        std::fs::copy(
            &s.ground_truth.as_ref().unwrap().path,
            pred.join(format!("{}.exr", s.name)),
        )
        .unwrap();
    }
    let r = score_predictions(&out, &pred, &tmp.path().join("eval")).expect("eval");
    assert!(r.rows.iter().all(|r| r.scores.psnr_l == f64::INFINITY));
}

/// The Network-2 path with a stand-in network (the reference frame linearised with γ 2.2):
/// frames (EV −2, 0, +2) with exposure times 1/4, 1, 4, scored against the linear ground truth.
#[test]
fn a_multi_frame_hdr_network_is_scored_against_the_linear_ground_truth() {
    use hdrsynth::eval::evaluate::{self, Network2};
    let tmp = tempfile::tempdir().expect("tmp");
    let data = dataset3();
    let method = Network2 {
        description: "stand-in".into(),
        infer: Box::new(|frames: [&Image; 3], times: [f32; 3], _| {
            assert_eq!(times, [0.25, 1.0, 4.0]);
            Ok(frames[1].map(|v| v.powf(2.2) / times[1]))
        }),
    };
    let out = tmp.path().join("out");
    let r = evaluate::evaluate(data, &method, &out, &EvalOptions::default()).expect("eval");
    assert_eq!(r.rows.len(), 2);
    for row in &r.rows {
        assert!(row.scores.psnr_t.is_finite() && row.scores.ssim_t < 1.0);
    }
    let names: Vec<String> = r.rows.iter().map(|r| r.set.clone()).collect();
    for s in &names {
        assert!(out.join("grids").join(format!("{s}.png")).is_file());
    }
    // The grid shows the three input frames in its first row.
    let grid = read_image(&out.join("grids").join(format!("{}.png", names[0]))).expect("grid");
    assert!(grid.width >= 3 * 48);
}

/// A small generated set with the Network-2 bracket (EV −2/0/+2).
fn dataset3() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().expect("tmp");
        let text = "seed = 8\ncount = 2\nwidth = 48\nheight = 40\nevs = [-2.0, 0.0, 2.0]\n\
                    [camera]\ncandidates = 2\n";
        let mut c: GenerateConfig = parse_toml(text, Path::new("gen.toml")).expect("config");
        c.source = None;
        hdrsynth::data::generate::generate(&c, dir.path(), false).expect("generate");
        dir
    })
    .path()
}

#[test]
fn a_tiny_network2_checkpoint_is_evaluated_through_the_binary() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = tmp.path().join("run");
    let text = format!(
        "[run]\nout = {run:?}\nseed = 4\nsteps = 2\ncheckpoint_every = 2\nlog_every = 1\n\
         [model]\nkind = \"wu\"\nbase_width = 4\nres_blocks = 1\n\
         [data]\ndataset = {:?}\npatch = 32\nbatch_size = 2\nworkers = 1\nprofile = \"pure\"\n\
         [optim]\nlr = 1e-3\n",
        dataset3()
    );
    let cfg: TrainConfig = parse_toml(&text, Path::new("net2.toml")).expect("config");
    hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("train");
    let out = tmp.path().join("out");
    let st = Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
        .args(["eval", "--quiet", "--checkpoint"])
        .arg(&run)
        .arg("--testset")
        .arg(dataset3())
        .arg("--out")
        .arg(&out)
        .status()
        .expect("run");
    assert!(st.success());
    let (_, rows) = read_csv(&out.join("per_image.csv"));
    assert_eq!(rows.len(), 2);
    for row in &rows {
        for v in &row[1..7] {
            assert!(num(v).is_finite(), "{}: {v}", row[0]);
        }
    }
    let md = std::fs::read_to_string(out.join("summary.md")).expect("md");
    assert!(md.contains("Network-2"), "{md}");
}
