//! Colour maths as colour-science computes it: linear sRGB ↔ XYZ (D65), Bradford chromatic
//! adaptation, CIE 1976 L*a*b* (D50, and D65 for display values), CIEDE2000 and the correlated
//! colour temperature of a chromaticity (Robertson 1968). Conventions: the module docs of
//! `colour`.

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

/// Chromaticity xy of XYZ; None when X + Y + Z is not positive (no chromaticity).
pub fn xyz_to_xy(xyz: [f64; 3]) -> Option<[f64; 2]> {
    let s = xyz[0] + xyz[1] + xyz[2];
    (s > 0.0 && s.is_finite()).then(|| [xyz[0] / s, xyz[1] / s])
}

/// Robertson's isotemperature lines (Wyszecki & Stiles, Table 1(3.11)): reciprocal
/// megakelvin, CIE 1960 u, v, slope. The 325-mired u is 0.24792 (Lindbloom's correction, as
/// colour-science has it; the DNG SDK's copy reads 0.24702).
const ROBERTSON: [[f64; 4]; 31] = [
    [0.0, 0.18006, 0.26352, -0.24341],
    [10.0, 0.18066, 0.26589, -0.25479],
    [20.0, 0.18133, 0.26846, -0.26876],
    [30.0, 0.18208, 0.27119, -0.28539],
    [40.0, 0.18293, 0.27407, -0.30470],
    [50.0, 0.18388, 0.27709, -0.32675],
    [60.0, 0.18494, 0.28021, -0.35156],
    [70.0, 0.18611, 0.28342, -0.37915],
    [80.0, 0.18740, 0.28668, -0.40955],
    [90.0, 0.18880, 0.28997, -0.44278],
    [100.0, 0.19032, 0.29326, -0.47888],
    [125.0, 0.19462, 0.30141, -0.58204],
    [150.0, 0.19962, 0.30921, -0.70471],
    [175.0, 0.20525, 0.31647, -0.84901],
    [200.0, 0.21142, 0.32312, -1.0182],
    [225.0, 0.21807, 0.32909, -1.2168],
    [250.0, 0.22511, 0.33439, -1.4512],
    [275.0, 0.23247, 0.33904, -1.7298],
    [300.0, 0.24010, 0.34308, -2.0637],
    [325.0, 0.24792, 0.34655, -2.4681],
    [350.0, 0.25591, 0.34951, -2.9641],
    [375.0, 0.26400, 0.35200, -3.5814],
    [400.0, 0.27218, 0.35407, -4.3633],
    [425.0, 0.28039, 0.35577, -5.3762],
    [450.0, 0.28863, 0.35714, -6.7262],
    [475.0, 0.29685, 0.35823, -8.5955],
    [500.0, 0.30505, 0.35907, -11.324],
    [525.0, 0.31320, 0.35968, -15.628],
    [550.0, 0.32129, 0.36011, -23.325],
    [575.0, 0.32931, 0.36038, -40.770],
    [600.0, 0.33724, 0.36051, -116.45],
];

/// Correlated colour temperature (K) of a chromaticity by Robertson's method (1968): the signed
/// distance to each isotemperature line in CIE 1960 uv, interpolated in reciprocal temperature
/// between the two lines either side, as colour-science's `uv_to_CCT_Robertson1968` and the
/// DNG SDK compute it. Beyond the table the result is its end: 100 000 K or 1667 K.
pub fn xy_to_cct(xy: [f64; 2]) -> f64 {
    let d = 1.5 - xy[0] + 6.0 * xy[1];
    let (u, v) = (2.0 * xy[0] / d, 3.0 * xy[1] / d);
    let (mut last_dt, mut k) = (0.0, ROBERTSON.len() - 1);
    let mut dt_k = 0.0;
    for (i, line) in ROBERTSON.iter().enumerate().skip(1) {
        let len = (1.0 + line[3] * line[3]).sqrt();
        // Distance from the line, positive on the high-temperature side.
        let dt = -(u - line[1]) * (line[3] / len) + (v - line[2]) / len;
        if dt <= 0.0 || i == ROBERTSON.len() - 1 {
            (k, dt_k) = (i, (-dt).max(0.0));
            break;
        }
        last_dt = dt;
    }
    let f = if k == 1 { 0.0 } else { dt_k / (last_dt + dt_k) };
    1.0e6 / (ROBERTSON[k - 1][0] * f + ROBERTSON[k][0] * (1.0 - f))
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
