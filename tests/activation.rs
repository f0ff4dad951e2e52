//! Leaky ReLU (`kernels::activation`): on flex one op of our own with its own gradient.
//! It must give the same bits as Burn's `leaky_relu` and that op's autodiff gradient (the path
//! it replaces), and the hand-computed values, including the gradient 1 at x = 0.
#![cfg(feature = "flex")]

mod common;

use burn::tensor::{Tensor, activation};
use common::{centred_tensor, flex_autodiff, to_vec, value_and_grad};
use hdrsynth::kernels::activation::leaky_relu;

#[test]
fn equals_burns_leaky_relu_and_its_gradient() {
    // Network-2's encoder shape class, more elements than one parallel chunk, and a few zeros.
    let x = centred_tensor([2, 3, 130, 140], 5);
    let x = x.clone().mask_fill(x.clone().abs().lower_elem(1e-3), 0.0);
    for slope in [0.2, 0.0, 1.5] {
        let ours = value_and_grad(&x, 98, |x| leaky_relu(x, slope));
        let burn = value_and_grad(&x, 98, |x| activation::leaky_relu(x, slope));
        assert_eq!(ours, burn, "slope {slope}");
    }
}

#[test]
fn by_hand() {
    let x = Tensor::<4>::from_floats([[[[-2.0, -0.5, 0.0, 3.0]]]], &flex_autodiff()).require_grad();
    let y = leaky_relu(x.clone(), 0.2);
    assert_eq!(to_vec(y.clone()), vec![-0.4, -0.1, 0.0, 3.0]);
    let r = Tensor::<4>::from_floats([[[[1.0, 2.0, 3.0, 4.0]]]], &flex_autodiff());
    let g = (y * r).sum().backward();
    // Slope below 0, 1 from 0 up.
    assert_eq!(to_vec(x.grad(&g).expect("dx")), vec![0.2, 0.4, 3.0, 4.0]);
}
