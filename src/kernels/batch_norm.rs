//! BatchNorm for the networks' layers, fused and parallel on flex in training mode.
//!
//! Flex inherits burn-backend's default `batch_norm_train` and `batch_norm_train_backward`: a
//! chain of swap_dims/reshape copies, reductions and broadcasts, each a serial pass over the
//! activation. Here, on flex (f32), each channel is one rayon task: forward, the mean and the
//! biased variance (two passes, summed in f64), then y = (x − mean)·inv_std·γ + β; backward,
//! Σdy and Σdy·x̂ (f64), then dx = γ·inv_std·(dy − Σdy/N − x̂·Σ(dy·x̂)/N), dγ = Σdy·x̂, dβ = Σdy.
//! Sums run in a fixed order within a channel, so results do not depend on the thread count.
//! The kernels take flex tensors and slices only, so they could go upstream as flex's
//! `batch_norm_train` and `batch_norm_train_backward`.

use burn::nn::BatchNorm;
use burn::tensor::Tensor;

/// `norm.forward(x)`, through the kernels above when `x` lives on flex and the layer trains.
pub fn batch_norm<const D: usize>(norm: &BatchNorm, x: Tensor<D>) -> Tensor<D> {
    normalise(norm, x, false)
}

/// `relu(norm.forward(x))`, the ReLU fused into the kernels above when they run: one pass
/// less over the activation each way (the backward recomputes the output's sign), with the same
/// bits as Burn's ReLU after the BatchNorm (Network-1's blocks, Network-2's residual blocks).
pub fn batch_norm_relu<const D: usize>(norm: &BatchNorm, x: Tensor<D>) -> Tensor<D> {
    normalise(norm, x, true)
}

fn normalise<const D: usize>(norm: &BatchNorm, x: Tensor<D>, relu: bool) -> Tensor<D> {
    #[cfg(feature = "flex")]
    {
        let device = x.device();
        // Burn's condition for the training path; a wrong channel count goes to Burn's forward
        // for its message, an empty input to its NaN statistics.
        if device.is_autodiff()
            && norm.training.is_enabled()
            && crate::device::is_flex(&device)
            && x.dims().get(1) == Some(&norm.gamma.dims()[0])
            && x.shape().num_elements() > 0
        {
            let (y, mean, var) =
                flex::batch_norm_train(x, norm.gamma.val(), norm.beta.val(), norm.epsilon, relu);
            // As `BatchNorm::forward_train`.
            let update = |state: &burn::module::RunningState<Tensor<1>>, batch: Tensor<1>| {
                let running = state
                    .value_sync()
                    .to_device(&device)
                    .mul_scalar(1.0 - norm.momentum)
                    .add(batch.detach().mul_scalar(norm.momentum));
                state.update(running.detach());
            };
            update(&norm.running_mean, mean);
            update(&norm.running_var, var);
            return y;
        }
    }
    let y = norm.forward(x);
    if relu {
        burn::tensor::activation::relu(y)
    } else {
        y
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
    use burn::backend::ops::{ActivationOps, ModuleOps};
    use burn::backend::tensor::FloatTensor;
    use burn::backend::{AutodiffBackend, Dispatch, Flex, TensorMetadata, backend_extension};
    use burn::tensor::{DType, Shape, Tensor};
    use rayon::prelude::*;

    use crate::kernels::par::{Shared, flex_tensor};

    /// Batch normalisation with the batch's own statistics: (output, mean, biased variance), as
    /// `ModuleOps::batch_norm_train`, then a ReLU where `relu`, by [`forward`]; its autodiff step
    /// uses [`backward`].
    #[backend_extension(Flex, Autodiff)]
    pub trait FlexBatchNorm: burn::backend::Backend {
        #[allow(clippy::type_complexity)]
        fn batch_norm_train_fused(
            x: FloatTensor<Self>,
            gamma: FloatTensor<Self>,
            beta: FloatTensor<Self>,
            epsilon: f64,
            relu: bool,
        ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>);
    }

    impl FlexBatchNorm for Flex {
        fn batch_norm_train_fused(
            x: FloatTensor<Self>,
            gamma: FloatTensor<Self>,
            beta: FloatTensor<Self>,
            epsilon: f64,
            relu: bool,
        ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
            forward(x, gamma, beta, epsilon, relu)
        }
    }

    #[derive(Debug)]
    struct BatchNormTrain;

    impl Backward<Flex, 3> for BatchNormTrain {
        /// x, γ and β (checkpointed), the batch mean and variance, ε, and whether a ReLU
        /// follows.
        type State = (
            NodeId,
            NodeId,
            NodeId,
            FloatTensor<Flex>,
            FloatTensor<Flex>,
            f64,
            bool,
        );

        fn backward(
            self,
            ops: Ops<Self::State, 3>,
            grads: &mut Gradients,
            checkpointer: &mut Checkpointer,
        ) {
            let [node_x, node_gamma, node_beta] = ops.parents;
            let grad = grads.consume::<Flex>(&ops.node);
            let (x_state, gamma_state, beta_state, mean, var, epsilon, relu) = ops.state;
            let x = checkpointer.retrieve_node_output::<FloatTensor<Flex>>(x_state);
            let gamma = checkpointer.retrieve_node_output::<FloatTensor<Flex>>(gamma_state);
            let beta = checkpointer.retrieve_node_output::<FloatTensor<Flex>>(beta_state);
            let affine = Affine {
                mean,
                var,
                epsilon,
                beta: relu.then_some(beta),
            };
            let (dx, dgamma, dbeta) = backward(x, gamma, affine, grad);
            for (node, g) in [(node_x, dx), (node_gamma, dgamma), (node_beta, dbeta)] {
                if let Some(node) = node {
                    grads.register::<Flex>(node.id, g);
                }
            }
        }
    }

    impl<C: CheckpointStrategy> FlexBatchNorm for Autodiff<Flex, C> {
        fn batch_norm_train_fused(
            x: FloatTensor<Self>,
            gamma: FloatTensor<Self>,
            beta: FloatTensor<Self>,
            epsilon: f64,
            relu: bool,
        ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
            // The statistics come back untracked, as burn-autodiff's `batch_norm_train` does.
            let untracked = <Self as AutodiffBackend>::from_inner;
            match BatchNormTrain
                .prepare::<C>([x.node(), gamma.node(), beta.node()])
                .compute_bound()
                .stateful()
            {
                OpsKind::Tracked(mut prep) => {
                    let x_state = prep.checkpoint(&x);
                    let gamma_state = prep.checkpoint(&gamma);
                    let beta_state = prep.checkpoint(&beta);
                    let (y, mean, var) = forward(
                        x.into_primitive(),
                        gamma.into_primitive(),
                        beta.into_primitive(),
                        epsilon,
                        relu,
                    );
                    let state = (
                        x_state,
                        gamma_state,
                        beta_state,
                        mean.clone(),
                        var.clone(),
                        epsilon,
                        relu,
                    );
                    (prep.finish(state, y), untracked(mean), untracked(var))
                }
                OpsKind::UnTracked(prep) => {
                    let (y, mean, var) = forward(
                        x.into_primitive(),
                        gamma.into_primitive(),
                        beta.into_primitive(),
                        epsilon,
                        relu,
                    );
                    (prep.finish(y), untracked(mean), untracked(var))
                }
            }
        }
    }

    /// (output, batch mean, biased batch variance) of batch normalisation of `x` in training
    /// mode, followed by a ReLU where `relu`, on flex.
    pub(super) fn batch_norm_train<const D: usize>(
        x: Tensor<D>,
        gamma: Tensor<1>,
        beta: Tensor<1>,
        epsilon: f64,
        relu: bool,
    ) -> (Tensor<D>, Tensor<1>, Tensor<1>) {
        let (y, mean, var) = <Dispatch as FlexBatchNorm>::batch_norm_train_fused(
            x.into_dispatch(),
            gamma.into_dispatch(),
            beta.into_dispatch(),
            epsilon,
            relu,
        );
        (
            Tensor::from_dispatch(y),
            Tensor::from_dispatch(mean),
            Tensor::from_dispatch(var),
        )
    }

    /// [B, C, the product of the other dimensions] of an input of rank ≥ 2.
    fn blocks(shape: &Shape) -> [usize; 3] {
        let dims = shape.as_slice();
        [dims[0], dims[1], dims[2..].iter().product()]
    }

    /// `Flex::batch_norm_train(x, gamma, beta, epsilon)` (then flex's ReLU where `relu`) by
    /// [`forward_f32`]; flex's own for other dtypes.
    pub fn forward(
        x: FloatTensor<Flex>,
        gamma: FloatTensor<Flex>,
        beta: FloatTensor<Flex>,
        epsilon: f64,
        relu: bool,
    ) -> (FloatTensor<Flex>, FloatTensor<Flex>, FloatTensor<Flex>) {
        if [&x, &gamma, &beta].iter().any(|t| t.dtype() != DType::F32) {
            let r = Flex::batch_norm_train(x, gamma, beta, epsilon);
            let y = if relu { Flex::relu(r.output) } else { r.output };
            return (y, r.mean, r.variance);
        }
        let shape = x.shape();
        let dims = blocks(&shape);
        let (x, gamma, beta) = (
            x.to_contiguous(),
            gamma.to_contiguous(),
            beta.to_contiguous(),
        );
        let (y, mean, var) = forward_f32(
            x.storage::<f32>(),
            dims,
            gamma.storage::<f32>(),
            beta.storage::<f32>(),
            epsilon,
            relu,
        );
        let c = Shape::new([dims[1]]);
        (
            flex_tensor(y, shape),
            flex_tensor(mean, c.clone()),
            flex_tensor(var, c),
        )
    }

    /// What the backward pass needs of the forward's affine map: the batch mean and variance,
    /// ε, and β where a ReLU followed (to recompute where the output was positive).
    pub struct Affine {
        pub mean: FloatTensor<Flex>,
        pub var: FloatTensor<Flex>,
        pub epsilon: f64,
        pub beta: Option<FloatTensor<Flex>>,
    }

    /// (dx, dγ, dβ) of [`forward`] from the output gradient `dy`, given the mean and variance
    /// it returned, by [`backward_f32`]; flex's own `batch_norm_train_backward` (after its
    /// `relu_backward`) for other dtypes.
    pub fn backward(
        x: FloatTensor<Flex>,
        gamma: FloatTensor<Flex>,
        affine: Affine,
        dy: FloatTensor<Flex>,
    ) -> (FloatTensor<Flex>, FloatTensor<Flex>, FloatTensor<Flex>) {
        let Affine {
            mean,
            var,
            epsilon,
            beta,
        } = affine;
        if [&x, &gamma, &mean, &var, &dy]
            .into_iter()
            .chain(&beta)
            .any(|t| t.dtype() != DType::F32)
        {
            let dy = match beta {
                Some(beta) => {
                    let r = Flex::batch_norm_train(x.clone(), gamma.clone(), beta, epsilon);
                    Flex::relu_backward(r.output, dy)
                }
                None => dy,
            };
            let r = Flex::batch_norm_train_backward(x, gamma, mean, var, epsilon, dy);
            return (r.x_grad, r.gamma_grad, r.beta_grad);
        }
        let shape = x.shape();
        let dims = blocks(&shape);
        let [x, gamma, mean, var, dy] = [x, gamma, mean, var, dy].map(|t| t.to_contiguous());
        let beta = beta.map(|b| b.to_contiguous());
        let (dx, dgamma, dbeta) = backward_f32(
            x.storage::<f32>(),
            dims,
            gamma.storage::<f32>(),
            [mean.storage::<f32>(), var.storage::<f32>()],
            epsilon,
            beta.as_ref().map(|b| b.storage::<f32>()),
            dy.storage::<f32>(),
        );
        let c = Shape::new([dims[1]]);
        (
            flex_tensor(dx, shape),
            flex_tensor(dgamma, c.clone()),
            flex_tensor(dbeta, c),
        )
    }

    /// Independent partial sums, so that the loop over a plane vectorises; they are added in
    /// a fixed order.
    const LANES: usize = 8;

    /// Σ f(a_i, b_i) in f64 over two slices of one length, in [`LANES`] partial sums.
    fn sum2(a: &[f32], b: &[f32], f: impl Fn(f32, f32) -> f64) -> f64 {
        let mut acc = [0.0f64; LANES];
        let (ac, bc) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
        let tail: f64 = ac
            .remainder()
            .iter()
            .zip(bc.remainder())
            .map(|(&u, &v)| f(u, v))
            .sum();
        for (ca, cb) in ac.zip(bc) {
            for l in 0..LANES {
                acc[l] += f(ca[l], cb[l]);
            }
        }
        acc.iter().sum::<f64>() + tail
    }

    /// The planes of channel `c`: its B blocks of `p` values in an [B, C, P] buffer.
    fn planes(
        v: &[f32],
        [_, channels, p]: [usize; 3],
        c: usize,
    ) -> impl Iterator<Item = &[f32]> + Clone {
        v.chunks_exact(channels * p)
            .map(move |item| &item[c * p..(c + 1) * p])
    }

    /// 1/sqrt(var + ε), as f32.
    fn inv_std(var: f32, epsilon: f64) -> f32 {
        (1.0 / (var as f64 + epsilon).sqrt()) as f32
    }

    /// Runs `f(c, planes)` for every channel c on the rayon pool, `planes` being channel c's B
    /// planes of a new [B, C, P] output; returns the output and the two values per channel that
    /// `f` returns.
    fn per_channel(
        [batch, channels, p]: [usize; 3],
        f: impl Fn(usize, Vec<&mut [f32]>) -> (f32, f32) + Sync,
    ) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
        let mut out = vec![0.0f32; batch * channels * p];
        let shared = Shared(out.as_mut_ptr());
        let (a, b) = (0..channels)
            .into_par_iter()
            .map(|c| {
                let planes = (0..batch)
                    // SAFETY: channel c's plane of item b, handed to this task only.
                    .map(|b| unsafe { shared.slice((b * channels + c) * p, p) })
                    .collect();
                f(c, planes)
            })
            .unzip();
        (out, a, b)
    }

    /// The kernel of [`forward`] on row-major slices: `x` is [B, C, P], `gamma` and `beta` [C];
    /// returns (y [B, C, P], mean [C], biased variance [C]), y through a ReLU where `relu`.
    pub fn forward_f32(
        x: &[f32],
        dims: [usize; 3],
        gamma: &[f32],
        beta: &[f32],
        epsilon: f64,
        relu: bool,
    ) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
        let n = (dims[0] * dims[2]) as f64;
        per_channel(dims, |c, out| {
            let mean = planes(x, dims, c)
                .map(|v| sum2(v, v, |u, _| u as f64))
                .sum::<f64>()
                / n;
            let var = planes(x, dims, c)
                .map(|v| sum2(v, v, |u, _| (u as f64 - mean).powi(2)))
                .sum::<f64>()
                / n;
            let (mean, var) = (mean as f32, var as f32);
            let scale = inv_std(var, epsilon) * gamma[c];
            for (dst, v) in out.into_iter().zip(planes(x, dims, c)) {
                for (d, &u) in dst.iter_mut().zip(v) {
                    let y = (u - mean) * scale + beta[c];
                    *d = if relu && !passes(y) { 0.0 } else { y };
                }
            }
            (mean, var)
        })
    }

    /// Where flex's ReLU keeps a BatchNorm output (and its gradient): above 0, or NaN.
    #[inline(always)]
    fn passes(y: f32) -> bool {
        y.is_nan() || y > 0.0
    }

    /// The kernel of [`backward`] on row-major slices: `x` and `dy` are [B, C, P], `gamma`,
    /// the mean and variance (and `beta` where a ReLU followed) [C]; returns (dx [B, C, P],
    /// dγ [C], dβ [C]). With a ReLU, dy counts only where the forward's output passed it, the
    /// output recomputed as the forward computed it.
    pub fn backward_f32(
        x: &[f32],
        dims: [usize; 3],
        gamma: &[f32],
        [mean, var]: [&[f32]; 2],
        epsilon: f64,
        beta: Option<&[f32]>,
        dy: &[f32],
    ) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
        let n = (dims[0] * dims[2]) as f64;
        per_channel(dims, |c, out| {
            let stats = [mean[c], inv_std(var[c], epsilon), gamma[c]];
            let (x, dy) = (planes(x, dims, c), planes(dy, dims, c));
            // One copy of the loops per case, so that the gate is a constant in each.
            match beta {
                Some(beta) => channel_grad::<true>(x, dy, stats, beta[c], n, out),
                None => channel_grad::<false>(x, dy, stats, 0.0, n, out),
            }
        })
    }

    /// One channel of [`backward_f32`]: its planes of x and dy, [mean, 1/std, γ], β (read where
    /// `RELU`), N; writes dx into `out`, returns (dγ, dβ).
    #[inline(always)]
    fn channel_grad<'a, const RELU: bool>(
        x: impl Iterator<Item = &'a [f32]> + Clone,
        dy: impl Iterator<Item = &'a [f32]> + Clone,
        [m, is, gamma]: [f32; 3],
        beta: f32,
        n: f64,
        out: Vec<&mut [f32]>,
    ) -> (f32, f32) {
        // dy where the forward's output (recomputed as the forward computes it) passed the ReLU.
        let fwd_scale = is * gamma;
        let gate = |u: f32, w: f32| {
            if RELU && !passes((u - m) * fwd_scale + beta) {
                0.0
            } else {
                w
            }
        };
        let pairs = || x.clone().zip(dy.clone());
        let dbeta: f64 = pairs()
            .map(|(v, g)| sum2(v, g, |u, w| gate(u, w) as f64))
            .sum();
        let dgamma: f64 = pairs()
            .map(|(v, g)| sum2(v, g, |u, w| gate(u, w) as f64 * ((u - m) * is) as f64))
            .sum();
        let scale = gamma * is;
        let (shift, slope) = ((dbeta / n) as f32, (dgamma / n) as f32);
        for (dst, (v, g)) in out.into_iter().zip(pairs()) {
            for ((d, &u), &w) in dst.iter_mut().zip(v).zip(g) {
                *d = scale * (gate(u, w) - shift - (u - m) * is * slope);
            }
        }
        (dgamma as f32, dbeta as f32)
    }
}
