//! DNG tags → sensor profile: the tag reader against tifffile (an independent reader), the DNG
//! specification's colour against an independent numpy implementation with colour-science's
//! CCT (tests/data/dng_tags_reference.json, tools/dng_tags_reference.py), the NoiseProfile
//! conversion against hand-computed values, refusals, and the written profile driving the
//! realism operator. Synthetic DNGs are built here (tags only, no image data); the real files
//! are under ../shared/data/real_raw.
#![allow(clippy::needless_range_loop)]

use hdrsynth::sensor::colour::cie::xy_to_cct;
use hdrsynth::sensor::dng::colour::dng_colour;
use hdrsynth::sensor::dng::profile::{DngOptions, calibrate_dng};
use hdrsynth::sensor::dng::{RawLayout, read_dng_tags, read_dng_tags_bytes};
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::sensor::realism::{NoiseModel, Realism, RealismOptions};
use serde_json::Value;
use std::path::{Path, PathBuf};

// --- a minimal TIFF writer for synthetic DNGs ------------------------------------------------

#[derive(Clone, Debug)]
enum Val {
    Byte(Vec<u8>),
    Ascii(&'static str),
    Short(Vec<u16>),
    Long(Vec<u32>),
    Rational(Vec<(u32, u32)>),
    SRational(Vec<(i32, i32)>),
    Double(Vec<f64>),
    /// Offsets of the IFDs with these indices (SubIFDs, the EXIF IFD).
    Ifds(Vec<usize>),
}

type Entries = Vec<(u16, Val)>;

/// A TIFF with IFD 0 = `ifds[0]` (no chain) and the other IFDs reachable through `Ifds`
/// pointers only.
fn tiff(ifds: &[Entries], big_endian: bool) -> Vec<u8> {
    let u16b = |v: u16| {
        if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let u32b = |v: u32| {
        if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let mut at = 8usize;
    let offsets: Vec<usize> = ifds
        .iter()
        .map(|e| {
            let o = at;
            at += 2 + 12 * e.len() + 4;
            o
        })
        .collect();
    let (mut out, mut extra) = (Vec::new(), Vec::new());
    out.extend(if big_endian { *b"MM" } else { *b"II" });
    out.extend(u16b(42));
    out.extend(u32b(8));
    for entries in ifds {
        let mut entries = entries.clone();
        entries.sort_by_key(|e| e.0);
        out.extend(u16b(entries.len() as u16));
        for (tag, v) in entries {
            let (typ, count, bytes): (u16, usize, Vec<u8>) = match v {
                Val::Byte(b) => (1, b.len(), b),
                Val::Ascii(s) => (2, s.len() + 1, [s.as_bytes(), &[0u8][..]].concat()),
                Val::Short(v) => (3, v.len(), v.iter().flat_map(|x| u16b(*x)).collect()),
                Val::Long(v) => (4, v.len(), v.iter().flat_map(|x| u32b(*x)).collect()),
                Val::Rational(v) => (
                    5,
                    v.len(),
                    v.iter()
                        .flat_map(|(n, d)| [u32b(*n), u32b(*d)].concat())
                        .collect(),
                ),
                Val::SRational(v) => (
                    10,
                    v.len(),
                    v.iter()
                        .flat_map(|(n, d)| [u32b(*n as u32), u32b(*d as u32)].concat())
                        .collect(),
                ),
                Val::Double(v) => (
                    12,
                    v.len(),
                    v.iter()
                        .flat_map(|x| {
                            if big_endian {
                                x.to_be_bytes()
                            } else {
                                x.to_le_bytes()
                            }
                        })
                        .collect(),
                ),
                Val::Ifds(k) => (
                    4,
                    k.len(),
                    k.iter().flat_map(|&i| u32b(offsets[i] as u32)).collect(),
                ),
            };
            out.extend(u16b(tag));
            out.extend(u16b(typ));
            out.extend(u32b(count as u32));
            if bytes.len() <= 4 {
                let mut b = bytes;
                b.resize(4, 0);
                out.extend(b);
            } else {
                out.extend(u32b((at + extra.len()) as u32));
                extra.extend(bytes);
                extra.resize(extra.len().next_multiple_of(2), 0);
            }
        }
        out.extend(u32b(0));
    }
    out.extend(extra);
    out
}

fn ratios(v: &[i32], d: i32) -> Val {
    Val::SRational(v.iter().map(|&n| (n, d)).collect())
}

const CM1: [i32; 9] = [7546, -1435, -929, -3846, 11488, 2692, -332, 1209, 6370];
const CM2: [i32; 9] = [7034, -804, -1014, -4420, 12564, 2058, -851, 1994, 5758];
const CC: [i32; 9] = [9883, 0, 0, 0, 10000, 0, 0, 0, 10120];
const AB: [u32; 3] = [1_100_000, 1_000_000, 950_000];
const NEUTRAL: [u32; 3] = [650_000, 1_000_000, 450_000];
const BLACK: [u32; 4] = [64, 60, 68, 72];
const DELTA_H: [i32; 4] = [1, 3, 1, 3];
const WHITE: u16 = 4000;
const NOISE: [f64; 6] = [2.0e-5, 4.0e-8, 1.5e-5, 3.0e-8, 2.5e-5, 5.0e-8];

/// IFD 0 (a preview with the colour tags and names), the raw IFD (an RGGB CFA, 12 bits, no
/// image data) as SubIFD 1, the EXIF IFD (ISO) as IFD 2.
fn synthetic(iso: u16, model: &'static str) -> Vec<Entries> {
    let ifd0 = vec![
        (254, Val::Long(vec![1])),
        (271, Val::Ascii("Example")),
        (272, Val::Ascii(model)),
        (330, Val::Ifds(vec![1])),
        (34665, Val::Ifds(vec![2])),
        (50706, Val::Byte(vec![1, 4, 0, 0])),
        (50708, Val::Ascii(model)),
        (50721, ratios(&CM1, 10000)),
        (50722, ratios(&CM2, 10000)),
        (50723, ratios(&CC, 10000)),
        (50724, ratios(&CC, 10000)),
        (
            50727,
            Val::Rational(AB.iter().map(|&n| (n, 1_000_000)).collect()),
        ),
        (
            50728,
            Val::Rational(NEUTRAL.iter().map(|&n| (n, 1_000_000)).collect()),
        ),
        (50778, Val::Short(vec![17])),
        (50779, Val::Short(vec![21])),
        (50931, Val::Ascii("com.example")),
        (50932, Val::Ascii("com.example")),
    ];
    let raw = vec![
        (254, Val::Long(vec![0])),
        (256, Val::Long(vec![4])),
        (257, Val::Long(vec![2])),
        (258, Val::Short(vec![12])),
        (259, Val::Short(vec![1])),
        (262, Val::Short(vec![32803])),
        (277, Val::Short(vec![1])),
        (33421, Val::Short(vec![2, 2])),
        (33422, Val::Byte(vec![0, 1, 1, 2])),
        (50713, Val::Short(vec![2, 2])),
        (50714, Val::Long(BLACK.to_vec())),
        (
            50715,
            Val::SRational(DELTA_H.iter().map(|&n| (n, 1)).collect()),
        ),
        (50717, Val::Short(vec![WHITE])),
        (51041, Val::Double(NOISE.to_vec())),
    ];
    let exif = vec![(34855, Val::Short(vec![iso]))];
    vec![ifd0, raw, exif]
}

fn without(mut ifds: Vec<Entries>, tag: u16) -> Vec<Entries> {
    for ifd in &mut ifds {
        ifd.retain(|e| e.0 != tag);
    }
    ifds
}

fn set(mut ifds: Vec<Entries>, ifd: usize, tag: u16, v: Val) -> Vec<Entries> {
    ifds[ifd].retain(|e| e.0 != tag);
    ifds[ifd].push((tag, v));
    ifds
}

fn write(dir: &Path, name: &str, ifds: &[Entries]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, tiff(ifds, false)).unwrap();
    p
}

// --- the reference JSON ----------------------------------------------------------------------

fn reference() -> Value {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/dng_tags_reference.json");
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn nums(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn rows(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().flat_map(nums).collect()
}

/// [[numerator, denominator], ...] as the f64 quotients a TIFF reader computes.
fn quotients(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let p = p.as_array().unwrap();
            p[0].as_i64().unwrap() as f64 / p[1].as_i64().unwrap() as f64
        })
        .collect()
}

fn close(got: &[f64], want: &[f64], tol: f64, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}");
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() <= tol, "{what}: {got:?} vs {want:?}");
    }
}

// --- synthetic files ---------------------------------------------------------------------------

#[test]
fn robertson_cct_matches_colour_science() {
    let r = reference();
    for case in r["cct"].as_array().unwrap() {
        let xy = nums(&case["xy"]);
        let want = case["cct"].as_f64().unwrap();
        let got = xy_to_cct([xy[0], xy[1]]);
        assert!(
            (got - want).abs() < 1e-7 * want,
            "xy {xy:?}: {got} vs {want}"
        );
    }
}

#[test]
fn synthetic_tags_read_exactly_in_both_byte_orders() {
    for big in [false, true] {
        let bytes = tiff(&synthetic(400, "Cam 1"), big);
        let t = read_dng_tags_bytes(&bytes, Path::new("syn.dng")).unwrap();
        assert_eq!(t.make.as_deref(), Some("Example"));
        assert_eq!(t.model.as_deref(), Some("Cam 1"));
        assert_eq!(t.camera().as_deref(), Some("Cam 1"));
        assert_eq!(t.iso, Some(400.0));
        assert_eq!(
            t.layout,
            RawLayout::Cfa {
                dims: [2, 2],
                pattern: vec![0, 1, 1, 2]
            }
        );
        assert_eq!(t.bits_per_sample, 12);
        let q = |v: &[i32], d: f64| -> Vec<f64> { v.iter().map(|&n| n as f64 / d).collect() };
        assert_eq!(t.color_matrix[0].unwrap().as_flattened(), q(&CM1, 10000.0));
        assert_eq!(t.color_matrix[1].unwrap().as_flattened(), q(&CM2, 10000.0));
        assert_eq!(
            t.camera_calibration[1].unwrap().as_flattened(),
            q(&CC, 10000.0)
        );
        assert_eq!(t.calibration_illuminant, [Some(17), Some(21)]);
        assert_eq!(
            t.camera_calibration_signature.as_deref(),
            Some("com.example")
        );
        assert_eq!(t.analog_balance, Some([1.1, 1.0, 0.95]));
        assert_eq!(t.as_shot_neutral, Some([0.65, 1.0, 0.45]));
        assert_eq!(t.black_level, Some(vec![64.0, 60.0, 68.0, 72.0]));
        assert_eq!(t.black_level_repeat, [2, 2]);
        assert_eq!(t.black_level_delta_h, vec![1.0, 3.0, 1.0, 3.0]);
        assert_eq!(t.white_level, Some(vec![4000.0]));
        assert_eq!(t.noise_profile, Some(NOISE.to_vec()));
    }
}

#[test]
fn synthetic_colour_matches_the_independent_reference() {
    let r = reference();
    let s = &r["synthetic"];
    // The reference was computed for exactly these tags.
    let tags = &s["tags"];
    let q = |v: &[i32]| -> Vec<f64> { v.iter().map(|&n| n as f64 / 10000.0).collect() };
    assert_eq!(nums(&tags["color_matrix1"]), q(&CM1));
    assert_eq!(nums(&tags["color_matrix2"]), q(&CM2));
    assert_eq!(nums(&tags["camera_calibration1"]), q(&CC));
    assert_eq!(nums(&tags["as_shot_neutral"]), vec![0.65, 1.0, 0.45]);
    assert_eq!(nums(&tags["analog_balance"]), vec![1.1, 1.0, 0.95]);
    assert_eq!(nums(&tags["noise_profile"]), NOISE.to_vec());
    let bytes = tiff(&synthetic(400, "Cam 1"), false);
    let p = Path::new("syn.dng");
    let t = read_dng_tags_bytes(&bytes, p).unwrap();
    let c = dng_colour(&t, p).unwrap();
    let e = &s["expected"];
    assert!(
        (c.cct - e["cct"].as_f64().unwrap()).abs() < 1e-6,
        "{}",
        c.cct
    );
    close(&c.white_xy, &nums(&e["xy"]), 1e-12, "white xy");
    let (temps, g) = c.interpolation.unwrap();
    assert_eq!(temps, [2856.0, 6504.0]);
    assert!((g - e["weight_lower_temperature"].as_f64().unwrap()).abs() < 1e-10);
    close(
        c.camera_from_xyz.as_flattened(),
        &rows(&e["camera_from_xyz"]),
        1e-9,
        "CM",
    );
    let tm = hdrsynth::sensor::colour::fit::t_from_camera_xyz(&c.camera_from_xyz).unwrap();
    close(tm.as_flattened(), &rows(&e["t"]), 1e-9, "T");
    // With the two calibrations equal to one matrix, the white's CCT is irrelevant: CM is
    // AnalogBalance · CameraCalibration · ColorMatrix exactly (hand-computed for row 0).
    let same = set(synthetic(400, "Cam 1"), 0, 50722, ratios(&CM1, 10000));
    let t = read_dng_tags_bytes(&tiff(&same, false), p).unwrap();
    let c = dng_colour(&t, p).unwrap();
    for j in 0..3 {
        let want = 1.1 * 0.9883 * CM1[j] as f64 / 10000.0;
        assert!((c.camera_from_xyz[0][j] - want).abs() < 1e-12);
    }
}

/// The synthetic levels by hand: BlackLevel 64, 60 / 68, 72 over RGGB plus the mean
/// BlackLevelDeltaH (1 + 3 + 1 + 3) / 4 = 2: R 66, G (60 + 68)/2 + 2 = 66, B 74, the profile's
/// black (64 + 60 + 68 + 72)/4 + 2 = 68, white 4000. So r_R = r_G = (4000 − 66)/(4000 − 68) =
/// 3934/3932 and r_B = 3926/3932; a = S·r, b = O·r².
#[test]
fn noise_profile_converts_to_the_profile_units_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "iso400.dng", &synthetic(400, "Cam 1"));
    let out = dir.path().join("p.toml");
    let cal = calibrate_dng(&DngOptions {
        files: vec![f],
        out: out.clone(),
        name: None,
        noise: true,
    })
    .unwrap();
    let l = &cal.profile.levels;
    assert_eq!(
        (l.black_level, l.white_level, l.bit_depth),
        (68.0, 4000.0, 12)
    );
    assert_eq!(cal.files[0].levels.black, [66.0, 66.0, 74.0]);
    let r = [3934.0 / 3932.0, 3934.0 / 3932.0, 3926.0 / 3932.0];
    let n = &cal.profile.noise[0];
    assert_eq!(n.iso, 400.0);
    for c in 0..3 {
        let (s, o) = (NOISE[2 * c], NOISE[2 * c + 1]);
        assert!((n.a[c] - s * r[c]).abs() < 1e-20, "a[{c}] {}", n.a[c]);
        assert!(
            (n.b[c] - o * r[c] * r[c]).abs() < 1e-22,
            "b[{c}] {}",
            n.b[c]
        );
    }
    // The independent reference agrees.
    let e = &reference()["synthetic"]["expected"]["noise"];
    close(&n.a, &nums(&e["a"]), 1e-18, "a");
    close(&n.b, &nums(&e["b"]), 1e-20, "b");
}

/// CFAPlaneColor 2, 1, 0: plane 0 is blue, so NoiseProfile's first pair is the blue channel's.
/// One black level: every r is 1 and a, b are S, O as given.
#[test]
fn noise_planes_map_to_channels_through_the_cfa_plane_colours() {
    let mut ifds = synthetic(200, "Cam 1");
    ifds = set(ifds, 1, 50710, Val::Byte(vec![2, 1, 0]));
    ifds = set(ifds, 1, 33422, Val::Byte(vec![2, 1, 1, 0]));
    ifds = set(ifds, 1, 50714, Val::Short(vec![64]));
    ifds = without(without(ifds, 50713), 50715);
    let p = Path::new("planes.dng");
    let t = read_dng_tags_bytes(&tiff(&ifds, false), p).unwrap();
    let np = t.noise_per_channel(p).unwrap().unwrap();
    assert_eq!(np, [[2.5e-5, 5.0e-8], [1.5e-5, 3.0e-8], [2.0e-5, 4.0e-8]]);
    let lv = t.channel_levels(p).unwrap();
    assert_eq!(lv.black, [64.0; 3]);
    // One pair for all planes.
    let one = set(ifds, 1, 51041, Val::Double(vec![1e-5, 2e-8]));
    let t = read_dng_tags_bytes(&tiff(&one, false), p).unwrap();
    assert_eq!(t.noise_per_channel(p).unwrap().unwrap(), [[1e-5, 2e-8]; 3]);
}

/// A NoiseProfile no sensor has (1e300, NaN, a negative scale or offset — the DNG SDK's
/// rule) is refused naming the file, the tag and the channel, and no profile is written.
#[test]
fn a_noise_profile_no_sensor_has_is_refused_naming_the_file_and_the_tag() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, Vec<f64>, &str); 4] = [
        ("huge", vec![1e300, 2e-8], "S = 1e300"),
        ("nan", vec![f64::NAN, 2e-8], "non-finite value: [NaN, 2e-8]"),
        ("negative_scale", vec![-1e-5, 2e-8], "S = -1e-5"),
        (
            "negative_offset",
            vec![1.5e-5, 3e-8, 2e-5, -4e-8, 2.5e-5, 5e-8],
            "O = -4e-8",
        ),
    ];
    for (name, np, value) in cases {
        let f = write(
            dir.path(),
            &format!("{name}.dng"),
            &set(synthetic(400, "Cam 1"), 1, 51041, Val::Double(np)),
        );
        let out = dir.path().join(format!("{name}.toml"));
        let e = calibrate_dng(&DngOptions {
            files: vec![f],
            out: out.clone(),
            name: None,
            noise: true,
        })
        .unwrap_err()
        .to_string();
        assert!(
            e.contains(&format!("{name}.dng")) && e.contains("NoiseProfile") && e.contains(value),
            "{name}: {e}"
        );
        assert!(!out.exists(), "{name}: a profile was written");
    }
    // The shipped values pass: S and O of every channel positive and small.
    let ok = write(dir.path(), "ok.dng", &synthetic(400, "Cam 1"));
    let t = read_dng_tags_bytes(&std::fs::read(&ok).unwrap(), &ok).unwrap();
    assert!(t.noise_per_channel(&ok).unwrap().is_some());
}

/// LinearRaw, 3 samples with their own BlackLevel (10, 20, 30) and WhiteLevel (1000, 1010,
/// 1030): black = 20, white = 1000 (the lowest), r = (990, 990, 1000)/980.
#[test]
fn linear_raw_levels_per_sample() {
    let mut ifds = synthetic(100, "Cam 1");
    ifds[1] = vec![
        (254, Val::Long(vec![0])),
        (258, Val::Short(vec![16, 16, 16])),
        (262, Val::Short(vec![34892])),
        (277, Val::Short(vec![3])),
        (50714, Val::Short(vec![10, 20, 30])),
        (50717, Val::Short(vec![1000, 1010, 1030])),
        (51041, Val::Double(vec![1e-5, 2e-8])),
    ];
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "linear.dng", &ifds);
    let cal = calibrate_dng(&DngOptions {
        files: vec![f],
        out: dir.path().join("p.toml"),
        name: Some("linear".into()),
        noise: true,
    })
    .unwrap();
    let l = &cal.profile.levels;
    assert_eq!(
        (l.black_level, l.white_level, l.bit_depth),
        (20.0, 1000.0, 16)
    );
    let r = [990.0 / 980.0, 990.0 / 980.0, 1000.0 / 980.0];
    let n = &cal.profile.noise[0];
    for c in 0..3 {
        assert!((n.a[c] - 1e-5 * r[c]).abs() < 1e-20);
        assert!((n.b[c] - 2e-8 * r[c] * r[c]).abs() < 1e-22);
    }
    assert!(cal.profile.provenance.levels.contains("LinearRaw"));
}

#[test]
fn iso_from_ifd0_and_the_65535_rule() {
    let p = Path::new("iso.dng");
    let ifds = set(
        without(synthetic(100, "Cam 1"), 34665),
        0,
        34855,
        Val::Short(vec![800]),
    );
    assert_eq!(
        read_dng_tags_bytes(&tiff(&ifds, false), p).unwrap().iso,
        Some(800.0)
    );
    let mut ifds = synthetic(65535, "Cam 1");
    ifds[2].push((34866, Val::Long(vec![102400])));
    assert_eq!(
        read_dng_tags_bytes(&tiff(&ifds, false), p).unwrap().iso,
        Some(102400.0)
    );
    let ifds = synthetic(0, "Cam 1");
    assert_eq!(
        read_dng_tags_bytes(&tiff(&ifds, false), p).unwrap().iso,
        None
    );
}

#[test]
fn profile_from_several_dngs_is_sorted_loads_and_drives_realism() {
    let dir = tempfile::tempdir().unwrap();
    let hi = write(dir.path(), "iso400.dng", &synthetic(400, "Cam 1"));
    let mut low = synthetic(100, "Cam 1");
    low = set(low, 1, 51041, Val::Double(vec![5e-6, 1e-8]));
    let lo = write(dir.path(), "iso100.dng", &low);
    let out = dir.path().join("cam.toml");
    let opts = DngOptions {
        files: vec![hi, lo],
        out: out.clone(),
        name: None,
        noise: true,
    };
    let cal = calibrate_dng(&opts).unwrap();
    assert!(!cal.existed);
    let p = SensorProfile::load(&out).unwrap();
    assert_eq!(p.name, "Cam 1");
    assert_eq!(
        p.noise.iter().map(|n| n.iso).collect::<Vec<_>>(),
        vec![100.0, 400.0]
    );
    assert!(p.provenance.colour.contains("iso400.dng") && p.provenance.colour.contains("K"));
    assert!(p.provenance.noise.contains("iso100.dng ISO 100"));
    // Realism at ISO 100 in DN: σ² = S·(W_c − B_c)·I + O·(W_c − B_c)² with the file's own
    // channel levels (R: 4000 − 66 = 3934), whatever the profile's normalisation.
    let r = Realism::new(&p, &RealismOptions::new(100.0)).unwrap();
    let i = 1000.0f32;
    let v = r.variance_dn([i; 3]);
    let want = 5e-6 * 3934.0 * i as f64 + 1e-8 * 3934.0f64.powi(2);
    assert!(
        (v[0] as f64 - want).abs() < 1e-5 * want,
        "{} vs {want}",
        v[0]
    );
    let img = hdrsynth::io::Image::from_fn(4, 4, |x, y| [0.1 * x as f32, 0.2, 0.05 * y as f32]);
    let opts_none = RealismOptions {
        noise: NoiseModel::Gaussian,
        ..RealismOptions::new(400.0)
    };
    let out_img = Realism::new(&p, &opts_none).unwrap().apply(&img, 7);
    assert_eq!((out_img.width, out_img.height), (4, 4));
    // Running again updates the profile and keeps its name.
    let mut renamed = p.clone();
    renamed.name = "kept".into();
    renamed.save(&out).unwrap();
    let cal = calibrate_dng(&opts).unwrap();
    assert!(cal.existed);
    assert_eq!(SensorProfile::load(&out).unwrap().name, "kept");
}

fn err(files: &[PathBuf], out: &Path, noise: bool) -> String {
    calibrate_dng(&DngOptions {
        files: files.to_vec(),
        out: out.to_path_buf(),
        name: None,
        noise,
    })
    .unwrap_err()
    .to_string()
}

#[test]
fn refusals_name_the_file_and_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.toml");
    let d = dir.path();
    // Missing NoiseProfile and ISO: both named, with the file.
    let f = write(
        d,
        "bare.dng",
        &without(without(synthetic(100, "Cam 1"), 51041), 34665),
    );
    let e = err(std::slice::from_ref(&f), &out, true);
    assert!(
        e.contains("bare.dng") && e.contains("NoiseProfile (51041)") && e.contains("ISO"),
        "{e}"
    );
    // Without noise the same file gives a profile with no noise.
    calibrate_dng(&DngOptions {
        files: vec![f],
        out: out.clone(),
        name: None,
        noise: false,
    })
    .unwrap();
    assert!(SensorProfile::load(&out).unwrap().noise.is_empty());
    std::fs::remove_file(&out).unwrap();
    // Missing colour tags.
    let f = write(
        d,
        "nocm.dng",
        &without(without(synthetic(100, "Cam 1"), 50721), 50728),
    );
    let e = err(&[f], &out, true);
    assert!(
        e.contains("nocm.dng") && e.contains("ColorMatrix1 (50721)") && e.contains("AsShotNeutral"),
        "{e}"
    );
    let f = write(d, "noill.dng", &without(synthetic(100, "Cam 1"), 50779));
    let e = err(&[f], &out, true);
    assert!(
        e.contains("noill.dng") && e.contains("CalibrationIlluminant2"),
        "{e}"
    );
    let f = write(
        d,
        "other.dng",
        &set(synthetic(100, "Cam 1"), 0, 50779, Val::Short(vec![255])),
    );
    let e = err(&[f], &out, true);
    assert!(
        e.contains("other.dng") && e.contains("255 (other light source)"),
        "{e}"
    );
    // Mixed models name both files and both models.
    let a = write(d, "a.dng", &synthetic(100, "Cam 1"));
    let b = write(d, "b.dng", &synthetic(200, "Cam 2"));
    let e = err(&[a.clone(), b], &out, true);
    assert!(
        e.contains("a.dng") && e.contains("b.dng") && e.contains("Cam 1") && e.contains("Cam 2"),
        "{e}"
    );
    // Duplicate ISOs name both files.
    let c = write(d, "c.dng", &synthetic(100, "Cam 1"));
    let e = err(&[a, c], &out, true);
    assert!(
        e.contains("a.dng") && e.contains("c.dng") && e.contains("ISO 100"),
        "{e}"
    );
    // A NoiseProfile of 4 values.
    let f = write(
        d,
        "np4.dng",
        &set(
            synthetic(100, "Cam 1"),
            1,
            51041,
            Val::Double(vec![1e-5; 4]),
        ),
    );
    let e = err(&[f], &out, true);
    assert!(
        e.contains("np4.dng") && e.contains("NoiseProfile has 4 values"),
        "{e}"
    );
    // Not a DNG; no raw IFD.
    let f = d.join("text.dng");
    std::fs::write(&f, b"hello").unwrap();
    assert!(err(&[f], &out, true).contains("text.dng"));
    let mut ifds = synthetic(100, "Cam 1");
    ifds[1].retain(|e| e.0 != 262);
    let f = write(d, "noraw.dng", &ifds);
    assert!(err(&[f], &out, true).contains("no raw image IFD"));
    assert!(!out.exists(), "nothing is written on failure");
}

/// Every prefix of a synthetic DNG and every single-byte corruption of its first 512 bytes:
/// an error or a result, never a panic.
#[test]
fn truncated_or_corrupt_files_never_panic() {
    let bytes = tiff(&synthetic(100, "Cam 1"), false);
    let p = Path::new("bad.dng");
    for n in 0..bytes.len() {
        let _ = read_dng_tags_bytes(&bytes[..n], p);
    }
    for i in 0..bytes.len().min(512) {
        for v in [0x00u8, 0xff, 0x7f] {
            let mut b = bytes.clone();
            b[i] = v;
            if let Ok(t) = read_dng_tags_bytes(&b, p) {
                let _ = dng_colour(&t, p);
                let _ = t.channel_levels(p);
                let _ = t.noise_per_channel(p);
            }
        }
    }
}

// --- the real files ----------------------------------------------------------------------------

mod common;
use common::shared_data as shared;

fn opt_str(v: &Value) -> Option<String> {
    v.as_str().map(String::from)
}

/// Every tag against tifffile's reading, exactly; colour, levels and noise against the numpy
/// reference.
#[test]
#[ignore = "needs ../shared/data"]
fn real_dng_tags_match_tifffile_and_the_reference() {
    let r = reference();
    for (name, rec) in r["files"].as_object().unwrap() {
        let path = shared(rec["file"].as_str().unwrap());
        let t = read_dng_tags(&path).unwrap();
        assert_eq!(t.make, opt_str(&rec["make"]), "{name}");
        assert_eq!(t.model, opt_str(&rec["model"]), "{name}");
        assert_eq!(
            t.unique_camera_model,
            opt_str(&rec["unique_camera_model"]),
            "{name}"
        );
        assert_eq!(t.iso, rec["iso"].as_f64(), "{name}");
        assert_eq!(
            t.bits_per_sample as u64,
            rec["bits_per_sample"].as_u64().unwrap()
        );
        let linear = matches!(t.layout, RawLayout::LinearRaw { samples: 3 });
        assert_eq!(linear, rec["photometric"].as_u64() == Some(34892), "{name}");
        for (k, key) in ["color_matrix1", "color_matrix2"].iter().enumerate() {
            let want = (!rec[key].is_null()).then(|| quotients(&rec[key]));
            assert_eq!(
                t.color_matrix[k].map(|m| m.as_flattened().to_vec()),
                want,
                "{name} {key}"
            );
        }
        for (k, key) in ["camera_calibration1", "camera_calibration2"]
            .iter()
            .enumerate()
        {
            let want = (!rec[key].is_null()).then(|| quotients(&rec[key]));
            let got = t.camera_calibration[k].map(|m| m.as_flattened().to_vec());
            assert_eq!(got, want, "{name} {key}");
        }
        for (k, key) in ["calibration_illuminant1", "calibration_illuminant2"]
            .iter()
            .enumerate()
        {
            assert_eq!(
                t.calibration_illuminant[k].map(u64::from),
                rec[*key].as_u64(),
                "{name}"
            );
        }
        let sig = |key: &str| opt_str(&rec[key]);
        assert_eq!(
            t.camera_calibration_signature,
            sig("camera_calibration_signature")
        );
        assert_eq!(
            t.profile_calibration_signature,
            sig("profile_calibration_signature")
        );
        let v3 = |key: &str| (!rec[key].is_null()).then(|| quotients(&rec[key]));
        assert_eq!(
            t.analog_balance.map(|v| v.to_vec()),
            v3("analog_balance"),
            "{name}"
        );
        assert_eq!(
            t.as_shot_neutral.map(|v| v.to_vec()),
            v3("as_shot_neutral"),
            "{name}"
        );
        assert_eq!(
            t.black_level.clone().unwrap_or(vec![0.0]),
            quotients(&rec["black_level"])
        );
        let rep = nums(&rec["black_level_repeat"]);
        assert_eq!(
            t.black_level_repeat.map(|v| v as f64).to_vec(),
            rep,
            "{name}"
        );
        assert_eq!(t.white_level, Some(nums(&rec["white_level"])), "{name}");
        let bits: Option<Vec<f64>> = rec["noise_profile_bits"].as_array().map(|a| {
            a.iter()
                .map(|b| f64::from_bits(b.as_u64().unwrap()))
                .collect()
        });
        assert_eq!(t.noise_profile, bits, "{name} NoiseProfile");
        assert_eq!(t.plane_colours, vec![0, 1, 2]);
        // Colour, levels, noise.
        let e = &rec["expected"];
        let c = dng_colour(&t, &path).unwrap();
        assert!(
            (c.cct - e["cct"].as_f64().unwrap()).abs() < 1e-6,
            "{name} CCT {}",
            c.cct
        );
        close(
            c.camera_from_xyz.as_flattened(),
            &rows(&e["camera_from_xyz"]),
            1e-9,
            name,
        );
        let tm = hdrsynth::sensor::colour::fit::t_from_camera_xyz(&c.camera_from_xyz).unwrap();
        close(tm.as_flattened(), &rows(&e["t"]), 1e-9, name);
        let lv = t.channel_levels(&path).unwrap().levels;
        let el = &e["levels"];
        assert_eq!(
            lv.black_level,
            el["black_level"].as_f64().unwrap(),
            "{name}"
        );
        assert_eq!(
            lv.white_level,
            el["white_level"].as_f64().unwrap(),
            "{name}"
        );
        assert_eq!(
            lv.bit_depth as u64,
            el["bit_depth"].as_u64().unwrap(),
            "{name}"
        );
        if let Some(np) = t.noise_per_channel(&path).unwrap() {
            let lv = t.channel_levels(&path).unwrap();
            let row = hdrsynth::sensor::dng::profile::noise_row(1.0, &np, &lv, &lv.levels);
            close(&row.a, &nums(&e["noise"]["a"]), 1e-18, name);
            close(&row.b, &nums(&e["noise"]["b"]), 1e-20, name);
        }
    }
}

#[test]
#[ignore = "needs ../shared/data"]
fn real_dngs_make_profiles_or_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.toml");
    let six_d = shared("real_raw/dng_tags/canon_eos_6d.dng");
    let iphone = shared("real_raw/dng_tags/iphone12pro_IMG_1361.dng");
    let chart = shared("real_raw/colorchart.dng");
    for (f, iso) in [(&six_d, 1000.0), (&iphone, 32.0)] {
        let _ = std::fs::remove_file(&out);
        let cal = calibrate_dng(&DngOptions {
            files: vec![f.clone()],
            out: out.clone(),
            name: None,
            noise: true,
        })
        .unwrap();
        let p = SensorProfile::load(&out).unwrap();
        assert_eq!(p.noise[0].iso, iso);
        assert!(Realism::new(&p, &RealismOptions::new(iso)).is_ok());
        assert!(!cal.report().is_empty());
    }
    // The 550D chart capture: no NoiseProfile, ISO 0 (not recorded).
    let e = err(std::slice::from_ref(&chart), &out, true);
    assert!(
        e.contains("colorchart.dng") && e.contains("NoiseProfile") && e.contains("ISO"),
        "{e}"
    );
    let _ = std::fs::remove_file(&out);
    calibrate_dng(&DngOptions {
        files: vec![chart],
        out: out.clone(),
        name: None,
        noise: false,
    })
    .unwrap();
    let p = SensorProfile::load(&out).unwrap();
    assert_eq!(p.levels.black_level, 2056.0);
    assert!(p.provenance.colour.contains("ColorMatrix1 alone"));
    let e = err(&[six_d, iphone], &out, true);
    assert!(
        e.contains("Canon EOS 6D") && e.contains("iPhone13,3 back camera"),
        "{e}"
    );
}
