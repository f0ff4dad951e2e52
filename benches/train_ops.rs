//! Where Network-1's training step goes, op by op. Times each convolution of
//! the default U-Net (batch 4, 128² crops) forward, forward + input gradient, forward + weight
//! gradient on an autodiff device, then the other op kinds of the step (BatchNorm, ReLU,
//! max-pool, concatenation) at their largest shape. The backward costs are the differences.
//! Plain timings (median of `HDRSYNTH_BENCH_REPS`, default 3, after one warm-up), on the backend
//! named by `HDRSYNTH_BENCH_BACKEND` (default flex); the convolutions go through the networks'
//! `kernels::conv::{conv2d_op, conv_transpose2d_op}`, or Burn's with `HDRSYNTH_BENCH_CONV=burn`;
//! BatchNorm through the networks' `kernels::batch_norm::batch_norm`:
//!     cargo bench --bench train_ops

#[path = "../tests/common/mod.rs"]
mod common;

use burn::module::Module;
use burn::nn::pool::MaxPool2dConfig;
use burn::nn::{BatchNormConfig, Relu};
use burn::tensor::module::{conv_transpose2d, conv2d};
use burn::tensor::ops::{ConvOptions, ConvTransposeOptions};
use burn::tensor::{Device, Int, Tensor, TensorData};
use hdrsynth::kernels::batch_norm::batch_norm;
use hdrsynth::kernels::conv::{conv_transpose2d_op, conv2d_op};
use hdrsynth::kernels::pool::max_pool2d;
use hdrsynth::train::config::DEFAULT_LABEL_SIGMA;
use hdrsynth::train::loss::{Network1Reading, network1_loss};
use std::time::Instant;

const BATCH: usize = 4;

fn tensor(shape: [usize; 4], seed: u64, dev: &Device) -> Tensor<4> {
    let n = shape.iter().product();
    Tensor::from_data(TensorData::new(common::values(n, seed), shape), dev)
}

/// Median seconds of `f` over the repetitions, after one warm-up call.
fn time(reps: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Reads one value back so lazy backends finish the work being timed.
fn sync(t: Tensor<4>) {
    let _ = t.slice([0..1, 0..1, 0..1, 0..1]).into_data();
}

struct Conv {
    name: &'static str,
    cin: usize,
    cout: usize,
    k: usize,
    size: usize,
    transposed: bool,
    /// 1, or 2 for Network-2's 5×5 layers.
    stride: usize,
    count: usize,
}

fn main() {
    // As the binary does (src/main.rs): keep freed activations in the heap.
    hdrsynth::device::retain_freed_memory();
    let backend = std::env::var("HDRSYNTH_BENCH_BACKEND").unwrap_or_else(|_| "flex".into());
    let reps: usize = std::env::var("HDRSYNTH_BENCH_REPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    // `HDRSYNTH_BENCH_CONV=burn`: Burn's conv2d instead of the networks' (src/kernels/conv.rs).
    let burn_conv = std::env::var("HDRSYNTH_BENCH_CONV").is_ok_and(|v| v == "burn");
    // `HDRSYNTH_BENCH_CONV=im2col`: the networks' convolutions without Winograd.
    if std::env::var("HDRSYNTH_BENCH_CONV").is_ok_and(|v| v == "im2col") {
        hdrsynth::kernels::conv::set_winograd(false);
    }
    let dev = hdrsynth::device::device_from_name(&backend)
        .expect("backend")
        .autodiff();
    // Network-1 default: widths 32..512 over sizes 128..8; `count` = how many convolutions of
    // that exact shape one step runs.
    let w = [32, 64, 128, 256, 512];
    let mut convs = vec![Conv {
        name: "enc0 a",
        cin: 6,
        cout: 32,
        k: 3,
        size: 128,
        transposed: false,
        stride: 1,
        count: 1,
    }];
    for l in 0..5 {
        let size = 128 >> l;
        if l > 0 {
            convs.push(Conv {
                name: "enc a",
                cin: w[l - 1],
                cout: w[l],
                k: 3,
                size,
                transposed: false,
                stride: 1,
                count: 1,
            });
        }
        // enc b and dec b share a shape; dec a has 2w → w.
        convs.push(Conv {
            name: if l < 4 { "enc b + dec b" } else { "enc b" },
            cin: w[l],
            cout: w[l],
            k: 3,
            size,
            transposed: false,
            stride: 1,
            count: if l < 4 { 2 } else { 1 },
        });
        if l < 4 {
            convs.push(Conv {
                name: "dec a",
                cin: 2 * w[l],
                cout: w[l],
                k: 3,
                size,
                transposed: false,
                stride: 1,
                count: 1,
            });
            convs.push(Conv {
                name: "up (2×2 s2)",
                cin: w[l + 1],
                cout: w[l],
                k: 2,
                size: size / 2,
                transposed: true,
                stride: 2,
                count: 1,
            });
        }
    }
    convs.push(Conv {
        name: "head 5×5",
        cin: 32,
        cout: 256,
        k: 5,
        size: 128,
        transposed: false,
        stride: 1,
        count: 1,
    });

    // Network-2's residual-block convolution (3×3 256→256 on 32² crops' 1/8 plane; the block
    // pads by reflection itself, so the convolution has none of its own: the bench's padding 1
    // on a 32² input gives the same 32² output).
    convs.push(Conv {
        name: "Network-2 residual 3×3",
        cin: 256,
        cout: 256,
        k: 3,
        size: 32,
        transposed: false,
        stride: 1,
        count: 0,
    });

    // Network-2's 5×5 stride-2 layers (ResNet, b = 64, batch 4 of 256² crops; 'SAME'
    // padding, input size given): the encoders' two convs (× 3 encoders), the merger's
    // down-sampling, the decoder's three deconvolutions.
    for (name, cin, cout, size, transposed) in [
        ("Network-2 encoder conv1 5×5 s2", 6, 64, 256, false),
        ("Network-2 encoder conv2 5×5 s2", 64, 128, 128, false),
        ("Network-2 merger down 5×5 s2", 384, 256, 64, false),
        ("Network-2 deconv1 5×5 s2", 512, 128, 32, true),
        ("Network-2 deconv2 5×5 s2", 512, 64, 64, true),
        ("Network-2 deconv3 5×5 s2", 256, 64, 128, true),
    ] {
        convs.push(Conv {
            name,
            cin,
            cout,
            k: 5,
            size,
            transposed,
            stride: 2,
            count: 0,
        });
    }

    // Network-2's output convolution (5×5 64→3 at full resolution, stride 1; the network pads
    // by reflection itself, the bench's zero padding 2 keeps the size).
    convs.push(Conv {
        name: "Network-2 output 5×5",
        cin: 64,
        cout: 3,
        k: 5,
        size: 256,
        transposed: false,
        stride: 1,
        count: 0,
    });

    println!(
        "Network-1 ops on {backend} ({} conv2d), batch {BATCH}, median of {reps} (seconds per op call)",
        if burn_conv { "Burn's" } else { "the networks'" }
    );
    println!("| op | in→out | size | × | forward | input grad | weight grad | total × count |");
    println!("|---|---|---|---|---|---|---|---|");
    let mut sum = [0.0f64; 3];
    // `HDRSYNTH_BENCH_ONLY=other`: skip the convolutions; `=NAME`: only the convolutions whose
    // name contains NAME (and the other ops).
    let only = std::env::var("HDRSYNTH_BENCH_ONLY").unwrap_or_default();
    for c in convs
        .iter()
        .filter(|c| only != "other" && c.name.contains(only.as_str()))
    {
        let x = tensor([BATCH, c.cin, c.size, c.size], 1, &dev);
        let wshape = if c.transposed {
            [c.cin, c.cout, c.k, c.k]
        } else {
            [c.cout, c.cin, c.k, c.k]
        };
        let wt = tensor(wshape, 2, &dev);
        let run = |x: Tensor<4>, wt: Tensor<4>| -> Tensor<4> {
            if c.transposed {
                // Output 2× the input: padding 2 and output padding 1 for the 5×5 kernel.
                let (p, op) = if c.k == 5 { (2, 1) } else { (0, 0) };
                let options = ConvTransposeOptions::new([2, 2], [p, p], [op, op], [1, 1], 1);
                if burn_conv {
                    conv_transpose2d(x, wt, None, options)
                } else {
                    conv_transpose2d_op(x, wt, None, options)
                }
            } else {
                let (s, p) = (c.stride, c.k / 2);
                let options = ConvOptions::new([s, s], [p, p], [1, 1], 1);
                if burn_conv {
                    conv2d(x, wt, None, options)
                } else {
                    conv2d_op(x, wt, None, options)
                }
            }
        };
        let fwd = time(reps, || sync(run(x.clone(), wt.clone())));
        let with_x = time(reps, || {
            let xg = x.clone().require_grad();
            let grads = run(xg.clone(), wt.clone()).sum().backward();
            sync(xg.grad(&grads).expect("x grad"));
        });
        let with_w = time(reps, || {
            let wg = wt.clone().require_grad();
            let grads = run(x.clone(), wg.clone()).sum().backward();
            sync(wg.grad(&grads).expect("w grad"));
        });
        let (gx, gw) = ((with_x - fwd).max(0.0), (with_w - fwd).max(0.0));
        let n = c.count as f64;
        sum[0] += fwd * n;
        sum[1] += gx * n;
        sum[2] += gw * n;
        println!(
            "| {} | {}→{} ({}×{}) | {} | {} | {fwd:.4} | {gx:.4} | {gw:.4} | {:.4} |",
            c.name,
            c.cin,
            c.cout,
            c.k,
            c.k,
            c.size,
            c.count,
            (fwd + gx + gw) * n
        );
    }
    println!(
        "| all convolutions | | | | {:.3} | {:.3} | {:.3} | {:.3} |",
        sum[0],
        sum[1],
        sum[2],
        sum.iter().sum::<f64>()
    );

    // The other op kinds at their largest shape (level 0: 32 channels at 128²); a step runs
    // each at every level, ≈ 4/3 of the level-0 cost per encoder/decoder pair.
    let x = tensor([BATCH, 32, 128, 128], 3, &dev);
    let bn = BatchNormConfig::new(32).init(&dev);
    let bn_f = time(reps, || sync(batch_norm(&bn, x.clone())));
    let bn_fb = time(reps, || {
        let xg = x.clone().require_grad();
        let grads = batch_norm(&bn, xg.clone()).sum().backward();
        sync(xg.grad(&grads).expect("grad"));
    });
    let relu = Relu::new();
    let relu_f = time(reps, || sync(relu.forward(x.clone())));
    let relu_fb = time(reps, || {
        let xg = x.clone().require_grad();
        let grads = relu.forward(xg.clone()).sum().backward();
        sync(xg.grad(&grads).expect("grad"));
    });
    let pool = MaxPool2dConfig::new([2, 2]).init();
    let pool_fb = time(reps, || {
        let xg = x.clone().require_grad();
        let grads = max_pool2d(&pool, xg.clone()).sum().backward();
        sync(xg.grad(&grads).expect("grad"));
    });
    let cat_fb = time(reps, || {
        let xg = x.clone().require_grad();
        let grads = Tensor::cat(vec![xg.clone(), x.clone()], 1).sum().backward();
        sync(xg.grad(&grads).expect("grad"));
    });
    let sum_fb = time(reps, || {
        let xg = x.clone().require_grad();
        let grads = xg.clone().sum().backward();
        sync(xg.grad(&grads).expect("grad"));
    });
    // Network-1's loss on its logits (4 × 256 × 128²): softmax over the classes, then Eq. 4.
    let logits = tensor([BATCH, 256, 128, 128], 4, &dev);
    let target = Tensor::<3, Int>::from_data(
        TensorData::new(
            (0..BATCH * 128 * 128)
                .map(|i| ((i * 37) % 256) as i64)
                .collect::<Vec<_>>(),
            [BATCH, 128, 128],
        ),
        &dev,
    );
    let alpha = Tensor::<1>::ones([256], &dev);
    let loss_f = time(reps, || {
        let l = network1_loss(
            Network1Reading::Literal,
            logits.clone(),
            target.clone(),
            alpha.clone(),
            DEFAULT_LABEL_SIGMA,
        );
        let _ = l.into_data();
    });
    let loss_fb = |reading| {
        time(reps, || {
            let zg = logits.clone().require_grad();
            let l = network1_loss(
                reading,
                zg.clone(),
                target.clone(),
                alpha.clone(),
                DEFAULT_LABEL_SIGMA,
            );
            let grads = l.backward();
            sync(zg.grad(&grads).expect("grad"));
        })
    };
    let (literal_fb, soft_fb) = (
        loss_fb(Network1Reading::Literal),
        loss_fb(Network1Reading::Soft),
    );
    println!(
        "\nOther ops at 32×128² (batch {BATCH}); `+ backward` includes a sum and its backward"
    );
    println!("| op | forward | forward + backward |");
    println!("|---|---|---|");
    println!("| BatchNorm (training) | {bn_f:.4} | {bn_fb:.4} |");
    println!("| ReLU | {relu_f:.4} | {relu_fb:.4} |");
    println!("| max-pool 2×2 | | {pool_fb:.4} |");
    println!("| cat (skip, 2 × 32 ch) | | {cat_fb:.4} |");
    println!("| sum alone (the backward's seed) | | {sum_fb:.4} |");
    println!("| softmax + Eq. 4 loss on 256×128² logits | {loss_f:.4} | {literal_fb:.4} |");
    println!("| soft cross-entropy on 256×128² logits (trainer's default) | | {soft_fb:.4} |");
    let _ = bn.num_params();
}
