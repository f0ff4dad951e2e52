//! The realism operator against hand-computed expectations: mean and variance at a flat input,
//! colour transform, clipping, response curves, ISO interpolation, determinism.

use hdrsynth::io::Image;
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::sensor::realism::{NoiseModel, Realism, RealismOptions};
use std::path::Path;

/// Black 64, white 4095 (12 bits): range 4031 DN. Noise (normalised) at ISO 100 and 400.
fn profile(source: &str, response: &str, matrix: &str) -> SensorProfile {
    let text = format!(
        r#"
format = "hdrsynth-sensor/1"
name = "test-sensor"
kind = "synthetic-example"
source_response = {source}
response = {response}
[provenance]
colour = "invented for tests"
noise = "invented for tests"
levels = "invented for tests"
response = "invented for tests"
[colour]
matrix = {matrix}
[levels]
black_level = 64.0
white_level = 4095.0
bit_depth = 12
[[noise]]
iso = 100.0
a = [0.0005, 0.0004, 0.0006]
b = [2e-6, 1e-6, 3e-6]
[[noise]]
iso = 400.0
a = [0.002, 0.0016, 0.0024]
b = [3.2e-5, 1.6e-5, 4.8e-5]
"#
    );
    let p: SensorProfile =
        hdrsynth::config::parse_toml(&text, Path::new("test-profile.toml")).expect("profile");
    p.validate().expect("valid");
    p
}

const IDENTITY: &str = "[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]";
const LINEAR: &str = r#"{ kind = "linear" }"#;

fn flat(w: usize, h: usize, v: [f32; 3]) -> Image {
    Image::from_fn(w, h, |_, _| v)
}

fn mean_var(img: &Image, c: usize) -> (f64, f64) {
    let v: Vec<f64> = img
        .data
        .iter()
        .skip(c)
        .step_by(3)
        .map(|&x| x as f64)
        .collect();
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (
        m,
        v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0),
    )
}

fn check_flat(noise: NoiseModel) {
    let p = profile(LINEAR, LINEAR, IDENTITY);
    let mut o = RealismOptions::new(100.0);
    o.noise = noise;
    let r = Realism::new(&p, &o).expect("realism");
    let dn = r.to_dn(&flat(512, 512, [0.3, 0.3, 0.3]), 42);
    let n = 512.0f64 * 512.0;
    // Signal above black: 0.3 · 4031 = 1209.3 DN. Variance in DN²: a·4031·I + b·4031² + 1/12.
    let i = 0.3 * 4031.0;
    for (c, (a, b)) in [(0.0005, 2e-6), (0.0004, 1e-6), (0.0006, 3e-6)]
        .into_iter()
        .enumerate()
    {
        let var = a * 4031.0 * i + b * 4031.0 * 4031.0 + 1.0 / 12.0;
        let (m, v) = mean_var(&dn, c);
        let se_mean = (var / n).sqrt();
        assert!(
            (m - (64.0 + i)).abs() < 4.0 * se_mean,
            "{noise:?} ch{c}: mean {m} vs {}",
            64.0 + i
        );
        // Standard error of a sample variance of n normal draws: var·√(2/(n−1)).
        let se_var = var * (2.0 / (n - 1.0)).sqrt();
        assert!(
            (v - var).abs() < 4.0 * se_var,
            "{noise:?} ch{c}: variance {v} vs {var}"
        );
    }
}

#[test]
fn flat_input_has_the_configured_mean_and_variance_gaussian() {
    check_flat(NoiseModel::Gaussian);
}

#[test]
fn flat_input_has_the_configured_mean_and_variance_poisson_gaussian() {
    check_flat(NoiseModel::PoissonGaussian);
}

#[test]
fn iso_between_calibrations_interpolates_in_log_iso() {
    let p = profile(LINEAR, LINEAR, IDENTITY);
    // ISO 200 is halfway between 100 and 400 in log2: a_R = (0.0005 + 0.002)/2 = 0.00125,
    // b_R = (2e-6 + 3.2e-5)/2 = 1.7e-5.
    let (a, b) = p.noise_at(200.0).expect("in range");
    assert!((a[0] - 0.00125).abs() < 1e-12 && (b[0] - 1.7e-5).abs() < 1e-15);
    let r = Realism::new(&p, &RealismOptions::new(200.0)).expect("realism");
    let dn = r.to_dn(&flat(512, 512, [0.3, 0.3, 0.3]), 7);
    let i = 0.3 * 4031.0;
    let var = 0.00125 * 4031.0 * i + 1.7e-5 * 4031.0f64.powi(2) + 1.0 / 12.0;
    let (_, v) = mean_var(&dn, 0);
    assert!((v / var - 1.0).abs() < 0.02, "variance {v} vs {var}");
    let err = Realism::new(&p, &RealismOptions::new(800.0))
        .err()
        .expect("out of range");
    assert!(
        err.to_string().contains("outside the calibrated range"),
        "{err}"
    );
}

#[test]
fn colour_transform_and_quantisation_without_noise() {
    let m = "[[0.9, 0.2, -0.1], [0.05, 0.85, 0.1], [0.0, -0.2, 1.2]]";
    let p = profile(LINEAR, LINEAR, m);
    let mut o = RealismOptions::new(100.0);
    o.noise = NoiseModel::None;
    let r = Realism::new(&p, &o).expect("realism");
    let input = flat(4, 4, [0.2, 0.5, 0.1]);
    let dn = r.to_dn(&input, 1);
    // T·[0.2, 0.5, 0.1] = [0.27, 0.445, 0.02]; DN = round(64 + v·4031).
    let expect = [
        64.0 + (0.27f64 * 4031.0),
        64.0 + 0.445 * 4031.0,
        64.0 + 0.02 * 4031.0,
    ]
    .map(|v| v.round());
    for px in dn.pixels() {
        for c in 0..3 {
            assert_eq!(px[c] as f64, expect[c], "channel {c}");
        }
    }
    // Negative device values clamp to black, over-range clips at white.
    let dn = r.to_dn(&flat(2, 2, [0.0, 0.0, 1.0]), 1);
    assert_eq!(dn.get(0, 0), [64.0, 467.0, 4095.0]); // [−0.1, 0.1, 1.2] → [0, 64+403.1, clip]
    // Turning colour off: identity.
    o.colour = false;
    let r = Realism::new(&p, &o).expect("realism");
    assert_eq!(r.to_dn(&input, 1).get(0, 0), [870.0, 2080.0, 467.0]);
}

#[test]
fn filmic_source_and_srgb_device_response() {
    let p = profile(r#"{ kind = "filmic" }"#, r#"{ kind = "srgb" }"#, IDENTITY);
    let mut o = RealismOptions::new(100.0);
    o.noise = NoiseModel::None;
    let r = Realism::new(&p, &o).expect("realism");
    // Code 1.0 is the filmic curve's clipping point (x = 7.2416): it maps to the white level.
    assert_eq!(r.to_dn(&flat(1, 1, [1.0; 3]), 0).get(0, 0), [4095.0; 3]);
    // Code 0.5: sRGB decode → 0.214041; invert y = x(2.51x+0.03)/(x(2.43x+0.59)+0.14):
    // (2.51−2.43y)x² + (0.03−0.59y)x − 0.14y = 0 → x = 0.149271; saturation: 0.08x² − 0.56x
    // − 0.14 = 0 → x = 7.241657; 0.149271/7.241657 = 0.020613 → DN 64 + 83.09.
    let dn = r.to_dn(&flat(1, 1, [0.5; 3]), 0).get(0, 0)[0] as f64;
    assert!(
        (dn - (64.0f64 + 0.020613 * 4031.0).round()).abs() <= 1.0,
        "{dn}"
    );
    // Output: sRGB of (DN − 64)/4031, 8-bit.
    let ldr = r.apply(&flat(1, 1, [0.5; 3]), 0).get(0, 0)[0] as f64;
    let x = (dn - 64.0) / 4031.0;
    let srgb = 1.055 * x.powf(1.0 / 2.4) - 0.055;
    assert!(
        (ldr - (srgb * 255.0).round() / 255.0).abs() < 1e-6,
        "{ldr} vs {srgb}"
    );
}

#[test]
fn output_bits_do_not_depend_on_thread_count() {
    let p = profile(r#"{ kind = "filmic" }"#, r#"{ kind = "srgb" }"#, IDENTITY);
    let r = Realism::new(&p, &RealismOptions::new(400.0)).expect("realism");
    let input = Image::from_fn(97, 61, |x, y| [x as f32 / 97.0, y as f32 / 61.0, 0.5]);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .expect("pool");
    let a = one.install(|| r.apply(&input, 9));
    let b = three.install(|| r.apply(&input, 9));
    assert_eq!(a, b);
    assert_ne!(a, r.apply(&input, 10), "another seed must give other noise");
    // The fused path equals DN then response.
    assert_eq!(a, r.dn_to_ldr(&r.to_dn(&input, 9)));
}

#[test]
fn non_finite_inputs_cannot_escape_the_dn_range() {
    // Readers reject NaN/Inf, but frames built in code might carry them: the operator must
    // still produce in-range DN (NaN → black, +inf → white) for every source kind.
    for source in [LINEAR, r#"{ kind = "filmic" }"#] {
        let p = profile(source, LINEAR, IDENTITY);
        let r = Realism::new(&p, &RealismOptions::new(100.0)).expect("realism");
        let input = Image::from_vec(
            2,
            1,
            vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.5, -1.0, 2.0],
        );
        let dn = r.to_dn(&input, 3);
        assert!(
            dn.data.iter().all(|v| (0.0..=4095.0).contains(v)),
            "{source}: {:?}",
            dn.data
        );
        let ldr = r.apply(&input, 3);
        assert!(ldr.data.iter().all(|v| (0.0..=1.0).contains(v)));
    }
}

#[test]
fn an_output_floor_crushes_the_signal_under_it_and_keeps_white() {
    use hdrsynth::sensor::effects::EffectSpec;
    let mut p = profile(LINEAR, r#"{ kind = "srgb" }"#, IDENTITY);
    p.effects.push(EffectSpec {
        id: "floor".into(),
        params: toml::toml! { threshold = 0.01 },
    });
    let mut o = RealismOptions::new(100.0);
    o.noise = NoiseModel::None;
    o.colour = false;
    let r = Realism::new(&p, &o).expect("realism");
    // DN = round(64 + v·4031); the floor maps x = (DN − 64)/4031 to (x − 0.01)/0.99, then
    // IEC 61966-2-1's sRGB, 8 bits.
    let srgb = |x: f64| {
        if x <= 0.003_130_8 {
            12.92 * x
        } else {
            1.055 * x.powf(1.0 / 2.4) - 0.055
        }
    };
    for v in [0.0f64, 0.005, 0.0099, 0.02, 0.18, 0.5, 1.0] {
        let dn = (64.0 + v * 4031.0).round();
        let x = ((dn - 64.0) / 4031.0 - 0.01).max(0.0) / 0.99;
        let want = (srgb(x) * 255.0).round() / 255.0;
        let got = r.apply(&flat(2, 2, [v as f32; 3]), 1).get(0, 0);
        assert!(
            (got[0] as f64 - want).abs() < 1e-6,
            "{v}: {} for {want}",
            got[0]
        );
    }
    // Under the threshold: code 0; white stays white.
    assert_eq!(r.apply(&flat(1, 1, [0.0099; 3]), 1).get(0, 0), [0.0; 3]);
    assert_eq!(r.apply(&flat(1, 1, [1.0; 3]), 1).get(0, 0), [1.0; 3]);
    // A threshold out of range is refused, naming the effect and the parameter.
    p.effects[0].params = toml::toml! { threshold = 0.2 };
    let e = Realism::new(&p, &o).err().expect("refused").to_string();
    assert!(e.contains("floor") && e.contains("threshold"), "{e}");
}
