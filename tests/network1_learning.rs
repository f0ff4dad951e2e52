//! Making Network-1 learn: the loss readings against hand-computed values and
//! gradients, target smoothing against a hand computation, the best-constant baseline, the
//! config keys, and a short training run that must beat the best constant on held-out pairs.

mod common;

use burn::tensor::{Device, Int, Tensor};
use hdrsynth::config::parse_toml;
use hdrsynth::data::ground_truth::{
    blend_classes, blend_classes_smoothed, gaussian_blur, smoothed_ratio,
};
use hdrsynth::data::loader::{Sample, Target};
use hdrsynth::io::Image;
use hdrsynth::train::config::TrainConfig;
use hdrsynth::train::loss::{
    Network1Reading, network1_loss, ordinal_l1, soft_cross_entropy, weighted_cross_entropy,
};
use hdrsynth::train::task::best_constant_weight_mae;
use std::path::Path;

fn close(a: f32, b: f64, tol: f64, what: &str) {
    assert!((a as f64 - b).abs() < tol, "{what}: {a} vs hand value {b}");
}

/// The two pixels of tests/blend_unet.rs's Eq. 4 example, as one 1×2 image:
/// A: p = (0.1, 0.6, 0.2, 0.1), target 1, α = 2;  B: p = (0.25, 0.25, 0.4, 0.1), target 3, α = 3.
fn example(dev: &Device) -> (Tensor<4>, Tensor<3, Int>, Tensor<1>) {
    let probs = Tensor::<4>::from_floats(
        [[[[0.1, 0.25]], [[0.6, 0.25]], [[0.2, 0.4]], [[0.1, 0.1]]]],
        dev,
    );
    let target = Tensor::<3, Int>::from_ints([[[1, 3]]], dev);
    let alpha = Tensor::<1>::from_floats([0.5, 2.0, 1.0, 3.0], dev);
    (probs, target, alpha)
}

/// Ordinal: expected weight E = Σ p_c·c/3.
/// A: E = (0.6 + 0.4 + 0.3)/3 = 0.4333…, t = 1/3 → |0.1| · 2 = 0.2
/// B: E = (0.25 + 0.8 + 0.3)/3 = 0.45, t = 1 → 0.55 · 3 = 1.65;   mean 0.925.
/// Cross-entropy: A: −2 ln 0.6 = 1.021651, B: −3 ln 0.1 = 6.907755;   mean 3.964703.
/// Soft (σ = 1 class): q ∝ exp(−(c − t)²/2); A: (e^−½, 1, e^−½, e^−2), B: (e^−9/2, e^−2, e^−½, 1).
#[test]
fn loss_readings_hand_values() {
    let dev = Device::flex();
    let (p, t, a) = example(&dev);
    close(
        ordinal_l1(p.clone(), t.clone(), a.clone()).into_scalar(),
        0.925,
        1e-6,
        "ordinal",
    );
    let logits = p.clone().log();
    close(
        weighted_cross_entropy(logits.clone(), t.clone(), a.clone()).into_scalar(),
        3.964_703,
        1e-5,
        "cross-entropy",
    );
    let e = |x: f64| (-x).exp();
    let ce = |q: [f64; 4], p: [f64; 4]| -> f64 {
        let s: f64 = q.iter().sum();
        -q.iter().zip(p).map(|(q, p)| q / s * p.ln()).sum::<f64>()
    };
    let soft_a = 2.0 * ce([e(0.5), 1.0, e(0.5), e(2.0)], [0.1, 0.6, 0.2, 0.1]);
    let soft_b = 3.0 * ce([e(4.5), e(2.0), e(0.5), 1.0], [0.25, 0.25, 0.4, 0.1]);
    // (2.721183 and 5.239137.)
    close(
        soft_cross_entropy(logits.clone(), t.clone(), a.clone(), 1.0).into_scalar(),
        (soft_a + soft_b) / 2.0,
        1e-5,
        "soft",
    );
    // Tiny σ: the soft labels are one-hot, the loss is the cross-entropy.
    close(
        soft_cross_entropy(logits.clone(), t.clone(), a.clone(), 0.01).into_scalar(),
        3.964_703,
        1e-5,
        "soft, σ → 0",
    );
    // The dispatcher takes logits: the literal reading is paper Eq. 4 (3.5, tests/blend_unet.rs).
    let lit: f32 = network1_loss(
        Network1Reading::Literal,
        logits.clone(),
        t.clone(),
        a.clone(),
        8.0,
    )
    .into_scalar();
    close(lit, 3.5, 1e-5, "literal through the dispatcher");
    let ord: f32 = network1_loss(Network1Reading::Ordinal, logits, t, a, 8.0).into_scalar();
    close(ord, 0.925, 1e-5, "ordinal through the dispatcher");
}

/// A confidently wrong pixel: logits (20, 0, 0, 0) (p₀ ≈ 1), target 3, α = 1. Eq. 4's gradient
/// is −2·p_t(1 − p_t) at z_t ≈ −4e−9: it vanishes with p_t. Cross-entropy's is p − onehot, so
/// ≈ −1 at z_t and ≈ +1 at z₀; the soft reading's is p − q with q the soft label.
#[test]
fn new_readings_have_a_gradient_where_eq4_has_none() {
    let dev = Device::flex().autodiff();
    let target = Tensor::<3, Int>::from_ints([[[3]]], &dev);
    let alpha = Tensor::<1>::from_floats([1.0, 1.0, 1.0, 1.0], &dev);
    let grad = |reading: Network1Reading, sigma: f32| -> Vec<f32> {
        let z =
            Tensor::<4>::from_floats([[[[20.0]], [[0.0]], [[0.0]], [[0.0]]]], &dev).require_grad();
        let loss = network1_loss(reading, z.clone(), target.clone(), alpha.clone(), sigma);
        z.grad(&loss.backward())
            .expect("gradient")
            .into_data()
            .try_to_vec::<f32>()
            .expect("f32")
    };
    let lit = grad(Network1Reading::Literal, 1.0);
    assert!(lit.iter().all(|g| g.abs() < 1e-7), "Eq. 4 gradient {lit:?}");
    let ce = grad(Network1Reading::CrossEntropy, 1.0);
    for (g, want) in ce.iter().zip([1.0, 0.0, 0.0, -1.0]) {
        close(*g, want, 1e-5, "cross-entropy gradient");
    }
    // σ = 1: q ∝ (e^−9/2, e^−2, e^−½, 1); gradient p − q with p = (1, 0, 0, 0).
    let e = |x: f64| (-x).exp();
    let q = [e(4.5), e(2.0), e(0.5), 1.0];
    let s: f64 = q.iter().sum();
    let want = [1.0 - q[0] / s, -q[1] / s, -q[2] / s, -q[3] / s];
    let soft = grad(Network1Reading::Soft, 1.0);
    for (g, w) in soft.iter().zip(want) {
        close(*g, w, 1e-5, "soft gradient");
    }
    // A uniform softmax (logits 0) far from the target: the ordinal reading's gradient is
    // α·sign(E − t)·p_c(c/3 − E) = −¼(c/3 − ½) = (1/8, 1/24, −1/24, −1/8): every class moves,
    // and not in proportion to p_t.
    let z = Tensor::<4>::zeros([1, 4, 1, 1], &dev).require_grad();
    let loss = network1_loss(
        Network1Reading::Ordinal,
        z.clone(),
        target.clone(),
        alpha,
        1.0,
    );
    let g = z.grad(&loss.backward()).expect("gradient");
    let g = g.into_data().try_to_vec::<f32>().expect("f32");
    for (g, w) in g
        .iter()
        .zip([1.0 / 8.0, 1.0 / 24.0, -1.0 / 24.0, -1.0 / 8.0])
    {
        close(*g, w, 1e-6, "ordinal gradient");
    }
}

/// The Gaussian of σ = 1 has taps e^(−k²/2), |k| ≤ 3, summing to S = 2.505950. A unit impulse
/// in the centre of a 7×7 map becomes g_i·g_j: centre 1/S² = 0.159241, (±1, 0) e^−½/S² =
/// 0.096585, (±1, ±1) e^−1/S² = 0.058582, e^−9/2/S² = 0.001769 per tap at (±3, 0).
/// At a border, reflect-101: a 2×1 map (1, 0) with σ = 1/3 (taps k = −1..1, t₀ = 1/(1 + 2e^−9/2),
/// t₁ = e^−9/2·t₀) gives (t₀·1 + 2t₁·0, t₀·0 + 2t₁·1) = (t₀, 2t₁).
#[test]
fn gaussian_smoothing_hand_values() {
    let mut map = vec![0f32; 49];
    map[3 * 7 + 3] = 1.0;
    let out = gaussian_blur(&map, 7, 7, 1.0);
    close(out[3 * 7 + 3], 0.159_241_1, 1e-6, "centre");
    close(out[3 * 7 + 4], 0.096_584_6, 1e-6, "(+1, 0)");
    close(out[2 * 7 + 3], 0.096_584_6, 1e-6, "(0, −1)");
    close(out[4 * 7 + 4], 0.058_581_5, 1e-6, "(+1, +1)");
    // (+3, 0) is the last column: its taps k = −3 and k = +3 (reflect-101: column 9 → 3) both
    // read the impulse, 2·e^−9/2/S².
    close(
        out[3 * 7 + 6],
        2.0 * 0.001_769_0,
        1e-6,
        "(+3, 0), at the border",
    );
    // Reflect-101 counts the distance-3 tap twice at both borders of each axis: total mass
    // (1 + 2·e^−9/2/S)² = 1.017811.
    let per_axis = 1.0 + 2.0 * (-4.5f64).exp() / 2.505_949_9;
    close(out.iter().sum::<f32>(), per_axis * per_axis, 1e-5, "mass");

    let t0 = 1.0 / (1.0 + 2.0 * (-4.5f64).exp());
    let t1 = (-4.5f64).exp() * t0;
    let out = gaussian_blur(&[1.0, 0.0], 2, 1, 1.0 / 3.0);
    close(out[0], t0, 1e-6, "border pixel");
    close(out[1], 2.0 * t1, 1e-6, "its neighbour");
    // σ = 0: unchanged.
    assert_eq!(gaussian_blur(&[0.25, 0.5], 2, 1, 0.0), vec![0.25, 0.5]);

    // The smoothed ratio blurs each frame's raw weights, then normalises: low (1, 3), high
    // (3, 1) → blurred low (t₀ + 2t₁·3, 3t₀ + 2t₁), high (3t₀ + 2t₁, t₀ + 6t₁).
    let w = smoothed_ratio(&[1.0, 3.0], &[3.0, 1.0], 2, 1, 1.0 / 3.0);
    let (l0, l1) = (t0 + 6.0 * t1, 3.0 * t0 + 2.0 * t1);
    let (h0, h1) = (3.0 * t0 + 2.0 * t1, t0 + 6.0 * t1);
    close(w[0], h0 / (l0 + h0), 1e-6, "ratio 0");
    close(w[1], h1 / (l1 + h1), 1e-6, "ratio 1");
}

/// σ = 0 reproduces the paper's class maps exactly; a large σ leaves a smooth map in which
/// neighbouring classes differ by far less than in the per-pixel one.
#[test]
fn smoothed_classes_reduce_to_the_paper_at_sigma_zero() {
    let (w, h) = (24, 16);
    let low = Image::from_vec(
        w,
        h,
        common::values(w * h * 3, 5)
            .iter()
            .map(|v| v * 0.3)
            .collect(),
    );
    let high = Image::from_vec(w, h, common::values(w * h * 3, 6));
    let raw = blend_classes(&low, &high).expect("classes");
    assert_eq!(blend_classes_smoothed(&low, &high, 0.0).expect("σ 0"), raw);
    let smooth = blend_classes_smoothed(&low, &high, 3.0).expect("σ 3");
    let jump = |c: &[u8]| -> f64 {
        c.windows(2)
            .map(|p| (p[0] as f64 - p[1] as f64).abs())
            .sum::<f64>()
            / (c.len() - 1) as f64
    };
    assert!(
        jump(&smooth) < 0.25 * jump(&raw),
        "mean neighbour jump {} (σ 3) vs {} (raw)",
        jump(&smooth),
        jump(&raw)
    );
}

/// The best constant under the mean absolute error is the median: targets 0, 0, 255 and 51
/// (weights 0, 0, 1, 0.2) have the lower median 0, MAE (0 + 0 + 1 + 0.2)/4 = 0.3.
#[test]
fn best_constant_is_the_median() {
    let sample = |c: Vec<u8>| Sample {
        input: vec![0.0; 6 * c.len()],
        channels: 6,
        size: 1,
        target: Target::Classes(c),
        exposure_times: vec![0.125, 1.0],
        set: "s".into(),
        iso: None,
    };
    let (m, mae) =
        best_constant_weight_mae(&[sample(vec![0, 0]), sample(vec![255, 51])]).expect("classes");
    assert_eq!(m, 0.0);
    assert!((mae - 0.3).abs() < 1e-12, "{mae}");
    // Three pixels 0, 51, 255: median 0.2, MAE (0.2 + 0 + 0.8)/3.
    let (m, mae) = best_constant_weight_mae(&[sample(vec![0, 51, 255])]).expect("classes");
    assert!(
        (m - 0.2).abs() < 1e-12 && (mae - 1.0 / 3.0).abs() < 1e-12,
        "{m} {mae}"
    );
}

const MINIMAL: &str = "[run]\nout = \"r\"\nseed = 1\nsteps = 1\n[model]\nkind = \"blend_unet\"\n\
                       [data]\ndataset = \"d\"\npatch = 64\nbatch_size = 1\nprofile = \"pure\"\n";

#[test]
fn config_keys_defaults_and_refusals() {
    let parse = |extra: &str| -> hdrsynth::error::Result<TrainConfig> {
        let cfg: TrainConfig = parse_toml(&format!("{MINIMAL}{extra}"), Path::new("t.toml"))?;
        cfg.validate()?;
        Ok(cfg)
    };
    let d = parse("").expect("defaults");
    assert_eq!(d.loss.reading, Network1Reading::Soft);
    assert_eq!(d.loss.alpha, "uniform");
    assert_eq!(
        d.data.target_sigma,
        hdrsynth::train::config::DEFAULT_TARGET_SIGMA
    );
    let lit = parse("[loss]\nreading = \"literal\"\n").expect("literal");
    assert_eq!(lit.loss.reading, Network1Reading::Literal);
    for r in ["ordinal", "cross_entropy", "soft"] {
        parse(&format!("[loss]\nreading = \"{r}\"\nlabel_sigma = 2.0\n")).expect(r);
    }
    let e = parse("[loss]\nreading = \"l2\"\n").expect_err("unknown reading");
    assert!(e.to_string().contains("t.toml"), "{e}");
    let e = parse("[loss]\nlabel_sigma = 0.0\n").expect_err("σ 0");
    assert!(e.to_string().contains("label_sigma"), "{e}");
    let e = parse("").map(|mut c| {
        c.data.target_sigma = -1.0;
        c.validate()
    });
    assert!(
        matches!(e, Ok(Err(ref err)) if err.to_string().contains("data.target_sigma")),
        "{e:?}"
    );
}

/// A short run with the defaults (soft labels, uniform α, targets smoothed with σ = 4 px) must
/// beat the best constant predictor on held-out pairs (other scenes, another generator seed),
/// scored against the paper's per-pixel targets, by 20 %. Measured (docs/network1.md): defaults
/// 0.209 vs constant 0.308 (0.68×); the old defaults (literal Eq. 4, stream α, per-pixel
/// targets) 0.264 (0.86×), so this test fails on the old code.
#[test]
fn a_short_run_beats_the_best_constant_on_held_out_pairs() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (train, val) = (tmp.path().join("train"), tmp.path().join("val"));
    common::generate(&train, 21, 6, (96, 80), "[-3.0, 0.0]");
    common::generate(&val, 22, 4, (96, 80), "[-3.0, 0.0]");
    let run = tmp.path().join("run");
    let text = format!(
        "[run]\nout = {run:?}\nseed = 3\nsteps = {STEPS}\ncheckpoint_every = {STEPS}\n\
         log_every = 10\n\
         [model]\nkind = \"blend_unet\"\nbase_width = 4\ndepth = 2\n\
         [data]\ndataset = {train:?}\npatch = 32\nbatch_size = 4\nworkers = 2\nprofile = \"pure\"\n\
         [optim]\nlr = 3e-3\n[schedule]\nkind = \"cosine\"\nwarmup_steps = 10\n\
         [validation]\ndataset = {val:?}\nevery = {STEPS}\nsamples = 4\npatch = 64\n"
    );
    let cfg: TrainConfig = parse_toml(&text, Path::new("t.toml")).expect("config");
    hdrsynth::train::run(&cfg, &hdrsynth::train::TrainOptions::default()).expect("train");
    let at = |step, key| common::validation_at(&run, step, key);
    let (mae0, mae1, constant) = (
        at(0, "weight_mae"),
        at(STEPS, "weight_mae"),
        at(STEPS, "weight_mae_const"),
    );
    println!("held-out blend-weight MAE {mae0:.4} → {mae1:.4}; best constant {constant:.4}");
    assert!(
        mae1 < 0.8 * constant,
        "held-out MAE {mae1} is not 20 % below the best constant's {constant}"
    );
}

const STEPS: u64 = 150;
