//! 2D convolution for the networks' layers, faster on flex.
//!
//! Burn 0.22's default weight gradient (`burn-backend`'s `conv2d_weight_backward`, which flex
//! inherits) is itself a convolution: x with batch and channels swapped, by the output gradient
//! as a kernel as large as the image. On flex that becomes one GEMM per input channel with N =
//! kh·kw output columns (9 for a 3×3 kernel) that re-packs the whole output gradient each time,
//! so the weight gradient cost more than the forward pass (`cargo bench --bench train_ops`).
//! Here, on flex, it is the usual lowering instead: dW[co, (ci, i, j)] = Σ_b Σ_p dY_b[co, p] ·
//! col_b[(ci, i, j), p], one GEMM per batch item and tile of output rows (M = c_out,
//! N = c_in·kh·kw, K = the tile). The forward pass uses the same im2col tiles (Y_b = W · col,
//! written straight into the NCHW output, no NHWC round trip), and the input gradient runs them
//! backwards: col = Wᵀ · dY_b per tile, then col2im adds each column row into dX (flex's own
//! transposed convolution did the GEMM for the whole image and a scalar col2im). Sums run in a
//! fixed order (tiles and batch items in sequence, kernel offsets in order within a tile, the
//! GEMM splits its output, never its K), so results are bit-for-bit repeatable. Stride-1 3×3
//! and 5×5 layers with enough channels and tiles (`flex::winograd_for`) run all three
//! passes by Winograd instead (`kernels::winograd`), and stride-1 layers with at most 4 channels
//! on one side (`flex::direct_for`) by a direct convolution (`kernels::direct`).
//!
//! It is a Burn backend extension (`#[backend_extension]`) with a hand-written autodiff step;
//! other backends (tch, wgpu, cuda, ndarray) run Burn's conv2d unchanged. The kernels take flex
//! tensors and slices only, so they could be offered upstream as flex's `conv2d`,
//! `conv2d_x_backward` and `conv2d_weight_backward`.

use burn::nn::PaddingConfig2d;
use burn::nn::conv::{Conv2d, ConvTranspose2d};
use burn::tensor::Tensor;
use burn::tensor::ops::{ConvOptions, ConvTransposeOptions};

/// Whether flex's stride-1 3×3 and 5×5 convolutions use Winograd (`kernels::winograd`, the
/// default) or im2col; for benchmarks that compare the two in one process. Results differ in
/// rounding only.
#[cfg(feature = "flex")]
pub fn set_winograd(on: bool) {
    flex::WINOGRAD.store(on, std::sync::atomic::Ordering::Relaxed);
}

/// `conv.forward(x)`, through the kernels above when `x` lives on flex.
pub fn conv2d(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    let ((top, bottom), (left, right)) = match conv.padding {
        PaddingConfig2d::Valid => ((0, 0), (0, 0)),
        PaddingConfig2d::Explicit(top, left, bottom, right) => ((top, bottom), (left, right)),
        // `Same` depends on the input size; the networks do not use it.
        PaddingConfig2d::Same => return conv.forward(x),
    };
    let options = ConvOptions::new_with_padding(
        conv.stride,
        [(top, bottom), (left, right)],
        conv.dilation,
        conv.groups,
    );
    conv2d_op(
        x,
        conv.weight.val(),
        conv.bias.as_ref().map(|b| b.val()),
        options,
    )
}

/// `conv.forward(x)` for a transposed convolution, through the kernels above when `x` lives on
/// flex.
pub fn conv_transpose2d(conv: &ConvTranspose2d, x: Tensor<4>) -> Tensor<4> {
    conv_transpose2d_op(
        x,
        conv.weight.val(),
        conv.bias.as_ref().map(|b| b.val()),
        ConvTransposeOptions::new(
            conv.stride,
            conv.padding,
            conv.padding_out,
            conv.dilation,
            conv.groups,
        ),
    )
}

/// `burn::tensor::module::conv_transpose2d`, through the kernels above when `x` lives on flex
/// and the convolution has one group. A transposed convolution is a convolution's input
/// gradient, so it runs the same kernels with the roles swapped: forward = [`flex::input_grad`]'s
/// kernel, input gradient = the convolution's forward, weight gradient = the convolution's
/// weight gradient with x and dy exchanged (flex's own did the weight gradient as a
/// convolution as large as the image).
pub fn conv_transpose2d_op(
    x: Tensor<4>,
    weight: Tensor<4>,
    bias: Option<Tensor<1>>,
    options: ConvTransposeOptions<2>,
) -> Tensor<4> {
    #[cfg(feature = "flex")]
    if options.groups == 1 && crate::device::is_flex(&x.device()) {
        return with_bias(flex::conv_transpose2d(x, weight, options), bias);
    }
    burn::tensor::module::conv_transpose2d(x, weight, bias, options)
}

/// `burn::tensor::module::conv2d`, through the kernels above when `x` lives on flex and the
/// convolution has one group.
pub fn conv2d_op(
    x: Tensor<4>,
    weight: Tensor<4>,
    bias: Option<Tensor<1>>,
    options: ConvOptions<2>,
) -> Tensor<4> {
    #[cfg(feature = "flex")]
    if options.groups == 1 && crate::device::is_flex(&x.device()) {
        return with_bias(flex::conv2d(x, weight, options), bias);
    }
    burn::tensor::module::conv2d(x, weight, bias, options)
}

/// y + bias per output channel.
#[cfg(feature = "flex")]
fn with_bias(y: Tensor<4>, bias: Option<Tensor<1>>) -> Tensor<4> {
    match bias {
        Some(b) => {
            let c = b.dims()[0];
            y + b.reshape([1, c, 1, 1])
        }
        None => y,
    }
}

#[cfg(feature = "flex")]
pub(crate) mod flex {
    use burn::backend::autodiff::Autodiff;
    use burn::backend::autodiff::NodeId;
    use burn::backend::autodiff::checkpoint::base::Checkpointer;
    use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
    use burn::backend::autodiff::grads::Gradients;
    use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
    use burn::backend::ops::ModuleOps;
    use burn::backend::tensor::FloatTensor;
    use burn::backend::{Dispatch, Flex, TensorMetadata, backend_extension};
    use burn::tensor::ops::{ConvOptions, ConvTransposeOptions};
    use burn::tensor::{DType, Tensor};
    use rayon::prelude::*;

    use crate::kernels::direct;
    use crate::kernels::par::{Shared, flex_tensor, matmul};
    use crate::kernels::winograd::{self, Winograd};

    /// Conv2d without bias by [`forward`], whose autodiff step uses [`input_grad`] and
    /// [`weight_grad`].
    #[backend_extension(Flex, Autodiff)]
    pub trait FlexConv: burn::backend::Backend {
        fn conv2d_im2col(
            x: FloatTensor<Self>,
            weight: FloatTensor<Self>,
            options: ConvOptions<2>,
        ) -> FloatTensor<Self>;

        fn conv_transpose2d_im2col(
            x: FloatTensor<Self>,
            weight: FloatTensor<Self>,
            options: ConvTransposeOptions<2>,
        ) -> FloatTensor<Self>;
    }

    impl FlexConv for Flex {
        fn conv2d_im2col(
            x: FloatTensor<Self>,
            weight: FloatTensor<Self>,
            options: ConvOptions<2>,
        ) -> FloatTensor<Self> {
            forward(x, weight, options)
        }

        fn conv_transpose2d_im2col(
            x: FloatTensor<Self>,
            weight: FloatTensor<Self>,
            options: ConvTransposeOptions<2>,
        ) -> FloatTensor<Self> {
            transpose_forward(x, weight, options)
        }
    }

    impl<C: CheckpointStrategy> FlexConv for Autodiff<Flex, C> {
        fn conv2d_im2col(
            x: FloatTensor<Self>,
            weight: FloatTensor<Self>,
            options: ConvOptions<2>,
        ) -> FloatTensor<Self> {
            tracked::<C>(x, weight, Kind::Conv(options))
        }

        fn conv_transpose2d_im2col(
            x: FloatTensor<Self>,
            weight: FloatTensor<Self>,
            options: ConvTransposeOptions<2>,
        ) -> FloatTensor<Self> {
            tracked::<C>(x, weight, Kind::Transposed(options))
        }
    }

    /// Which convolution an autodiff step runs and differentiates.
    #[derive(Clone, Debug)]
    enum Kind {
        Conv(ConvOptions<2>),
        Transposed(ConvTransposeOptions<2>),
    }

    impl Kind {
        fn forward(&self, x: FloatTensor<Flex>, weight: FloatTensor<Flex>) -> FloatTensor<Flex> {
            match self {
                Kind::Conv(o) => forward(x, weight, o.clone()),
                Kind::Transposed(o) => transpose_forward(x, weight, o.clone()),
            }
        }

        fn input_grad(
            &self,
            x: FloatTensor<Flex>,
            weight: FloatTensor<Flex>,
            dy: FloatTensor<Flex>,
        ) -> FloatTensor<Flex> {
            match self {
                Kind::Conv(o) => input_grad(x, weight, dy, o.clone()),
                Kind::Transposed(o) => transpose_input_grad(x, weight, dy, o.clone()),
            }
        }

        fn weight_grad(
            &self,
            x: FloatTensor<Flex>,
            weight: FloatTensor<Flex>,
            dy: FloatTensor<Flex>,
        ) -> FloatTensor<Flex> {
            match self {
                Kind::Conv(o) => weight_grad(x, weight, dy, o.clone()),
                Kind::Transposed(o) => transpose_weight_grad(x, weight, dy, o.clone()),
            }
        }
    }

    #[derive(Debug)]
    struct Im2colConv;

    impl Backward<Flex, 2> for Im2colConv {
        type State = (NodeId, NodeId, Kind);

        fn backward(
            self,
            ops: Ops<Self::State, 2>,
            grads: &mut Gradients,
            checkpointer: &mut Checkpointer,
        ) {
            let [node_x, node_weight] = ops.parents;
            let grad = grads.consume::<Flex>(&ops.node);
            let (x_state, weight_state, kind) = ops.state;
            let x = checkpointer.retrieve_node_output::<FloatTensor<Flex>>(x_state);
            let weight = checkpointer.retrieve_node_output::<FloatTensor<Flex>>(weight_state);
            if let Some(node) = node_x {
                let g = kind.input_grad(x.clone(), weight.clone(), grad.clone());
                grads.register::<Flex>(node.id, g);
            }
            if let Some(node) = node_weight {
                grads.register::<Flex>(node.id, kind.weight_grad(x, weight, grad));
            }
        }
    }

    /// `kind`'s forward on an autodiff device, recording [`Im2colConv`]'s step when x or the
    /// weight is tracked.
    fn tracked<C: CheckpointStrategy>(
        x: FloatTensor<Autodiff<Flex, C>>,
        weight: FloatTensor<Autodiff<Flex, C>>,
        kind: Kind,
    ) -> FloatTensor<Autodiff<Flex, C>> {
        match Im2colConv
            .prepare::<C>([x.node(), weight.node()])
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(mut prep) => {
                let x_state = prep.checkpoint(&x);
                let weight_state = prep.checkpoint(&weight);
                let y = kind.forward(x.into_primitive(), weight.into_primitive());
                prep.finish((x_state, weight_state, kind), y)
            }
            OpsKind::UnTracked(prep) => {
                prep.finish(kind.forward(x.into_primitive(), weight.into_primitive()))
            }
        }
    }

    pub(super) fn conv2d(x: Tensor<4>, weight: Tensor<4>, options: ConvOptions<2>) -> Tensor<4> {
        Tensor::from_dispatch(<Dispatch as FlexConv>::conv2d_im2col(
            x.into_dispatch(),
            weight.into_dispatch(),
            options,
        ))
    }

    pub(super) fn conv_transpose2d(
        x: Tensor<4>,
        weight: Tensor<4>,
        options: ConvTransposeOptions<2>,
    ) -> Tensor<4> {
        Tensor::from_dispatch(<Dispatch as FlexConv>::conv_transpose2d_im2col(
            x.into_dispatch(),
            weight.into_dispatch(),
            options,
        ))
    }

    /// The convolution whose input gradient the transposed convolution `options` is: same
    /// stride, padding and dilation, from the transposed output's plane to its input's.
    fn transposed(options: &ConvTransposeOptions<2>) -> ConvOptions<2> {
        ConvOptions::new(options.stride, options.padding, options.dilation, 1)
    }

    fn all_f32(tensors: &[&FloatTensor<Flex>]) -> bool {
        tensors.iter().all(|t| t.dtype() == DType::F32)
    }

    /// `Flex::conv_transpose2d(x, weight, None, options)`: x [B, C_in, H, W], weight
    /// [C_in, C_out, kh, kw] → [B, C_out, H_out, W_out] by [`input_grad_f32`] (x as the
    /// output gradient of the convolution [`transposed`]); flex's own for other dtypes and
    /// grouped convolutions.
    pub fn transpose_forward(
        x: FloatTensor<Flex>,
        weight: FloatTensor<Flex>,
        options: ConvTransposeOptions<2>,
    ) -> FloatTensor<Flex> {
        if !all_f32(&[&x, &weight]) || options.groups != 1 {
            return Flex::conv_transpose2d(x, weight, None, options);
        }
        let xs: [usize; 4] = x.shape().dims();
        let ws: [usize; 4] = weight.shape().dims();
        let out = |i: usize| {
            ((xs[2 + i].max(1) - 1) * options.stride[i]
                + options.dilation[i] * (ws[2 + i].max(1) - 1)
                + options.padding_out[i]
                + 1)
            .saturating_sub(2 * options.padding[i])
        };
        let (ho, wo) = (out(0), out(1));
        let (x, weight) = (x.to_contiguous(), weight.to_contiguous());
        let y = input_grad_f32(
            x.storage::<f32>(),
            xs,
            weight.storage::<f32>(),
            ws,
            [ho, wo],
            &transposed(&options),
        );
        flex_tensor(y, [xs[0], ws[1], ho, wo])
    }

    /// dL/dx of [`transpose_forward`]: the convolution [`transposed`] of the output gradient.
    fn transpose_input_grad(
        x: FloatTensor<Flex>,
        weight: FloatTensor<Flex>,
        dy: FloatTensor<Flex>,
        options: ConvTransposeOptions<2>,
    ) -> FloatTensor<Flex> {
        if !all_f32(&[&weight, &dy]) || options.groups != 1 {
            return Flex::conv_transpose2d_x_backward(weight, dy, options);
        }
        let xs: [usize; 4] = x.shape().dims();
        let (weight, dy) = (weight.to_contiguous(), dy.to_contiguous());
        let dx = forward_f32(
            dy.storage::<f32>(),
            dy.shape().dims(),
            weight.storage::<f32>(),
            weight.shape().dims(),
            [xs[2], xs[3]],
            &transposed(&options),
        );
        flex_tensor(dx, xs)
    }

    /// dL/dW of [`transpose_forward`]: the weight gradient of the convolution [`transposed`]
    /// with the output gradient as its input and x as its output gradient.
    fn transpose_weight_grad(
        x: FloatTensor<Flex>,
        weight: FloatTensor<Flex>,
        dy: FloatTensor<Flex>,
        options: ConvTransposeOptions<2>,
    ) -> FloatTensor<Flex> {
        if !all_f32(&[&x, &dy]) || options.groups != 1 {
            return Flex::conv_transpose2d_weight_backward(x, weight, dy, options);
        }
        let ws: [usize; 4] = weight.shape().dims();
        let (x, dy) = (x.to_contiguous(), dy.to_contiguous());
        let dw = weight_grad_f32(
            dy.storage::<f32>(),
            dy.shape().dims(),
            x.storage::<f32>(),
            x.shape().dims(),
            [ws[2], ws[3]],
            &transposed(&options),
        );
        flex_tensor(dw, ws)
    }

    /// `Flex::conv2d(x, weight, None, options)` by [`forward_f32`]; flex's own for other dtypes
    /// and grouped convolutions.
    pub fn forward(
        x: FloatTensor<Flex>,
        weight: FloatTensor<Flex>,
        options: ConvOptions<2>,
    ) -> FloatTensor<Flex> {
        if x.dtype() != DType::F32 || weight.dtype() != DType::F32 || options.groups != 1 {
            return Flex::conv2d(x, weight, None, options);
        }
        let xs: [usize; 4] = x.shape().dims();
        let ws: [usize; 4] = weight.shape().dims();
        let out = |i: usize| {
            let (begin, end) = options.padding[i];
            let span = options.dilation[i] * (ws[2 + i] - 1) + 1;
            (xs[2 + i] + begin + end).saturating_sub(span) / options.stride[i] + 1
        };
        let (ho, wo) = (out(0), out(1));
        let (x, weight) = (x.to_contiguous(), weight.to_contiguous());
        let y = forward_f32(
            x.storage::<f32>(),
            xs,
            weight.storage::<f32>(),
            ws,
            [ho, wo],
            &options,
        );
        flex_tensor(y, [xs[0], ws[0], ho, wo])
    }

    /// Bytes of one im2col tile (c_in·kh·kw rows × tile columns): small enough to stay in L2/L3
    /// while the GEMM packs it, large enough for a K dimension of thousands on the networks'
    /// layers.
    const TILE_BYTES: usize = 8 << 20;

    /// dL/dW of `conv2d(x, weight)` (no groups) from the output gradient `dy`, by im2col + GEMM.
    /// Falls back to flex's own weight gradient for other dtypes and grouped convolutions.
    pub fn weight_grad(
        x: FloatTensor<Flex>,
        weight: FloatTensor<Flex>,
        dy: FloatTensor<Flex>,
        options: ConvOptions<2>,
    ) -> FloatTensor<Flex> {
        if x.dtype() != DType::F32 || dy.dtype() != DType::F32 || options.groups != 1 {
            return Flex::conv2d_weight_backward(x, weight, dy, options);
        }
        let ws: [usize; 4] = weight.shape().dims();
        let xs: [usize; 4] = x.shape().dims();
        let ys: [usize; 4] = dy.shape().dims();
        let x = x.to_contiguous();
        let dy = dy.to_contiguous();
        let out = weight_grad_f32(
            x.storage::<f32>(),
            xs,
            dy.storage::<f32>(),
            ys,
            [ws[2], ws[3]],
            &options,
        );
        flex_tensor(out, ws)
    }

    /// dL/dx of `conv2d(x, weight)` (no groups) from the output gradient `dy`, by GEMM + col2im
    /// per tile. Falls back to flex's own input gradient for other dtypes and grouped
    /// convolutions.
    pub fn input_grad(
        x: FloatTensor<Flex>,
        weight: FloatTensor<Flex>,
        dy: FloatTensor<Flex>,
        options: ConvOptions<2>,
    ) -> FloatTensor<Flex> {
        if weight.dtype() != DType::F32 || dy.dtype() != DType::F32 || options.groups != 1 {
            return Flex::conv2d_x_backward(x, weight, dy, options);
        }
        let xs: [usize; 4] = x.shape().dims();
        let ws: [usize; 4] = weight.shape().dims();
        let ys: [usize; 4] = dy.shape().dims();
        let (weight, dy) = (weight.to_contiguous(), dy.to_contiguous());
        let dx = input_grad_f32(
            dy.storage::<f32>(),
            ys,
            weight.storage::<f32>(),
            ws,
            [xs[2], xs[3]],
            &options,
        );
        flex_tensor(dx, xs)
    }

    /// One tile of the im2col matrix of one image `xb` ([C_in, H, W]): output rows oh0.. (as many
    /// as `col` holds, `col.len() / (C_in·kh·kw·wo)`), each of `wo` columns:
    /// col[(ci, i, j), (oh, ow)] = x[ci, oh·sh + i·dh − pt, ow·sw + j·dw − pl], or 0 outside x.
    fn im2col(
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
                if sw == 1 {
                    // A shifted copy of one input row with zeros outside it.
                    let off = (j * dw) as isize - pl as isize;
                    let lo = (-off).clamp(0, wo as isize) as usize;
                    let hi = (w as isize - off).clamp(lo as isize, wo as isize) as usize;
                    out[..lo].fill(0.0);
                    let s0 = (lo as isize + off) as usize;
                    out[lo..hi].copy_from_slice(&src[s0..s0 + hi - lo]);
                    out[hi..].fill(0.0);
                    continue;
                }
                for (ow, v) in out.iter_mut().enumerate() {
                    let iw = (ow * sw + j * dw) as isize - pl as isize;
                    *v = if iw >= 0 && iw < w as isize {
                        src[iw as usize]
                    } else {
                        0.0
                    };
                }
            }
        });
    }

    /// The inverse of [`im2col`] for one image: adds the tile `col` (output rows oh0.., as many
    /// as it holds) into `dxb` ([C_in, H, W]) at the positions im2col read them from. Each input
    /// channel is one task, and within it the kernel offsets and rows run in order, so the sum
    /// order is fixed.
    fn col2im(
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
                        let off = (j * dw) as isize - pl as isize;
                        if sw == 1 {
                            // The columns lo..hi land on one contiguous run of the input row.
                            let lo = (-off).clamp(0, wo as isize) as usize;
                            let hi = (w as isize - off).clamp(lo as isize, wo as isize) as usize;
                            let d0 = (lo as isize + off) as usize;
                            for (d, s) in dst[d0..d0 + hi - lo].iter_mut().zip(&src[lo..hi]) {
                                *d += s;
                            }
                            continue;
                        }
                        for (ow, s) in src.iter().enumerate() {
                            let iw = (ow * sw) as isize + off;
                            if iw >= 0 && iw < w as isize {
                                dst[iw as usize] += s;
                            }
                        }
                    }
                }
            });
    }

    /// Output rows per im2col tile: whole rows, about [`TILE_BYTES`].
    fn tile_rows(rows: usize, wo: usize, ho: usize) -> usize {
        (TILE_BYTES / 4 / rows.max(1) / wo.max(1)).clamp(1, ho.max(1))
    }

    /// Channels below which a layer stays on im2col: Winograd's GEMMs have K = c_in, too short
    /// to pay for the transforms.
    const WINOGRAD_MIN_CHANNELS: usize = 16;
    /// Output tiles (batch × tile rows × tile columns) below which a layer stays on im2col: the
    /// filter transform (c_out·c_in·α² values) then costs as much as the GEMMs it saves
    /// (Network-1's 8² and 16² levels at batch 4 are faster on im2col, `cargo bench --bench
    /// train_ops`; its 32² level and up, and Network-2's residual blocks, on Winograd).
    const WINOGRAD_MIN_TILES: usize = 128;

    /// Tiles per Winograd block below which a layer stays on im2col: wide layers (c_in + c_out
    /// channels) fit few tiles in a block, and GEMMs that narrow re-pack the transformed filters
    /// for every block (Network-2's merger down-sampling, 384 → 256 by polyphase: 16 tiles,
    /// slower on Winograd; its first deconvolution 24 tiles and slower too; its second 32 tiles
    /// and faster, `cargo bench --bench train_ops`).
    const WINOGRAD_MIN_BLOCK_TILES: usize = 32;

    /// Whether a c_in → c_out convolution runs by [`direct`]: stride 1, no dilation, and at
    /// most [`direct::MAX_BLOCK`] channels on one side (Network-2's output layer, 64 → 3), where
    /// im2col's GEMM has M or N of a few channels.
    fn direct_for([cin, cout]: [usize; 2], options: &ConvOptions<2>) -> bool {
        options.stride == [1, 1] && options.dilation == [1, 1] && cin.min(cout) <= direct::MAX_BLOCK
    }

    /// The kernels of the input gradient's correlation: `wt` ([C_out, C_in, kh, kw]) turned
    /// 180° with its channels swapped, as [C_in, C_out, kh, kw].
    fn flipped(wt: &[f32], [cout, cin, kh, kw]: [usize; 4]) -> Vec<f32> {
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
    pub(super) static WINOGRAD: std::sync::atomic::AtomicBool =
        std::sync::atomic::AtomicBool::new(true);

    /// The Winograd transform for a c_in → c_out convolution with this kernel and `options`
    /// onto `batch` planes of `out`: stride 1, no dilation, a square kernel
    /// [`Winograd::for_kernel`] covers, and enough channels and tiles.
    fn winograd_for(
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
    struct Polyphase {
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
    fn valid() -> ConvOptions<2> {
        ConvOptions::new([1, 1], [0, 0], [1, 1], 1)
    }

    /// The polyphase form of a stride-2 c_in → c_out convolution onto `out`, where its
    /// stride-1 convolution runs by Winograd (otherwise im2col's fewer multiplies on the
    /// original kernel win).
    fn polyphase_for(
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
    fn tiles([batch, ho, wo]: [usize; 3], rows: usize) -> (Vec<(usize, usize)>, usize) {
        let tile_rows = tile_rows(rows, wo, ho);
        let items = (0..batch)
            .flat_map(|b| (0..ho).step_by(tile_rows).map(move |oh0| (b, oh0)))
            .collect();
        (items, tile_rows * wo)
    }

    /// Rows of a tile starting at output row `oh0`, times wo.
    fn tile_len(oh0: usize, [ho, wo]: [usize; 2], max_len: usize) -> usize {
        max_len.min((ho - oh0) * wo)
    }

    /// Splits the tiles `items` into one contiguous run per rayon thread (fewer if there are
    /// fewer tiles) and calls `f(run, parallel, col)` on the runs concurrently, each with its
    /// own buffer of `col_len`. With several runs each GEMM runs on its
    /// own thread (`parallel` false): one GEMM per thread beats splitting every GEMM across
    /// threads for the narrow layers and the long-K weight gradient (BENCHMARKS.md). Only for
    /// outputs whose every element one GEMM computes whole: gemm's result does not depend on
    /// its parallelism, so neither the split nor the thread count changes a bit.
    fn par_runs(
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
    fn par_items<T: Send>(
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
}
