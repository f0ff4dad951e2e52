//! Small dense linear algebra: 3×3 colour transforms (colour, EXR, test sets), least squares by
//! Householder QR (colour fits, the Debevec–Malik response) and the 6×6 normal equations of the
//! flat-field surface (sensor/effects/summary.rs).

use crate::error::{Error, Result};

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

/// The determinant of `m`, or None when `m` is singular for every 3×3 solve here: the
/// determinant is not finite, 0, or tiny for the matrix's scale (|det| ≤ 1e-14 · max|m|³, so
/// the test means the same at any unit).
fn regular_det(m: &Mat3) -> Option<f64> {
    let det = det3(m);
    let scale = m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    if !det.is_finite() || det.abs() <= 1e-300 || det.abs() <= 1e-14 * scale.powi(3) {
        return None;
    }
    Some(det)
}

/// 3×3 inverse by cofactors; None when `m` is singular ([`regular_det`]).
pub fn inverse3(m: &Mat3) -> Option<Mat3> {
    let det = regular_det(m)?;
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

/// m · x = v by Cramer's rule; None when `m` is singular by [`inverse3`]'s rule.
pub fn solve3(m: Mat3, v: [f64; 3]) -> Option<[f64; 3]> {
    let d = regular_det(&m)?;
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

// --- Least squares (colour fits, the Debevec–Malik response) ----------------------------------

/// Least squares: the k×M X minimising ‖A·X − B‖ (A n×k, rows `a`), by Householder QR. This is
/// the solution colour-science's Moore–Penrose mapping (and OpenCV's `solve(DECOMP_SVD)`) gives
/// when A has full column rank; a rank-deficient A (rows that do not span the unknowns) is an
/// error, not a minimum-norm guess. `what` names the fit in errors. Also the solver of the
/// Debevec–Malik response (src/sensor/crf.rs).
#[allow(clippy::needless_range_loop)]
pub fn least_squares<const M: usize>(
    what: &str,
    a: &[Vec<f64>],
    b: &[[f64; M]],
) -> Result<Vec<[f64; M]>> {
    let n = a.len();
    let k = a.first().map_or(0, |r| r.len());
    if n != b.len() {
        return Err(Error::Invalid(format!(
            "{what}: {n} rows of A but {} of B",
            b.len()
        )));
    }
    if k == 0 || n < k {
        return Err(Error::Invalid(format!(
            "{what}: {n} equations cannot determine {k} unknowns"
        )));
    }
    if a.iter()
        .flatten()
        .chain(b.iter().flatten())
        .any(|v| !v.is_finite())
    {
        return Err(Error::Invalid(format!("{what}: non-finite values")));
    }
    // Column-major copy of A and a copy of B we transform in place.
    let mut q: Vec<Vec<f64>> = (0..k).map(|j| a.iter().map(|r| r[j]).collect()).collect();
    let mut rhs: Vec<[f64; M]> = b.to_vec();
    let scale = q.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut diag = vec![0.0; k];
    for j in 0..k {
        let norm = q[j][j..].iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm <= 1e-12 * scale * (n as f64).sqrt() || norm == 0.0 {
            return Err(Error::Invalid(format!(
                "{what}: the data do not determine unknown {} (rank-deficient design)",
                j + 1
            )));
        }
        let alpha = if q[j][j] > 0.0 { -norm } else { norm };
        // v = x − alpha·e1, stored in q[j][j..].
        q[j][j] -= alpha;
        let vnorm2: f64 = q[j][j..].iter().map(|v| v * v).sum();
        diag[j] = alpha;
        let v: Vec<f64> = q[j][j..].to_vec();
        for c in j + 1..k {
            let dot: f64 = v.iter().zip(&q[c][j..]).map(|(x, y)| x * y).sum();
            let f = 2.0 * dot / vnorm2;
            for (i, vi) in v.iter().enumerate() {
                q[c][j + i] -= f * vi;
            }
        }
        for ch in 0..M {
            let dot: f64 = v
                .iter()
                .enumerate()
                .map(|(i, vi)| vi * rhs[j + i][ch])
                .sum();
            let f = 2.0 * dot / vnorm2;
            for (i, vi) in v.iter().enumerate() {
                rhs[j + i][ch] -= f * vi;
            }
        }
    }
    // Back substitution with R (upper triangle in q above the diagonal, diagonal in diag).
    let mut x = vec![[0.0; M]; k];
    for j in (0..k).rev() {
        for ch in 0..M {
            let mut s = rhs[j][ch];
            for c in j + 1..k {
                s -= q[c][j] * x[c][ch];
            }
            x[j][ch] = s / diag[j];
        }
    }
    Ok(x)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse3_judges_singularity_relative_to_the_matrix_scale() {
        // A well-conditioned matrix in small units (det 1e-18) is invertible …
        let small: Mat3 = [[1e-6, 0.0, 0.0], [0.0, 2e-6, 0.0], [0.0, 0.0, 5e-7]];
        let inv = inverse3(&small).unwrap();
        let want = [[1e6, 0.0, 0.0], [0.0, 5e5, 0.0], [0.0, 0.0, 2e6]];
        let close = |a: &Mat3, b: &Mat3, tol: f64| {
            a.iter()
                .flatten()
                .zip(b.iter().flatten())
                .all(|(x, y)| (x - y).abs() <= tol * y.abs().max(1.0))
        };
        assert!(close(&inv, &want, 1e-12), "{inv:?}");
        // … and rank 2 is not, at any scale.
        for s in [1e-6, 1.0, 1e6] {
            let m: Mat3 = [
                [s, 2.0 * s, 3.0 * s],
                [2.0 * s, 4.0 * s, 6.0 * s],
                [0.0, s, s],
            ];
            assert!(inverse3(&m).is_none(), "{s}");
        }
        let m: Mat3 = [[2.0, 1.0, 0.5], [0.3, 1.7, 0.2], [0.1, -0.4, 1.1]];
        let p = mul3(&m, &inverse3(&m).unwrap());
        let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(close(&p, &identity, 1e-12), "{p:?}");
    }

    /// solve3 refuses exactly what inverse3 refuses: a small-unit system (det 1e-18, below the
    /// old absolute cut-off 1e-15) is solved, rank 2 is not at any scale.
    #[test]
    fn solve3_shares_the_singularity_rule_of_inverse3() {
        let small: Mat3 = [[1e-6, 0.0, 0.0], [0.0, 2e-6, 0.0], [0.0, 0.0, 5e-7]];
        let x = solve3(small, [1e-6, 1e-6, 1e-6]).unwrap();
        for (got, want) in x.iter().zip([1.0, 0.5, 2.0]) {
            assert!((got - want).abs() <= 1e-12, "{x:?}");
        }
        for s in [1e-6, 1.0, 1e6] {
            let m: Mat3 = [
                [s, 2.0 * s, 3.0 * s],
                [2.0 * s, 4.0 * s, 6.0 * s],
                [0.0, s, s],
            ];
            assert!(solve3(m, [1.0, 2.0, 3.0]).is_none(), "{s}");
            assert_eq!(solve3(m, [1.0; 3]).is_none(), inverse3(&m).is_none());
        }
        let m: Mat3 = [[2.0, 1.0, 0.5], [0.3, 1.7, 0.2], [0.1, -0.4, 1.1]];
        let v = [0.7, -1.2, 3.4];
        let (x, y) = (solve3(m, v).unwrap(), mat_vec(&inverse3(&m).unwrap(), v));
        assert!(
            x.iter().zip(y).all(|(a, b)| (a - b).abs() <= 1e-12),
            "{x:?} {y:?}"
        );
    }
}
