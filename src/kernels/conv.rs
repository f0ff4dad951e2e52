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
pub(crate) mod flex;
