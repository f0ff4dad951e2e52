//! One target unit in every mode, realism from linear frames, one
//! auto-exposure rule. Expected values are hand-derived (see each test).

use hdrsynth::config::parse_toml;
use hdrsynth::data::generate::GenerateConfig;
use hdrsynth::data::loader::{Loader, LoaderConfig, Target};
use hdrsynth::data::testset::{self, TestsetOptions};
use hdrsynth::io::{BitDepth, ExrPrecision, Image, read_image, write_exr, write_ldr};
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::sensor::realism::NoiseModel;
use hdrsynth::sensor::response::{ToneCurve, filmic_saturation};
use std::path::Path;

/// One generated 64×64 set (filmic display frames, linear EXRs, hdr_gt.exr).
fn dataset(evs: &str, dir: &Path) {
    let text = format!(
        "seed = 5\ncount = 1\nwidth = 64\nheight = 64\nevs = {evs}\n[camera]\ncandidates = 2\n"
    );
    let mut c: GenerateConfig = parse_toml(&text, Path::new("t.toml")).expect("config");
    c.source = None;
    hdrsynth::data::generate::generate(&c, dir, false).expect("generate");
}

fn loader(dir: &Path, kind: &str, realism: &str) -> Loader {
    let text = format!(
        "dataset = {:?}\nkind = \"{kind}\"\npatch = 64\nbatch_size = 1\nworkers = 1\nseed = 3\n\
         augment = false\n{realism}",
        dir
    );
    let cfg: LoaderConfig = parse_toml(&text, Path::new("loader.toml")).expect("loader config");
    Loader::new(&cfg).expect("loader")
}

/// A pure-mode Network-2 target is hdr_gt in units of the reference frame's white.
/// The engine's EV0 display white is the filmic curve's clipping point (7.24 engine units), so
/// target = hdr_gt / 7.24 (before, the target was hdr_gt itself: 7.24× too large).
#[test]
fn pure_network2_targets_are_in_units_of_the_reference_white() {
    let tmp = tempfile::tempdir().expect("tmp");
    dataset("[-2.0, 0.0, 2.0]", tmp.path());
    let s = loader(tmp.path(), "network2", "")
        .sample(0, 0)
        .expect("sample");
    let gt = read_image(&tmp.path().join("000000/hdr_gt.exr")).expect("gt");
    let white = filmic_saturation();
    assert!((white - 7.24).abs() < 0.01, "{white}");
    let Target::Hdr(t) = s.target else {
        panic!("network2 target")
    };
    let n = 64 * 64;
    let mut worst = 0f32;
    for px in 0..n {
        for c in 0..3 {
            let want = gt.data[px * 3 + c] / white;
            worst = worst.max((t[c * n + px] - want).abs() / want.max(1e-3));
        }
    }
    assert!(worst < 1e-5, "relative error {worst}");
}

/// Realism starts from the linear EXRs. An EV0 highlight ramp 3.0 … 7.2 engine units
/// occupies filmic display codes ~250–255 (a handful of 8-bit levels); metered (log-average →
/// 0.128 of white, k ≈ 0.027) it lands at ~0.08–0.19 of sensor white, which a 10-bit raw and an
/// 8-bit sRGB output resolve into dozens of codes. Reading the display PNGs (the old path)
/// leaves at most the PNG's own handful of levels.
#[test]
fn realism_reads_the_linear_frames_not_the_posterised_display_frames() {
    let tmp = tempfile::tempdir().expect("tmp");
    dataset("[-3.0, 0.0]", tmp.path());
    let set = tmp.path().join("000000");
    let mut ramp = Image::new(64, 64);
    for (i, p) in ramp.data.chunks_exact_mut(3).enumerate() {
        let v = 3.0 + 4.2 * (i % 64) as f32 / 63.0;
        p.copy_from_slice(&[v; 3]);
    }
    let low = ramp.map(|v| v / 8.0);
    for (name, img) in [("ev+0", &ramp), ("ev-3", &low)] {
        for sub in ["static", "dynamic"] {
            write_exr(
                &set.join(sub).join(format!("{name}.exr")),
                img,
                ExrPrecision::Float,
            )
            .expect("exr");
            let display = ToneCurve::Filmic.display(img, 1.0);
            write_ldr(
                &set.join(sub).join(format!("{name}.png")),
                &display,
                BitDepth::Eight,
            )
            .expect("png");
        }
    }
    write_exr(&set.join("hdr_gt.exr"), &ramp, ExrPrecision::Float).expect("gt");
    let display_levels = {
        let d = ToneCurve::Filmic.display(&ramp, 1.0);
        let mut codes: Vec<u32> = d.data.iter().map(|v| (v * 255.0).round() as u32).collect();
        codes.sort();
        codes.dedup();
        codes.len()
    };
    assert!(display_levels <= 8, "{display_levels} display levels");
    let profile = SensorProfile::shipped_dir().join("example_synthetic.toml");
    let realism = format!(
        "[realism]\nprofile = {profile:?}\nisos = [100.0]\nnoise = \"none\"\ncolour = false\n\
         ev_jitter = 0.0\n"
    );
    let l = loader(tmp.path(), "network1", &realism);
    assert!(
        l.describe_source().contains("linear EXR"),
        "{}",
        l.describe_source()
    );
    let s = l.sample(0, 0).expect("sample");
    // Channel-major input: planes 3..6 are the EV0 frame.
    let n = 64 * 64;
    let mut codes: Vec<u32> = s.input[3 * n..4 * n]
        .iter()
        .map(|v| (v * 255.0).round() as u32)
        .collect();
    codes.sort();
    codes.dedup();
    assert!(
        codes.len() >= 30,
        "{} distinct EV0 codes from the linear ramp (display PNG: {display_levels})",
        codes.len()
    );
    // And nothing is clipped: the metered exposure keeps the ramp below white.
    assert!(codes.iter().all(|&c| c < 250), "{codes:?}");
}

/// The test set is exposed by the auto-exposure rule. A scene of 0.1 with a sun of
/// 1000 on 1.5 % of the pixels: the old rule (99th percentile at 0.9 of white) put the sun's
/// percentile at 0.9 and the scene at 9e-5 of white (≈ 98 % of the EV0 frame black); average
/// metering with a 2 % clipping budget lets the sun clip and puts the log-average,
/// 0.1^0.985 · 1000^0.015 ≈ 0.1148, at 0.128 of white: the scene sits at ≈ 0.11 of white.
#[test]
fn testset_meters_like_a_phone_not_on_the_highlights() {
    let tmp = tempfile::tempdir().expect("tmp");
    let mut rad = Image::new(100, 100);
    for (i, p) in rad.data.chunks_exact_mut(3).enumerate() {
        let v = if i % 200 < 3 { 1000.0 } else { 0.1 };
        p.copy_from_slice(&[v; 3]);
    }
    let opts = TestsetOptions {
        isos: vec![100.0],
        evs: vec![-3.0, 0.0],
        noise: NoiseModel::None,
        colour: false,
        ..TestsetOptions::default()
    };
    let key = testset::exposure_key(&rad, &opts).expect("key");
    let want = 0.128 / (0.1f64.powf(0.985) * 1000f64.powf(0.015));
    assert!((key as f64 - want).abs() / want < 1e-4, "{key} vs {want}");
    let file = tmp.path().join("sun.exr");
    write_exr(&file, &rad, ExrPrecision::Float).expect("exr");
    let profile = SensorProfile::load(&SensorProfile::shipped_dir().join("example_synthetic.toml"))
        .expect("profile");
    let out = tmp.path().join("test");
    testset::build(&file, &profile, &opts, &out).expect("testset");
    let ev0 = read_image(&out.join("sun_iso100/static/ev+0.png")).expect("ev0");
    let dark = ev0.data.chunks_exact(3).filter(|p| p[1] <= 0.02).count();
    assert!(
        (dark as f64) < 0.01 * ev0.pixel_count() as f64,
        "{dark} of {} EV0 pixels under-exposed",
        ev0.pixel_count()
    );
}

/// `ground_truth = "scene"` writes the metered radiance itself (scene-linear Rec. 709, key k)
/// while the frames keep T; `device` writes T · radiance · k. Both by hand from the profile's
/// matrix and the key, per pixel, below the ground truth's white.
#[test]
fn a_scene_referred_ground_truth_is_the_metered_radiance_and_the_device_one_t_of_it() {
    use hdrsynth::sensor::realism::TargetSpace;
    let tmp = tempfile::tempdir().expect("tmp");
    let mut rad = Image::new(48, 32);
    for (i, p) in rad.data.chunks_exact_mut(3).enumerate() {
        let t = (i % 48) as f32 / 47.0;
        p.copy_from_slice(&[0.02 + 0.3 * t, 0.05 + 0.1 * t, 0.2 - 0.15 * t]);
    }
    let file = tmp.path().join("patch.exr");
    write_exr(&file, &rad, ExrPrecision::Float).expect("exr");
    let profile = SensorProfile::load(&SensorProfile::shipped_dir().join("canon_eos_550d.toml"))
        .expect("profile");
    let m = profile.colour.as_ref().expect("a colour matrix").matrix;
    let gt = |space: TargetSpace, name: &str| {
        let opts = TestsetOptions {
            isos: vec![100.0],
            evs: vec![-2.0, 0.0, 2.0],
            noise: NoiseModel::None,
            ground_truth: space,
            ..TestsetOptions::default()
        };
        let key = testset::exposure_key(&rad, &opts).expect("key") as f64;
        let out = tmp.path().join(name);
        testset::build(&file, &profile, &opts, &out).expect("testset");
        let frame = read_image(&out.join("patch_iso100/static/ev+0.png")).expect("ev0");
        (
            read_image(&out.join("patch_iso100/hdr_gt.exr")).expect("gt"),
            frame,
            key,
        )
    };
    let (scene, scene_frame, key) = gt(TargetSpace::Scene, "scene");
    let (device, device_frame, _) = gt(TargetSpace::Device, "device");
    // Same frames: the option changes the ground truth only.
    assert_eq!(scene_frame.data, device_frame.data);
    let white = 4.0; // the shortest frame (EV −2) clips at 2^2 in EV0 units
    let mut checked = 0;
    for ((r, s), d) in rad
        .data
        .chunks_exact(3)
        .zip(scene.data.chunks_exact(3))
        .zip(device.data.chunks_exact(3))
    {
        let lin: Vec<f64> = r.iter().map(|&v| v as f64 * key).collect();
        for c in 0..3 {
            let want_scene = lin[c].min(white);
            let want_device = (0..3)
                .map(|k| m[c][k] * lin[k])
                .sum::<f64>()
                .max(0.0)
                .min(white);
            assert!(
                (s[c] as f64 - want_scene).abs() <= 1e-5 * want_scene.max(1.0),
                "{s:?} vs {lin:?}"
            );
            assert!(
                (d[c] as f64 - want_device).abs() <= 1e-5 * want_device.max(1.0),
                "{d:?}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 48 * 32 * 3);
    // The two differ where T is not the identity.
    assert!(
        scene
            .data
            .iter()
            .zip(&device.data)
            .any(|(a, b)| (a - b).abs() > 1e-3)
    );
}

/// `testset` exposes with the profile's measured rule unless one is given (the options'
/// `metering`, the `--mid-grey`/`--max-clipped` flags, which replace it whole), else the
/// default; the recipe records the rule used. A flat radiance of 0.5 never clips, so the key is
/// mid_grey / 0.5 by hand.
#[test]
fn testset_takes_the_given_rule_else_the_profiles_else_the_default() {
    use hdrsynth::sensor::metering::Metering;
    use std::process::Command;
    let tmp = tempfile::tempdir().expect("tmp");
    let mut rad = Image::new(32, 24);
    rad.data.fill(0.5);
    let file = tmp.path().join("flat.exr");
    write_exr(&file, &rad, ExrPrecision::Float).expect("exr");
    let plain = SensorProfile::load(&SensorProfile::shipped_dir().join("example_synthetic.toml"))
        .expect("profile");
    let mut measured = plain.clone();
    let rule = Metering {
        mid_grey: 0.2,
        max_clipped: 0.05,
    };
    measured.set_metering(Some((rule, "by hand".into())));
    let measured_path = tmp.path().join("measured.toml");
    measured.save(&measured_path).expect("save");
    let build = |profile: &SensorProfile, given: Option<Metering>, name: &str| {
        let opts = TestsetOptions {
            isos: vec![100.0],
            noise: NoiseModel::None,
            metering: given,
            ..TestsetOptions::default()
        };
        let out = tmp.path().join(name);
        let s = testset::build(&file, profile, &opts, &out).expect("testset");
        let recipe = std::fs::read_to_string(out.join(testset::RECIPE)).expect("recipe");
        (s.sets[0].key as f64, s.notes.join("\n"), recipe)
    };
    let (key, notes, recipe) = build(&measured, None, "profile");
    assert!((key - 0.2 / 0.5).abs() < 1e-6, "{key}");
    assert!(notes.contains("the profile's measured rule"), "{notes}");
    assert!(
        recipe.contains("[options.metering]\nmid_grey = 0.2\nmax_clipped = 0.05\n"),
        "{recipe}"
    );
    let given = Metering {
        mid_grey: 0.1,
        ..Metering::default()
    };
    let (key, notes, _) = build(&measured, Some(given), "given");
    assert!((key - 0.1 / 0.5).abs() < 1e-6, "{key}");
    assert!(notes.contains("given explicitly"), "{notes}");
    // No rule anywhere: the default, recorded as test sets always recorded it.
    let (key, notes, recipe) = build(&plain, None, "default");
    assert!((key - 0.128 / 0.5).abs() < 1e-6, "{key}");
    assert!(notes.contains("the default rule"), "{notes}");
    assert!(
        recipe.contains("[options.metering]\nmid_grey = 0.128\nmax_clipped = 0.02\n"),
        "{recipe}"
    );
    // The command: no flag takes the profile's rule; one flag replaces it whole, the other
    // key at its default.
    let cli = |flags: &[&str], name: &str| {
        let out = tmp.path().join(name);
        let o = Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
            .args(["testset", "--radiance"])
            .arg(&file)
            .arg("--profile")
            .arg(&measured_path)
            .args(["--isos", "100", "--noise", "none", "--out"])
            .arg(&out)
            .args(flags)
            .output()
            .expect("run");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let recipe: toml::Table =
            toml::from_str(&std::fs::read_to_string(out.join(testset::RECIPE)).expect("recipe"))
                .expect("toml");
        let m = &recipe["options"]["metering"];
        (m["mid_grey"].as_float(), m["max_clipped"].as_float())
    };
    assert_eq!(cli(&[], "cli_profile"), (Some(0.2), Some(0.05)));
    assert_eq!(
        cli(&["--max-clipped", "0.04"], "cli_flag"),
        (Some(0.128), Some(0.04))
    );
}
