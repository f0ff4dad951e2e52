//! Spatially correlated output noise in `calibrate brackets`: seen, told from scene texture, and
//! fitted as the catalogue's kernel.

use crate::helpers::{Spatial, calibrate_srgb, gauss_kernel, noisy_png_bracket, noisy_png_scene};
use hdrsynth::capture::scan::ScanOptions;
use hdrsynth::sensor::profile::SensorProfile;

#[test]
fn calibrate_brackets_sees_spatially_correlated_output_noise() {
    let tmp = tempfile::tempdir().expect("tmp");
    noisy_png_bracket(
        &tmp.path().join("scene"),
        4e-4,
        1e-5,
        &[-2.0, 0.0, 2.0],
        Spatial::Box2,
    );
    let beside = tempfile::tempdir().expect("tmp");
    let out = beside.path().join("phone.toml");
    let cal = calibrate_srgb(tmp.path(), ScanOptions::default(), &out, false);
    eprintln!("{}", cal.report(&out));
    // 2×2-box noise: neighbours share half their draws. Immerkær's second differences cancel
    // much of it; the pixel − 3×3-mean residual far less, so the ratio rises well above 1.
    for r in cal.correlation_ratio {
        assert!(r > 1.5, "{:?}", cal.correlation_ratio);
    }
    // A 2×2 box's lag-1 correlation is exactly 0.5 (two of four draws shared); the fitted
    // Gaussian kernel, another shape, still matches it.
    assert!(
        (cal.correlation.rho - 0.5).abs() < 0.04,
        "{:?}",
        cal.correlation
    );
}

/// Fine scene texture survives in a single frame's flattest pixels and raises the low-order
/// residual over Immerkær's as correlated noise does; measured on each frame's residual against
/// the other frames' merge, the scene cancels: white noise reads white and correlated noise its
/// own correlation, with or without the texture.
#[test]
fn scene_texture_is_not_read_as_correlated_noise() {
    let calibrate = |spatial: Spatial, texture: f64| {
        let tmp = tempfile::tempdir().expect("tmp");
        let stops = [-2.0, -1.0, 0.0, 1.0, 2.0];
        noisy_png_scene(
            &tmp.path().join("scene"),
            4e-4,
            1e-5,
            &stops,
            spatial,
            texture,
        );
        let beside = tempfile::tempdir().expect("tmp");
        let out = beside.path().join("phone.toml");
        let cal = calibrate_srgb(tmp.path(), ScanOptions::default(), &out, true);
        eprintln!("{}", cal.report(&out));
        assert_eq!(cal.cross_frames, stops.len());
        cal
    };
    for texture in [0.0, 0.15] {
        let white = calibrate(Spatial::White, texture);
        assert!(
            white.correlation.rho < 0.02 && white.profile.effects.is_empty(),
            "texture {texture}: {:?} {:?}",
            white.correlation,
            white.profile.effects
        );
        assert!(
            white.channel_correlation.abs() < 0.05,
            "texture {texture}: channel correlation {}",
            white.channel_correlation
        );
        // A 2×2 box's lag-1 correlation is exactly 0.5 (two of four draws shared).
        let boxed = calibrate(Spatial::Box2, texture);
        assert!(
            (boxed.correlation.rho - 0.5).abs() < 0.05,
            "texture {texture}: {:?}",
            boxed.correlation
        );
        // Chroma noise of ρ = 0.6 between every two channels.
        let chroma = calibrate(Spatial::Channel(0.6), texture);
        assert!(
            (chroma.channel_correlation - 0.6).abs() < 0.06,
            "texture {texture}: channel correlation {}",
            chroma.channel_correlation
        );
    }
}

#[test]
fn correlated_output_noise_is_fitted_as_the_catalogues_kernel_with_its_per_pixel_variance() {
    let (a, b) = (4e-4, 1e-5);
    let calibrate = |spatial: Spatial| {
        let tmp = tempfile::tempdir().expect("tmp");
        noisy_png_bracket(&tmp.path().join("scene"), a, b, &[-2.0, 0.0, 2.0], spatial);
        let beside = tempfile::tempdir().expect("tmp");
        let out = beside.path().join("phone.toml");
        let cal = calibrate_srgb(tmp.path(), ScanOptions::default(), &out, true);
        eprintln!("{}", cal.report(&out));
        let written = SensorProfile::load(&out).expect("load");
        assert_eq!(written, cal.profile);
        cal
    };
    // Gaussian-filtered noise of width 0.8: its lag-1 correlation Σ k(i) k(i+1), from the
    // test's own kernel.
    let sigma = 0.8;
    let k = gauss_kernel(sigma);
    let rho_true: f64 = (0..k.len() - 1).map(|i| k[i] * k[i + 1]).sum();
    let cal = calibrate(Spatial::Gauss(sigma));
    let effect = cal
        .profile
        .effects
        .iter()
        .find(|e| e.id == "correlated_noise")
        .expect("the correlation is written as an effect");
    let rho = effect.params["rho"].as_float().expect("rho");
    assert!(
        (rho - rho_true).abs() < 0.04,
        "fitted lag-1 correlation {rho}, true {rho_true:.3}"
    );
    // The provenance reads as one sentence per measurement: a string continued across source
    // lines without its `\` would carry the next line's indentation as a run of spaces.
    let prov = &cal.profile.provenance;
    for text in [&prov.noise, &prov.response, &prov.colour, &prov.levels] {
        assert!(
            text.contains("bracket folder")
                || text.contains("output domain")
                || text.contains("identity"),
            "{text}"
        );
        assert!(!text.contains("  ") && !text.contains('\n'), "{text:?}");
    }
    assert!(
        prov.noise.contains("spatially correlated as measured"),
        "{}",
        prov.noise
    );
    // a is the per-pixel variance's again, not the fraction Immerkær's residual sees.
    for c in 0..3 {
        let got = cal.profile.noise[0].a[c];
        assert!((got / a - 1.0).abs() < 0.15, "a[{c}] = {got:e}, true {a:e}");
    }
    // White noise: no effect is written and a stays the white estimate.
    let white = calibrate(Spatial::White);
    assert!(
        white.correlation.rho < 0.02 && white.profile.effects.is_empty(),
        "{:?} {:?}",
        white.correlation,
        white.profile.effects
    );
}
