//! Reading bracket folders: EXIF exposures, ShutterSpeedValue labels, sidecars (list.txt,
//! exposure.txt), declared EVs, grouping into sets, DNG frames, regions of a frame, and the
//! refusals that name the file.

use crate::helpers::{
    Spatial, assert_close, bracket_jpeg, noisy_png_bracket, png_bracket, ramp_scene, read_u16_tiff,
    scan, stops_rel, tags,
};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::scan::{self, ScanOptions};
use hdrsynth::capture::testset::{self, BracketOptions, EncodeSpec};
use hdrsynth::sensor::profile::Response;
use std::path::Path;

#[test]
fn exif_exposure_time_iso_and_fnumber_are_read_from_a_jpeg() {
    let tmp = tempfile::tempdir().expect("tmp");
    let p = tmp.path().join("a.jpg");
    let mut t = tags((1, 400), 200, "2026:11:24 23:59:59", "25");
    t.f_number = Some((28, 10));
    t.bias = Some((-2, 1));
    bracket_jpeg(&p, 1.0 / 400.0, Some(&t));
    let e = scan::read_exif(&p).expect("exif");
    assert_eq!(e.exposure_time, Some(0.0025));
    assert_eq!(e.iso, Some(200.0));
    assert_eq!(e.f_number, Some(2.8));
    assert_eq!(e.bias_ev, Some(-2.0));
    // 2026-11-24 is day 20 781 since 1970-01-01 (hand count: 56 years incl. 14 leap days =
    // 20 454 days to 2026-01-01, plus 327 days to Nov 24); 86 399 s into the day; .25 s.
    assert_eq!(e.captured_s, Some(20_781.0 * 86_400.0 + 86_399.0 + 0.25));
}

#[test]
fn a_sub_folder_per_set_gets_stops_from_exposure_time_and_iso() {
    let tmp = tempfile::tempdir().expect("tmp");
    // Set A: times 1/400, 1/100, 1/25 at ISO 100 → stops 0, 2, 4.
    // Set B: 1/100 s at ISO 100, 400 and 1600 → stops 0, 2, 4 from the gain alone.
    let a = tmp.path().join("A");
    let b = tmp.path().join("B");
    std::fs::create_dir_all(&a).expect("mkdir");
    std::fs::create_dir_all(&b).expect("mkdir");
    for (i, d) in [400, 100, 25].iter().enumerate() {
        let t = tags((1, *d), 100, "2026:11:24 10:00:00", &format!("{i}"));
        bracket_jpeg(&a.join(format!("IMG_{i}.jpg")), 1.0 / *d as f64, Some(&t));
    }
    for (i, iso) in [1600u16, 100, 400].iter().enumerate() {
        let t = tags((1, 100), *iso, "2026:11:24 11:00:00", &format!("{i}"));
        bracket_jpeg(
            &b.join(format!("IMG_{i}.jpg")),
            0.01 * *iso as f64 / 100.0,
            Some(&t),
        );
    }
    let s = scan(tmp.path());
    assert_eq!(s.sets.len(), 2);
    assert_eq!(s.sets[0].name, "A");
    assert_close(&stops_rel(&s.sets[0]), &[0.0, 2.0, 4.0], 1e-9);
    assert!(
        s.sets[0].exposure_source.contains("ISO"),
        "{}",
        s.sets[0].exposure_source
    );
    assert_eq!(s.sets[0].grouping, "sub-folder A");
    assert_close(&stops_rel(&s.sets[1]), &[0.0, 2.0, 4.0], 1e-9);
    // Ascending exposure: ISO 100, 400, 1600 = files IMG_1, IMG_2, IMG_0.
    let names: Vec<String> = s.sets[1]
        .frames
        .iter()
        .map(|f| f.path.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["IMG_1.jpg", "IMG_2.jpg", "IMG_0.jpg"]);
    assert!(s.notes.is_empty(), "{:?}", s.notes);
}

#[test]
fn one_folder_is_grouped_by_capture_time_and_repeating_exposures() {
    let tmp = tempfile::tempdir().expect("tmp");
    // A phone's AEB order 0, −2, +2; the second burst 1 s later lost its +2 frame; a third
    // burst 60 s later starts with +2, which the short second set does not hold (only the time
    // gap splits there). File names are not in capture order (the camera's counter wrapped):
    // capture time decides.
    let plan = [
        ("P9997.jpg", 100, "10:00:00", "10"),
        ("P9998.jpg", 400, "10:00:00", "40"),
        ("P9999.jpg", 25, "10:00:00", "70"),
        ("P0000.jpg", 100, "10:00:01", "20"),
        ("P0001.jpg", 400, "10:00:01", "50"),
        ("P0003.jpg", 25, "10:01:01", "00"),
        ("P0004.jpg", 100, "10:01:01", "30"),
        ("P0005.jpg", 400, "10:01:01", "60"),
    ];
    for (name, d, time, sub) in plan {
        let t = tags((1, d), 100, &format!("2026:11:24 {time}"), sub);
        bracket_jpeg(&tmp.path().join(name), 1.0 / d as f64, Some(&t));
    }
    let s = scan(tmp.path());
    let groups: Vec<Vec<String>> = s
        .sets
        .iter()
        .map(|set| {
            set.frames
                .iter()
                .map(|f| f.path.file_name().unwrap().to_string_lossy().into_owned())
                .collect()
        })
        .collect();
    assert_eq!(
        groups,
        [
            vec!["P9998.jpg", "P9997.jpg", "P9999.jpg"],
            vec!["P0001.jpg", "P0000.jpg"],
            vec!["P0005.jpg", "P0004.jpg", "P0003.jpg"],
        ]
    );
    for set in [&s.sets[0], &s.sets[2]] {
        assert_close(&stops_rel(set), &[0.0, 2.0, 4.0], 1e-9);
    }
    assert_close(&stops_rel(&s.sets[1]), &[0.0, 2.0], 1e-9);
    for set in &s.sets {
        assert!(set.grouping.contains("capture time"), "{}", set.grouping);
    }
    assert_eq!(s.sets[0].name, "set_001");
    // The third set's boundary came from the time gap alone, and the sizes differ: reported.
    assert!(s.notes.iter().any(|n| n.contains("gap")), "{:?}", s.notes);
    assert!(
        s.notes.iter().any(|n| n.contains("differing")),
        "{:?}",
        s.notes
    );
}

#[test]
fn opencv_list_txt_holds_inverse_exposure_times() {
    let tmp = tempfile::tempdir().expect("tmp");
    for (i, d) in [32u32, 8, 2].iter().enumerate() {
        bracket_jpeg(&tmp.path().join(format!("m{i}.jpg")), 1.0 / *d as f64, None);
    }
    // OpenCV's loadExposureSeq: times = 1 / value.
    std::fs::write(
        tmp.path().join("list.txt"),
        "m0.jpg 32\nm1.jpg 8\nm2.jpg 2\n",
    )
    .expect("w");
    let s = scan(tmp.path());
    assert_eq!(s.sets.len(), 1);
    // log2(1/32) = −5, log2(1/8) = −3, log2(1/2) = −1.
    let abs: Vec<f64> = s.sets[0].frames.iter().map(|f| f.stop).collect();
    assert_close(&abs, &[-5.0, -3.0, -1.0], 1e-12);
    assert!(s.sets[0].exposure_source.contains("list.txt"));
}

#[test]
fn frames_without_exposure_are_refused_by_name_unless_evs_are_declared() {
    let tmp = tempfile::tempdir().expect("tmp");
    let t = tags((1, 100), 100, "2026:11:24 10:00:00", "0");
    bracket_jpeg(&tmp.path().join("a.jpg"), 0.01, Some(&t));
    bracket_jpeg(&tmp.path().join("b.jpg"), 0.04, None);
    bracket_jpeg(&tmp.path().join("c.jpg"), 0.0025, None);
    let err = scan::scan(tmp.path(), &ScanOptions::default())
        .expect_err("undeterminable")
        .to_string();
    assert!(err.contains("b.jpg") && err.contains("c.jpg"), "{err}");
    assert!(!err.contains("a.jpg"), "{err}");
    assert!(err.contains("--declared-evs"), "{err}");
    // Declared EV steps in capture (here: file-name) order.
    let opts = ScanOptions {
        evs: Some(vec![0.0, 2.0, -2.0]),
        ..ScanOptions::default()
    };
    let s = scan::scan(tmp.path(), &opts).expect("declared");
    let names: Vec<String> = s.sets[0]
        .frames
        .iter()
        .map(|f| f.path.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["c.jpg", "a.jpg", "b.jpg"]);
    assert_close(&stops_rel(&s.sets[0]), &[0.0, 2.0, 4.0], 0.0);
}

#[test]
fn a_lone_frame_and_equal_exposures_are_refused_naming_the_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    let d = tmp.path().join("solo");
    std::fs::create_dir_all(&d).expect("mkdir");
    let t = tags((1, 100), 100, "2026:11:24 10:00:00", "0");
    bracket_jpeg(&d.join("only.jpg"), 0.01, Some(&t));
    let err = scan::scan(tmp.path(), &ScanOptions::default())
        .expect_err("lone frame")
        .to_string();
    assert!(
        err.contains("only.jpg") && err.contains("at least two"),
        "{err}"
    );
}

#[test]
fn a_corrupt_jpeg_is_an_error_naming_it_not_a_panic() {
    let tmp = tempfile::tempdir().expect("tmp");
    let d = tmp.path().join("s");
    std::fs::create_dir_all(&d).expect("mkdir");
    for (i, den) in [400u32, 100, 25].iter().enumerate() {
        let t = tags((1, *den), 100, "2026:11:24 10:00:00", &format!("{i}"));
        bracket_jpeg(&d.join(format!("f{i}.jpg")), 1.0 / *den as f64, Some(&t));
    }
    // Truncate the middle frame's entropy-coded data.
    let p = d.join("f1.jpg");
    let bytes = std::fs::read(&p).expect("read");
    std::fs::write(&p, &bytes[..bytes.len() / 2]).expect("write");
    let opts = BracketOptions {
        scan: ScanOptions::default(),
        response: ResponseChoice::Declared(Response::Srgb),
        align: None,
        // Written as the field's linear^(1/2.2), which the hand merges below read with γ 2.2.
        encode: EncodeSpec::Field,
        ..BracketOptions::default()
    };
    let beside = tempfile::tempdir().expect("tmp"); // outputs inside the input are refused
    let err = testset::build(tmp.path(), &opts, &beside.path().join("out"))
        .expect_err("corrupt")
        .to_string();
    assert!(err.contains("f1.jpg"), "{err}");
}

/// A little-endian uncompressed 16-bit RGGB DNG of a uniform colour (`dn` per CFA colour), with
/// an Exif IFD holding ExposureTime 1/`den` s and ISO 100 (TIFF 6.0 / DNG 1.4 / EXIF 2.32 tags).
fn write_uniform_dng(path: &Path, w: usize, h: usize, dn: [u16; 3], den: u32) {
    let short = |v: u16| v.to_le_bytes().to_vec();
    let long = |v: u32| v.to_le_bytes().to_vec();
    let mut pixels = Vec::with_capacity(w * h * 2);
    for y in 0..h {
        for x in 0..w {
            let c = match (y % 2, x % 2) {
                (0, 0) => 0,
                (1, 1) => 2,
                _ => 1,
            };
            pixels.extend(dn[c].to_le_bytes());
        }
    }
    let mut entries: Vec<(u16, u16, u32, Vec<u8>)> = vec![
        (254, 4, 1, long(0)),
        (256, 4, 1, long(w as u32)),
        (257, 4, 1, long(h as u32)),
        (258, 3, 1, short(16)),
        (259, 3, 1, short(1)),
        (262, 3, 1, short(32803)),
        (273, 4, 1, vec![]), // strip offset, filled below
        (277, 3, 1, short(1)),
        (278, 4, 1, long(h as u32)),
        (279, 4, 1, long(pixels.len() as u32)),
        (33421, 3, 2, [short(2), short(2)].concat()),
        (33422, 1, 4, vec![0, 1, 1, 2]),
        (34665, 4, 1, vec![]), // Exif IFD offset, filled below
        (50714, 3, 1, short(64)),
        (50717, 3, 1, short(4159)),
    ];
    let ifd0 = 8usize;
    let exif_at = ifd0 + 2 + 12 * entries.len() + 4;
    // Exif IFD: ExposureTime (RATIONAL, out of line) and ISO; then its rational, then pixels.
    let exif_len = 2 + 12 * 2 + 4;
    let rational_at = exif_at + exif_len;
    let pixels_at = rational_at + 8;
    entries[6].3 = long(pixels_at as u32);
    entries[12].3 = long(exif_at as u32);
    let mut out = b"II".to_vec();
    out.extend(42u16.to_le_bytes());
    out.extend((ifd0 as u32).to_le_bytes());
    out.extend((entries.len() as u16).to_le_bytes());
    for (tag, typ, count, mut val) in entries {
        out.extend(tag.to_le_bytes());
        out.extend(typ.to_le_bytes());
        out.extend(count.to_le_bytes());
        val.resize(4, 0);
        out.extend(val);
    }
    out.extend(0u32.to_le_bytes());
    assert_eq!(out.len(), exif_at);
    out.extend(2u16.to_le_bytes());
    for (tag, typ, val) in [
        (33434u16, 5u16, long(rational_at as u32)),
        (34855, 3, [short(100), short(0)].concat()),
    ] {
        out.extend(tag.to_le_bytes());
        out.extend(typ.to_le_bytes());
        out.extend(1u32.to_le_bytes());
        out.extend(val);
    }
    out.extend(0u32.to_le_bytes());
    out.extend(long(1));
    out.extend(long(den));
    out.extend(pixels);
    std::fs::write(path, out).expect("write dng");
}

#[test]
fn dng_brackets_are_linear_raw_with_exif_exposures() {
    let tmp = tempfile::tempdir().expect("tmp");
    let d = tmp.path().join("raw");
    std::fs::create_dir_all(&d).expect("mkdir");
    // Radiance (R, G, B) = (0.2, 0.5, 0.9) · 1/10 per second of exposure, in units of raw white.
    let lin = |t: f64| [0.2, 0.5, 0.9].map(|l: f64| (l * t * 10.0).min(1.0));
    for (name, den) in [("a.dng", 400u32), ("b.dng", 100), ("c.dng", 25)] {
        let l = lin(1.0 / den as f64);
        let dn = l.map(|v| (64.0 + v * 4095.0).round() as u16);
        write_uniform_dng(&d.join(name), 12, 12, dn, den);
    }
    let s = scan(tmp.path());
    assert_close(&stops_rel(&s.sets[0]), &[0.0, 2.0, 4.0], 1e-9);
    let opts = BracketOptions {
        scan: ScanOptions::default(),
        // Ignored for DNG frames: they are linear.
        response: ResponseChoice::Declared(Response::Srgb),
        align: None,
        // `--encode auto`: a raw has no device curve, so the field's linear^(1/2.2).
        ..BracketOptions::default()
    };
    let beside = tempfile::tempdir().expect("tmp"); // outputs inside the input are refused
    let built = testset::build(tmp.path(), &opts, &beside.path().join("out")).expect("build");
    let enc = std::fs::read_to_string(beside.path().join("out/encoding.toml")).expect("encoding");
    assert!(
        enc.contains("kind = \"gamma\"") && enc.contains("gamma = 2.2"),
        "{enc}"
    );
    // Device codes of a raw do not exist: refused, naming a frame.
    let device = BracketOptions {
        encode: EncodeSpec::Device,
        ..opts.clone()
    };
    let e = testset::build(tmp.path(), &device, &beside.path().join("out2"))
        .expect_err("device codes of a DNG")
        .to_string();
    assert!(e.contains(".dng") && e.contains("linear raw"), "{e}");
    assert!(
        built.sets[0].response.contains("linear raw"),
        "{}",
        built.sets[0].response
    );
    let set = beside.path().join("out/raw");
    for (n, den) in [
        ("frame_1.tif", 400u32),
        ("frame_2.tif", 100),
        ("frame_3.tif", 25),
    ] {
        let (_, _, v) = read_u16_tiff(&set.join(n));
        let l = lin(1.0 / den as f64);
        for c in 0..3 {
            // DN quantisation (1/4095) then 16-bit codes of L^(1/2.2).
            let want = ((64.0 + l[c] * 4095.0).round() - 64.0) / 4095.0;
            let got = v[c].powf(2.2);
            assert!(
                (got - want).abs() < 2e-4 * want.max(0.01),
                "{n} c{c}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn shutter_speed_value_gives_the_exact_time_behind_a_marked_label() {
    let tmp = tempfile::tempdir().expect("tmp");
    // A camera: labels 1/125, 1/30, 1/8 for 2^−7, 2^−5, 2^−3 s (Tv 7, 5, 3).
    let cam = tmp.path().join("camera");
    // A phone: measured times 1/121 and 1/30 s, its Tv computed from them.
    let phone = tmp.path().join("phone");
    // A label whose Tv is 2 stops away: not the same time, the label is kept.
    let odd = tmp.path().join("odd");
    for d in [&cam, &phone, &odd] {
        std::fs::create_dir_all(d).expect("mkdir");
    }
    for (i, (den, tv)) in [(125u32, 7), (30, 5), (8, 3)].iter().enumerate() {
        let mut t = tags((1, *den), 100, "2026:11:24 10:00:00", &format!("{i}"));
        t.shutter_apex = Some((*tv, 1));
        bracket_jpeg(&cam.join(format!("c{i}.jpg")), 1.0 / *den as f64, Some(&t));
        let mut t = tags((1, *den), 100, "2026:11:24 10:00:00", &format!("{i}"));
        t.shutter_apex = Some((if i == 0 { 9 } else { *tv }, 1));
        bracket_jpeg(&odd.join(format!("o{i}.jpg")), 1.0 / *den as f64, Some(&t));
    }
    // log2(121) = 6.918863 → Tv 6918863/1000000; log2(30) = 4.906891.
    for (i, (den, tv)) in [(121u32, 6_918_863), (30, 4_906_891)].iter().enumerate() {
        let mut t = tags((1, *den), 100, "2026:11:24 10:00:00", &format!("{i}"));
        t.shutter_apex = Some((*tv, 1_000_000));
        bracket_jpeg(
            &phone.join(format!("p{i}.jpg")),
            1.0 / *den as f64,
            Some(&t),
        );
    }
    let s = scan(tmp.path());
    let by_name = |n: &str| s.sets.iter().find(|x| x.name == n).expect(n);
    assert_close(&stops_rel(by_name("camera")), &[0.0, 2.0, 4.0], 1e-12);
    assert!(
        by_name("camera")
            .exposure_source
            .contains("ShutterSpeedValue"),
        "{}",
        by_name("camera").exposure_source
    );
    // 1/121 is no marked label: the measured times stand, log2(121/30) = 2.011972.
    assert_close(
        &stops_rel(by_name("phone")),
        &[0.0, (121.0f64 / 30.0).log2()],
        1e-12,
    );
    assert!(
        !by_name("phone")
            .exposure_source
            .contains("ShutterSpeedValue")
    );
    // Tv 9 for "1/125" is 2.03 stops off: the labels stand for every frame of the folder.
    assert_close(
        &stops_rel(by_name("odd")),
        &[0.0, (125.0f64 / 30.0).log2(), (125.0f64 / 8.0).log2()],
        1e-12,
    );
}

#[test]
fn halves_of_a_frame_share_no_pixel_and_are_read_as_cut() {
    use hdrsynth::capture::scan::Region;
    assert_eq!(Region::Left.bounds(5, 3), Some([0, 0, 2, 3]));
    assert_eq!(Region::Right.bounds(5, 3), Some([2, 0, 5, 3]));
    assert_eq!(Region::Top.bounds(4, 5), Some([0, 0, 4, 2]));
    assert_eq!(Region::Bottom.bounds(4, 5), Some([0, 2, 4, 5]));
    assert_eq!(
        "1,2,3,4".parse::<Region>(),
        Ok(Region::Rect {
            x: 1,
            y: 2,
            w: 3,
            h: 4
        })
    );
    assert_eq!(
        Region::Rect {
            x: 3,
            y: 0,
            w: 3,
            h: 1
        }
        .bounds(5, 3),
        None
    );
    for bad in ["middle", "1,2,3", "1,2,0,4", "-1,0,2,2"] {
        let e = bad.parse::<Region>().expect_err(bad);
        assert!(e.contains(bad), "{e}");
    }
    // Read through a scan: the left half's pixels are the frame's first columns.
    let tmp = tempfile::tempdir().expect("tmp");
    noisy_png_bracket(
        &tmp.path().join("scene"),
        4e-4,
        1e-5,
        &[-1.0, 0.0, 1.0],
        Spatial::White,
    );
    let whole = image::open(tmp.path().join("scene/f1.png"))
        .expect("png")
        .to_rgb8();
    for (region, x0) in [(Region::Left, 0u32), (Region::Right, 96)] {
        let scan = scan::scan(
            tmp.path(),
            &ScanOptions {
                region: Some(region),
                ..ScanOptions::default()
            },
        )
        .expect("scan");
        let f = &scan.sets[0].frames[1];
        let img = scan::read_frame_image(f).expect("read");
        assert_eq!((img.width, img.height), (96, 144));
        for (x, y) in [(0u32, 0u32), (95, 143), (40, 70)] {
            let want = whole.get_pixel(x0 + x, y).0;
            let got = img.get(x as usize, y as usize);
            for c in 0..3 {
                assert!(
                    (got[c] - want[c] as f32 / 255.0).abs() < 1e-6,
                    "{region} ({x}, {y})"
                );
            }
        }
        let source = scan::frame_source(f).expect("source");
        assert_eq!(source.pixels, [x0 as usize, 0, x0 as usize + 96, 144]);
    }
}

#[test]
fn an_exif_exposure_time_no_camera_gives_is_refused_naming_the_file() {
    for (bad, shown) in [((0u32, 1u32), "0e0 s"), ((u32::MAX, 1), "4.294967295e9 s")] {
        let tmp = tempfile::tempdir().expect("tmp");
        for (i, t) in [(1u32, 400u32), bad, (1, 25)].iter().enumerate() {
            let tg = tags(*t, 100, "2026:11:24 10:00:00", &format!("{i}"));
            let t = if t.0 == 0 {
                1e-3
            } else {
                (f64::from(t.0) / f64::from(t.1)).min(1.0)
            };
            bracket_jpeg(&tmp.path().join(format!("IMG_{i}.jpg")), t, Some(&tg));
        }
        let e = scan::scan(tmp.path(), &ScanOptions::default())
            .expect_err("refused")
            .to_string();
        assert!(
            e.contains("IMG_1.jpg") && e.contains("ExposureTime") && e.contains(shown),
            "{e}"
        );
    }
}

/// A bracket folder read once serves every stage of a run: each selection of sets and region
/// equals a fresh scan with the same options, and it needs no second read of the folder (it
/// holds after the folder is moved away).
#[test]
fn a_folder_scanned_once_gives_each_stage_what_a_scan_would() {
    use hdrsynth::capture::scan::{FolderScan, Region};
    let tmp = tempfile::tempdir().expect("tmp");
    let root = tmp.path().join("b");
    for name in ["park", "desk"] {
        png_bracket(&root.join(name), 24, 16, &ramp_scene, &[0.0, 2.0, 4.0]);
    }
    let folder = FolderScan::new(&root, &ScanOptions::default()).expect("scan");
    let choices = [
        ScanOptions::default(),
        ScanOptions {
            sets: vec!["park".into()],
            ..ScanOptions::default()
        },
        ScanOptions {
            region: Some(Region::Left),
            ..ScanOptions::default()
        },
        ScanOptions {
            sets: vec!["desk".into()],
            region: Some(Region::Rect {
                x: 2,
                y: 1,
                w: 12,
                h: 12,
            }),
            ..ScanOptions::default()
        },
    ];
    let fresh: Vec<_> = choices
        .iter()
        .map(|o| scan::scan(&root, o).expect("scan"))
        .collect();
    let unknown = ScanOptions {
        sets: vec!["attic".into()],
        ..ScanOptions::default()
    };
    let e = scan::scan(&root, &unknown).unwrap_err().to_string();
    std::fs::rename(&root, tmp.path().join("moved")).expect("move");
    for (o, f) in choices.iter().zip(&fresh) {
        assert_eq!(&folder.select(o).expect("select"), f, "{o:?}");
    }
    assert_eq!(folder.select(&unknown).unwrap_err().to_string(), e);
}
