//! Noise calibration, capture sets and the darktable import.
//!
//! Simulated capture sets: per ISO and channel a known σ²_DN = a·I + b (Gaussian), flat targets
//! at five levels with vignetting plus a dark burst, 8 frames of 64×48, quantised to integer DN
//! and clipped to [0, white], written as 16-bit PNG through the capture-set writer and read
//! back through the manifest. Acceptance criterion for recovery: every one of the 18
//! (ISO, channel, parameter) estimates within 5 % of the truth, and at least 80 % of them
//! within 3 reported standard errors.

use hdrsynth::io::{Image, read_image_info};
use hdrsynth::sensor::captures::{
    Burst, BurstKind, CaptureManifest, CaptureSet, MANIFEST_NAME, SensorInfo, chart_patch_rects,
    write_capture_set,
};
use hdrsynth::sensor::darktable::{self, ImportRequest, NegativeRule, Query};
use hdrsynth::sensor::noise::plot::ptc_plot_size;
use hdrsynth::sensor::noise::profile::{NoiseProfileOptions, calibrate_noise_profile};
use hdrsynth::sensor::noise::{CalibrateOptions, NoiseCalibration, calibrate};
use hdrsynth::sensor::profile::{Levels, ProfileKind, SensorProfile};
use std::path::{Path, PathBuf};

const W: f64 = 4095.0;
const B: f64 = 64.0;
const ISOS: [f64; 3] = [100.0, 400.0, 1600.0];
const LEVELS: [f64; 5] = [150.0, 500.0, 1200.0, 2200.0, 3300.0];
/// Channel response to the neutral flat target (relative to G).
const GAIN: [f64; 3] = [0.55, 1.0, 0.75];
const FRAMES: usize = 8;
const WIDTH: usize = 64;
const HEIGHT: usize = 48;

fn truth_a(iso: f64, c: usize) -> f64 {
    iso / 200.0 * [0.9, 1.0, 1.1][c]
}
fn truth_b(iso: f64, c: usize) -> f64 {
    [3.0, 3.5, 4.0][c] + 0.02 * iso
}

/// SplitMix64 with f64 uniforms and Box–Muller normals.
struct Rng(u64);
impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// Sensor defects planted at fixed positions in every frame of every burst.
#[derive(Default, Clone)]
struct Defects {
    /// Stuck at 3000 DN.
    hot: Vec<(usize, usize)>,
    /// Stuck at 0 DN.
    dead: Vec<(usize, usize)>,
    /// Ten times the model variance.
    noisy: Vec<(usize, usize)>,
    /// In flat bursts, this rectangle (x0, y0, x1, y1) gets 5000 DN of signal (clipped).
    saturated: Option<(usize, usize, usize, usize)>,
}

impl Defects {
    fn planted(seed: u64) -> Defects {
        let mut rng = Rng(seed);
        let mut used = std::collections::HashSet::new();
        let mut pick = |n: usize, rng: &mut Rng| {
            let mut v = Vec::new();
            while v.len() < n {
                let x = (rng.uniform() * WIDTH as f64) as usize;
                let y = (rng.uniform() * HEIGHT as f64) as usize;
                // Keep defects apart from each other and out of the saturated block.
                let block = (40..56).contains(&x) && (4..16).contains(&y);
                if !block && used.insert((x / 3, y / 3)) {
                    v.push((x, y));
                }
            }
            v
        };
        Defects {
            hot: pick(12, &mut rng),
            dead: pick(12, &mut rng),
            noisy: pick(20, &mut rng),
            saturated: Some((44, 6, 52, 14)),
        }
    }
}

/// Simulate the capture set into `dir`; returns the manifest.
fn simulate(dir: &Path, defects: &Defects, seed: u64) -> CaptureManifest {
    let mut manifest = CaptureManifest {
        sensor: SensorInfo {
            name: Some("sim-sensor".into()),
            white_level: Some(W),
            black_level: Some(B),
        },
        ..CaptureManifest::new()
    };
    let mut frames = Vec::new();
    let mut rng = Rng(seed);
    for &iso in &ISOS {
        let mut targets: Vec<(String, BurstKind, f64)> =
            vec![(format!("dark_iso{iso}"), BurstKind::Dark, 0.0)];
        for (k, &l) in LEVELS.iter().enumerate() {
            targets.push((format!("flat_iso{iso}_{k}"), BurstKind::Flat, l));
        }
        for (name, kind, level) in targets {
            let paths: Vec<String> = (0..FRAMES).map(|j| format!("{name}/{j:03}.png")).collect();
            let mut imgs = Vec::new();
            for _ in 0..FRAMES {
                imgs.push(Image::from_fn(WIDTH, HEIGHT, |x, y| {
                    let dx = (x as f64 + 0.5) / WIDTH as f64 - 0.5;
                    let dy = (y as f64 + 0.5) / HEIGHT as f64 - 0.5;
                    let vignette = 1.0 - 0.5 * (dx * dx + dy * dy);
                    let in_block = defects.saturated.is_some_and(|(x0, y0, x1, y1)| {
                        (x0..x1).contains(&x) && (y0..y1).contains(&y)
                    });
                    std::array::from_fn(|c| {
                        let p = (x, y);
                        if defects.hot.contains(&p) {
                            return 3000.0;
                        }
                        if defects.dead.contains(&p) {
                            return 0.0;
                        }
                        let signal = if kind == BurstKind::Flat && in_block {
                            5000.0
                        } else {
                            level * GAIN[c] * vignette
                        };
                        let mut var = truth_a(iso, c) * signal + truth_b(iso, c);
                        if defects.noisy.contains(&p) {
                            var *= 10.0;
                        }
                        let dn = (B + signal + var.sqrt() * rng.normal()).round();
                        dn.clamp(0.0, W) as f32
                    })
                }));
            }
            manifest.bursts.push(Burst {
                name,
                kind,
                iso,
                exposure_s: if level > 0.0 {
                    level / (iso * 1000.0)
                } else {
                    0.01
                },
                frames: paths,
                scene: None,
            });
            frames.push(imgs);
        }
    }
    write_capture_set(dir, &manifest, &frames).unwrap();
    manifest
}

/// Check recovery; returns (within 5 %, within 3 SE) counts over the 18 cases.
fn check_recovery(cal: &NoiseCalibration) -> (usize, usize) {
    assert_eq!(cal.isos.len(), 3);
    let (mut ok5, mut ok3se) = (0, 0);
    for (f, &iso) in cal.isos.iter().zip(&ISOS) {
        assert_eq!(f.iso, iso);
        for c in 0..3 {
            let ch = &f.channels[c];
            for (name, est, se, truth) in [
                ("a", ch.a, ch.a_stderr, truth_a(iso, c)),
                ("b", ch.b, ch.b_stderr, truth_b(iso, c)),
            ] {
                let rel = (est - truth).abs() / truth;
                let z = (est - truth).abs() / se;
                println!(
                    "ISO {iso} ch {c} {name}: est {est:.5} ± {se:.5}, truth {truth:.5}, rel {rel:.4}, z {z:.2}"
                );
                assert!(se > 0.0 && se.is_finite(), "stderr {se}");
                ok5 += usize::from(rel <= 0.05);
                ok3se += usize::from(z <= 3.0);
            }
        }
    }
    (ok5, ok3se)
}

fn options(captures: &Path, out: &Path) -> NoiseProfileOptions {
    NoiseProfileOptions {
        captures: captures.to_path_buf(),
        out: out.to_path_buf(),
        plot: None,
        white_level: None,
        black_level: None,
    }
}

#[test]
fn recovers_known_noise_and_writes_profile_and_ptc_plot() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("captures");
    let manifest = simulate(&dir, &Defects::default(), 1);

    // The writer stores exact DN: read back one frame and compare with a re-simulation-free
    // check (every value an integer in [0, W]) and with the manifest.
    let set = CaptureSet::load(&dir).unwrap();
    assert_eq!(set.manifest, manifest);
    let f = set.read_frame(1, 0).unwrap();
    assert!(
        f.data
            .iter()
            .all(|&v| v.fract() == 0.0 && (0.0..=W as f32).contains(&v))
    );

    let cal = calibrate(&set, &CalibrateOptions::default()).unwrap();
    println!("{}", cal.report(W, B));
    let (ok5, ok3se) = check_recovery(&cal);
    assert_eq!(ok5, 18, "all 18 (ISO, channel, param) within 5 %");
    assert!(ok3se >= 15, "{ok3se}/18 within 3 SE; need ≥ 80 % (15)");
    // Black level: declared 64 and estimated from the dark bursts.
    let est = cal.black_estimated.unwrap();
    assert!((est - B).abs() < 0.5, "estimated black {est}");
    for f in &cal.isos {
        for ch in &f.channels {
            assert_eq!(ch.counts.saturated, 0);
            // 6σ rules on clean data: false positives are rare.
            assert!(
                ch.counts.defective <= ch.counts.used / 200,
                "{:?}",
                ch.counts
            );
        }
    }

    // CLI: new profile from the capture set, plus the PTC plot next to it.
    let out = tmp.path().join("profiles/sim.toml");
    let report = calibrate_noise_profile(&options(&dir, &out)).unwrap();
    println!("{report}");
    let p = SensorProfile::load(&out).unwrap();
    assert_eq!(p.name, "sim-sensor");
    assert_eq!(p.levels.white_level, W);
    assert_eq!(p.levels.black_level, B);
    assert_eq!(p.levels.bit_depth, 12);
    assert!(p.colour.is_none());
    assert!(p.provenance.response.contains("default"));
    assert_eq!(p.noise.len(), 3);
    let r = W - B;
    for (n, &iso) in p.noise.iter().zip(&ISOS) {
        assert_eq!(n.iso, iso);
        for c in 0..3 {
            let (a, b) = (truth_a(iso, c) / r, truth_b(iso, c) / (r * r));
            assert!((n.a[c] - a).abs() / a <= 0.05, "a_norm {} vs {a}", n.a[c]);
            assert!((n.b[c] - b).abs() / b <= 0.05, "b_norm {} vs {b}", n.b[c]);
            assert!(n.a_stderr.unwrap()[c] > 0.0 && n.b_stderr.unwrap()[c] > 0.0);
        }
    }
    // The PTC plot: a valid PNG of the documented size, with the three channel colours drawn.
    let plot = out.with_extension("ptc.png");
    let (img, info) = read_image_info(&plot).unwrap();
    assert_eq!(info.format, hdrsynth::io::Format::Png);
    assert_eq!((img.width, img.height), ptc_plot_size(3));
    assert_eq!(ptc_plot_size(3), (1260, 350));
    let bytes = std::fs::read(&plot).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    for c in 0..3 {
        let coloured = img
            .pixels()
            .filter(|p| p[c] > 0.5 && p.iter().enumerate().all(|(k, &v)| k == c || v < 0.45))
            .count();
        assert!(
            coloured > 100,
            "channel {c}: {coloured} pixels of its colour"
        );
    }

    // Updating an existing profile replaces noise and provenance.noise only.
    let mut edited = p.clone();
    edited.name = "renamed".into();
    edited.noise.clear();
    edited.provenance.noise = "old".into();
    edited.save(&out).unwrap();
    let plot2 = tmp.path().join("ptc2.png");
    let mut args = options(&dir, &out);
    args.plot = Some(plot2.clone());
    calibrate_noise_profile(&args).unwrap();
    let q = SensorProfile::load(&out).unwrap();
    assert_eq!(q.name, "renamed");
    assert_eq!(q.noise, p.noise);
    assert!(q.provenance.noise.contains("calibrate noise"));
    assert!(plot2.exists());
}

#[test]
fn defects_and_saturation_are_excluded_and_do_not_bias_the_fit() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("captures");
    let defects = Defects::planted(7);
    simulate(&dir, &defects, 2);
    let set = CaptureSet::load(&dir).unwrap();
    let cal = calibrate(&set, &CalibrateOptions::default()).unwrap();
    println!("{}", cal.report(W, B));
    let (ok5, ok3se) = check_recovery(&cal);
    assert_eq!(ok5, 18, "all 18 (ISO, channel, param) within 5 %");
    assert!(ok3se >= 15, "{ok3se}/18 within 3 SE; need ≥ 80 % (15)");

    // Counts, per burst and channel: every hot and dead pixel excluded as defective, ≥ 80 % of
    // the noisy ones excluded (as defective or clipped at 0), few false positives; the
    // saturated block excluded as saturated.
    let (x0, y0, x1, y1) = defects.saturated.unwrap();
    let block = (x1 - x0) * (y1 - y0);
    let stuck = defects.hot.len() + defects.dead.len();
    let pixels = WIDTH * HEIGHT;
    let (mut noisy_excluded, mut noisy_planted) = (0, 0);
    for b in &cal.bursts {
        for (c, n) in b.counts.iter().enumerate() {
            let at = format!("burst {} channel {c}: {n:?}", b.name);
            // Noisy pixels that reach 0 DN in some frame are excluded as clipped instead.
            let excluded = n.defective + n.clipped_low;
            assert!(n.defective >= stuck, "hot/dead not all excluded: {at}");
            // A 10× pixel escapes the 6σ variance rule with probability ≈ 9 % at 8 frames
            // (χ²₇ tail), so per burst only half are required; ≥ 80 % over all bursts below.
            assert!(
                excluded >= stuck + defects.noisy.len() / 2,
                "too few excluded: {at}"
            );
            noisy_excluded += excluded - stuck;
            noisy_planted += defects.noisy.len();
            assert!(
                excluded <= stuck + defects.noisy.len() + pixels / 200,
                "too many excluded: {at}"
            );
            if b.kind == BurstKind::Flat {
                assert!(n.saturated >= block, "saturated block not excluded: {at}");
                assert!(n.saturated <= block + pixels / 200, "{at}");
            } else {
                assert_eq!(n.saturated, 0, "{at}");
            }
        }
    }
    println!("noisy pixels excluded: {noisy_excluded} of {noisy_planted} (with false positives)");
    assert!(
        noisy_excluded * 10 >= noisy_planted * 8,
        "{noisy_excluded} of {noisy_planted} noisy pixels excluded"
    );
    // The per-ISO totals are the sums over bursts.
    for f in &cal.isos {
        let sum: usize = cal
            .bursts
            .iter()
            .filter(|b| b.iso == f.iso)
            .map(|b| b.counts[1].defective)
            .sum();
        assert_eq!(f.channels[1].counts.defective, sum);
    }
    // The report names the exclusion counts.
    assert!(cal.report(W, B).contains("defect"));
}

/// A small valid capture set: one dark and one flat burst of 3 frames, 16×12.
fn small_set(dir: &Path) -> CaptureManifest {
    let mut manifest = CaptureManifest {
        sensor: SensorInfo {
            name: Some("small".into()),
            white_level: Some(1023.0),
            black_level: Some(16.0),
        },
        ..CaptureManifest::new()
    };
    let mut rng = Rng(5);
    let mut frames = Vec::new();
    for (name, kind, level) in [
        ("dark_a", BurstKind::Dark, 0.0),
        ("flat_a", BurstKind::Flat, 400.0),
    ] {
        let paths: Vec<String> = (0..3).map(|j| format!("{name}/{j}.png")).collect();
        let imgs: Vec<Image> = (0..3)
            .map(|_| {
                Image::from_fn(16, 12, |_, _| {
                    std::array::from_fn(|_| (16.0 + level + 3.0 * rng.normal()).round() as f32)
                })
            })
            .collect();
        manifest.bursts.push(Burst {
            name: name.into(),
            kind,
            iso: 200.0,
            exposure_s: 0.01,
            frames: paths,
            scene: None,
        });
        frames.push(imgs);
    }
    write_capture_set(dir, &manifest, &frames).unwrap();
    manifest
}

#[test]
fn manifest_errors_name_the_burst_and_file_and_write_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    // An existing profile must stay byte-identical through every failure.
    let existing = out_dir.join("existing.toml");
    let fresh = out_dir.join("fresh.toml");

    type Mutation = Box<dyn Fn(&Path)>;
    let cases: Vec<(&str, Mutation, Vec<&str>)> = vec![
        (
            "unknown key",
            Box::new(|d: &Path| edit(d, "name = \"flat_a\"", "name = \"flat_a\"\ngain = 2")),
            vec!["flat_a", "unknown key 'gain'"],
        ),
        (
            "scene key on a flat",
            Box::new(|d: &Path| edit(d, "name = \"flat_a\"", "name = \"flat_a\"\nscene = \"x\"")),
            vec!["flat_a", "'scene' names the scene of a scene burst"],
        ),
        (
            "unknown kind",
            Box::new(|d: &Path| edit(d, "kind = \"flat\"", "kind = \"bright\"")),
            vec!["flat_a", "unknown kind 'bright'"],
        ),
        (
            "missing field",
            Box::new(|d: &Path| {
                let p = d.join(MANIFEST_NAME);
                let text = std::fs::read_to_string(&p).unwrap();
                // Drop the iso line of the second burst (flat_a).
                let pos = text.find("name = \"flat_a\"").unwrap();
                let (head, tail) = text.split_at(pos);
                let mut dropped = false;
                let tail: Vec<&str> = tail
                    .lines()
                    .filter(|l| {
                        let drop = !dropped && l.starts_with("iso =");
                        dropped |= drop;
                        !drop
                    })
                    .collect();
                let tail = tail.join("\n");
                std::fs::write(&p, format!("{head}{tail}")).unwrap();
            }),
            vec!["flat_a", "missing field 'iso'"],
        ),
        (
            "missing file",
            Box::new(|d: &Path| std::fs::remove_file(d.join("flat_a/1.png")).unwrap()),
            vec!["flat_a", "flat_a/1.png", "not found"],
        ),
        (
            "frames of different sizes",
            Box::new(|d: &Path| {
                let img = Image::from_fn(8, 12, |_, _| [0.01; 3]);
                hdrsynth::io::write_ldr(
                    &d.join("dark_a/2.png"),
                    &img,
                    hdrsynth::io::BitDepth::Sixteen,
                )
                .unwrap();
            }),
            vec!["dark_a", "dark_a/2.png", "dark_a/0.png", "8×12", "16×12"],
        ),
        (
            "one frame",
            Box::new(|d: &Path| {
                edit(
                    d,
                    "frames = [\"flat_a/0.png\", \"flat_a/1.png\", \"flat_a/2.png\"]",
                    "frames = [\"flat_a/0.png\"]",
                )
            }),
            vec!["flat_a", "flat_a/0.png", "at least 2"],
        ),
    ];
    for (what, mutate, needles) in cases {
        let dir = tmp.path().join(what.replace(' ', "_"));
        small_set(&dir);
        // Sanity: the unmodified set calibrates.
        if what == "unknown key" {
            let ok = out_dir.join("ok.toml");
            calibrate_noise_profile(&options(&dir, &ok)).unwrap();
            std::fs::copy(&ok, &existing).unwrap();
            std::fs::remove_file(&ok).unwrap();
            std::fs::remove_file(ok.with_extension("ptc.png")).unwrap();
        }
        mutate(&dir);
        let before = std::fs::read(&existing).unwrap();
        for out in [&fresh, &existing] {
            let err = calibrate_noise_profile(&options(&dir, out))
                .expect_err(what)
                .to_string();
            println!("{what}: {err}");
            for n in &needles {
                assert!(err.contains(n), "{what}: '{err}' lacks '{n}'");
            }
            assert!(
                err.contains(&dir.join(MANIFEST_NAME).display().to_string())
                    || err.contains(&dir.display().to_string()),
                "{what}: '{err}' does not name the capture set"
            );
        }
        assert!(!fresh.exists(), "{what}: profile written");
        assert!(
            !fresh.with_extension("ptc.png").exists(),
            "{what}: plot written"
        );
        assert!(
            !existing.with_extension("ptc.png").exists(),
            "{what}: plot written"
        );
        assert_eq!(
            std::fs::read(&existing).unwrap(),
            before,
            "{what}: profile changed"
        );
    }
    let left: Vec<PathBuf> = std::fs::read_dir(&out_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(
        left,
        vec![existing.clone()],
        "only the pre-existing profile remains"
    );
}

fn edit(dir: &Path, from: &str, to: &str) {
    let p = dir.join(MANIFEST_NAME);
    let text = std::fs::read_to_string(&p).unwrap();
    let pos = text.find("name = \"flat_a\"").unwrap();
    let (head, tail) = text.split_at(pos);
    assert!(tail.contains(from), "'{from}' not in\n{tail}");
    std::fs::write(&p, format!("{head}{}", tail.replacen(from, to, 1))).unwrap();
}

#[test]
fn capture_set_round_trip_and_chart_geometry() {
    let tmp = tempfile::tempdir().unwrap();
    let m = small_set(tmp.path());
    let set = CaptureSet::load(&tmp.path().join(MANIFEST_NAME)).unwrap();
    assert_eq!(set.manifest, m);
    assert_eq!(set.sizes, vec![(16, 12), (16, 12)]);
    // Exact DN through 16-bit PNG, including the extremes.
    let mut m2 = m.clone();
    m2.bursts.truncate(1);
    m2.bursts[0].frames.truncate(2);
    let vals: Vec<f32> = (0..16 * 12 * 3)
        .map(|i| [0.0, 1.0, 4095.0, 65535.0, 1234.0][i % 5])
        .collect();
    let img = Image::from_vec(16, 12, vals);
    let dir2 = tmp.path().join("exact");
    write_capture_set(&dir2, &m2, &[vec![img.clone(), img.clone()]]).unwrap();
    let set2 = CaptureSet::load(&dir2).unwrap();
    assert_eq!(set2.load_burst(0).unwrap(), vec![img.clone(), img]);
    // Non-integer-representable DN are refused before anything is written.
    let bad = Image::from_fn(16, 12, |_, _| [70000.0; 3]);
    let dir3 = tmp.path().join("bad");
    assert!(write_capture_set(&dir3, &m2, &[vec![bad.clone(), bad]]).is_err());
    assert!(!dir3.exists());
    // Chart cells: 6×4 grid, central half of each cell.
    let r = chart_patch_rects(600, 400);
    assert_eq!((r[0].x0, r[0].y0, r[0].x1, r[0].y1), (25, 25, 75, 75));
    assert_eq!(
        (r[23].x0, r[23].y0, r[23].x1, r[23].y1),
        (525, 325, 575, 375)
    );
    assert_eq!((r[7].x0, r[7].y0), (125, 125));
}

// ---------------------------------------------------------------------------------------------
// darktable import

mod common;

/// darktable's measured noise profiles, flattened to CSV (GPL data, not in the repository).
fn darktable_csv() -> PathBuf {
    common::shared_data("noise/darktable_noiseprofiles.csv")
}

/// Independent CSV parse: (iso, a, b) rows of one camera in file order.
fn csv_rows(csv: &Path, maker: &str, model: &str) -> Vec<(f64, [f64; 3], [f64; 3], String)> {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "maker,model,iso,a_R,a_G,a_B,b_R,b_G,b_B,profile_name"
    );
    lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f[0] == maker && f[1] == model)
        .map(|f| {
            let n = |i: usize| f[i].parse::<f64>().unwrap();
            (
                n(2),
                [n(3), n(4), n(5)],
                [n(6), n(7), n(8)],
                f[9].to_string(),
            )
        })
        .collect()
}

fn import_args(csv: &Path, maker: &str, model: &str, out: &Path) -> ImportRequest {
    ImportRequest {
        csv: csv.to_path_buf(),
        query: Query {
            maker: maker.into(),
            model: model.into(),
            profile_name: None,
            set: None,
        },
        levels: Levels {
            black_level: 2048.0,
            white_level: 15000.0,
            bit_depth: 14,
        },
        levels_source: "test levels".into(),
        rule: NegativeRule::Floor,
        out: out.to_path_buf(),
        name: None,
        kind: ProfileKind::Measured,
    }
}

fn import(req: &ImportRequest) -> hdrsynth::error::Result<String> {
    darktable::import(req).map(|done| done.report(req))
}

#[test]
#[ignore = "needs ../shared/data"]
fn darktable_import_reproduces_the_csv() {
    let csv = darktable_csv();
    let tmp = tempfile::tempdir().unwrap();

    // Canon EOS 550D: two profiles share ISO 100–6400 under one profile name.
    let out = tmp.path().join("550d.toml");
    let mut args = import_args(&csv, "canon", "eos 550d", &out);
    let err = import(&args).unwrap_err().to_string();
    println!("{err}");
    for n in ["--set 1", "--set 2", "ISO 100", "Canon EOS 550D", "12800"] {
        assert!(err.contains(n), "'{err}' lacks '{n}'");
    }
    assert!(!out.exists());
    args.query.set = Some(3);
    assert!(
        import(&args)
            .unwrap_err()
            .to_string()
            .contains("--set 3 does not exist")
    );
    assert!(!out.exists());
    // Set 1 has negative b (ISO 200–3200) and a negative a_B at 12800: copied verbatim on
    // request.
    args.query.set = Some(1);
    args.rule = NegativeRule::Verbatim;
    import(&args).expect("verbatim import");
    let rows = csv_rows(&csv, "Canon", "EOS 550D");
    let verbatim = SensorProfile::load(&out).unwrap();
    let mut negatives = 0;
    for n in &verbatim.noise {
        let r = rows.iter().find(|r| r.0 == n.iso).expect("iso in csv");
        assert_eq!((n.a, n.b), (r.1, r.2), "ISO {} verbatim", n.iso);
        negatives += n.b.iter().chain(&n.a).filter(|v| **v < 0.0).count();
    }
    assert!(negatives > 0);
    assert!(verbatim.provenance.noise.contains("kept verbatim"));
    std::fs::remove_file(&out).unwrap();
    // With --negative zero they become 0.
    args.rule = NegativeRule::Zero;
    let report = import(&args).unwrap();
    println!("{report}");
    let mut first: Vec<_> = Vec::new();
    for r in &rows {
        if !first
            .iter()
            .any(|f: &(f64, [f64; 3], [f64; 3], String)| f.0 == r.0)
        {
            first.push(r.clone());
        }
    }
    first.sort_by(|a, b| a.0.total_cmp(&b.0));
    let p = SensorProfile::load(&out).unwrap();
    assert_eq!(p.noise.len(), first.len());
    assert_eq!(p.noise.len(), 8);
    let mut clamped = 0;
    for (n, r) in p.noise.iter().zip(&first) {
        assert_eq!(n.iso, r.0);
        for c in 0..3 {
            for (got, want) in [(n.a[c], r.1[c]), (n.b[c], r.2[c])] {
                if want >= 0.0 {
                    assert_eq!(got, want, "ISO {} exact copy", r.0);
                } else {
                    assert_eq!(got, 0.0);
                    clamped += 1;
                }
            }
        }
    }
    assert!(clamped > 0);
    assert_eq!(p.provenance.noise.matches("written as 0").count(), 1);
    assert_eq!(
        p.provenance.noise.matches(" = -").count(),
        clamped,
        "{}",
        p.provenance.noise
    );
    for n in [
        "noiseprofiles.json",
        "Canon",
        "EOS 550D",
        "'Canon EOS 550D'",
        "set 1 of 2",
    ] {
        assert!(p.provenance.noise.contains(n), "provenance lacks {n}");
    }
    assert!(p.provenance.noise.contains(&csv.display().to_string()));
    assert_eq!(p.provenance.levels, "test levels");
    assert_eq!(
        (
            p.levels.black_level,
            p.levels.white_level,
            p.levels.bit_depth
        ),
        (2048.0, 15000.0, 14)
    );
    assert_eq!(p.name, "Canon EOS 550D");
    assert!(p.colour.is_none());

    // Default (--negative floor): each negative b becomes the largest positive b of the same
    // channel at a lower ISO (here ISO 100's b for ISO 200–3200: read noise referred to the raw
    // output cannot fall as the gain rises); the negative a_B at ISO 12800 stays; the rest is
    // copied exactly.
    std::fs::remove_file(&out).unwrap();
    args.rule = NegativeRule::Floor;
    import(&args).unwrap();
    let p = SensorProfile::load(&out).unwrap();
    let b100 = first[0].2;
    assert_eq!(first[0].0, 100.0);
    assert!(b100.iter().all(|v| *v > 0.0));
    let mut replaced = 0;
    for (n, r) in p.noise.iter().zip(&first) {
        assert_eq!(n.a, r.1, "ISO {}: a copied exactly (negative a kept)", r.0);
        for ((got, csv_b), floor) in n.b.iter().zip(r.2).zip(b100) {
            if csv_b < 0.0 {
                assert!((200.0..=3200.0).contains(&r.0));
                assert_eq!(*got, floor, "ISO {} b", r.0);
                replaced += 1;
            } else {
                assert_eq!(*got, csv_b);
            }
        }
    }
    assert_eq!(replaced, 15);
    assert!(p.noise[7].a[2] < 0.0);
    assert_eq!(p.provenance.noise.matches("(b_R at ISO 100)").count(), 5);
    assert!(
        p.provenance
            .noise
            .contains("a_B = -2.77604100359821e-5 (line 767) kept")
    );

    // Nikon D40: two sets, no negative values: every number copied exactly (set 2 here).
    let out = tmp.path().join("d40.toml");
    let mut args = import_args(&csv, "Nikon", "D40", &out);
    args.query.set = Some(2);
    args.query.profile_name = Some("nikon d40".into());
    import(&args).unwrap();
    let rows = csv_rows(&csv, "Nikon", "D40");
    let mut second: Vec<_> = Vec::new();
    let mut seen: Vec<f64> = Vec::new();
    for r in &rows {
        if seen.contains(&r.0) {
            second.push(r.clone());
        }
        seen.push(r.0);
    }
    second.sort_by(|a, b| a.0.total_cmp(&b.0));
    let p = SensorProfile::load(&out).unwrap();
    assert_eq!(p.noise.len(), 5);
    for (n, r) in p.noise.iter().zip(&second) {
        assert_eq!((n.iso, n.a, n.b), (r.0, r.1, r.2));
        assert_eq!(r.3, format!("NIKON D40 iso {}", r.0));
    }
    // Log-linear ISO interpolation at an intermediate ISO, by hand.
    let iso: f64 = 283.0;
    let (n0, n1) = (&second[0], &second[1]);
    assert_eq!((n0.0, n1.0), (200.0, 400.0));
    let w = (iso / 200.0).ln() / 2f64.ln();
    let (a, b) = p.noise_at(iso).unwrap();
    for c in 0..3 {
        let ha = n0.1[c] + (n1.1[c] - n0.1[c]) * w;
        let hb = n0.2[c] + (n1.2[c] - n0.2[c]) * w;
        assert!((a[c] - ha).abs() <= 1e-12 * ha.abs(), "a {} vs {ha}", a[c]);
        assert!((b[c] - hb).abs() <= 1e-12 * hb.abs(), "b {} vs {hb}", b[c]);
    }
    assert_eq!(p.noise_at(400.0).unwrap(), (n1.1, n1.2));
    assert!(p.noise_at(100.0).is_err());

    // Updating an existing profile keeps its name and colour; replaces noise and levels.
    let mut args = import_args(&csv, "Nikon", "D40", &out);
    args.query.set = Some(1);
    args.levels.black_level = 0.0;
    args.levels.white_level = 4095.0;
    args.levels.bit_depth = 12;
    args.levels_source = "second".into();
    let mut renamed = p.clone();
    renamed.name = "my D40".into();
    renamed.save(&out).unwrap();
    import(&args).unwrap();
    let q = SensorProfile::load(&out).unwrap();
    assert_eq!(q.name, "my D40");
    assert_eq!(q.levels.white_level, 4095.0);
    assert_eq!(q.provenance.levels, "second");
    let first_d40: Vec<_> = rows.iter().take(5).collect();
    for (n, r) in q.noise.iter().zip(first_d40) {
        assert_eq!((n.iso, n.a, n.b), (r.0, r.1, r.2));
    }
    assert_ne!(q.noise, p.noise);

    // Unknown camera: the error lists the maker's models.
    let err = import(&import_args(
        &csv,
        "Nikon",
        "D9999",
        &tmp.path().join("x.toml"),
    ))
    .unwrap_err()
    .to_string();
    assert!(err.contains("D40") && err.contains("D9999"), "{err}");
    assert!(!tmp.path().join("x.toml").exists());
}
