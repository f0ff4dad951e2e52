//! Test sets with moving subjects, built from a generated dataset's linear frames
//! (`testset::dynamic`), and PSNR-T over the moving pixels that `eval` reports for them.

mod common;

use hdrsynth::data::layout;
use hdrsynth::data::testset::{self, TestsetOptions};
use hdrsynth::eval::evaluate::{self, Classical, ClassicalMerge, EvalOptions};
use hdrsynth::io::{Image, read_image};
use hdrsynth::sensor::profile::SensorProfile;
use std::path::Path;

fn canon() -> SensorProfile {
    SensorProfile::load(&SensorProfile::shipped_dir().join("canon_eos_550d.toml")).expect("profile")
}

fn options() -> TestsetOptions {
    TestsetOptions {
        isos: vec![400.0],
        evs: vec![-2.0, 0.0, 2.0],
        seed: 5,
        ..TestsetOptions::default()
    }
}

fn png(path: &Path) -> Image {
    read_image(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// μ-law as the field writes it: log(1 + 5000 x) / log(5001), unclipped (HDR-Transformer's
/// `range_compressor`).
fn mu(x: f32) -> f64 {
    (1.0 + 5000.0 * x as f64).ln() / 5001f64.ln()
}

#[test]
fn moving_scenes_render_each_frame_at_its_own_time_and_agree_with_the_static_build_elsewhere() {
    let tmp = tempfile::tempdir().expect("tmp");
    let generated = tmp.path().join("gen");
    common::generate(&generated, 11, 3, (96, 64), "[-2.0, 0.0, 2.0]");
    // The same scenes' reference radiance as plain radiance maps, named as the sets.
    let maps = tmp.path().join("maps");
    std::fs::create_dir_all(&maps).expect("mkdir");
    let sets = layout::detect(&generated).expect("generated").sets;
    for s in &sets {
        std::fs::copy(
            s.dir.join("hdr_gt.exr"),
            maps.join(format!("{}.exr", s.name)),
        )
        .expect("copy");
    }
    let (dyn_out, static_out) = (tmp.path().join("dyn"), tmp.path().join("static"));
    let built = testset::build(&generated, &canon(), &options(), &dyn_out).expect("dynamic build");
    assert!(built.dynamic && built.sets.len() == 3, "{:?}", built.notes);
    testset::build(&maps, &canon(), &options(), &static_out).expect("static build");

    let mut moved = 0usize;
    for s in &sets {
        let name = format!("{}_iso400", s.name);
        let (d, st) = (dyn_out.join(&name), static_out.join(&name));
        // The static frames, clean frames and ground truth are the static build's, to the byte.
        for f in [
            "static/ev-2.png",
            "static/ev+0.png",
            "static/ev+2.png",
            "static/clean_ev-2.png",
            "hdr_gt.exr",
            "dynamic/ev+0.png",
        ] {
            assert_eq!(
                std::fs::read(d.join(f)).expect("dynamic file"),
                std::fs::read(st.join(f)).expect("static file"),
                "{name}/{f}"
            );
        }
        for tag in ["ev-2", "ev+2"] {
            let mask = png(&d.join(format!("dynamic/mask_{tag}.png")));
            let from_engine = png(&s.dir.join(format!("dynamic/mask_{tag}.png")));
            assert_eq!(mask.data, from_engine.data, "{name}: the generator's mask");
            let (still, moving) = (
                png(&d.join(format!("static/{tag}.png"))),
                png(&d.join(format!("dynamic/{tag}.png"))),
            );
            let mut differs_inside = 0usize;
            for ((a, b), m) in still
                .data
                .chunks_exact(3)
                .zip(moving.data.chunks_exact(3))
                .zip(mask.data.chunks_exact(3))
            {
                if m[0] == 0.0 {
                    assert_eq!(a, b, "{name} {tag}: a still pixel differs");
                } else {
                    moved += 1;
                    differs_inside += usize::from(a != b);
                }
            }
            let inside = mask.data.chunks_exact(3).filter(|m| m[0] > 0.0).count();
            assert!(
                inside == 0 || differs_inside * 4 > inside,
                "{name} {tag}: {differs_inside} of {inside} moving pixels differ"
            );
        }
        let meta = std::fs::read_to_string(d.join("meta.toml")).expect("meta");
        assert!(!meta.contains("subjects = 0"), "{meta}");
    }
    assert!(moved > 100, "the scenes moved: {moved} masked pixels");
}

#[test]
fn eval_reports_psnr_t_over_the_union_of_the_motion_masks() {
    let tmp = tempfile::tempdir().expect("tmp");
    let generated = tmp.path().join("gen");
    common::generate(&generated, 12, 2, (96, 64), "[-2.0, 0.0, 2.0]");
    let out = tmp.path().join("dyn");
    testset::build(&generated, &canon(), &options(), &out).expect("build");
    let merge = ClassicalMerge::for_testset(Classical::Triangle, &out).expect("curve");
    let ev = tmp.path().join("eval");
    let summary = evaluate::evaluate(&out, &merge, &ev, &EvalOptions::default()).expect("eval");
    let rows = hdrsynth::eval::report::read_per_image(&ev.join("per_image.csv")).expect("csv");
    assert_eq!(rows.len(), 2);
    for row in &rows {
        let set = out.join(&row.set);
        let gt = read_image(&set.join("hdr_gt.exr")).expect("gt");
        let pred = read_image(&ev.join(format!("{}.exr", row.set))).expect("output");
        let masks: Vec<Image> = ["ev-2", "ev+0", "ev+2"]
            .iter()
            .map(|t| png(&set.join(format!("dynamic/mask_{t}.png"))))
            .collect();
        let (mut se, mut n) = (0.0f64, 0usize);
        for p in 0..gt.data.len() / 3 {
            if masks.iter().any(|m| m.data[3 * p] > 0.5) {
                n += 1;
                for c in 0..3 {
                    let d = mu(gt.data[3 * p + c]) - mu(pred.data[3 * p + c]);
                    se += d * d;
                }
            }
        }
        let by_hand = 10.0 * (1.0 / (se / (3 * n) as f64)).log10();
        let reported = row.psnr_t_moving.expect("a moving PSNR-T");
        assert!(
            (reported - by_hand).abs() < 1e-6,
            "{}: reported {reported}, by hand {by_hand} over {n} pixels",
            row.set
        );
        // The triangle merge ghosts where subjects moved: worse there than over the image.
        assert!(reported < row.psnr_t - 1.0, "{row:?}");
    }
    let moving = summary
        .summary
        .iter()
        .find(|m| m.metric == "psnr_t_moving")
        .expect("summarised");
    assert_eq!(moving.n, 2);
}
