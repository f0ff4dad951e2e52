//! A profile from brackets (`calibrate brackets`): the device's output-domain noise, response
//! and metering, and the encoding it makes agree by construction.

use crate::helpers::{Spatial, bracket_jpeg, calibrate_srgb, noisy_png_bracket, tags};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::scan::ScanOptions;
use hdrsynth::capture::testset::{self, BracketOptions};
use hdrsynth::sensor::profile::Response;
use std::path::Path;

#[test]
fn calibrate_brackets_recovers_a_known_output_noise_and_encodes_what_it_trains_on() {
    use hdrsynth::capture::profile::{BracketProfileOptions, calibrate_brackets};
    let tmp = tempfile::tempdir().expect("tmp");
    let (a, b) = (4e-4, 1e-5);
    noisy_png_bracket(
        &tmp.path().join("scene"),
        a,
        b,
        &[-2.0, 0.0, 2.0],
        Spatial::White,
    );
    let beside = tempfile::tempdir().expect("tmp");
    let out = beside.path().join("phone.toml");
    let cal = calibrate_brackets(
        tmp.path(),
        &BracketProfileOptions {
            scan: ScanOptions::default(),
            response: ResponseChoice::Declared(Response::Srgb),
            out: out.clone(),
            name: Some("test phone".into()),
            correlated: false,
        },
    )
    .expect("calibrate");
    eprintln!("{}", cal.report(&out));
    let p = hdrsynth::sensor::profile::SensorProfile::load(&out).expect("profile");
    assert_eq!(p.response, Response::Srgb);
    // No EXIF: ISO 100, said so.
    assert_eq!(p.noise.len(), 1);
    assert!(
        cal.notes.iter().any(|n| n.contains("ISO 100")),
        "{:?}",
        cal.notes
    );
    let row = &p.noise[0];
    for c in 0..3 {
        // σ² at mid-signal within 15 % of the truth; b is small beside a·L there.
        let (got, want) = (row.a[c] * 0.25 + row.b[c], a * 0.25 + b);
        assert!(
            (got / want - 1.0).abs() < 0.15,
            "channel {c}: {got} vs {want}"
        );
        assert!(
            (row.a[c] / a - 1.0).abs() < 0.2,
            "channel {c}: a {} vs {a}",
            row.a[c]
        );
    }
    // White noise: the low- and high-order residuals agree.
    for r in cal.correlation_ratio {
        assert!((r - 1.0).abs() < 0.1, "{:?}", cal.correlation_ratio);
    }
    // The middle frame (no ExposureBiasValue) is taken as the auto-exposed one.
    assert_eq!(cal.metering.len(), 1);
    assert!(cal.metering[0].how.contains("middle"), "{:?}", cal.metering);

    // Test set and training agree by construction: the test set linearised by the profile and
    // kept as device codes records the profile's curve, which a run trained on it reads.
    let ts = beside.path().join("ts");
    let opts = BracketOptions {
        response: ResponseChoice::new(Some(&out), None).expect("choice"),
        ..BracketOptions::default()
    };
    testset::build(tmp.path(), &opts, &ts).expect("testset");
    let test = hdrsynth::data::encoding::of_testset(&ts)
        .expect("read")
        .expect("some");
    let data: hdrsynth::train::config::DataConfig = hdrsynth::config::parse_toml(
        &format!(
            "dataset = \"unused\"\npatch = 32\nbatch_size = 2\nprofile = {out:?}\nisos = [100.0]\n"
        ),
        Path::new("data.toml"),
    )
    .expect("data config");
    let trained = data.frame_encoding().expect("read").expect("some");
    assert_eq!(trained.response, test.response);
    assert!(hdrsynth::data::encoding::mismatch(&trained, &test).is_none());
}

#[test]
fn the_device_meter_is_read_from_the_frame_exif_marks_and_not_from_a_manual_bracket() {
    use hdrsynth::capture::profile::metering_rule;
    use hdrsynth::sensor::profile::SensorProfile;
    let beside = tempfile::tempdir().expect("tmp");
    // A bracket of 1/100, 1/400 and 1/25 s whose frames record these biases, calibrated into
    // `out`; with the test's own log-average of the 1/100 s frame.
    let calibrate = |bias: [Option<i32>; 3], out: &Path| {
        let tmp = tempfile::tempdir().expect("tmp");
        let d = tmp.path().join("scene1");
        std::fs::create_dir_all(&d).expect("mkdir");
        for (i, (den, b)) in [100u32, 400, 25].iter().zip(bias).enumerate() {
            let mut t = tags((1, *den), 100, "2026:11:24 10:00:00", &format!("{i}"));
            t.bias = b.map(|b| (b, 1));
            bracket_jpeg(&d.join(format!("IMG_{i}.jpg")), 1.0 / *den as f64, Some(&t));
        }
        let cal = calibrate_srgb(tmp.path(), ScanOptions::default(), out, false);
        // sRGB-decoded codes, Rec. 709 luminance, geometric mean over the pixels.
        let marked = d.join("IMG_0.jpg");
        let rgb = image::open(&marked).expect("jpeg").to_rgb8();
        let dec = |c: u8| {
            let v = c as f64 / 255.0;
            if v <= 0.04045 {
                v / 12.92
            } else {
                ((v + 0.055) / 1.055).powf(2.4)
            }
        };
        let n = rgb.pixels().len() as f64;
        let ln: f64 = rgb
            .pixels()
            .map(|p| {
                let l = 0.2126 * dec(p[0]) + 0.7152 * dec(p[1]) + 0.0722 * dec(p[2]);
                l.max(1e-6).ln()
            })
            .sum::<f64>()
            / n;
        let report = cal.report(out);
        (cal, ln.exp(), report)
    };
    // An auto-exposure bracket: the 1/100 s frame records bias 0, the others −2 and +2.
    let out = beside.path().join("p.toml");
    let (cal, want, report) = calibrate([Some(0), Some(-2), Some(2)], &out);
    let frames = &cal.metering;
    assert!(
        frames[0].auto_exposed && frames[0].frame.ends_with("IMG_0.jpg"),
        "{frames:?}"
    );
    let m = metering_rule(frames).expect("a marked frame gives the device's rule");
    assert!(
        (m.mid_grey / want - 1.0).abs() < 1e-3,
        "{} vs {want}",
        m.mid_grey
    );
    assert!((m.max_clipped - frames[0].clipped).abs() < 1e-12);
    // Written into the profile, with where it was measured.
    let saved = SensorProfile::load(&out).expect("profile");
    let rule = saved.metering.expect("the rule is in the profile");
    assert!((rule.mid_grey / want - 1.0).abs() < 1e-3, "{rule:?}");
    assert_eq!(rule.max_clipped, frames[0].clipped);
    let why = saved.provenance.metering.clone().expect("provenance");
    assert!(
        why.contains("IMG_0.jpg") && !why.contains("IMG_1.jpg") && why.contains("ExposureBias"),
        "{why}"
    );
    assert!(report.contains("written into the profile"), "{report}");
    // Recalibrating the same profile from a manual bracket removes the rule, and says so.
    let (cal, _, report) = calibrate([Some(0), Some(0), Some(0)], &out);
    assert!(metering_rule(&cal.metering).is_none());
    let saved = SensorProfile::load(&out).expect("profile");
    assert_eq!((saved.metering, saved.provenance.metering), (None, None));
    assert!(
        cal.notes.iter().any(|n| n.contains("was removed")),
        "{:?}",
        cal.notes
    );
    assert!(report.contains("exposure rule: none"), "{report}");
    // Manual exposures (every bias 0, or none recorded) say nothing about the meter: a new
    // profile holds no rule.
    for bias in [[Some(0); 3], [None; 3]] {
        let fresh = beside.path().join("manual.toml");
        let (cal, _, _) = calibrate(bias, &fresh);
        assert!(metering_rule(&cal.metering).is_none());
        assert!(!cal.notes.iter().any(|n| n.contains("was removed")));
        let text = std::fs::read_to_string(&fresh).expect("written");
        assert!(!text.contains("metering"), "{text}");
        std::fs::remove_file(&fresh).expect("rm");
    }
}
