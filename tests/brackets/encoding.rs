//! The written inputs' encoding (`--encode`), the recorded curve, and eval's check against a
//! network's training frames.

use crate::helpers::{bracket_folder, debevec_tables, read_u16_tiff, train_tiny_with};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::testset::{self, BracketOptions, EncodeSpec};
use hdrsynth::sensor::profile::Response;
use std::path::{Path, PathBuf};

/// The 8-bit codes of a JPEG of `bracket_folder`.
fn jpeg_codes(path: &Path) -> Vec<f64> {
    let img = image::open(path).expect("jpeg").to_rgb8();
    img.into_raw().iter().map(|&v| f64::from(v)).collect()
}

/// A copy of the composite phone profile with its device response replaced by `response`
/// (TOML lines of the `[response]` table).
fn profile_with_response(dir: &Path, response: &str) -> PathBuf {
    let shipped =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/sensors/composite_phone.toml");
    let text = std::fs::read_to_string(shipped).expect("profile");
    assert!(text.contains("[response]\nkind = \"srgb\"\n"));
    let p = dir.join(format!("phone_{}.toml", response.len()));
    let new = text.replace(
        "[response]\nkind = \"srgb\"\n",
        &format!("[response]\n{response}\n"),
    );
    std::fs::write(&p, new).expect("write profile");
    p
}

#[test]
fn written_inputs_keep_the_device_codes_or_take_a_named_curve_and_the_ground_truth_stays() {
    let tmp = tempfile::tempdir().expect("tmp");
    let src = bracket_folder(tmp.path());
    let beside = tempfile::tempdir().expect("tmp");
    let gamma18 = profile_with_response(beside.path(), "kind = \"gamma\"\ngamma = 1.8");
    let srgb_profile = profile_with_response(beside.path(), "kind = \"srgb\"");
    let build = |encode: EncodeSpec, name: &str| -> PathBuf {
        let opts = BracketOptions {
            response: ResponseChoice::Declared(Response::Srgb),
            encode,
            ..BracketOptions::default()
        };
        let out = beside.path().join(name);
        testset::build(tmp.path(), &opts, &out).expect("build");
        out
    };
    let auto = build(EncodeSpec::Auto, "auto");
    let field = build(EncodeSpec::Field, "field");
    let g18 = build(EncodeSpec::Profile(gamma18), "g18");
    let same = build(EncodeSpec::Profile(srgb_profile), "srgb");
    // Inputs by exposure: 1/400 (IMG_1), 1/100 (IMG_0), 1/25 s (IMG_2).
    let inputs = ["IMG_1.jpg", "IMG_0.jpg", "IMG_2.jpg"];
    let srgb_decode = |v: f64| {
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    for (k, jpeg) in inputs.iter().enumerate() {
        let codes = jpeg_codes(&src.join(jpeg));
        let frame = format!("scene1/frame_{}.tif", k + 1);
        // auto = device for JPEGs: the JPEG's own codes, 8 bits widened to 16 exactly (×257).
        let (_, _, dev) = read_u16_tiff(&auto.join(&frame));
        for (d, c) in dev.iter().zip(&codes) {
            assert!((d * 255.0 - c).abs() < 1e-9, "{frame}: {d} vs code {c}");
        }
        // field: sRGB decoded by hand, then L^(1/2.2); profile γ 1.8: L^(1/1.8); 16-bit codes.
        for (dir, g) in [(&field, 2.2), (&g18, 1.8)] {
            let (_, _, v) = read_u16_tiff(&dir.join(&frame));
            for (got, c) in v.iter().zip(&codes) {
                let want = srgb_decode(c / 255.0).powf(1.0 / g);
                assert!(
                    (got - want).abs() <= 0.6 / 65535.0,
                    "{frame} γ {g}: {got} vs {want}"
                );
            }
        }
        // Re-encoded with the device's true curve: its own codes again.
        let (_, _, v) = read_u16_tiff(&same.join(&frame));
        for (got, c) in v.iter().zip(&codes) {
            assert!(
                (got * 255.0 - c).abs() < 255.0 / 65535.0,
                "{frame}: {got} vs {c}"
            );
        }
    }
    // The ground truth merges the linearised frames whatever the inputs' encoding; only
    // Kalantari's weights follow the reference as written (three frames: the inputs' merge),
    // so the encodings' ground truths differ where the frames disagree (8-bit rounding here).
    let read_gt =
        |dir: &Path| hdrsynth::io::read_image(&dir.join("scene1/HDRImg.hdr")).expect("gt");
    let gt = read_gt(&field);
    for dir in [&auto, &g18, &same] {
        let p = hdrsynth::eval::metrics::psnr_mu(&gt, &read_gt(dir)).expect("psnr");
        assert!(
            p > 50.0,
            "{}: PSNR-T {p} against the field encoding's",
            dir.display()
        );
    }
    // The record: the curve each set of inputs holds.
    let enc = |dir: &Path| {
        hdrsynth::data::encoding::of_testset(dir)
            .expect("read")
            .expect("some")
    };
    assert_eq!(enc(&auto).response, Response::Srgb);
    assert_eq!(enc(&field).response, Response::Gamma { gamma: 2.2 });
    assert_eq!(enc(&g18).response, Response::Gamma { gamma: 1.8 });
    let record = std::fs::read_to_string(auto.join("scene1/brackets.toml")).expect("record");
    assert!(
        record.contains("encoding = \"srgb (the device's own codes"),
        "{record}"
    );
}

#[test]
fn an_estimated_response_is_recorded_as_the_curve_of_the_device_codes() {
    // Debevec from the test's sRGB JPEGs: the recorded curve maps linear (1 = the tables'
    // white) to code, the mean over channels of the inverse of crf_debevec.csv's curves,
    // computed here by hand from that file (`debevec_tables`), inverted by linear
    // interpolation between codes.
    let tmp = tempfile::tempdir().expect("tmp");
    bracket_folder(tmp.path());
    let beside = tempfile::tempdir().expect("tmp");
    let out = beside.path().join("out");
    testset::build(tmp.path(), &BracketOptions::default(), &out).expect("build");
    let e = hdrsynth::data::encoding::of_testset(&out)
        .expect("read")
        .expect("some");
    assert!(e.source.contains("Debevec"), "{}", e.source);
    let tables = debevec_tables(&out.join("crf_debevec.csv"));
    let inverse = |t: &[f64], x: f64| -> f64 {
        if x <= t[0] {
            return 0.0;
        }
        let z = (1..256).find(|&z| t[z] >= x).unwrap_or(255);
        let f = if t[z] > t[z - 1] {
            (x - t[z - 1]) / (t[z] - t[z - 1])
        } else {
            1.0
        };
        ((z - 1) as f64 + f) / 255.0
    };
    let mut worst = 0.0f64;
    // On the curve's own 1024 + 1 sample points, where it is the inverse itself.
    for i in 0..=1024 {
        let x = i as f64 / 1024.0;
        let want = tables.iter().map(|t| inverse(t, x)).sum::<f64>() / 3.0;
        worst = worst.max((e.response.apply(x) - want).abs());
    }
    assert!(worst < 1e-9, "{worst}");
}

#[test]
fn eval_warns_when_a_network_meets_a_curve_it_was_not_trained_on() {
    use hdrsynth::eval::evaluate::{self, EvalOptions};
    use hdrsynth::eval::infer::NetworkOptions;
    use hdrsynth::runner::method::from_checkpoint;
    let tmp = tempfile::tempdir().expect("tmp");
    bracket_folder(tmp.path());
    let beside = tempfile::tempdir().expect("tmp");
    let testset = |encode: EncodeSpec, name: &str| -> PathBuf {
        let opts = BracketOptions {
            response: ResponseChoice::Declared(Response::Srgb),
            encode,
            ..BracketOptions::default()
        };
        let out = beside.path().join(name);
        testset::build(tmp.path(), &opts, &out).expect("build");
        out
    };
    let device_set = testset(EncodeSpec::Device, "device");
    let field_set = testset(EncodeSpec::Field, "field");
    // Fine-tuned on the composite phone, whose device response is sRGB, as the JPEGs'.
    let phone = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/sensors/composite_phone.toml");
    let run = beside.path().join("phone_run");
    train_tiny_with(
        &run,
        "kind = \"wu\"\nbase_width = 4\nres_blocks = 1",
        "[-2.0, 0.0, 2.0]",
        &format!("profile = {phone:?}\nisos = [100.0]"),
    );
    let device = hdrsynth::device::device_from_name("flex").expect("flex");
    let method = from_checkpoint(&run, &NetworkOptions::default(), &device).expect("load");
    let trained = method
        .trained_encoding()
        .expect("the run records its profile");
    assert_eq!(trained.response, Response::Srgb);
    let eval = |set: &Path, name: &str| {
        evaluate::evaluate(
            set,
            method.as_ref(),
            &beside.path().join(name),
            &EvalOptions::default(),
        )
        .expect("eval")
    };
    let same = eval(&device_set, "e_device");
    assert!(same.warnings.is_empty(), "{:?}", same.warnings);
    let other = eval(&field_set, "e_field");
    assert_eq!(other.warnings.len(), 1, "{:?}", other.warnings);
    let w = &other.warnings[0];
    assert!(w.contains("srgb") && w.contains("gamma 2.2"), "{w}");
    let md = std::fs::read_to_string(beside.path().join("e_field/summary.md")).expect("md");
    assert!(
        md.contains("## Warnings") && md.contains("gamma 2.2"),
        "{md}"
    );
}
