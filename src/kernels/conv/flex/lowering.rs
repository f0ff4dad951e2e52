//! The f32 convolutions themselves: im2col / col2im tiles and their GEMMs, and which of
//! Winograd, the direct convolution or polyphase a layer takes.

use super::*;

/// One tile of the im2col matrix of one image `xb` ([C_in, H, W]): output rows oh0.. (as many
/// as `col` holds, `col.len() / (C_in·kh·kw·wo)`), each of `wo` columns:
/// col[(ci, i, j), (oh, ow)] = x[ci, oh·sh + i·dh − pt, ow·sw + j·dw − pl], or 0 outside x.
pub(super) fn im2col(
    xb: &[f32],
    [cin, h, w]: [usize; 3],
    [kh, kw]: [usize; 2],
    options: &ConvOptions<2>,
    wo: usize,
    oh0: usize,
    col: &mut [f32],
) {
    let [sh, sw] = options.stride;
    let [dh, dw] = options.dilation;
    let [pt, pl] = options.padding_begin();
    let t = col.len() / (cin * kh * kw);
    col.par_chunks_mut(t).enumerate().for_each(|(r, row)| {
        let (ci, i, j) = (r / (kh * kw), (r / kw) % kh, r % kw);
        let plane = &xb[ci * h * w..(ci + 1) * h * w];
        for (lo, out) in row.chunks_mut(wo).enumerate() {
            let ih = ((oh0 + lo) * sh + i * dh) as isize - pt as isize;
            if ih < 0 || ih >= h as isize {
                out.fill(0.0);
                continue;
            }
            let src = &plane[ih as usize * w..(ih as usize + 1) * w];
            // Every sw-th value of one input row, shifted, with zeros outside it.
            let off = (j * dw) as isize - pl as isize;
            let (c0, c1) = inside(off, sw, w, wo);
            out[..c0].fill(0.0);
            out[c1..].fill(0.0);
            if c0 == c1 {
                continue;
            }
            let s0 = ((c0 * sw) as isize + off) as usize;
            if sw == 1 {
                out[c0..c1].copy_from_slice(&src[s0..s0 + c1 - c0]);
            } else {
                for (o, s) in out[c0..c1].iter_mut().zip(src[s0..].iter().step_by(sw)) {
                    *o = *s;
                }
            }
        }
    });
}

/// The output columns `c0..c1` of a row whose column ow reads input column ow·sw + off:
/// those that land inside the row's `w` columns (an empty range if none do).
fn inside(off: isize, sw: usize, w: usize, wo: usize) -> (usize, usize) {
    let first = |x: isize| (x.max(0) as usize).div_ceil(sw).min(wo);
    let lo = first(-off);
    (lo, first(w as isize - off).max(lo))
}

/// The inverse of [`im2col`] for one image: adds the tile `col` (output rows oh0.., as many
/// as it holds) into `dxb` ([C_in, H, W]) at the positions im2col read them from. Each input
/// channel is one task, and within it the kernel offsets and rows run in order, so the sum
/// order is fixed.
pub(super) fn col2im(
    col: &[f32],
    [kh, kw]: [usize; 2],
    options: &ConvOptions<2>,
    [h, w]: [usize; 2],
    wo: usize,
    oh0: usize,
    dxb: &mut [f32],
) {
    let [sh, sw] = options.stride;
    let [dh, dw] = options.dilation;
    let [pt, pl] = options.padding_begin();
    let t = col.len() / (dxb.len() / (h * w) * kh * kw);
    dxb.par_chunks_mut(h * w)
        .enumerate()
        .for_each(|(ci, plane)| {
            for ij in 0..kh * kw {
                let (i, j) = (ij / kw, ij % kw);
                let row = &col[((ci * kh * kw) + ij) * t..][..t];
                for (lo, src) in row.chunks(wo).enumerate() {
                    let ih = ((oh0 + lo) * sh + i * dh) as isize - pt as isize;
                    if ih < 0 || ih >= h as isize {
                        continue;
                    }
                    let dst = &mut plane[ih as usize * w..(ih as usize + 1) * w];
                    // The columns lo..hi land on every sw-th value of the input row.
                    let off = (j * dw) as isize - pl as isize;
                    let (c0, c1) = inside(off, sw, w, wo);
                    if c0 == c1 {
                        continue;
                    }
                    let d0 = ((c0 * sw) as isize + off) as usize;
                    let dst = dst[d0..].iter_mut().step_by(sw);
                    for (d, s) in dst.zip(&src[c0..c1]) {
                        *d += s;
                    }
                }
            }
        });
}

/// Output rows per im2col tile: whole rows, about [`TILE_BYTES`].
pub(super) fn tile_rows(rows: usize, wo: usize, ho: usize) -> usize {
    (TILE_BYTES / 4 / rows.max(1) / wo.max(1)).clamp(1, ho.max(1))
}

/// Channels below which a layer stays on im2col: Winograd's GEMMs have K = c_in, too short
/// to pay for the transforms.
pub(super) const WINOGRAD_MIN_CHANNELS: usize = 16;
/// Output tiles (batch × tile rows × tile columns) below which a layer stays on im2col: the
/// filter transform (c_out·c_in·α² values) then costs as much as the GEMMs it saves
/// (Network-1's 8² and 16² levels at batch 4 are faster on im2col, `cargo bench --bench
/// train_ops`; its 32² level and up, and Network-2's residual blocks, on Winograd).
pub(super) const WINOGRAD_MIN_TILES: usize = 128;

/// Tiles per Winograd block below which a layer stays on im2col: wide layers (c_in + c_out
/// channels) fit few tiles in a block, and GEMMs that narrow re-pack the transformed filters
/// for every block (Network-2's merger down-sampling, 384 → 256 by polyphase: 16 tiles,
/// slower on Winograd; its first deconvolution 24 tiles and slower too; its second 32 tiles
/// and faster, `cargo bench --bench train_ops`).
pub(super) const WINOGRAD_MIN_BLOCK_TILES: usize = 32;

/// Whether a c_in → c_out convolution runs by [`direct`]: stride 1, no dilation, and at
/// most [`direct::MAX_BLOCK`] channels on one side (Network-2's output layer, 64 → 3), where
/// im2col's GEMM has M or N of a few channels.
pub(super) fn direct_for([cin, cout]: [usize; 2], options: &ConvOptions<2>) -> bool {
    options.stride == [1, 1] && options.dilation == [1, 1] && cin.min(cout) <= direct::MAX_BLOCK
}

/// The kernels of the input gradient's correlation: `wt` ([C_out, C_in, kh, kw]) turned
/// 180° with its channels swapped, as [C_in, C_out, kh, kw].
pub(super) fn flipped(wt: &[f32], [cout, cin, kh, kw]: [usize; 4]) -> Vec<f32> {
    (0..cin * cout * kh * kw)
        .map(|n| {
            let (ci, co, i, j) = (
                n / (cout * kh * kw),
                n / (kh * kw) % cout,
                n / kw % kh,
                n % kw,
            );
            wt[((co * cin + ci) * kh + kh - 1 - i) * kw + kw - 1 - j]
        })
        .collect()
}

/// [`super::set_winograd`]'s switch.
pub(in crate::kernels::conv) static WINOGRAD: std::sync::atomic::AtomicBool =
    std::sync::atomic::AtomicBool::new(true);

/// The Winograd transform for a c_in → c_out convolution with this kernel and `options`
/// onto `batch` planes of `out`: stride 1, no dilation, a square kernel
/// [`Winograd::for_kernel`] covers, and enough channels and tiles.
pub(super) fn winograd_for(
    [cin, cout]: [usize; 2],
    [kh, kw]: [usize; 2],
    options: &ConvOptions<2>,
    batch: usize,
    out: [usize; 2],
) -> Option<Winograd> {
    let plain = options.stride == [1, 1]
        && options.dilation == [1, 1]
        && kh == kw
        && WINOGRAD.load(std::sync::atomic::Ordering::Relaxed);
    let kind = Winograd::for_kernel(kh).filter(|_| plain)?;
    let m = kind.matrices().m;
    let tiles = batch * out[0].div_ceil(m) * out[1].div_ceil(m);
    let block_tiles = winograd::block_tiles(kind, cin + cout, out[1]);
    (cin.min(cout) >= WINOGRAD_MIN_CHANNELS
        && tiles >= WINOGRAD_MIN_TILES
        && block_tiles >= WINOGRAD_MIN_BLOCK_TILES)
        .then_some(kind)
}

/// A stride-2 convolution as a stride-1 one (polyphase): with the four phases of x
/// x_(py,px)[u, v] = x[2u + py − pt, 2v + px − pl] stacked as 4·c_in channels and the kernel
/// split the same way, W'[(py, px), i, j] = W[2i + py, 2j + px] (zero past the kernel), the
/// convolution is the stride-1 ⌈k/2⌉×⌈k/2⌉ one without padding over the phase planes:
/// y[oy, ox] = Σ W'[(py, px), i, j]·x_(py,px)[oy + i, ox + j]. A 5×5 stride-2 layer becomes a
/// 3×3 layer Winograd covers: F(4×4, 3×3) on 4·c_in channels takes 9 multiplies per output
/// and input channel against im2col's 25, and all three passes follow (the input gradient
/// gathers the phases back, the weight gradient drops the padded taps).
#[derive(Clone, Copy)]
pub(super) struct Polyphase {
    /// c_in, the original kernel size k and the phase kernel's ⌈k/2⌉.
    cin: usize,
    k: usize,
    kp: usize,
    /// The convolution's padding at the top and the left.
    pad: [usize; 2],
    /// The phase planes: the output plane grown by kp − 1.
    plane: [usize; 2],
}

/// The stride-1 options of [`Polyphase`]'s convolution: no padding.
pub(super) fn valid() -> ConvOptions<2> {
    ConvOptions::new([1, 1], [0, 0], [1, 1], 1)
}

/// The polyphase form of a stride-2 c_in → c_out convolution onto `out`, where its
/// stride-1 convolution runs by Winograd (otherwise im2col's fewer multiplies on the
/// original kernel win).
pub(super) fn polyphase_for(
    [cin, cout]: [usize; 2],
    [kh, kw]: [usize; 2],
    options: &ConvOptions<2>,
    batch: usize,
    out: [usize; 2],
) -> Option<Polyphase> {
    if options.stride != [2, 2] || options.dilation != [1, 1] || kh != kw {
        return None;
    }
    let kp = kh.div_ceil(2);
    winograd_for([4 * cin, cout], [kp, kp], &valid(), batch, out)?;
    Some(Polyphase {
        cin,
        k: kh,
        kp,
        pad: options.padding_begin(),
        plane: [out[0] + kp - 1, out[1] + kp - 1],
    })
}

impl Polyphase {
    /// The phases of `x` ([B, C_in, H, W]) as [B, 4·C_in, U, V], zero outside x.
    fn split_input(self, x: &[f32], [b, cin, h, w]: [usize; 4]) -> Vec<f32> {
        let [u, v] = self.plane;
        let [pt, pl] = self.pad;
        let mut xp = vec![0.0f32; b * 4 * cin * u * v];
        xp.par_chunks_mut(u * v).enumerate().for_each(|(n, dst)| {
            let (bi, p, c) = (n / (4 * cin), n / cin % 4, n % cin);
            let (py, px) = (p / 2, p % 2);
            let plane = &x[(bi * cin + c) * h * w..][..h * w];
            for (uu, row) in dst.chunks_exact_mut(v).enumerate() {
                let iy = (2 * uu + py).wrapping_sub(pt);
                if iy >= h {
                    continue;
                }
                let src = &plane[iy * w..][..w];
                for (vv, e) in row.iter_mut().enumerate() {
                    let ix = (2 * vv + px).wrapping_sub(pl);
                    if ix < w {
                        *e = src[ix];
                    }
                }
            }
        });
        xp
    }

    /// dL/dx ([B, C_in, H, W]) from the phases' gradient `dxp`: each element of x is in
    /// exactly one phase; the phases' padding is dropped.
    fn join_input_grad(self, dxp: &[f32], [b, cin, h, w]: [usize; 4]) -> Vec<f32> {
        let [u, v] = self.plane;
        let [pt, pl] = self.pad;
        let mut dx = vec![0.0f32; b * cin * h * w];
        dx.par_chunks_mut(h * w).enumerate().for_each(|(n, plane)| {
            let (bi, c) = (n / cin, n % cin);
            for (iy, row) in plane.chunks_exact_mut(w).enumerate() {
                let (uu, py) = ((iy + pt) / 2, (iy + pt) % 2);
                if uu >= u {
                    continue;
                }
                for (ix, e) in row.iter_mut().enumerate() {
                    let (vv, px) = ((ix + pl) / 2, (ix + pl) % 2);
                    if vv < v {
                        let ch = (bi * 4 + py * 2 + px) * cin + c;
                        *e = dxp[(ch * u + uu) * v + vv];
                    }
                }
            }
        });
        dx
    }

    /// W' ([C_out, 4·C_in, kp, kp]) of `wt` ([C_out, C_in, k, k]).
    fn split_weights(self, wt: &[f32], cout: usize) -> Vec<f32> {
        let (cin, k, kp) = (self.cin, self.k, self.kp);
        let mut wp = vec![0.0f32; cout * 4 * cin * kp * kp];
        for co in 0..cout {
            for p in 0..4 {
                for c in 0..cin {
                    for i in 0..kp {
                        for j in 0..kp {
                            let (ki, kj) = (2 * i + p / 2, 2 * j + p % 2);
                            if ki < k && kj < k {
                                wp[(((co * 4 + p) * cin + c) * kp + i) * kp + j] =
                                    wt[((co * cin + c) * k + ki) * k + kj];
                            }
                        }
                    }
                }
            }
        }
        wp
    }

    /// dL/dW ([C_out, C_in, k, k]) from W''s gradient: the padded taps are dropped.
    fn join_weight_grad(self, dwp: &[f32], cout: usize) -> Vec<f32> {
        let (cin, k, kp) = (self.cin, self.k, self.kp);
        let mut dw = vec![0.0f32; cout * cin * k * k];
        for co in 0..cout {
            for c in 0..cin {
                for ki in 0..k {
                    for kj in 0..k {
                        let p = (ki % 2) * 2 + kj % 2;
                        dw[((co * cin + c) * k + ki) * k + kj] =
                            dwp[(((co * 4 + p) * cin + c) * kp + ki / 2) * kp + kj / 2];
                    }
                }
            }
        }
        dw
    }
}

/// The (batch item, first output row) of every im2col tile in a fixed order, and the
/// largest tile's length (tile rows · wo).
pub(super) fn tiles([batch, ho, wo]: [usize; 3], rows: usize) -> (Vec<(usize, usize)>, usize) {
    let tile_rows = tile_rows(rows, wo, ho);
    let items = (0..batch)
        .flat_map(|b| (0..ho).step_by(tile_rows).map(move |oh0| (b, oh0)))
        .collect();
    (items, tile_rows * wo)
}

/// Rows of a tile starting at output row `oh0`, times wo.
pub(super) fn tile_len(oh0: usize, [ho, wo]: [usize; 2], max_len: usize) -> usize {
    max_len.min((ho - oh0) * wo)
}

/// Splits the tiles `items` into one contiguous run per rayon thread (fewer if there are
/// fewer tiles) and calls `f(run, parallel, col)` on the runs concurrently, each with its
/// own buffer of `col_len`. With several runs each GEMM runs on its
/// own thread (`parallel` false): one GEMM per thread beats splitting every GEMM across
/// threads for the narrow layers and the long-K weight gradient (BENCHMARKS.md). Only for
/// outputs whose every element one GEMM computes whole: gemm's result does not depend on
/// its parallelism, so neither the split nor the thread count changes a bit.
pub(super) fn par_runs(
    items: &[(usize, usize)],
    col_len: usize,
    f: impl Fn(&[(usize, usize)], bool, &mut [f32]) + Sync,
) {
    let n = rayon::current_num_threads().clamp(1, items.len().max(1));
    if n == 1 {
        return f(items, true, &mut vec![0.0f32; col_len]);
    }
    items
        .par_chunks(items.len().div_ceil(n))
        .for_each(|run| f(run, false, &mut vec![0.0f32; col_len]));
}

/// Calls `f(b, parallel, col)` for every batch item concurrently, each with its own buffer
/// of `col_len`; returns the results in item order. Each item's GEMMs run on its own thread
/// (`parallel` false) unless there are more threads than items. The items do not depend on
/// the thread count, so neither do the results.
pub(super) fn par_items<T: Send>(
    batch: usize,
    col_len: usize,
    f: impl Fn(usize, bool, &mut [f32]) -> T + Sync,
) -> Vec<T> {
    let parallel = rayon::current_num_threads() > batch;
    (0..batch)
        .into_par_iter()
        .map(|b| f(b, parallel, &mut vec![0.0f32; col_len]))
        .collect()
}

/// The forward convolution (no bias, one group) on row-major slices by the same im2col
/// tiles: Y_b[co, tile] = W[co, (ci, i, j)] · col; `x` is [B, C_in, H, W], `w` is
/// [C_out, C_in, kh, kw]; returns Y as [B, C_out, H_out, W_out].
pub fn forward_f32(
    x: &[f32],
    xs: [usize; 4],
    wt: &[f32],
    ws: [usize; 4],
    [ho, wo]: [usize; 2],
    options: &ConvOptions<2>,
) -> Vec<f32> {
    if direct_for([ws[1], ws[0]], options) {
        return direct::conv2d_f32(x, xs, wt, ws, [ho, wo], options.padding_begin());
    }
    if let Some(kind) = winograd_for([ws[1], ws[0]], [ws[2], ws[3]], options, xs[0], [ho, wo]) {
        let pad = options.padding_begin();
        return winograd::conv2d_f32(x, xs, wt, ws, [ho, wo], pad, kind);
    }
    if let Some(pp) = polyphase_for([ws[1], ws[0]], [ws[2], ws[3]], options, xs[0], [ho, wo]) {
        let (xp, wp) = (pp.split_input(x, xs), pp.split_weights(wt, ws[0]));
        let [u, v] = pp.plane;
        let (xps, wps) = ([xs[0], 4 * xs[1], u, v], [ws[0], 4 * ws[1], pp.kp, pp.kp]);
        return forward_f32(&xp, xps, &wp, wps, [ho, wo], &valid());
    }
    let [batch, cin, h, w] = xs;
    let [cout, _, kh, kw] = ws;
    let rows = cin * kh * kw;
    let p_all = ho * wo;
    let mut y = vec![0.0f32; batch * cout * p_all];
    if rows == 0 || p_all == 0 || cout == 0 {
        return y;
    }
    let (items, col_len) = tiles([batch, ho, wo], rows);
    let out = Shared(y.as_mut_ptr());
    par_runs(&items, rows * col_len, |run, parallel, col| {
        for &(b, oh0) in run {
            let xb = &x[b * cin * h * w..(b + 1) * cin * h * w];
            let t = tile_len(oh0, [ho, wo], col_len);
            let col = &mut col[..rows * t];
            im2col(xb, [cin, h, w], [kh, kw], options, wo, oh0, col);
            // SAFETY: all strides and extents index inside y's item b, `wt` and `col`;
            // each (b, oh0) is one run's, so no two runs write the same element of y.
            unsafe {
                matmul(
                    [cout, t, rows],
                    out.at(b * cout * p_all + oh0 * wo),
                    [1, p_all as isize],
                    false,
                    wt.as_ptr(),
                    [1, rows as isize],
                    col.as_ptr(),
                    [1, t as isize],
                    parallel,
                );
            }
        }
    });
    y
}

/// The kernel of [`weight_grad`] on row-major slices: `x` is [B, C_in, H, W], `dy` is
/// [B, C_out, H_out, W_out]; returns dW as [C_out, C_in, kh, kw].
pub fn weight_grad_f32(
    x: &[f32],
    xs: [usize; 4],
    dy: &[f32],
    ys: [usize; 4],
    k: [usize; 2],
    options: &ConvOptions<2>,
) -> Vec<f32> {
    let [batch, cin, h, w] = xs;
    let [_, cout, ho, wo] = ys;
    let [kh, kw] = k;
    if direct_for([cin, cout], options) {
        return direct::weight_grad_f32(x, xs, dy, ys, k, options.padding_begin());
    }
    if let Some(kind) = winograd_for([cin, cout], k, options, batch, [ho, wo]) {
        let pad = options.padding_begin();
        return winograd::weight_grad_f32(x, xs, dy, ys, pad, kind);
    }
    if let Some(pp) = polyphase_for([cin, cout], k, options, batch, [ho, wo]) {
        let [u, v] = pp.plane;
        let xp = pp.split_input(x, xs);
        let dwp = weight_grad_f32(&xp, [batch, 4 * cin, u, v], dy, ys, [pp.kp; 2], &valid());
        return pp.join_weight_grad(&dwp, cout);
    }
    let rows = cin * kh * kw;
    let p_all = ho * wo;
    if rows == 0 || p_all == 0 || cout == 0 {
        return vec![0.0f32; cout * rows];
    }
    let tile_rows = tile_rows(rows, wo, ho);
    let col_len = tile_rows * wo;
    // Each batch item sums its tiles into its own dW (K split by item: a GEMM per thread);
    // the items' sums are added in item order.
    let parts = par_items(batch, rows * col_len, |b, parallel, col| {
        let xb = &x[b * cin * h * w..(b + 1) * cin * h * w];
        let yb = &dy[b * cout * p_all..(b + 1) * cout * p_all];
        let mut dw = vec![0.0f32; cout * rows];
        for oh0 in (0..ho).step_by(tile_rows) {
            let t = tile_len(oh0, [ho, wo], col_len);
            let col = &mut col[..rows * t];
            im2col(xb, [cin, h, w], k, options, wo, oh0, col);
            // dW[co, r] (+)= Σ_p dY[co, oh0·wo + p] · col[r, p]: M = c_out, N = rows, K = t.
            // SAFETY: all strides and extents index inside `dw`, `yb` and `col`.
            unsafe {
                matmul(
                    [cout, rows, t],
                    dw.as_mut_ptr(),
                    [1, rows as isize],
                    oh0 > 0,
                    yb.as_ptr().add(oh0 * wo),
                    [1, p_all as isize],
                    col.as_ptr(),
                    [t as isize, 1],
                    parallel,
                );
            }
        }
        dw
    });
    let sum = |mut acc: Vec<f32>, part: Vec<f32>| {
        acc.iter_mut().zip(&part).for_each(|(d, p)| *d += p);
        acc
    };
    parts
        .into_iter()
        .reduce(sum)
        .unwrap_or_else(|| vec![0.0f32; cout * rows])
}

/// The kernel of [`input_grad`] on row-major slices: `dy` is [B, C_out, H_out, W_out], `wt`
/// is [C_out, C_in, kh, kw], `[h, w]` is x's plane; returns dX as [B, C_in, H, W]:
/// col = Wᵀ · dY_b per tile of output rows (M = c_in·kh·kw, N = the tile, K = c_out), then
/// [`col2im`].
pub fn input_grad_f32(
    dy: &[f32],
    ys: [usize; 4],
    wt: &[f32],
    ws: [usize; 4],
    [h, w]: [usize; 2],
    options: &ConvOptions<2>,
) -> Vec<f32> {
    let [batch, cout, ho, wo] = ys;
    let [_, cin, kh, kw] = ws;
    let [pt, pl] = options.padding_begin();
    // dX is the stride-1 correlation of dY with the kernels turned 180° and their channels
    // swapped, padded by k − 1 − p.
    let reach = pt < kh && pl < kw;
    let pad = [kh.wrapping_sub(1 + pt), kw.wrapping_sub(1 + pl)];
    if reach && direct_for([cout, cin], options) {
        let wf = flipped(wt, ws);
        return direct::conv2d_f32(dy, ys, &wf, [cin, cout, kh, kw], [h, w], pad);
    }
    if let Some(kind) =
        winograd_for([cout, cin], [kh, kw], options, batch, [h, w]).filter(|_| reach)
    {
        let wf = flipped(wt, ws);
        return winograd::conv2d_f32(dy, ys, &wf, [cin, cout, kh, kw], [h, w], pad, kind);
    }
    if let Some(pp) = polyphase_for([cin, cout], [kh, kw], options, batch, [ho, wo]) {
        let [u, v] = pp.plane;
        let wp = pp.split_weights(wt, cout);
        let wps = [cout, 4 * cin, pp.kp, pp.kp];
        let dxp = input_grad_f32(dy, ys, &wp, wps, [u, v], &valid());
        return pp.join_input_grad(&dxp, [batch, cin, h, w]);
    }
    let rows = cin * kh * kw;
    let p_all = ho * wo;
    let mut dx = vec![0.0f32; batch * cin * h * w];
    if rows == 0 || p_all == 0 || cout == 0 || h * w == 0 {
        return dx;
    }
    let tile_rows = tile_rows(rows, wo, ho);
    let col_len = tile_rows * wo;
    let out = Shared(dx.as_mut_ptr());
    // By batch item (the tiles of one item overlap in dx); within an item the tiles go in
    // order, so each element's sum order is fixed.
    par_items(batch, rows * col_len, |b, parallel, col| {
        let yb = &dy[b * cout * p_all..(b + 1) * cout * p_all];
        // SAFETY: item b's slice of dx is written by this item only.
        let dxb = unsafe { out.slice(b * cin * h * w, cin * h * w) };
        for oh0 in (0..ho).step_by(tile_rows) {
            let t = tile_len(oh0, [ho, wo], col_len);
            let col = &mut col[..rows * t];
            // col[r, p] = Σ_co W[co, r] · dY[co, oh0·wo + p].
            // SAFETY: all strides and extents index inside `col`, `wt` and `yb`.
            unsafe {
                matmul(
                    [rows, t, cout],
                    col.as_mut_ptr(),
                    [1, t as isize],
                    false,
                    wt.as_ptr(),
                    [rows as isize, 1],
                    yb.as_ptr().add(oh0 * wo),
                    [1, p_all as isize],
                    parallel,
                );
            }
            col2im(col, [kh, kw], options, [h, w], wo, oh0, dxb);
        }
    });
    dx
}
