//! The networks' convolution (`kernels::conv`): on flex its forward pass, input
//! gradient and weight gradient are im2col tiles + GEMM of our own; they must equal a
//! hand-computed case, Burn's own conv2d and its gradients (flex's transposed convolution for
//! dx, burn-backend's default weight gradient: the references they replace) on the networks'
//! kinds of layers, and be bit-for-bit repeatable. Layers with few channels on one side take
//! `models::direct` instead, stride-1 layers with many `models::winograd`.
#![cfg(feature = "flex")]

mod common;

use burn::tensor::module::{conv_transpose2d, conv2d};
use burn::tensor::ops::{ConvOptions, ConvTransposeOptions};
use burn::tensor::{Tensor, TensorData};
use common::{centred_tensor, flex_autodiff, to_vec};
use hdrsynth::kernels::conv::{conv_transpose2d_op, conv2d_op};

/// (output, dL/dx, dL/dW, dL/db) of Σ (y ⊙ r) for a fixed r, y = `op(x, w, bias)` with a bias
/// of `cout` channels.
fn grads_of(
    x: &Tensor<4>,
    w: &Tensor<4>,
    cout: usize,
    op: impl Fn(Tensor<4>, Tensor<4>, Tensor<1>) -> Tensor<4>,
) -> [Vec<f32>; 4] {
    let (x, w) = (x.clone().require_grad(), w.clone().require_grad());
    let b = Tensor::<1>::from_data(
        TensorData::new(common::values(cout, 9), [cout]),
        &flex_autodiff(),
    )
    .require_grad();
    let y = op(x.clone(), w.clone(), b.clone());
    let r = centred_tensor(y.dims(), 7);
    let g = (y.clone() * r).sum().backward();
    [
        to_vec(y),
        to_vec(x.grad(&g).expect("dx")),
        to_vec(w.grad(&g).expect("dw")),
        b.grad(&g)
            .expect("db")
            .into_data()
            .try_to_vec::<f32>()
            .expect("f32"),
    ]
}

/// [`grads_of`] the convolution: ours (`conv2d_op`) or Burn's conv2d.
fn grads(ours: bool, x: &Tensor<4>, w: &Tensor<4>, options: &ConvOptions<2>) -> [Vec<f32>; 4] {
    grads_of(x, w, w.dims()[0], |x, w, b| {
        if ours {
            conv2d_op(x, w, Some(b), options.clone())
        } else {
            conv2d(x, w, Some(b), options.clone())
        }
    })
}

/// [`grads_of`] a transposed convolution (weight [C_in, C_out, kh, kw]), ours or Burn's.
fn transposed_grads(
    ours: bool,
    x: &Tensor<4>,
    w: &Tensor<4>,
    options: &ConvTransposeOptions<2>,
) -> [Vec<f32>; 4] {
    grads_of(x, w, w.dims()[1], |x, w, b| {
        if ours {
            conv_transpose2d_op(x, w, Some(b), options.clone())
        } else {
            conv_transpose2d(x, w, Some(b), options.clone())
        }
    })
}

/// max |a − b| over each of the four results, against 1e-5 of the largest |b|.
fn assert_close(case: &str, ours: &[Vec<f32>; 4], burn: &[Vec<f32>; 4]) {
    for (name, a, b) in ["y", "dx", "dw", "db"]
        .iter()
        .zip(ours)
        .zip(burn)
        .map(|((n, a), b)| (n, a, b))
    {
        assert_eq!(a.len(), b.len(), "{case} {name}: length");
        let scale = b.iter().fold(1.0f32, |m, v| m.max(v.abs()));
        let err = a
            .iter()
            .zip(b)
            .fold(0.0f32, |m, (p, q)| m.max((p - q).abs()));
        assert!(
            err <= 1e-5 * scale,
            "{case} {name}: max |ours − Burn| = {err} (scale {scale})"
        );
    }
}

#[test]
fn transposed_by_hand() {
    // A 2×2 stride-2 transposed convolution copies w, scaled by each input pixel, into that
    // pixel's 2×2 block of the output: y = x ⊗ w. For L = Σ y, dL/dx = Σ w = 1111 at every
    // pixel and dL/dW = Σ x = 10 at every tap.
    let x = Tensor::<4>::from_data(
        TensorData::new(vec![1.0f32, 2.0, 3.0, 4.0], [1, 1, 2, 2]),
        &flex_autodiff(),
    )
    .require_grad();
    let w = Tensor::<4>::from_data(
        TensorData::new(vec![1.0f32, 10.0, 100.0, 1000.0], [1, 1, 2, 2]),
        &flex_autodiff(),
    )
    .require_grad();
    let options = ConvTransposeOptions::new([2, 2], [0, 0], [0, 0], [1, 1], 1);
    let y = conv_transpose2d_op(x.clone(), w.clone(), None, options);
    #[rustfmt::skip]
    let want = vec![
        1.0, 10.0, 2.0, 20.0,
        100.0, 1000.0, 200.0, 2000.0,
        3.0, 30.0, 4.0, 40.0,
        300.0, 3000.0, 400.0, 4000.0,
    ];
    assert_eq!(to_vec(y.clone()), want);
    let g = y.sum().backward();
    assert_eq!(to_vec(x.grad(&g).expect("dx")), vec![1111.0; 4]);
    assert_eq!(to_vec(w.grad(&g).expect("dw")), vec![10.0; 4]);
}

#[test]
fn transposed_equals_burns_on_the_networks_layer_kinds() {
    // (x shape, c_out, kernel, stride, padding, padding_out)
    type Case = ([usize; 4], usize, usize, usize, usize, usize);
    let cases: [Case; 7] = [
        // Network-1's 2×2 stride-2 up-sampling.
        ([2, 8, 6, 7], 4, 2, 2, 0, 0),
        ([4, 16, 8, 8], 8, 2, 2, 0, 0),
        // Network-2's 5×5 stride-2 deconvolution, TensorFlow and PyTorch alignments.
        ([2, 6, 9, 8], 5, 5, 2, 1, 0),
        ([2, 6, 9, 8], 5, 5, 2, 2, 1),
        // Stride 1, and big enough that the tiles split the rows.
        ([1, 3, 40, 128], 64, 3, 1, 1, 0),
        // Network-2's deconvolution big enough for the polyphase Winograd path, both
        // alignments.
        ([2, 16, 32, 32], 4, 5, 2, 1, 0),
        ([2, 16, 32, 31], 8, 5, 2, 2, 1),
    ];
    for (i, (xs, cout, k, s, p, op)) in cases.into_iter().enumerate() {
        let x = centred_tensor(xs, 300 + i as u64);
        let w = centred_tensor([xs[1], cout, k, k], 400 + i as u64);
        let options = ConvTransposeOptions::new([s, s], [p, p], [op, op], [1, 1], 1);
        let ours = transposed_grads(true, &x, &w, &options);
        let burn = transposed_grads(false, &x, &w, &options);
        assert_close(&format!("transposed case {i}"), &ours, &burn);
    }
}

#[test]
fn weight_gradient_by_hand() {
    // x = 1..9 on a 3×3 plane, 2×2 kernel, no padding, L = Σ y: dL/dW[i, j] is the sum of the
    // 2×2 window of x at offset (i, j): 1+2+4+5, 2+3+5+6, 4+5+7+8, 5+6+8+9.
    let x = Tensor::<4>::from_data(
        TensorData::new((1..=9).map(|v| v as f32).collect(), [1, 1, 3, 3]),
        &flex_autodiff(),
    );
    let w = Tensor::<4>::from_data(
        TensorData::new(vec![0.0f32; 4], [1, 1, 2, 2]),
        &flex_autodiff(),
    )
    .require_grad();
    let y = conv2d_op(
        x,
        w.clone(),
        None,
        ConvOptions::new([1, 1], [0, 0], [1, 1], 1),
    );
    let g = y.sum().backward();
    assert_eq!(
        to_vec(w.grad(&g).expect("dw")),
        vec![12.0, 16.0, 24.0, 28.0]
    );
}

#[test]
fn equals_burns_conv2d_on_the_networks_layer_kinds() {
    // (x shape, c_out, kernel, stride, padding (top, bottom), (left, right), dilation)
    type Case = ([usize; 4], usize, usize, usize, [(usize, usize); 2], usize);
    let cases: [Case; 20] = [
        // Network-1's 3×3 block conv and 5×5 head (padding k/2).
        ([2, 6, 16, 16], 8, 3, 1, [(1, 1), (1, 1)], 1),
        ([2, 8, 16, 12], 20, 5, 1, [(2, 2), (2, 2)], 1),
        // The largest batch, and c_out ≫ c_in as in the head.
        ([8, 4, 12, 10], 6, 3, 1, [(1, 1), (1, 1)], 1),
        ([3, 2, 10, 10], 32, 5, 1, [(2, 2), (2, 2)], 1),
        // Network-2's stride-2 convs on reflect-padded input (no padding of their own); an even
        // size leaves the last input row and column outside every window (dx = 0 there).
        ([2, 6, 17, 17], 8, 5, 2, [(0, 0), (0, 0)], 1),
        ([2, 5, 18, 16], 7, 5, 2, [(2, 2), (2, 2)], 1),
        // Asymmetric padding, dilation.
        ([1, 3, 11, 9], 4, 3, 1, [(0, 2), (1, 0)], 2),
        // Big enough that the im2col is tiled over output rows (1600 rows × 128 columns), so
        // the input gradient's rows take sums from two tiles.
        ([1, 64, 40, 128], 2, 5, 1, [(2, 2), (2, 2)], 1),
        ([3, 4, 9, 7], 5, 1, 1, [(0, 0), (0, 0)], 1),
        // Winograd (≥ 16 channels, ≥ 128 tiles): F(4, 3) and F(4, 5) with padding k/2 (F(4, 5)
        // also with c_in > c_out, the head's input gradient),
        // Network-2's residual conv (reflect-padded input, no padding of its own), asymmetric
        // padding, and a task's batch of tiles spanning two batch items (48 tile rows in blocks
        // of 38).
        ([4, 16, 32, 32], 16, 3, 1, [(1, 1), (1, 1)], 1),
        ([2, 16, 48, 48], 32, 5, 1, [(2, 2), (2, 2)], 1),
        ([2, 32, 44, 48], 16, 5, 1, [(2, 2), (2, 2)], 1),
        ([2, 16, 34, 34], 24, 3, 1, [(0, 0), (0, 0)], 1),
        ([4, 16, 30, 30], 16, 3, 1, [(0, 2), (1, 0)], 1),
        ([2, 16, 96, 96], 16, 3, 1, [(1, 1), (1, 1)], 1),
        // Polyphase (stride 2 as a stride-1 3×3 layer over 4·c_in phase channels, by
        // Winograd): Network-2's 5×5 stride-2 conv on reflect-padded input, and odd sizes with
        // asymmetric padding (phases of unequal length, a last input row no window reaches).
        ([2, 4, 66, 66], 16, 5, 2, [(0, 0), (0, 0)], 1),
        ([2, 6, 67, 65], 16, 5, 2, [(1, 2), (2, 1)], 1),
        // Direct (≤ 4 channels on one side, models::direct): Network-2's output layer (5×5,
        // 64 → 3 on reflect-padded input, rows of two whole 16-pixel chunks), zero padding with
        // a partial last chunk, and few input channels onto two output blocks (4 + 2) with
        // asymmetric padding (the input gradient then has 3 output channels).
        ([2, 64, 20, 36], 3, 5, 1, [(0, 0), (0, 0)], 1),
        ([2, 8, 13, 21], 3, 5, 1, [(2, 2), (2, 2)], 1),
        ([1, 3, 9, 40], 6, 3, 1, [(0, 2), (1, 0)], 1),
    ];
    for (i, (xs, cout, k, s, pad, d)) in cases.into_iter().enumerate() {
        let x = centred_tensor(xs, 100 + i as u64);
        let w = centred_tensor([cout, xs[1], k, k], 200 + i as u64);
        let options = ConvOptions::new_with_padding([s, s], pad, [d, d], 1);
        let ours = grads(true, &x, &w, &options);
        let burn = grads(false, &x, &w, &options);
        assert_close(&format!("case {i}"), &ours, &burn);
    }
}

#[test]
fn repeatable_bit_for_bit() {
    let x = centred_tensor([2, 8, 24, 24], 1);
    let w = centred_tensor([16, 8, 5, 5], 2);
    let options = ConvOptions::new([1, 1], [2, 2], [1, 1], 1);
    let a = grads(true, &x, &w, &options);
    let b = grads(true, &x, &w, &options);
    assert_eq!(a, b);
    let options = ConvOptions::new([2, 2], [0, 0], [1, 1], 1);
    let a = grads(true, &x, &w, &options);
    let b = grads(true, &x, &w, &options);
    assert_eq!(a, b);
}

/// The same bits on 1, 2 and 4 threads: with batch 3, one thread runs every item's GEMMs
/// (split across threads only on 4) — the split must never change a result.
#[test]
fn same_bits_on_any_thread_count() {
    let on = |threads: usize, x: &Tensor<4>, w: &Tensor<4>, options: &ConvOptions<2>| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| grads(true, x, w, options))
    };
    let x = centred_tensor([3, 8, 24, 24], 3);
    let w = centred_tensor([16, 8, 5, 5], 4);
    let options = ConvOptions::new([1, 1], [2, 2], [1, 1], 1);
    let one = on(1, &x, &w, &options);
    assert_eq!(one, on(2, &x, &w, &options), "2 threads");
    assert_eq!(one, on(4, &x, &w, &options), "4 threads");
    // Winograd: two batches of tiles (see above), split across threads or not.
    let x = centred_tensor([2, 16, 96, 96], 5);
    let w = centred_tensor([16, 16, 3, 3], 6);
    let options = ConvOptions::new([1, 1], [1, 1], [1, 1], 1);
    let one = on(1, &x, &w, &options);
    assert_eq!(one, on(2, &x, &w, &options), "Winograd, 2 threads");
    assert_eq!(one, on(3, &x, &w, &options), "Winograd, 3 threads");
    // Direct: tasks by output rows (forward, input gradient) and input channel (weight
    // gradient).
    let x = centred_tensor([2, 32, 40, 40], 7);
    let w = centred_tensor([3, 32, 5, 5], 8);
    let options = ConvOptions::new([1, 1], [2, 2], [1, 1], 1);
    let one = on(1, &x, &w, &options);
    assert_eq!(one, on(2, &x, &w, &options), "direct, 2 threads");
    assert_eq!(one, on(3, &x, &w, &options), "direct, 3 threads");
}
