//! Reflection padding of the last two axes (Network-2's 'SAME' convolutions, TensorFlow's
//! `REFLECT`, PyTorch's `ReflectionPad2d`: the edge sample is not repeated). Where a pad reaches
//! as far as the axis is long (which TensorFlow rejects) the reflection continues periodically
//! (period 2(n − 1)); an axis of length 1 is replicated.
//!
//! On flex it is one op with its own autodiff step: Burn's `pad` builds the padded
//! tensor from slices, and its gradient from zeroed tensors and slice assignments. Here the forward pass
//! copies each plane once through the two axes' index maps, and the backward pass adds each
//! output gradient element into the input element it came from, in a fixed order (rows in
//! sequence; within a row the interior, then the borders; one task per plane), so results do
//! not depend on the thread count.

use burn::tensor::ops::PadMode;
use burn::tensor::{Device, Int, Tensor, TensorData};

/// `x` ([B, C, H, W]) padded by reflection: (top, bottom) rows and (left, right) columns.
pub fn reflect_pad(
    x: Tensor<4>,
    (top, bottom): (usize, usize),
    (left, right): (usize, usize),
) -> Tensor<4> {
    let [_, _, h, w] = x.dims();
    if top + bottom + left + right == 0 {
        return x;
    }
    #[cfg(feature = "flex")]
    if crate::device::is_flex(&x.device()) && x.dtype() == burn::tensor::DType::F32 && h * w > 0 {
        return flex::reflect_pad(x, [top, bottom, left, right]);
    }
    if top < h && bottom < h && left < w && right < w {
        return x.pad([(top, bottom), (left, right)], PadMode::Reflect);
    }
    let device = x.device();
    let x = if top + bottom > 0 {
        x.select(2, indices(h, top, bottom, &device))
    } else {
        x
    };
    if left + right > 0 {
        x.select(3, indices(w, left, right, &device))
    } else {
        x
    }
}

/// The source index of each of the `before + n + after` padded positions along an axis of
/// length `n` ≥ 1.
fn source_indices(n: usize, before: usize, after: usize) -> Vec<usize> {
    let len = n + before + after;
    if n == 1 {
        return vec![0; len];
    }
    let period = 2 * (n as i64 - 1);
    (0..len)
        .map(|j| {
            let m = (j as i64 - before as i64).rem_euclid(period);
            (if m < n as i64 { m } else { period - m }) as usize
        })
        .collect()
}

fn indices(n: usize, before: usize, after: usize, device: &Device) -> Tensor<1, Int> {
    let idx: Vec<i64> = source_indices(n, before, after)
        .into_iter()
        .map(|i| i as i64)
        .collect();
    let len = idx.len();
    Tensor::from_data(TensorData::new(idx, [len]), device)
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

    use super::source_indices;
    use crate::kernels::par::{flex_tensor, unary_backward};

    /// Pads as [`super::reflect_pad`] by [`forward`]; its autodiff step runs [`backward`].
    #[backend_extension(Flex, Autodiff)]
    pub trait FlexReflectPad: burn::backend::Backend {
        /// `pad` = [top, bottom, left, right].
        fn reflect_pad_fused(x: FloatTensor<Self>, pad: [usize; 4]) -> FloatTensor<Self>;
    }

    impl FlexReflectPad for Flex {
        fn reflect_pad_fused(x: FloatTensor<Self>, pad: [usize; 4]) -> FloatTensor<Self> {
            forward(x, pad)
        }
    }

    #[derive(Debug)]
    struct ReflectPad;

    impl Backward<Flex, 1> for ReflectPad {
        /// The input's shape and the padding.
        type State = ([usize; 4], [usize; 4]);

        fn backward(
            self,
            ops: Ops<Self::State, 1>,
            grads: &mut Gradients,
            _checkpointer: &mut Checkpointer,
        ) {
            unary_backward(ops, grads, |grad, (xs, pad)| backward(grad, xs, pad));
        }
    }

    impl<C: CheckpointStrategy> FlexReflectPad for Autodiff<Flex, C> {
        fn reflect_pad_fused(x: FloatTensor<Self>, pad: [usize; 4]) -> FloatTensor<Self> {
            match ReflectPad
                .prepare::<C>([x.node()])
                .compute_bound()
                .stateful()
            {
                OpsKind::Tracked(prep) => {
                    let xs: [usize; 4] = x.shape().dims();
                    prep.finish((xs, pad), forward(x.into_primitive(), pad))
                }
                OpsKind::UnTracked(prep) => prep.finish(forward(x.into_primitive(), pad)),
            }
        }
    }

    pub(super) fn reflect_pad(x: Tensor<4>, pad: [usize; 4]) -> Tensor<4> {
        Tensor::from_dispatch(<Dispatch as FlexReflectPad>::reflect_pad_fused(
            x.into_dispatch(),
            pad,
        ))
    }

    /// The padded tensor (f32: [`super::reflect_pad`] sends other dtypes to Burn's padding), by
    /// [`forward_f32`].
    fn forward(x: FloatTensor<Flex>, pad: [usize; 4]) -> FloatTensor<Flex> {
        let xs: [usize; 4] = x.shape().dims();
        let [top, bottom, left, right] = pad;
        let out = [xs[0], xs[1], xs[2] + top + bottom, xs[3] + left + right];
        let x = x.to_contiguous();
        flex_tensor(forward_f32(x.storage::<f32>(), xs, pad), out)
    }

    /// The padded planes of `x` ([B, C, H, W]), one task per plane.
    pub fn forward_f32(x: &[f32], [b, c, h, w]: [usize; 4], pad: [usize; 4]) -> Vec<f32> {
        let [top, bottom, left, right] = pad;
        let (hp, wp) = (h + top + bottom, w + left + right);
        let (rows, cols) = (
            source_indices(h, top, bottom),
            source_indices(w, left, right),
        );
        let mut y = vec![0.0f32; b * c * hp * wp];
        y.par_chunks_mut(hp * wp)
            .zip(x.par_chunks(h * w))
            .for_each(|(out, plane)| {
                for (dst, &sy) in out.chunks_exact_mut(wp).zip(&rows) {
                    let src = &plane[sy * w..][..w];
                    // The interior is the row itself; the borders go through the index map.
                    dst[left..left + w].copy_from_slice(src);
                    for ox in (0..left).chain(left + w..wp) {
                        dst[ox] = src[cols[ox]];
                    }
                }
            });
        y
    }

    /// dL/dx of [`forward`] from the padded output's gradient `dy`.
    fn backward(dy: FloatTensor<Flex>, xs: [usize; 4], pad: [usize; 4]) -> FloatTensor<Flex> {
        let dy = dy.to_contiguous();
        flex_tensor(backward_f32(dy.storage::<f32>(), xs, pad), xs)
    }

    /// dx[p] = Σ of dy over the padded positions whose source is p: output rows in order, within
    /// a row the interior columns, then the left and the right border; one task per plane.
    pub fn backward_f32(dy: &[f32], [b, c, h, w]: [usize; 4], pad: [usize; 4]) -> Vec<f32> {
        let [top, bottom, left, right] = pad;
        let (hp, wp) = (h + top + bottom, w + left + right);
        let (rows, cols) = (
            source_indices(h, top, bottom),
            source_indices(w, left, right),
        );
        let mut dx = vec![0.0f32; b * c * h * w];
        dx.par_chunks_mut(h * w)
            .zip(dy.par_chunks(hp * wp))
            .for_each(|(plane, grad)| {
                for (src, &sy) in grad.chunks_exact(wp).zip(&rows) {
                    let dst = &mut plane[sy * w..][..w];
                    for (d, s) in dst.iter_mut().zip(&src[left..left + w]) {
                        *d += s;
                    }
                    for ox in (0..left).chain(left + w..wp) {
                        dst[cols[ox]] += src[ox];
                    }
                }
            });
        dx
    }
}
