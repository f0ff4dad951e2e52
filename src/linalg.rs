//! Small dense linear algebra: 3×3 colour transforms (colour, EXR, test sets) and the 6×6
//! normal equations of the flat-field surface (sensor/effects/summary.rs).

// --- 3×3 (colour transforms, chromaticities) -------------------------------------------------

pub type Mat3 = [[f64; 3]; 3];

/// 3×3 matrix product.
pub fn mul3(a: &Mat3, b: &Mat3) -> Mat3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// 3×3 determinant.
pub fn det3(m: &Mat3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// 3×3 inverse by cofactors; None when the determinant is not finite or below 1e-15.
pub fn inverse3(m: &Mat3) -> Option<Mat3> {
    let det = det3(m);
    if !det.is_finite() || det.abs() < 1e-15 {
        return None;
    }
    let c =
        |r0: usize, r1: usize, c0: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    Some([
        [
            c(1, 2, 1, 2) / det,
            -c(0, 2, 1, 2) / det,
            c(0, 1, 1, 2) / det,
        ],
        [
            -c(1, 2, 0, 2) / det,
            c(0, 2, 0, 2) / det,
            -c(0, 1, 0, 2) / det,
        ],
        [
            c(1, 2, 0, 1) / det,
            -c(0, 2, 0, 1) / det,
            c(0, 1, 0, 1) / det,
        ],
    ])
}

pub fn mat_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

/// Inverse of a 3×3 matrix; None when singular.
pub fn mat_inv(m: &Mat3) -> Option<Mat3> {
    let c =
        |r0: usize, r1: usize, c0: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    let cof = [
        [c(1, 2, 1, 2), -c(1, 2, 0, 2), c(1, 2, 0, 1)],
        [-c(0, 2, 1, 2), c(0, 2, 0, 2), -c(0, 2, 0, 1)],
        [c(0, 1, 1, 2), -c(0, 1, 0, 2), c(0, 1, 0, 1)],
    ];
    let det = m[0][0] * cof[0][0] + m[0][1] * cof[0][1] + m[0][2] * cof[0][2];
    let scale = m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    if !det.is_finite() || det.abs() <= 1e-300 || det.abs() <= 1e-14 * scale.powi(3) {
        return None;
    }
    // Inverse = adjugate / det; the adjugate is the transposed cofactor matrix.
    Some(std::array::from_fn(|i| {
        std::array::from_fn(|j| cof[j][i] / det)
    }))
}

/// m · x = v by Cramer's rule; None when the determinant is not finite or below 1e-15.
pub fn solve3(m: Mat3, v: [f64; 3]) -> Option<[f64; 3]> {
    let d = det3(&m);
    if d.abs() < 1e-15 || !d.is_finite() {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut mk = m;
        for row in 0..3 {
            mk[row][k] = v[row];
        }
        *o = det3(&mk) / d;
    }
    Some(out)
}

// --- 6×6 (the flat-field surface's normal equations) -------------------------------------------

/// Gaussian elimination with partial pivoting (6×6 normal equations); a zero pivot
/// gives 0 for its unknown.
#[allow(clippy::needless_range_loop)]
pub fn solve6(mut a: [[f64; 6]; 6], mut b: [f64; 6]) -> [f64; 6] {
    for i in 0..6 {
        let p = (i..6)
            .max_by(|&r, &s| a[r][i].abs().total_cmp(&a[s][i].abs()))
            .unwrap_or(i);
        a.swap(i, p);
        b.swap(i, p);
        if a[i][i].abs() < 1e-300 {
            continue;
        }
        for r in i + 1..6 {
            let f = a[r][i] / a[i][i];
            for k in i..6 {
                a[r][k] -= f * a[i][k];
            }
            b[r] -= f * b[i];
        }
    }
    let mut x = [0.0; 6];
    for i in (0..6).rev() {
        let s: f64 = (i + 1..6).map(|k| a[i][k] * x[k]).sum();
        x[i] = if a[i][i].abs() < 1e-300 {
            0.0
        } else {
            (b[i] - s) / a[i][i]
        };
    }
    x
}
