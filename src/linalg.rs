//! Small dense linear algebra.

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
