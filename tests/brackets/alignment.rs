//! Alignment of hand-held sets: MTB against OpenCV AlignMTB (tools/crf_oracle.py), shifts and
//! crops applied to the inputs and the ground truth's frames.

use crate::common::srgb;
use crate::helpers::{exposure_txt, oracle_dir, read_rgbe, read_u16_tiff, srgb_opts, write_jpeg};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::scan::ScanOptions;
use hdrsynth::capture::testset::{self, BracketOptions, GtFrames, InputChoice};
use hdrsynth::sensor::profile::Response;

#[test]
fn mtb_recovers_known_shifts_as_opencv_align_mtb_does() {
    use hdrsynth::capture::align::{self, MtbOptions};
    let dir = oracle_dir();
    let lines: Vec<Vec<String>> = std::fs::read_to_string(dir.join("mtb_shifts.txt"))
        .expect("shifts")
        .lines()
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect();
    let frames: Vec<hdrsynth::io::Image> = (0..3)
        .map(|i| hdrsynth::io::read_image(&dir.join(format!("mtb_{i}.png"))).expect("png"))
        .collect();
    // The oracle ran AlignMTB(max_bits 4, exclude 4): 160×128 frames are too small for 6 bits.
    let opts = MtbOptions {
        max_bits: 4,
        exclude: 4,
    };
    for (i, l) in lines.iter().enumerate() {
        let n = |k: usize| l[k].parse::<i32>().expect("int");
        let (applied, opencv) = ((n(2), n(3)), (n(5), n(6)));
        let ours = align::mtb_shift(&frames[0], &frames[i], opts);
        assert_eq!(ours, opencv, "frame {i}: ours {ours:?}, OpenCV {opencv:?}");
        // The shift that undoes the applied motion.
        assert_eq!(ours, (-applied.0, -applied.1), "frame {i}");
    }
    // Applying the shifts crops to the region all three cover: x from 5 (frame 2 moved 5 px
    // right) to 157 (frame 1 moved 3 px left), y from 2 to 124 (hand-computed).
    let shifts: Vec<(i32, i32)> = (0..3)
        .map(|i| align::mtb_shift(&frames[0], &frames[i], opts))
        .collect();
    let cropped = align::apply_shifts(&frames, &shifts);
    assert_eq!((cropped[0].width, cropped[0].height), (160 - 8, 128 - 6));
}

#[test]
fn hand_held_sets_are_aligned_by_mtb_and_cropped() {
    use hdrsynth::capture::align::MtbOptions;
    let tmp = tempfile::tempdir().expect("tmp");
    let d = tmp.path().join("handheld");
    std::fs::create_dir_all(&d).expect("mkdir");
    let (w, h) = (160usize, 128usize);
    // Blocks of 8 px with pseudo-random log radiance over 6 stops (a fixed integer hash).
    let scene = |x: i64, y: i64| -> f64 {
        let (bx, by) = (x.div_euclid(8), y.div_euclid(8));
        let k = (bx * 73_856_093) ^ (by * 19_349_663);
        let u = (k.rem_euclid(1000)) as f64 / 1000.0;
        (-6.0 + 6.0 * u).exp2()
    };
    // (file, time, motion of the camera: frame pixel (x, y) shows scene (x − dx, y − dy)).
    for (name, t, (dx, dy)) in [
        ("s.jpg", 0.25, (-1i64, 2i64)),
        ("m.jpg", 1.0, (0, 0)),
        ("l.jpg", 4.0, (2, -1)),
    ] {
        let mut rgb = Vec::with_capacity(w * h * 3);
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                let v = (srgb(scene(x - dx, y - dy) * t * 4.0) * 255.0).round() as u8;
                rgb.extend([v, v, v]);
            }
        }
        write_jpeg(&d.join(name), w as u32, h as u32, &rgb, None);
    }
    std::fs::write(d.join("list.txt"), "s.jpg 4\nm.jpg 1\nl.jpg 0.25\n").expect("list");
    let opts = BracketOptions {
        scan: ScanOptions::default(),
        response: ResponseChoice::Declared(Response::Srgb),
        // 160×128 frames: 4 bits (shifts up to ±15 px) keep the coarsest level 20×16.
        align: Some(MtbOptions {
            max_bits: 4,
            exclude: 4,
        }),
        ..BracketOptions::default()
    };
    let beside = tempfile::tempdir().expect("tmp"); // outputs inside the input are refused
    let built = testset::build(tmp.path(), &opts, &beside.path().join("out")).expect("build");
    let b = &built.sets[0];
    // The shifts undo the motion: short (1, −2), middle 0, long (−2, 1).
    assert_eq!(b.shifts, vec![[1, -2], [0, 0], [-2, 1]]);
    // Common region: x from 1 to 158, y from 1 to 126 (hand-computed from the shifts).
    assert_eq!((b.width, b.height), (157, 125));
    let (tw, th, _) = read_u16_tiff(&beside.path().join("out/handheld/frame_1.tif"));
    assert_eq!((tw, th), (157, 125));
}

#[test]
fn hand_held_ground_truth_from_all_frames_aligns_and_crops_every_frame() {
    use hdrsynth::capture::align::MtbOptions;
    let tmp = tempfile::tempdir().expect("tmp");
    let d = tmp.path().join("handheld4");
    std::fs::create_dir_all(&d).expect("mkdir");
    let (w, h) = (160usize, 128usize);
    let scene = |x: i64, y: i64| -> f64 {
        let (bx, by) = (x.div_euclid(8), y.div_euclid(8));
        let k = (bx * 73_856_093) ^ (by * 19_349_663);
        (-6.0 + 6.0 * (k.rem_euclid(1000)) as f64 / 1000.0).exp2()
    };
    // Four frames, 2 stops apart; the inputs are the last three, the first (shortest) frame
    // moved 3 px left and 2 px down and enters only the ground truth.
    for (name, t, (dx, dy)) in [
        ("a.jpg", 0.0625, (-3i64, 2i64)),
        ("s.jpg", 0.25, (-1, 2)),
        ("m.jpg", 1.0, (0, 0)),
        ("l.jpg", 4.0, (2, -1)),
    ] {
        let mut rgb = Vec::with_capacity(w * h * 3);
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                let v = (srgb(scene(x - dx, y - dy) * t * 4.0) * 255.0).round() as u8;
                rgb.extend([v, v, v]);
            }
        }
        write_jpeg(&d.join(name), w as u32, h as u32, &rgb, None);
    }
    std::fs::write(
        d.join("list.txt"),
        "a.jpg 16\ns.jpg 4\nm.jpg 1\nl.jpg 0.25\n",
    )
    .expect("list");
    let opts = BracketOptions {
        align: Some(MtbOptions {
            max_bits: 4,
            exclude: 4,
        }),
        ..srgb_opts(InputChoice::Indices([1, 2, 3]), GtFrames::All)
    };
    let beside = tempfile::tempdir().expect("tmp");
    let built = testset::build(tmp.path(), &opts, &beside.path().join("out")).expect("build");
    let b = &built.sets[0];
    // The inputs' shifts as with three frames; the extra frame's undoes its motion too.
    assert_eq!(b.shifts, vec![[1, -2], [0, 0], [-2, 1]]);
    let gt_shifts: Vec<Option<[i32; 2]>> = b.ground_truth.iter().map(|g| g.shift).collect();
    assert_eq!(
        gt_shifts,
        vec![Some([3, -2]), Some([1, -2]), Some([0, 0]), Some([-2, 1])]
    );
    // Common region of all four: x from 3 to 158, y from 1 to 126 (hand-computed).
    assert_eq!((b.width, b.height), (155, 125));
    let (tw, th, _) = read_u16_tiff(&beside.path().join("out/handheld4/frame_1.tif"));
    assert_eq!((tw, th), (155, 125));
    let gt = read_rgbe(&beside.path().join("out/handheld4/HDRImg.hdr"));
    assert_eq!(gt.len(), 155 * 125 * 3);
    assert_eq!(
        exposure_txt(&beside.path().join("out/handheld4")),
        "0\n2\n4\n"
    );
}

#[test]
fn mtb_keeps_a_textureless_frame_in_place_against_itself() {
    use hdrsynth::capture::align::{self, MtbOptions};
    // A flat frame: every pixel sits within the exclusion range of the median, so every
    // candidate shift ties at 0 differing bits. OpenCV's rule (first candidate in scan order)
    // drifts by (−1, −1) per level, (−63, −63) over 6 levels; smooth real frames drift too
    // (OpenCV measured (−3, −4) for a smooth 4032×3024 frame against itself).
    let img = hdrsynth::io::Image::from_fn(256, 192, |_, _| [0.5; 3]);
    assert_eq!(align::mtb_shift(&img, &img, MtbOptions::default()), (0, 0));
}
