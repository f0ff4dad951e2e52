//! Direct convolution for thin stride-1 layers on flex: those with at most
//! [`MAX_BLOCK`] channels on one side, such as Network-2's output layer (5×5, 64 → 3 at full
//! resolution). im2col + GEMM is a poor fit there: a GEMM with M = 3 runs at a fraction of the
//! machine's speed, and the im2col matrix (c_in·k² rows × the image) is 25× the input, copied
//! for every pass. Here each task holds a few zero-padded input rows and keeps, for
//! [`LANES`] output pixels of up to [`MAX_BLOCK`] output channels, the sums in registers
//! over every input channel and kernel tap (timings: `cargo bench --bench train_ops`). The
//! input gradient is the same kernel on the output gradient with the kernels turned 180° (`kernels::conv`); the weight gradient sums each (c_out, c_in, tap)
//! product over the batch and the image in `LANES` partial sums, added in lane order.
//! Every sum runs in a fixed order inside one task, so results do not depend on the thread
//! count.

use crate::kernels::par::{Shared, pad_rows, with_avx2};
use rayon::prelude::*;

/// Output pixels of one row computed together: the inner loops' vector width.
const LANES: usize = 16;
/// Output channels whose sums one pass over the input keeps in registers; layers with at
/// most this many channels on one side run here.
pub const MAX_BLOCK: usize = 4;
/// Bytes of the zero-padded input rows one forward task holds.
const ROWS_BYTES: usize = 256 << 10;

/// The stride-1, dilation-1 correlation (no bias, one group) of `x` ([B, C_in, H, W]) by `wt`
/// ([C_out, C_in, kh, kw]) with zero padding `[top, left]` (bottom and right follow from the
/// output size `[ho, wo]`); returns Y as [B, C_out, ho, wo].
pub fn conv2d_f32(
    x: &[f32],
    [batch, cin, h, w]: [usize; 4],
    wt: &[f32],
    [cout, wcin, kh, kw]: [usize; 4],
    [ho, wo]: [usize; 2],
    [pt, pl]: [usize; 2],
) -> Vec<f32> {
    assert_eq!(cin, wcin, "input channels of x and the kernels");
    let mut y = vec![0.0f32; batch * cout * ho * wo];
    if y.is_empty() || cin * kh * kw == 0 {
        return y;
    }
    // Padded rows: whole LANES chunks of output plus the kernel's reach.
    let wp = wo.next_multiple_of(LANES) + kw - 1;
    let rows = (ROWS_BYTES / 4 / (cin * wp))
        .saturating_sub(kh - 1)
        .clamp(1, ho);
    // Output channels in blocks of MAX_BLOCK; per block, its kernels packed tap by tap:
    // packed[(ci·kh + ky)·kw + kx][j] = wt[o0 + j, ci, ky, kx].
    let taps = cin * kh * kw;
    let blocks: Vec<(usize, Vec<f32>)> = (0..cout)
        .step_by(MAX_BLOCK)
        .map(|o0| {
            let n = MAX_BLOCK.min(cout - o0);
            let packed = (0..taps * n)
                .map(|i| wt[(o0 + i % n) * taps + i / n])
                .collect();
            (o0, packed)
        })
        .collect();
    let tasks: Vec<(usize, usize)> = (0..batch)
        .flat_map(|b| (0..ho).step_by(rows).map(move |r0| (b, r0)))
        .collect();
    let out = Shared(y.as_mut_ptr());
    tasks.into_par_iter().for_each(|(b, r0)| {
        let r1 = (r0 + rows).min(ho);
        let n_in = r1 - r0 + kh - 1;
        let mut buf = vec![0.0f32; cin * n_in * wp];
        for (ci, dst) in buf.chunks_exact_mut(n_in * wp).enumerate() {
            let plane = &x[(b * cin + ci) * h * w..][..h * w];
            pad_rows(plane, [h, w], [r0, pt, pl], wp, dst);
        }
        with_avx2(
            #[inline(always)]
            || {
                for (o0, packed) in &blocks {
                    let n = MAX_BLOCK.min(cout - o0);
                    for oy in r0..r1 {
                        for x0 in (0..wo).step_by(LANES) {
                            let inp = &buf[(oy - r0) * wp + x0..];
                            let geom = Geometry {
                                channel: n_in * wp,
                                row: wp,
                                cin,
                                kh,
                                kw,
                            };
                            let acc = block(n, inp, geom, packed);
                            let len = LANES.min(wo - x0);
                            for (j, a) in acc.iter().enumerate().take(n) {
                                let at = ((b * cout + o0 + j) * ho + oy) * wo + x0;
                                // SAFETY: (item b, channel o0 + j, row oy, columns x0..) is
                                // inside y, and row oy of item b is this task's only.
                                unsafe { out.slice(at, len) }.copy_from_slice(&a[..len]);
                            }
                        }
                    }
                }
            },
        );
    });
    y
}

/// Strides and extents of a task's padded input rows.
#[derive(Clone, Copy)]
struct Geometry {
    /// Elements between one input channel's rows and the next's.
    channel: usize,
    /// Elements between rows.
    row: usize,
    cin: usize,
    kh: usize,
    kw: usize,
}

/// [`sums`] for `n` ≤ [`MAX_BLOCK`] output channels, as a full block (rows ≥ n are zero).
#[inline(always)]
fn block(n: usize, inp: &[f32], g: Geometry, packed: &[f32]) -> [[f32; LANES]; MAX_BLOCK] {
    let mut full = [[0.0f32; LANES]; MAX_BLOCK];
    match n {
        1 => full[..1].copy_from_slice(&sums::<1>(inp, g, packed)),
        2 => full[..2].copy_from_slice(&sums::<2>(inp, g, packed)),
        3 => full[..3].copy_from_slice(&sums::<3>(inp, g, packed)),
        _ => full.copy_from_slice(&sums::<MAX_BLOCK>(inp, g, packed)),
    }
    full
}

/// For the LANES output pixels whose windows start at `inp`'s first element: Σ over input
/// channels and taps (in that order) of kernel × input, for N output channels at once.
#[inline(always)]
fn sums<const N: usize>(inp: &[f32], g: Geometry, packed: &[f32]) -> [[f32; LANES]; N] {
    let taps = g.cin * g.kh * g.kw;
    assert!(packed.len() >= taps * N, "one packed tap per (ci, ky, kx)");
    assert!(
        taps == 0 || inp.len() >= (g.cin - 1) * g.channel + (g.kh - 1) * g.row + g.kw - 1 + LANES,
        "the windows lie inside the padded rows"
    );
    let mut acc = [[0.0f32; LANES]; N];
    let (ip, kp) = (inp.as_ptr(), packed.as_ptr());
    let mut t = 0;
    for ci in 0..g.cin {
        for ky in 0..g.kh {
            for kx in 0..g.kw {
                // SAFETY: the asserts above bound every window and tap read here; the bounds
                // checks they replace kept the loop from vectorising fully.
                let (v, k) = unsafe {
                    (
                        &*(ip.add(ci * g.channel + ky * g.row + kx) as *const [f32; LANES]),
                        &*(kp.add(t * N) as *const [f32; N]),
                    )
                };
                t += 1;
                for (a, &kj) in acc.iter_mut().zip(k) {
                    for (al, &vl) in a.iter_mut().zip(v) {
                        *al += kj * vl;
                    }
                }
            }
        }
    }
    acc
}

/// dL/dW of [`conv2d_f32`] with the same padding, from its input `x` ([B, C_in, H, W]) and
/// output gradient `dy` ([B, C_out, ho, wo]); returns dW as [C_out, C_in, kh, kw]. One task
/// per input channel; each (c_out, tap) sums its products in LANES partial sums over the
/// batch items, rows and column chunks in order, then adds the lanes in order.
pub fn weight_grad_f32(
    x: &[f32],
    [batch, cin, h, w]: [usize; 4],
    dy: &[f32],
    [ybatch, cout, ho, wo]: [usize; 4],
    [kh, kw]: [usize; 2],
    [pt, pl]: [usize; 2],
) -> Vec<f32> {
    assert_eq!(batch, ybatch, "batch of x and dy");
    let mut dw = vec![0.0f32; cout * cin * kh * kw];
    if dw.is_empty() || batch * ho * wo == 0 {
        return dw;
    }
    let wr = wo.next_multiple_of(LANES);
    let wp = wr + kw - 1;
    let per_channel: Vec<Vec<f32>> = (0..cin)
        .into_par_iter()
        .map(|ci| {
            // The output gradient's rows for every c_out (zero past wo) and the kh input rows
            // one output row reads.
            let mut dyr = vec![0.0f32; cout * wr];
            let mut rows = vec![0.0f32; kh * wp];
            let mut acc = vec![[0.0f32; LANES]; cout * kh * kw];
            for b in 0..batch {
                let plane = &x[(b * cin + ci) * h * w..][..h * w];
                for oy in 0..ho {
                    for (co, dst) in dyr.chunks_exact_mut(wr).enumerate() {
                        dst[..wo].copy_from_slice(&dy[((b * cout + co) * ho + oy) * wo..][..wo]);
                    }
                    pad_rows(plane, [h, w], [oy, pt, pl], wp, &mut rows);
                    with_avx2(
                        #[inline(always)]
                        || {
                            for (co, d) in dyr.chunks_exact(wr).enumerate() {
                                for ky in 0..kh {
                                    for kx in 0..kw {
                                        let r = &rows[ky * wp + kx..][..wr];
                                        let mut a = acc[(co * kh + ky) * kw + kx];
                                        for (dc, rc) in
                                            d.chunks_exact(LANES).zip(r.chunks_exact(LANES))
                                        {
                                            for l in 0..LANES {
                                                a[l] += dc[l] * rc[l];
                                            }
                                        }
                                        acc[(co * kh + ky) * kw + kx] = a;
                                    }
                                }
                            }
                        },
                    );
                }
            }
            acc.iter().map(|a| a.iter().sum()).collect()
        })
        .collect();
    for (ci, sums) in per_channel.iter().enumerate() {
        for (co, s) in sums.chunks_exact(kh * kw).enumerate() {
            dw[(co * cin + ci) * kh * kw..][..kh * kw].copy_from_slice(s);
        }
    }
    dw
}
