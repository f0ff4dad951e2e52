//! Winograd minimal filtering F(m×m, r×r) for the networks' stride-1 convolutions on flex:
//! each m×m block of outputs from an α×α input patch (α = m + r − 1) by α² products
//! instead of m²·r², so Network-1's 5×5 head by F(4×4, 5×5) needs 4 multiplies per output
//! instead of 25 and a 3×3 layer by F(4×4, 3×3) 2.25 instead of 9 (Lavin & Gray, "Fast
//! Algorithms for Convolutional Neural Networks", CVPR 2016). Per batch of tiles:
//! V = Bᵀ·d·B per (input channel, tile), U = G·g·Gᵀ per filter, then one GEMM per frequency ξ
//! (M_ξ = U_ξ · V_ξ, K = input channels), and Y = Aᵀ·M·A per (output channel, tile). The
//! weight gradient ([`weight_grad_f32`]) reuses the input transform and turns the output
//! gradient's tiles into the same α×α frequencies, so its GEMMs run over the tiles (K = tiles).
//!
//! The matrices come from Cook–Toom's construction on points p₀… and ∞, evaluated at compile
//! time ([`cook_toom`], f64 then rounded once): a correlation is the transpose of a polynomial
//! product evaluated at those points, so with Vₙ the α×n Vandermonde matrix (row j = 1, pⱼ, …,
//! pⱼⁿ⁻¹; the ∞ row picks the top-degree coefficient), Aᵀ = V_mᵀ, G = V_r and Bᵀ = (V_α⁻¹)ᵀ. As
//! constants, the transforms' unrolled loops skip every zero entry. Rounding differs from the
//! direct convolution's (the transforms add and subtract before the products): a few 1e-7 of the
//! output's scale for F(2, 3), up to about 1e-5 for α = 6 and 2e-5 for α = 8 (tests/winograd.rs,
//! against an f64 convolution). Sums run in a fixed order and every batch of tiles is computed whole by one
//! task, so results do not depend on the thread count.

// The transforms are small matrix products, clearest with indices.
#![allow(clippy::needless_range_loop)]

use crate::kernels::par::{Shared, matmul, pad_rows, with_avx2};
use rayon::prelude::*;

/// Most points any transform here uses (α ≤ 8).
const MAX_ALPHA: usize = 8;
/// Tiles (or, for the filters, input channels) transformed together: the lanes of the
/// transforms' vector loops.
const LANES: usize = 8;
/// Bytes of one task's transformed inputs and products (V and M for a batch of tiles).
const BLOCK_BYTES: usize = 4 << 20;

/// The three matrices of F(m, r), row-major in the top-left corner of 8×8 arrays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Matrices {
    pub m: usize,
    pub r: usize,
    pub alpha: usize,
    /// Aᵀ, m × α.
    pub at: [[f32; MAX_ALPHA]; MAX_ALPHA],
    /// Bᵀ, α × α.
    pub bt: [[f32; MAX_ALPHA]; MAX_ALPHA],
    /// G, α × r.
    pub g: [[f32; MAX_ALPHA]; MAX_ALPHA],
}

/// Cook–Toom's F(m, r) on the finite points `points` (α − 1 distinct values) and ∞. Row j of Bᵀ
/// (column j of V_α⁻¹) is scaled to a smallest nonzero entry of 1 and G's row j takes the factor
/// back: on 0, ±1, ±1/2 that makes Bᵀ Lavin & Gray's integer matrix, so the input transform
/// multiplies exactly.
pub const fn cook_toom(m: usize, r: usize, points: &[f64]) -> Matrices {
    let alpha = m + r - 1;
    assert!(m > 0 && r > 0 && alpha <= MAX_ALPHA && points.len() == alpha - 1);
    // [V_α | I], Gauss–Jordan with partial pivoting → [I | V_α⁻¹].
    let mut aug = [[0.0f64; 2 * MAX_ALPHA]; MAX_ALPHA];
    let mut j = 0;
    while j < alpha {
        let mut i = 0;
        while i < alpha {
            aug[j][i] = vander(points, j, i, alpha);
            i += 1;
        }
        aug[j][MAX_ALPHA + j] = 1.0;
        j += 1;
    }
    let mut c = 0;
    while c < alpha {
        let mut p = c;
        let mut i = c + 1;
        while i < alpha {
            if aug[i][c].abs() > aug[p][c].abs() {
                p = i;
            }
            i += 1;
        }
        assert!(aug[p][c] != 0.0, "Cook–Toom points must be distinct");
        let row = aug[p];
        aug[p] = aug[c];
        aug[c] = row;
        let pivot = aug[c][c];
        let mut k = 0;
        while k < 2 * MAX_ALPHA {
            aug[c][k] /= pivot;
            k += 1;
        }
        let mut i = 0;
        while i < alpha {
            let f = aug[i][c];
            if i != c && f != 0.0 {
                let mut k = 0;
                while k < 2 * MAX_ALPHA {
                    aug[i][k] -= f * aug[c][k];
                    k += 1;
                }
            }
            i += 1;
        }
        c += 1;
    }
    let mut out = Matrices {
        m,
        r,
        alpha,
        at: [[0.0; MAX_ALPHA]; MAX_ALPHA],
        bt: [[0.0; MAX_ALPHA]; MAX_ALPHA],
        g: [[0.0; MAX_ALPHA]; MAX_ALPHA],
    };
    let mut j = 0;
    while j < alpha {
        // Column j of V_α⁻¹, its round-off (≈ 1e-16 on these small rationals) snapped to 0.
        let mut col = [0.0f64; MAX_ALPHA];
        let mut scale = f64::INFINITY;
        let mut i = 0;
        while i < alpha {
            let v = aug[i][MAX_ALPHA + j];
            col[i] = if v.abs() < 1e-9 { 0.0 } else { v };
            if col[i] != 0.0 && col[i].abs() < scale {
                scale = col[i].abs();
            }
            i += 1;
        }
        let mut i = 0;
        while i < alpha {
            out.bt[j][i] = (col[i] / scale) as f32;
            i += 1;
        }
        let mut k = 0;
        while k < r {
            out.g[j][k] = (vander(points, j, k, r) * scale) as f32;
            k += 1;
        }
        let mut i = 0;
        while i < m {
            out.at[i][j] = vander(points, j, i, m) as f32;
            i += 1;
        }
        j += 1;
    }
    out
}

/// Entry (j, i) of the α×n Vandermonde matrix: pⱼ^i, or for the last row (∞) 1 at i = n − 1.
const fn vander(points: &[f64], j: usize, i: usize, n: usize) -> f64 {
    if j == points.len() {
        return if i == n - 1 { 1.0 } else { 0.0 };
    }
    let mut v = 1.0;
    let mut e = 0;
    while e < i {
        v *= points[j];
        e += 1;
    }
    v
}

/// The points of the α = 6 transforms: 0, ±1, ±1/2 (and ∞).
const POINTS: [f64; 5] = [0.0, 1.0, -1.0, 0.5, -0.5];

/// The Winograd transforms the convolutions use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Winograd {
    /// F(2×2, 3×3) on 0, ±1 (α = 4): the most accurate; for tests and comparisons.
    F2x3,
    /// F(4×4, 3×3) on 0, ±1, ±1/2 (α = 6): the 3×3 layers.
    F4x3,
    /// F(2×2, 5×5) on 0, ±1, ±1/2 (α = 6): for tests and comparisons.
    F2x5,
    /// F(4×4, 5×5) on 0, ±1, ±1/2, ±2 (α = 8): Network-1's 5×5 head. Against F(2×2, 5×5) a
    /// quarter of the tiles and 4 transformed values per pixel instead of 9 (timings: `cargo
    /// bench --bench train_ops`), at about twice the rounding error (tests/winograd.rs).
    F4x5,
}

impl Winograd {
    /// The transform the convolutions use for an r×r kernel, if any.
    pub fn for_kernel(r: usize) -> Option<Winograd> {
        match r {
            3 => Some(Winograd::F4x3),
            5 => Some(Winograd::F4x5),
            _ => None,
        }
    }

    /// Its matrices.
    pub fn matrices(self) -> Matrices {
        match self {
            Winograd::F2x3 => F2x3::MAT,
            Winograd::F4x3 => F4x3::MAT,
            Winograd::F2x5 => F2x5::MAT,
            Winograd::F4x5 => F4x5::MAT,
        }
    }
}

/// A transform with its matrices as compile-time constants, so the kernels' loops unroll and
/// fold every 0 and 1.
trait Kind {
    const MAT: Matrices;
    /// A = (Aᵀ)ᵀ, α × m: the output gradient's transform in [`weight_grad_f32`].
    const A: [[f32; MAX_ALPHA]; MAX_ALPHA] = transpose(Self::MAT.at);
    /// Gᵀ, r × α: the weight gradient's output transform.
    const GT: [[f32; MAX_ALPHA]; MAX_ALPHA] = transpose(Self::MAT.g);
}

const fn transpose(a: [[f32; MAX_ALPHA]; MAX_ALPHA]) -> [[f32; MAX_ALPHA]; MAX_ALPHA] {
    let mut t = [[0.0f32; MAX_ALPHA]; MAX_ALPHA];
    let mut i = 0;
    while i < MAX_ALPHA {
        let mut j = 0;
        while j < MAX_ALPHA {
            t[j][i] = a[i][j];
            j += 1;
        }
        i += 1;
    }
    t
}
struct F2x3;
struct F4x3;
struct F2x5;
struct F4x5;
impl Kind for F4x5 {
    const MAT: Matrices = cook_toom(4, 5, &[0.0, 1.0, -1.0, 0.5, -0.5, 2.0, -2.0]);
}
impl Kind for F2x3 {
    const MAT: Matrices = cook_toom(2, 3, &[0.0, 1.0, -1.0]);
}
impl Kind for F4x3 {
    const MAT: Matrices = cook_toom(4, 3, &POINTS);
}
impl Kind for F2x5 {
    const MAT: Matrices = cook_toom(2, 5, &POINTS);
}

/// Tile rows of `tw` tiles each per block: the transformed inputs and products of `channels`
/// (c_in + c_out) channels within [`BLOCK_BYTES`], at least one row.
fn block_rows(alpha: usize, channels: usize, tw: usize) -> usize {
    (BLOCK_BYTES / 4 / (channels * alpha * alpha * tw).max(1)).max(1)
}

/// Tiles per block (the GEMMs' N in the forward pass, their K in the weight gradient) for a
/// layer of `channels` = c_in + c_out channels and output rows `out_w` wide.
pub fn block_tiles(kind: Winograd, channels: usize, out_w: usize) -> usize {
    let mat = kind.matrices();
    let tw = out_w.div_ceil(mat.m);
    block_rows(mat.alpha, channels, tw) * tw
}

/// The stride-1, dilation-1 convolution (no bias, one group) of `x` ([B, C_in, H, W]) by `wt`
/// ([C_out, C_in, r, r]) with zero padding `[top, left]` (bottom and right follow from the
/// output size `[ho, wo]`), by `kind`; returns Y as [B, C_out, ho, wo].
pub fn conv2d_f32(
    x: &[f32],
    xs: [usize; 4],
    wt: &[f32],
    ws: [usize; 4],
    out: [usize; 2],
    pad: [usize; 2],
    kind: Winograd,
) -> Vec<f32> {
    let r = kind.matrices().r;
    assert!(
        ws[2] == r && ws[3] == r,
        "kernel {}×{} for r = {r}",
        ws[2],
        ws[3]
    );
    assert_eq!(xs[1], ws[1], "input channels of x and the kernels");
    match kind {
        Winograd::F2x3 => conv2d_impl::<F2x3>(x, xs, wt, ws, out, pad),
        Winograd::F4x3 => conv2d_impl::<F4x3>(x, xs, wt, ws, out, pad),
        Winograd::F2x5 => conv2d_impl::<F2x5>(x, xs, wt, ws, out, pad),
        Winograd::F4x5 => conv2d_impl::<F4x5>(x, xs, wt, ws, out, pad),
    }
}

fn conv2d_impl<K: Kind>(
    x: &[f32],
    [batch, cin, h, w]: [usize; 4],
    wt: &[f32],
    [cout, ..]: [usize; 4],
    [ho, wo]: [usize; 2],
    [pt, pl]: [usize; 2],
) -> Vec<f32> {
    let (a, m) = (K::MAT.alpha, K::MAT.m);
    let mut y = vec![0.0f32; batch * cout * ho * wo];
    if batch * cin * cout * ho * wo == 0 {
        return y;
    }
    let u = filter_transform::<K>(wt, cout, cin);
    let (th, tw) = (ho.div_ceil(m), wo.div_ceil(m));
    // A task's block: a run of tile rows over the whole batch (item b's rows are b·th..); the
    // deep layers' few tiles per item batch across items.
    let rows = block_rows(a, cin + cout, tw).min(batch * th);
    let blocks: Vec<usize> = (0..batch * th).step_by(rows).collect();
    let nt_max = rows * tw;
    // One input channel's padded rows for one item's part of a block: tile columns rounded up
    // to LANES, so every lane reads inside the buffer.
    let wp = tw.next_multiple_of(LANES) * m + a - m;
    let hp = rows.min(th) * m + a - m;
    let out = Shared(y.as_mut_ptr());
    let threads = rayon::current_num_threads().clamp(1, blocks.len());
    let run = |run: &[usize], parallel: bool| {
        let mut v = vec![0.0f32; a * a * cin * nt_max];
        let mut mm = vec![0.0f32; a * a * cout * nt_max];
        let mut padded = vec![0.0f32; hp * wp];
        for &g0 in run {
            let g1 = (g0 + rows).min(batch * th);
            let nt = (g1 - g0) * tw;
            // The block's parts by batch item: (item, first tile row, end, first tile index).
            let parts = (g0 / th..g1.div_ceil(th)).map(|b| {
                let (r0, r1) = (g0.max(b * th) - b * th, g1.min((b + 1) * th) - b * th);
                (b, r0, r1, (b * th + r0 - g0) * tw)
            });
            for (b, r0, r1, t0) in parts.clone() {
                for ci in 0..cin {
                    let plane = &x[(b * cin + ci) * h * w..][..h * w];
                    let padded = &mut padded[..((r1 - r0) * m + a - m) * wp];
                    pad_rows(plane, [h, w], [r0 * m, pt, pl], wp, padded);
                    with_avx2(
                        #[inline(always)]
                        || input_transform::<K>(padded, wp, [r1 - r0, tw], ci, nt, t0, &mut v),
                    );
                }
            }
            for xi in 0..a * a {
                // M_ξ[co, t] = Σ_ci U_ξ[co, ci] · V_ξ[ci, t] (V and M hold each channel's α²
                // frequencies together, so a transform reads or writes one contiguous run).
                // SAFETY: the extents index inside mm's, u's and v's ξ blocks.
                unsafe {
                    matmul(
                        [cout, nt, cin],
                        mm.as_mut_ptr().add(xi * nt),
                        [1, (a * a * nt) as isize],
                        false,
                        u.as_ptr().add(xi * cout * cin),
                        [1, cin as isize],
                        v.as_ptr().add(xi * nt),
                        [1, (a * a * nt) as isize],
                        parallel,
                    );
                }
            }
            for (b, r0, r1, t0) in parts {
                for co in 0..cout {
                    // SAFETY: item b's channel co; its tile rows r0..r1 belong to this block only.
                    let plane = unsafe { out.slice((b * cout + co) * ho * wo, ho * wo) };
                    with_avx2(
                        #[inline(always)]
                        || output_transform::<K>(&mm, [ho, wo], [r0, r1, tw], co, nt, t0, plane),
                    );
                }
            }
        }
    };
    if threads == 1 {
        run(&blocks, true);
    } else {
        blocks
            .par_chunks(blocks.len().div_ceil(threads))
            .for_each(|r| run(r, false));
    }
    y
}

/// dL/dW of the convolution [`conv2d_f32`] computes with the same `pad` and `kind`, from its
/// input `x` ([B, C_in, H, W]) and output gradient `dy` ([B, C_out, ho, wo]); returns dW as
/// [C_out, C_in, r, r].
///
/// Over one m×m output tile, dW is the correlation of the tile's α×α input patch d with the
/// tile's gradient: F(r, m) on the same points. Σ_u w_u·y_u = Σ_ξ (A·w)_ξ (G·g)_ξ (Bᵀ·d)_ξ is
/// symmetric in the output weights w and the filter g, so F(r, m)'s matrices are F(m, r)'s with
/// A and G swapped: dW = Gᵀ·[Σ_tiles (A·dy·Aᵀ) ⊙ (Bᵀ·d·B)]·G. The sum over tiles is one GEMM per
/// frequency ξ with K = tiles (M = c_out, N = c_in). Each batch item sums its own tiles and the
/// items' sums are added in item order, so the result does not depend on the thread count.
pub fn weight_grad_f32(
    x: &[f32],
    xs: [usize; 4],
    dy: &[f32],
    ys: [usize; 4],
    pad: [usize; 2],
    kind: Winograd,
) -> Vec<f32> {
    assert_eq!(xs[0], ys[0], "batch of x and dy");
    match kind {
        Winograd::F2x3 => weight_grad_impl::<F2x3>(x, xs, dy, ys, pad),
        Winograd::F4x3 => weight_grad_impl::<F4x3>(x, xs, dy, ys, pad),
        Winograd::F2x5 => weight_grad_impl::<F2x5>(x, xs, dy, ys, pad),
        Winograd::F4x5 => weight_grad_impl::<F4x5>(x, xs, dy, ys, pad),
    }
}

fn weight_grad_impl<K: Kind>(
    x: &[f32],
    [batch, cin, h, w]: [usize; 4],
    dy: &[f32],
    [_, cout, ho, wo]: [usize; 4],
    [pt, pl]: [usize; 2],
) -> Vec<f32> {
    let (a, m, r) = (K::MAT.alpha, K::MAT.m, K::MAT.r);
    if batch * cin * cout * ho * wo == 0 {
        return vec![0.0f32; cout * cin * r * r];
    }
    let (th, tw) = (ho.div_ceil(m), wo.div_ceil(m));
    // A block: a run of one item's tile rows.
    let rows = block_rows(a, cin + cout, tw).min(th);
    let nt_max = rows * tw;
    // Padded rows, tile columns rounded up to LANES as in the forward pass: x's with the
    // convolution's padding, dy's with zeros past the output.
    let wp = tw.next_multiple_of(LANES) * m + a - m;
    let wq = tw.next_multiple_of(LANES) * m;
    let parallel = rayon::current_num_threads() > batch;
    let parts: Vec<Vec<f32>> = (0..batch)
        .into_par_iter()
        .map(|b| {
            let mut v = vec![0.0f32; a * a * cin * nt_max];
            let mut yh = vec![0.0f32; a * a * cout * nt_max];
            let mut padded = vec![0.0f32; (rows * m + a - m) * wp];
            let mut dpad = vec![0.0f32; rows * m * wq];
            let mut sum = vec![0.0f32; a * a * cout * cin];
            for r0 in (0..th).step_by(rows) {
                let r1 = (r0 + rows).min(th);
                let nt = (r1 - r0) * tw;
                let padded = &mut padded[..((r1 - r0) * m + a - m) * wp];
                for ci in 0..cin {
                    let plane = &x[(b * cin + ci) * h * w..][..h * w];
                    pad_rows(plane, [h, w], [r0 * m, pt, pl], wp, padded);
                    with_avx2(
                        #[inline(always)]
                        || input_transform::<K>(padded, wp, [r1 - r0, tw], ci, nt, 0, &mut v),
                    );
                }
                let dpad = &mut dpad[..(r1 - r0) * m * wq];
                for co in 0..cout {
                    let plane = &dy[(b * cout + co) * ho * wo..][..ho * wo];
                    pad_rows(plane, [ho, wo], [r0 * m, 0, 0], wq, dpad);
                    with_avx2(
                        #[inline(always)]
                        || grad_transform::<K>(dpad, wq, [r1 - r0, tw], co, nt, &mut yh),
                    );
                }
                for xi in 0..a * a {
                    // S_ξ[co, ci] (+)= Σ_t Ŷ_ξ[co, t] · V_ξ[ci, t].
                    // SAFETY: the extents index inside sum's, yh's and v's ξ blocks.
                    unsafe {
                        matmul(
                            [cout, cin, nt],
                            sum.as_mut_ptr().add(xi * cout * cin),
                            [1, cin as isize],
                            r0 > 0,
                            yh.as_ptr().add(xi * nt),
                            [1, (a * a * nt) as isize],
                            v.as_ptr().add(xi * nt),
                            [(a * a * nt) as isize, 1],
                            parallel,
                        );
                    }
                }
            }
            sum
        })
        .collect();
    let mut parts = parts.into_iter();
    let mut sum = parts.next().expect("batch > 0");
    for part in parts {
        sum.iter_mut().zip(&part).for_each(|(s, p)| *s += p);
    }
    // dW = Gᵀ·S·G per (c_out, c_in), `LANES` input channels at a time.
    let mut dw = vec![0.0f32; cout * cin * r * r];
    dw.par_chunks_mut(cin * r * r)
        .enumerate()
        .for_each(|(co, dwc)| {
            with_avx2(
                #[inline(always)]
                || {
                    let mut p = [[[0.0f32; LANES]; MAX_ALPHA]; MAX_ALPHA];
                    let mut tmp = [[[0.0f32; LANES]; MAX_ALPHA]; MAX_ALPHA];
                    for ci0 in (0..cin).step_by(LANES) {
                        let lanes = LANES.min(cin - ci0);
                        for i in 0..a {
                            for j in 0..a {
                                load(
                                    &mut p[i][j],
                                    &sum[((i * a + j) * cout + co) * cin + ci0..],
                                    lanes,
                                );
                            }
                        }
                        left_mul(&K::GT, [r, a, a], &p, &mut tmp);
                        for k in 0..r {
                            for l in 0..r {
                                let acc = right_mul(&tmp[k], &K::GT[l], a);
                                for (c, &e) in acc.iter().enumerate().take(lanes) {
                                    dwc[(ci0 + c) * r * r + k * r + l] = e;
                                }
                            }
                        }
                    }
                },
            )
        });
    dw
}

/// Ŷ[co][ξ][t] = (A·e·Aᵀ)_ξ for `tile_rows` × `tw` tiles, e the m×m block of `dpad` (the tile
/// rows' output-gradient rows, `wq` wide) at (ty·m, tx·m); `LANES` tiles of one row at a time.
#[inline(always)]
fn grad_transform<K: Kind>(
    dpad: &[f32],
    wq: usize,
    [tile_rows, tw]: [usize; 2],
    co: usize,
    nt: usize,
    yh: &mut [f32],
) {
    let (a, m) = (K::MAT.alpha, K::MAT.m);
    let am = &K::A;
    let mut e = [[[0.0f32; LANES]; MAX_ALPHA]; MAX_ALPHA];
    let mut tmp = [[[0.0f32; LANES]; MAX_ALPHA]; MAX_ALPHA];
    let yc = &mut yh[co * a * a * nt..][..a * a * nt];
    for ty in 0..tile_rows {
        for tx0 in (0..tw).step_by(LANES) {
            let lanes = LANES.min(tw - tx0);
            let base = ty * m * wq + tx0 * m;
            for (uu, eu) in e.iter_mut().enumerate().take(m) {
                let row = &dpad[base + uu * wq..][..LANES * m];
                for (c, ec) in eu.iter_mut().enumerate().take(m) {
                    for (l, v) in ec.iter_mut().enumerate() {
                        *v = row[l * m + c];
                    }
                }
            }
            // tmp = A·e (α × m), then Ŷ = tmp·Aᵀ (α × α).
            left_mul(am, [a, m, m], &e, &mut tmp);
            let t = ty * tw + tx0;
            for i in 0..a {
                for j in 0..a {
                    let acc = right_mul(&tmp[i], &am[j], m);
                    store(&mut yc[(i * a + j) * nt + t..], &acc, lanes);
                }
            }
        }
    }
}

/// G·g·Gᵀ for every (c_out, c_in) filter of `wt` ([C_out, C_in, r, r]), as U[ξ][c_out][c_in];
/// `LANES` input channels at a time.
fn filter_transform<K: Kind>(wt: &[f32], cout: usize, cin: usize) -> Vec<f32> {
    let (a, r) = (K::MAT.alpha, K::MAT.r);
    let gm = &K::MAT.g;
    let mut u = vec![0.0f32; a * a * cout * cin];
    let out = Shared(u.as_mut_ptr());
    (0..cout).into_par_iter().for_each(|co| {
        with_avx2(
            #[inline(always)]
            || {
                let mut g = [[[0.0f32; LANES]; MAX_ALPHA]; MAX_ALPHA];
                let mut tmp = [[[0.0f32; LANES]; MAX_ALPHA]; MAX_ALPHA];
                for ci0 in (0..cin).step_by(LANES) {
                    let lanes = LANES.min(cin - ci0);
                    let base = (co * cin + ci0) * r * r;
                    for (k, gk) in g.iter_mut().enumerate().take(r) {
                        for (l, gkl) in gk.iter_mut().enumerate().take(r) {
                            for (c, e) in gkl.iter_mut().enumerate() {
                                *e = if c < lanes {
                                    wt[base + c * r * r + k * r + l]
                                } else {
                                    0.0
                                };
                            }
                        }
                    }
                    // tmp = G·g (α × r), then U = tmp·Gᵀ (α × α).
                    left_mul(gm, [a, r, r], &g, &mut tmp);
                    for i in 0..a {
                        for j in 0..a {
                            let acc = right_mul(&tmp[i], &gm[j], r);
                            // SAFETY: (ξ, co, ci0..) is inside u, and only this co's task writes it.
                            let dst =
                                unsafe { out.slice(((i * a + j) * cout + co) * cin + ci0, lanes) };
                            store(dst, &acc, lanes);
                        }
                    }
                }
            },
        )
    });
    u
}

/// V[ci][ξ][t0 + t] = (Bᵀ·d·B)_ξ for `tile_rows` × `tw` tiles, d the α×α patch of `padded` (the
/// tile rows' input rows, `wp` wide) at (ty·m, tx·m). `LANES` tiles of one row at a time, so the
/// inner loops run across tiles.
#[inline(always)]
fn input_transform<K: Kind>(
    padded: &[f32],
    wp: usize,
    [tile_rows, tw]: [usize; 2],
    ci: usize,
    nt: usize,
    t0: usize,
    v: &mut [f32],
) {
    let (a, m) = (K::MAT.alpha, K::MAT.m);
    let bt = &K::MAT.bt;
    let mut d = [[[0.0f32; LANES]; MAX_ALPHA]; MAX_ALPHA];
    let mut tmp = [[[0.0f32; LANES]; MAX_ALPHA]; MAX_ALPHA];
    let vc = &mut v[ci * a * a * nt..][..a * a * nt];
    for ty in 0..tile_rows {
        for tx0 in (0..tw).step_by(LANES) {
            let lanes = LANES.min(tw - tx0);
            let base = ty * m * wp + tx0 * m;
            for (uu, du) in d.iter_mut().enumerate().take(a) {
                let row = &padded[base + uu * wp..][..(LANES - 1) * m + a];
                for (c, dc) in du.iter_mut().enumerate().take(a) {
                    for (l, e) in dc.iter_mut().enumerate() {
                        *e = row[l * m + c];
                    }
                }
            }
            // tmp = Bᵀ·d, then V = tmp·B.
            left_mul(bt, [a, a, a], &d, &mut tmp);
            let t = t0 + ty * tw + tx0;
            for i in 0..a {
                for j in 0..a {
                    let acc = right_mul(&tmp[i], &bt[j], a);
                    store(&mut vc[(i * a + j) * nt + t..], &acc, lanes);
                }
            }
        }
    }
}

/// Y = Aᵀ·M·A for channel co's tiles of tile rows r0..r1 (from tile t0 of the block), written
/// into its output plane (the parts inside [ho, wo]).
#[inline(always)]
fn output_transform<K: Kind>(
    mm: &[f32],
    [ho, wo]: [usize; 2],
    [r0, r1, tw]: [usize; 3],
    co: usize,
    nt: usize,
    t0: usize,
    plane: &mut [f32],
) {
    let (a, m) = (K::MAT.alpha, K::MAT.m);
    let at = &K::MAT.at;
    let mc = &mm[co * a * a * nt..][..a * a * nt];
    let mut p = [[[0.0f32; LANES]; MAX_ALPHA]; MAX_ALPHA];
    let mut tmp = [[[0.0f32; LANES]; MAX_ALPHA]; MAX_ALPHA];
    for ty in r0..r1 {
        for tx0 in (0..tw).step_by(LANES) {
            let lanes = LANES.min(tw - tx0);
            let t = t0 + (ty - r0) * tw + tx0;
            for i in 0..a {
                for j in 0..a {
                    load(&mut p[i][j], &mc[(i * a + j) * nt + t..], lanes);
                }
            }
            // tmp = Aᵀ·P (m × α), then Y = tmp·A (m × m).
            left_mul(at, [m, a, a], &p, &mut tmp);
            let full = lanes == LANES && (ty + 1) * m <= ho && (tx0 + LANES) * m <= wo;
            for uu in 0..m {
                let oy = ty * m + uu;
                if oy >= ho {
                    break;
                }
                let row = &mut plane[oy * wo..][..wo];
                for vv in 0..m {
                    let acc = right_mul(&tmp[uu], &at[vv], a);
                    if full {
                        let row = &mut row[tx0 * m + vv..][..(LANES - 1) * m + 1];
                        for (l, &e) in acc.iter().enumerate() {
                            row[l * m] = e;
                        }
                    } else {
                        for (l, &e) in acc.iter().enumerate().take(lanes) {
                            let ox = (tx0 + l) * m + vv;
                            if ox < wo {
                                row[ox] = e;
                            }
                        }
                    }
                }
            }
        }
    }
}

/// `LANES` small matrices side by side: the lane-wise α×α (at most) blocks the transforms work on.
type Lanes = [[[f32; LANES]; MAX_ALPHA]; MAX_ALPHA];

/// out[i][c] = Σ_k mat[i][k]·src[k][c] (i < rows, k < inner, c < cols) in every lane, k in
/// order: the left half of each transform. Inlined with `mat` a constant, the loops unroll and
/// skip its zero entries.
#[inline(always)]
fn left_mul(
    mat: &[[f32; MAX_ALPHA]; MAX_ALPHA],
    [rows, inner, cols]: [usize; 3],
    src: &Lanes,
    out: &mut Lanes,
) {
    for i in 0..rows {
        for c in 0..cols {
            let mut acc = [0.0f32; LANES];
            for k in 0..inner {
                let coef = mat[i][k];
                if coef != 0.0 {
                    for (e, v) in acc.iter_mut().zip(&src[k][c]) {
                        *e += coef * v;
                    }
                }
            }
            out[i][c] = acc;
        }
    }
}

/// Σ_k row[k]·coefs[k] (k < inner, in order) in every lane: one entry of the right half of a
/// transform, tmp·Mᵀ with `coefs` a row of M. Inlined with `coefs` a constant, the loop unrolls
/// and skips its zero entries.
#[inline(always)]
fn right_mul(
    row: &[[f32; LANES]; MAX_ALPHA],
    coefs: &[f32; MAX_ALPHA],
    inner: usize,
) -> [f32; LANES] {
    let mut acc = [0.0f32; LANES];
    for k in 0..inner {
        let c = coefs[k];
        if c != 0.0 {
            for (e, v) in acc.iter_mut().zip(&row[k]) {
                *e += v * c;
            }
        }
    }
    acc
}

/// dst[..lanes] = src[..lanes]; a fixed-size copy for whole groups (a `copy_from_slice` of a
/// run-time length is a call to memmove).
#[inline(always)]
fn store(dst: &mut [f32], src: &[f32; LANES], lanes: usize) {
    if lanes == LANES {
        let dst: &mut [f32; LANES] = (&mut dst[..LANES]).try_into().expect("LANES elements");
        *dst = *src;
    } else {
        dst[..lanes].copy_from_slice(&src[..lanes]);
    }
}

/// dst = src[..lanes], the rest 0 (see [`store`]).
#[inline(always)]
fn load(dst: &mut [f32; LANES], src: &[f32], lanes: usize) {
    if lanes == LANES {
        *dst = src[..LANES].try_into().expect("LANES elements");
    } else {
        *dst = [0.0; LANES];
        dst[..lanes].copy_from_slice(&src[..lanes]);
    }
}
