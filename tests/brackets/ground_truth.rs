//! The ground truth's merge and its frames (`--gt-frames`): what all frames recover, a black
//! floor kept out, the inputs' noise kept out, and what a denoised reference scores against it.

use crate::common::srgb;
use crate::helpers::{
    Spatial, bracket_folder, exposure_txt, noisy_png_bracket, png_bracket, ramp_scene, read_rgbe,
    srgb_opts,
};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::testset::{self, BracketOptions, GtFrames, InputChoice};
use hdrsynth::sensor::profile::Response;
use std::path::Path;

#[test]
fn ground_truth_from_all_frames_recovers_what_the_inputs_clip_or_lose_in_the_dark() {
    let tmp = tempfile::tempdir().expect("tmp");
    let stops = [0.0, 2.0, 4.0, 6.0, 8.0, 10.0];
    png_bracket(&tmp.path().join("ramp"), 80, 12, &ramp_scene, &stops);
    let beside = tempfile::tempdir().expect("tmp");
    let build = |gt: GtFrames, name: &str| {
        let out = beside.path().join(name);
        let b = testset::build(
            tmp.path(),
            &srgb_opts(InputChoice::Indices([1, 2, 3]), gt),
            &out,
        )
        .expect("build");
        (b, read_rgbe(&out.join("ramp/HDRImg.hdr")))
    };
    let (b3, gt3) = build(GtFrames::Inputs, "three");
    let (b6, gt6) = build(GtFrames::All, "all");
    assert_eq!(b3.sets[0].ground_truth.len(), 3);
    assert_eq!(b6.sets[0].ground_truth.len(), 6);
    assert!(b6.sets[0].dropped.is_empty());
    assert!(
        b6.sets[0].gt_merge.contains("· t"),
        "{}",
        b6.sets[0].gt_merge
    );
    let shortest = &b6.sets[0].ground_truth[0];
    assert!(!shortest.input && shortest.stop == -2.0, "{shortest:?}");
    // The inputs and exposure.txt are the same either way.
    assert_eq!(exposure_txt(&beside.path().join("all/ramp")), "0\n2\n4\n");
    // The truth in the field's unit: the shortest input (stop 2) has white 1, so H = L · 2^2.
    let err = |gt: &[f64], cols: std::ops::Range<usize>| -> f64 {
        let (mut sum, mut n) = (0.0, 0);
        for y in 0..12 {
            for x in cols.clone() {
                let truth = ramp_scene(x, y) * 4.0;
                sum += ((gt[(y * 80 + x) * 3 + 1] - truth) / truth).abs();
                n += 1;
            }
        }
        sum / n as f64
    };
    // Clipped in every input: log radiance ≥ −2.07 (columns 72…79).
    let bright = 72..80;
    // A few codes at most in the longest input (stop 6): log radiance ≤ −15.3 (columns 0…15),
    // yet at least 6 codes in the stop-10 frame: log radiance ≥ −19.
    let dark = 0..16;
    // Well exposed in the inputs' reference (stop 4): codes 30…230.
    let mid = 40..56;
    let (b3e, b6e) = (err(&gt3, bright.clone()), err(&gt6, bright));
    let (d3e, d6e) = (err(&gt3, dark.clone()), err(&gt6, dark));
    let (m3e, m6e) = (err(&gt3, mid.clone()), err(&gt6, mid));
    eprintln!(
        "mean relative error, three inputs vs all frames: clipped {b3e:.4} vs {b6e:.4}, dark \
         {d3e:.4} vs {d6e:.4}, well exposed {m3e:.4} vs {m6e:.4}"
    );
    assert!(b3e > 0.3 && b6e < 0.01, "clipped: {b3e} vs {b6e}");
    assert!(
        d3e > 0.2 && d6e < d3e / 4.0 && d6e < 0.05,
        "dark: {d3e} vs {d6e}"
    );
    assert!(m3e < 0.02 && m6e < 0.02, "well exposed: {m3e} vs {m6e}");
}

#[test]
fn a_short_frames_black_floor_does_not_lift_the_dark_regions_of_the_merge() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("floor");
    std::fs::create_dir_all(&dir).expect("mkdir");
    // Stops 0, 2, 4, 6, 8; the two shortest frames never go below code 8 (a black floor: flare
    // or an offset). Scene: log radiance −13 … −9 over 40 columns, codes 8 (the floor) in
    // both short frames, mid codes in the stop-8 frame.
    let stops = [0.0f64, 2.0, 4.0, 6.0, 8.0];
    let scene = |x: usize| (-13.0 + 4.0 * x as f64 / 39.0).exp2();
    for (i, s) in stops.iter().enumerate() {
        let mut img = image::RgbImage::new(40, 12);
        for y in 0..12 {
            for x in 0..40 {
                let mut v = (srgb(scene(x) * s.exp2()) * 255.0).round() as u8;
                if i < 2 {
                    v = v.max(8);
                }
                img.put_pixel(x as u32, y, image::Rgb([v, v, v]));
            }
        }
        img.save(dir.join(format!("f{i}.png"))).expect("png");
    }
    std::fs::write(dir.join("exposure.txt"), "0\n2\n4\n6\n8\n").expect("exposure.txt");
    let beside = tempfile::tempdir().expect("tmp");
    let out = beside.path().join("out");
    testset::build(
        tmp.path(),
        &srgb_opts(InputChoice::Indices([2, 3, 4]), GtFrames::All),
        &out,
    )
    .expect("build");
    let gt = read_rgbe(&out.join("floor/HDRImg.hdr"));
    // The floor, code 8, reads as 0.0024 of white: over the stop-0 frame's time (1/16 of the
    // shortest input's) that is 0.039, up to 80× the truth L · 2^4 here. Weighted by its hat
    // alone (0.063) against the stop-8 frame's (≤ 1), it would more than double the dark end;
    // weighted also by its time (1/16 against 16) it moves it by about 1 %.
    let mut worst: f64 = 0.0;
    for x in 0..40 {
        let truth = scene(x) * 16.0;
        worst = worst.max(((gt[x * 3 + 1] - truth) / truth).abs());
    }
    assert!(worst < 0.05, "largest relative error {worst}");
}

/// `--gt-frames others` keeps the inputs' noise out of the ground truth: on a noisy 5-frame
/// ramp (every column one radiance), the ground truth's deviation from its column mean is
/// correlated with the reference input's under `all` (the reference is merged in) and not
/// under `others`.
#[test]
fn ground_truth_from_the_other_frames_is_independent_of_the_inputs_noise() {
    let tmp = tempfile::tempdir().expect("tmp");
    let set = tmp.path().join("ramp");
    noisy_png_bracket(
        &set,
        4e-4,
        1e-5,
        &[-2.0, -1.0, 0.0, 1.0, 2.0],
        Spatial::White,
    );
    let beside = tempfile::tempdir().expect("tmp");
    let correlation = |gt: GtFrames, name: &str| {
        let out = beside.path().join(name);
        let opts = srgb_opts(InputChoice::Indices([0, 2, 4]), gt);
        testset::build(tmp.path(), &opts, &out).expect("build");
        let read = |f: &str| hdrsynth::io::read_image(&out.join("ramp").join(f)).expect(f);
        let (hdr, reference) = (read("HDRImg.hdr"), read("frame_2.tif"));
        let (w, h) = (hdr.width, hdr.height);
        let lin = |v: f32| f64::from(v).powf(2.2);
        // Green deviations from each column's mean, where the reference reads mid codes.
        let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
        for x in 0..w {
            let g = |img: &hdrsynth::io::Image, y: usize, f: &dyn Fn(f32) -> f64| {
                f(img.data[(y * w + x) * 3 + 1])
            };
            let id = |v: f32| f64::from(v);
            let code = (0..h).map(|y| g(&reference, y, &id)).sum::<f64>() / h as f64;
            if !(0.2..0.8).contains(&code) {
                continue;
            }
            let mh = (0..h).map(|y| g(&hdr, y, &id)).sum::<f64>() / h as f64;
            let mr = (0..h).map(|y| g(&reference, y, &lin)).sum::<f64>() / h as f64;
            for y in 0..h {
                let (a, b) = (g(&hdr, y, &id) - mh, g(&reference, y, &lin) - mr);
                (sab, saa, sbb) = (sab + a * b, saa + a * a, sbb + b * b);
            }
        }
        let gt_merge = std::fs::read_to_string(out.join("ramp/brackets.toml")).expect("toml");
        (sab / (saa * sbb).sqrt(), gt_merge)
    };
    let (all, _) = correlation(GtFrames::All, "all");
    let (others, record) = correlation(GtFrames::Others, "others");
    assert!(
        all > 0.2,
        "all: the reference's noise in the ground truth, r = {all:.3}"
    );
    assert!(others.abs() < 0.05, "others: r = {others:.3}");
    assert!(record.contains("2 frames that are not inputs"), "{record}");
}

#[test]
fn ground_truth_from_all_frames_of_a_three_frame_set_is_the_inputs_merge() {
    let tmp = tempfile::tempdir().expect("tmp");
    bracket_folder(tmp.path());
    let beside = tempfile::tempdir().expect("tmp");
    let bytes = |gt: GtFrames, name: &str| {
        let out = beside.path().join(name);
        testset::build(tmp.path(), &srgb_opts(InputChoice::Auto, gt), &out).expect("build");
        [
            "HDRImg.hdr",
            "frame_1.tif",
            "frame_2.tif",
            "frame_3.tif",
            "exposure.txt",
            "brackets.toml",
        ]
        .map(|f| std::fs::read(out.join("scene1").join(f)).expect(f))
    };
    assert_eq!(
        bytes(GtFrames::Inputs, "inputs"),
        bytes(GtFrames::All, "all")
    );
}

#[test]
fn against_the_default_ground_truth_a_denoised_reference_beats_the_noisy_one() {
    // Five sRGB frames one stop apart with noise (variance 1e-3·L + 1e-6 in linear, white):
    // the default ground truth merges all five, `--gt-frames inputs` only the three inputs
    // (stops −2, 0, 2). The reference linearised as it is (a network that copies its input)
    // against the reference without noise (a network that denoises it perfectly).
    use hdrsynth::eval::evaluate::Classical;
    use hdrsynth::eval::metrics;
    let stops = [-2.0, -1.0, 0.0, 1.0, 2.0];
    let tmp = tempfile::tempdir().expect("tmp");
    noisy_png_bracket(
        &tmp.path().join("noisy/s"),
        1e-3,
        1e-6,
        &stops,
        Spatial::White,
    );
    noisy_png_bracket(
        &tmp.path().join("clean/s"),
        0.0,
        0.0,
        &stops,
        Spatial::White,
    );
    let beside = tempfile::tempdir().expect("tmp");
    let build = |what: &str, gt_frames: GtFrames| {
        let out = beside.path().join(format!("{what}_{gt_frames:?}"));
        let opts = BracketOptions {
            response: ResponseChoice::Declared(Response::Srgb),
            gt_frames,
            ..BracketOptions::default()
        };
        testset::build(&tmp.path().join(what), &opts, &out).expect("build");
        out.join("s")
    };
    let copy = |set: &Path| {
        let frames: [hdrsynth::io::Image; 3] = std::array::from_fn(|k| {
            hdrsynth::io::read_image(&set.join(format!("frame_{}.tif", k + 1))).expect("frame")
        });
        Classical::Copy
            .merge(&frames, [0.25, 1.0, 4.0], &Response::Srgb)
            .expect("copy")
    };
    assert_eq!(BracketOptions::default().gt_frames, GtFrames::All);
    let clean = copy(&build("clean", GtFrames::All));
    let mut scores = Vec::new();
    for gt_frames in [GtFrames::All, GtFrames::Inputs] {
        let set = build("noisy", gt_frames);
        assert_eq!(exposure_txt(&set).split_whitespace().count(), 3);
        // eval's unit: 1 = the reference's white (stop 2 above the shortest input).
        let gt = hdrsynth::io::read_image(&set.join("HDRImg.hdr"))
            .expect("gt")
            .map(|v| v * 4.0);
        let noisy = copy(&set);
        let (n, c) = (
            metrics::psnr_mu(&gt, &noisy).expect("psnr"),
            metrics::psnr_mu(&gt, &clean).expect("psnr"),
        );
        eprintln!("ground truth {gt_frames:?}: PSNR-T noisy reference {n:.2}, denoised {c:.2}");
        scores.push((n, c));
    }
    let ((all_noisy, all_clean), (in_noisy, in_clean)) = (scores[0], scores[1]);
    assert!(
        all_clean > all_noisy + 1.0,
        "all frames: denoised {all_clean} vs noisy {all_noisy}"
    );
    // The inputs' own merge holds the reference's noise where the reference is well exposed,
    // so against it removing that noise earns less: the gap the default ground truth shows
    // shrinks by more than a decibel.
    assert!(
        all_clean - all_noisy > in_clean - in_noisy + 1.0,
        "denoising gains {:.2} dB against all frames, {:.2} against the inputs",
        all_clean - all_noisy,
        in_clean - in_noisy
    );
}
