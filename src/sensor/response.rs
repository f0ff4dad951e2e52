//! Tone curves / response curves and their inverses: linear value → code value in [0, 1].
//!
//! The engine curve ("filmic") is what the procedural scene engine bakes into its display
//! frames, like a game engine's tonemapper: Narkowicz's 2015 fit of the ACES filmic RRT+ODT,
//!   f(x) = x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14),  clipped to [0, 1],
//! followed by the sRGB transfer function. It saturates at x = X_SAT ≈ 7.24 (scene-linear,
//! where 0.18 is mid grey), about 5.3 stops above mid grey.

use crate::io::{Image, srgb_decode, srgb_encode_fast};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ToneCurve {
    /// ACES filmic (Narkowicz fit) then sRGB encoding: the engine's display curve.
    #[default]
    Filmic,
    /// Clip to [0, 1] and sRGB-encode, no highlight roll-off.
    Srgb,
    /// Clip to [0, 1] only: code value = linear value.
    Linear,
}

const A: f32 = 2.51;
const B: f32 = 0.03;
const C: f32 = 2.43;
const D: f32 = 0.59;
const E: f32 = 0.14;

/// Scene-linear value where the filmic fit reaches 1: root of (A−C)x² + (B−D)x − E = 0.
pub fn filmic_saturation() -> f32 {
    let (qa, qb, qc) = (A - C, B - D, -E);
    (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa)
}

#[inline]
fn aces_fit(x: f32) -> f32 {
    let x = x.max(0.0);
    ((x * (A * x + B)) / (x * (C * x + D) + E)).min(1.0)
}

#[inline]
fn aces_fit_inv(y: f32) -> f32 {
    // Solve y(Cx² + Dx + E) = Ax² + Bx for x ≥ 0.
    let y = y.clamp(0.0, 1.0);
    let qa = A - y * C;
    let qb = B - y * D;
    let qc = -y * E;
    (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa)
}

impl ToneCurve {
    /// Linear value → code value in [0, 1].
    #[inline]
    pub fn apply(self, x: f32) -> f32 {
        match self {
            ToneCurve::Filmic => srgb_encode_fast(aces_fit(x)),
            ToneCurve::Srgb => srgb_encode_fast(x),
            ToneCurve::Linear => x.clamp(0.0, 1.0),
        }
    }

    /// Code value → linear value; exact inverse of `apply` below the clipping point.
    #[inline]
    pub fn invert(self, v: f32) -> f32 {
        let v = v.clamp(0.0, 1.0);
        match self {
            ToneCurve::Filmic => aces_fit_inv(srgb_decode(v)),
            ToneCurve::Srgb => srgb_decode(v),
            ToneCurve::Linear => v,
        }
    }

    /// Display frame of `radiance · gain` in one parallel pass (no intermediate image).
    pub fn display(self, radiance: &Image, gain: f32) -> Image {
        let mut out = Image::new(radiance.width, radiance.height);
        out.data
            .par_chunks_mut(4096)
            .zip(radiance.data.par_chunks(4096))
            .for_each(|(o, r)| {
                for (o, r) in o.iter_mut().zip(r) {
                    *o = self.apply(r * gain);
                }
            });
        out
    }

    /// Smallest linear value that maps to code value 1 (clips).
    pub fn saturation(self) -> f32 {
        match self {
            ToneCurve::Filmic => filmic_saturation(),
            ToneCurve::Srgb | ToneCurve::Linear => 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn filmic_hand_values() {
        // f(0.18) = 0.18(2.51·0.18+0.03)/(0.18(2.43·0.18+0.59)+0.14) = 0.086724/0.324932 = 0.266899
        let lin = 0.18f32 * (2.51 * 0.18 + 0.03) / (0.18 * (2.43 * 0.18 + 0.59) + 0.14);
        assert!((lin - 0.266_899).abs() < 1e-5);
        let srgb = 1.055 * 0.266_899f32.powf(1.0 / 2.4) - 0.055;
        assert!((ToneCurve::Filmic.apply(0.18) - srgb).abs() < 1e-5);
        // Saturation: 0.08x² − 0.56x − 0.14 = 0 → x = (0.56 + √0.3584)/0.16 = 7.2416
        assert!((filmic_saturation() - 7.241_64).abs() < 1e-3);
        assert!((ToneCurve::Filmic.apply(10.0) - 1.0).abs() < 1e-6);
    }
    #[test]
    fn inverse_round_trip() {
        for c in [ToneCurve::Filmic, ToneCurve::Srgb, ToneCurve::Linear] {
            for i in 1..100 {
                let x = c.saturation() * i as f32 / 100.0;
                let y = c.invert(c.apply(x));
                assert!((y - x).abs() <= 2e-4 * x.max(1e-2), "{c:?} {x} {y}");
            }
        }
    }
}
