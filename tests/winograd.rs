//! Winograd F(m×m, r×r) (src/kernels/winograd.rs) against a direct convolution in f64, and its
//! Cook–Toom matrices against Lavin & Gray's published F(2, 3).
#![cfg(feature = "flex")]
// Matrix entries by index, as the papers write them.
#![allow(clippy::needless_range_loop)]

use hdrsynth::kernels::winograd::{Winograd, conv2d_f32, cook_toom, weight_grad_f32};

/// Deterministic values in [−1, 1).
fn values(n: usize, seed: u64) -> Vec<f32> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        })
        .collect()
}

/// The stride-1 correlation with zero padding [top, left], in f64, by its definition.
fn direct(
    x: &[f32],
    [b, cin, h, w]: [usize; 4],
    wt: &[f32],
    [cout, _, k, _]: [usize; 4],
    [ho, wo]: [usize; 2],
    [pt, pl]: [usize; 2],
) -> Vec<f64> {
    let mut y = vec![0.0f64; b * cout * ho * wo];
    for bi in 0..b {
        for co in 0..cout {
            for oy in 0..ho {
                for ox in 0..wo {
                    let mut s = 0.0f64;
                    for ci in 0..cin {
                        for i in 0..k {
                            for j in 0..k {
                                let (iy, ix) = (oy + i, ox + j);
                                if iy < pt || ix < pl || iy - pt >= h || ix - pl >= w {
                                    continue;
                                }
                                s += f64::from(x[((bi * cin + ci) * h + iy - pt) * w + ix - pl])
                                    * f64::from(wt[((co * cin + ci) * k + i) * k + j]);
                            }
                        }
                    }
                    y[((bi * cout + co) * ho + oy) * wo + ox] = s;
                }
            }
        }
    }
    y
}

/// Lavin & Gray's F(2, 3) on 0, 1, −1, ∞ (their Bᵀ, G, Aᵀ), up to what the construction is free
/// to choose: per point j, scales of Aᵀ's column j, Bᵀ's row j and G's row j whose product is 1.
/// So each point's triple product Aᵀ[i][j]·Bᵀ[j][u]·G[j][k] must equal theirs.
#[test]
fn f23_matches_lavin_and_gray() {
    let tf = Winograd::F2x3.matrices();
    let bt = [
        [1.0, 0.0, -1.0, 0.0],
        [0.0, 1.0, 1.0, 0.0],
        [0.0, -1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0, -1.0],
    ];
    let g = [
        [1.0, 0.0, 0.0],
        [0.5, 0.5, 0.5],
        [0.5, -0.5, 0.5],
        [0.0, 0.0, 1.0],
    ];
    let at = [[1.0f32, 1.0, 1.0, 0.0], [0.0, 1.0, -1.0, -1.0]];
    assert_eq!((tf.m, tf.r, tf.alpha), (2, 3, 4));
    for j in 0..4 {
        for i in 0..2 {
            for u in 0..4 {
                for k in 0..3 {
                    let ours = tf.at[i][j] * tf.bt[j][u] * tf.g[j][k];
                    let theirs = at[i][j] * bt[j][u] * g[j][k];
                    assert!(
                        (ours - theirs).abs() < 1e-7,
                        "point {j}: Aᵀ[{i}]·Bᵀ[{u}]·G[{k}] = {ours}, Lavin & Gray {theirs}"
                    );
                }
            }
        }
    }
}

/// Small integers keep every intermediate of F(2, 3) exact in f32 (its matrices hold 0, ±1 and
/// ±1/2), so the result equals the direct sum exactly.
#[test]
fn f23_is_exact_on_integers() {
    let xs = [1, 2, 7, 9];
    let ws = [3, 2, 3, 3];
    let x: Vec<f32> = values(126, 1).iter().map(|v| (v * 8.0).round()).collect();
    let wt: Vec<f32> = values(54, 2).iter().map(|v| (v * 4.0).round()).collect();
    let y = conv2d_f32(&x, xs, &wt, ws, [7, 9], [1, 1], Winograd::F2x3);
    let d = direct(&x, xs, &wt, ws, [7, 9], [1, 1]);
    for (i, (a, b)) in y.iter().zip(&d).enumerate() {
        assert_eq!(f64::from(*a), *b, "output {i}");
    }
}

/// Every shape kind the networks use (3×3 padding 1 and 0, 5×5 padding 2), odd sizes that leave
/// partial tiles, several blocks: the α = 6 transforms agree with f64 to 1e-5 of the output's
/// scale (measured: up to 7e-6 at 256 input channels, rms 1e-6), F(4×4, 5×5) (α = 8, the
/// head's) to 2e-5 (measured: 1.6e-5 at 256 input channels, rms 1.3e-6), F(2, 3) to 1e-6.
#[test]
fn agrees_with_the_direct_convolution() {
    type Case = (usize, usize, [usize; 4], usize, [usize; 2], usize);
    let cases: [Case; 7] = [
        // (m, r, [b, cin, h, w], cout, [ho, wo], pad)
        (4, 3, [2, 16, 13, 11], 24, [13, 11], 1),
        (4, 3, [1, 32, 34, 34], 32, [32, 32], 0),
        (2, 5, [2, 8, 17, 12], 40, [17, 12], 2),
        (2, 3, [1, 16, 9, 10], 16, [9, 10], 1),
        (4, 3, [1, 3, 5, 4], 2, [5, 4], 1),
        (4, 5, [2, 8, 17, 12], 40, [17, 12], 2),
        (4, 5, [1, 256, 12, 10], 8, [12, 10], 2),
    ];
    for (n, (m, r, xs, cout, out, pad)) in cases.into_iter().enumerate() {
        let kind = match (m, r) {
            (2, 3) => Winograd::F2x3,
            (4, 3) => Winograd::F4x3,
            (2, 5) => Winograd::F2x5,
            _ => Winograd::F4x5,
        };
        let tf = kind.matrices();
        assert_eq!((tf.m, tf.r), (m, r));
        let ws = [cout, xs[1], r, r];
        let x = values(xs.iter().product(), 10 + n as u64);
        let wt = values(ws.iter().product(), 20 + n as u64);
        let y = conv2d_f32(&x, xs, &wt, ws, out, [pad, pad], kind);
        let d = direct(&x, xs, &wt, ws, out, [pad, pad]);
        let scale = d.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let err = y
            .iter()
            .zip(&d)
            .fold(0.0f64, |a, (p, q)| a.max((f64::from(*p) - q).abs()));
        let tol = match kind {
            Winograd::F2x3 => 1e-6,
            Winograd::F4x5 => 2e-5,
            _ => 1e-5,
        };
        assert!(
            err <= tol * scale,
            "case {n} F({m},{r}): max error {err:e} against scale {scale:e}"
        );
    }
}

/// Row j of Bᵀ holds the coefficients of the polynomial that is 1 at pⱼ and 0 at the other
/// points (∞: leading coefficient). By hand for 0, ±1, ±1/2: at 0 it is 4(x² − 1)(x² − 1/4) =
/// 1 − 5x² + 4x⁴; at ∞ it is x(x² − 1)(x² − 1/4) = x/4 − 5x³/4 + x⁵, scaled to 1, −5, 4.
#[test]
fn alpha6_input_transform_is_integer() {
    for kind in [Winograd::F4x3, Winograd::F2x5] {
        let tf = kind.matrices();
        assert_eq!(tf.alpha, 6);
        assert_eq!(tf.bt[0][..6], [1.0, 0.0, -5.0, 0.0, 4.0, 0.0]);
        assert_eq!(tf.bt[5][..6], [0.0, 1.0, 0.0, -5.0, 0.0, 4.0]);
        for row in &tf.bt[..6] {
            assert!(row[..6].iter().all(|v| v.fract() == 0.0), "{row:?}");
        }
    }
    // A transform built at run time equals the compile-time one.
    assert_eq!(
        cook_toom(4, 3, &[0.0, 1.0, -1.0, 0.5, -0.5]),
        Winograd::F4x3.matrices()
    );
}

/// dL/dW of the stride-1 correlation with zero padding [top, left] in f64, by its definition:
/// dW[co, ci, i, j] = Σ_(b, oy, ox) dY[b, co, oy, ox] · x[b, ci, oy + i − pt, ox + j − pl].
fn direct_weight_grad(
    x: &[f32],
    [b, cin, h, w]: [usize; 4],
    dy: &[f32],
    [_, cout, ho, wo]: [usize; 4],
    k: usize,
    [pt, pl]: [usize; 2],
) -> Vec<f64> {
    let mut dw = vec![0.0f64; cout * cin * k * k];
    for co in 0..cout {
        for ci in 0..cin {
            for i in 0..k {
                for j in 0..k {
                    let mut s = 0.0f64;
                    for bi in 0..b {
                        for oy in 0..ho {
                            for ox in 0..wo {
                                let (iy, ix) = (oy + i, ox + j);
                                if iy < pt || ix < pl || iy - pt >= h || ix - pl >= w {
                                    continue;
                                }
                                s += f64::from(dy[((bi * cout + co) * ho + oy) * wo + ox])
                                    * f64::from(x[((bi * cin + ci) * h + iy - pt) * w + ix - pl]);
                            }
                        }
                    }
                    dw[((co * cin + ci) * k + i) * k + j] = s;
                }
            }
        }
    }
    dw
}

/// The weight gradient (F(r, m) by the transposed matrices) on the networks' shape kinds, partial
/// tiles, several batch items and input channels not a multiple of the 8 lanes: within 1e-5 of
/// the gradient's scale of the f64 sum (F(2, 3): 1e-6), and exact for F(2, 3) on small integers.
#[test]
fn weight_gradient_agrees_with_the_direct_sum() {
    type Case = (Winograd, [usize; 4], usize, [usize; 2], usize);
    let cases: [Case; 6] = [
        // (kind, [b, cin, h, w], cout, [ho, wo], pad)
        (Winograd::F4x3, [2, 16, 13, 11], 24, [13, 11], 1),
        (Winograd::F4x3, [3, 20, 34, 30], 12, [32, 28], 0),
        (Winograd::F2x5, [2, 8, 17, 12], 40, [17, 12], 2),
        (Winograd::F4x5, [2, 12, 19, 13], 20, [19, 13], 2),
        (Winograd::F2x3, [1, 16, 9, 10], 16, [9, 10], 1),
        (Winograd::F4x3, [1, 3, 5, 4], 2, [5, 4], 1),
    ];
    for (n, (kind, xs, cout, [ho, wo], pad)) in cases.into_iter().enumerate() {
        let r = kind.matrices().r;
        let ys = [xs[0], cout, ho, wo];
        let x = values(xs.iter().product(), 30 + n as u64);
        let dy = values(ys.iter().product(), 40 + n as u64);
        let dw = weight_grad_f32(&x, xs, &dy, ys, [pad, pad], kind);
        let d = direct_weight_grad(&x, xs, &dy, ys, r, [pad, pad]);
        assert_eq!(dw.len(), d.len());
        let scale = d.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let err = dw
            .iter()
            .zip(&d)
            .fold(0.0f64, |a, (p, q)| a.max((f64::from(*p) - q).abs()));
        let tol = if kind == Winograd::F2x3 { 1e-6 } else { 1e-5 };
        assert!(
            err <= tol * scale,
            "case {n} {kind:?}: max error {err:e} against scale {scale:e}"
        );
    }
    // F(2, 3)'s matrices hold 0, ±1 and ±1/2: small integers stay exact.
    let (xs, ys) = ([2, 3, 7, 9], [2, 5, 7, 9]);
    let x: Vec<f32> = values(378, 5).iter().map(|v| (v * 8.0).round()).collect();
    let dy: Vec<f32> = values(630, 6).iter().map(|v| (v * 4.0).round()).collect();
    let dw = weight_grad_f32(&x, xs, &dy, ys, [1, 1], Winograd::F2x3);
    let d = direct_weight_grad(&x, xs, &dy, ys, 3, [1, 1]);
    for (i, (a, b)) in dw.iter().zip(&d).enumerate() {
        assert_eq!(f64::from(*a), *b, "dW {i}");
    }
}
