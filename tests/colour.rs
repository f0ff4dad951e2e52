//! Colour calibration: colour maths and fits against colour-science oracles (committed in
//! tests/data/oracle_crops, and those of ../shared/data where it exists), recovery of a known
//! T from a noisy chart, leave-one-out, homography sampling, clipping, the DNG reader and the
//! `calibrate colour` command end to end.
#![allow(clippy::needless_range_loop)]

use hdrsynth::io::{Image, write_exr};
use hdrsynth::rng::Rng;
use hdrsynth::sensor::colour::calibrate::{CalibrateOptions, SyntheticChart, run};
use hdrsynth::sensor::colour::chart::{self, COLORCHECKER24, ChartRegion, Homography, Illuminant};
use hdrsynth::sensor::colour::cie;
use hdrsynth::sensor::colour::fit::{self, Model, WhiteBalance};
use hdrsynth::sensor::dng::{read_dng, read_dng_info, read_dng_mosaic};
use hdrsynth::sensor::profile::{
    Levels, NoiseAtIso, PROFILE_FORMAT, ProfileKind, Provenance, Response, SensorProfile,
};
use std::path::Path;

mod common;
use common::shared_data;

// --- oracles.json through serde_json, with accessors that panic naming what is missing -------

use serde_json::Value;

trait Oracle {
    fn key(&self, key: &str) -> &Value;
    fn arr(&self) -> &[Value];
    fn num(&self) -> f64;
    fn vec3(&self) -> [f64; 3] {
        let a = self.arr();
        assert_eq!(a.len(), 3);
        [a[0].num(), a[1].num(), a[2].num()]
    }
    fn rows3(&self) -> Vec<[f64; 3]> {
        self.arr().iter().map(|r| r.vec3()).collect()
    }
    fn matrix(&self) -> Vec<Vec<f64>> {
        self.arr()
            .iter()
            .map(|r| r.arr().iter().map(|v| v.num()).collect())
            .collect()
    }
}

impl Oracle for Value {
    fn key(&self, key: &str) -> &Value {
        self.get(key).unwrap_or_else(|| panic!("no key {key}"))
    }
    fn arr(&self) -> &[Value] {
        self.as_array().expect("not an array")
    }
    fn num(&self) -> f64 {
        self.as_f64().expect("not a number")
    }
}

fn read_oracles(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).expect("oracles.json")
}

/// ../shared/data's oracles.json.
fn oracles() -> Value {
    read_oracles(&shared_data("oracles/oracles.json"))
}

/// The committed oracles.json (tools/oracle_crops.py): its own 40 random Lab pairs and a
/// simulated camera's chart values, computed with the same colour-science calls.
fn crop_oracles() -> Value {
    read_oracles(&common::oracle_crops("oracles.json"))
}

// --- oracles -------------------------------------------------------------------------------------

/// Our ΔE00 on the 40 Lab pairs of an oracles.json ("delta_e_2000") against colour-science's,
/// both ways round, to `tol`.
fn check_delta_e_oracles(o: &Value, tol: f64) {
    let pairs = o.key("delta_e_2000").arr();
    assert_eq!(pairs.len(), 40);
    let mut worst = 0f64;
    for (k, p) in pairs.iter().enumerate() {
        let (l1, l2, want) = (
            p.key("lab1").vec3(),
            p.key("lab2").vec3(),
            p.key("de00").num(),
        );
        let got = cie::delta_e_2000(l1, l2);
        assert!((got - want).abs() < tol, "pair {k}: {got} vs {want}");
        // Symmetric.
        let swapped = cie::delta_e_2000(l2, l1);
        assert!((swapped - want).abs() < tol, "pair {k} swapped");
        worst = worst.max((got - want).abs()).max((swapped - want).abs());
    }
    println!("ΔE00: max |diff| {worst:e}");
}

#[test]
#[ignore = "needs ../shared/data"]
fn delta_e_2000_matches_colour_science_on_40_pairs() {
    check_delta_e_oracles(&oracles(), 1e-6);
}

#[test]
fn delta_e_2000_matches_colour_science_on_40_committed_pairs() {
    // Both are f64 evaluations of one formula: agreement to ~1e-14 is expected.
    check_delta_e_oracles(&crop_oracles(), 1e-10);
}

#[test]
fn delta_e_2000_edge_cases() {
    // Identical colours, zero chroma on one side, hue wrap-around (Sharma 2005 test pairs 7, 17).
    assert_eq!(cie::delta_e_2000([50.0, 0.0, 0.0], [50.0, 0.0, 0.0]), 0.0);
    let d = cie::delta_e_2000([50.0, 0.0, 0.0], [50.0, -1.0, 2.0]);
    assert!((d - 2.3669).abs() < 1e-4, "{d}");
    let d = cie::delta_e_2000([50.0, 2.5, 0.0], [73.0, 25.0, -18.0]);
    assert!((d - 27.1492).abs() < 1e-4, "{d}");
    let d = cie::delta_e_2000([2.0776, 0.0795, -1.135], [0.9033, -0.0636, -0.5514]);
    assert!((d - 0.9082).abs() < 1e-4, "{d}");
}

/// Our 3×3 least-squares and degree-2 root-polynomial fits of an oracles.json's
/// "colour_correction" sets against colour-science's `matrix_colour_correction`, to `tol`.
fn check_colour_correction_oracles(o: &Value, tol: f64) {
    let cc = o.key("colour_correction");
    let syn = cc.key("synthetic_rgb").rows3();
    let real = cc.key("real_rgb").rows3();
    assert_eq!(syn.len(), 24);
    assert!(
        syn.iter().flatten().any(|v| *v < 0.0),
        "the oracle has a negative synthetic value"
    );
    let want_t = cc.key("T_least_squares_3x3").matrix();
    let t = fit::fit_matrix(&syn, &real).unwrap();
    let mut worst = [0f64; 2];
    for i in 0..3 {
        for j in 0..3 {
            worst[0] = worst[0].max((t[i][j] - want_t[i][j]).abs());
            assert!(
                (t[i][j] - want_t[i][j]).abs() < tol,
                "T[{i}][{j}] {} vs {}",
                t[i][j],
                want_t[i][j]
            );
        }
    }
    let want_rp = cc.key("root_polynomial_degree2_matrix").matrix();
    let rp = fit::fit_root_polynomial(&syn, &real).unwrap();
    for i in 0..3 {
        for j in 0..6 {
            worst[1] = worst[1].max((rp[i][j] - want_rp[i][j]).abs());
            assert!(
                (rp[i][j] - want_rp[i][j]).abs() < tol,
                "RP[{i}][{j}] {} vs {}",
                rp[i][j],
                want_rp[i][j]
            );
        }
    }
    println!(
        "max |diff| T {:e}, root-polynomial {:e}",
        worst[0], worst[1]
    );
    // The synthetic set is the shipped reference table.
    for (s, p) in syn.iter().zip(COLORCHECKER24.iter()) {
        assert_eq!(*s, p.linear_srgb, "patch {}", p.number);
    }
    // Applying the fits to colours and images agrees.
    let img = Image::from_fn(24, 1, |x, _| syn[x].map(|v| v as f32));
    let out = fit::apply_root_polynomial_image(&rp, &img);
    for x in 0..24 {
        let want = fit::apply_root_polynomial(&rp, syn[x]);
        let got = out.get(x, 0);
        for c in 0..3 {
            assert!((got[c] as f64 - want[c]).abs() < 1e-5);
        }
    }
}

#[test]
#[ignore = "needs ../shared/data"]
fn least_squares_and_root_polynomial_match_colour_science() {
    check_colour_correction_oracles(&oracles(), 1e-6);
}

#[test]
fn least_squares_and_root_polynomial_match_colour_science_on_committed_values() {
    // QR here, a pseudo-inverse there, both f64 on a well-conditioned design: ~1e-15 apart.
    check_colour_correction_oracles(&crop_oracles(), 1e-10);
}

#[test]
fn reference_table_round_trips_to_its_lab() {
    // linear sRGB → XYZ D65 → Bradford → Lab D50 of the shipped linear values gives the shipped
    // Lab (the linear values are rounded to 6 decimals, hence the small tolerance).
    for p in &COLORCHECKER24 {
        let lab = cie::linear_srgb_to_lab_d50(p.linear_srgb);
        let de = cie::delta_e_2000(lab, p.lab_d50);
        assert!(de < 0.01, "patch {} ({}): ΔE00 {de}", p.number, p.name);
    }
    // Patch 1 through colour-science 0.4.7 (RGB_to_XYZ 'sRGB' with Bradford to the chart's D50,
    // XYZ_to_Lab), computed at development time.
    let lab = cie::linear_srgb_to_lab_d50(COLORCHECKER24[0].linear_srgb);
    let want = [37.54081845880617, 14.368174961664648, 14.920555790621492];
    for c in 0..3 {
        assert!((lab[c] - want[c]).abs() < 1e-9, "{lab:?}");
    }
}

// --- fits on noisy charts -----------------------------------------------------------------------

fn gauss(rng: &mut Rng) -> f64 {
    // Box–Muller.
    let u1 = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let u2 = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * (1.0 - u1).ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

fn add_noise(img: &Image, sigma: f64, seed: u64) -> Image {
    let mut rng = Rng::new(seed);
    let mut out = img.clone();
    for v in out.data.iter_mut() {
        *v += (sigma * gauss(&mut rng)) as f32;
    }
    out
}

const KNOWN_T: [[f64; 3]; 3] = [[0.82, 0.21, -0.03], [0.06, 0.88, 0.06], [0.01, -0.17, 1.16]];

#[test]
fn known_matrix_is_recovered_from_a_noisy_chart() {
    // Real chart = KNOWN_T · rendered chart + N(0, σ²) per pixel. Each patch mean then carries
    // noise σ_m = σ/√n (n pixels in the central half), and the least-squares row estimate has
    // covariance σ_m² (SᵀS)⁻¹ (S the 24×3 synthetic colours): entry (i, j) has standard error
    // σ_m √[(SᵀS)⁻¹]_jj. We allow 5 standard errors.
    let sigma = 0.02;
    let syn_img = chart::render_chart(600, 400, &Illuminant::D65, 1.0);
    let real_img = add_noise(&fit::apply_matrix_image(&KNOWN_T, &syn_img), sigma, 7);
    let samples = chart::sample_chart(&real_img, &ChartRegion::FullFrame, None).unwrap();
    let n = samples[0].pixels;
    assert_eq!(n, 50 * 50);
    for s in &samples {
        for c in 0..3 {
            assert!(
                (s.std[c] / sigma - 1.0).abs() < 0.1,
                "per-patch std {:?}",
                s.std
            );
        }
    }
    let syn = chart::reference_linear_srgb();
    let real: Vec<[f64; 3]> = samples.iter().map(|s| s.mean).collect();
    let t = fit::fit_matrix(&syn, &real).unwrap();
    let mut sts = [[0.0; 3]; 3];
    for s in &syn {
        for i in 0..3 {
            for j in 0..3 {
                sts[i][j] += s[i] * s[j];
            }
        }
    }
    let inv = hdrsynth::linalg::inverse3(&sts).unwrap();
    let sigma_m = sigma / (n as f64).sqrt();
    for i in 0..3 {
        for j in 0..3 {
            let se = sigma_m * inv[j][j].sqrt();
            let err = (t[i][j] - KNOWN_T[i][j]).abs();
            assert!(
                err < 5.0 * se,
                "T[{i}][{j}] = {} vs {} (error {err:.2e}, 5 SE {:.2e})",
                t[i][j],
                KNOWN_T[i][j],
                5.0 * se
            );
        }
    }
}

#[test]
fn leave_one_out_exceeds_in_sample_on_noisy_data() {
    let syn = chart::reference_linear_srgb();
    let mut rng = Rng::new(11);
    let real: Vec<[f64; 3]> = syn
        .iter()
        .map(|&s| fit::apply_matrix(&KNOWN_T, s).map(|v| v + 0.01 * gauss(&mut rng)))
        .collect();
    for model in [Model::Matrix, Model::RootPolynomial] {
        let e = fit::fit_and_evaluate(model, &syn, &real).unwrap();
        assert!(
            e.loo.mean > e.after.mean,
            "{model:?}: LOO {} vs in-sample {}",
            e.loo.mean,
            e.after.mean
        );
        assert!(e.after.mean < e.before.mean, "{model:?}");
        assert_eq!(e.loo.per_patch.len(), 24);
    }
    // Noise-free: the fit is exact and LOO is exact too.
    let exact: Vec<[f64; 3]> = syn
        .iter()
        .map(|&s| fit::apply_matrix(&KNOWN_T, s))
        .collect();
    let e = fit::fit_and_evaluate(Model::Matrix, &syn, &exact).unwrap();
    assert!(
        e.after.max < 1e-6 && e.loo.max < 1e-6,
        "{} {}",
        e.after.max,
        e.loo.max
    );
}

/// The chart fit shared by `calibrate colour` and `diagnose`, on exact patches whose answer is
/// known by hand.
#[test]
fn chart_fit_recovers_a_known_matrix_and_white_balance() {
    let reference = chart::reference_linear_srgb();
    let mul = |m: &[[f64; 3]; 3], p: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|i| (0..3).map(|k| m[i][k] * p[k]).sum())
    };
    let close = |a: f64, b: f64, what: &str| assert!((a - b).abs() < 1e-12, "{what}: {a} vs {b}");

    // No white balance: real = 0.4 · M · reference, synthetic = 1.5 · reference. Every column of
    // M sums to 1, so M keeps each patch's channel sum and the exposure scale is exactly
    // 1.5 / 0.4; the common scale is 1 / 1.5; T = M.
    let m = [[0.7, 0.2, 0.1], [0.2, 0.6, 0.3], [0.1, 0.2, 0.6]];
    let real: Vec<[f64; 3]> = reference
        .iter()
        .map(|&p| mul(&m, p).map(|v| 0.4 * v))
        .collect();
    let synthetic: Vec<[f64; 3]> = reference.iter().map(|p| p.map(|v| 1.5 * v)).collect();
    let f = fit::fit_chart(&real, &synthetic, WhiteBalance::None, false).unwrap();
    assert_eq!(f.white_balance_gains, [1.0; 3]);
    close(f.exposure_scale, 1.5 / 0.4, "exposure scale");
    close(f.chart_scale, 1.0 / 1.5, "chart scale");
    assert!(f.root_polynomial.is_none());
    let t = f.t();
    for i in 0..3 {
        for j in 0..3 {
            close(t[i][j], m[i][j], &format!("T[{i}][{j}]"));
        }
    }
    for (i, p) in f.synthetic.iter().enumerate() {
        for c in 0..3 {
            close(
                p[c],
                reference[i][c],
                "synthetic patch on the reference scale",
            );
        }
    }

    // Neutral white balance: a synthetic chart whose neutral patches 20–23 are exactly grey (the
    // reference's channel mean), and a camera that differs from it only by channel gains d and
    // exposure 0.25. The gains are d_G / d_c, the balanced patches 0.25 · d_G · synthetic, the
    // exposure scale 1 / (0.25 · d_G), the common scale 1 (the grey neutrals keep the
    // reference's mean), T = identity and the root-polynomial is [I | 0].
    let synthetic: Vec<[f64; 3]> = reference
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if (19..23).contains(&i) {
                [p.iter().sum::<f64>() / 3.0; 3]
            } else {
                *p
            }
        })
        .collect();
    let d = [0.5, 0.8, 0.25];
    let real: Vec<[f64; 3]> = synthetic
        .iter()
        .map(|p| std::array::from_fn(|c| 0.25 * d[c] * p[c]))
        .collect();
    let f = fit::fit_chart(&real, &synthetic, WhiteBalance::Neutral, true).unwrap();
    let g = f.white_balance_gains;
    close(g[0], 0.8 / 0.5, "gain R");
    close(g[1], 1.0, "gain G");
    close(g[2], 0.8 / 0.25, "gain B");
    close(f.exposure_scale, 1.0 / (0.25 * 0.8), "exposure scale");
    close(f.chart_scale, 1.0, "chart scale");
    let t = f.t();
    let rp = match &f.root_polynomial.as_ref().unwrap().fitted {
        fit::Fitted::RootPolynomial(rp) => *rp,
        other => panic!("{other:?}"),
    };
    for i in 0..3 {
        for j in 0..3 {
            let want = if i == j { 1.0 } else { 0.0 };
            close(t[i][j], want, &format!("T[{i}][{j}]"));
            close(rp[i][j], want, &format!("RP[{i}][{j}]"));
            close(rp[i][j + 3], 0.0, &format!("RP[{i}][{}]", j + 3));
        }
    }

    // A black chart: white balance is refused; without it, the neutral-mean check names both.
    let black = vec![[0.0; 3]; 24];
    let e = fit::fit_chart(&black, &reference, WhiteBalance::Neutral, false).unwrap_err();
    assert!(
        matches!(e, fit::ChartFitError::WhiteBalance(_)) && e.to_string().contains("non-positive"),
        "{e}"
    );
    let e = fit::fit_chart(&black, &reference, WhiteBalance::None, false).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("the neutral patches 20–23 average 0.00000 (real) and 0.30720"),
        "{e}"
    );
}

// --- chart rendering and sampling ------------------------------------------------------------------

#[test]
fn rendered_chart_layout_and_illuminants() {
    let img = chart::render_chart(60, 40, &Illuminant::D65, 2.0);
    let at = |x, y| img.get(x, y).map(|v| v as f64);
    let p1 = COLORCHECKER24[0].linear_srgb;
    let p24 = COLORCHECKER24[23].linear_srgb;
    let p6 = COLORCHECKER24[5].linear_srgb;
    for c in 0..3 {
        assert!((at(0, 0)[c] - 2.0 * p1[c]).abs() < 1e-6);
        assert!((at(59, 39)[c] - 2.0 * p24[c]).abs() < 1e-6);
        assert!((at(59, 0)[c] - 2.0 * p6[c]).abs() < 1e-6);
    }
    let a = Illuminant::A.gains();
    let ia = chart::render_chart(60, 40, &Illuminant::A, 1.0);
    let px = ia.get(0, 0);
    for c in 0..3 {
        assert!((px[c] as f64 - p1[c] * a[c]).abs() < 1e-6);
    }
    assert_eq!("d50".parse::<Illuminant>().unwrap(), Illuminant::D50);
    assert_eq!(
        "1,0.5,2".parse::<Illuminant>().unwrap(),
        Illuminant::Gains([1.0, 0.5, 2.0])
    );
    assert!("D75".parse::<Illuminant>().is_err());
    // Gains cross-checked with numpy and colour-science 0.4.7's Bradford
    // (matrix_chromatic_adaptation_VonKries) at development time.
    for (ill, want) in [
        (Illuminant::D50, [1.17626, 0.97572, 0.72157]),
        (Illuminant::A, [1.84537, 0.82612, 0.23323]),
    ] {
        let g = ill.gains();
        for c in 0..3 {
            assert!((g[c] - want[c]).abs() < 1e-5, "{ill}: {g:?}");
        }
    }
    let d50 = Illuminant::D50.gains();
    assert!(
        d50[0] > 1.0 && d50[2] < 1.0,
        "D50 is warmer than D65: {d50:?}"
    );
}

/// A chart seen through `h` (chart → image) on a dark background, with dark gaps between the
/// patches (each patch covers 84% of its cell), so only the central half is clean.
fn warped_chart(w: usize, h_px: usize, h: &Homography) -> Image {
    let inv = h.inverse().unwrap();
    Image::from_fn(w, h_px, |x, y| {
        let [u, v] = inv.apply([x as f64 + 0.5, y as f64 + 0.5]);
        if !(0.0..6.0).contains(&u) || !(0.0..4.0).contains(&v) {
            return [0.05; 3];
        }
        let (i, j) = (u as usize, v as usize);
        let (fu, fv) = (u - i as f64, v - j as f64);
        if !(0.08..0.92).contains(&fu) || !(0.08..0.92).contains(&fv) {
            return [0.02; 3];
        }
        COLORCHECKER24[j * 6 + i]
            .linear_srgb
            .map(|v| v.max(0.0) as f32)
    })
}

#[test]
fn corner_sampling_recovers_patches_through_a_homography() {
    let corners = [[120.3, 80.7], [610.2, 60.1], [650.8, 430.4], [90.5, 460.9]];
    let h = Homography::chart_to_image(corners).unwrap();
    let img = warped_chart(720, 520, &h);
    let region =
        ChartRegion::parse_corners("120.3,80.7,610.2,60.1,650.8,430.4,90.5,460.9").unwrap();
    assert_eq!(region, ChartRegion::Corners(corners));
    let s = chart::sample_chart(&img, &region, Some(1.0)).unwrap();
    for (k, p) in COLORCHECKER24.iter().enumerate() {
        assert!(s[k].pixels > 500, "patch {}: {} px", p.number, s[k].pixels);
        for c in 0..3 {
            let want = p.linear_srgb[c].max(0.0);
            assert!(
                (s[k].mean[c] - want).abs() < 1e-6,
                "patch {}: {:?}",
                p.number,
                s[k].mean
            );
            assert!(s[k].std[c] < 1e-6);
        }
    }
    // Corners off by 4 px still land inside every patch.
    let off = [[124.0, 77.0], [606.0, 64.0], [654.0, 427.0], [87.0, 464.0]];
    let s = chart::sample_chart(&img, &ChartRegion::Corners(off), None).unwrap();
    for (k, p) in COLORCHECKER24.iter().enumerate() {
        for c in 0..3 {
            assert!(
                (s[k].mean[c] - p.linear_srgb[c].max(0.0)).abs() < 1e-6,
                "patch {}",
                p.number
            );
        }
    }
    // Out of the image, and corners in the wrong order, are errors.
    let out = ChartRegion::Corners([
        [-300.0, 80.0],
        [610.0, 60.0],
        [650.0, 430.0],
        [-300.0, 460.0],
    ]);
    assert!(
        chart::sample_chart(&img, &out, None)
            .unwrap_err()
            .to_string()
            .contains("outside")
    );
    let twisted = ChartRegion::Corners([corners[0], corners[2], corners[1], corners[3]]);
    assert!(chart::sample_chart(&img, &twisted, None).is_err());
    assert!(ChartRegion::parse_corners("1,2,3").is_err());
}

#[test]
fn clipped_patch_error_names_the_patch() {
    // Exposure 1.12 puts patch 19 (white, G 0.885) at 0.991 ≥ 0.98 while patch 20 stays at 0.66.
    let img = chart::render_chart(600, 400, &Illuminant::D65, 1.12);
    let err = chart::sample_chart(&img, &ChartRegion::FullFrame, Some(1.0))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("patch 19") && err.contains("white 9.5") && err.contains("clipped"),
        "{err}"
    );
    // No clip level: no check.
    assert!(chart::sample_chart(&img, &ChartRegion::FullFrame, None).is_ok());
}

// --- DNG ----------------------------------------------------------------------------------------

#[test]
#[ignore = "needs ../shared/data"]
fn real_dng_reads_with_expected_size_pattern_and_levels() {
    let p = shared_data("real_raw/colorchart.dng");
    let info = read_dng_info(&p).unwrap();
    assert_eq!(info.cfa_string(), "RGGB");
    assert_eq!((info.raw_width, info.raw_height), (1888, 1182));
    assert_eq!(info.active_area, [26, 152, 1182, 1886]);
    assert_eq!((info.width, info.height), (1734, 1156));
    assert_eq!(info.bits_per_sample, 14);
    assert_eq!(info.compression, 1);
    assert_eq!(info.black_level_mean(), 2056.0);
    assert_eq!(info.white_level, 15000.0);
    let cm = info.color_matrix1.expect("ColorMatrix1");
    assert!((cm[0][0] - 0.6461).abs() < 1e-9 && (cm[2][2] - 0.6039).abs() < 1e-9);
    let n = info.as_shot_neutral.expect("AsShotNeutral");
    assert!((n[1] - 2.477).abs() < 1e-9);
    let dng = read_dng(&p).unwrap();
    assert_eq!((dng.image.width, dng.image.height), (1734, 1156));
    // Normalised values: the scene is below white, with mean well above black.
    let mean: f64 =
        dng.image.data.iter().map(|&v| v as f64).sum::<f64>() / dng.image.data.len() as f64;
    assert!(mean > 0.01 && mean < 0.5, "{mean}");
    assert!(dng.image.data.iter().all(|&v| v < 1.0 && v > -0.1));
    // Green photosites agree between the two green positions of the RGGB pattern.
    let (m, _) = read_dng_mosaic(&p).unwrap();
    let (mut g1, mut g2) = (0.0f64, 0.0f64);
    for y in (0..m.height).step_by(2) {
        for x in (0..m.width).step_by(2) {
            g1 += m.data[y * m.width + x + 1] as f64;
            g2 += m.data[(y + 1) * m.width + x] as f64;
        }
    }
    assert!((g1 / g2 - 1.0).abs() < 0.02, "{g1} {g2}");
}

/// A little-endian uncompressed CFA DNG: one IFD, strips of 3 rows (the last one shorter when
/// the height is not a multiple of 3), `bits`-bit samples packed MSB-first, each strip starting
/// on a byte boundary.
fn write_test_dng(
    path: &Path,
    w: usize,
    h: usize,
    bits: usize,
    pattern: [u8; 4],
    compression: u16,
    samples: &[u16],
) {
    let rps = 3usize;
    let pack = |rows: &[u16]| -> Vec<u8> {
        let mut packed = Vec::new();
        let (mut acc, mut n) = (0u64, 0usize);
        for &s in rows {
            if bits == 16 {
                // 16-bit samples are stored in the file's byte order (little-endian here).
                packed.extend(s.to_le_bytes());
                continue;
            }
            acc = (acc << bits) | s as u64;
            n += bits;
            while n >= 8 {
                packed.push((acc >> (n - 8)) as u8);
                n -= 8;
            }
        }
        if n > 0 {
            packed.push((acc << (8 - n)) as u8);
        }
        packed
    };
    let strips: Vec<Vec<u8>> = samples.chunks(rps * w).map(pack).collect();
    let ns = strips.len() as u32;
    let short = |v: u16| v.to_le_bytes().to_vec();
    let long = |v: u32| v.to_le_bytes().to_vec();
    // Entries: (tag, type, count, value bytes); values over 4 bytes go after the IFD.
    let mut entries: Vec<(u16, u16, u32, Vec<u8>)> = vec![
        (254, 4, 1, long(0)),
        (256, 4, 1, long(w as u32)),
        (257, 4, 1, long(h as u32)),
        (258, 3, 1, short(bits as u16)),
        (259, 3, 1, short(compression)),
        (262, 3, 1, short(32803)),
        (273, 4, ns, vec![]), // strip offsets, filled below
        (277, 3, 1, short(1)),
        (278, 4, 1, long(rps as u32)),
        (
            279,
            4,
            ns,
            strips.iter().flat_map(|s| long(s.len() as u32)).collect(),
        ),
        (33421, 3, 2, [short(2), short(2)].concat()),
        (33422, 1, 4, pattern.to_vec()),
        (50714, 3, 1, short(64)),
        (50717, 3, 1, short(((1u32 << bits) - 1) as u16)),
    ];
    let ifd_off = 8usize;
    let data_off = ifd_off + 2 + 12 * entries.len() + 4;
    // Layout after the IFD: strip data, then the out-of-line values.
    let mut extra: Vec<u8> = Vec::new();
    let mut offsets = Vec::new();
    for st in &strips {
        offsets.extend(long((data_off + extra.len()) as u32));
        extra.extend(st);
    }
    entries[6].3 = offsets;
    let mut out = b"II".to_vec();
    out.extend(42u16.to_le_bytes());
    out.extend((ifd_off as u32).to_le_bytes());
    out.extend((entries.len() as u16).to_le_bytes());
    for (tag, typ, count, mut val) in entries {
        out.extend(tag.to_le_bytes());
        out.extend(typ.to_le_bytes());
        out.extend(count.to_le_bytes());
        if val.len() > 4 {
            let at = data_off + extra.len();
            extra.extend(&val);
            val = long(at as u32);
        }
        val.resize(4, 0);
        out.extend(val);
    }
    out.extend(0u32.to_le_bytes());
    out.extend(extra);
    std::fs::write(path, out).unwrap();
}

#[test]
fn synthetic_dng_unpacks_bits_and_reads_the_cfa_pattern() {
    let dir = tempfile::tempdir().unwrap();
    // 6 × 4 photosites in strips of 3 rows: the second strip holds one row.
    let (w, h) = (6usize, 4usize);
    for (bits, pattern, name) in [
        (12, [1u8, 0, 2, 1], "GRBG"),
        (14, [2, 1, 1, 0], "BGGR"),
        (16, [0, 1, 1, 2], "RGGB"),
    ] {
        let max = (1u32 << bits) - 1;
        let samples: Vec<u16> = (0..w * h)
            .map(|i| (64 + i as u32 * 37 % (max - 64)) as u16)
            .collect();
        let p = dir.path().join(format!("t{bits}.dng"));
        write_test_dng(&p, w, h, bits, pattern, 1, &samples);
        let (m, info) = read_dng_mosaic(&p).unwrap();
        assert_eq!(info.cfa_string(), name);
        assert_eq!((m.width, m.height), (w, h));
        for i in 0..w * h {
            let want = (samples[i] as f64 - 64.0) / (max as f64 - 64.0);
            assert!(
                (m.data[i] as f64 - want).abs() < 1e-6,
                "{bits} bits, sample {i}"
            );
        }
        // Bilinear demosaic keeps each photosite's own colour.
        let img = read_dng(&p).unwrap().image;
        for y in 0..h {
            for x in 0..w {
                let c = pattern[(y % 2) * 2 + x % 2] as usize;
                assert_eq!(img.get(x, y)[c], m.data[y * w + x]);
            }
        }
    }
    // Unsupported compression and CFA patterns name the file.
    let p = dir.path().join("ljpeg.dng");
    write_test_dng(&p, w, h, 12, [0, 1, 1, 2], 7, &vec![100; w * h]);
    let e = read_dng(&p).unwrap_err().to_string();
    assert!(
        e.contains("ljpeg.dng") && e.contains("lossless-JPEG"),
        "{e}"
    );
    let p = dir.path().join("cyan.dng");
    write_test_dng(&p, w, h, 12, [0, 1, 3, 2], 1, &vec![100; w * h]);
    let e = read_dng(&p).unwrap_err().to_string();
    assert!(e.contains("cyan.dng") && e.contains("CFA pattern"), "{e}");
    let p = dir.path().join("not.dng");
    std::fs::write(&p, b"hello world").unwrap();
    let e = read_dng(&p).unwrap_err().to_string();
    assert!(e.contains("not.dng"), "{e}");
}

// --- calibrate colour end to end --------------------------------------------------------------

/// Corners of the ColorChecker's 6×4 patch area in colorchart.dng (active-area pixels), found on
/// a preview: the outer corners of patches 1, 6, 24, 19 (fitted through all 24 patch centres).
const DNG_CORNERS: &str = "665,579,1303,564,1316,974,645,984";

/// The defaults of `calibrate colour` for a real capture and a profile path.
fn options(real: &Path, out: &Path) -> CalibrateOptions {
    CalibrateOptions::new(
        real.to_path_buf(),
        out.to_path_buf(),
        "tests/colour.rs".into(),
    )
}

#[test]
#[ignore = "needs ../shared/data"]
fn calibrate_colour_on_the_real_dng_writes_a_profile() {
    let dng = shared_data("real_raw/colorchart.dng");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("canon.toml");
    let opts = CalibrateOptions {
        real_region: ChartRegion::parse_corners(DNG_CORNERS).unwrap(),
        ..options(&dng, &out)
    };
    let report = run(&opts).unwrap();
    println!("{report}");
    println!("{}", std::fs::read_to_string(&out).unwrap());
    let p = SensorProfile::load(&out).unwrap();
    assert_eq!(p.format, PROFILE_FORMAT);
    assert_eq!(p.kind, ProfileKind::Measured);
    assert_eq!(
        p.levels,
        Levels {
            black_level: 2056.0,
            white_level: 15000.0,
            bit_depth: 14
        }
    );
    assert!(p.noise.is_empty());
    assert_eq!(p.response, Response::Linear);
    let c = p.colour.clone().unwrap();
    assert!(!c.use_root_polynomial && c.root_polynomial.is_none());
    // A neutral stays roughly neutral with unit gain: row sums of T near 1.
    for r in c.matrix {
        let s: f64 = r.iter().sum();
        assert!((s - 1.0).abs() < 0.15, "{:?}", c.matrix);
    }
    assert!(
        p.provenance.colour.contains("colorchart.dng") && p.provenance.colour.contains("ΔE00 mean")
    );
    assert!(p.provenance.levels.contains("BlackLevel"));
    assert!(report.contains("leave-one-patch-out"));
    // The fit helps and generalises sensibly.
    let parse = |key: &str| -> f64 {
        let line = report.lines().find(|l| l.starts_with(key)).unwrap();
        line.split("mean ")
            .nth(1)
            .unwrap()
            .split(',')
            .next()
            .unwrap()
            .trim()
            .parse()
            .unwrap()
    };
    let (before, after) = (parse("ΔE00 before"), parse("ΔE00 after T"));
    assert!(after < before, "{after} vs {before}");

    // Second run with the root-polynomial updates the existing profile and keeps the rest.
    let mut edited = p.clone();
    edited.provenance.notes = Some("keep me".into());
    edited.save(&out).unwrap();
    let report = run(&CalibrateOptions {
        root_polynomial: true,
        invocation: "calibrate with --root-polynomial".into(),
        ..opts
    })
    .unwrap();
    println!("{report}");
    let q = SensorProfile::load(&out).unwrap();
    assert_eq!(q.provenance.notes.as_deref(), Some("keep me"));
    assert_eq!(q.levels, p.levels);
    let qc = q.colour.unwrap();
    assert!(qc.use_root_polynomial && qc.root_polynomial.is_some());
    assert!(
        q.provenance
            .colour
            .contains("fit by `calibrate with --root-polynomial`")
    );
    assert!(
        q.provenance
            .colour
            .contains("Root-polynomial degree 2 (used)")
    );
}

fn example_profile() -> SensorProfile {
    SensorProfile {
        format: PROFILE_FORMAT.into(),
        name: "example".into(),
        kind: ProfileKind::SyntheticExample,
        provenance: Provenance {
            colour: "none yet".into(),
            noise: "invented".into(),
            levels: "invented".into(),
            response: "invented".into(),
            metering: None,
            notes: None,
        },
        colour: None,
        levels: Levels {
            black_level: 64.0,
            white_level: 1023.0,
            bit_depth: 10,
        },
        noise: vec![NoiseAtIso {
            iso: 100.0,
            a: [1e-4; 3],
            b: [1e-6; 3],
            a_stderr: None,
            b_stderr: None,
        }],
        response: Response::Srgb,
        source_response: Response::Filmic,
        metering: None,
        effects: Vec::new(),
        calibrated_on: Vec::new(),
    }
}

#[test]
fn calibrate_colour_updates_an_existing_profile_from_an_exr() {
    // A "real" capture made with a known T and a different exposure, warped into a frame.
    let dir = tempfile::tempdir().unwrap();
    let corners = [[40.0, 30.0], [560.0, 42.0], [548.0, 380.0], [35.0, 370.0]];
    let h = Homography::chart_to_image(corners).unwrap();
    let rendered = warped_chart(600, 420, &h);
    let real = fit::apply_matrix_image(&KNOWN_T, &rendered).map(|v| v * 0.5);
    let real_path = dir.path().join("real.exr");
    write_exr(&real_path, &real, hdrsynth::io::ExrPrecision::Float).unwrap();
    let out = dir.path().join("profile.toml");
    example_profile().save(&out).unwrap();
    let report = run(&CalibrateOptions {
        real_region: ChartRegion::Corners(corners),
        white_balance: WhiteBalance::None,
        ..options(&real_path, &out)
    })
    .unwrap();
    let p = SensorProfile::load(&out).unwrap();
    assert_eq!(p.noise, example_profile().noise);
    assert_eq!(p.levels, example_profile().levels);
    assert_eq!(p.provenance.noise, "invented");
    let t = p.colour.unwrap().matrix;
    // Exposure is normalised on the neutral patches 20–23, so T = KNOWN_T / g with g the mean
    // response of KNOWN_T on them relative to the synthetic neutrals.
    let refs = chart::reference_linear_srgb();
    let mapped: Vec<[f64; 3]> = refs
        .iter()
        .map(|&s| fit::apply_matrix(&KNOWN_T, s.map(|v| v.max(0.0))))
        .collect();
    let g = chart::neutral_mean(&mapped) / chart::neutral_mean(&refs);
    // Patch 18 (cyan) has R < 0 in the table but the warped chart stores 0: the fit maps the
    // rendered (negative) synthetic value to what the capture holds.
    let want = fit::fit_matrix(
        &refs,
        &mapped.iter().map(|m| m.map(|v| v / g)).collect::<Vec<_>>(),
    )
    .unwrap();
    for i in 0..3 {
        for j in 0..3 {
            assert!(
                (t[i][j] - want[i][j]).abs() < 1e-4,
                "T {t:?} vs {want:?}\n{report}"
            );
        }
    }
    assert!(report.contains("updated"));
}

#[test]
fn calibrate_colour_writes_nothing_on_failure() {
    let dir = tempfile::tempdir().unwrap();
    // A PNG capture that clips patch 19 (white, G 0.885 × 1.12 = 0.991) and no other.
    let img = chart::render_chart(300, 200, &Illuminant::D65, 1.12);
    let png = dir.path().join("clipped.png");
    hdrsynth::io::write_ldr(
        &png,
        &img.map(|v| v.clamp(0.0, 1.0)),
        hdrsynth::io::BitDepth::Sixteen,
    )
    .unwrap();
    let out = dir.path().join("new.toml");
    let with_levels = |png: &Path| CalibrateOptions {
        black: Some(0.0),
        white: Some(65535.0),
        bits: Some(16),
        ..options(png, &out)
    };
    let e = run(&with_levels(&png)).unwrap_err();
    let msg = format!("{e:#}");
    assert!(
        msg.contains("clipped.png") && msg.contains("patch 19"),
        "{msg}"
    );
    assert!(!out.exists());
    // A good capture but no levels for a new profile: refused, nothing written.
    let img = chart::render_chart(300, 200, &Illuminant::D65, 0.9);
    let png = dir.path().join("good.png");
    hdrsynth::io::write_ldr(
        &png,
        &img.map(|v| v.clamp(0.0, 1.0)),
        hdrsynth::io::BitDepth::Sixteen,
    )
    .unwrap();
    let e = run(&options(&png, &out)).unwrap_err();
    assert!(format!("{e:#}").contains("--black"), "{e:#}");
    assert!(!out.exists());
    // With levels it works; 16-bit PNG is read as linear by default; an identity T results
    // (the negative R of patch 18 is clamped in the PNG, so allow a small deviation).
    let report = run(&with_levels(&png)).unwrap();
    let p = SensorProfile::load(&out).unwrap();
    assert_eq!(p.response, Response::Linear);
    let t = p.colour.unwrap().matrix;
    for i in 0..3 {
        for j in 0..3 {
            let want = if i == j { 1.0 } else { 0.0 };
            assert!((t[i][j] - want).abs() < 0.03, "{t:?}\n{report}");
        }
    }
    // Inputs the calibration cannot use are refused.
    let e = run(&CalibrateOptions {
        synthetic: SyntheticChart::Render {
            illuminant: Illuminant::D65,
            exposure: -2.0,
        },
        ..with_levels(&png)
    })
    .unwrap_err();
    assert!(e.to_string().contains("--exposure -2 must be > 0"), "{e}");
    let e = run(&CalibrateOptions {
        synthetic: SyntheticChart::Image {
            path: dir.path().join("synthetic.dng"),
            region: ChartRegion::FullFrame,
            response: None,
        },
        ..with_levels(&png)
    })
    .unwrap_err();
    assert!(e.to_string().contains("cannot be a DNG"), "{e}");
}

/// The command line: arguments that contradict each other or do not parse are refused before
/// anything is read.
#[test]
fn calibrate_colour_command_refuses_contradicting_arguments() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.toml");
    let refused = |extra: &[&str], want: &str| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
            .args(["calibrate", "colour", "--real", "absent.png", "--out"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(want),
            "{extra:?}: {err}"
        );
    };
    refused(
        &["--synthetic", "syn.png", "--exposure", "2"],
        "--illuminant and --exposure apply to `--synthetic render` only",
    );
    refused(
        &["--synthetic-corners", "0,0,1,0,1,1,0,1"],
        "apply to a synthetic image, not to `render`",
    );
    refused(&["--real-response", "gamma:x"], "gamma 'x' is not a number");
    assert!(!out.exists());
}
