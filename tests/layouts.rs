//! Dataset layout detection and set loading, on small fixtures written by the tests.

use hdrsynth::data::layout::{self, GroundTruthKind, LayoutKind, SetInfo};
use hdrsynth::io::{self, BitDepth, Image};
use std::path::{Path, PathBuf};
use tempfile::TempDir;

const W: usize = 16;
const H: usize = 12;

/// An LDR test pattern in [0, 1], different per `seed`.
fn ldr(seed: usize) -> Image {
    Image::from_fn(W, H, |x, y| {
        let v = ((x * 7 + y * 13 + seed * 29) % 97) as f32 / 96.0;
        [v, 1.0 - v, (v * 0.5 + 0.25 * seed as f32).fract()]
    })
}

/// A linear HDR test pattern spanning ~12 stops.
fn hdr(seed: usize) -> Image {
    Image::from_fn(W, H, |x, y| {
        let t = (x + y * W + seed) as f32 / (W * H) as f32;
        let v = 0.01 * 2f32.powf(12.0 * t);
        [v, 0.5 * v, 2.0 * v]
    })
}

fn mkdir(p: &Path) -> PathBuf {
    std::fs::create_dir_all(p).unwrap();
    p.to_path_buf()
}

fn write(p: &Path, text: &str) {
    std::fs::write(p, text).unwrap();
}

fn assert_close(a: &Image, b: &Image, tol: f32, what: &str) {
    assert_eq!((a.width, a.height), (b.width, b.height), "{what}: size");
    for (i, (x, y)) in a.data.iter().zip(&b.data).enumerate() {
        assert!(
            (x - y).abs() <= tol,
            "{what}: value {i}: {x} vs {y} (tol {tol})"
        );
    }
}

/// RGBE (.hdr) tolerance: an 8-bit mantissa per channel with an exponent shared by the pixel,
/// so the error is relative to the pixel's largest channel.
fn assert_close_rgbe(a: &Image, b: &Image, what: &str) {
    assert_eq!((a.width, a.height), (b.width, b.height), "{what}: size");
    for (i, (pa, pb)) in a.pixels().zip(b.pixels()).enumerate() {
        let m = pb.iter().fold(0f32, |m, v| m.max(v.abs()));
        for c in 0..3 {
            assert!(
                (pa[c] - pb[c]).abs() <= m / 100.0,
                "{what}: pixel {i} channel {c}: {} vs {}",
                pa[c],
                pb[c]
            );
        }
    }
}

const TOL16: f32 = 0.6 / 65535.0;
const TOL8: f32 = 0.6 / 255.0;

/// A Kalantari set: three 16-bit TIFFs named so that name order = exposure order.
fn kalantari_set(dir: &Path, stops: &str) {
    mkdir(dir);
    for (i, name) in ["262A0898.tif", "262A0899.tif", "262A0900.tif"]
        .iter()
        .enumerate()
    {
        io::write_ldr(&dir.join(name), &ldr(i), BitDepth::Sixteen).unwrap();
    }
    write(&dir.join("exposure.txt"), stops);
    io::write_hdr(&dir.join("HDRImg.hdr"), &hdr(0)).unwrap();
}

/// A Wu set: frames `input_N_aligned.<ext>` with pattern seed N, refs with seed 10+N.
fn wu_set(dir: &Path, ext: &str, input_exp: &str, refs: bool) {
    mkdir(dir);
    for n in 1..=3 {
        io::write_ldr(
            &dir.join(format!("input_{n}_aligned.{ext}")),
            &ldr(n),
            BitDepth::Sixteen,
        )
        .unwrap();
        if refs {
            io::write_ldr(
                &dir.join(format!("ref_{n}_aligned.{ext}")),
                &ldr(10 + n),
                BitDepth::Sixteen,
            )
            .unwrap();
        }
    }
    write(&dir.join("input_exp.txt"), input_exp);
    if refs {
        write(&dir.join("ref_exp.txt"), input_exp);
    }
    io::write_hdr(&dir.join("ref_hdr_aligned.hdr"), &hdr(1)).unwrap();
}

/// An 8-bit RGBA PNG with constant alpha; returns the RGB code values written.
fn write_rgba_png(path: &Path, seed: usize) -> Image {
    let src = ldr(seed);
    let mut rgba = image::RgbaImage::new(W as u32, H as u32);
    let mut expect = Image::new(W, H);
    for y in 0..H {
        for x in 0..W {
            let p = src.get(x, y);
            let q = p.map(|v| (v * 255.0).round() as u8);
            rgba.put_pixel(x as u32, y as u32, image::Rgba([q[0], q[1], q[2], 255]));
            expect.set(x, y, q.map(|v| v as f32 / 255.0));
        }
    }
    rgba.save(path).unwrap();
    expect
}

/// A Dataset-1 set; input_N.png has pattern seed N, hdr_gt.png seed 9.
fn paper1_set(dir: &Path, rgba: bool) {
    mkdir(dir);
    for n in 1..=4 {
        let p = dir.join(format!("input_{n}.png"));
        if rgba {
            write_rgba_png(&p, n);
        } else {
            io::write_ldr(&p, &ldr(n), BitDepth::Eight).unwrap();
        }
    }
    if rgba {
        write_rgba_png(&dir.join("hdr_gt.png"), 9);
    } else {
        io::write_ldr(&dir.join("hdr_gt.png"), &ldr(9), BitDepth::Eight).unwrap();
    }
}

fn names(sets: &[SetInfo]) -> Vec<&str> {
    sets.iter().map(|s| s.name.as_str()).collect()
}

fn err_string<T: std::fmt::Debug>(r: hdrsynth::Result<T>) -> String {
    r.expect_err("expected an error").to_string()
}

#[test]
fn kalantari_nested_training_test_folders() {
    let tmp = TempDir::new().unwrap();
    let root = tmp.path();
    kalantari_set(&root.join("Training/001"), "0\n2\n4\n");
    kalantari_set(&root.join("Training/002"), "0 3 6");
    kalantari_set(&root.join("Test/001"), "-1.5\n0.5\n2.5");
    mkdir(&root.join("empty"));
    write(&root.join("README.txt"), "not a set");

    let info = layout::detect(root).unwrap();
    assert_eq!(info.layout, LayoutKind::Kalantari);
    assert_eq!(
        names(&info.sets),
        ["Test/001", "Training/001", "Training/002"]
    );
    assert_eq!(info.skipped.len(), 1, "{:?}", info.skipped);
    assert_eq!(info.skipped[0].0, root.join("empty"));
    assert!(info.skipped[0].1.contains("no image"), "{:?}", info.skipped);

    let s = &info.sets[1];
    assert_eq!((s.width, s.height), (W, H));
    assert_eq!(s.evs, [-2.0, 0.0, 2.0]);
    assert_eq!(s.reference, 1);
    assert!(s.static_frames.is_empty());
    let dyn_names: Vec<_> = s
        .dynamic_frames
        .iter()
        .map(|p| p.file_name().unwrap().to_str().unwrap())
        .collect();
    assert_eq!(dyn_names, ["262A0898.tif", "262A0899.tif", "262A0900.tif"]);
    let gt = s.ground_truth.as_ref().unwrap();
    assert_eq!(gt.kind, GroundTruthKind::Linear);
    assert_eq!(gt.path, root.join("Training/001/HDRImg.hdr"));
    assert_eq!(info.sets[2].evs, [-3.0, 0.0, 3.0]);
    assert_eq!(info.sets[0].evs, [-2.0, 0.0, 2.0]);

    let loaded = layout::load_set(s).unwrap();
    assert!(loaded.static_frames.is_empty());
    assert_eq!(loaded.dynamic_frames.len(), 3);
    for (i, f) in loaded.dynamic_frames.iter().enumerate() {
        assert_close(f, &ldr(i), TOL16, &format!("frame {i}"));
    }
    // In hdrsynth's unit: HDRImg.hdr is in the unit of stop 0 as written ("0 2 4": the shortest
    // frame), the reference is 2 stops above it, so × 2^2 (docs/layout.md).
    assert_close_rgbe(
        loaded.ground_truth.as_ref().unwrap(),
        &hdr(0).map(|v| 4.0 * v),
        "GT",
    );
}

#[test]
fn kalantari_root_is_one_set() {
    let tmp = TempDir::new().unwrap();
    let dir = tmp.path().join("scene_a");
    kalantari_set(&dir, "0\n2\n4");
    let info = layout::detect(&dir).unwrap();
    assert_eq!(info.layout, LayoutKind::Kalantari);
    assert_eq!(names(&info.sets), ["scene_a"]);
    assert_eq!(info.sets[0].dir, dir);
}

#[test]
fn kalantari_missing_exposure_file_is_an_error_naming_it() {
    let tmp = TempDir::new().unwrap();
    let root = tmp.path();
    kalantari_set(&root.join("scene_001"), "0 2 4");
    kalantari_set(&root.join("scene_003"), "0 2 4");
    std::fs::remove_file(root.join("scene_003/exposure.txt")).unwrap();
    let msg = err_string(layout::detect(root));
    let path = root.join("scene_003/exposure.txt");
    assert!(msg.contains(&path.display().to_string()), "{msg}");
    assert!(msg.contains("missing"), "{msg}");
}

#[test]
fn kalantari_bad_exposure_files() {
    let tmp = TempDir::new().unwrap();
    let dir = tmp.path().join("s");
    kalantari_set(&dir, "0 2");
    let msg = err_string(layout::detect(&dir));
    assert!(
        msg.contains("exposure.txt") && msg.contains("2 value"),
        "{msg}"
    );

    write(&dir.join("exposure.txt"), "0 two 4");
    let msg = err_string(layout::detect(&dir));
    assert!(
        msg.contains("exposure.txt") && msg.contains("'two'"),
        "{msg}"
    );

    write(&dir.join("exposure.txt"), "4 2 0");
    let msg = err_string(layout::detect(&dir));
    assert!(
        msg.contains("exposure.txt") && msg.contains("increase"),
        "{msg}"
    );
}

#[test]
fn kalantari_wrong_frame_count_and_sizes() {
    let tmp = TempDir::new().unwrap();
    let dir = tmp.path().join("s");
    kalantari_set(&dir, "0 2 4");
    io::write_ldr(&dir.join("zz_extra.tif"), &ldr(5), BitDepth::Sixteen).unwrap();
    let msg = err_string(layout::detect(&dir));
    assert!(msg.contains("found 4 TIFF"), "{msg}");
    std::fs::remove_file(dir.join("zz_extra.tif")).unwrap();

    let odd = Image::new(W + 2, H);
    io::write_ldr(&dir.join("262A0900.tif"), &odd, BitDepth::Sixteen).unwrap();
    let msg = err_string(layout::detect(&dir));
    assert!(msg.contains("262A0900.tif"), "{msg}");
    assert!(msg.contains("18×12") && msg.contains("16×12"), "{msg}");

    io::write_ldr(&dir.join("262A0900.tif"), &ldr(2), BitDepth::Eight).unwrap();
    let msg = err_string(layout::detect(&dir));
    assert!(
        msg.contains("262A0900.tif") && msg.contains("8-bit"),
        "{msg}"
    );
}

#[test]
fn tiffs_without_exposure_file_are_a_broken_kalantari_set() {
    let tmp = TempDir::new().unwrap();
    let dir = mkdir(&tmp.path().join("scene"));
    for i in 0..3 {
        io::write_ldr(&dir.join(format!("f{i}.tif")), &ldr(i), BitDepth::Sixteen).unwrap();
    }
    let msg = err_string(layout::detect(tmp.path()));
    assert!(
        msg.contains(&dir.join("exposure.txt").display().to_string()),
        "{msg}"
    );
    assert!(msg.contains("missing"), "{msg}");
}

#[test]
fn wu_sets_with_refs_and_gt_choice() {
    let tmp = TempDir::new().unwrap();
    let root = tmp.path();
    wu_set(&root.join("001"), "tif", "-2 0 2\n", true);
    io::write_hdr(&root.join("001/ref_hdr_aligned_linear.hdr"), &hdr(2)).unwrap();
    // Frame 1 brightest: frames must come back sorted by ascending EV.
    wu_set(&root.join("002"), "png", "2.0\n0.0\n-2.0\n", false);
    std::fs::rename(
        root.join("002/ref_hdr_aligned.hdr"),
        root.join("002/ref_hdr_aligned_linear.hdr"),
    )
    .unwrap();

    let info = layout::detect(root).unwrap();
    assert_eq!(info.layout, LayoutKind::Wu);
    assert_eq!(names(&info.sets), ["001", "002"]);

    let a = &info.sets[0];
    assert_eq!((a.width, a.height), (W, H));
    assert_eq!(a.evs, [-2.0, 0.0, 2.0]);
    assert_eq!(a.reference, 1);
    let file = |p: &PathBuf| p.file_name().unwrap().to_str().unwrap().to_string();
    assert_eq!(
        a.dynamic_frames.iter().map(file).collect::<Vec<_>>(),
        [
            "input_1_aligned.tif",
            "input_2_aligned.tif",
            "input_3_aligned.tif"
        ]
    );
    assert_eq!(
        a.static_frames.iter().map(file).collect::<Vec<_>>(),
        [
            "ref_1_aligned.tif",
            "ref_2_aligned.tif",
            "ref_3_aligned.tif"
        ]
    );
    let gt = a.ground_truth.as_ref().unwrap();
    assert_eq!(gt.kind, GroundTruthKind::Linear);
    assert_eq!(file(&gt.path), "ref_hdr_aligned.hdr");
    // The unused candidate is reported.
    assert!(
        info.skipped
            .iter()
            .any(|(p, r)| p.ends_with("001/ref_hdr_aligned_linear.hdr")
                && r.contains("ref_hdr_aligned.hdr")),
        "{:?}",
        info.skipped
    );

    let b = &info.sets[1];
    assert_eq!(b.evs, [-2.0, 0.0, 2.0]);
    assert_eq!(b.reference, 1);
    assert!(b.static_frames.is_empty());
    assert_eq!(
        b.dynamic_frames.iter().map(file).collect::<Vec<_>>(),
        [
            "input_3_aligned.png",
            "input_2_aligned.png",
            "input_1_aligned.png"
        ]
    );
    assert_eq!(
        file(&b.ground_truth.as_ref().unwrap().path),
        "ref_hdr_aligned_linear.hdr"
    );

    let la = layout::load_set(a).unwrap();
    for i in 0..3 {
        assert_close(&la.dynamic_frames[i], &ldr(i + 1), TOL16, "wu input");
        assert_close(&la.static_frames[i], &ldr(11 + i), TOL16, "wu ref");
    }
    // Wu's code subtracts the smallest stop: "-2 0 2" puts the GT in the shortest frame's unit,
    // 2 stops below the reference, so × 2^2 in hdrsynth's unit.
    assert_close_rgbe(
        la.ground_truth.as_ref().unwrap(),
        &hdr(1).map(|v| 4.0 * v),
        "wu GT",
    );
    let lb = layout::load_set(b).unwrap();
    for i in 0..3 {
        assert_close(&lb.dynamic_frames[i], &ldr(3 - i), TOL16, "wu input sorted");
    }
}

#[test]
fn wu_errors() {
    let tmp = TempDir::new().unwrap();
    let dir = tmp.path().join("s");
    wu_set(&dir, "png", "-2 0 2", true);

    std::fs::remove_file(dir.join("input_3_aligned.png")).unwrap();
    let msg = err_string(layout::detect(&dir));
    assert!(
        msg.contains("input_3_aligned") && msg.contains("missing"),
        "{msg}"
    );
    io::write_ldr(&dir.join("input_3_aligned.png"), &ldr(3), BitDepth::Sixteen).unwrap();

    write(&dir.join("ref_exp.txt"), "-3 0 3");
    let msg = err_string(layout::detect(&dir));
    assert!(
        msg.contains("ref_exp.txt") && msg.contains("differ"),
        "{msg}"
    );
    write(&dir.join("ref_exp.txt"), "-2 0 2");

    std::fs::remove_file(dir.join("input_exp.txt")).unwrap();
    let msg = err_string(layout::detect(&dir));
    assert!(
        msg.contains(&dir.join("input_exp.txt").display().to_string()),
        "{msg}"
    );
    assert!(msg.contains("missing"), "{msg}");
    write(&dir.join("input_exp.txt"), "-2 0 2");

    std::fs::rename(
        dir.join("ref_hdr_aligned.hdr"),
        dir.join("ref_hdr_aligned_a.hdr"),
    )
    .unwrap();
    io::write_hdr(&dir.join("ref_hdr_aligned_b.hdr"), &hdr(0)).unwrap();
    let msg = err_string(layout::detect(&dir));
    assert!(msg.contains("several ground-truth candidates"), "{msg}");
}

#[test]
fn paper_dataset1_rgba_constant_alpha() {
    let tmp = TempDir::new().unwrap();
    let root = tmp.path();
    paper1_set(&root.join("scene_1"), true);
    paper1_set(&root.join("scene_2"), false);

    let info = layout::detect(root).unwrap();
    assert_eq!(info.layout, LayoutKind::PaperDataset1);
    assert_eq!(names(&info.sets), ["scene_1", "scene_2"]);
    let s = &info.sets[0];
    assert_eq!((s.width, s.height), (W, H));
    assert_eq!(s.evs, [-3.0, 0.0]);
    assert_eq!(s.reference, 1);
    let file = |p: &PathBuf| p.file_name().unwrap().to_str().unwrap().to_string();
    assert_eq!(
        s.static_frames.iter().map(file).collect::<Vec<_>>(),
        ["input_2.png", "input_1.png"]
    );
    assert_eq!(
        s.dynamic_frames.iter().map(file).collect::<Vec<_>>(),
        ["input_4.png", "input_3.png"]
    );
    let gt = s.ground_truth.as_ref().unwrap();
    assert_eq!(gt.kind, GroundTruthKind::Display);
    assert_eq!(file(&gt.path), "hdr_gt.png");

    let l = layout::load_set(s).unwrap();
    let scratch = TempDir::new().unwrap();
    let expect = |seed| write_rgba_png(&scratch.path().join(format!("expect_{seed}.png")), seed);
    assert_close(&l.static_frames[0], &expect(2), TOL8, "input_2");
    assert_close(&l.static_frames[1], &expect(1), TOL8, "input_1");
    assert_close(&l.dynamic_frames[0], &expect(4), TOL8, "input_4");
    assert_close(&l.dynamic_frames[1], &expect(3), TOL8, "input_3");
    assert_close(l.ground_truth.as_ref().unwrap(), &expect(9), TOL8, "hdr_gt");

    let l2 = layout::load_set(&info.sets[1]).unwrap();
    assert_close(&l2.dynamic_frames[1], &ldr(3), TOL8, "rgb input_3");

    std::fs::remove_file(root.join("scene_2/input_4.png")).unwrap();
    let msg = err_string(layout::detect(root));
    assert!(
        msg.contains("input_4.png") && msg.contains("missing"),
        "{msg}"
    );
}

#[test]
fn truncated_image_fails_load_naming_the_file() {
    let tmp = TempDir::new().unwrap();
    let dir = tmp.path().join("s");
    wu_set(&dir, "png", "-2 0 2", false);
    let victim = dir.join("input_3_aligned.png");
    let bytes = std::fs::read(&victim).unwrap();
    std::fs::write(&victim, &bytes[..bytes.len() / 2]).unwrap();
    let name = victim.display().to_string();
    // The header survives, so detection passes; loading must fail naming the file.
    let info = layout::detect(&dir).unwrap();
    let msg = err_string(layout::load_set(&info.sets[0]));
    assert!(msg.contains(&name), "{msg}");

    // A truncated .hdr ground truth: the header is text, so detection passes.
    let dir = tmp.path().join("k");
    kalantari_set(&dir, "0 2 4");
    let gt = dir.join("HDRImg.hdr");
    let bytes = std::fs::read(&gt).unwrap();
    std::fs::write(&gt, &bytes[..bytes.len() - 100]).unwrap();
    let info = layout::detect(&dir).unwrap();
    let msg = err_string(layout::load_set(&info.sets[0]));
    assert!(msg.contains(&gt.display().to_string()), "{msg}");
}

#[test]
fn load_set_checks_sizes_against_the_set() {
    let tmp = TempDir::new().unwrap();
    let dir = tmp.path().join("s");
    kalantari_set(&dir, "0 2 4");
    let info = layout::detect(&dir).unwrap();
    // The file changes after detection.
    let victim = dir.join("262A0898.tif");
    io::write_ldr(&victim, &Image::new(8, 8), BitDepth::Sixteen).unwrap();
    let msg = err_string(layout::load_set(&info.sets[0]));
    assert!(msg.contains(&victim.display().to_string()), "{msg}");
    assert!(msg.contains("8×8") && msg.contains("16×12"), "{msg}");
}

#[test]
fn mixed_layouts_are_an_error() {
    let tmp = TempDir::new().unwrap();
    let root = tmp.path();
    kalantari_set(&root.join("a"), "0 2 4");
    wu_set(&root.join("b"), "tif", "-2 0 2", false);
    let msg = err_string(layout::detect(root));
    assert!(msg.contains("mixed layouts"), "{msg}");
    assert!(msg.contains("kalantari") && msg.contains("wu"), "{msg}");
}

#[test]
fn empty_folder_has_no_sets() {
    let tmp = TempDir::new().unwrap();
    let msg = err_string(layout::detect(tmp.path()));
    assert!(msg.contains("no sets found"), "{msg}");
    assert!(msg.contains(&tmp.path().display().to_string()), "{msg}");

    mkdir(&tmp.path().join("x/y"));
    write(&tmp.path().join("x/y/notes.txt"), "hi");
    io::write_ldr(&tmp.path().join("pic.png"), &ldr(0), BitDepth::Eight).unwrap();
    let msg = err_string(layout::detect(tmp.path()));
    assert!(msg.contains("no sets found"), "{msg}");

    let missing = tmp.path().join("nope");
    let msg = err_string(layout::detect(&missing));
    assert!(msg.contains(&missing.display().to_string()), "{msg}");
}

#[test]
fn unrecognised_folders_are_skipped_with_a_reason() {
    let tmp = TempDir::new().unwrap();
    let root = tmp.path();
    kalantari_set(&root.join("001"), "0 2 4");
    mkdir(&root.join("previews"));
    io::write_ldr(&root.join("previews/thumb.png"), &ldr(0), BitDepth::Eight).unwrap();
    mkdir(&root.join(".cache"));
    let info = layout::detect(root).unwrap();
    assert_eq!(names(&info.sets), ["001"]);
    assert_eq!(info.skipped.len(), 1, "{:?}", info.skipped);
    assert_eq!(info.skipped[0].0, root.join("previews"));
    assert!(
        info.skipped[0].1.contains("thumb.png"),
        "{:?}",
        info.skipped
    );
}

#[test]
fn info_report_lists_sets_and_skipped() {
    let tmp = TempDir::new().unwrap();
    let root = tmp.path();
    kalantari_set(&root.join("001"), "0\n2\n4");
    kalantari_set(&root.join("002"), "0\n3\n6");
    mkdir(&root.join("docs"));
    let report = hdrsynth::data::layout::info::info_report(root).unwrap();
    assert!(report.contains(&root.display().to_string()), "{report}");
    assert!(report.contains("kalantari"), "{report}");
    assert!(report.contains("sets:    2"), "{report}");
    assert!(
        report.contains("docs") && report.contains("no image files"),
        "{report}"
    );
    assert!(report.contains("16×12"), "{report}");
    assert!(
        report.contains("[-2, 0, +2]") && report.contains("[-3, 0, +3]"),
        "{report}"
    );
    let gt = io::read_image(&root.join("001/HDRImg.hdr")).unwrap();
    let dr = io::dynamic_range_stops(&gt, 0.1, 99.9).unwrap();
    let line = report.lines().find(|l| l.contains("001")).unwrap();
    assert!(line.contains(&format!("{dr:.1} stops")), "{report}");
    assert!(line.contains("0/3") && line.contains("linear"), "{report}");

    let tmp1 = TempDir::new().unwrap();
    paper1_set(&tmp1.path().join("a"), false);
    let report = hdrsynth::data::layout::info::info_report(tmp1.path()).unwrap();
    assert!(report.contains("paper-dataset-1"), "{report}");
    assert!(report.contains("n/a (display-referred GT)"), "{report}");
    assert!(
        report.contains("2/2") && report.contains("[-3, 0]"),
        "{report}"
    );
}

#[test]
fn info_report_summarises_many_sets() {
    let tmp = TempDir::new().unwrap();
    for i in 0..53 {
        kalantari_set(&tmp.path().join(format!("{i:03}")), "0 2 4");
    }
    let report = hdrsynth::data::layout::info::info_report(tmp.path()).unwrap();
    assert!(report.contains("sets:    53"), "{report}");
    assert!(
        report.contains("049") && !report.contains(" 050 "),
        "{report}"
    );
    assert!(report.contains("3 more set(s) not listed"), "{report}");
    assert!(report.contains("summary over all 53 sets"), "{report}");
    assert!(
        report.contains("min 16×12, median 16×12, max 16×12"),
        "{report}"
    );
    assert!(
        report.contains("GT dynamic range (53 set(s) with linear GT)"),
        "{report}"
    );
}

#[test]
fn info_report_errors_name_the_dir() {
    let tmp = TempDir::new().unwrap();
    let msg = format!(
        "{:#}",
        hdrsynth::data::layout::info::info_report(tmp.path()).unwrap_err()
    );
    assert!(msg.contains(&tmp.path().display().to_string()), "{msg}");
    assert!(msg.contains("no sets found"), "{msg}");
}
