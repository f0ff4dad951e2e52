//! Network-1's 2×2 max-pool (`kernels::pool`): on flex one op of our own with its own
//! gradient. It must give the same values and gradient as Burn's `MaxPool2d` (flex's kernel, the
//! path it replaces), ties and odd sizes included, and the hand-computed case.
#![cfg(feature = "flex")]

mod common;

use burn::nn::pool::MaxPool2dConfig;
use burn::tensor::Tensor;
use common::{centred_tensor, flex_autodiff, to_vec, value_and_grad};
use hdrsynth::kernels::pool::max_pool2d;

#[test]
fn equals_burns_max_pool_and_its_gradient() {
    let pool = network1_pool();
    for (i, shape) in [[2, 3, 16, 20], [1, 2, 7, 9], [3, 1, 1, 5]]
        .into_iter()
        .enumerate()
    {
        let x = centred_tensor(shape, 30 + i as u64);
        // After a ReLU most windows tie at 0: the gradient must go where flex's goes.
        for x in [x.clone(), x.clone().clamp_min(0.0)] {
            let ours = value_and_grad(&x, 97, |x| max_pool2d(&pool, x));
            let burn = value_and_grad(&x, 97, |x| pool.forward(x));
            assert_eq!(ours, burn, "case {i}");
        }
    }
}

#[test]
fn by_hand() {
    let x = Tensor::<4>::from_floats(
        [[[[1.0, 5.0, 2.0, 2.0], [3.0, 4.0, 0.0, -1.0]]]],
        &flex_autodiff(),
    )
    .require_grad();
    let y = max_pool2d(&network1_pool(), x.clone());
    assert_eq!(to_vec(y.clone()), vec![5.0, 2.0]);
    let r = Tensor::<4>::from_floats([[[[10.0, 20.0]]]], &flex_autodiff());
    let g = (y * r).sum().backward();
    // 5 wins its window; 2 and 2 tie, the first takes the gradient.
    assert_eq!(
        to_vec(x.grad(&g).expect("dx")),
        vec![0.0, 10.0, 20.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    );
}

/// Network-1's pool.
fn network1_pool() -> burn::nn::pool::MaxPool2d {
    MaxPool2dConfig::new([2, 2]).init()
}
