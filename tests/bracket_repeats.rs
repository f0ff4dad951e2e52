//! Temporal noise from repeated captures: `calibrate brackets --repeats` measures the output
//! noise from the differences of frames taken at one exposure, where the scene cancels, and
//! refuses pairs that are not of one static scene.
//!
//! The frames are written here: a finely textured scene (which a single frame's residual
//! cannot tell from noise), noise of variance a·L + b added to the linear signal, sRGB
//! encoded by hand, 8-bit PNG; the oracle values are the generator's a, b and correlations.

use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::profile::{BracketCalibration, BracketProfileOptions};
use hdrsynth::capture::scan::{self, ScanOptions};
use hdrsynth::sensor::profile::Response;
use std::path::Path;

mod common;
use common::{TestNoise, srgb};

const W: usize = 200;
const H: usize = 150;
const A: f64 = 4e-4;
const B: f64 = 1e-5;

/// How the noise of one frame is drawn.
#[derive(Clone, Copy)]
enum Noise {
    White,
    /// Neighbours share draws: the mean of the 2×2 block's draws times 2 (lag-1 exactly 0.5).
    Box2,
    /// Every two channels of a pixel correlated by ρ (a fresh shared draw per pixel).
    Channel(f64),
}

/// What a frame shows: a shift of the whole frame in pixels and the light on the scene.
#[derive(Clone, Copy)]
struct Take {
    shift: usize,
    light: f64,
}

impl Default for Take {
    fn default() -> Self {
        Take {
            shift: 0,
            light: 1.0,
        }
    }
}

/// Linear radiance at stop 0: a ramp of 2^−6 … 2^−0.5 of white across x with a strong fine
/// texture (period ≈ 3 px), slightly tinted per channel.
fn scene(x: usize, y: usize, c: usize) -> f64 {
    let ramp = (-6.0 + 5.5 * x as f64 / (W - 1) as f64).exp2();
    let texture = 1.0 + 0.35 * (x as f64 * 2.0).sin() * (y as f64 * 1.9).sin();
    ramp * texture * [0.9, 1.0, 0.8][c]
}

/// One 8-bit sRGB PNG of the scene at `stop` with noise drawn from `rng`.
fn frame(path: &Path, stop: f64, take: Take, noise: Noise, rng: &mut TestNoise) {
    let pad = 2;
    let (fw, fh) = (W + pad, H + pad);
    let field: Vec<f64> = (0..fw * fh * 3).map(|_| rng.normal()).collect();
    let shared: Vec<f64> = (0..fw * fh).map(|_| rng.normal()).collect();
    let f = |x: usize, y: usize, c: usize| field[(y * fw + x) * 3 + c];
    let mut img = image::RgbImage::new(W as u32, H as u32);
    for y in 0..H {
        for x in 0..W {
            let px = [0, 1, 2].map(|c| {
                let z = match noise {
                    Noise::White => f(x, y, c),
                    Noise::Box2 => {
                        (f(x, y, c) + f(x + 1, y, c) + f(x, y + 1, c) + f(x + 1, y + 1, c)) / 2.0
                    }
                    Noise::Channel(r) => {
                        (1.0 - r).sqrt() * f(x, y, c) + r.sqrt() * shared[y * fw + x]
                    }
                };
                let l = (scene(x + take.shift, y, c) * take.light * stop.exp2()).min(1.0);
                (srgb(l + (A * l + B).sqrt() * z) * 255.0).round() as u8
            });
            img.put_pixel(x as u32, y as u32, image::Rgb(px));
        }
    }
    img.save(path).expect("png");
}

/// A folder of `repeats` captures at each of `stops` (file names sort by stop, then capture),
/// with Kalantari's exposure.txt; `take(stop index, capture)` says what each capture shows.
fn folder(
    dir: &Path,
    stops: &[f64],
    repeats: usize,
    noise: Noise,
    take: &dyn Fn(usize, usize) -> Take,
) {
    std::fs::create_dir_all(dir).expect("mkdir");
    let mut rng = TestNoise(11);
    let mut text = String::new();
    for (i, &s) in stops.iter().enumerate() {
        for k in 0..repeats {
            frame(
                &dir.join(format!("f{i}_{k}.png")),
                s,
                take(i, k),
                noise,
                &mut rng,
            );
            text += &format!("{s}\n");
        }
    }
    std::fs::write(dir.join("exposure.txt"), text).expect("exposure.txt");
}

fn repeats_scan() -> ScanOptions {
    ScanOptions {
        repeats: true,
        ..ScanOptions::default()
    }
}

fn calibrate(
    dir: &Path,
    scan: ScanOptions,
    response: ResponseChoice,
    correlated: bool,
) -> hdrsynth::Result<BracketCalibration> {
    let beside = tempfile::tempdir().expect("tmp");
    let out = beside.path().join("phone.toml");
    let cal = hdrsynth::capture::profile::calibrate_brackets(
        dir,
        &BracketProfileOptions {
            scan,
            response,
            out: out.clone(),
            name: None,
            correlated,
        },
    )?;
    eprintln!("{}", cal.report(&out));
    Ok(cal)
}

fn srgb_choice() -> ResponseChoice {
    ResponseChoice::Declared(Response::Srgb)
}

/// σ² at a quarter of white, relative to the generator's.
fn relative_variance(cal: &BracketCalibration) -> [f64; 3] {
    let row = &cal.profile.noise[0];
    [0, 1, 2].map(|c| (row.a[c] * 0.25 + row.b[c]) / (A * 0.25 + B))
}

const STOPS: [f64; 3] = [-2.0, 0.0, 2.0];

#[test]
fn repeated_captures_stay_in_their_set_only_when_asked() {
    let tmp = tempfile::tempdir().expect("tmp");
    folder(tmp.path(), &STOPS, 3, Noise::White, &|_, _| Take::default());
    // As brackets, every repeated exposure starts a new set: sets of one frame, refused.
    let err = scan::scan(tmp.path(), &ScanOptions::default()).expect_err("lone frames");
    assert!(err.to_string().contains("holds only this frame"), "{err}");
    let scan = scan::scan(tmp.path(), &repeats_scan()).expect("scan");
    assert_eq!(scan.sets.len(), 1);
    let set = &scan.sets[0];
    assert_eq!(set.frames.len(), 3);
    assert_eq!(set.repeats.len(), 6);
    let name = |p: &Path| p.file_name().unwrap().to_string_lossy().into_owned();
    // The first capture of each exposure is the set's frame, the later ones its repeats.
    let frames: Vec<String> = set.frames.iter().map(|f| name(&f.path)).collect();
    assert_eq!(frames, ["f0_0.png", "f1_0.png", "f2_0.png"]);
    let repeats: Vec<String> = set.repeats.iter().map(|f| name(&f.path)).collect();
    assert_eq!(
        repeats,
        [
            "f0_1.png", "f0_2.png", "f1_1.png", "f1_2.png", "f2_1.png", "f2_2.png"
        ]
    );
    for r in &set.repeats {
        let i: usize = name(&r.path)[1..2].parse().expect("index");
        assert_eq!(r.stop, set.frames[i].stop);
    }
    assert!(
        set.grouping.contains("repeated captures"),
        "{}",
        set.grouping
    );
}

#[test]
fn temporal_noise_recovers_the_noise_a_textured_scene_hides_from_a_single_frame() {
    let tmp = tempfile::tempdir().expect("tmp");
    folder(tmp.path(), &STOPS, 3, Noise::White, &|_, _| Take::default());
    let temporal = calibrate(tmp.path(), repeats_scan(), srgb_choice(), true).expect("calibrate");
    assert!(
        temporal
            .profile
            .provenance
            .noise
            .contains("6 repeated-capture pair"),
        "{}",
        temporal.profile.provenance.noise
    );
    for (c, r) in relative_variance(&temporal).iter().enumerate() {
        assert!((r - 1.0).abs() < 0.1, "temporal, channel {c}: σ² ratio {r}");
    }
    for c in 0..3 {
        let a = temporal.profile.noise[0].a[c];
        assert!((a / A - 1.0).abs() < 0.15, "channel {c}: a {a:e} vs {A:e}");
    }
    // White noise: no spatial or channel correlation is measured, none written.
    assert!(
        temporal.correlation.rho < 0.02,
        "{:?}",
        temporal.correlation
    );
    assert!(temporal.channel_correlation < 0.02);
    assert!(
        temporal.profile.effects.is_empty(),
        "{:?}",
        temporal.profile.effects
    );

    // The first capture of each exposure alone, as a bracket: the texture enters the
    // residual and the noise comes out far too high.
    let single = tempfile::tempdir().expect("tmp");
    for i in 0..3 {
        let from = tmp.path().join(format!("f{i}_0.png"));
        std::fs::copy(&from, single.path().join(format!("f{i}.png"))).expect("copy");
    }
    std::fs::write(single.path().join("exposure.txt"), "-2\n0\n2\n").expect("write");
    let spatial =
        calibrate(single.path(), ScanOptions::default(), srgb_choice(), false).expect("calibrate");
    for (c, r) in relative_variance(&spatial).iter().enumerate() {
        assert!(*r > 1.5, "single frames, channel {c}: σ² ratio {r}");
    }
}

#[test]
fn temporal_noise_measures_spatial_and_channel_correlation_without_the_scene() {
    let tmp = tempfile::tempdir().expect("tmp");
    folder(tmp.path(), &STOPS, 2, Noise::Box2, &|_, _| Take::default());
    let cal = calibrate(tmp.path(), repeats_scan(), srgb_choice(), true).expect("calibrate");
    // A 2×2 box's lag-1 correlation is exactly 0.5 (two of four draws shared).
    assert!(
        (cal.correlation.rho - 0.5).abs() < 0.04,
        "{:?}",
        cal.correlation
    );
    // Written with a raised to the per-pixel variance (the generator's: the box keeps it).
    for c in 0..3 {
        let a = cal.profile.noise[0].a[c];
        assert!((a / A - 1.0).abs() < 0.2, "channel {c}: a {a:e} vs {A:e}");
    }

    let tmp = tempfile::tempdir().expect("tmp");
    folder(tmp.path(), &STOPS, 2, Noise::Channel(0.4), &|_, _| {
        Take::default()
    });
    let cal = calibrate(tmp.path(), repeats_scan(), srgb_choice(), true).expect("calibrate");
    assert!(
        (cal.channel_correlation - 0.4).abs() < 0.05,
        "channel correlation {}",
        cal.channel_correlation
    );
    assert!(cal.correlation.rho < 0.02, "{:?}", cal.correlation);
}

#[test]
fn repeats_that_are_not_of_one_static_scene_are_refused_naming_both_files() {
    // The camera moved by one pixel for the second capture at stop 0.
    let tmp = tempfile::tempdir().expect("tmp");
    folder(tmp.path(), &STOPS, 2, Noise::White, &|i, k| Take {
        shift: usize::from(i == 1 && k == 1),
        ..Take::default()
    });
    let err = calibrate(tmp.path(), repeats_scan(), srgb_choice(), false).expect_err("moved");
    let msg = err.to_string();
    assert!(
        msg.contains("not aligned") && msg.contains("f1_0.png"),
        "{msg}"
    );
    assert!(msg.contains("f1_1.png"), "{msg}");

    // The light changed (30 % brighter) between the captures at stop 0.
    let tmp = tempfile::tempdir().expect("tmp");
    folder(tmp.path(), &STOPS, 2, Noise::White, &|i, k| Take {
        light: if i == 1 && k == 1 { 1.3 } else { 1.0 },
        ..Take::default()
    });
    let err = calibrate(tmp.path(), repeats_scan(), srgb_choice(), false).expect_err("changed");
    let msg = err.to_string();
    assert!(msg.contains("differ by more than noise"), "{msg}");
    assert!(
        msg.contains("f1_0.png") && msg.contains("f1_1.png"),
        "{msg}"
    );
}

#[test]
fn a_burst_of_one_exposure_needs_a_declared_response() {
    let tmp = tempfile::tempdir().expect("tmp");
    folder(tmp.path(), &[0.0], 4, Noise::White, &|_, _| Take::default());
    let debevec = ResponseChoice::new(None, None).expect("default choice");
    let err = calibrate(tmp.path(), repeats_scan(), debevec, false).expect_err("no bracket");
    assert!(err.to_string().contains("two or more exposures"), "{err}");
    let cal = calibrate(tmp.path(), repeats_scan(), srgb_choice(), false).expect("calibrate");
    assert!(
        cal.profile
            .provenance
            .noise
            .contains("3 repeated-capture pair")
    );
    for (c, r) in relative_variance(&cal).iter().enumerate() {
        assert!((r - 1.0).abs() < 0.1, "channel {c}: σ² ratio {r}");
    }
}

#[test]
fn the_device_output_check_on_repeats_compares_noise_without_the_scene() {
    use hdrsynth::capture::output::{OutputCheckOptions, check};
    let tmp = tempfile::tempdir().expect("tmp");
    folder(tmp.path(), &STOPS, 2, Noise::White, &|_, _| Take::default());
    let cal = calibrate(tmp.path(), repeats_scan(), srgb_choice(), false).expect("calibrate");
    let opts = |scan| OutputCheckOptions {
        scan,
        replicates: 12,
        seed: 5,
        noise: true,
    };
    // On repeated pairs the profile's own noise reproduces the frames': nothing to name.
    let temporal = check(tmp.path(), &cal.profile, &opts(repeats_scan())).expect("check");
    for s in &temporal.stats {
        eprintln!(
            "{} {:.4} vs {:.4} z {:.2}",
            s.name, s.measured, s.sim_mean, s.z
        );
    }
    assert!(
        temporal.stats.iter().all(|s| !s.significant),
        "{temporal:?}"
    );
    assert_eq!(temporal.gap, 0.0);

    // The first capture of each exposure alone: the scene's fine texture is in each real
    // frame and not in the smoothed estimate the simulation renders, but the check takes every
    // frame against the merge of the others, real and simulated alike: the scene cancels, and
    // the same profile again reproduces the frames.
    let single = tempfile::tempdir().expect("tmp");
    for i in 0..3 {
        let from = tmp.path().join(format!("f{i}_0.png"));
        std::fs::copy(&from, single.path().join(format!("f{i}.png"))).expect("copy");
    }
    std::fs::write(single.path().join("exposure.txt"), "-2\n0\n2\n").expect("write");
    let frames = check(single.path(), &cal.profile, &opts(ScanOptions::default())).expect("check");
    assert!(
        frames.stats.iter().all(|s| !s.significant),
        "{}",
        frames.markdown()
    );
}
