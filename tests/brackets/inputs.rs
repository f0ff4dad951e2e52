//! Choosing the inputs (`--inputs`): the defaults, frames by index, `auto`'s pick, and bad
//! indices refused. The truth is this test's own camera: a known radiance, exposure = radiance
//! · 2^stop clipped at 1, encoded by hand (IEC 61966-2-1 sRGB, 8 bits).

use crate::helpers::{bracket_jpeg, exposure_txt, png_bracket, read_u16_tiff, srgb_opts, tags};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::testset::{self, BracketOptions, GtFrames, InputChoice};
use std::path::PathBuf;

fn file_names(paths: &[PathBuf]) -> Vec<String> {
    paths
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect()
}

#[test]
fn the_default_options_keep_the_shortest_middle_and_longest_and_merge_every_frame() {
    let o = BracketOptions::default();
    assert_eq!(o.inputs, InputChoice::Spread);
    assert_eq!(o.gt_frames, GtFrames::All);
    assert_eq!(
        o.response,
        ResponseChoice::Debevec(hdrsynth::sensor::crf::DebevecOptions::one_curve())
    );
    assert_eq!(o.align, None);
    assert_eq!("auto".parse::<InputChoice>(), Ok(InputChoice::Auto));
    assert_eq!(
        " 1, 2 ,3".parse::<InputChoice>(),
        Ok(InputChoice::Indices([1, 2, 3]))
    );
    for bad in ["1,2", "1,2,3,4", "a,b,c", "-1,0,1", ""] {
        let e = bad.parse::<InputChoice>().expect_err(bad);
        assert!(e.contains("I,J,K"), "{bad}: {e}");
    }
    assert_eq!("all".parse::<GtFrames>(), Ok(GtFrames::All));
    assert_eq!("inputs".parse::<GtFrames>(), Ok(GtFrames::Inputs));
    assert!("every".parse::<GtFrames>().is_err());
}

#[test]
fn inputs_by_index_write_those_frames_with_their_exif_stops() {
    let tmp = tempfile::tempdir().expect("tmp");
    let d = tmp.path().join("six");
    std::fs::create_dir_all(&d).expect("mkdir");
    // Six frames, 1/4000 … 1/2 s (ExposureTime only: the times as written).
    let dens = [4000u32, 1000, 125, 30, 8, 2];
    for (i, den) in dens.iter().enumerate() {
        let t = tags((1, *den), 100, "2026:11:24 10:00:00", &format!("{i}"));
        bracket_jpeg(&d.join(format!("IMG_{i}.jpg")), 1.0 / *den as f64, Some(&t));
    }
    let beside = tempfile::tempdir().expect("tmp");
    let out = beside.path().join("out");
    let opts = srgb_opts(InputChoice::Indices([1, 2, 3]), GtFrames::Inputs);
    let built = testset::build(tmp.path(), &opts, &out).expect("build");
    let b = &built.sets[0];
    assert_eq!(b.inputs, vec![1, 2, 3]);
    let sources: Vec<PathBuf> = b.frames.iter().map(|f| f.source.clone()).collect();
    assert_eq!(
        file_names(&sources),
        ["IMG_1.jpg", "IMG_2.jpg", "IMG_3.jpg"]
    );
    // 1/1000 → 1/125 is 3 stops, 1/125 → 1/30 is log2(125/30) = 2.058894 (6 decimals).
    assert_eq!(exposure_txt(&out.join("six")), "0\n3\n5.058894\n");
    assert_eq!(
        file_names(&b.dropped),
        ["IMG_0.jpg", "IMG_4.jpg", "IMG_5.jpg"]
    );
    assert_eq!(b.ground_truth.len(), 3);
    // The written frames are those JPEGs, linearised by hand and re-encoded as L^(1/2.2).
    let srgb_decode = |v: f64| {
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    for (name, src) in ["frame_1.tif", "frame_2.tif", "frame_3.tif"].iter().zip([
        "IMG_1.jpg",
        "IMG_2.jpg",
        "IMG_3.jpg",
    ]) {
        let (_, _, got) = read_u16_tiff(&out.join("six").join(name));
        let jpeg = image::open(d.join(src)).expect("jpeg").to_rgb8().into_raw();
        for (g, c) in got.iter().zip(jpeg) {
            let want = srgb_decode(c as f64 / 255.0).powf(1.0 / 2.2);
            assert!(
                (g - want).abs() <= 1.0 / 65535.0 + 1e-9,
                "{name}: {g} vs {want}"
            );
        }
    }
    // brackets.toml records the inputs and the ground truth's frames.
    let rec = std::fs::read_to_string(out.join("six/brackets.toml")).expect("record");
    assert!(
        rec.contains("inputs = [\n    1,\n    2,\n    3,\n]") || rec.contains("inputs = [1, 2, 3]"),
        "{rec}"
    );
    assert!(rec.contains("[[ground_truth]]"), "{rec}");
}

/// Three grey bands of known radiance over 40 columns: 20 columns at 2^−12, 10 at 2^−3.5,
/// 10 at 2^−5. A pixel's 8-bit sRGB code at stop s is dark (≤ 5) where 2^(e+s) < 0.00167 and
/// clipped (≥ 250) where 2^(e+s) ≥ 0.955 (hand values of the sRGB encoding).
fn band_scene(x: usize, _y: usize) -> f64 {
    match x {
        0..20 => (-12.0f64).exp2(),
        20..30 => (-3.5f64).exp2(),
        _ => (-5.0f64).exp2(),
    }
}

#[test]
fn auto_picks_two_stop_steps_and_the_least_clipped_or_dark_reference() {
    let tmp = tempfile::tempdir().expect("tmp");
    // Stops 0, 1, 2, 3, 4, 6. Exact 2-stop triples: (0, 2, 4) = frames 0, 2, 4 and (2, 4, 6) =
    // frames 2, 4, 5; every other triple is a stop or more off. Hand-computed codes: the
    // 2^−12 band is dark up to stop 2 (code 3 at stop 2, 6 at stop 3); the 2^−3.5 band clips
    // from stop 4 (code 219 at stop 3); the 2^−5 band clips at stop 6 (188 at stop 4). So
    // frame 2 (stop 2) is 50 % dark, frame 4 (stop 4) 25 % clipped: auto takes (2, 4, 5).
    // Frame 3 (stop 3, 0 %) is the best exposed frame but the reference of no 2-stop triple;
    // the default takes (0, 3, 5).
    png_bracket(
        &tmp.path().join("bands"),
        40,
        12,
        &band_scene,
        &[0.0, 1.0, 2.0, 3.0, 4.0, 6.0],
    );
    let beside = tempfile::tempdir().expect("tmp");
    let out = beside.path().join("out");
    let built = testset::build(
        tmp.path(),
        &srgb_opts(InputChoice::Auto, GtFrames::Inputs),
        &out,
    )
    .expect("build");
    let b = &built.sets[0];
    assert_eq!(b.inputs, vec![2, 4, 5]);
    assert_eq!(b.reference_clipped_or_dark, 0.25);
    assert!(b.selection.contains("auto"), "{}", b.selection);
    assert_eq!(exposure_txt(&out.join("bands")), "0\n2\n4\n");
    let report = built.report(&out);
    assert!(report.contains("4:f4.png"), "{report}");

    let spread = testset::build(
        tmp.path(),
        &srgb_opts(InputChoice::Spread, GtFrames::Inputs),
        &beside.path().join("spread"),
    )
    .expect("build");
    assert_eq!(spread.sets[0].inputs, vec![0, 3, 5]);
    assert_eq!(spread.sets[0].reference_clipped_or_dark, 0.0);

    // The rule alone, on the stops of a 3-stop bracket: no 2-stop triple exists; (0, 1, 2)
    // and (1, 2, 3) are both 1 stop off, and the metering decides between references 1 and 2.
    let stops = [0.0, 3.0, 6.0, 9.0];
    let sel = testset::auto_inputs(&stops, |j| Ok([0.9, 0.4, 0.1, 0.9][j])).expect("auto");
    assert_eq!(sel.indices, [1, 2, 3]);
    assert_eq!(sel.metered, vec![(1, 0.4), (2, 0.1)]);
    let sel = testset::auto_inputs(&stops, |j| Ok([0.9, 0.1, 0.4, 0.9][j])).expect("auto");
    assert_eq!(sel.indices, [0, 1, 2]);
}

#[test]
fn bad_input_indices_are_refused_naming_the_folder_and_nothing_is_written() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("five");
    png_bracket(&dir, 8, 4, &|_, _| 0.01, &[0.0, 2.0, 4.0, 6.0, 8.0]);
    let beside = tempfile::tempdir().expect("tmp");
    for (idx, what) in [
        ([0, 5, 9], "out of range"),
        ([0, 2, 5], "out of range"),
        ([2, 1, 3], "ascending"),
        ([3, 2, 1], "ascending"),
        ([1, 1, 3], "repeats"),
        ([1, 3, 3], "repeats"),
    ] {
        let out = beside.path().join(format!("{idx:?}"));
        let e = testset::build(
            tmp.path(),
            &srgb_opts(InputChoice::Indices(idx), GtFrames::All),
            &out,
        )
        .expect_err("bad --inputs")
        .to_string();
        assert!(e.contains(what), "{idx:?}: {e}");
        assert!(e.contains(&dir.display().to_string()), "{idx:?}: {e}");
        assert!(e.contains("4 f4.png"), "lists the frames: {e}");
        assert!(!out.join("five").exists(), "{idx:?}: a set was written");
    }
}
