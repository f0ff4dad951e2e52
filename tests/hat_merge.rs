//! The ground truth of a bracket test set: the weighted merge of every frame
//! (`testset::hat_merge`), against hand values and against a known radiance.

use hdrsynth::capture::testset::{code_weight, hat_merge};
use hdrsynth::io::Image;
use hdrsynth::rng::Rng;

#[test]
fn the_hat_merge_matches_hand_values() {
    let px = |v: [f32; 3]| Image::from_vec(1, 1, v.to_vec());
    // Weights: the hat of the code, 0 at codes ≤ 5 and ≥ 250 (of 255).
    assert_eq!(code_weight(0.5), 1.0);
    assert_eq!(code_weight(250.0 / 255.0), 0.0);
    assert_eq!(code_weight(5.0 / 255.0), 0.0);
    assert!((code_weight(249.0 / 255.0) - 12.0 / 255.0).abs() < 1e-6);
    assert!((code_weight(6.0 / 255.0) - 12.0 / 255.0).abs() < 1e-6);
    // One pixel per frame: each frame's code ↔ value table holds one point, so the code
    // expected at the merged value is the code recorded and the refinements keep the first
    // pass. γ 1, times 0.5 and 4. Channel 0: codes 0.25 and 0.75 (hat 0.5 each), so
    // w = 0.5 · 0.5 and 0.5 · 4: H = (0.25 · 0.25/0.5 + 2 · 0.75/4) / 2.25 = 0.5 / 2.25.
    // Channel 1: clipped in both: the shortest's white over its time, 1/0.5 = 2. Channel 2:
    // dark in both (codes 0 and 0.01 · 255 = 2.55): the longest frame not clipped, 0.01/4.
    let v = [px([0.25, 1.0, 0.0]), px([0.75, 1.0, 0.01])];
    let h = hat_merge(&v, &v, &[0.5, 4.0], 1.0).expect("merge");
    assert!((h.data[0] as f64 - 0.5 / 2.25).abs() < 1e-7, "{:?}", h.data);
    assert_eq!(h.data[1], 2.0);
    assert!((h.data[2] - 0.0025).abs() < 1e-9, "{:?}", h.data);
    // γ 2.2, codes apart from the written values: codes 0.5 and 0.9 weigh 1 · 1 and 0.2 · 2;
    // values 0.5 and 0.9: H = (0.5^2.2 / 1 + 0.4 · 0.9^2.2 / 2) / 1.4.
    let h = hat_merge(
        &[px([0.5; 3]), px([0.9; 3])],
        &[px([0.5; 3]), px([0.9; 3])],
        &[1.0, 2.0],
        2.2,
    )
    .expect("merge");
    let want = (0.5f64.powf(2.2) + 0.4 * 0.9f64.powf(2.2) / 2.0) / 1.4;
    assert!(
        (h.data[0] as f64 - want).abs() < 1e-6,
        "{} vs {want}",
        h.data[0]
    );
    assert!(hat_merge(&v, &v, &[1.0], 1.0).is_err());
}

/// A noisy 8-bit bracket of a known radiance: 5 frames 2 stops apart, white noise
/// σ² = a·x + b on the linear signal (a 2e-4, b 2e-6, the generated device of
/// tools/generated_bracket.sh), codes 255 · x^(1/1.8) rounded; the written values are the
/// linear signal^(1/2.2) as a test set stores them.
struct Bracket {
    radiance: Vec<f64>,
    frames: Vec<Image>,
    codes: Vec<Image>,
    times: Vec<f64>,
}

fn noisy_bracket() -> Bracket {
    let (w, h) = (256usize, 64usize);
    // Radiance (the t = 1 frame's linear value) from 1e-4 to 4, log-spaced along x.
    let radiance: Vec<f64> = (0..w * h * 3)
        .map(|k| {
            let x = (k / 3) % w;
            1e-4 * (4e4f64).powf(x as f64 / (w - 1) as f64)
        })
        .collect();
    let times = vec![1.0 / 16.0, 0.25, 1.0, 4.0, 16.0];
    let mut rng = Rng::new(7);
    let mut gauss = move || {
        let (u, v) = (rng.f32().max(1e-7) as f64, rng.f32() as f64);
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    let (mut frames, mut codes) = (Vec::new(), Vec::new());
    for &t in &times {
        let mut code = Vec::with_capacity(radiance.len());
        let mut written = Vec::with_capacity(radiance.len());
        for &e in &radiance {
            let x = (e * t).min(1.0);
            let noisy = (x + (2e-4 * x + 2e-6).sqrt() * gauss()).clamp(0.0, 1.0);
            let z = (255.0 * noisy.powf(1.0 / 1.8)).round() / 255.0;
            code.push(z as f32);
            written.push(z.powf(1.8).powf(1.0 / 2.2) as f32);
        }
        codes.push(Image::from_vec(w, h, code));
        frames.push(Image::from_vec(w, h, written));
    }
    Bracket {
        radiance,
        frames,
        codes,
        times,
    }
}

/// μ-law (μ = 5000, as PSNR-T) of a value in the t = 1 frame's unit.
fn mu_law(v: f64) -> f64 {
    (1.0 + 5000.0 * v.max(0.0)).ln() / 5001f64.ln()
}

#[test]
fn the_hat_merge_is_unbiased_in_the_shadows_of_a_noisy_bracket() {
    let b = noisy_bracket();
    let merged = hat_merge(&b.frames, &b.codes, &b.times, 2.2).expect("merge");
    let longest = b.times.len() - 1;
    // Shadows: the longest frame is expected to record codes 4–40 (radiance below ~1.5e-3).
    let shadow = |e: f64| {
        let c = 255.0 * (e * b.times[longest]).min(1.0).powf(1.0 / 1.8);
        (4.0..=40.0).contains(&c)
    };
    let (mut n, mut ratio, mut se_merge, mut se_longest) = (0usize, 0.0f64, 0.0f64, 0.0f64);
    for (k, &e) in b.radiance.iter().enumerate() {
        if !shadow(e) {
            continue;
        }
        let m = f64::from(merged.data[k]);
        let l = f64::from(b.frames[longest].data[k]).powf(2.2) / b.times[longest];
        n += 1;
        ratio += m / e;
        se_merge += (mu_law(m) - mu_law(e)).powi(2);
        se_longest += (mu_law(l) - mu_law(e)).powi(2);
    }
    let (bias, rmse_merge, rmse_longest) = (
        ratio / n as f64 - 1.0,
        (se_merge / n as f64).sqrt(),
        (se_longest / n as f64).sqrt(),
    );
    eprintln!(
        "{n} shadow samples: mean ratio − 1 {bias:+.4}, μ-law RMSE merge {rmse_merge:.5}, longest frame alone {rmse_longest:.5}"
    );
    // Weights from each sample's own code (the first pass alone) kept only the upward
    // excursions of the longest frame near its floor: the merge sat at 2.9× the radiance here
    // (μ-law RMSE 0.061 against the longest frame's 0.023).
    assert!(bias.abs() < 0.05, "shadow bias {bias:+.4}");
    assert!(
        rmse_merge <= rmse_longest,
        "merge {rmse_merge:.5} vs the longest frame alone {rmse_longest:.5}"
    );
    // Mid-tones, where several frames record mid codes: within 1 % of the radiance on average.
    let (mut n, mut ratio) = (0usize, 0.0f64);
    for (k, &e) in b.radiance.iter().enumerate() {
        if (0.01..0.5).contains(&e) {
            n += 1;
            ratio += f64::from(merged.data[k]) / e;
        }
    }
    let mid = ratio / n as f64 - 1.0;
    assert!(mid.abs() < 0.01, "mid-tone bias {mid:+.4}");
}
