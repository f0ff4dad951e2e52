//! Evaluation metrics against the field's Python convention (oracle values computed with
//! scikit-image on the committed crops in tests/data/oracle_crops and, where it exists, on
//! ../shared/data/oracles), hand values, PU21, ΔE2000 against colour-science and
//! Sharma et al.'s published CIEDE2000 table (tests/data/delta_e_reference.json, written by
//! tools/delta_e_reference.py), PSNR-T over the under-exposed pixels, and the bootstrap.

use hdrsynth::error::Error;
use hdrsynth::eval::metrics::{
    self, DARK_CODE, MU, MetricOptions, PixelMask, Pu21Scale, mu_law, psnr, pu21_encode, score,
    score_pair, ssim,
};
use hdrsynth::io::{Image, read_image};
use hdrsynth::rng::Rng;
use hdrsynth::sensor::colour::cie;
use hdrsynth::stats::bootstrap_ci;
use std::path::{Path, PathBuf};

mod common;

/// The oracle folder (scikit-image's outputs; conventions in its oracles.json).
fn oracle_dir() -> PathBuf {
    common::shared_data("oracles/oracles.json")
        .parent()
        .expect("parent")
        .to_path_buf()
}

const CASES: [&str; 6] = [
    "desk_noise",
    "desk_gain",
    "desk_blur",
    "carrots_noise",
    "carrots_gain",
    "carrots_blur",
];

/// PU21 (ReferenceMax, peak 4000) from tools/metrics_reference.py: a numpy transcription of
/// pu21's MATLAB pu21_metric (PSNR over RGB, peak 256; MATLAB-style SSIM of PU luminance).
const PU21_REF: [(&str, f64, f64); 6] = [
    ("desk_noise", 10.028119858750378, 0.34490662002262434),
    ("desk_gain", 38.4744995756787, 0.9992280465520751),
    ("desk_blur", 18.345229273739925, 0.7520288656921813),
    ("carrots_noise", 24.271493973066676, 0.9410241492057004),
    ("carrots_gain", 34.40821985788024, 0.9998992804053741),
    ("carrots_blur", 25.393857564639415, 0.8636912256947583),
];

/// Scores each of [`CASES`] in `DIR/oracles.json` ("metrics"."cases": gt, pred and the
/// scikit-image values) and checks PSNR-L/T, SSIM-L/T and PU21 PSNR/SSIM to `tol`; `pu21(case,
/// oracle case)` gives the PU21 references. Prints the largest |diff| of each metric.
fn check_metric_oracles(
    dir: &Path,
    tol: f64,
    pu21: impl Fn(&str, &serde_json::Value) -> (f64, f64),
) {
    let text = std::fs::read_to_string(dir.join("oracles.json")).unwrap();
    let oracles: serde_json::Value = serde_json::from_str(&text).expect("oracles.json");
    let mut worst = [0.0f64; 6];
    for case in CASES {
        let o = &oracles["metrics"]["cases"][case];
        let number = |key: &str| o[key].as_f64().unwrap_or_else(|| panic!("{case}.{key}"));
        let file = |key: &str| dir.join(o[key].as_str().unwrap_or_else(|| panic!("{case}.{key}")));
        let gt = read_image(&file("gt")).unwrap();
        let pred = read_image(&file("pred")).unwrap();
        let s = score(&gt, &pred, None, &MetricOptions::default()).unwrap();
        let (pu_psnr, pu_ssim) = pu21(case, o);
        let want = [
            number("psnr_l"),
            number("psnr_t"),
            number("ssim_l"),
            number("ssim_t"),
            pu_psnr,
            pu_ssim,
        ];
        let got = [
            s.psnr_l,
            s.psnr_t,
            s.ssim_l,
            s.ssim_t,
            s.pu21_psnr,
            s.pu21_ssim,
        ];
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            let d = (g - w).abs();
            worst[i] = worst[i].max(d);
            assert!(
                d <= tol,
                "{case} metric #{i}: got {g}, want {w} (|diff| {d:e}, limit {tol:e})"
            );
        }
    }
    println!(
        "max |diff| psnr_l {:e} psnr_t {:e} ssim_l {:e} ssim_t {:e} pu21_psnr {:e} pu21_ssim {:e}",
        worst[0], worst[1], worst[2], worst[3], worst[4], worst[5]
    );
}

#[test]
#[ignore = "needs ../shared/data"]
fn oracle_cases_match_skimage_to_1e6() {
    check_metric_oracles(&oracle_dir(), 1e-6, |case, _| {
        let (_, psnr, ssim) = PU21_REF
            .iter()
            .find(|(n, ..)| *n == case)
            .unwrap_or_else(|| panic!("no PU21 reference for {case}"));
        (*psnr, *ssim)
    });
}

/// The same cases (noise, gain, blur predictions of Desk and Carrots) on the committed 64×48
/// crops: scikit-image PSNR/SSIM and the numpy PU21 transcription, stored in the crops'
/// oracles.json by tools/oracle_crops.py.
#[test]
fn crop_metrics_match_skimage_and_pu21_to_1e9() {
    let dir = common::oracle_crops("oracles.json")
        .parent()
        .expect("parent")
        .to_path_buf();
    // Both sides are f64 on the same f32 pixels: they agree to ~1e-13.
    check_metric_oracles(&dir, 1e-9, |case, o| {
        let n = |k: &str| o[k].as_f64().unwrap_or_else(|| panic!("{case}.{k}"));
        (n("pu21_psnr"), n("pu21_ssim"))
    });
}

fn ramp(w: usize, h: usize) -> Image {
    Image::from_fn(w, h, |x, y| {
        let v = ((x * 7 + y * 13) % 97) as f32 / 97.0;
        [v * 0.8, (v * v).min(0.9), 0.9 - v * 0.5]
    })
}

// --- ΔE2000 ----------------------------------------------------------------------------------

fn delta_e_reference() -> serde_json::Value {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/delta_e_reference.json");
    serde_json::from_str(&std::fs::read_to_string(&p).expect("delta_e_reference.json"))
        .expect("json")
}

fn vec3(v: &serde_json::Value) -> [f64; 3] {
    let a = v.as_array().expect("array of 3");
    assert_eq!(a.len(), 3);
    std::array::from_fn(|i| a[i].as_f64().expect("number"))
}

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().expect("number")
}

/// The 34 pairs of Sharma, Wu & Dalal (2005), Table 1: CIEDE2000 within the table's rounding
/// (4 decimals) of the published values, and within 1e-6 of colour-science, either order.
#[test]
fn ciede2000_matches_sharmas_table_and_colour_science() {
    let o = delta_e_reference();
    let pairs = o["sharma"].as_array().expect("sharma");
    assert_eq!(pairs.len(), 34);
    let (mut worst_table, mut worst_cs) = (0.0f64, 0.0f64);
    for (k, p) in pairs.iter().enumerate() {
        let (l1, l2) = (vec3(&p["lab1"]), vec3(&p["lab2"]));
        for got in [cie::delta_e_2000(l1, l2), cie::delta_e_2000(l2, l1)] {
            let (table, cs) = (num(&p["published"]), num(&p["colour_science"]));
            assert!(
                (got - table).abs() <= 5e-5 + 1e-12,
                "pair {}: {got} vs published {table}",
                k + 1
            );
            assert!(
                (got - cs).abs() <= 1e-6,
                "pair {}: {got} vs colour-science {cs}",
                k + 1
            );
            worst_table = worst_table.max((got - table).abs());
            worst_cs = worst_cs.max((got - cs).abs());
        }
    }
    println!("Sharma pairs: max |diff| published {worst_table:e}, colour-science {worst_cs:e}");
}

/// Display RGB read as sRGB (greys, saturated colours, values above 1, a small negative,
/// random): Lab and ΔE00 within 1e-6 of colour-science's sRGB_to_XYZ → XYZ_to_Lab → delta_E.
#[test]
fn display_lab_and_delta_e_match_colour_science() {
    let o = delta_e_reference();
    let white = vec3(&o["white_xyz"]);
    let mine = cie::srgb_white();
    assert!(
        (0..3).all(|c| (white[c] - mine[c]).abs() < 1e-12),
        "{mine:?}"
    );
    let pairs = o["display_pairs"].as_array().expect("display_pairs");
    assert!(pairs.len() >= 20);
    let (mut worst_lab, mut worst_de) = (0.0f64, 0.0f64);
    for (k, p) in pairs.iter().enumerate() {
        let (a, b) = (
            cie::display_srgb_to_lab(vec3(&p["rgb1"])),
            cie::display_srgb_to_lab(vec3(&p["rgb2"])),
        );
        for (got, want) in [(a, vec3(&p["lab1"])), (b, vec3(&p["lab2"]))] {
            for c in 0..3 {
                let d = (got[c] - want[c]).abs();
                assert!(d <= 1e-6, "pair {k}: Lab {got:?} vs {want:?}");
                worst_lab = worst_lab.max(d);
            }
        }
        let de = cie::delta_e_2000(a, b);
        let want = num(&p["delta_e"]);
        assert!((de - want).abs() <= 1e-6, "pair {k}: {de} vs {want}");
        worst_de = worst_de.max((de - want).abs());
    }
    // Display greys are neutral, white is L* = 100.
    let grey = cie::display_srgb_to_lab([0.5; 3]);
    assert!(grey[1].abs() < 1e-9 && grey[2].abs() < 1e-9, "{grey:?}");
    assert!((cie::display_srgb_to_lab([1.0; 3])[0] - 100.0).abs() < 1e-9);
    println!("display pairs: max |diff| Lab {worst_lab:e}, ΔE00 {worst_de:e}");
}

/// The metric on images: mean over pixels of ΔE00 of the μ-law images (numpy's μ-law, then
/// colour-science), through `delta_e2000_mu` and `score`.
#[test]
fn delta_e2000_of_mu_law_images_matches_colour_science() {
    let o = delta_e_reference();
    let cases = o["mu_law_images"].as_array().expect("mu_law_images");
    assert_eq!(cases.len(), 2);
    for (k, c) in cases.iter().enumerate() {
        let (w, h) = (num(&c["width"]) as usize, num(&c["height"]) as usize);
        let img = |key: &str| {
            let v: Vec<f32> = c[key]
                .as_array()
                .expect("values")
                .iter()
                .map(|x| num(x) as f32)
                .collect();
            Image::from_vec(w, h, v)
        };
        let (gt, pred) = (img("gt"), img("pred"));
        let want = num(&c["mean_delta_e"]);
        let got = metrics::delta_e2000_mu(&gt, &pred).unwrap();
        assert!((got - want).abs() <= 1e-6, "case {k}: {got} vs {want}");
        println!("μ-law image {k}: ΔE00 {got} vs colour-science {want}");
        assert_eq!(metrics::delta_e2000_mu(&gt, &gt).unwrap(), 0.0);
    }
    // Through `score` (needs 11×11 for SSIM): a grey ramp against itself tinted.
    let gt = ramp(16, 12);
    let s = score(&gt, &gt, None, &MetricOptions::default()).unwrap();
    assert_eq!(s.delta_e2000, 0.0);
    let tinted = gt.map(|v| v * 0.9);
    let s = score(&gt, &tinted, None, &MetricOptions::default()).unwrap();
    assert_eq!(
        s.delta_e2000,
        metrics::delta_e2000_mu(&gt, &tinted).unwrap()
    );
    assert!(s.delta_e2000 > 0.0);
}

// --- PSNR-T over the under-exposed pixels -------------------------------------------------------

/// A 20×20 reference frame whose first `n_dark` pixels (row-major) are under-exposed, the
/// others not: their largest channel is exactly DARK_CODE (not below it) or bright.
fn frame_with_dark(n_dark: usize) -> Image {
    Image::from_fn(20, 20, |x, y| {
        let i = y * 20 + x;
        if i < n_dark {
            [0.05, 0.099, 0.0]
        } else if i % 2 == 0 {
            [0.0, DARK_CODE, 0.02]
        } else {
            [0.8, 0.6, 0.3]
        }
    })
}

/// Ground truth 0 everywhere; the prediction's masked pixels are (1, 0, 0) (μ-law T = (1, 0, 0)
/// exactly), the others 1 in every channel, so including them would change the value.
#[test]
fn psnr_t_dark_is_the_hand_computed_psnr_over_the_masked_pixels() {
    let n_dark = 40;
    let dark = PixelMask::from_frame(&frame_with_dark(n_dark)).unwrap();
    assert_eq!(dark.count(), n_dark);
    assert_eq!(dark.fraction(), 0.1);
    let gt = Image::new(20, 20);
    let pred = Image::from_fn(20, 20, |x, y| {
        if y * 20 + x < n_dark {
            [1.0, 0.0, 0.0]
        } else {
            [1.0, 1.0, 1.0]
        }
    });
    assert_eq!(mu_law(1.0), 1.0);
    // PU21 scaled by value, not by the ground truth's maximum (0 here).
    let opts = MetricOptions {
        pu21_scale: Pu21Scale::UnitValue,
        ..MetricOptions::default()
    };
    let s = score(&gt, &pred, Some(&dark), &opts).unwrap();
    // Masked MSE over three channels: (1 + 0 + 0) / 3.
    let hand = 10.0 * 3f64.log10();
    let got = s.psnr_t_dark.expect("10 % of the pixels are dark");
    assert!((got - hand).abs() < 1e-12, "{got} vs {hand}");
    assert_eq!(s.dark_fraction, Some(0.1));
    // The whole image: MSE (40 · 1 + 360 · 3) / 1200.
    let whole = 10.0 * (1200.0f64 / (40.0 + 360.0 * 3.0)).log10();
    assert!((s.psnr_t - whole).abs() < 1e-12, "{} vs {whole}", s.psnr_t);

    // Network-1's path: PSNR of the given T images over the same pixels. Masked errors
    // (0.125, 0, 0.25): MSE (1/64 + 1/16) / 3, PSNR = 10 log10(38.4).
    let gt_t = Image::from_fn(20, 20, |_, _| [0.5; 3]);
    let pred_t = Image::from_fn(20, 20, |x, y| {
        if y * 20 + x < n_dark {
            [0.625, 0.5, 0.75]
        } else {
            [0.0; 3]
        }
    });
    let p = score_pair(&gt, &pred, &gt_t, &pred_t, Some(&dark), &opts).unwrap();
    let got = p.psnr_t_dark.expect("dark");
    assert!((got - 10.0 * 38.4f64.log10()).abs() < 1e-12, "{got}");
    assert_eq!(p.dark_fraction, Some(0.1));
}

/// Fewer than 1 % of the pixels masked (or none): no value, but the fraction is reported;
/// exactly 1 % gives a value. Without a mask both are absent.
#[test]
fn psnr_t_dark_is_absent_below_one_percent_of_dark_pixels() {
    let gt = ramp(20, 20);
    let pred = gt.map(|v| v * 0.8);
    let opts = MetricOptions::default();
    let at = |n: usize| {
        let dark = PixelMask::from_frame(&frame_with_dark(n)).unwrap();
        score(&gt, &pred, Some(&dark), &opts).unwrap()
    };
    let none = at(0);
    assert_eq!((none.psnr_t_dark, none.dark_fraction), (None, Some(0.0)));
    let three = at(3);
    assert_eq!(
        (three.psnr_t_dark, three.dark_fraction),
        (None, Some(0.0075))
    );
    let four = at(4);
    assert_eq!(four.dark_fraction, Some(0.01));
    assert!(four.psnr_t_dark.is_some_and(f64::is_finite), "{four:?}");
    let unmasked = score(&gt, &pred, None, &opts).unwrap();
    assert_eq!((unmasked.psnr_t_dark, unmasked.dark_fraction), (None, None));
    // Identical images over the mask: +inf, as PSNR-T.
    let dark = PixelMask::from_frame(&frame_with_dark(40)).unwrap();
    let same = score(&gt, &gt, Some(&dark), &opts).unwrap();
    assert_eq!(same.psnr_t_dark, Some(f64::INFINITY));
}

#[test]
fn a_mask_of_another_size_is_an_error_naming_both_sizes() {
    let dark = PixelMask::from_frame(&frame_with_dark(40)).unwrap();
    let gt = ramp(24, 20);
    let msg = score(&gt, &gt, Some(&dark), &MetricOptions::default())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("20x20") && msg.contains("24x20"), "{msg}");
}

#[test]
fn psnr_of_constant_offset_is_20_db() {
    let gt = ramp(40, 30);
    let pred = gt.map(|v| v + 0.1);
    let p = psnr(&gt, &pred, 1.0).unwrap();
    // f32 storage makes the offset 0.1 only to ~1e-8, i.e. ~1e-6 dB.
    assert!((p - 20.0).abs() < 1e-5, "{p}");
    // Range 2 adds 20·log10(2).
    let p2 = psnr(&gt, &pred, 2.0).unwrap();
    assert!((p2 - p - 20.0 * 2f64.log10()).abs() < 1e-9);
}

#[test]
fn identical_images_give_infinite_psnr_and_unit_ssim() {
    let gt = ramp(64, 48);
    let s = score(&gt, &gt, None, &MetricOptions::default()).unwrap();
    assert_eq!(s.psnr_l, f64::INFINITY);
    assert_eq!(s.psnr_t, f64::INFINITY);
    assert_eq!(s.pu21_psnr, f64::INFINITY);
    for v in [s.ssim_l, s.ssim_t, s.pu21_ssim] {
        assert!((v - 1.0).abs() < 1e-12, "{v}");
    }
}

#[test]
fn ssim_saturates_above_one_and_drops_with_noise() {
    let gt = ramp(64, 48);
    // Everything above 1 clips to 255: two different over-range images are identical to SSIM.
    let a = gt.map(|v| v + 2.0);
    let b = gt.map(|v| v + 3.0);
    assert!((ssim(&a, &b).unwrap() - 1.0).abs() < 1e-12);
    let mut r = Rng::new(3);
    let noisy = gt.map(|v| v);
    let noisy = Image::from_vec(
        noisy.width,
        noisy.height,
        noisy
            .data
            .iter()
            .map(|&v| v + r.range(-0.05, 0.05))
            .collect(),
    );
    let s = ssim(&gt, &noisy).unwrap();
    assert!(s > 0.3 && s < 0.99, "{s}");
}

#[test]
fn mismatched_sizes_error_names_both() {
    let a = ramp(32, 24);
    let b = ramp(24, 32);
    let err = score(&a, &b, None, &MetricOptions::default()).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, Error::Invalid(_)));
    assert!(msg.contains("32x24") && msg.contains("24x32"), "{msg}");
    assert!(psnr(&a, &b, 1.0).is_err());
    assert!(ssim(&a, &b).is_err());
}

#[test]
fn bad_inputs_are_clear_errors() {
    let gt = ramp(32, 24);
    let mut nan = gt.clone();
    nan.data[3 * (5 * 32 + 7) + 1] = f32::NAN;
    let msg = score(&gt, &nan, None, &MetricOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("non-finite") && msg.contains("x=7, y=5"),
        "{msg}"
    );
    // Below −1/μ the μ-law is undefined.
    let neg = gt.map(|v| v - 0.5);
    let msg = score(&gt, &neg, None, &MetricOptions::default())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("mu-law"), "{msg}");
    // SSIM needs the 11×11 window.
    let tiny = ramp(10, 20);
    assert!(
        ssim(&tiny, &tiny)
            .unwrap_err()
            .to_string()
            .contains("11x11")
    );
    assert!(psnr(&gt, &gt, 0.0).is_err());
}

#[test]
fn mu_law_values() {
    assert_eq!(mu_law(0.0), 0.0);
    assert!((mu_law(1.0) - 1.0).abs() < 1e-15);
    let x = 0.01;
    assert!((mu_law(x) - (1.0 + MU * x).ln() / 5001f64.ln()).abs() < 1e-15);
}

#[test]
fn pu21_encoder_values() {
    // From the pu21 formula with the banding_glare parameters (tools/metrics_reference.py).
    let cases = [
        (0.001, 5.470456654038225e-10), // clamped to L_min = 0.005
        (0.005, 5.470456654038225e-10),
        (0.1, 5.717073839669447),
        (1.0, 36.5439111394192),
        (10.0, 123.64748355384738),
        (100.0, 256.3838973127039), // ~256 at 100 cd/m²: an SDR display's range
        (1000.0, 420.0969213492443),
        (4000.0, 527.4939005367281),
        (10000.0, 595.393920020095),
        (20000.0, 595.393920020095), // clamped to L_max = 10000
    ];
    for (y, v) in cases {
        let got = pu21_encode(y);
        assert!(
            (got - v).abs() <= 1e-9 * v.max(1.0),
            "encode({y}) = {got}, want {v}"
        );
    }
}

#[test]
fn pu21_scaling_options() {
    let gt = ramp(32, 24);
    let pred = gt.map(|v| v * 0.9);
    let max = gt.data.iter().fold(0f32, |m, &v| m.max(v)) as f64;
    let opts = MetricOptions::default();
    assert_eq!(opts.peak_luminance, 4000.0);
    assert!((metrics::pu21_scale_factor(&gt, &opts).unwrap() - 4000.0 / max).abs() < 1e-9);
    let unit = MetricOptions {
        pu21_scale: Pu21Scale::UnitValue,
        ..opts
    };
    assert_eq!(metrics::pu21_scale_factor(&gt, &unit).unwrap(), 4000.0);
    // ReferenceMax is invariant to the images' common exposure.
    let a = metrics::pu21_psnr(&gt, &pred, &opts).unwrap();
    let b = metrics::pu21_psnr(&gt.map(|v| v * 4.0), &pred.map(|v| v * 4.0), &opts).unwrap();
    assert!((a - b).abs() < 1e-4, "{a} vs {b}");
    let black = Image::new(32, 24);
    assert!(metrics::pu21_psnr(&black, &black, &opts).is_err());
}

#[test]
fn score_pair_uses_given_tonemapped_images() {
    let gt = ramp(48, 40);
    let pred = gt.map(|v| v * 0.95 + 0.01);
    let opts = MetricOptions::default();
    let curve = |v: f32| (mu_law(v as f64)) as f32;
    let s = score(&gt, &pred, None, &opts).unwrap();
    let p = score_pair(&gt, &pred, &gt.map(curve), &pred.map(curve), None, &opts).unwrap();
    assert_eq!((s.psnr_l, s.ssim_l), (p.psnr_l, p.ssim_l));
    assert_eq!((s.pu21_psnr, s.pu21_ssim), (p.pu21_psnr, p.pu21_ssim));
    // Only f32 rounding of the tonemapped values separates the two.
    assert!(
        (s.psnr_t - p.psnr_t).abs() < 1e-3,
        "{} {}",
        s.psnr_t,
        p.psnr_t
    );
    assert!(
        (s.ssim_t - p.ssim_t).abs() < 1e-5,
        "{} {}",
        s.ssim_t,
        p.ssim_t
    );
    assert!(
        (s.delta_e2000 - p.delta_e2000).abs() < 1e-4,
        "{} {}",
        s.delta_e2000,
        p.delta_e2000
    );
    let small = ramp(40, 40);
    assert!(score_pair(&gt, &pred, &small, &small, None, &opts).is_err());
}

#[test]
fn bootstrap_constant_sample_has_zero_width() {
    let v = vec![0.1; 25];
    let (m, lo, hi) = bootstrap_ci(&v, 1000, 42, 0.95);
    assert_eq!(lo, m);
    assert_eq!(hi, m);
    assert!((m - 0.1).abs() < 1e-15);
}

#[test]
fn bootstrap_matches_normal_interval_and_is_deterministic() {
    // n = 400 normal draws (Box–Muller), mean 30, sd 2.
    let mut r = Rng::new(11);
    let n = 400;
    let xs: Vec<f64> = (0..n)
        .map(|_| {
            let u1 = 1.0 - r.f32() as f64;
            let u2 = r.f32() as f64;
            30.0 + 2.0 * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        })
        .collect();
    let mean = xs.iter().sum::<f64>() / n as f64;
    let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
    let half = 1.96 * sd / (n as f64).sqrt();
    let (m, lo, hi) = bootstrap_ci(&xs, 4000, 7, 0.95);
    assert!((m - mean).abs() < 1e-12);
    assert!(lo < m && m < hi);
    // Loose: the percentile bootstrap of a mean is close to the normal interval.
    assert!(
        (m - lo - half).abs() < 0.15 * half,
        "lo {lo} mean {m} half {half}"
    );
    assert!(
        (hi - m - half).abs() < 0.15 * half,
        "hi {hi} mean {m} half {half}"
    );
    assert_eq!(bootstrap_ci(&xs, 4000, 7, 0.95), (m, lo, hi));
    assert_ne!(bootstrap_ci(&xs, 4000, 8, 0.95), (m, lo, hi));
    // Edge cases.
    let (a, b, c) = bootstrap_ci(&[], 100, 1, 0.9);
    assert!(a.is_nan() && b.is_nan() && c.is_nan());
    assert_eq!(bootstrap_ci(&[3.0], 100, 1, 0.9), (3.0, 3.0, 3.0));
}
