//! HDR scores in one unit whatever exposure stops a set's file writes,
//! and Network-1's reference from noise-free frames.

use hdrsynth::data::ground_truth::{self, MertensWeights};
use hdrsynth::data::layout::{self, SetInfo};
use hdrsynth::data::pyramid::laplacian_blend;
use hdrsynth::data::testset::{self, TestsetOptions};
use hdrsynth::eval::evaluate::{
    self, EvalOptions, EvalSummary, Method, Network1, Network1Reference, Network2, Predictions,
    ScoreUnit, network1_reference,
};
use hdrsynth::io::{self, BitDepth, ExrPrecision, Image, read_image, write_exr};
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::sensor::realism::NoiseModel;
use std::path::{Path, PathBuf};

const W: usize = 48;
const H: usize = 32;
/// EVs of the bracket relative to the reference.
const EVS: [f32; 3] = [-2.0, 0.0, 2.0];

/// A scene's linear radiance in hdrsynth's unit (1 = the reference exposure's white), ~10 stops.
fn scene() -> Image {
    Image::from_fn(W, H, |x, y| {
        let v = (x as f32 / (W - 1) as f32 * 10.0 - 7.0).exp2();
        let t = y as f32 / (H - 1) as f32;
        [v * (0.5 + 0.5 * t), v, v * (1.0 - 0.4 * t)]
    })
}

/// The frame at `ev`: (radiance · 2^ev clipped to 1)^(1/2.2), as the field's data assumes.
fn frame(g: &Image, ev: f32) -> Image {
    g.map(|v| (v * ev.exp2()).clamp(0.0, 1.0).powf(1.0 / 2.2))
}

fn write_frames(dir: &Path, names: [&str; 3], g: &Image) {
    std::fs::create_dir_all(dir).unwrap();
    for (name, ev) in names.iter().zip(EVS) {
        io::write_ldr(&dir.join(name), &frame(g, ev), BitDepth::Sixteen).unwrap();
    }
}

/// A Kalantari set of the scene: `stops` written to exposure.txt, `HDRImg.hdr` = `gt`.
fn kalantari(dir: &Path, stops: &str, gt: &Image) {
    write_frames(dir, ["a.tif", "b.tif", "c.tif"], &scene());
    std::fs::write(dir.join("exposure.txt"), stops).unwrap();
    io::write_hdr(&dir.join("HDRImg.hdr"), gt).unwrap();
}

/// A Wu set of the scene: `stops` written to input_exp.txt, `ref_hdr_aligned.hdr` = `gt`.
fn wu(dir: &Path, stops: &str, gt: &Image) {
    let names = [
        "input_1_aligned.tif",
        "input_2_aligned.tif",
        "input_3_aligned.tif",
    ];
    write_frames(dir, names, &scene());
    std::fs::write(dir.join("input_exp.txt"), stops).unwrap();
    io::write_hdr(&dir.join("ref_hdr_aligned.hdr"), gt).unwrap();
}

/// The field's triangle-weighted merge of the three frames with the times it is given.
fn merge_network() -> Network2 {
    Network2 {
        description: "triangle merge".into(),
        infer: Box::new(|frames: [&Image; 3], times: [f32; 3], _| {
            assert_eq!(
                times,
                [0.25, 1.0, 4.0],
                "times stay relative to the reference"
            );
            ground_truth::triangle_merge(
                &[frames[0].clone(), frames[1].clone(), frames[2].clone()],
                times,
                2.2,
            )
        }),
    }
}

fn eval(root: &Path, method: &dyn Method, opts: &EvalOptions) -> EvalSummary {
    let out = tempfile::tempdir().unwrap();
    evaluate::evaluate(root, method, out.path(), opts).expect("evaluate")
}

fn only_set(root: &Path) -> SetInfo {
    let info = layout::detect(root).expect("detect");
    assert_eq!(info.sets.len(), 1);
    info.sets.into_iter().next().unwrap()
}

/// (PSNR-L, PSNR-T, SSIM-L, SSIM-T) of the only row.
fn scores(r: &EvalSummary) -> [f64; 4] {
    assert_eq!(r.rows.len(), 1);
    let s = &r.rows[0].scores;
    [s.psnr_l, s.psnr_t, s.ssim_l, s.ssim_t]
}

#[test]
fn the_same_scene_scores_the_same_whatever_stops_its_exposure_file_writes() {
    let tmp = tempfile::tempdir().unwrap();
    let g = scene();
    // The field's reading: Kalantari GT = LDR^γ / 2^s as written; "−2 0 2" → reference units,
    // "0 2 4" → the shortest frame's (reference-unit GT / 4). Wu's code subtracts the
    // smallest stop first, so both Wu files have the GT in the shortest frame's unit.
    let quarter = g.map(|v| v / 4.0);
    let sets = [
        ("k_ref", "-2\n0\n2\n"),
        ("k_short", "0\n2\n4\n"),
        ("w_ref", "-2\n0\n2\n"),
        ("w_short", "0\n2\n4\n"),
    ];
    kalantari(&tmp.path().join(sets[0].0).join("s"), sets[0].1, &g);
    kalantari(&tmp.path().join(sets[1].0).join("s"), sets[1].1, &quarter);
    wu(&tmp.path().join(sets[2].0).join("s"), sets[2].1, &quarter);
    wu(&tmp.path().join(sets[3].0).join("s"), sets[3].1, &quarter);

    let net = merge_network();
    let opts = EvalOptions::default();
    let mut all = Vec::new();
    for (name, _) in sets {
        let root = tmp.path().join(name);
        let r = eval(&root, &net, &opts);
        let s = scores(&r);
        assert!(s.iter().all(|v| v.is_finite()), "{name}: {s:?}");
        all.push((name, s));
    }
    for (name, s) in &all[1..] {
        assert_eq!(*s, all[0].1, "{name} vs {}", all[0].0);
    }

    // Predictions made elsewhere are in the file's unit: 1.1 × that file's ground truth.
    let mut pred_scores = Vec::new();
    for (name, gt) in [("k_ref", &g), ("k_short", &quarter)] {
        let root = tmp.path().join(name);
        let pred = tmp.path().join(format!("{name}_pred"));
        std::fs::create_dir_all(&pred).unwrap();
        let stored = read_image(&root.join("s").join("HDRImg.hdr")).unwrap();
        assert_eq!(stored.width, gt.width);
        write_exr(
            &pred.join("s.exr"),
            &stored.map(|v| 1.1 * v),
            ExrPrecision::Float,
        )
        .unwrap();
        pred_scores.push(scores(&eval(&root, &Predictions { dir: pred }, &opts)));
    }
    assert_eq!(pred_scores[0], pred_scores[1]);
}

#[test]
fn the_unit_factor_is_two_to_the_reference_stop_above_the_files_unit() {
    let tmp = tempfile::tempdir().unwrap();
    let g = scene();
    // Hand values: Kalantari 2^(s_ref − 0), Wu 2^(s_ref − s_min).
    for (i, (stops, k_kal, k_wu)) in [
        ("0 2 4", 4.0, 4.0),
        ("-2 0 2", 1.0, 4.0),
        ("0 3 6", 8.0, 8.0),
        ("1 3 5", 8.0, 4.0),
    ]
    .into_iter()
    .enumerate()
    {
        let kd = tmp.path().join(format!("k{i}"));
        kalantari(&kd, stops, &g);
        assert_eq!(
            only_set(&kd).file_to_reference(),
            k_kal,
            "kalantari {stops}"
        );
        let wd = tmp.path().join(format!("w{i}"));
        wu(&wd, stops, &g);
        assert_eq!(only_set(&wd).file_to_reference(), k_wu, "wu {stops}");
    }
    // hdrsynth's own layout is in reference units already.
    let own = tmp.path().join("own");
    let ts = small_testset(&own, NoiseModel::None);
    assert_eq!(only_set(&ts).file_to_reference(), 1.0);

    // load_set brings the file's ground truth into reference units.
    let k1 = tmp.path().join("k0");
    let loaded = layout::load_set(&only_set(&k1)).unwrap();
    let stored = read_image(&k1.join("HDRImg.hdr")).unwrap();
    let gt = loaded.ground_truth.unwrap();
    for (a, b) in gt.data.iter().zip(&stored.data) {
        assert_eq!(*a, 4.0 * b);
    }
}

#[test]
fn scoring_in_the_files_unit_shifts_psnr_by_the_hand_computed_amount() {
    // Prediction = 1.1 × GT: PSNR-L = 20·log10(1 / (0.1 · rms(GT))) in whichever unit, so
    // going from reference units to the file's (GT / 4) adds 20·log10(4) = 12.04 dB.
    let tmp = tempfile::tempdir().unwrap();
    let g = scene();
    let root = tmp.path().join("k");
    kalantari(&root.join("s"), "0 2 4", &g.map(|v| v / 4.0));
    let pred = tmp.path().join("pred");
    std::fs::create_dir_all(&pred).unwrap();
    let stored = read_image(&root.join("s").join("HDRImg.hdr")).unwrap();
    write_exr(
        &pred.join("s.exr"),
        &stored.map(|v| 1.1 * v),
        ExrPrecision::Float,
    )
    .unwrap();
    let method = Predictions { dir: pred };
    let rms = |img: &Image| {
        (img.data.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / img.data.len() as f64).sqrt()
    };
    let by_hand = |gt: &Image| 20.0 * (1.0 / (0.1 * rms(gt))).log10();
    let reference_unit = stored.map(|v| 4.0 * v);
    let r = scores(&eval(&root, &method, &EvalOptions::default()));
    assert!((r[0] - by_hand(&reference_unit)).abs() < 1e-3, "{r:?}");
    let file = EvalOptions {
        unit: ScoreUnit::File,
        ..EvalOptions::default()
    };
    let f = scores(&eval(&root, &method, &file));
    assert!((f[0] - by_hand(&stored)).abs() < 1e-3, "{f:?}");
    assert!((f[0] - r[0] - 20.0 * 4f64.log10()).abs() < 1e-3);
}

// ---------------------------------------------------------------------------------------------
// Network-1's reference

fn canon() -> SensorProfile {
    SensorProfile::load(&SensorProfile::shipped_dir().join("canon_eos_550d.toml")).expect("profile")
}

/// A one-set test set (EV −3/0, ISO 3200) of a textured radiance map.
fn small_testset(out: &Path, noise: NoiseModel) -> PathBuf {
    let src = out.with_extension("exr");
    let radiance = Image::from_fn(64, 48, |x, y| {
        let v = (x as f32 / 63.0 * 9.0 - 6.0).exp2();
        let tex = 1.0 + 0.3 * ((x * 7 + y * 5) % 11) as f32 / 11.0;
        [v * tex, v * (1.2 - 0.4 * y as f32 / 47.0), v * 0.8 * tex]
    });
    write_exr(&src, &radiance, ExrPrecision::Float).unwrap();
    let opts = TestsetOptions {
        isos: vec![3200.0],
        evs: vec![-3.0, 0.0],
        noise,
        ..TestsetOptions::default()
    };
    testset::build(&src, &canon(), &opts, out).expect("testset");
    out.to_path_buf()
}

fn read_pair(paths: &[PathBuf]) -> (Image, Image) {
    (
        read_image(&paths[0]).unwrap(),
        read_image(&paths[1]).unwrap(),
    )
}

fn max_abs_diff(a: &Image, b: &Image) -> f32 {
    a.data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn testset_writes_noise_free_frames_that_read_back() {
    let tmp = tempfile::tempdir().unwrap();
    let noisy = only_set(&small_testset(
        &tmp.path().join("noisy"),
        NoiseModel::Gaussian,
    ));
    let clean = only_set(&small_testset(&tmp.path().join("clean"), NoiseModel::None));
    for set in [&noisy, &clean] {
        assert_eq!(set.clean_frames.len(), 2);
        assert!(set.clean_frames[0].ends_with("static/clean_ev-3.png"));
        assert!(set.clean_frames[1].ends_with("static/clean_ev+0.png"));
    }
    // The noise-free frames are the realism operator without noise: the frames of the same
    // recipe built with noise off, and different from the noisy frames.
    let (nl, nh) = read_pair(&noisy.clean_frames);
    let (cl, ch) = read_pair(&clean.static_frames);
    assert_eq!(nl.data, cl.data);
    assert_eq!(nh.data, ch.data);
    let (sl, _) = read_pair(&noisy.static_frames);
    assert!(max_abs_diff(&sl, &nl) >= 2.0 / 255.0);
    // All or none: a set missing one is an error naming that file.
    std::fs::remove_file(&noisy.clean_frames[1]).unwrap();
    let err = layout::detect(&tmp.path().join("noisy")).expect_err("partial");
    assert!(err.to_string().contains("clean_ev+0.png"), "{err}");
}

#[test]
fn network1_reference_blends_the_noisy_pair_with_weights_of_the_clean_pair() {
    let tmp = tempfile::tempdir().unwrap();
    let root = small_testset(&tmp.path().join("ts"), NoiseModel::Gaussian);
    let set = only_set(&root);
    let (low, high) = read_pair(&set.static_frames);
    let (clow, chigh) = read_pair(&set.clean_frames);

    // By hand: normalised Mertens weights (OpenCV defaults) of the clean frames, Laplacian
    // pyramid blend of the noisy frames.
    let w = ground_truth::mertens_weights(&[clow, chigh], MertensWeights::OPENCV_DEFAULT).unwrap();
    let hand = laplacian_blend(&[low.clone(), high.clone()], &w).unwrap();
    let (got, note) =
        network1_reference(&set, (0, 1), &low, &high, Network1Reference::CleanWeights).unwrap();
    assert!(note.is_none());
    assert!(
        max_abs_diff(&got, &hand) < 1e-5,
        "{}",
        max_abs_diff(&got, &hand)
    );

    // Today's reference is the option, and it differs.
    let old = ground_truth::mertens(&[low.clone(), high.clone()], 1.0, 1.0, 0.0).unwrap();
    let (got_old, _) =
        network1_reference(&set, (0, 1), &low, &high, Network1Reference::NoisyMertens).unwrap();
    assert_eq!(got_old.data, old.data);
    assert!(
        max_abs_diff(&got, &old) > 0.01,
        "{}",
        max_abs_diff(&got, &old)
    );
}

/// A stand-in Network-1 that returns given weights for the pair.
fn fixed_weights(name: &str, w: Vec<f32>) -> Network1 {
    Network1 {
        description: name.into(),
        weights: Box::new(move |_, _| Ok(w.clone())),
        tone_k: 2.0,
    }
}

#[test]
fn network1_is_scored_against_the_clean_weight_reference_by_default() {
    let tmp = tempfile::tempdir().unwrap();
    let root = small_testset(&tmp.path().join("ts"), NoiseModel::Gaussian);
    let set = only_set(&root);
    let (low, high) = read_pair(&set.static_frames);
    let (clow, chigh) = read_pair(&set.clean_frames);
    // A network that sees through the noise, and one that imitates the noisy Mertens weights.
    let seer = fixed_weights(
        "clean",
        ground_truth::blend_weights_high(&clow, &chigh).unwrap(),
    );
    let mimic = fixed_weights(
        "noisy",
        ground_truth::blend_weights_high(&low, &high).unwrap(),
    );
    let new = EvalOptions::default();
    let old = EvalOptions {
        network1_reference: Network1Reference::NoisyMertens,
        ..EvalOptions::default()
    };
    let [seer_new, seer_old, mimic_new, mimic_old] = [
        eval(&root, &seer, &new),
        eval(&root, &seer, &old),
        eval(&root, &mimic, &new),
        eval(&root, &mimic, &old),
    ]
    .map(|r| scores(&r));
    // The clean-weight network reproduces the default reference exactly; the mimic reproduces
    // today's (up to OpenCV's 1e-12 weight floor and code-value snapping).
    assert_eq!(seer_new[0], f64::INFINITY);
    assert!(seer_old[0].is_finite());
    assert!(mimic_old[0] > 60.0, "{mimic_old:?}");
    assert!(
        mimic_new[0] < mimic_old[0] - 10.0,
        "{mimic_new:?} vs {mimic_old:?}"
    );

    // Without noise-free frames: today's reference, with a note.
    for p in &set.clean_frames {
        std::fs::remove_file(p).unwrap();
    }
    let r = eval(&root, &mimic, &new);
    assert_eq!(scores(&r), mimic_old);
    assert!(
        r.notes.iter().any(|n| n.contains("no noise-free frames")),
        "{:?}",
        r.notes
    );
}

#[test]
fn network2_training_targets_from_kalantari_sets_are_in_reference_units() {
    use hdrsynth::data::loader::{Loader, LoaderConfig, Target};
    // The same scene with exposure.txt "-2 0 2" (GT) and "0 2 4" (GT / 4): the loader's
    // inputs use times relative to the reference, so its targets must be the same (reference
    // units) for both; before, the second got targets 4× too small.
    let tmp = tempfile::tempdir().unwrap();
    let g = scene();
    kalantari(&tmp.path().join("a/s"), "-2 0 2", &g);
    kalantari(&tmp.path().join("b/s"), "0 2 4", &g.map(|v| v / 4.0));
    let sample = |root: &str| {
        let text = format!(
            "dataset = {:?}\nkind = \"network2\"\npatch = 32\nbatch_size = 1\nworkers = 1\nseed = 3\n",
            tmp.path().join(root)
        );
        let cfg: LoaderConfig =
            hdrsynth::config::parse_toml(&text, Path::new("loader.toml")).unwrap();
        Loader::new(&cfg).unwrap().sample(0, 0).unwrap()
    };
    let (a, b) = (sample("a"), sample("b"));
    assert_eq!(a.input, b.input);
    let (Target::Hdr(ta), Target::Hdr(tb)) = (&a.target, &b.target) else {
        panic!("network2 targets are HDR");
    };
    assert_eq!(ta, tb);
    assert!(ta.iter().any(|&v| v > 0.5), "reference-unit highlights");
}
