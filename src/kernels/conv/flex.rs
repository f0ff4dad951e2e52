//! The flex kernels of the convolutions: the backend extension and its autodiff step, and
//! the dispatch to im2col + GEMM, Winograd or the direct convolution.

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

mod lowering;
pub(super) use lowering::WINOGRAD;
use lowering::*;

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
