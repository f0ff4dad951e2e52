//! Colour maths as colour-science computes it: linear sRGB ↔ XYZ (D65), Bradford chromatic
//! adaptation, CIE 1976 L*a*b* (D50, and D65 for display values) and CIEDE2000. Conventions:
//! the module docs of `colour`.

use crate::linalg::{Mat3, inverse3, mat_vec, mul3};

/// colour-science's sRGB RGB → XYZ matrix (`RGB_COLOURSPACES['sRGB'].matrix_RGB_to_XYZ`).
pub const SRGB_TO_XYZ: Mat3 = [
    [0.4124, 0.3576, 0.1805],
    [0.2126, 0.7152, 0.0722],
    [0.0193, 0.1192, 0.9505],
];

/// The Bradford cone-response matrix (colour-science `CHROMATIC_ADAPTATION_TRANSFORMS`).
pub const BRADFORD: Mat3 = [
    [0.8951, 0.2664, -0.1614],
    [-0.7502, 1.7135, 0.0367],
    [0.0389, -0.0685, 1.0296],
];

/// CIE 1931 2° chromaticities of the whites used here.
pub const D65_XY: [f64; 2] = [0.3127, 0.329];
/// The ColorChecker dataset's D50 (ICC PCS white, XYZ 0.9642, 1, 0.8249).
pub const D50_XY: [f64; 2] = [0.345702914918791, 0.358538596679933];
pub const A_XY: [f64; 2] = [0.44758, 0.40745];

/// XYZ (Y = 1) of a chromaticity.
pub fn xy_to_xyz(xy: [f64; 2]) -> [f64; 3] {
    [xy[0] / xy[1], 1.0, (1.0 - xy[0] - xy[1]) / xy[1]]
}

/// von Kries chromatic adaptation matrix with the Bradford cone space, from white `src` to white
/// `dst` (XYZ), built as colour-science's `matrix_chromatic_adaptation_VonKries` builds it.
/// None when a cone response of `src` is (near) 0: no adaptation from that white.
pub fn bradford(src: [f64; 3], dst: [f64; 3]) -> Option<Mat3> {
    let w = mat_vec(&BRADFORD, src);
    let wr = mat_vec(&BRADFORD, dst);
    if w.iter().any(|v| v.abs() < 1e-12) {
        return None;
    }
    let d: Mat3 = [
        [wr[0] / w[0], 0.0, 0.0],
        [0.0, wr[1] / w[1], 0.0],
        [0.0, 0.0, wr[2] / w[2]],
    ];
    let inv = inverse3(&BRADFORD).expect("Bradford matrix is invertible");
    Some(mul3(&mul3(&inv, &d), &BRADFORD))
}

/// Bradford D65 → the ColorChecker D50.
fn d65_to_d50() -> Mat3 {
    bradford(xy_to_xyz(D65_XY), xy_to_xyz(D50_XY)).expect("D65 has non-zero cone responses")
}

/// Linear sRGB → XYZ (D65, Y of the sRGB white = 1).
pub fn linear_srgb_to_xyz(rgb: [f64; 3]) -> [f64; 3] {
    mat_vec(&SRGB_TO_XYZ, rgb)
}

/// XYZ → linear sRGB (exact inverse of [`SRGB_TO_XYZ`]).
pub fn xyz_to_linear_srgb(xyz: [f64; 3]) -> [f64; 3] {
    let inv = inverse3(&SRGB_TO_XYZ).expect("sRGB matrix is invertible");
    mat_vec(&inv, xyz)
}

/// Bradford D65 → D50 (the ColorChecker D50, [`D50_XY`]).
pub fn xyz_d65_to_d50(xyz: [f64; 3]) -> [f64; 3] {
    mat_vec(&d65_to_d50(), xyz)
}

/// CIE 1976 L*a*b* of `xyz` relative to the white `white` (XYZ), as colour-science's
/// `XYZ_to_Lab` (L in 0..100).
pub fn xyz_to_lab(xyz: [f64; 3], white: [f64; 3]) -> [f64; 3] {
    let f = |t: f64| {
        if t > (24.0f64 / 116.0).powi(3) {
            t.cbrt()
        } else {
            (841.0 / 108.0) * t + 16.0 / 116.0
        }
    };
    let (fx, fy, fz) = (
        f(xyz[0] / white[0]),
        f(xyz[1] / white[1]),
        f(xyz[2] / white[2]),
    );
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// XYZ of the sRGB white, RGB (1, 1, 1) through [`SRGB_TO_XYZ`]: (0.9505, 1, 1.089).
pub fn srgb_white() -> [f64; 3] {
    linear_srgb_to_xyz([1.0; 3])
}

/// CIELAB of a display value read as sRGB-encoded RGB (IEC 61966-2-1 decoding, Rec. 709
/// primaries, D65): decode, [`SRGB_TO_XYZ`], Lab relative to [`srgb_white`] (so display greys
/// have a* = b* = 0). Values outside [0, 1] go through the same formulas, unclipped.
pub fn display_srgb_to_lab(rgb: [f64; 3]) -> [f64; 3] {
    let linear = rgb.map(crate::io::srgb_decode_f64);
    xyz_to_lab(linear_srgb_to_xyz(linear), srgb_white())
}

/// Lab (D50) of a colour treated as linear sRGB (D65): sRGB → XYZ D65 → Bradford → Lab D50.
pub fn linear_srgb_to_lab_d50(rgb: [f64; 3]) -> [f64; 3] {
    let m = mul3(&d65_to_d50(), &SRGB_TO_XYZ);
    xyz_to_lab(mat_vec(&m, rgb), xy_to_xyz(D50_XY))
}

/// CIEDE2000 colour difference (Sharma, Wu and Dalal 2005; k_L = k_C = k_H = 1), the same
/// formulation and edge cases (zero chroma, hue wrap-around) as colour-science's
/// `delta_E_CIE2000`.
pub fn delta_e_2000(lab1: [f64; 3], lab2: [f64; 3]) -> f64 {
    let [l1, a1, b1] = lab1;
    let [l2, a2, b2] = lab2;
    let c1 = a1.hypot(b1);
    let c2 = a2.hypot(b2);
    let c_bar7 = ((c1 + c2) / 2.0).powi(7);
    let p25_7 = 25.0f64.powi(7);
    let g = 0.5 * (1.0 - (c_bar7 / (c_bar7 + p25_7)).sqrt());
    let ap1 = (1.0 + g) * a1;
    let ap2 = (1.0 + g) * a2;
    let cp1 = ap1.hypot(b1);
    let cp2 = ap2.hypot(b2);
    let hue = |b: f64, ap: f64| {
        if b == 0.0 && ap == 0.0 {
            0.0
        } else {
            b.atan2(ap).to_degrees().rem_euclid(360.0)
        }
    };
    let hp1 = hue(b1, ap1);
    let hp2 = hue(b2, ap2);
    let dl = l2 - l1;
    let dc = cp2 - cp1;
    let dh_raw = hp2 - hp1;
    let cc = cp1 * cp2;
    let dh = if cc == 0.0 {
        0.0
    } else if dh_raw.abs() <= 180.0 {
        dh_raw
    } else if dh_raw > 180.0 {
        dh_raw - 360.0
    } else {
        dh_raw + 360.0
    };
    let d_big_h = 2.0 * cc.sqrt() * (dh / 2.0).to_radians().sin();
    let l_bar = (l1 + l2) / 2.0;
    let c_bar_p = (cp1 + cp2) / 2.0;
    let abs_diff = (hp1 - hp2).abs();
    let sum = hp1 + hp2;
    let h_bar = if cc == 0.0 {
        sum
    } else if abs_diff <= 180.0 {
        sum / 2.0
    } else if sum < 360.0 {
        (sum + 360.0) / 2.0
    } else {
        (sum - 360.0) / 2.0
    };
    let t = 1.0 - 0.17 * (h_bar - 30.0).to_radians().cos()
        + 0.24 * (2.0 * h_bar).to_radians().cos()
        + 0.32 * (3.0 * h_bar + 6.0).to_radians().cos()
        - 0.20 * (4.0 * h_bar - 63.0).to_radians().cos();
    let d_theta = 30.0 * (-((h_bar - 275.0) / 25.0).powi(2)).exp();
    let c_bar_p7 = c_bar_p.powi(7);
    let r_c = 2.0 * (c_bar_p7 / (c_bar_p7 + p25_7)).sqrt();
    let l50 = (l_bar - 50.0).powi(2);
    let s_l = 1.0 + 0.015 * l50 / (20.0 + l50).sqrt();
    let s_c = 1.0 + 0.045 * c_bar_p;
    let s_h = 1.0 + 0.015 * c_bar_p * t;
    let r_t = -(2.0 * d_theta).to_radians().sin() * r_c;
    let (ql, qc, qh) = (dl / s_l, dc / s_c, d_big_h / s_h);
    (ql * ql + qc * qc + qh * qh + r_t * qc * qh).sqrt()
}

/// ΔE00 between two colours both treated as linear sRGB (D65), compared in Lab D50.
pub fn delta_e_linear_srgb(a: [f64; 3], b: [f64; 3]) -> f64 {
    delta_e_2000(linear_srgb_to_lab_d50(a), linear_srgb_to_lab_d50(b))
}
