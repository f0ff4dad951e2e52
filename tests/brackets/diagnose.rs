//! `diagnose --brackets`: a bracket folder as scene bursts (response and exposure-ratio checks).
//! The truth here is this test's own camera: radiance × exposure time, an optional hidden
//! power-law response before the sRGB encoding, and an optional frame whose true exposure
//! differs from the one written into its EXIF.

use crate::common::srgb;
use crate::helpers::{H, Tags, W, write_jpeg};
use hdrsynth::capture::diagnose::{self, BracketDiagnoseOptions};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::sensor::profile::Response;
use std::path::Path;

/// EXIF exposure times of every set (EV −2/0/+2), seconds.
const DIAG_TIMES: [u32; 3] = [400, 100, 25];

/// Radiance of scene `s` (three scenes): a 10-stop ramp with a wavy row structure.
fn diag_radiance(s: usize, x: usize, y: usize) -> [f64; 3] {
    let u = -7.0 + 10.0 * x as f64 / (W - 1) as f64 + 0.5 * (y as f64 / 3.0 + s as f64).sin();
    let l = u.exp2();
    let c = y as f64 / (H - 1) as f64;
    [l * (0.6 + 0.4 * c), l, l * (1.0 - 0.5 * c)]
}

/// Three sub-folders of sRGB JPEGs with EXIF ExposureTime and ISO 100. The camera's signal is
/// (radiance · t · 12.5)^`exponent` (clipped at 1) before the sRGB encoding; `wrong` = (scene,
/// frame, stops) exposes that frame 2^stops longer than its EXIF says.
fn diag_brackets(root: &Path, exponent: f64, wrong: Option<(usize, usize, f64)>) {
    for s in 0..3 {
        let d = root.join(format!("scene_{s}"));
        std::fs::create_dir_all(&d).expect("mkdir");
        for (j, den) in DIAG_TIMES.iter().enumerate() {
            let mut t = 1.0 / f64::from(*den);
            if let Some((ws, wj, stops)) = wrong
                && (ws, wj) == (s, j)
            {
                t *= stops.exp2();
            }
            let mut rgb = Vec::with_capacity(W * H * 3);
            for y in 0..H {
                for x in 0..W {
                    for v in diag_radiance(s, x, y) {
                        let signal = (v * t * 12.5).min(1.0).powf(exponent);
                        rgb.push((srgb(signal) * 255.0).round() as u8);
                    }
                }
            }
            let tags = Tags {
                exposure_time: Some((1, *den)),
                iso: Some(100),
                ..Tags::default()
            };
            write_jpeg(
                &d.join(format!("f{j}.jpg")),
                W as u32,
                H as u32,
                &rgb,
                Some(&tags),
            );
        }
    }
}

fn diagnose_srgb(root: &Path) -> diagnose::BracketDiagnosis {
    let opts = BracketDiagnoseOptions {
        // The user declares the phone's curve as sRGB (what a JPEG claims to be).
        response: ResponseChoice::Declared(Response::Srgb),
        ..BracketDiagnoseOptions::default()
    };
    let out = root.with_file_name("diag");
    diagnose::diagnose_brackets(root, &opts, &out).expect("diagnose")
}

fn step_names(b: &diagnose::BracketDiagnosis) -> Vec<String> {
    b.diagnosis.steps.iter().map(|s| s.effect.clone()).collect()
}

#[test]
fn a_clean_bracket_folder_names_nothing() {
    let tmp = tempfile::tempdir().expect("tmp");
    let root = tmp.path().join("brackets");
    diag_brackets(&root, 1.0, None);
    let b = diagnose_srgb(&root);
    for p in &b.ratios.pairs {
        eprintln!(
            "{} {:+.4} vs {:+.4} (residual {:+.4})",
            p.frame.display(),
            p.measured_stops,
            p.exif_stops,
            p.residual_stops
        );
    }
    // Three sets, two pairs each (each frame against the middle one).
    assert_eq!(b.ratios.pairs.len(), 6);
    assert!(b.ratios.named().next().is_none(), "{:?}", b.ratios.pairs);
    assert!(
        (b.ratios.exponent - 1.0).abs() < 0.02,
        "{}",
        b.ratios.exponent
    );
    assert!(step_names(&b).is_empty(), "{:?}", step_names(&b));
    assert!(
        b.diagnosis.unexplained.is_empty(),
        "{:?}",
        b.diagnosis.unexplained
    );
    assert!(b.diagnosis.final_gap() < b.diagnosis.threshold);
    // The noise statistics cannot be tested by one frame per exposure and are listed.
    assert!(!b.diagnosis.skipped.is_empty());
    assert!(
        b.linearisation.contains("sRGB") || b.linearisation.contains("srgb"),
        "{}",
        b.linearisation
    );
    // The capture set and both reports are written; the capture set groups by scene key.
    let out = root.with_file_name("diag");
    for f in [
        "brackets.md",
        "brackets.toml",
        "report.md",
        "report.json",
        "captures/captures.toml",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let m = std::fs::read_to_string(out.join("captures/captures.toml")).expect("manifest");
    assert_eq!(m.matches("scene = \"scene_1\"").count(), 3, "{m}");
}

#[test]
fn a_hidden_response_is_named_with_its_exponent() {
    let tmp = tempfile::tempdir().expect("tmp");
    let root = tmp.path().join("brackets");
    diag_brackets(&root, 0.8, None);
    let b = diagnose_srgb(&root);
    // A power law scales every log ratio alike: no frame is named, the shared exponent is 0.8.
    assert!(b.ratios.named().next().is_none(), "{:?}", b.ratios.pairs);
    assert!(
        (b.ratios.exponent - 0.8).abs() < 0.02,
        "{}",
        b.ratios.exponent
    );
    assert_eq!(step_names(&b), vec!["nonlinear_response".to_string()]);
    let e = b.diagnosis.steps[0].params["exponent"]
        .as_float()
        .expect("exponent");
    eprintln!(
        "ratio-check exponent {:.4}, fitted {e:.4}",
        b.ratios.exponent
    );
    assert!((e - 0.8).abs() < 0.02, "fitted exponent {e}, planted 0.8");
    assert!(
        b.diagnosis.unexplained.is_empty(),
        "{:?}",
        b.diagnosis.unexplained
    );
}

#[test]
fn a_misreported_exposure_is_named_by_file_and_left_out() {
    let tmp = tempfile::tempdir().expect("tmp");
    let root = tmp.path().join("brackets");
    // scene_1's EV −2 frame was exposed half a stop longer than its EXIF 1/400 s says.
    diag_brackets(&root, 1.0, Some((1, 0, 0.5)));
    let b = diagnose_srgb(&root);
    let named: Vec<&diagnose::FrameRatio> = b.ratios.named().collect();
    assert_eq!(named.len(), 1, "{:?}", b.ratios.pairs);
    eprintln!(
        "named {:?}: residual {:+.4} stops",
        named[0].frame, named[0].residual_stops
    );
    assert!(
        named[0].frame.ends_with("scene_1/f0.jpg"),
        "{:?}",
        named[0].frame
    );
    assert!(
        (named[0].residual_stops - 0.5).abs() < 0.05,
        "off by {} stops, planted +0.5",
        named[0].residual_stops
    );
    // Left out of the scene bursts, so the workflow does not fit it as a response.
    assert!(step_names(&b).is_empty(), "{:?}", step_names(&b));
    assert!(
        b.diagnosis.unexplained.is_empty(),
        "{:?}",
        b.diagnosis.unexplained
    );
    let m = std::fs::read_to_string(root.with_file_name("diag").join("captures/captures.toml"))
        .expect("manifest");
    assert_eq!(m.matches("scene = \"scene_1\"").count(), 2, "{m}");
    let md = std::fs::read_to_string(root.with_file_name("diag").join("brackets.md")).expect("md");
    assert!(md.contains("f0.jpg") && md.contains("**yes**"), "{md}");
    // An output inside the bracket folder is refused (a rerun would scan it as a set).
    let e = diagnose::diagnose_brackets(
        &root,
        &BracketDiagnoseOptions::default(),
        &root.join("diag"),
    )
    .err()
    .expect("output inside the input")
    .to_string();
    assert!(e.contains("inside"), "{e}");
}
