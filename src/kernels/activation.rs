//! Leaky ReLU (Network-2's encoders, the released code's `lrelu`, leak 0.2): x where x ≥ 0,
//! slope·x below, with gradient 1 at 0 as Burn's (and TensorFlow's `maximum(x, leak·x)`).
//!
//! On flex it is one op with its own autodiff step: Burn's `leaky_relu` is a
//! comparison, a scaled copy and a `mask_where`, and its gradient two more `mask_where`s and a
//! scaling. Here the forward pass and the gradient are
//! one pass each over the tensor, with the same bits as Burn's (each element is either copied
//! or multiplied once).

use burn::tensor::Tensor;

/// `x` where x ≥ 0, `slope`·x elsewhere.
pub fn leaky_relu<const D: usize>(x: Tensor<D>, slope: f64) -> Tensor<D> {
    #[cfg(feature = "flex")]
    if crate::device::is_flex(&x.device()) && x.dtype() == burn::tensor::DType::F32 {
        return flex::leaky_relu(x, slope as f32);
    }
    burn::tensor::activation::leaky_relu(x, slope)
}

#[cfg(feature = "flex")]
mod flex {
    use burn::backend::autodiff::checkpoint::base::Checkpointer;
    use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
    use burn::backend::autodiff::grads::Gradients;
    use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
    use burn::backend::autodiff::{Autodiff, NodeId};
    use burn::backend::tensor::FloatTensor;
    use burn::backend::{Dispatch, Flex, TensorMetadata, backend_extension};
    use burn::tensor::Tensor;
    use rayon::prelude::*;

    use crate::kernels::par::{flex_tensor, with_avx2};

    /// Elements per parallel task.
    const CHUNK: usize = 1 << 16;

    /// Leaky ReLU by [`forward`]; its autodiff step runs [`backward`].
    #[backend_extension(Flex, Autodiff)]
    pub trait FlexLeakyRelu: burn::backend::Backend {
        fn leaky_relu_fused(x: FloatTensor<Self>, slope: f32) -> FloatTensor<Self>;
    }

    impl FlexLeakyRelu for Flex {
        fn leaky_relu_fused(x: FloatTensor<Self>, slope: f32) -> FloatTensor<Self> {
            forward(x, slope)
        }
    }

    #[derive(Debug)]
    struct LeakyRelu;

    impl Backward<Flex, 1> for LeakyRelu {
        /// The input and the slope.
        type State = (NodeId, f32);

        fn backward(
            self,
            ops: Ops<Self::State, 1>,
            grads: &mut Gradients,
            checkpointer: &mut Checkpointer,
        ) {
            let [node_x] = ops.parents;
            let grad = grads.consume::<Flex>(&ops.node);
            let (x_state, slope) = ops.state;
            let x = checkpointer.retrieve_node_output::<FloatTensor<Flex>>(x_state);
            if let Some(node) = node_x {
                grads.register::<Flex>(node.id, backward(x, grad, slope));
            }
        }
    }

    impl<C: CheckpointStrategy> FlexLeakyRelu for Autodiff<Flex, C> {
        fn leaky_relu_fused(x: FloatTensor<Self>, slope: f32) -> FloatTensor<Self> {
            match LeakyRelu
                .prepare::<C>([x.node()])
                .compute_bound()
                .stateful()
            {
                OpsKind::Tracked(mut prep) => {
                    let x_state = prep.checkpoint(&x);
                    prep.finish((x_state, slope), forward(x.into_primitive(), slope))
                }
                OpsKind::UnTracked(prep) => prep.finish(forward(x.into_primitive(), slope)),
            }
        }
    }

    pub(super) fn leaky_relu<const D: usize>(x: Tensor<D>, slope: f32) -> Tensor<D> {
        Tensor::from_dispatch(<Dispatch as FlexLeakyRelu>::leaky_relu_fused(
            x.into_dispatch(),
            slope,
        ))
    }

    /// f(a[i], b[i]) for every element, in parallel chunks, into a new vector.
    fn map2(a: &[f32], b: &[f32], f: impl Fn(f32, f32) -> f32 + Sync) -> Vec<f32> {
        assert_eq!(a.len(), b.len(), "operands of one shape");
        let mut out: Vec<f32> = Vec::with_capacity(a.len());
        out.spare_capacity_mut()
            .par_chunks_mut(CHUNK)
            .zip(a.par_chunks(CHUNK).zip(b.par_chunks(CHUNK)))
            .for_each(|(dst, (a, b))| {
                with_avx2(
                    #[inline(always)]
                    || {
                        for ((d, &p), &q) in dst.iter_mut().zip(a).zip(b) {
                            d.write(f(p, q));
                        }
                    },
                )
            });
        // SAFETY: the chunks above cover all a.len() elements, each written once.
        unsafe { out.set_len(a.len()) };
        out
    }

    fn forward(x: FloatTensor<Flex>, slope: f32) -> FloatTensor<Flex> {
        let shape = x.shape();
        let x = x.to_contiguous();
        let v = x.storage::<f32>();
        let y = map2(v, v, |p, _| if p < 0.0 { p * slope } else { p });
        flex_tensor(y, shape)
    }

    fn backward(x: FloatTensor<Flex>, dy: FloatTensor<Flex>, slope: f32) -> FloatTensor<Flex> {
        let shape = x.shape();
        let (x, dy) = (x.to_contiguous(), dy.to_contiguous());
        let dx = map2(x.storage::<f32>(), dy.storage::<f32>(), |p, g| {
            if p < 0.0 { g * slope } else { g }
        });
        flex_tensor(dx, shape)
    }
}
