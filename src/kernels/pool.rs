//! Max-pooling for Network-1's encoder (2×2, stride 2).
//!
//! On flex the 2×2 stride-2 case is one op with its own autodiff step: flex's
//! max-pool goes through its general 3-D kernel (a window loop per output with i64 indices, then
//! a backward that scatters through them). Here the forward pass
//! keeps, per output, which of its four inputs won (one byte), and the backward writes each
//! gradient there. The winner is flex's: the first maximum in row-major order, a NaN wherever
//! the window holds one (the last), so values and gradients have the same bits as flex's.

use burn::nn::PaddingConfig2d;
use burn::nn::pool::MaxPool2d;
use burn::tensor::Tensor;

/// `pool.forward(x)`, through the op above when `x` lives on flex and the pool is 2×2 with
/// stride 2, no padding or dilation, and floor rounding.
pub fn max_pool2d(pool: &MaxPool2d, x: Tensor<4>) -> Tensor<4> {
    #[cfg(feature = "flex")]
    if pool.kernel_size == [2, 2]
        && pool.stride == [2, 2]
        && pool.dilation == [1, 1]
        && !pool.ceil_mode
        && matches!(pool.padding, PaddingConfig2d::Valid)
        && crate::device::is_flex(&x.device())
        && x.dtype() == burn::tensor::DType::F32
    {
        return flex::max_pool_2x2(x);
    }
    pool.forward(x)
}

#[cfg(feature = "flex")]
mod flex {
    use burn::backend::autodiff::Autodiff;
    use burn::backend::autodiff::checkpoint::base::Checkpointer;
    use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
    use burn::backend::autodiff::grads::Gradients;
    use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
    use burn::backend::tensor::FloatTensor;
    use burn::backend::{Dispatch, Flex, TensorMetadata, backend_extension};
    use burn::tensor::Tensor;
    use rayon::prelude::*;
    use std::sync::Arc;

    use crate::kernels::par::{flex_tensor, unary_backward};

    /// 2×2 stride-2 max-pool by [`forward`]; its autodiff step runs [`backward`].
    #[backend_extension(Flex, Autodiff)]
    pub trait FlexMaxPool: burn::backend::Backend {
        fn max_pool_2x2_fused(x: FloatTensor<Self>) -> FloatTensor<Self>;
    }

    impl FlexMaxPool for Flex {
        fn max_pool_2x2_fused(x: FloatTensor<Self>) -> FloatTensor<Self> {
            forward(x).0
        }
    }

    #[derive(Debug)]
    struct MaxPool;

    impl Backward<Flex, 1> for MaxPool {
        /// The input's shape and each output's winner (0..4, row-major in its window).
        type State = ([usize; 4], Arc<[u8]>);

        fn backward(
            self,
            ops: Ops<Self::State, 1>,
            grads: &mut Gradients,
            _checkpointer: &mut Checkpointer,
        ) {
            unary_backward(ops, grads, |grad, (xs, winners)| {
                backward(grad, xs, &winners)
            });
        }
    }

    impl<C: CheckpointStrategy> FlexMaxPool for Autodiff<Flex, C> {
        fn max_pool_2x2_fused(x: FloatTensor<Self>) -> FloatTensor<Self> {
            match MaxPool.prepare::<C>([x.node()]).compute_bound().stateful() {
                OpsKind::Tracked(prep) => {
                    let xs: [usize; 4] = x.shape().dims();
                    let (y, winners) = forward(x.into_primitive());
                    prep.finish((xs, winners.into()), y)
                }
                OpsKind::UnTracked(prep) => prep.finish(forward(x.into_primitive()).0),
            }
        }
    }

    pub(super) fn max_pool_2x2(x: Tensor<4>) -> Tensor<4> {
        Tensor::from_dispatch(<Dispatch as FlexMaxPool>::max_pool_2x2_fused(
            x.into_dispatch(),
        ))
    }

    /// The pooled tensor and each output's winner.
    fn forward(x: FloatTensor<Flex>) -> (FloatTensor<Flex>, Vec<u8>) {
        let xs: [usize; 4] = x.shape().dims();
        let x = x.to_contiguous();
        let (y, winners) = forward_f32(x.storage::<f32>(), xs);
        (
            flex_tensor(y, [xs[0], xs[1], xs[2] / 2, xs[3] / 2]),
            winners,
        )
    }

    /// Per output of each plane of `x` ([B, C, H, W]; a last odd row or column is dropped): the
    /// maximum of its 2×2 window and which input it is; one task per plane.
    pub fn forward_f32(x: &[f32], [b, c, h, w]: [usize; 4]) -> (Vec<f32>, Vec<u8>) {
        let (ho, wo) = (h / 2, w / 2);
        let mut y = vec![0.0f32; b * c * ho * wo];
        let mut winners = vec![0u8; b * c * ho * wo];
        if y.is_empty() {
            return (y, winners);
        }
        y.par_chunks_mut(ho * wo)
            .zip(winners.par_chunks_mut(ho * wo))
            .zip(x.par_chunks(h * w))
            .for_each(|((out, win), plane)| {
                for oy in 0..ho {
                    let (r0, r1) = (&plane[2 * oy * w..][..w], &plane[(2 * oy + 1) * w..][..w]);
                    for ox in 0..wo {
                        let window = [r0[2 * ox], r0[2 * ox + 1], r1[2 * ox], r1[2 * ox + 1]];
                        let (mut m, mut k) = (window[0], 0);
                        for (i, &v) in window.iter().enumerate().skip(1) {
                            // As flex: a strictly larger value, or any NaN, takes over.
                            if v > m || v.is_nan() {
                                (m, k) = (v, i);
                            }
                        }
                        out[oy * wo + ox] = m;
                        win[oy * wo + ox] = k as u8;
                    }
                }
            });
        (y, winners)
    }

    /// dL/dx of [`forward`]: each output's gradient at its winner, zero elsewhere.
    fn backward(dy: FloatTensor<Flex>, xs: [usize; 4], winners: &[u8]) -> FloatTensor<Flex> {
        let dy = dy.to_contiguous();
        flex_tensor(backward_f32(dy.storage::<f32>(), xs, winners), xs)
    }

    pub fn backward_f32(dy: &[f32], [b, c, h, w]: [usize; 4], winners: &[u8]) -> Vec<f32> {
        let (ho, wo) = (h / 2, w / 2);
        let mut dx = vec![0.0f32; b * c * h * w];
        if ho * wo == 0 {
            return dx;
        }
        dx.par_chunks_mut(h * w)
            .zip(dy.par_chunks(ho * wo).zip(winners.par_chunks(ho * wo)))
            .for_each(|(plane, (grad, win))| {
                for (i, (&g, &k)) in grad.iter().zip(win).enumerate() {
                    let (oy, ox, k) = (i / wo, i % wo, k as usize);
                    plane[(2 * oy + k / 2) * w + 2 * ox + k % 2] = g;
                }
            });
        dx
    }
}
