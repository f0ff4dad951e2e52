//! The Kalantari-layout test set written from brackets: its frames, exposure.txt and triangle-merge
//! ground truth, read back as Kalantari and scored by eval, also through the binary.

use crate::helpers::{
    H, W, assert_close, bracket_folder, radiance, read_rgbe, read_u16_tiff, train_tiny,
};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::scan::ScanOptions;
use hdrsynth::capture::testset::{self, BracketOptions, EncodeSpec};
use hdrsynth::sensor::profile::Response;
use std::path::Path;

#[test]
fn the_ground_truth_is_the_triangle_merge_of_the_written_frames() {
    let tmp = tempfile::tempdir().expect("tmp");
    bracket_folder(tmp.path());
    let beside = tempfile::tempdir().expect("tmp"); // outputs inside the input are refused
    let out = beside.path().join("out");
    let opts = BracketOptions {
        scan: ScanOptions::default(),
        response: ResponseChoice::Declared(Response::Srgb),
        align: None,
        // Written as the field's linear^(1/2.2), which the hand merges below read with γ 2.2.
        encode: EncodeSpec::Field,
        ..BracketOptions::default()
    };
    // An output inside the bracket folder is refused before anything is written (a rerun
    // would scan its Kalantari sets as brackets).
    let inside = tmp.path().join("out");
    let e = testset::build(tmp.path(), &opts, &inside)
        .expect_err("output inside the input")
        .to_string();
    assert!(e.contains("inside") && !inside.exists(), "{e}");
    let summary = testset::build(tmp.path(), &opts, &out).expect("build");
    assert_eq!(summary.sets.len(), 1);
    let set = out.join("scene1");

    // exposure.txt: stops relative to the shortest frame, as Kalantari writes "0 2 4".
    let stops: Vec<f64> = std::fs::read_to_string(set.join("exposure.txt"))
        .expect("exposure.txt")
        .split_whitespace()
        .map(|s| s.parse().expect("number"))
        .collect();
    assert_close(&stops, &[0.0, 2.0, 4.0], 1e-9);

    // Frames: the JPEG's sRGB code linearised by hand, re-encoded as linear^(1/2.2), 16 bits.
    let jpeg = |name: &str| -> Vec<f64> {
        let img = image::open(tmp.path().join("scene1").join(name))
            .expect("jpeg")
            .to_rgb8();
        img.into_raw().iter().map(|&v| v as f64 / 255.0).collect()
    };
    let srgb_decode = |v: f64| {
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    let frames: Vec<Vec<f64>> = ["frame_1.tif", "frame_2.tif", "frame_3.tif"]
        .iter()
        .map(|n| {
            let (w, h, v) = read_u16_tiff(&set.join(n));
            assert_eq!((w, h), (W, H));
            v
        })
        .collect();
    // frame_1 = the 1/400 s frame = IMG_1.jpg.
    for (frame, src) in frames.iter().zip(["IMG_1.jpg", "IMG_0.jpg", "IMG_2.jpg"]) {
        for (l, c) in frame.iter().zip(jpeg(src)) {
            let want = srgb_decode(c).powf(1.0 / 2.2);
            // f32 arithmetic in the library may round to the neighbouring code.
            assert!((l - want).abs() <= 1.0 / 65535.0 + 1e-9, "{l} vs {want}");
        }
    }

    // HDRImg.hdr against Kalantari's triangle weights computed here from the written frames:
    // w from the middle frame's value I: short (I−½)⁺/½, middle I/½ or (1−I)/½, long (½−I)⁺/½;
    // H = Σ w L^2.2 / 2^s / Σ w.
    let gt = read_rgbe(&set.join("HDRImg.hdr"));
    assert_eq!(gt.len(), W * H * 3);
    let mut want = vec![0.0; gt.len()];
    for (k, v) in want.iter_mut().enumerate() {
        let i = frames[1][k];
        let w = [
            (i - 0.5).max(0.0) / 0.5,
            if i < 0.5 { i / 0.5 } else { (1.0 - i) / 0.5 },
            (0.5 - i).max(0.0) / 0.5,
        ];
        let hsum: f64 = (0..3)
            .map(|j| w[j] * frames[j][k].powf(2.2) / stops[j].exp2())
            .sum();
        *v = hsum / (w[0] + w[1] + w[2]);
    }
    // RGBE shares one exponent per pixel with 8 mantissa bits: the error of each channel is
    // below 2^-8 of the pixel's largest channel (truncation; 2^-7 allows rounding either way).
    let mut worst: f64 = 0.0;
    for (p, q) in gt.chunks_exact(3).zip(want.chunks_exact(3)) {
        let m = q.iter().copied().fold(0.0, f64::max).max(1e-6);
        for c in 0..3 {
            worst = worst.max((p[c] - q[c]).abs() / m);
        }
    }
    assert!(worst < 1.0 / 128.0, "worst relative error {worst}");

    // And the merge recovers the scene: radiance · 16 (the stop-0 frame is 1/400 s, so the
    // field's unit is the white of radiance · 16/400) where no frame is clipped or near black.
    let scale = 16.0 / 400.0;
    let (mut n, mut sum_err) = (0, 0.0);
    for y in 0..H {
        for x in 0..W {
            for (c, r) in radiance(x, y).iter().enumerate() {
                let k = (y * W + x) * 3 + c;
                let mid = frames[1][k];
                if (0.2..0.8).contains(&mid) {
                    sum_err += ((gt[k] - r * scale) / (r * scale)).abs();
                    n += 1;
                }
            }
        }
    }
    assert!(n > 100, "{n} well-exposed samples");
    assert!(
        sum_err / (n as f64) < 0.03,
        "mean relative error {}",
        sum_err / n as f64
    );
}

#[test]
fn the_bracket_test_set_reads_as_kalantari_and_eval_scores_it() {
    use hdrsynth::data::layout::{self, LayoutKind};
    use hdrsynth::eval::evaluate::{self, EvalOptions, Network2};
    use hdrsynth::io::Image;
    let tmp = tempfile::tempdir().expect("tmp");
    bracket_folder(tmp.path());
    let beside = tempfile::tempdir().expect("tmp"); // outputs inside the input are refused
    let out = beside.path().join("out");
    let opts = BracketOptions {
        scan: ScanOptions::default(),
        response: ResponseChoice::Declared(Response::Srgb),
        align: None,
        // Written as the field's linear^(1/2.2), which the hand merges below read with γ 2.2.
        encode: EncodeSpec::Field,
        ..BracketOptions::default()
    };
    testset::build(tmp.path(), &opts, &out).expect("build");
    let info = layout::detect(&out).expect("detect");
    assert_eq!(info.layout, LayoutKind::Kalantari);
    assert_eq!(info.sets.len(), 1);
    assert_eq!(info.sets[0].evs, vec![-2.0, 0.0, 2.0]);
    // A stand-in network that merges by hand in hdrsynth's unit (1 = the reference's white):
    // the field's unit is the stop-0 frame's, 4× the reference's, and eval must convert.
    let method = Network2 {
        description: "hand triangle merge".into(),
        infer: Box::new(|f: [&Image; 3], times: [f32; 3], _| {
            assert_eq!(times, [0.25, 1.0, 4.0]);
            let data = (0..f[1].data.len())
                .map(|k| {
                    let i = f[1].data[k] as f64;
                    let w = [
                        (i - 0.5).max(0.0) / 0.5,
                        if i < 0.5 { i / 0.5 } else { (1.0 - i) / 0.5 },
                        (0.5 - i).max(0.0) / 0.5,
                    ];
                    let h: f64 = (0..3)
                        .map(|j| w[j] * (f[j].data[k] as f64).powf(2.2) / times[j] as f64)
                        .sum();
                    (h / (w[0] + w[1] + w[2])) as f32
                })
                .collect();
            Ok(Image::from_vec(f[1].width, f[1].height, data))
        }),
    };
    let r = evaluate::evaluate(
        &out,
        &method,
        &tmp.path().join("eval"),
        &EvalOptions::default(),
    )
    .expect("eval");
    assert_eq!(r.rows.len(), 1);
    // Only RGBE rounding separates the two: PSNR-L far above any network's.
    assert!(r.rows[0].scores.psnr_l > 50.0, "{:?}", r.rows[0].scores);
    // The same stand-in off by the field's unit factor 4 scores far lower: the unit matters.
    let wrong = Network2 {
        description: "field unit".into(),
        infer: Box::new(|f: [&Image; 3], _, _| Ok(f[1].map(|v| v.powf(2.2) / 4.0))),
    };
    let r2 = evaluate::evaluate(
        &out,
        &wrong,
        &tmp.path().join("eval2"),
        &EvalOptions::default(),
    )
    .expect("eval");
    assert!(r2.rows[0].scores.psnr_l < r.rows[0].scores.psnr_l - 20.0);
}

fn per_image_rows(path: &Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(path)
        .expect("csv")
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

#[test]
fn testset_brackets_through_the_binary_then_eval_scores_checkpoints() {
    use std::process::Command;
    let tmp = tempfile::tempdir().expect("tmp");
    let src = tmp.path().join("phone");
    bracket_folder(&src);
    let out = tmp.path().join("testset");
    let o = Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
        .args(["testset", "--brackets"])
        .arg(&src)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("run");
    let text = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{text}");
    assert!(text.contains("Debevec"), "{text}");
    assert!(out.join("crf_debevec.csv").is_file());
    let record = std::fs::read_to_string(out.join("scene1/brackets.toml")).expect("record");
    assert!(record.contains("Debevec"), "{record}");

    // Network-2 (EV −2/0/+2) against HDRImg.hdr.
    let run2 = tmp.path().join("net2");
    train_tiny(
        &run2,
        "kind = \"wu\"\nbase_width = 4\nres_blocks = 1",
        "[-2.0, 0.0, 2.0]",
    );
    let e2 = tmp.path().join("eval2");
    let st = Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
        .args(["eval", "--quiet", "--checkpoint"])
        .arg(&run2)
        .arg("--testset")
        .arg(&out)
        .arg("--out")
        .arg(&e2)
        .status()
        .expect("run");
    assert!(st.success());
    let rows = per_image_rows(&e2.join("per_image.csv"));
    assert_eq!(rows.len(), 1);
    assert!(
        rows[0][1..7]
            .iter()
            .all(|v| v.parse::<f64>().is_ok_and(f64::is_finite)),
        "{rows:?}"
    );

    // Network-1: the frames are static (brackets.toml marks them), Mertens reference from them.
    let run1 = tmp.path().join("net1");
    train_tiny(
        &run1,
        "kind = \"blend_unet\"\nbase_width = 4\ndepth = 2\nbatch_norm = true",
        "[-3.0, 0.0]",
    );
    let e1 = tmp.path().join("eval1");
    let o = Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
        .args(["eval", "--quiet", "--checkpoint"])
        .arg(&run1)
        .arg("--testset")
        .arg(&out)
        .arg("--out")
        .arg(&e1)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows = per_image_rows(&e1.join("per_image.csv"));
    assert_eq!(rows.len(), 1);
    assert!(
        rows[0][1..7]
            .iter()
            .all(|v| v.parse::<f64>().is_ok_and(f64::is_finite)),
        "{rows:?}"
    );
}
