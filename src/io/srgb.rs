//! sRGB transfer function (IEC 61966-2-1), encode linear → code value and decode back.

#[inline]
pub fn srgb_encode(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

const LUT_N: usize = 1 << 16;
static ENCODE_LUT: std::sync::LazyLock<Vec<f32>> = std::sync::LazyLock::new(|| {
    (0..=LUT_N + 1)
        .map(|i| srgb_encode((i as f64 / LUT_N as f64).min(1.0) as f32))
        .collect()
});

/// `srgb_encode` on [0, 1] by table with linear interpolation (max error < 1e-6, far below a
/// 16-bit code step of 1.5e-5), for the hot path of tone-mapping whole frames. Input clamped.
#[inline]
pub fn srgb_encode_fast(x: f32) -> f32 {
    let t = x.clamp(0.0, 1.0) * LUT_N as f32;
    let i = t as usize;
    let f = t - i as f32;
    let lut = &*ENCODE_LUT;
    lut[i] + (lut[i + 1] - lut[i]) * f
}

#[inline]
pub fn srgb_decode(v: f32) -> f32 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// [`srgb_decode`] in f64, for metrics that must agree with colour-science to 1e-6 (the f32
/// version serves whole-frame paths). No clipping: codes outside [0, 1] follow the same two
/// pieces, as colour-science's `eotf_sRGB` does.
#[inline]
pub fn srgb_decode_f64(v: f64) -> f64 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn known_values() {
        // IEC 61966-2-1: 0.5 code value ↔ 0.214041 linear; 0.18 linear ↔ 0.461356
        assert!((srgb_decode(0.5) - 0.214_041_14).abs() < 1e-6);
        // ((0.5 + 0.055) / 1.055)^2.4 and 0.02 / 12.92 by hand.
        assert!((srgb_decode_f64(0.5) - 0.214_041_140_482_232_5).abs() < 1e-15);
        assert!((srgb_decode_f64(0.02) - 0.02 / 12.92).abs() < 1e-18);
        assert!((srgb_encode(0.18) - 0.461_356_1).abs() < 1e-6);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        for i in 0..=100_000 {
            let x = i as f32 / 100_000.0;
            assert!((srgb_encode_fast(x) - srgb_encode(x)).abs() < 1e-6, "{x}");
        }
        for i in 0..=100 {
            let x = i as f32 / 100.0;
            assert!((srgb_decode(srgb_encode(x)) - x).abs() < 1e-6);
        }
    }
}
