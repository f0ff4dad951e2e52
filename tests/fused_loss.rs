//! Network-1's loss fused into one operation on flex (`kernels::fused_loss`): it must
//! equal hand-computed values and Burn's composition of the same loss (softmax, gather, log-
//! softmax … in train/loss.rs) in every reading, forward and gradient, and be bit-for-bit
//! repeatable on any thread count.
#![cfg(feature = "flex")]

mod common;

use burn::tensor::activation::softmax;
use burn::tensor::{Int, Tensor, TensorData};
use common::{flex_autodiff, to_vec};
use hdrsynth::kernels::fused_loss::{ClassLoss, class_loss, exp};
use hdrsynth::train::loss::{
    Network1Reading, network1_loss, ordinal_l1, soft_cross_entropy, weighted_cross_entropy,
    weighted_l1,
};

/// (loss, dL/dlogits) of the fused loss, or of Burn's composition with `composed`.
fn loss_and_grad(
    reading: Network1Reading,
    composed: bool,
    logits: &Tensor<4>,
    target: &Tensor<3, Int>,
    alpha: &Tensor<1>,
) -> (f32, Vec<f32>) {
    let z = logits.clone().require_grad();
    let (t, a, sigma) = (target.clone(), alpha.clone(), 3.0);
    let loss = if composed {
        match reading {
            Network1Reading::Literal => weighted_l1(softmax(z.clone(), 1), t, a),
            Network1Reading::Ordinal => ordinal_l1(softmax(z.clone(), 1), t, a),
            Network1Reading::CrossEntropy => weighted_cross_entropy(z.clone(), t, a),
            Network1Reading::Soft => soft_cross_entropy(z.clone(), t, a, sigma),
        }
    } else {
        network1_loss(reading, z.clone(), t, a, sigma)
    };
    let grads = loss.clone().backward();
    (
        loss.into_scalar::<f32>(),
        to_vec(z.grad(&grads).expect("dlogits")),
    )
}

#[test]
fn two_classes_by_hand() {
    // One pixel, logits (0, ln 3): p = (1/4, 3/4); target 1, α = (1, 2), so α_t = 2.
    let d = flex_autodiff();
    let z = Tensor::<4>::from_data(TensorData::new(vec![0.0f32, 3f32.ln()], [1, 2, 1, 1]), &d);
    let t = Tensor::<3, Int>::from_data(TensorData::new(vec![1i32], [1, 1, 1]), &d);
    let a = Tensor::<1>::from_data(TensorData::new(vec![1.0f32, 2.0], [2]), &d);
    let close = |got: f32, want: f32| assert!((got - want).abs() < 1e-6, "{got} vs {want}");
    // Literal: 2·α_t·(1 − p_t) = 4 · 1/4 = 1; dℓ/dz_c = 2α_t·p_t·(p_c − δ_ct) = 3·(p_c − δ_ct):
    // (3/4, −3/4).
    let (l, g) = loss_and_grad(Network1Reading::Literal, false, &z, &t, &a);
    close(l, 1.0);
    close(g[0], 0.75);
    close(g[1], -0.75);
    // Cross-entropy: α_t·(−ln p_t) = 2·ln(4/3); gradient α_t·(p_c − δ_ct) = (1/2, −1/2).
    let (l, g) = loss_and_grad(Network1Reading::CrossEntropy, false, &z, &t, &a);
    close(l, 2.0 * (4.0f32 / 3.0).ln());
    close(g[0], 0.5);
    close(g[1], -0.5);
    // Ordinal: E = p_1 = 3/4 against t/(C−1) = 1: α_t·|E − 1| = 1/2; gradient
    // α_t·sign(E − 1)·p_c·(c − E) = −2·(1/4·(−3/4), 3/4·(1/4)) = (3/8, −3/8).
    let (l, g) = loss_and_grad(Network1Reading::Ordinal, false, &z, &t, &a);
    close(l, 0.5);
    close(g[0], 0.375);
    close(g[1], -0.375);
}

#[test]
fn equals_the_composed_loss_in_every_reading() {
    let d = flex_autodiff();
    // 667 pixels per item: a whole task block of 512 and a partial one.
    let (b, c, h, w) = (2, 256, 23, 29);
    // Logits spread over ±8 so the softmax is far from uniform; targets over all classes,
    // including 0 and 255.
    let z: Vec<f32> = common::values(b * c * h * w, 5)
        .iter()
        .map(|v| 16.0 * v - 8.0)
        .collect();
    let z = Tensor::<4>::from_data(TensorData::new(z, [b, c, h, w]), &d);
    let t: Vec<i32> = (0..b * h * w).map(|i| ((i * 97) % c) as i32).collect();
    assert!(t.contains(&0) && t.iter().any(|&v| v > 200));
    let t = Tensor::<3, Int>::from_data(TensorData::new(t, [b, h, w]), &d);
    let a: Vec<f32> = common::values(c, 6).iter().map(|v| 0.5 + v).collect();
    let a = Tensor::<1>::from_data(TensorData::new(a, [c]), &d);
    let fused = ClassLoss {
        reading: Network1Reading::Literal,
        sigma: 3.0,
    };
    assert!(
        class_loss(&z, &t, &a, fused).is_some(),
        "network1_loss must take the fused path on flex"
    );
    for reading in [
        Network1Reading::Literal,
        Network1Reading::Ordinal,
        Network1Reading::CrossEntropy,
        Network1Reading::Soft,
    ] {
        let (fused, fused_g) = loss_and_grad(reading, false, &z, &t, &a);
        let (composed, composed_g) = loss_and_grad(reading, true, &z, &t, &a);
        assert!(
            (fused - composed).abs() <= 2e-6 * composed.abs().max(1.0),
            "{reading:?}: loss {fused} vs {composed}"
        );
        let scale = composed_g.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(scale > 0.0, "{reading:?}: no gradient");
        let diff = common::max_abs_diff(&fused_g, &composed_g);
        assert!(
            diff <= 1e-5 * scale,
            "{reading:?}: gradient differs by {diff} (largest {scale})"
        );
    }
}

#[test]
fn exp_is_within_two_ulp() {
    // Against f64's exp over the softmax's range.
    let mut worst = 0.0f64;
    for i in 0..=87_000 {
        let x = -(i as f32) / 1000.0 + 0.000_123;
        let want = (x as f64).exp();
        worst = worst.max(((exp(x) as f64) - want).abs() / want);
    }
    assert!(worst < 2.5e-7, "relative error {worst}");
    assert_eq!(exp(0.0), 1.0);
    assert_eq!(exp(-1000.0), exp(-87.0));
}

#[test]
fn same_bits_on_any_thread_count() {
    let d = flex_autodiff();
    let (b, c, h, w) = (3, 256, 9, 17);
    let z = Tensor::<4>::from_data(
        TensorData::new(common::values(b * c * h * w, 8), [b, c, h, w]),
        &d,
    );
    let t: Vec<i32> = (0..b * h * w).map(|i| ((i * 31) % c) as i32).collect();
    let t = Tensor::<3, Int>::from_data(TensorData::new(t, [b, h, w]), &d);
    let a = Tensor::<1>::ones([c], &d);
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| {
                let (l, g) = loss_and_grad(Network1Reading::Soft, false, &z, &t, &a);
                (
                    l.to_bits(),
                    g.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                )
            })
    };
    let one = on(1);
    assert_eq!(one, on(2), "2 threads");
    assert_eq!(one, on(3), "3 threads");
}
