//! The networks' BatchNorm (`kernels::batch_norm`): in training mode on flex it is a
//! fused kernel of our own; it must equal a hand-computed case and Burn's own
//! `BatchNorm::forward` (burn-backend's default decomposition, the reference it replaces) in
//! output, running statistics and gradients, be bit-for-bit repeatable, and leave eval mode to
//! Burn.
#![cfg(feature = "flex")]

mod common;

use burn::module::{Param, RunningState};
use burn::nn::{BatchNorm, BatchNormConfig};
use burn::tensor::{Device, Tensor, TensorData};
use hdrsynth::kernels::batch_norm::{batch_norm, batch_norm_relu};

fn flex() -> Device {
    hdrsynth::device::device_from_name("flex").expect("flex")
}

fn tensor<const D: usize>(v: Vec<f32>, shape: [usize; D], device: &Device) -> Tensor<D> {
    Tensor::from_data(TensorData::new(v, shape), device)
}

fn vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().try_to_vec::<f32>().expect("f32")
}

/// A BatchNorm of `c` channels with γ and β set, on `device`.
fn norm(
    gamma: Vec<f32>,
    beta: Vec<f32>,
    epsilon: f64,
    momentum: f64,
    device: &Device,
) -> BatchNorm {
    let c = gamma.len();
    let mut n = BatchNormConfig::new(c)
        .with_epsilon(epsilon)
        .with_momentum(momentum)
        .init(device);
    n.gamma = Param::from_tensor(tensor(gamma, [c], device));
    n.beta = Param::from_tensor(tensor(beta, [c], device));
    n
}

/// [y, running mean, running var, dL/dx, dL/dγ, dL/dβ] of L = Σ (y ⊙ w), through `ours` or
/// `BatchNorm::forward`.
fn run(ours: bool, n: &BatchNorm, x: &Tensor<4>, w: &Tensor<4>) -> [Vec<f32>; 6] {
    run_with(
        n,
        x,
        w,
        |n, x| {
            if ours { batch_norm(n, x) } else { n.forward(x) }
        },
    )
}

/// [`run`] through `f`.
fn run_with(
    n: &BatchNorm,
    x: &Tensor<4>,
    w: &Tensor<4>,
    f: impl Fn(&BatchNorm, Tensor<4>) -> Tensor<4>,
) -> [Vec<f32>; 6] {
    let x = x.clone().require_grad();
    let y = f(n, x.clone());
    let g = (y.clone() * w.clone()).sum().backward();
    [
        vec(y),
        vec(n.running_mean.value_sync()),
        vec(n.running_var.value_sync()),
        vec(x.grad(&g).expect("dx")),
        vec(n.gamma.val().grad(&g).expect("dγ")),
        vec(n.beta.val().grad(&g).expect("dβ")),
    ]
}

#[test]
fn equals_burns_batch_norm_in_training() {
    let dev = flex().autodiff();
    let shape = [3, 5, 7, 9];
    let len = shape.iter().product();
    // An offset and a spread per channel, so that the statistics are far from 0 and 1.
    let x: Vec<f32> = common::values(len, 1)
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let c = (i / 63) % 5;
            (v - 0.3) * (0.5 + c as f32) + c as f32 - 2.0
        })
        .collect();
    let x = tensor(x, shape, &dev);
    let w = tensor(common::values(len, 2), shape, &dev) - 0.5;
    let gamma: Vec<f32> = common::values(5, 3).iter().map(|v| v * 2.0 - 0.5).collect();
    let beta: Vec<f32> = common::values(5, 4).iter().map(|v| v - 0.5).collect();
    let n = || norm(gamma.clone(), beta.clone(), 1e-5, 0.1, &dev);
    let theirs = run(false, &n(), &x, &w);
    let ours = run(true, &n(), &x, &w);
    let names = ["y", "running mean", "running var", "dx", "dγ", "dβ"];
    for ((a, b), name) in ours.iter().zip(&theirs).zip(names) {
        assert_eq!(a.len(), b.len(), "{name}");
        let scale = b.iter().map(|v| v.abs()).fold(0.0f32, f32::max);
        for (i, (p, q)) in a.iter().zip(b).enumerate() {
            assert!(
                (p - q).abs() <= 1e-5 * scale.max(1e-3),
                "{name}[{i}]: ours {p}, Burn's {q}"
            );
        }
    }
}

/// The ReLU fused into the kernels gives the same bits as Burn's ReLU after them, forward and
/// backward (γ of both signs, so some channels are mostly cut and some mostly passed).
#[test]
fn fused_relu_equals_relu_after_batch_norm() {
    let dev = flex().autodiff();
    let shape = [2, 6, 5, 11];
    let len = shape.iter().product();
    let x = tensor(common::values(len, 11), shape, &dev) - 0.4;
    let w = tensor(common::values(len, 12), shape, &dev) - 0.5;
    let gamma: Vec<f32> = common::values(6, 13)
        .iter()
        .map(|v| v * 2.0 - 1.0)
        .collect();
    let beta: Vec<f32> = common::values(6, 14).iter().map(|v| v - 0.5).collect();
    let n = || norm(gamma.clone(), beta.clone(), 1e-5, 0.1, &dev);
    let fused = run_with(&n(), &x, &w, batch_norm_relu);
    let composed = run_with(&n(), &x, &w, |n, x| {
        burn::tensor::activation::relu(batch_norm(n, x))
    });
    assert_eq!(fused, composed);
    // The ReLU cut something and passed something.
    let zeros = fused[0].iter().filter(|v| **v == 0.0).count();
    assert!(
        zeros > len / 5 && zeros < len * 4 / 5,
        "{zeros} of {len} cut"
    );
}

#[test]
fn by_hand() {
    // One channel of x = 1, 3 | 5, 7 (two items of 2 values), ε = 4, γ = 2, β = 1, momentum 1
    // (the running statistics become the batch's). mean = 4, biased var = (9+1+1+9)/4 = 5,
    // inv_std = 1/sqrt(5+4) = 1/3, x̂ = −1, −1/3, 1/3, 1, y = 2x̂ + 1 = −1, 1/3, 5/3, 3.
    // L = y₀ (dy = 1, 0, 0, 0): Σdy = 1, Σdy·x̂ = −1, N = 4, so
    // dx = γ·inv_std·(dy − Σdy/N − x̂·Σ(dy·x̂)/N) = (2/3)·(dy − 1/4 + x̂/4) = 1/3, −2/9, −1/9, 0;
    // dγ = Σdy·x̂ = −1, dβ = Σdy = 1.
    let dev = flex().autodiff();
    let x = tensor(vec![1.0, 3.0, 5.0, 7.0], [2, 1, 1, 2], &dev);
    let w = tensor(vec![1.0, 0.0, 0.0, 0.0], [2, 1, 1, 2], &dev);
    let n = norm(vec![2.0], vec![1.0], 4.0, 1.0, &dev);
    let got = run(true, &n, &x, &w);
    let want: [&[f32]; 6] = [
        &[-1.0, 1.0 / 3.0, 5.0 / 3.0, 3.0],
        &[4.0],
        &[5.0],
        &[1.0 / 3.0, -2.0 / 9.0, -1.0 / 9.0, 0.0],
        &[-1.0],
        &[1.0],
    ];
    for (g, w) in got.iter().zip(want) {
        assert_eq!(g.len(), w.len());
        for (a, b) in g.iter().zip(w) {
            assert!((a - b).abs() < 1e-6, "{got:?}");
        }
    }
}

#[test]
fn same_bits_on_any_thread_count() {
    let dev = flex().autodiff();
    let shape = [2, 16, 20, 21];
    let len = shape.iter().product();
    let x = tensor(common::values(len, 5), shape, &dev);
    let w = tensor(common::values(len, 6), shape, &dev);
    let gamma = common::values(16, 7);
    let beta = common::values(16, 8);
    let on = |threads: usize| {
        let n = norm(gamma.clone(), beta.clone(), 1e-5, 0.1, &dev);
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| run(true, &n, &x, &w))
    };
    let bits = |r: [Vec<f32>; 6]| r.map(|v| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>());
    let one = bits(on(1));
    assert_eq!(one, bits(on(3)), "3 threads");
}

#[test]
fn eval_mode_uses_the_running_statistics() {
    // Running mean 1 and var 3 (ε 1 makes the std 2), γ = 3, β = −1: y = 3·(x − 1)/2 − 1,
    // whatever the batch's statistics; the running statistics stay as they were.
    let x = [0.0f32, 1.0, 3.0, 9.0];
    let want: Vec<f32> = x.iter().map(|v| 1.5 * (v - 1.0) - 1.0).collect();
    let check = |dev: &Device, training: bool| {
        let mut n = norm(vec![3.0], vec![-1.0], 1.0, 0.1, dev);
        n.running_mean = RunningState::new(tensor(vec![1.0], [1], dev));
        n.running_var = RunningState::new(tensor(vec![3.0], [1], dev));
        n.training = Param::from_bool(training);
        let y = batch_norm(&n, tensor(x.to_vec(), [1, 1, 2, 2], dev));
        assert_eq!(vec(y), want, "training {training}");
        assert_eq!(vec(n.running_mean.value_sync()), [1.0]);
        assert_eq!(vec(n.running_var.value_sync()), [3.0]);
    };
    // Not an autodiff device, and an autodiff device with the layer's training disabled.
    check(&flex(), true);
    check(&flex().autodiff(), false);
}
