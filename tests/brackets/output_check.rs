//! The device-output check: what a profile misses (noise level, read-noise floor, correlation,
//! chroma noise) is found, fitted back, and nothing is named when the profile holds it.

use crate::helpers::{Spatial, calibrate_srgb, noisy_png_bracket};
use hdrsynth::capture::diagnose::{self, BracketDiagnoseOptions};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::scan::{self, ScanOptions};

#[test]
fn the_device_output_check_finds_what_a_profile_misses_and_nothing_when_it_has_it() {
    use hdrsynth::capture::output::{OutputCheckOptions, check};
    let run = |spatial: Spatial, correlated: bool| {
        let tmp = tempfile::tempdir().expect("tmp");
        noisy_png_bracket(
            &tmp.path().join("scene"),
            4e-4,
            1e-5,
            &[-2.0, 0.0, 2.0],
            spatial,
        );
        let beside = tempfile::tempdir().expect("tmp");
        let out = beside.path().join("phone.toml");
        let cal = calibrate_srgb(tmp.path(), ScanOptions::default(), &out, correlated);
        let c = check(
            tmp.path(),
            &cal.profile,
            &OutputCheckOptions {
                scan: ScanOptions::default(),
                replicates: 10,
                seed: 1,
                noise: true,
            },
        )
        .expect("check");
        eprintln!("{}", c.markdown());
        c
    };
    let white = run(Spatial::White, false);
    assert!(
        named_beside_the_floor(&white).is_none(),
        "{}",
        white.markdown()
    );
    // The same check from `diagnose --brackets --device-output`, written beside its report.
    {
        let tmp = tempfile::tempdir().expect("tmp");
        noisy_png_bracket(
            &tmp.path().join("scene"),
            4e-4,
            1e-5,
            &[-2.0, 0.0, 2.0],
            Spatial::White,
        );
        let beside = tempfile::tempdir().expect("tmp");
        let profile = beside.path().join("phone.toml");
        calibrate_srgb(tmp.path(), ScanOptions::default(), &profile, false);
        let out = beside.path().join("diag");
        let d = diagnose::diagnose_brackets(
            tmp.path(),
            &BracketDiagnoseOptions {
                response: ResponseChoice::new(Some(&profile), None).expect("profile"),
                device_output: Some(profile.clone()),
                ..BracketDiagnoseOptions::default()
            },
            &out,
        )
        .expect("diagnose");
        let c = d.device_output.expect("checked");
        assert_eq!((c.stats.len(), c.replicates), (17, 30));
        assert!(named_beside_the_floor(&c).is_none(), "{}", c.markdown());
        let md = std::fs::read_to_string(out.join("device_output.md")).expect("written");
        assert!(md.contains("channel correlation"), "{md}");
    }
    let missed = run(Spatial::Gauss(0.8), false);
    assert_eq!(
        named_beside_the_floor(&missed).map(|s| s.names),
        Some("correlated_noise"),
        "{}",
        missed.markdown()
    );
    let fitted = run(Spatial::Gauss(0.8), true);
    assert!(fitted.gap < missed.gap, "{} → {}", missed.gap, fitted.gap);
}

/// A white-noise bracket (σ² = a·L + b, stops −2, 0, 2) calibrated as most tests calibrate
/// it, with the device-output check's options for it and its scan.
fn white_bracket_for_the_check(
    a: f64,
    b: f64,
) -> (
    tempfile::TempDir,
    hdrsynth::sensor::profile::SensorProfile,
    hdrsynth::capture::output::OutputCheckOptions,
    scan::BracketScan,
) {
    bracket_for_the_check(a, b, crate::helpers::Isp::default())
}

/// [`white_bracket_for_the_check`] of a device whose processing does what `isp` says.
fn bracket_for_the_check(
    a: f64,
    b: f64,
    isp: crate::helpers::Isp,
) -> (
    tempfile::TempDir,
    hdrsynth::sensor::profile::SensorProfile,
    hdrsynth::capture::output::OutputCheckOptions,
    scan::BracketScan,
) {
    let tmp = tempfile::tempdir().expect("tmp");
    crate::helpers::noisy_png_device(
        &tmp.path().join("scene"),
        a,
        b,
        &[-2.0, 0.0, 2.0],
        Spatial::White,
        0.0,
        isp,
    );
    let beside = tempfile::tempdir().expect("tmp");
    let cal = calibrate_srgb(
        tmp.path(),
        ScanOptions::default(),
        &beside.path().join("p.toml"),
        false,
    );
    let (opts, scan) = check_options_and_scan(tmp.path());
    (tmp, cal.profile, opts, scan)
}

#[test]
fn a_noise_level_the_check_finds_off_is_fitted_back_to_what_the_frames_hold() {
    use hdrsynth::capture::output::{check_scanned, fit_noise_level};
    let (_frames, profile, opts, scan) = white_bracket_for_the_check(4e-4, 1e-5);
    // The measured noise made too low: R halved, B quartered, G kept. The frames hold 2×, 1×
    // and 4× what this profile simulates.
    let mut low = profile.clone();
    for row in &mut low.noise {
        for (c, k) in [(0, 0.5), (2, 0.25)] {
            row.a[c] *= k;
            row.b[c] *= k;
        }
    }
    let before = check_scanned(scan.clone(), &low, &opts).expect("check");
    assert!(before.level_off(), "{}", before.markdown());
    let fit = fit_noise_level(&scan, &low, &before, &opts, 4).expect("fit");
    let (fitted, k, after) = (fit.profile, fit.scale, fit.check);
    for (c, truth) in [(0, 2.0), (1, 1.0), (2, 4.0)] {
        assert!((k[c] / truth - 1.0).abs() < 0.15, "channel {c}: {k:?}");
        let row = (&fitted.noise[0], &low.noise[0]);
        assert!((row.0.a[c] - k[c] * row.1.a[c]).abs() <= 1e-12 * row.0.a[c].abs());
        assert!((row.0.b[c] - k[c] * row.1.b[c]).abs() <= 1e-12 * row.0.b[c].abs());
    }
    assert!(!after.level_off(), "{}", after.markdown());
    assert!(after.gap < before.gap, "{} → {}", before.gap, after.gap);
}

/// The largest significant statistic of `c` other than a noise floor, after checking that
/// every significant floor is one the profile holds too little of: `calibrate brackets`
/// carries the darkest bins' σ² to linear through the curve's slope at their mean, which
/// clipping at code 0 bends, and its b comes out 10–20 % low in variance on these brackets
/// (the check's floor statistic sees it; the loop's level step fits it).
fn named_beside_the_floor(
    c: &hdrsynth::capture::output::OutputCheck,
) -> Option<&hdrsynth::capture::output::OutputStat> {
    for s in c
        .stats
        .iter()
        .filter(|s| s.significant && s.name.contains("noise floor"))
    {
        assert!(s.measured > s.sim_mean, "{}", c.markdown());
    }
    c.stats
        .iter()
        .filter(|s| s.significant && !s.name.contains("noise floor"))
        .max_by(|a, b| a.z.abs().total_cmp(&b.z.abs()))
}

#[test]
fn a_read_noise_floor_the_profile_lacks_is_found_under_code_one_eighth_and_fitted_back() {
    use hdrsynth::capture::output::{check_scanned, fit_noise_level};
    // σ² = a·L + b with a floor that rules the darkest codes: under code 1/8 (L < 0.0144) the
    // shot noise a·L is at most 5.8·10⁻⁶, b is 10⁻⁵.
    let (a, b) = (4e-4, 1e-5);
    let (_frames, profile, opts, scan) = white_bracket_for_the_check(a, b);
    // The floor lost, as a flat-region fit that finds none gives it.
    let mut floorless = profile.clone();
    for row in &mut floorless.noise {
        row.b = [0.0; 3];
    }
    let before = check_scanned(scan.clone(), &floorless, &opts).expect("check");
    let floors: Vec<_> = before
        .stats
        .iter()
        .filter(|s| s.name.contains("noise floor"))
        .collect();
    assert_eq!(floors.len(), 3);
    for s in &floors {
        assert!(
            s.significant && s.measured > s.sim_mean,
            "{}",
            before.markdown()
        );
    }
    let fit = fit_noise_level(&scan, &floorless, &before, &opts, 4).expect("fit");
    eprintln!("{:?} {:?}\n{}", fit.scale, fit.floor, fit.check.markdown());
    let row = &fit.profile.noise[0];
    for c in 0..3 {
        assert!(fit.floor[c].is_some(), "channel {c}");
        assert!(
            (row.b[c] / b - 1.0).abs() < 0.35,
            "channel {c}: b {} for {b}",
            row.b[c]
        );
        assert!(
            (row.a[c] / a - 1.0).abs() < 0.25,
            "channel {c}: a {} for {a}",
            row.a[c]
        );
    }
    assert!(!fit.check.level_off(), "{}", fit.check.markdown());
    assert!(
        fit.check.gap < before.gap,
        "{} → {}",
        before.gap,
        fit.check.gap
    );
}

#[test]
fn chroma_noise_is_measured_fitted_and_closes_the_device_output_gap() {
    use hdrsynth::capture::output::{OutputCheckOptions, check};
    let tmp = tempfile::tempdir().expect("tmp");
    noisy_png_bracket(
        &tmp.path().join("scene"),
        4e-4,
        1e-5,
        &[-2.0, 0.0, 2.0],
        Spatial::Channel(0.5),
    );
    let beside = tempfile::tempdir().expect("tmp");
    let calibrate = |correlated: bool, name: &str| {
        calibrate_srgb(
            tmp.path(),
            ScanOptions::default(),
            &beside.path().join(name),
            correlated,
        )
    };
    let white = calibrate(false, "white.toml");
    let fitted = calibrate(true, "fitted.toml");
    eprintln!("{}", fitted.report(&beside.path().join("fitted.toml")));
    assert!(
        (fitted.channel_correlation - 0.5).abs() < 0.05,
        "{}",
        fitted.channel_correlation
    );
    let rho = fitted
        .profile
        .effects
        .iter()
        .find(|e| e.id == "channel_correlation")
        .and_then(|e| e.params["rho"].as_float())
        .expect("written");
    assert_eq!(rho, fitted.channel_correlation);
    // No spatial correlation was planted: none is written.
    assert!(
        fitted
            .profile
            .effects
            .iter()
            .all(|e| e.id != "correlated_noise")
    );
    let run = |profile: &hdrsynth::sensor::profile::SensorProfile| {
        check(
            tmp.path(),
            profile,
            &OutputCheckOptions {
                scan: ScanOptions::default(),
                replicates: 10,
                seed: 1,
                noise: true,
            },
        )
        .expect("check")
    };
    let missed = run(&white.profile);
    assert_eq!(
        named_beside_the_floor(&missed).map(|s| s.names),
        Some("channel_correlation"),
        "{}",
        missed.markdown()
    );
    let closed = run(&fitted.profile);
    assert!(
        named_beside_the_floor(&closed).is_none(),
        "{}",
        closed.markdown()
    );
}

#[test]
fn an_output_floor_the_profile_lacks_is_named_and_its_threshold_fitted_back() {
    use crate::helpers::Isp;
    use hdrsynth::capture::output::{check_scanned, fit_floor};
    // A device that subtracts 0.4 % of white before its sRGB curve: linear signal under it
    // (codes up to 13/255 of a plain sRGB encoding) leaves the camera as noise about code 0.
    let truth = 0.004;
    let (_frames, profile, opts, scan) = bracket_for_the_check(
        4e-4,
        1e-5,
        Isp {
            floor: truth,
            ..Isp::default()
        },
    );
    let before = check_scanned(scan.clone(), &profile, &opts).expect("check");
    let floor = before.floor_stat();
    assert!(
        floor.significant && floor.measured < floor.sim_mean - 2.0,
        "{}",
        before.markdown()
    );
    assert_eq!(floor.names, "floor");
    let fit = fit_floor(&scan, &profile, &before, &opts).expect("fit");
    eprintln!("threshold {}\n{}", fit.threshold, fit.check.markdown());
    assert!(!fit.at_bound);
    assert!(
        (fit.threshold / truth - 1.0).abs() < 0.15,
        "threshold {} for {truth}",
        fit.threshold
    );
    let after = fit.check.floor_stat();
    assert!(!after.significant, "{}", fit.check.markdown());
    assert!(
        (after.measured - after.sim_mean).abs() < 0.25 * (floor.measured - floor.sim_mean).abs(),
        "{}",
        fit.check.markdown()
    );
    assert!(
        fit.check.gap < before.gap,
        "{} → {}",
        before.gap,
        fit.check.gap
    );
    // The fitted profile names its floor and loads back as it was written.
    let beside = tempfile::tempdir().expect("tmp");
    let path = beside.path().join("floored.toml");
    fit.profile.save(&path).expect("save");
    let back = hdrsynth::sensor::profile::SensorProfile::load(&path).expect("load");
    assert_eq!(back.effects, fit.profile.effects);
    assert!(back.provenance.response.contains("output floor"));
}

#[test]
fn a_bracket_without_a_floor_is_not_given_one() {
    use hdrsynth::capture::output::{fit_floor, refusal};
    let (_frames, profile, opts, scan) = white_bracket_for_the_check(4e-4, 1e-5);
    let c = hdrsynth::capture::output::check_scanned(scan.clone(), &profile, &opts).expect("check");
    let floor = c.floor_stat();
    assert!(
        floor.measured.is_finite() && !floor.significant,
        "{}",
        c.markdown()
    );
    // Asked anyway, the fit either refuses (the frames are not under the simulation) or finds
    // a threshold too small to matter: under 0.05 % of white.
    match fit_floor(&scan, &profile, &c, &opts) {
        Ok(f) => assert!(f.threshold < 5e-4, "{}", f.threshold),
        Err(e) => {
            let why = refusal("floor", e).expect("a refusal, not a failure");
            assert!(why.contains("only lowers"), "{why}");
        }
    }
}

#[test]
fn jpeg_blocks_the_profile_lacks_are_named_and_closed_by_the_frames_own_quality() {
    use hdrsynth::capture::output::{check_scanned, fit_jpeg};
    // The white-noise bracket, stored as JPEG at quality 60 (libjpeg's scaling, 4:4:4).
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("scene");
    noisy_png_bracket(&dir, 4e-4, 1e-5, &[-2.0, 0.0, 2.0], Spatial::White);
    // The profile of the frames before their storage (calibrated on the JPEGs, the noise fit
    // finds no flat region left: quality 60 smooths it away).
    let beside = tempfile::tempdir().expect("tmp");
    let cal = calibrate_srgb(
        tmp.path(),
        ScanOptions::default(),
        &beside.path().join("p.toml"),
        false,
    );
    for i in 0..3 {
        let png = dir.join(format!("f{i}.png"));
        let img = image::open(&png).expect("png").to_rgb8();
        let mut jpg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpg, 60)
            .encode(
                img.as_raw(),
                img.width(),
                img.height(),
                image::ExtendedColorType::Rgb8,
            )
            .expect("encode");
        std::fs::write(dir.join(format!("f{i}.jpg")), jpg).expect("jpg");
        std::fs::remove_file(png).expect("rm");
    }
    let (opts, scan) = check_options_and_scan(tmp.path());
    let before = check_scanned(scan.clone(), &cal.profile, &opts).expect("check");
    let blocks = before.block_stat();
    assert!(
        blocks.significant && blocks.measured > blocks.sim_mean,
        "{}",
        before.markdown()
    );
    assert_eq!(blocks.names, "jpeg");
    let fit = fit_jpeg(&scan, &cal.profile, &opts).expect("fit");
    eprintln!("{}", fit.check.markdown());
    assert_eq!((fit.quality, fit.mismatch), (60, 0.0));
    let after = fit.check.block_stat();
    assert!(!after.significant, "{}", fit.check.markdown());
    assert!(after.z.abs() < blocks.z.abs());
    // Frames that are not JPEGs have no quality to read.
    let (_frames, profile, opts, scan) = white_bracket_for_the_check(4e-4, 1e-5);
    let e = fit_jpeg(&scan, &profile, &opts).unwrap_err().to_string();
    assert!(e.contains("no frame") && e.contains("JPEG"), "{e}");
    let c = check_scanned(scan, &profile, &opts).expect("check");
    assert!(!c.block_stat().significant, "{}", c.markdown());
}

/// The check's options as these tests run it (10 replicates, seed 1, with noise) and the scan
/// of the folder `dir`.
fn check_options_and_scan(
    dir: &std::path::Path,
) -> (
    hdrsynth::capture::output::OutputCheckOptions,
    scan::BracketScan,
) {
    let opts = hdrsynth::capture::output::OutputCheckOptions {
        scan: ScanOptions::default(),
        replicates: 10,
        seed: 1,
        noise: true,
    };
    let scan = scan::scan(dir, &opts.scan).expect("scan");
    (opts, scan)
}

#[test]
fn frames_that_disagree_at_coarse_scales_are_named_and_a_device_without_it_is_not() {
    use crate::helpers::Isp;
    use hdrsynth::capture::output::check_scanned;
    let disagreement = |shading: f64| {
        let (_frames, profile, opts, scan) = bracket_for_the_check(
            4e-4,
            1e-5,
            Isp {
                shading,
                ..Isp::default()
            },
        );
        let c = check_scanned(scan, &profile, &opts).expect("check");
        eprintln!("shading {shading}\n{}", c.markdown());
        c.stats
            .into_iter()
            .filter(|s| s.name.starts_with("disagreement"))
            .collect::<Vec<_>>()
    };
    // Each frame's gain varies by ±3 % over 48-pixel waves, differently in each frame: under
    // the noise per pixel at most codes, plain in 16-pixel means.
    let shaded = disagreement(0.03);
    let coarse = &shaded[1];
    assert!(
        coarse.significant && coarse.measured > coarse.sim_mean + 0.3,
        "{coarse:?}"
    );
    // The same device without the shading: its frames agree as its simulation's do.
    for s in disagreement(0.0) {
        assert!(!s.significant, "{s:?}");
    }
}

/// Frames made by a profile's own simulation with a known local gain field (σ 0.04 of ln
/// gain, 16 px) are named by the disagreement statistics against the profile without it; the
/// fit gives the field back (σ within 25 %, the length within a factor of two) and closes
/// its gap; the same frames made without the field are not named.
#[test]
fn a_local_gain_field_is_named_and_fitted_back_from_frames_made_with_it() {
    use hdrsynth::capture::output::{check_scanned, fit_output_effect, names, with_local_gain};
    use hdrsynth::io::{BitDepth, Image, write_ldr};
    use hdrsynth::sensor::effects::local_gain::ID;
    use hdrsynth::sensor::realism::{NoiseModel, Realism, RealismOptions};
    // A device profile as a user's calibration gives it, from a bracket without the field.
    let (_calibration, profile, opts, _) = white_bracket_for_the_check(4e-4, 1e-5);
    let frames_of = |sigma: f64| {
        let mut device = if sigma > 0.0 {
            with_local_gain(&profile, sigma, 16.0)
        } else {
            profile.clone()
        };
        // The scene below is linear, as the check's own scene estimate is.
        device.source_response = hdrsynth::sensor::profile::Response::Linear;
        let realism = Realism::new(
            &device,
            &RealismOptions {
                iso: 100.0,
                exposure: 1.0,
                noise: NoiseModel::Gaussian,
                colour: false,
                output_bits: 8,
            },
        )
        .expect("realism");
        let tmp = tempfile::tempdir().expect("tmp");
        let dir = tmp.path().join("scene");
        std::fs::create_dir_all(&dir).expect("mkdir");
        let stops = [-2.0f64, 0.0, 2.0];
        for (i, s) in stops.iter().enumerate() {
            // A ramp from 2^−7 to 2^0 of white at stop 0, tinted per channel.
            let scene = Image::from_fn(192, 144, |x, _| {
                let l = (-7.0 + 7.0 * x as f64 / 191.0).exp2() * s.exp2();
                [0.9, 1.0, 0.8].map(|k| (k * l).min(1.0) as f32)
            });
            let frame = realism.apply(&scene, 1000 + i as u64);
            write_ldr(&dir.join(format!("f{i}.png")), &frame, BitDepth::Eight).expect("png");
        }
        std::fs::write(dir.join("exposure.txt"), "-2\n0\n2\n").expect("exposure.txt");
        let scan = scan::scan(tmp.path(), &opts.scan).expect("scan");
        let first = check_scanned(scan.clone(), &profile, &opts).expect("check");
        (tmp, scan, first)
    };
    let (_frames, scan, first) = frames_of(0.04);
    assert!(names(&first, ID), "{}", first.markdown());
    let fit = fit_output_effect(ID, &scan, &profile, &first, &opts).expect("fit");
    let spec = fit
        .profile
        .effects
        .iter()
        .find(|e| e.id == ID)
        .expect("the fitted effect");
    let (sigma, scale) = (
        spec.params["sigma"].as_float().expect("sigma"),
        spec.params["scale"].as_float().expect("scale"),
    );
    assert!(
        (sigma / 0.04 - 1.0).abs() < 0.25,
        "σ {sigma}: {}",
        fit.text(&first)
    );
    assert!((8.0..=32.0).contains(&scale), "scale {scale}");
    assert!(fit.closes(&first), "{}", fit.text(&first));
    assert!(!names(&fit.check, ID), "{}", fit.check.markdown());
    eprintln!("{}", fit.text(&first));
    // Without the field the frames agree as the simulation's do: nothing named (so no step),
    // and a fit forced on them finds at most a quarter of the field above.
    let (_plain, scan, first) = frames_of(0.0);
    assert!(!names(&first, ID), "{}", first.markdown());
    if let Ok(f) = fit_output_effect(ID, &scan, &profile, &first, &opts) {
        let spec = f
            .profile
            .effects
            .iter()
            .find(|e| e.id == ID)
            .expect("fitted");
        let sigma = spec.params["sigma"].as_float().expect("sigma");
        assert!(sigma < 0.01, "{}", f.text(&first));
    }
}
