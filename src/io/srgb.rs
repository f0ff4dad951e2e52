//! sRGB transfer function (IEC 61966-2-1), encode linear → code value and decode back.

#[inline]
pub fn srgb_encode(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

#[inline]
pub fn srgb_decode(v: f32) -> f32 {
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
        assert!((srgb_encode(0.18) - 0.461_356_1).abs() < 1e-6);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        for i in 0..=100 {
            let x = i as f32 / 100.0;
            assert!((srgb_decode(srgb_encode(x)) - x).abs() < 1e-6);
        }
    }
}
