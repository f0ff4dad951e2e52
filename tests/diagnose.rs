//! The sim-to-real gap workflow against planted truth (tests/truth: an independent sensor
//! simulator): every catalogue effect hidden alone is named first, its parameter recovered
//! within 25 % and the gap ends under the threshold; no hidden effect names nothing; two hidden
//! effects are both named. Sizes, frame counts and strengths vary across cases.

mod truth;

use hdrsynth::sensor::captures::CaptureSet;
use hdrsynth::sensor::diagnose::{DiagnoseOptions, Diagnosis, diagnose};
use hdrsynth::sensor::profile::SensorProfile;
use std::path::Path;
use truth::Truth;

fn run(t: &Truth, name: &str) -> (Diagnosis, usize) {
    run_max(t, name, DiagnoseOptions::default().max_pixels)
}

fn run_max(t: &Truth, name: &str, max_pixels: usize) -> (Diagnosis, usize) {
    let dir = std::env::temp_dir().join(format!("hdrsynth-diagnose-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let hot = t.write(&dir);
    let set = CaptureSet::load(&dir).expect("load");
    let opts = DiagnoseOptions {
        replicates: 24,
        seed: 7,
        max_pixels,
        ..DiagnoseOptions::default()
    };
    let d = diagnose(&set, None, &opts).expect("diagnose");
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!("--- {name}\n{}", d.report_json());
    for n in &d.notes {
        eprintln!("note: {n}");
    }
    (d, hot)
}

/// A fitted parameter (fits write floats: `effects::float`).
fn number(p: &toml::Table, key: &str) -> Result<f64, String> {
    p.get(key)
        .and_then(toml::Value::as_float)
        .ok_or_else(|| format!("no number '{key}' in {p}"))
}

fn param(d: &Diagnosis, effect: &str, key: &str) -> f64 {
    let s = d
        .steps
        .iter()
        .find(|s| s.effect == effect)
        .unwrap_or_else(|| panic!("{effect} not named"));
    number(&s.params, key).expect(key)
}

fn within(got: f64, want: f64, what: &str) {
    assert!(
        (got - want).abs() <= 0.25 * want.abs(),
        "{what}: fitted {got}, planted {want} (more than 25 % off)"
    );
}

/// Named first, recovered, and the gap ends under the threshold.
fn single(d: &Diagnosis, effect: &str) {
    assert!(!d.steps.is_empty(), "{effect}: nothing named");
    assert_eq!(d.steps[0].effect, effect, "first named effect");
    assert!(d.initial_gap() > d.threshold);
    assert!(
        d.final_gap() <= d.threshold,
        "{effect}: final gap {} > threshold {}; unexplained {:?}",
        d.final_gap(),
        d.threshold,
        d.unexplained
    );
    assert!(d.unexplained.is_empty());
}

#[test]
fn no_hidden_effect_names_nothing() {
    let mut t = Truth::new(64, 48, 12, 11);
    t.isos = vec![100.0, 400.0];
    let (d, _) = run(&t, "none");
    assert!(
        d.steps.is_empty(),
        "named {:?}",
        d.steps.iter().map(|s| &s.effect).collect::<Vec<_>>()
    );
    assert!(d.final_gap() <= d.threshold);
    assert!(d.unexplained.is_empty());
}

#[test]
fn hidden_black_level() {
    let mut t = Truth::new(64, 48, 8, 1);
    t.black_offset = 6.0;
    let (d, _) = run(&t, "black");
    single(&d, "black_level");
    within(param(&d, "black_level", "offset_dn"), 6.0, "offset_dn");
}

#[test]
fn hidden_row_noise() {
    let mut t = Truth::new(80, 60, 12, 2);
    t.row_sigma = 2.0;
    let (d, _) = run(&t, "row");
    single(&d, "row_noise");
    within(param(&d, "row_noise", "sigma_dn"), 2.0, "sigma_dn");
}

#[test]
fn hidden_column_noise() {
    let mut t = Truth::new(96, 48, 10, 3);
    t.column_sigma = 1.5;
    let (d, _) = run(&t, "column");
    single(&d, "column_noise");
    within(param(&d, "column_noise", "sigma_dn"), 1.5, "sigma_dn");
}

#[test]
fn hidden_dsnu() {
    let mut t = Truth::new(64, 64, 16, 4);
    t.dsnu_sigma = 2.5;
    let (d, _) = run(&t, "dsnu");
    single(&d, "dsnu");
    within(param(&d, "dsnu", "sigma_dn"), 2.5, "sigma_dn");
}

#[test]
fn hidden_prnu() {
    let mut t = Truth::new(72, 48, 12, 5);
    t.prnu_sigma = 0.01;
    let (d, _) = run(&t, "prnu");
    single(&d, "prnu");
    within(param(&d, "prnu", "sigma"), 0.01, "sigma");
}

#[test]
fn hidden_hot_pixels() {
    let mut t = Truth::new(80, 64, 8, 6);
    t.hot = Some((0.004, 300.0));
    let (d, planted) = run(&t, "hot");
    single(&d, "hot_pixels");
    let n = (80 * 64 * 3) as f64;
    within(
        param(&d, "hot_pixels", "fraction"),
        planted as f64 / n,
        "fraction",
    );
    within(param(&d, "hot_pixels", "offset_dn"), 300.0, "offset_dn");
}

#[test]
fn hidden_heavy_tailed_read_noise() {
    let mut t = Truth::new(96, 64, 16, 7);
    t.heavy_dof = Some(10.0);
    let (d, _) = run(&t, "heavy");
    single(&d, "heavy_tailed_read_noise");
    within(param(&d, "heavy_tailed_read_noise", "dof"), 10.0, "dof");
}

#[test]
fn hidden_channel_noise() {
    let mut t = Truth::new(64, 48, 12, 8);
    let (sa, sb) = ([1.4, 1.0, 0.7], [1.6, 1.0, 0.6]);
    t.channel = Some((sa, sb));
    let (d, _) = run(&t, "channel");
    single(&d, "channel_noise");
    // Per-channel a, b of the final model (DN) against the planted ones.
    let p = &d.profile;
    let range = p.levels.white_level - p.levels.black_level;
    let (a, b) = p.noise_at(100.0).unwrap();
    let step = d
        .steps
        .iter()
        .find(|s| s.effect == "channel_noise")
        .unwrap();
    let arr = |k: &str| -> Vec<f64> {
        step.params[k]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_float().unwrap())
            .collect()
    };
    let (fa, fb) = (arr("a_scale"), arr("b_scale"));
    for c in 0..3 {
        within(a[c] * range * fa[c], t.a100 * sa[c], &format!("a[{c}]"));
        within(
            b[c] * range * range * fb[c],
            t.b100 * sb[c],
            &format!("b[{c}]"),
        );
    }
}

#[test]
fn hidden_vignetting() {
    let mut t = Truth::new(96, 64, 8, 9);
    t.vignetting = 0.3;
    let (d, _) = run(&t, "vignetting");
    single(&d, "vignetting");
    within(param(&d, "vignetting", "strength"), 0.3, "strength");
}

/// Bursts over `max_pixels` are analysed on evenly spread bands of rows, measured and simulated
/// alike. On 96×256 frames with a budget of 4096 pixels (the minimum of 8
/// bands of 8 rows, a quarter of the frame) the null case names nothing, and effects whose statistics need the
/// whole field (vignetting), whole rows (row noise), column means (column noise) and vertical
/// lags (correlated noise, 2-D Gaussian filter) are still named first and recovered.
#[test]
fn large_bursts_are_analysed_on_bands_of_rows() {
    let banded = |d: &Diagnosis| {
        assert!(
            d.notes.iter().any(|n| n.contains("64 of 256")),
            "no band note: {:?}",
            d.notes
        );
    };
    let (d, _) = run_max(&Truth::new(96, 256, 12, 3100), "band-null", 4096);
    banded(&d);
    assert!(d.steps.is_empty(), "null named {:?}", d.steps[0].effect);
    assert!(d.final_gap() <= d.threshold);

    let mut t = Truth::new(96, 256, 12, 3101);
    t.row_sigma = 2.0;
    let (d, _) = run_max(&t, "band-row", 4096);
    banded(&d);
    single(&d, "row_noise");
    within(param(&d, "row_noise", "sigma_dn"), 2.0, "sigma_dn");

    let mut t = Truth::new(96, 256, 8, 3102);
    t.vignetting = 0.3;
    let (d, _) = run_max(&t, "band-vignetting", 4096);
    single(&d, "vignetting");
    within(param(&d, "vignetting", "strength"), 0.3, "strength");

    let mut t = Truth::new(96, 256, 10, 3103);
    t.column_sigma = 1.5;
    let (d, _) = run_max(&t, "band-column", 4096);
    single(&d, "column_noise");
    within(param(&d, "column_noise", "sigma_dn"), 1.5, "sigma_dn");

    // The truth's 2-D Gaussian filter of σ 0.6 px (lag-1 correlation 0.445 by hand; the
    // library's kernel family is Gaussian too, so lag 2 matches as well, see the note in
    // docs/diagnose.md's limits on the 2-tap filter).
    let mut t = Truth::new(96, 256, 12, 3104);
    t.corr_gauss = 0.6;
    let (d, _) = run_max(&t, "band-correlated", 4096);
    single(&d, "correlated_noise");
    within(param(&d, "correlated_noise", "rho_v"), 0.445, "rho_v");
    within(param(&d, "correlated_noise", "rho_h"), 0.445, "rho_h");
}

#[test]
fn hidden_correlated_noise() {
    let mut t = Truth::new(64, 48, 12, 10);
    t.corr_rho = 0.25;
    let (d, _) = run(&t, "correlated");
    single(&d, "correlated_noise");
    // The truth's filter is vertical only: rho_v carries it.
    within(param(&d, "correlated_noise", "rho_v"), 0.25, "rho_v");
}

#[test]
fn hidden_channel_correlation() {
    // Chroma noise: every two channels' noise correlated by 0.4 (the truth's own construction,
    // a fresh shared draw per pixel).
    let mut t = Truth::new(64, 48, 12, 14);
    t.channel_rho = 0.4;
    let (d, _) = run(&t, "channel-correlation");
    single(&d, "channel_correlation");
    within(param(&d, "channel_correlation", "rho"), 0.4, "rho");
}

#[test]
fn hidden_nonlinear_response() {
    // A tone curve baked into the frames: the 16:1 exposure pair measures 16^0.8 ≈ 9.2.
    let mut t = Truth::new(64, 48, 8, 12);
    t.exponent = 0.8;
    let (d, _) = run(&t, "nonlinear");
    single(&d, "nonlinear_response");
    within(param(&d, "nonlinear_response", "exponent"), 0.8, "exponent");
    // The other direction, like the paper's synthetic frames (EV0/EV−3 ratio above 8): an
    // exponent of 1.2 turns an 8:1 exposure pair into 8^1.2 ≈ 12.1.
    let mut t = Truth::new(80, 60, 6, 15);
    t.exponent = 1.2;
    let (d, _) = run(&t, "nonlinear-up");
    single(&d, "nonlinear_response");
    within(param(&d, "nonlinear_response", "exponent"), 1.2, "exponent");
}

fn pair(d: &Diagnosis, a: &str, b: &str) {
    let named: Vec<&str> = d.steps.iter().map(|s| s.effect.as_str()).collect();
    assert!(
        named.contains(&a) && named.contains(&b),
        "named {named:?}, want {a} and {b}"
    );
    assert!(
        d.final_gap() <= d.threshold,
        "final gap {} > {}",
        d.final_gap(),
        d.threshold
    );
}

#[test]
fn two_hidden_effects_row_noise_and_prnu() {
    let mut t = Truth::new(80, 48, 12, 13);
    t.row_sigma = 1.5;
    t.prnu_sigma = 0.015;
    let (d, _) = run(&t, "pair1");
    pair(&d, "row_noise", "prnu");
    within(param(&d, "row_noise", "sigma_dn"), 1.5, "sigma_dn");
    within(param(&d, "prnu", "sigma"), 0.015, "sigma");
}

#[test]
fn two_hidden_effects_column_noise_and_vignetting() {
    let mut t = Truth::new(64, 64, 10, 14);
    t.column_sigma = 2.0;
    t.vignetting = 0.2;
    let (d, _) = run(&t, "pair2");
    pair(&d, "column_noise", "vignetting");
}

/// Weak versions of every effect on another frame size and frame count: the workflow must not
/// depend on one magnitude. (id, parameter, planted value, truth setter)
#[test]
fn weak_hidden_effects() {
    type Set = fn(&mut Truth);
    let cases: [(&str, &str, f64, Set); 10] = [
        ("black_level", "offset_dn", 1.5, |t| t.black_offset = 1.5),
        ("row_noise", "sigma_dn", 0.7, |t| t.row_sigma = 0.7),
        ("column_noise", "sigma_dn", 0.6, |t| t.column_sigma = 0.6),
        ("dsnu", "sigma_dn", 1.0, |t| t.dsnu_sigma = 1.0),
        ("prnu", "sigma", 0.004, |t| t.prnu_sigma = 0.004),
        ("vignetting", "strength", 0.06, |t| t.vignetting = 0.06),
        ("correlated_noise", "rho_v", 0.1, |t| t.corr_rho = 0.1),
        ("nonlinear_response", "exponent", 0.93, |t| {
            t.exponent = 0.93
        }),
        ("heavy_tailed_read_noise", "dof", 14.0, |t| {
            t.heavy_dof = Some(14.0)
        }),
        ("hot_pixels", "offset_dn", 120.0, |t| {
            t.hot = Some((0.0015, 120.0))
        }),
    ];
    for (k, (id, key, want, set)) in cases.iter().enumerate() {
        let mut t = Truth::new(128, 96, 16, 100 + k as u64);
        t.a100 = 0.3;
        t.b100 = 4.0;
        set(&mut t);
        let (d, _) = run(&t, &format!("weak-{id}"));
        single(&d, id);
        within(param(&d, id, key), *want, &format!("{id}.{key}"));
    }
}

/// `hdrsynth diagnose` writes report.json in its documented shape, report.md, the plots and a
/// profile.toml that the realism operator (what the loader builds for training samples)
/// applies: its fitted vignetting darkens a corner of a uniform frame by 1 − k·r².
#[test]
fn cli_report_and_profile_flow_into_the_realism_operator() {
    use hdrsynth::io::Image;
    use hdrsynth::sensor::profile::{Response, SensorProfile};
    use hdrsynth::sensor::realism::{NoiseModel, Realism, RealismOptions};
    let tmp = std::env::temp_dir().join(format!("hdrsynth-diagnose-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let mut t = Truth::new(64, 48, 8, 21);
    t.vignetting = 0.25;
    t.row_sigma = 1.5;
    t.write(&tmp.join("captures"));
    let out = tmp.join("diag");
    let opts = DiagnoseOptions {
        replicates: 12,
        seed: 3,
        ..Default::default()
    };
    let d = hdrsynth::sensor::diagnose::diagnose_folder(&tmp.join("captures"), None, &opts, &out)
        .expect("diagnose");
    eprintln!("{}", d.summary());
    for f in [
        "profile.toml",
        "report.md",
        "report.json",
        "gap.png",
        "radial.png",
        "ptc.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let json = std::fs::read_to_string(out.join("report.json")).unwrap();
    // The documented shape: these keys, in this order, and a step's keys.
    let mut at = 0;
    for key in [
        "\"format\": \"hdrsynth-diagnosis/1\"",
        "\"threshold\": ",
        "\"initial_gap\": ",
        "\"final_gap\": ",
        "\"steps\": [",
        "{\"effect\": ",
        "\"params\": {",
        "\"gap_before\": ",
        "\"gap_after\": ",
        "\"evidence\": \"",
        "\"unexplained\": []",
    ] {
        let i = json[at..]
            .find(key)
            .unwrap_or_else(|| panic!("{key} not in order in\n{json}"));
        at += i + key.len();
    }
    assert!(
        json.contains("\"effect\": \"vignetting\"") && json.contains("\"effect\": \"row_noise\"")
    );

    let p = SensorProfile::load(&out.join("profile.toml")).expect("profile loads");
    let ids: Vec<&str> = p.effects.iter().map(|e| e.id.as_str()).collect();
    assert!(
        ids.contains(&"vignetting") && ids.contains(&"row_noise"),
        "{ids:?}"
    );
    let k = number(
        &p.effects
            .iter()
            .find(|e| e.id == "vignetting")
            .unwrap()
            .params,
        "strength",
    )
    .unwrap();
    let mut lin = p.clone();
    lin.source_response = Response::Linear;
    let mut opts = RealismOptions::new(100.0);
    opts.noise = NoiseModel::None;
    opts.colour = false;
    let r = Realism::new(&lin, &opts).expect("realism");
    let dn = r.to_dn(&Image::from_fn(64, 48, |_, _| [0.5; 3]), 0);
    let black = p.levels.black_level;
    let centre = (dn.get(32, 24)[1] as f64 - black) / (0.5 * (p.levels.white_level - black));
    let corner = (dn.get(0, 0)[1] as f64 - black) / (0.5 * (p.levels.white_level - black));
    // r² of pixel (0, 0) in a 64×48 frame: ((0.5 − 32)² + (0.5 − 24)²) / 40² = 0.965234…
    let r2 = (31.5f64.powi(2) + 23.5f64.powi(2)) / 1600.0;
    assert!(
        (corner - (1.0 - k * r2)).abs() < 2e-3,
        "corner {corner} vs {}",
        1.0 - k * r2
    );
    assert!(
        (centre - (1.0 - k * (0.25 + 0.25) / 1600.0)).abs() < 2e-3,
        "centre {centre}"
    );
    // And the same through the default options the loader uses (filmic source, colour on).
    let r = Realism::new(&p, &RealismOptions::new(100.0)).expect("loader-style realism");
    let _ = r.apply(&Image::from_fn(64, 48, |_, _| [0.5; 3]), 1);
    let _ = std::fs::remove_dir_all(&tmp);
}

/// The worked example of docs/diagnose.md: four effects hidden at once are all named and
/// recovered, and the gap ends under the threshold. To write its capture set for
/// `hdrsynth diagnose`, set `HDRSYNTH_EXAMPLE_DIR=/tmp/ex` when running this test.
#[test]
fn worked_example_four_hidden_effects() {
    let mut t = Truth::new(96, 64, 12, 2026);
    t.black_offset = 3.0;
    t.row_sigma = 1.2;
    t.hot = Some((0.002, 250.0));
    t.vignetting = 0.15;
    if let Ok(dir) = std::env::var("HDRSYNTH_EXAMPLE_DIR") {
        t.write(Path::new(&dir));
    }
    let (d, _) = run(&t, "worked");
    let mut named: Vec<&str> = d.steps.iter().map(|s| s.effect.as_str()).collect();
    named.sort();
    assert_eq!(
        named,
        ["black_level", "hot_pixels", "row_noise", "vignetting"]
    );
    within(param(&d, "black_level", "offset_dn"), 3.0, "offset_dn");
    within(param(&d, "row_noise", "sigma_dn"), 1.2, "sigma_dn");
    within(param(&d, "hot_pixels", "fraction"), 0.002, "fraction");
    within(param(&d, "hot_pixels", "offset_dn"), 250.0, "offset_dn");
    within(param(&d, "vignetting", "strength"), 0.15, "strength");
    assert!(d.final_gap() <= d.threshold && d.unexplained.is_empty());
}

/// The base model's T from the chart burst of a camera whose RGB is M · reference: neutral
/// white balance scales the rows by g_c = n_G / n_c (n: M's mean response over the neutral
/// patches 20–23), which makes every balanced channel's neutral mean n_G; the exposure scale
/// n_ref / n_G (n_ref: the reference's neutral mean over patches and channels) puts them on
/// the reference. The fit is exact on exact patches, so T = (n_ref / n_G) · diag(g) · M up to
/// the burst's noise (about 1e-3 here). To write this capture set for `hdrsynth diagnose`, set
/// `HDRSYNTH_CHART_EXAMPLE_DIR=/tmp/chart` when running this test.
#[test]
fn base_model_fits_t_from_a_coloured_chart() {
    let mut t = Truth::new(96, 64, 4, 17);
    t.scenes = false;
    t.chart_matrix = [[0.9, 0.25, 0.05], [0.1, 1.0, 0.2], [0.0, 0.15, 0.7]];
    if let Ok(dir) = std::env::var("HDRSYNTH_CHART_EXAMPLE_DIR") {
        t.write(Path::new(&dir));
    }
    let (d, _) = run(&t, "chart");
    let got = d.profile.colour.expect("a chart burst gives T").matrix;
    let reference = hdrsynth::sensor::colour::chart::reference_linear_srgb();
    let m = t.chart_matrix;
    let neutral = 19..23;
    let n = |c: usize| -> f64 {
        neutral
            .clone()
            .map(|i| (0..3).map(|k| m[c][k] * reference[i][k]).sum::<f64>())
            .sum::<f64>()
            / 4.0
    };
    let n_ref = neutral
        .clone()
        .map(|i| reference[i].iter().sum::<f64>())
        .sum::<f64>()
        / 12.0;
    let g = [n(1) / n(0), 1.0, n(1) / n(2)];
    for i in 0..3 {
        for j in 0..3 {
            let want = n_ref / n(1) * g[i] * m[i][j];
            assert!(
                (got[i][j] - want).abs() < 5e-3,
                "T[{i}][{j}] {} vs {want}: {got:?}",
                got[i][j]
            );
        }
    }
}

/// A one-ISO profile (black 64, white 4095) with the given `[[effects]]` tables.
fn effect_profile(effects: &str) -> SensorProfile {
    let text = format!(
        r#"
format = "hdrsynth-sensor/1"
name = "t"
kind = "synthetic-example"
source_response = {{ kind = "linear" }}
response = {{ kind = "linear" }}
[provenance]
colour = "-"
noise = "-"
levels = "-"
response = "-"
[levels]
black_level = 64.0
white_level = 4095.0
bit_depth = 12
[[noise]]
iso = 100.0
a = [1.5e-4, 1.5e-4, 1.5e-4]
b = [5.5e-7, 5.5e-7, 5.5e-7]
{effects}
"#
    );
    let p: SensorProfile =
        hdrsynth::config::parse_toml(&text, Path::new("t.toml")).expect("profile");
    p.validate().expect("valid");
    p
}

/// Rows simulated on their own (`to_dn_rows_into`, what the diagnosis simulates for bands of
/// rows) are bit-identical to those rows of the whole frame, with every spatial and temporal
/// effect on: draws and patterns depend on the frame row, not on the row's place in the input.
#[test]
fn rows_simulated_alone_equal_those_rows_of_the_whole_frame() {
    use hdrsynth::io::Image;
    use hdrsynth::sensor::effects::summary::{analysed_rows, crop_rows};
    use hdrsynth::sensor::realism::{Realism, RealismOptions};
    let p = effect_profile(
        "[[effects]]\nid = \"row_noise\"\nsigma_dn = 1.5\n\
         [[effects]]\nid = \"column_noise\"\nsigma_dn = 1.0\nseed = 3\n\
         [[effects]]\nid = \"prnu\"\nsigma = 0.01\nseed = 4\n\
         [[effects]]\nid = \"dsnu\"\nsigma_dn = 1.0\nseed = 5\n\
         [[effects]]\nid = \"vignetting\"\nstrength = 0.2\n\
         [[effects]]\nid = \"correlated_noise\"\nrho = 0.3\n\
         [[effects]]\nid = \"heavy_tailed_read_noise\"\ndof = 6\n",
    );
    let mut opts = RealismOptions::new(100.0);
    opts.colour = false;
    let r = Realism::new(&p, &opts).unwrap();
    let (w, h) = (40, 200);
    let input = Image::from_fn(w, h, |x, y| [(x + y) as f32 / 240.0, 0.3, 0.05]);
    let whole = r.to_dn(&input, 11);
    // Any budget under 8 bands gives the 8 bands of 8 rows whose tops are ⌊k·192/7⌋.
    let rows = analysed_rows(w, h, 100);
    let want: Vec<usize> = [0, 27, 54, 82, 109, 137, 164, 192]
        .iter()
        .flat_map(|&t| t..t + 8)
        .collect();
    assert_eq!(rows, want);
    assert_eq!(analysed_rows(w, h, 8 * 8 * w), want);
    let mut part = Image::new(0, 0);
    r.to_dn_rows_into(&crop_rows(input, &rows), &rows, h, 11, &mut part);
    assert_eq!(part.data, crop_rows(whole, &rows).data);
    // Every row when the frame fits the budget, or with no budget.
    assert_eq!(analysed_rows(w, h, w * h), (0..h).collect::<Vec<_>>());
    assert_eq!(analysed_rows(w, h, 0), (0..h).collect::<Vec<_>>());
}

/// The realism operator's effect path: with zero-magnitude effects it gives bit-identical output
/// to the plain path (the two agree on the base model); black offset and vignetting give the
/// hand-computed DN; channel noise scales each channel's dark variance.
#[test]
fn realism_effect_path_against_plain_path_and_hand_values() {
    use hdrsynth::io::Image;
    use hdrsynth::sensor::realism::{NoiseModel, Realism, RealismOptions};
    let base = effect_profile;
    let mut opts = RealismOptions::new(100.0);
    opts.colour = false;
    let input = Image::from_fn(64, 48, |x, y| [(x + y) as f32 / 120.0, 0.3, 0.05]);
    let plain = Realism::new(&base(""), &opts).unwrap().to_dn(&input, 5);
    let zero = base(
        "[[effects]]\nid = \"column_noise\"\nsigma_dn = 0.0\nseed = 1\n\
         [[effects]]\nid = \"dsnu\"\nsigma_dn = 0.0\nseed = 2\n",
    );
    assert_eq!(
        Realism::new(&zero, &opts).unwrap().to_dn(&input, 5).data,
        plain.data
    );

    let p = base(
        "[[effects]]\nid = \"black_level\"\noffset_dn = 5\n\
         [[effects]]\nid = \"vignetting\"\nstrength = 0.2\n",
    );
    let mut quiet = opts.clone();
    quiet.noise = NoiseModel::None;
    let dn = Realism::new(&p, &quiet)
        .unwrap()
        .to_dn(&Image::from_fn(64, 48, |_, _| [0.25; 3]), 0);
    for (x, y) in [(0usize, 0usize), (32, 24), (63, 10)] {
        let hd2 = (64.0f64 * 64.0 + 48.0 * 48.0) / 4.0;
        let r2 = ((x as f64 + 0.5 - 32.0).powi(2) + (y as f64 + 0.5 - 24.0).powi(2)) / hd2;
        let want = (64.0 + 5.0 + 0.25 * 4031.0 * (1.0 - 0.2 * r2)).round();
        assert_eq!(dn.get(x, y)[0] as f64, want, "({x}, {y})");
    }

    let p =
        base("[[effects]]\nid = \"channel_noise\"\na_scale = [1, 1, 1]\nb_scale = [4, 1, 0.25]\n");
    let dark = Realism::new(&p, &opts)
        .unwrap()
        .to_dn(&Image::new(256, 256), 9);
    let b = 5.5e-7 * 4031.0f64 * 4031.0;
    for (c, s) in [4.0, 1.0, 0.25].iter().enumerate() {
        let v: Vec<f64> = dark
            .data
            .iter()
            .skip(c)
            .step_by(3)
            .map(|&v| v as f64)
            .collect();
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64;
        let want = b * s + 1.0 / 12.0;
        assert!(
            (var / want - 1.0).abs() < 0.03,
            "channel {c}: {var} vs {want}"
        );
    }
}

/// No hidden effect, over frame sizes, frame counts and seeds: nothing is named.
#[test]
fn no_hidden_effect_over_sizes_and_seeds() {
    for s in 0..6u64 {
        let (w, h, f) = [(64, 48, 8), (96, 64, 16), (128, 96, 12)][s as usize % 3];
        let (d, _) = run(&Truth::new(w, h, f, 500 + s), &format!("null{s}"));
        assert!(
            d.steps.is_empty(),
            "seed {s}: named {:?}",
            d.steps.iter().map(|x| &x.effect).collect::<Vec<_>>()
        );
        assert!(
            d.final_gap() <= d.threshold && d.unexplained.is_empty(),
            "seed {s}"
        );
    }
}

/// The classic confusions, hidden in pairs: row noise vs correlated noise, DSNU vs
/// column FPN, PRNU vs vignetting, hot pixels vs column FPN, channel noise vs heavy tails. Both
/// are named, each parameter within 25 %, and the gap ends under the threshold.
#[test]
fn confusable_pairs_are_told_apart() {
    type Set = fn(&mut Truth);
    /// (effect id, parameter, planted value); an empty parameter is not checked.
    type Want = [(&'static str, &'static str, f64); 2];
    let pairs: [(&str, Set, Want); 5] = [
        (
            "row+corr",
            |t| {
                t.row_sigma = 1.0;
                t.corr_rho = 0.2;
            },
            [
                ("row_noise", "sigma_dn", 1.0),
                ("correlated_noise", "rho_v", 0.2),
            ],
        ),
        (
            "dsnu+col",
            |t| {
                t.dsnu_sigma = 2.0;
                t.column_sigma = 1.0;
            },
            [("dsnu", "sigma_dn", 2.0), ("column_noise", "sigma_dn", 1.0)],
        ),
        (
            "prnu+vig",
            |t| {
                t.prnu_sigma = 0.008;
                t.vignetting = 0.2;
            },
            [("prnu", "sigma", 0.008), ("vignetting", "strength", 0.2)],
        ),
        (
            "hot+col",
            |t| {
                t.hot = Some((0.003, 200.0));
                t.column_sigma = 1.5;
            },
            [
                ("hot_pixels", "offset_dn", 200.0),
                ("column_noise", "sigma_dn", 1.5),
            ],
        ),
        (
            "chan+heavy",
            |t| {
                t.channel = Some(([1.3, 1.0, 0.8], [1.5, 1.0, 0.7]));
                t.heavy_dof = Some(10.0);
            },
            [
                ("heavy_tailed_read_noise", "dof", 10.0),
                ("channel_noise", "", 0.0),
            ],
        ),
    ];
    for (k, (name, set, want)) in pairs.iter().enumerate() {
        let mut t = Truth::new(96, 64, 12, 900 + k as u64);
        set(&mut t);
        let (d, _) = run(&t, name);
        pair(&d, want[0].0, want[1].0);
        for (id, key, v) in want {
            if !key.is_empty() {
                within(param(&d, id, key), *v, &format!("{name}: {id}.{key}"));
            }
        }
    }
}

/// The final model's temporal noise against the truth: per ISO, the shared a and b (DN, DN²)
/// within `tol` of the planted ones, and every dark and flat burst's simulated mean temporal
/// variance within 3 % of the measured one (the base-model check).
/// Returns the disagreements, so a test lists every failing case at once.
fn temporal_noise_mismatches(d: &Diagnosis, t: &Truth, tol: f64, what: &str) -> Vec<String> {
    let mut bad = Vec::new();
    let p = &d.profile;
    let range = p.levels.white_level - p.levels.black_level;
    for &iso in &t.isos {
        let (a, b) = p.noise_at(iso).unwrap();
        let (ta, tb) = (t.a100 * iso / 100.0, t.b100 * iso / 100.0);
        let (a, b) = (a[0] * range, b[0] * range * range);
        if (a - ta).abs() > tol * ta || (b - tb).abs() > tol * tb {
            bad.push(format!(
                "{what}, ISO {iso}: model a {a:.4} b {b:.3}, planted a {ta} b {tb}"
            ));
        }
    }
    let rows: Vec<_> = d
        .last
        .rows
        .iter()
        .filter(|r| r.stat.key.ends_with("mean temporal variance"))
        .collect();
    assert!(!rows.is_empty());
    for r in rows {
        let rel = (r.sim_mean - r.stat.value) / r.stat.value;
        if rel.abs() >= 0.03 {
            bad.push(format!(
                "{what}: {} measured {:.3}, model {:.3} ({:+.1} %)",
                r.stat.key,
                r.stat.value,
                r.sim_mean,
                100.0 * rel
            ));
        }
    }
    bad
}

/// Black offsets from 2 to 200 DN and every fixed pattern of the
/// catalogue (column FPN, DSNU, PRNU, hot pixels, vignetting) at two ISOs leave the model's
/// temporal noise (a, b) at the planted values: temporal statistics see no fixed pattern, and the
/// pedestal is named without breaking b.
#[test]
fn fixed_patterns_and_black_offsets_leave_temporal_noise_alone() {
    type Set = fn(&mut Truth);
    let cases: [(&str, &str, Set); 9] = [
        ("black 2", "black_level", |t| t.black_offset = 2.0),
        ("black 40", "black_level", |t| t.black_offset = 40.0),
        ("black 200", "black_level", |t| t.black_offset = 200.0),
        ("column 2.5", "column_noise", |t| t.column_sigma = 2.5),
        ("column 6", "column_noise", |t| t.column_sigma = 6.0),
        ("dsnu 4", "dsnu", |t| t.dsnu_sigma = 4.0),
        ("prnu 2 %", "prnu", |t| t.prnu_sigma = 0.02),
        ("hot 0.5 %", "hot_pixels", |t| t.hot = Some((0.005, 400.0))),
        ("vignetting 0.25", "vignetting", |t| t.vignetting = 0.25),
    ];
    let mut bad = Vec::new();
    for (k, (name, id, set)) in cases.iter().enumerate() {
        let mut t = Truth::new(64, 48, 8, 1500 + k as u64);
        t.isos = vec![100.0, 400.0];
        t.a100 = 0.35;
        t.b100 = 4.0;
        set(&mut t);
        let (d, _) = run(&t, &format!("fixed-{k}"));
        if !d.steps.iter().any(|s| s.effect == *id) {
            bad.push(format!("{name}: {id} not named"));
        }
        if d.final_gap() > d.threshold {
            bad.push(format!("{name}: unexplained {:?}", d.unexplained));
        }
        bad.extend(temporal_noise_mismatches(&d, &t, 0.05, name));
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// Student-t read noise at two strengths is named and the model keeps the
/// measured temporal variance (b within 5 %, every burst's mean variance within 3 %).
#[test]
fn heavy_tails_keep_the_temporal_variance() {
    let mut bad = Vec::new();
    for (k, dof) in [5.0, 7.0].into_iter().enumerate() {
        let mut t = Truth::new(96, 64, 16, 1600 + k as u64);
        t.heavy_dof = Some(dof);
        let (d, _) = run(&t, &format!("heavy-{k}"));
        single(&d, "heavy_tailed_read_noise");
        within(param(&d, "heavy_tailed_read_noise", "dof"), dof, "dof");
        bad.extend(temporal_noise_mismatches(
            &d,
            &t,
            0.05,
            &format!("dof {dof}"),
        ));
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// Noise filtered by a 2-D Gaussian kernel (the truth's own direct 2-D
/// filter) at lag-1 correlations from ≈ 0.45 to ≈ 0.91, beyond the old family's 0.5: named
/// first, both axes' lag-1 correlation within 10 % of the value computed by hand from the
/// truth's kernel, the gap closed, and the temporal variance kept.
#[test]
fn correlated_noise_up_to_high_correlation() {
    let mut bad = Vec::new();
    for (k, s) in [0.6, 0.95, 1.6].into_iter().enumerate() {
        let mut t = Truth::new(80, 60, 12, 1700 + k as u64);
        t.corr_gauss = s;
        let want = t.gauss_lag1();
        let (d, _) = run(&t, &format!("gauss-{k}"));
        single(&d, "correlated_noise");
        for key in ["rho_h", "rho_v"] {
            let got = param(&d, "correlated_noise", key);
            if (got - want).abs() > 0.1 * want {
                bad.push(format!("σ {s}: {key} {got}, by hand {want:.4}"));
            }
        }
        bad.extend(temporal_noise_mismatches(&d, &t, 0.05, &format!("σ {s}")));
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// A response exponent with no scene bursts is found from the flat series
/// (EMVA 1288: flats at two exposure times, one illumination) at several strengths and both
/// directions, and recovered within 5 %.
#[test]
fn linearity_from_flat_series() {
    for (k, p) in [0.85, 0.93, 1.12].into_iter().enumerate() {
        let mut t = Truth::new(64, 48, 8, 1800 + k as u64);
        t.scenes = false;
        t.exponent = p;
        let (d, _) = run(&t, &format!("flat-linearity-{k}"));
        single(&d, "nonlinear_response");
        let got = param(&d, "nonlinear_response", "exponent");
        assert!((got - p).abs() <= 0.05 * p, "exponent {got}, planted {p}");
    }
}

/// Toe/shoulder responses from an EMVA 1288 flat series of seven
/// levels (5–80 % of the range before the curve), with and without a scene; the catalogue
/// names the shape it found and recovers its parameters (toe within 15 %, shoulder within
/// 10 %), and a pure power law is still named a power law. The truth applies the curves in
/// its own code (tests/truth: the definitions of `toe` and `shoulder`).
#[test]
fn response_shapes_toe_shoulder_and_power_law() {
    let levels = vec![0.05, 0.1, 0.2, 0.35, 0.5, 0.65, 0.8];
    // (toe, shoulder, exponent, scenes, shape named)
    let cases = [
        (0.03, 0.0, 1.0, false, "toe"),
        (0.08, 0.0, 1.0, true, "toe"),
        (0.0, 0.75, 1.0, false, "shoulder"),
        (0.0, 1.1, 1.0, true, "shoulder"),
        (0.05, 0.8, 1.0, false, "toe_shoulder"),
        (0.0, 0.0, 0.9, false, "power_law"),
        (0.0, 0.0, 1.1, true, "power_law"),
    ];
    let mut bad = Vec::new();
    for (k, &(toe, shoulder, p, scenes, shape)) in cases.iter().enumerate() {
        let mut t = Truth::new(64, 48, 8, 1900 + k as u64);
        t.flat_levels = levels.clone();
        t.scenes = scenes;
        (t.toe, t.shoulder, t.exponent) = (toe, shoulder, p);
        let what = format!("toe {toe}, shoulder {shoulder}, exponent {p}, scenes {scenes}");
        let (d, _) = run(&t, &format!("shape-{k}"));
        single(&d, "nonlinear_response");
        let step = &d.steps[0];
        let named = step.params.get("shape").and_then(|v| v.as_str());
        if named != Some(shape) {
            bad.push(format!("{what}: named {named:?}, want {shape}"));
            continue;
        }
        let near = |key: &str, want: f64, tol: f64| match number(&step.params, key) {
            Ok(got) if (got - want).abs() <= tol * want => None,
            got => Some(format!("{what}: {key} {got:?}, planted {want}")),
        };
        bad.extend(near("toe", toe, 0.15).filter(|_| toe > 0.0));
        bad.extend(near("shoulder", shoulder, 0.10).filter(|_| shoulder > 0.0));
        bad.extend(near("exponent", p, 0.05).filter(|_| p != 1.0));
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The response shapes against hand-computed values: toe t = 0.1 at u = 0.1 gives √0.02 − 0.1
/// = 0.0414214, shoulder s = 0.5 at v = 0.5 gives 0.5 / 2^¼ = 0.4204482, both at u = 0.3:
/// T = √0.1 − 0.1 = 0.2162278, S = T / (1 + (T/0.5)⁴)^¼ = 0.2143774; inverses round-trip;
/// profiles written before the family (`exponent` only) still load as a power law; bad
/// shapes and values are refused with the parameter named.
#[test]
fn response_curves_by_hand() {
    use hdrsynth::sensor::effects::nonlinear_response::{Curve, curve};
    let c = |toe: f64, shoulder: f64| Curve::ToeShoulder { toe, shoulder };
    let cases = [
        (c(0.1, f64::INFINITY), 0.1, 0.0414214),
        (c(0.0, 0.5), 0.5, 0.4204482),
        (c(0.1, 0.5), 0.3, 0.2143774),
        (Curve::Power(0.8), 0.5, 0.5743492),
    ];
    for (k, (f, u, want)) in cases.into_iter().enumerate() {
        let y = f.apply(u);
        assert!(
            (y - want).abs() < 1e-6,
            "case {k}: f({u}) = {y}, by hand {want}"
        );
        assert!((f.inverse(y) - u).abs() < 1e-9, "case {k}: inverse");
    }
    let t = |s: &str| -> toml::Table { toml::from_str(s).unwrap() };
    assert_eq!(curve(&t("exponent = 0.8")).ok(), Some(Curve::Power(0.8)));
    assert_eq!(
        curve(&t("shape = \"toe_shoulder\"\ntoe = 0.05\nshoulder = 0.8")).ok(),
        Some(c(0.05, 0.8))
    );
    assert_eq!(c(0.05, f64::INFINITY).shape(), "toe");
    assert_eq!(c(0.0, 0.8).shape(), "shoulder");
    for (bad, word) in [
        ("shape = \"s-curve\"", "unknown shape"),
        ("shape = \"toe\"\ntoe = 0.9", "toe 0.9"),
        (
            "shape = \"shoulder\"\ntoe = 0.1\nshoulder = 1.0",
            "unknown parameter 'toe'",
        ),
        ("shape = \"power_law\"", "missing parameter 'exponent'"),
    ] {
        let e = curve(&t(bad)).unwrap_err().to_string();
        assert!(e.contains(word), "{bad}: {e}");
    }
}

/// Every effect parameter fault is named with the effect and the parameter (messages written
/// by hand); an unknown key is reported before anything else, and a missing parameter where it
/// falls in the effect's parameter order.
#[test]
fn effect_parameter_errors_name_the_effect_and_the_parameter() {
    use hdrsynth::sensor::effects::Plan;
    use hdrsynth::sensor::profile::EffectSpec;
    let cases = [
        (
            "row_noise",
            "sigma_dn = 1\nextra = 2",
            "unknown parameter 'extra' (expected sigma_dn)",
        ),
        ("row_noise", "", "missing parameter 'sigma_dn'"),
        (
            "row_noise",
            "sigma_dn = \"x\"",
            "'sigma_dn' must be a finite number, got \"x\"",
        ),
        (
            "row_noise",
            "sigma_dn = nan",
            "'sigma_dn' must be a finite number, got nan",
        ),
        ("row_noise", "sigma_dn = -1", "sigma_dn -1 must be ≥ 0"),
        (
            "vignetting",
            "strength = [1]",
            "'strength' must be a finite number, got [1]",
        ),
        (
            "dsnu",
            "zz = 1",
            "unknown parameter 'zz' (expected sigma_dn, seed)",
        ),
        (
            "dsnu",
            "sigma_dn = 1",
            "missing parameter 'seed' (fixed patterns derive from it)",
        ),
        (
            "dsnu",
            "sigma_dn = 1\nseed = -3",
            "'seed' must be an integer ≥ 0, got -3",
        ),
        (
            "dsnu",
            "sigma_dn = 1\nseed = 1.5",
            "'seed' must be an integer ≥ 0, got 1.5",
        ),
        (
            "hot_pixels",
            "offset_dn = \"x\"\nseed = 1",
            "missing parameter 'fraction'",
        ),
        (
            "hot_pixels",
            "fraction = 0.5\noffset_dn = 1\nseed = 1",
            "fraction 0.5 must be in [0, 0.1) and offset_dn 1 ≥ 0",
        ),
        (
            "channel_noise",
            "b_scale = [1, 1, 1]",
            "'a_scale' must be an array of 3 numbers",
        ),
        (
            "channel_noise",
            "a_scale = 2\nb_scale = [1, 1, 1]",
            "'a_scale' must be an array of 3 numbers",
        ),
        (
            "channel_noise",
            "a_scale = [1, \"x\", 1]\nb_scale = [1, 1, 1]",
            "'a_scale' must be 3 numbers > 0",
        ),
        (
            "channel_noise",
            "a_scale = [1, 1]\nb_scale = [1, 1, 1]",
            "'a_scale' must be 3 numbers > 0",
        ),
        (
            "channel_noise",
            "a_scale = [1, 1, 1]\nb_scale = [1, 0, 1]",
            "'b_scale' must be 3 numbers > 0",
        ),
        (
            "correlated_noise",
            "rho_h = 0.2",
            "needs rho_h and rho_v (or rho for both axes)",
        ),
        (
            "correlated_noise",
            "rho_h = 0.99\nrho_v = 0.1",
            "rho_h 0.99 must be in [0, 0.95]",
        ),
        (
            "correlated_noise",
            "rho = true",
            "'rho' must be a finite number, got true",
        ),
        (
            "heavy_tailed_read_noise",
            "dof = 3",
            "dof 3 must be > 4 (finite kurtosis)",
        ),
        (
            "nonlinear_response",
            "shape = 3",
            "'shape' must be a string, got 3",
        ),
        (
            "nonlinear_response",
            "shape = \"toe_shoulder\"\ntoe = 0.1",
            "missing parameter 'shoulder'",
        ),
        (
            "nonlinear_response",
            "exponent = 1\ntoe = 0.1",
            "unknown parameter 'toe' (expected shape, exponent)",
        ),
    ];
    for (id, params, want) in cases {
        let spec = EffectSpec {
            id: id.into(),
            params: toml::from_str(params).unwrap(),
        };
        let got = Plan::from_effects(&[spec]).unwrap_err().to_string();
        assert_eq!(got, format!("effect '{id}': {want}"), "{id} {{ {params} }}");
    }
}

/// The null case with the seven-level flat series (six response statistics per ISO) stays
/// clean over seeds and two ISOs.
#[test]
fn linear_sensor_with_a_long_flat_series_names_nothing() {
    for seed in 0..3u64 {
        let mut t = Truth::new(64, 48, 8, 1950 + seed);
        t.flat_levels = vec![0.05, 0.1, 0.2, 0.35, 0.5, 0.65, 0.8];
        t.isos = vec![100.0, 400.0];
        let (d, _) = run(&t, &format!("linear-long-{seed}"));
        assert!(
            d.steps.is_empty() && d.final_gap() <= d.threshold,
            "seed {seed}: {}",
            d.report_json()
        );
    }
}

/// A scene-only set (three scenes of one size, an EV0/EV−3 pair each, one
/// frame per burst, no darks or flats) runs without a profile; with `scene` keys each pair is
/// compared within its scene and the shared tone curve is named and recovered (exponents 0.8
/// and 1.15); the statistics the set cannot support are listed as not tested. Without the keys
/// the size fallback is used and the report says so.
#[test]
fn scene_only_sets_group_by_scene_key() {
    let opts = DiagnoseOptions {
        replicates: 12,
        seed: 3,
        ..DiagnoseOptions::default()
    };
    for (k, p) in [0.8, 1.15].into_iter().enumerate() {
        let dir = std::env::temp_dir().join(format!("hdrsynth-scenes-{k}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        truth::write_scene_pairs(&dir, 48, 32, &[p, p, p], true, 40 + k as u64);
        let set = CaptureSet::load(&dir).expect("load");
        let d = diagnose(&set, None, &opts).expect("a scene-only set runs without a profile");
        eprintln!("{}\n{:?}\n{:?}", d.report_json(), d.notes, d.skipped);
        single(&d, "nonlinear_response");
        let got = param(&d, "nonlinear_response", "exponent");
        assert!((got - p).abs() <= 0.05 * p, "exponent {got}, planted {p}");
        // Three scenes, one pair each: three statistics, one per scene.
        let n = d
            .initial
            .rows
            .iter()
            .filter(|r| r.stat.effect == Some("nonlinear_response"))
            .count();
        assert_eq!(n, 3);
        for id in ["row_noise", "dsnu", "prnu", "vignetting", "black_level"] {
            assert!(
                d.skipped
                    .iter()
                    .any(|s| s.starts_with(&format!("{id}: not tested"))),
                "{id} not listed as skipped: {:?}",
                d.skipped
            );
        }
        assert!(!d.notes.iter().any(|n| n.contains("grouped by frame size")));
        let _ = std::fs::remove_dir_all(&dir);
    }
    // A tone curve that differs between scenes (like the paper's frames, whose EV0/EV−3 ratio
    // varies 9–29): no single power law explains it, and the report says the frames hide a
    // tone curve.
    let dir = std::env::temp_dir().join(format!("hdrsynth-scenes-mixed-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    truth::write_scene_pairs(&dir, 48, 32, &[0.9, 1.2, 1.5], true, 60);
    let set = CaptureSet::load(&dir).expect("load");
    let d = diagnose(&set, None, &opts).expect("diagnose");
    assert!(!d.unexplained.is_empty(), "{}", d.report_json());
    assert!(
        d.notes.iter().any(|n| n.contains("hide a tone curve")),
        "{:?}",
        d.notes
    );
    let _ = std::fs::remove_dir_all(&dir);
    // No keys: the fallback groups the six bursts as one scene, and the report says so.
    let dir = std::env::temp_dir().join(format!("hdrsynth-scenes-nokey-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    truth::write_scene_pairs(&dir, 48, 32, &[1.0, 1.0, 1.0], false, 50);
    let set = CaptureSet::load(&dir).expect("load");
    let d = diagnose(&set, None, &opts).expect("diagnose");
    assert!(
        d.notes.iter().any(|n| n.contains("grouped by frame size")),
        "{:?}",
        d.notes
    );
    let _ = std::fs::remove_dir_all(&dir);
}
