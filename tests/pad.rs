//! Reflection padding (`kernels::pad`): on flex one op of our own with its own
//! gradient. It must equal Burn's `pad(PadMode::Reflect)` and that op's autodiff gradient (the
//! path it replaces) on Network-2's paddings, and hand-computed sums where a pad wraps around.
#![cfg(feature = "flex")]

mod common;

use burn::tensor::Tensor;
use burn::tensor::ops::PadMode;
use common::{centred_tensor, flex_autodiff, to_vec, value_and_grad};
use hdrsynth::kernels::pad::reflect_pad;

/// Network-2's paddings ('SAME' 5×5 stride 2 on even and odd sizes, 3×3 stride 1) and
/// asymmetric ones: the same values as Burn's reflection padding, and a gradient within float
/// rounding of Burn's (the border sums may add in another order).
#[test]
fn equals_burns_reflection_padding_and_its_gradient() {
    let cases: [([usize; 4], [usize; 4]); 5] = [
        ([2, 3, 8, 8], [1, 2, 1, 2]),
        ([1, 4, 7, 9], [2, 2, 2, 2]),
        ([2, 2, 6, 5], [1, 1, 1, 1]),
        ([1, 1, 5, 6], [0, 3, 2, 0]),
        ([3, 2, 4, 4], [3, 0, 0, 1]),
    ];
    for (i, (shape, [t, b, l, r])) in cases.into_iter().enumerate() {
        let x = centred_tensor(shape, 10 + i as u64);
        let (ours, ours_dx) = value_and_grad(&x, 99, |x| reflect_pad(x, (t, b), (l, r)));
        let (burn, burn_dx) = value_and_grad(&x, 99, |x| x.pad([(t, b), (l, r)], PadMode::Reflect));
        assert_eq!(ours, burn, "case {i}: padded values");
        for (j, (a, e)) in ours_dx.iter().zip(&burn_dx).enumerate() {
            assert!(
                (a - e).abs() <= 1e-6 * e.abs().max(1.0),
                "case {i} dx[{j}]: {a} vs {e}"
            );
        }
    }
}

/// By hand where the pad is as long as the axis: [a, b] padded (3, 3) is
/// [b a b | a b | a b a], so with r = 1 … 8, dL/da = 2 + 4 + 6 + 8 and dL/db = 1 + 3 + 5 + 7;
/// an axis of length 1 sends every padded row's gradient to its one row.
#[test]
fn periodic_and_replicated_gradients_by_hand() {
    let x = Tensor::<4>::from_floats([[[[10.0, 20.0]]]], &flex_autodiff()).require_grad();
    let y = reflect_pad(x.clone(), (0, 0), (3, 3));
    assert_eq!(
        to_vec(y.clone()),
        vec![20.0, 10.0, 20.0, 10.0, 20.0, 10.0, 20.0, 10.0]
    );
    let r = Tensor::<1>::from_floats([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0], &flex_autodiff())
        .reshape([1, 1, 1, 8]);
    let g = (y * r).sum().backward();
    assert_eq!(to_vec(x.grad(&g).expect("dx")), vec![20.0, 16.0]);

    let x = Tensor::<4>::from_floats([[[[1.0, 2.0]]]], &flex_autodiff()).require_grad();
    let y = reflect_pad(x.clone(), (1, 2), (0, 0));
    assert_eq!(y.dims(), [1, 1, 4, 2]);
    let r = Tensor::<1>::from_floats([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0], &flex_autodiff())
        .reshape([1, 1, 4, 2]);
    let g = (y * r).sum().backward();
    assert_eq!(to_vec(x.grad(&g).expect("dx")), vec![16.0, 20.0]);
}
