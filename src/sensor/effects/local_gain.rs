//! `local_gain`: the frames of a set disagree with each other slowly over the frame, as a tone
//! curve that varies over the frame and is set anew for each frame (local tone mapping, a
//! scene-adaptive ISP) leaves them. Each frame's signal above black is multiplied by
//! exp(g(x, y)), g a smooth stationary random field of standard deviation `sigma` (ln gain)
//! and correlation length `scale` pixels, drawn anew for every frame from the frame's seed.
//! Applied after the noise and the DN quantisation, before the output response (an ISP acts on
//! the sensor's noisy signal); the ground truth carries none.
//!
//! The field is phenomenological: it reproduces how much the frames of a static scene disagree
//! at coarse scales (the device-output check's disagreement statistics,
//! src/capture/output/consistency.rs) — what a network reads as motion — not any one tone
//! mapper's dependence on content. g = σ·√(2/K)·Σₖ cos(uₖx + vₖy + φₖ) over K plane waves,
//! (uₖ, vₖ) normal with standard deviation 1/scale each and φₖ uniform: over the draws, unit
//! variance and covariance σ²·exp(−r²/(2·scale²)).
//!
//! Raw bursts cannot show it. Its fit is the device-output check's on a bracket folder
//! (src/capture/output/local_gain.rs).

use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, hashed_normal, hashed_unit};
use super::{not_fitted, table};
use crate::error::Result;
use crate::io::Image;

pub const ID: &str = id::LOCAL_GAIN;

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "a smooth gain field over each frame, drawn anew per frame (the disagreement local \
            tone mapping leaves between frames)",
    needs: "a bracket folder (the device-output check: `diagnose --brackets --device-output`, \
            `hdrsynth loop`)",
    statistics,
    fit,
    adjust: None,
};

/// Plane waves summed: enough for a field whose values are close to normal.
const WAVES: usize = 32;

/// Raw bursts hold no statistic of an output-domain effect.
fn statistics(_: &Protocol, _: &[Summary], _: &mut Vec<Stat>) {}

fn fit(_: &FitCtx) -> Result<toml::Table> {
    Err(not_fitted(
        ID,
        "an output-domain effect: fitted from a bracket folder by the device-output check",
    ))
}

/// The effect's table.
pub fn params(sigma: f64, scale: f64) -> toml::Table {
    table(&[("sigma", float(sigma)), ("scale", float(scale))])
}

/// The field g (ln gain) of a w×h frame, row-major, for the frame seed `seed`.
pub fn field(w: usize, h: usize, sigma: f32, scale: f32, seed: u64) -> Vec<f32> {
    let amp = sigma * (2.0 / WAVES as f32).sqrt();
    let mut g = vec![0.0f32; w * h];
    for k in 0..WAVES as u64 {
        let u = hashed_normal(seed, &[k, 0]) / scale;
        let v = hashed_normal(seed, &[k, 1]) / scale;
        let phi = std::f32::consts::TAU * hashed_unit(seed, &[k, 2]);
        // cos(ux + vy + φ) = cos(ux)·cos(vy + φ) − sin(ux)·sin(vy + φ): one table per axis.
        let (sx, cx): (Vec<f32>, Vec<f32>) = (0..w).map(|x| (u * x as f32).sin_cos()).unzip();
        for (y, row) in g.chunks_exact_mut(w).enumerate() {
            let (sy, cy) = (v * y as f32 + phi).sin_cos();
            for ((o, s), c) in row.iter_mut().zip(&sx).zip(&cx) {
                *o += amp * (c * cy - s * sy);
            }
        }
    }
    g
}

/// `dn` (a frame in DN over `black`) with its signal above black scaled by the field's gain.
pub fn apply_dn(dn: &mut Image, black: f32, sigma: f32, scale: f32, seed: u64) {
    let g = field(dn.width, dn.height, sigma, scale, seed);
    for (px, g) in dn.data.chunks_exact_mut(3).zip(g) {
        let gain = g.exp();
        for v in px {
            *v = black + (*v - black) * gain;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Over a frame much larger than its scale, the field has the standard deviation asked
    /// for, neighbours `scale` apart correlate by about exp(−½) (the Gaussian covariance), and
    /// two seeds give two fields.
    #[test]
    fn the_field_has_its_sigma_and_its_scale() {
        let (w, h, scale) = (512, 512, 8.0);
        let (mut var, mut cov, mut n) = (0.0f64, 0.0f64, 0.0f64);
        let mut mean = 0.0f64;
        for seed in 0..8u64 {
            let g = field(w, h, 0.1, scale, seed);
            mean += g.iter().map(|&v| f64::from(v)).sum::<f64>() / (w * h) as f64 / 8.0;
            for y in 0..h {
                for x in 0..w - 8 {
                    let (a, b) = (f64::from(g[y * w + x]), f64::from(g[y * w + x + 8]));
                    var += a * a;
                    cov += a * b;
                    n += 1.0;
                }
            }
        }
        let sd = (var / n).sqrt();
        assert!((sd - 0.1).abs() < 0.02, "sd {sd}");
        assert!(mean.abs() < 0.02, "mean {mean}");
        let rho = cov / var;
        assert!(
            (rho - (-0.5f64).exp()).abs() < 0.15,
            "lag-scale correlation {rho}"
        );
        assert_ne!(field(16, 16, 0.1, 4.0, 1), field(16, 16, 0.1, 4.0, 2));
    }

    /// Black stays black; the signal above it is scaled by exp(g), the same in every channel.
    #[test]
    fn the_gain_scales_the_signal_above_black_alike_in_every_channel() {
        let mut dn = Image::from_fn(32, 32, |_, _| [100.0, 228.0, 612.0]);
        apply_dn(&mut dn, 100.0, 0.2, 4.0, 7);
        let g = field(32, 32, 0.2, 4.0, 7);
        for (px, g) in dn.data.chunks_exact(3).zip(g) {
            assert_eq!(px[0], 100.0);
            let gain = g.exp();
            assert!((px[1] - (100.0 + 128.0 * gain)).abs() < 1e-3);
            assert!((px[2] - (100.0 + 512.0 * gain)).abs() < 1e-3);
        }
    }
}
