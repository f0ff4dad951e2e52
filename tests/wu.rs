//! Network-2 (Wu et al. 2018) and its loss: parameter counts, shapes of both variants at several
//! sizes, the TensorFlow padding conventions, μ-law loss hand values, batch assembly, overfitting
//! one sample with Adam, and weight import/export through the documented naming scheme.

mod common;

use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams};
use burn::store::{BurnToPyTorchAdapter, ModuleSnapshot};
use burn::tensor::{Device, Tensor, TensorData};
use hdrsynth::data::loader::{Sample, Target};
use hdrsynth::kernels::pad::reflect_pad;
use hdrsynth::models::import::expected_tensors;
use hdrsynth::models::wu::{
    self, DeconvAlignment, WuConfig, WuNet, WuVariant, conv_same, same_padding,
};
use hdrsynth::train::loss::{MU, mu_law, mu_law_l2, mu_law_psnr_loss, network2_batch};
use std::path::Path;

/// Burn's seed is global to the backend and the tests of this file run on parallel threads:
/// seeding and initialising under one lock keeps each test's initial weights reproducible.
fn seeded_init(cfg: &WuConfig, dev: &Device, seed: u64) -> WuNet {
    hdrsynth::models::seeded_init(dev, seed, || cfg.init(dev)).expect("init")
}

const TIMES: [f32; 3] = [0.25, 1.0, 4.0];

/// A smooth linear HDR image 3×h×w in [0.01, 1] (sums of a few random sinusoids).
fn smooth_hdr(h: usize, w: usize, seed: u64) -> Vec<f32> {
    let p = common::values(3 * 8, seed);
    let mut v = Vec::with_capacity(3 * h * w);
    for c in 0..3 {
        let q = &p[c * 8..c * 8 + 8];
        for y in 0..h {
            for x in 0..w {
                let (fy, fx) = (y as f32 / h as f32, x as f32 / w as f32);
                let s = (6.0 * q[0] * fx + 4.0 * q[1] * fy + 6.3 * q[2]).sin()
                    + (5.0 * q[3] * fy - 3.0 * q[4] * fx + 6.3 * q[5]).cos() * q[6];
                // In [−2, 2] → a log-spread radiance in [0.01, 1].
                let t = (s + 2.0) / 4.0;
                v.push(0.01 * 100f32.powf(t.clamp(0.0, 1.0)));
            }
        }
    }
    v
}

/// The loader's 18×h×w input for a static scene of radiance `hdr` (3×h×w, 1 = the reference
/// frame's white): per frame LDR = clip(hdr·t)^(1/2.2), quantised to 8 bits, then LDR^2.2/t.
fn input_for(hdr: &[f32], h: usize, w: usize) -> Vec<f32> {
    let n = h * w;
    let mut v = Vec::with_capacity(18 * n);
    for t in TIMES {
        let ldr: Vec<f32> = hdr
            .iter()
            .map(|&r| ((r * t).clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() / 255.0)
            .collect();
        v.extend_from_slice(&ldr);
        v.extend(ldr.iter().map(|l| l.powf(2.2) / t));
    }
    v
}

fn input(b: usize, h: usize, w: usize, seed: u64, dev: &Device) -> Tensor<4> {
    let mut v = Vec::with_capacity(b * 18 * h * w);
    for i in 0..b {
        v.extend(input_for(&smooth_hdr(h, w, seed + i as u64), h, w));
    }
    Tensor::from_data(TensorData::new(v, [b, 18, h, w]), dev)
}

fn to_vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().try_to_vec::<f32>().expect("f32 data")
}

fn tiny_resnet() -> WuConfig {
    WuConfig::resnet(4)
}

#[test]
fn parameter_count_matches_hand_count() {
    // Hand count, default ResNet (b = 64; every convolution has a bias, k²·cin·cout + cout):
    // encoder ×3: conv 6→64 9 664, conv 64→128 204 928, BN 256 → 214 848 each, 644 544;
    // merger conv 384→256 2 457 856 + BN 512; 9 residual blocks × (2 × (3·3·256·256 + 256)
    // + 2 × 512) = 9 × 1 181 184 = 10 630 656;
    // decoder deconv 512→128 1 638 528 + BN 256, deconv 512→64 819 264 + BN 128,
    // deconv 256→64 409 664 + BN 128; out conv 64→3 4 803.
    assert_eq!(WuConfig::default().trainable_parameters(), 16_606_339);
    // Default U-Net (merger 256, 512, 512): encoders 644 544; merger 2 458 368 + 3 278 336
    // + 6 555 136; decoder 512→512 6 555 136, 1024→256 6 554 368, 512→128 1 638 784,
    // 512→64 819 392, 256→64 409 792; out 4 803.
    assert_eq!(WuConfig::unet(64).trainable_parameters(), 28_918_659);
    // Tiny ResNet (b = 4): encoders 3 × (604 + 808 + 16) = 4 284; merger 9 616 + 32;
    // residual 9 × (2 × 2 320 + 64) = 42 336; decoder 6 408 + 16, 3 204 + 8, 1 604 + 8; out 303.
    assert_eq!(tiny_resnet().trainable_parameters(), 67_819);
    // Burn's count also has BatchNorm's running mean and variance, 2 per BN channel:
    // 3·8 + 16 + 18·16 + 8 + 4 + 4 = 344 channels.
    let model = seeded_init(&tiny_resnet(), &Device::flex(), 0);
    assert_eq!(model.num_params(), 67_819 + 688);
    // Default: 3·128 + 256 + 18·256 + 128 + 64 + 64 = 5 504 BN channels.
    let model = seeded_init(&WuConfig::default(), &Device::flex(), 0);
    assert_eq!(model.num_params(), 16_606_339 + 11_008);
    let model = seeded_init(&WuConfig::unet(4), &Device::flex(), 0);
    assert_eq!(
        model.num_params(),
        WuConfig::unet(4).trainable_parameters() + 2 * (3 * 8 + 16 + 32 + 32 + 32 + 16 + 8 + 4 + 4)
    );
}

#[test]
fn padding_conventions_follow_tensorflow() {
    // ops.conv2d: total k − s when size % s == 0, else k − size % s; the smaller half first.
    assert_eq!(same_padding(8, 5, 2), (1, 2));
    assert_eq!(same_padding(7, 5, 2), (2, 2));
    assert_eq!(same_padding(8, 5, 1), (2, 2));
    assert_eq!(same_padding(8, 3, 1), (1, 1));
    let dev = Device::flex();
    // Reflection without repeating the edge: [1 2 3 4] padded (2, 1) → [3 2 | 1 2 3 4 | 3].
    let x = Tensor::<4>::from_floats([[[[1.0, 2.0, 3.0, 4.0]]]], &dev);
    assert_eq!(
        to_vec(reflect_pad(x, (0, 0), (2, 1))),
        vec![3.0, 2.0, 1.0, 2.0, 3.0, 4.0, 3.0]
    );
    // Beyond what TensorFlow accepts the reflection continues periodically; length 1 repeats.
    let x = Tensor::<4>::from_floats([[[[1.0, 2.0]]]], &dev);
    assert_eq!(
        to_vec(reflect_pad(x, (0, 0), (3, 3))),
        vec![2.0, 1.0, 2.0, 1.0, 2.0, 1.0, 2.0, 1.0]
    );
    let x = Tensor::<4>::from_floats([[[[5.0]]]], &dev);
    assert_eq!(to_vec(reflect_pad(x, (1, 2), (0, 0))), vec![5.0; 4]);

    // Stride-2 5×5 convolution of an 8×8 image: y[i] = Σₖ x[2i + k − 1]·w[k] per axis. A delta
    // at (2, 2) (away from the border) reaches y[0][0] through w[3][3], y[0][1] through w[3][1]
    // and y[1][1] through w[1][1].
    let conv = burn::nn::conv::Conv2dConfig::new([1, 1], [5, 5])
        .with_stride([2, 2])
        .with_bias(false);
    let mut conv = hdrsynth::models::seeded_init(&dev, 0, || Ok(conv.init(&dev))).expect("init");
    let w: Vec<f32> = (0..25).map(|i| (10 * (i / 5) + i % 5) as f32).collect();
    conv.weight = burn::module::Param::from_tensor(Tensor::from_data(
        TensorData::new(w.clone(), [1, 1, 5, 5]),
        &dev,
    ));
    let mut delta = vec![0.0f32; 64];
    delta[2 * 8 + 2] = 1.0;
    let y = to_vec(conv_same(
        &conv,
        Tensor::from_data(TensorData::new(delta.clone(), [1, 1, 8, 8]), &dev),
    ));
    assert_eq!(y.len(), 16);
    assert_eq!((y[0], y[1], y[5]), (w[3 * 5 + 3], w[3 * 5 + 1], w[5 + 1]));

    // Transposed 5×5 stride-2: TensorFlow 'SAME' puts input i at outputs 2i + k − 1, the
    // PyTorch port at 2i + k − 2. A delta at input (0, 0) of a 2×2 image gives a 4×4 output
    // equal to w[1..5][1..5] (TensorFlow) or w[2..5][2..5] then zeros (PyTorch).
    for align in [DeconvAlignment::Tensorflow, DeconvAlignment::Pytorch] {
        let (padding, padding_out) = align.paddings();
        let deconv = burn::nn::conv::ConvTranspose2dConfig::new([1, 1], [5, 5])
            .with_stride([2, 2])
            .with_padding([padding, padding])
            .with_padding_out([padding_out, padding_out])
            .with_bias(false);
        let mut deconv =
            hdrsynth::models::seeded_init(&dev, 0, || Ok(deconv.init(&dev))).expect("init");
        deconv.weight = burn::module::Param::from_tensor(Tensor::from_data(
            TensorData::new(w.clone(), [1, 1, 5, 5]),
            &dev,
        ));
        let x = Tensor::<4>::from_floats([[[[1.0, 0.0], [0.0, 0.0]]]], &dev);
        let y = wu::deconv_same(&deconv, x, align);
        assert_eq!(y.dims(), [1, 1, 4, 4]);
        let y = to_vec(y);
        let shift = match align {
            DeconvAlignment::Tensorflow => 1,
            DeconvAlignment::Pytorch => 2,
        };
        for oy in 0..4 {
            for ox in 0..4 {
                let (ky, kx) = (oy + shift, ox + shift);
                let expect = if ky < 5 && kx < 5 {
                    w[ky * 5 + kx]
                } else {
                    0.0
                };
                assert_eq!(y[oy * 4 + ox], expect, "{align:?} at ({oy}, {ox})");
            }
        }
    }
}

fn assert_unit_range(out: Tensor<4>) {
    let v = to_vec(out);
    assert!(
        v.iter().all(|x| (0.0..=1.0).contains(x)),
        "output outside [0, 1]"
    );
    // A freshly initialised network is not saturated: some spread around 0.5.
    let (lo, hi) = v
        .iter()
        .fold((1.0f32, 0.0f32), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    assert!(lo < hi, "constant output");
}

#[test]
fn resnet_shapes_at_several_sizes() {
    let dev = Device::flex();
    let model = seeded_init(&tiny_resnet(), &dev, 1);
    assert_eq!(model.size_multiple(), 8);
    for (b, h, w) in [(2, 16, 16), (1, 8, 8), (1, 24, 40)] {
        let out = model.forward(input(b, h, w, 3, &dev));
        assert_eq!(out.dims(), [b, 3, h, w]);
        assert_unit_range(out);
    }
    for (h, w) in [(13, 21), (1, 1), (8, 3), (30, 17)] {
        let out = model.forward_padded(input(1, h, w, 5, &dev));
        assert_eq!(out.dims(), [1, 3, h, w], "{h}×{w}");
        assert!(to_vec(out).iter().all(|x| (0.0..=1.0).contains(x)));
    }
    // On a valid size the padded variant is the plain forward.
    let x = input(1, 16, 8, 4, &dev);
    assert_eq!(
        to_vec(model.forward_padded(x.clone())),
        to_vec(model.forward(x))
    );
    // Training mode (autodiff device) gives the same shapes.
    let ad = Device::flex().autodiff();
    let model = seeded_init(&tiny_resnet(), &ad, 1);
    assert_eq!(
        model.forward(input(2, 16, 24, 3, &ad)).dims(),
        [2, 3, 16, 24]
    );
}

#[test]
fn unet_shapes_at_several_sizes() {
    let dev = Device::flex();
    let cfg = WuConfig::unet(4);
    let model = seeded_init(&cfg, &dev, 2);
    // Two encoder steps and three merger steps.
    assert_eq!(model.size_multiple(), 32);
    for (b, h, w) in [(2, 32, 32), (1, 64, 32)] {
        let out = model.forward(input(b, h, w, 6, &dev));
        assert_eq!(out.dims(), [b, 3, h, w]);
        assert_unit_range(out);
    }
    for (h, w) in [(20, 37), (5, 5)] {
        let out = model.forward_padded(input(1, h, w, 7, &dev));
        assert_eq!(out.dims(), [1, 3, h, w]);
        assert!(to_vec(out).iter().all(|x| (0.0..=1.0).contains(x)));
    }
    // A one-level U-Net merger and the PyTorch deconvolution alignment.
    let cfg = WuConfig {
        unet_merger_widths: vec![2],
        deconv_alignment: DeconvAlignment::Pytorch,
        ..WuConfig::unet(4)
    };
    let model = seeded_init(&cfg, &dev, 2);
    assert_eq!(model.size_multiple(), 8);
    assert_eq!(
        model.forward(input(1, 16, 8, 8, &dev)).dims(),
        [1, 3, 16, 8]
    );
}

#[test]
fn input_checks_and_config() {
    let dev = Device::flex();
    let model = seeded_init(&tiny_resnet(), &dev, 0);
    assert!(model.check_input(18, 16, 24).is_ok());
    let e = model.check_input(18, 16, 12).unwrap_err().to_string();
    assert!(e.contains("multiple of 8"), "{e}");
    let e = model.check_input(6, 16, 16).unwrap_err().to_string();
    assert!(e.contains("18"), "{e}");
    assert!(model.check_input(18, 0, 8).is_err());

    let c: WuConfig = toml::from_str("").expect("empty");
    assert_eq!(c, WuConfig::default());
    assert_eq!(
        (
            c.variant,
            c.base_width,
            c.res_blocks,
            c.unet_merger_widths.clone()
        ),
        (WuVariant::Resnet, 64, 9, vec![4, 8, 8])
    );
    assert_eq!(
        (c.deconv_alignment, c.hdr_input_scale),
        (DeconvAlignment::Tensorflow, 0.25)
    );
    let c: WuConfig = toml::from_str(
        "variant = \"unet\"\nbase_width = 8\nunet_merger_widths = [4, 8]\n\
         deconv_alignment = \"pytorch\"\nhdr_input_scale = 1.0",
    )
    .expect("cfg");
    assert_eq!(c.variant, WuVariant::Unet);
    assert_eq!(c.size_multiple(), 16);
    assert!(toml::from_str::<WuConfig>("width = 8").is_err());
    assert!(toml::from_str::<WuConfig>("variant = \"vgg\"").is_err());
    for bad in [
        WuConfig::resnet(0),
        WuConfig {
            unet_merger_widths: vec![],
            ..WuConfig::unet(4)
        },
        WuConfig {
            hdr_input_scale: 0.0,
            ..WuConfig::default()
        },
    ] {
        assert!(bad.init(&dev).is_err(), "{bad:?}");
    }
    // The HDR input scale changes the mapping of the HDR channels only.
    let scaled = seeded_init(
        &WuConfig {
            hdr_input_scale: 1.0,
            ..tiny_resnet()
        },
        &dev,
        9,
    );
    let plain = seeded_init(&tiny_resnet(), &dev, 9);
    let x = input(1, 8, 8, 1, &dev);
    assert_ne!(to_vec(scaled.forward(x.clone())), to_vec(plain.forward(x)));
}

#[test]
#[should_panic(expected = "is not a positive multiple of 8")]
fn forward_rejects_sizes_not_a_multiple_of_eight() {
    let dev = Device::flex();
    let model = seeded_init(&tiny_resnet(), &dev, 0);
    let _ = model.forward(input(1, 12, 16, 3, &dev));
}

/// T(x) = ln(1 + 5000x) / ln(5001): T(0.5) = ln 2501 / ln 5001 = 7.824446 / 8.517393 = 0.918643,
/// T(0.25) = ln 1251 / ln 5001 = 0.837310, T(0.01) = ln 51 / ln 5001 = 0.461623.
#[test]
fn mu_law_hand_values() {
    let dev = Device::flex();
    let t = mu_law(
        Tensor::<1>::from_floats([0.0, 1.0, 0.5, 0.25, 0.01, -0.1], &dev),
        MU,
    );
    let expect = [0.0, 1.0, 0.918_643_3, 0.837_310, 0.461_623_1, 0.0];
    for (a, b) in to_vec(t).iter().zip(expect) {
        assert!((a - b).abs() < 1e-6, "{a} vs {b}");
    }
    // Two elements: pred (0.5, 0.25), target (0, 0.01):
    // ((0.918643 − 0)² + (0.837310 − 0.461623)²) / 2 = (0.843905 + 0.141141) / 2 = 0.492523.
    let pred = Tensor::<4>::from_floats([[[[0.5, 0.25]]]], &dev);
    let target = Tensor::<4>::from_floats([[[[0.0, 0.01]]]], &dev);
    let l: f32 = mu_law_l2(pred.clone(), target).into_scalar();
    assert!((l - 0.492_523).abs() < 1e-5, "{l}");
    assert_eq!(mu_law_l2(pred.clone(), pred).into_scalar::<f32>(), 0.0);
}

/// The PSNR-averaged loss weighs each crop by its own error, unlike the pooled one. Two crops
/// of two elements: crop 1 pred (1, 1), target (0, 0): MSE 1; crop 2 pred (1, 0), target
/// (0, 0): MSE 0.5. Pooled: (1 + 1 + 1 + 0) / 4 = 0.75. PSNR-averaged:
/// (10·log10(1 + 1e-6) + 10·log10(0.5 + 1e-6)) / 2 = (4.3429e-6 − 3.010291) / 2 = −1.505143.
/// A crop with no error counts as 60 dB (−60).
#[test]
fn the_psnr_averaged_loss_by_hand() {
    let dev = Device::flex();
    let pred = Tensor::<4>::from_floats([[[[1.0, 1.0]]], [[[1.0, 0.0]]]], &dev);
    let target = Tensor::<4>::zeros([2, 1, 1, 2], &dev);
    let pooled: f32 = mu_law_l2(pred.clone(), target.clone()).into_scalar();
    assert!((pooled - 0.75).abs() < 1e-6, "{pooled}");
    let l: f32 = mu_law_psnr_loss(pred.clone(), target).into_scalar();
    assert!((l - -1.505_143).abs() < 1e-5, "{l}");
    let exact: f32 = mu_law_psnr_loss(pred.clone(), pred).into_scalar();
    assert!((exact - -60.0).abs() < 1e-4, "{exact}");
}

#[test]
fn batch_from_samples() {
    let dev = Device::flex();
    let sample = |k: f32, set: &str| Sample {
        input: (0..18 * 4).map(|i| i as f32 / 100.0 + k).collect(),
        channels: 18,
        size: 2,
        target: Target::Hdr((0..12).map(|i| i as f32 + k).collect()),
        exposure_times: TIMES.to_vec(),
        set: set.into(),
        iso: None,
    };
    let (x, t) = network2_batch(&[sample(3.0, "a"), sample(7.0, "b")], &dev).expect("batch");
    assert_eq!(x.dims(), [2, 18, 2, 2]);
    assert_eq!(t.dims(), [2, 3, 2, 2]);
    let xv = to_vec(x);
    // Sample 1, channel 17, pixel (y=1, x=0): index 17·4 + 2 = 70 → 0.70 + 7.
    assert!((xv[72 + 70] - 7.70).abs() < 1e-5);
    let tv = to_vec(t);
    assert_eq!(tv[12 + 5], 5.0 + 7.0);

    let mut classes = sample(1.0, "net1");
    classes.target = Target::Classes(vec![0; 4]);
    let e = network2_batch(&[sample(1.0, "a"), classes], &dev)
        .unwrap_err()
        .to_string();
    assert!(e.contains("'net1'"), "{e}");
    let mut six = sample(1.0, "six");
    six.channels = 6;
    six.input.truncate(24);
    assert!(network2_batch(&[six], &dev).is_err());
    let mut short = sample(1.0, "short");
    short.target = Target::Hdr(vec![0.0; 4]);
    assert!(network2_batch(&[short], &dev).is_err());
    assert!(network2_batch(&[], &dev).is_err());
}

/// PSNR of the μ-law tone-mapped images (peak 1), in dB.
fn psnr_t(mse: f32) -> f32 {
    10.0 * (1.0 / mse).log10()
}

#[test]
fn tiny_model_overfits_one_sample_with_adam() {
    let dev = Device::flex().autodiff();
    let cfg = WuConfig::resnet(8);
    let mut model = seeded_init(&cfg, &dev, 11);
    let (h, w) = (32, 32);
    // Target in the reference frame's linear scale, within [0.01, 1] (the tanh output's range).
    let hdr = smooth_hdr(h, w, 42);
    let x = Tensor::<4>::from_data(TensorData::new(input_for(&hdr, h, w), [1, 18, h, w]), &dev);
    let target = Tensor::<4>::from_data(TensorData::new(hdr, [1, 3, h, w]), &dev);
    let mut optim = AdamConfig::new().init();
    let (steps, lr) = (300, 2e-3);
    let mut losses = Vec::with_capacity(steps);
    for _ in 0..steps {
        let loss = mu_law_l2(model.forward(x.clone()), target.clone());
        let grads = GradientsParams::from_grads(loss.backward(), &model);
        model = optim.step(lr, model, grads);
        losses.push(loss.into_scalar::<f32>());
    }
    let (first, last) = (losses[0], *losses.last().unwrap());
    let best = losses.iter().copied().fold(f32::INFINITY, f32::min);
    // Evaluation on the same sample with the running statistics (inference mode).
    let eval = model.valid();
    let x_eval = x.clone().inner();
    let t_eval = target.clone().inner();
    let valid_mse: f32 = mu_law_l2(eval.forward(x_eval), t_eval).into_scalar();
    eprintln!(
        "overfit ResNet b=8 32×32: PSNR-T step 0 {:.2} dB, after {steps} steps {:.2} dB \
         (best {:.2}), inference mode {:.2} dB",
        psnr_t(first),
        psnr_t(last),
        psnr_t(best),
        psnr_t(valid_mse)
    );
    assert!(
        psnr_t(last) > 35.0,
        "PSNR-T {} dB after {steps} steps",
        psnr_t(last)
    );
}

/// The documented names (docs/network2.md) of a ResNet with base width b and `r` residual
/// blocks, with their shapes, written out by hand.
fn documented_resnet_names(b: usize, r: usize) -> Vec<(String, Vec<usize>)> {
    let mut v = Vec::new();
    let mut conv = |name: &str, shape: [usize; 4]| {
        v.push((format!("{name}.weight"), shape.to_vec()));
        v.push((format!("{name}.bias"), vec![shape[0]]));
    };
    for i in 0..3 {
        conv(&format!("encoders.{i}.conv1"), [b, 6, 5, 5]);
        conv(&format!("encoders.{i}.conv2"), [2 * b, b, 5, 5]);
    }
    conv("merger.down.0.conv", [4 * b, 6 * b, 5, 5]);
    for k in 0..r {
        conv(&format!("merger.res.{k}.conv1"), [4 * b, 4 * b, 3, 3]);
        conv(&format!("merger.res.{k}.conv2"), [4 * b, 4 * b, 3, 3]);
    }
    conv("decoder.out", [3, b, 5, 5]);
    // Transposed convolutions are [in, out, kh, kw].
    let mut deconv = |name: &str, shape: [usize; 4]| {
        v.push((format!("{name}.weight"), shape.to_vec()));
        v.push((format!("{name}.bias"), vec![shape[1]]));
    };
    deconv("decoder.up.0.deconv", [8 * b, 2 * b, 5, 5]);
    deconv("decoder.up.1.deconv", [8 * b, b, 5, 5]);
    deconv("decoder.up.2.deconv", [4 * b, b, 5, 5]);
    let mut bn = |name: String, c: usize| {
        for p in ["weight", "bias", "running_mean", "running_var"] {
            v.push((format!("{name}.{p}"), vec![c]));
        }
    };
    for i in 0..3 {
        bn(format!("encoders.{i}.bn2"), 2 * b);
    }
    bn("merger.down.0.bn".into(), 4 * b);
    for k in 0..r {
        bn(format!("merger.res.{k}.bn1"), 4 * b);
        bn(format!("merger.res.{k}.bn2"), 4 * b);
    }
    bn("decoder.up.0.bn".into(), 2 * b);
    bn("decoder.up.1.bn".into(), b);
    bn("decoder.up.2.bn".into(), b);
    v.sort();
    v
}

/// Known values for tensor number `k` (positive, so they also suit running variances).
fn known(k: usize, n: usize) -> Vec<f32> {
    (0..n).map(|j| 0.5 + k as f32 + j as f32 * 1e-3).collect()
}

/// Writes `tensors` (name, shape, values) as a SafeTensors file in f32 or f64.
fn write_safetensors(path: &Path, tensors: &[(String, Vec<usize>, Vec<f32>)], f64s: bool) {
    let bytes: Vec<Vec<u8>> = tensors
        .iter()
        .map(|(_, _, v)| {
            if f64s {
                v.iter().flat_map(|&x| (x as f64).to_le_bytes()).collect()
            } else {
                v.iter().flat_map(|x| x.to_le_bytes()).collect()
            }
        })
        .collect();
    let dtype = if f64s {
        safetensors::Dtype::F64
    } else {
        safetensors::Dtype::F32
    };
    let views: Vec<(String, safetensors::tensor::TensorView)> = tensors
        .iter()
        .zip(&bytes)
        .map(|((name, shape, _), b)| {
            (
                name.clone(),
                safetensors::tensor::TensorView::new(dtype, shape.clone(), b).expect("view"),
            )
        })
        .collect();
    safetensors::serialize_to_file(views, None, path).expect("write safetensors");
}

/// The model's tensors under their PyTorch-style names, with their f32 values.
fn model_tensors(model: &WuNet) -> Vec<(String, Vec<usize>, Vec<f32>)> {
    let mut v: Vec<_> = model
        .collect(None, Some(Box::new(BurnToPyTorchAdapter)), true)
        .into_iter()
        .map(|t| {
            let bytes = t.to_bytes().expect("bytes");
            let vals = bytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect();
            (t.name.clone(), t.shape.to_vec(), vals)
        })
        .collect();
    v.sort_by(|a, b| a.0.cmp(&b.0));
    v
}

#[test]
fn import_follows_the_documented_names_and_checks_the_file() {
    let dev = Device::flex();
    let cfg = WuConfig {
        res_blocks: 2,
        ..WuConfig::resnet(2)
    };
    let names = documented_resnet_names(2, 2);
    let model = seeded_init(&cfg, &dev, 3);
    let mut expected = expected_tensors(&model);
    expected.sort();
    assert_eq!(expected, names, "the model's names are the documented ones");

    let file: Vec<(String, Vec<usize>, Vec<f32>)> = names
        .iter()
        .enumerate()
        .map(|(k, (n, s))| (n.clone(), s.clone(), known(k, s.iter().product())))
        .collect();
    let dir = tempfile::tempdir().expect("tempdir");
    let good = dir.path().join("wu.safetensors");
    write_safetensors(&good, &file, false);
    let loaded = wu::import_weights(model, &good).expect("import");
    assert_eq!(
        model_tensors(&loaded),
        file,
        "loaded parameters equal the file's"
    );
    // The running statistics are used in inference: the output is finite and in range.
    let out = to_vec(loaded.forward(input(1, 8, 8, 2, &dev)));
    assert!(out.iter().all(|x| (0.0..=1.0).contains(x)));

    // Export writes the same names and values back.
    let exported = dir.path().join("exported.safetensors");
    wu::export_weights(&loaded, &exported).expect("export");
    let again = wu::import_weights(seeded_init(&cfg, &dev, 4), &exported).expect("re-import");
    assert_eq!(model_tensors(&again), file);

    // f64 files, an nn.DataParallel "module." prefix and num_batches_tracked are accepted.
    let mut wrapped: Vec<_> = file
        .iter()
        .map(|(n, s, v)| (format!("module.{n}"), s.clone(), v.clone()))
        .collect();
    wrapped.push((
        "module.encoders.0.bn2.num_batches_tracked".into(),
        vec![],
        vec![3.0],
    ));
    let f64_path = dir.path().join("f64.safetensors");
    write_safetensors(&f64_path, &wrapped, true);
    let loaded = wu::import_weights(seeded_init(&cfg, &dev, 5), &f64_path).expect("f64 import");
    for ((n, _, a), (_, _, b)) in model_tensors(&loaded).iter().zip(&file) {
        assert!(a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6), "{n}");
    }

    let fresh = || seeded_init(&cfg, &dev, 6);
    let err = |name: &str, tensors: &[(String, Vec<usize>, Vec<f32>)]| {
        let path = dir.path().join(name);
        write_safetensors(&path, tensors, false);
        let e = wu::import_weights(fresh(), &path).unwrap_err().to_string();
        assert!(e.contains(name), "error does not name the file: {e}");
        e
    };
    // A wrong shape names the key, both shapes and the file.
    let mut bad = file.clone();
    let i = bad
        .iter()
        .position(|(n, _, _)| n == "merger.res.1.conv2.weight")
        .unwrap();
    bad[i].1 = vec![8, 8, 5, 5];
    bad[i].2 = vec![0.0; 8 * 8 * 25];
    let e = err("shape.safetensors", &bad);
    assert!(
        e.contains("'merger.res.1.conv2.weight'")
            && e.contains("[8, 8, 5, 5]")
            && e.contains("[8, 8, 3, 3]"),
        "{e}"
    );
    // A missing key is named.
    let mut missing = file.clone();
    missing.retain(|(n, _, _)| n != "decoder.up.1.bn.running_var");
    let e = err("missing.safetensors", &missing);
    assert!(e.contains("decoder.up.1.bn.running_var"), "{e}");
    // So is a key of another naming scheme.
    let mut renamed = file.clone();
    let i = renamed
        .iter()
        .position(|(n, _, _)| n == "encoders.2.bn2.weight")
        .unwrap();
    renamed[i].0 = "encoders.2.bn2.gamma".into();
    let e = err("renamed.safetensors", &renamed);
    assert!(
        e.contains("encoders.2.bn2.weight") && e.contains("missing"),
        "{e}"
    );
    let mut extra = file.clone();
    extra.push(("decoder.head.weight".into(), vec![1], vec![1.0]));
    let e = err("extra.safetensors", &extra);
    assert!(e.contains("'decoder.head.weight'"), "{e}");
    // Files that are not SafeTensors, or absent.
    let pt = dir.path().join("wu.pt");
    std::fs::write(&pt, b"not a pickle").unwrap();
    let e = wu::import_weights(fresh(), &pt).unwrap_err().to_string();
    assert!(e.contains("wu.pt") && e.contains("SafeTensors"), "{e}");
    let junk = dir.path().join("junk.safetensors");
    std::fs::write(&junk, b"\x08\x00\x00\x00\x00\x00\x00\x00{}garbage").unwrap();
    let e = wu::import_weights(fresh(), &junk).unwrap_err().to_string();
    assert!(e.contains("junk.safetensors"), "{e}");
    let e = wu::import_weights(fresh(), dir.path().join("absent.safetensors"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("absent.safetensors"), "{e}");
}

/// The merge head (`output = "merge"`) before training is the triangle merge of its inputs:
/// the last convolution starts at zero, so the weights are the triangle's (each + ε, then
/// normalised). Hand values: a reference code I = 0.25 gives the short, middle and long frames
/// triangle weights 0, 0.5, 0.5; I = 0.75 gives 0.5, 0.5, 0; I = 1 gives 1, 0, 0.
#[test]
fn the_untrained_merge_head_is_the_triangle_merge() {
    let dev = Device::flex();
    let cfg = WuConfig {
        output: wu::WuOutput::Merge,
        ..WuConfig::resnet(2)
    };
    assert_eq!(
        cfg.trainable_parameters(),
        WuConfig::resnet(2).trainable_parameters() + 6 * 25 * 2 + 6,
        "the head predicts 9 channels instead of 3"
    );
    let net = seeded_init(&cfg, &dev, 7);
    let (h, w) = (8, 8);
    // Per pixel column x: a reference code, and HDR channels of each frame chosen by hand
    // (the head reads them as given: any curve, any noise).
    let cases: [(f32, [f32; 3]); 3] = [
        (0.25, [0.8, 0.10, 0.14]),
        (0.75, [0.6, 0.50, 0.40]),
        (1.0, [0.9, 1.00, 0.25]),
    ];
    let want = [
        (0.5 + 1e-3) * 0.10 / (1.0 + 3e-3)
            + (0.5 + 1e-3) * 0.14 / (1.0 + 3e-3)
            + 1e-3 * 0.8 / (1.0 + 3e-3),
        (0.5 + 1e-3) * 0.6 / (1.0 + 3e-3)
            + (0.5 + 1e-3) * 0.50 / (1.0 + 3e-3)
            + 1e-3 * 0.40 / (1.0 + 3e-3),
        (1.0 + 1e-3) * 0.9 / (1.0 + 3e-3) + 1e-3 * 1.00 / (1.0 + 3e-3) + 1e-3 * 0.25 / (1.0 + 3e-3),
    ];
    let n = h * w;
    let mut x = vec![0.0f32; 18 * n];
    for px in 0..n {
        let (code, hdr) = cases[(px % w) % 3];
        for f in 0..3 {
            for c in 0..3 {
                x[(6 * f + c) * n + px] = if f == 1 { code } else { 0.5 };
                x[(6 * f + 3 + c) * n + px] = hdr[f];
            }
        }
    }
    let y = to_vec(net.forward(Tensor::from_data(TensorData::new(x, [1, 18, h, w]), &dev)));
    for px in 0..n {
        let k = (px % w) % 3;
        for c in 0..3 {
            // The output unit is HDR × hdr_input_scale (0.25).
            let got = y[c * n + px] / 0.25;
            assert!(
                (got - want[k]).abs() < 1e-5,
                "pixel {px} channel {c}: {got} vs the triangle merge's {}",
                want[k]
            );
        }
    }
}

/// The merge head with `merge_prior = "robertson"` before training: each frame's weight is
/// OpenCV's Robertson weight of its code times code^(2·2.2) (∝ t² on a static pixel),
/// normalised over the frames, + ε, normalised again. Computed here in f64 from the formula
/// (w(z) = s·exp(−(4z − 2)²) + c, s = e⁴/(e⁴ − 1), c = 1/(1 − e⁴)). A pixel clipped in every
/// frame (codes 1, 1, 1) falls back to the triangle's weights (the short frame's value).
#[test]
fn the_untrained_robertson_merge_head_is_robertsons_merge() {
    let dev = Device::flex();
    let cfg = WuConfig {
        output: wu::WuOutput::Merge,
        merge_prior: wu::MergePrior::Robertson,
        ..WuConfig::resnet(2)
    };
    let net = seeded_init(&cfg, &dev, 7);
    let (h, w) = (8, 8);
    let n = h * w;
    // Per pixel column: the three frames' codes (EV −2, 0, +2 of one static radiance, and a
    // pixel clipped everywhere) and HDR channels chosen by hand.
    let cases: [([f32; 3], [f32; 3]); 3] = [
        ([0.1, 0.19, 0.35], [0.8, 0.10, 0.14]),
        ([0.4, 0.75, 1.0], [0.6, 0.50, 0.40]),
        ([1.0, 1.0, 1.0], [0.9, 1.00, 0.25]),
    ];
    let e4 = 4f64.exp();
    let rob = |z: f64| {
        let d = 4.0 * z - 2.0;
        ((e4 / (e4 - 1.0)) * (-d * d).exp() + 1.0 / (1.0 - e4)).max(0.0) * z.powf(4.4)
    };
    let eps = 1e-3f64;
    let want: Vec<f64> = cases
        .iter()
        .enumerate()
        .map(|(k, (codes, hdr))| {
            let p: [f64; 3] = if k == 2 {
                [1.0, 0.0, 0.0]
            } else {
                let a = codes.map(|z| rob(z as f64));
                let sum: f64 = a.iter().sum();
                a.map(|v| v / sum)
            };
            (0..3).map(|i| (p[i] + eps) * hdr[i] as f64).sum::<f64>() / (1.0 + 3.0 * eps)
        })
        .collect();
    // The long frame gets most of the first pixel, the clipped long frame nothing of the second.
    let a0 = cases[0].0.map(|z| rob(z as f64));
    assert!(a0[2] > 0.9 * a0.iter().sum::<f64>(), "{a0:?}");
    assert_eq!(rob(1.0), 0.0);
    let mut x = vec![0.0f32; 18 * n];
    for px in 0..n {
        let (codes, hdr) = cases[(px % w) % 3];
        for f in 0..3 {
            for c in 0..3 {
                x[(6 * f + c) * n + px] = codes[f];
                x[(6 * f + 3 + c) * n + px] = hdr[f];
            }
        }
    }
    let y = to_vec(net.forward(Tensor::from_data(TensorData::new(x, [1, 18, h, w]), &dev)));
    for px in 0..n {
        let k = (px % w) % 3;
        for c in 0..3 {
            let got = (y[c * n + px] / 0.25) as f64;
            assert!(
                (got - want[k]).abs() < 1e-5 * want[k].max(1.0),
                "pixel {px} channel {c}: {got} vs Robertson's merge {}",
                want[k]
            );
        }
    }
}

/// The kernel head (`output = "kernel"`) before training: the triangle weights on each frame's
/// centre tap and ε on its 8 neighbours, one softmax over the 27. On a uniform image every tap
/// holds the centre's value, so by hand out = (Σᵢ (wᵢ + ε)·Hᵢ + 8ε·Σᵢ Hᵢ) / (1 + 27ε); a lone
/// bright pixel leaks ε / (1 + 27ε) of its value into each neighbour, no more.
#[test]
fn the_untrained_kernel_head_is_the_triangle_merge_with_eps_neighbours() {
    let dev = Device::flex();
    let cfg = WuConfig {
        output: wu::WuOutput::Kernel,
        ..WuConfig::resnet(2)
    };
    let net = seeded_init(&cfg, &dev, 7);
    let (h, w) = (8, 8);
    let n = h * w;
    let (code, hdr) = (0.25f32, [0.8f32, 0.10, 0.14]);
    let eps = 1e-3f32;
    let tri = [0.0f32, 0.5, 0.5];
    let want = ((0..3).map(|i| (tri[i] + eps) * hdr[i]).sum::<f32>()
        + 8.0 * eps * hdr.iter().sum::<f32>())
        / (1.0 + 27.0 * eps);
    let mut x = vec![0.0f32; 18 * n];
    for px in 0..n {
        for f in 0..3 {
            for c in 0..3 {
                x[(6 * f + c) * n + px] = if f == 1 { code } else { 0.5 };
                x[(6 * f + 3 + c) * n + px] = hdr[f];
            }
        }
    }
    let run = |x: Vec<f32>| {
        to_vec(net.forward(Tensor::from_data(TensorData::new(x, [1, 18, h, w]), &dev)))
    };
    let y = run(x.clone());
    for (i, v) in y.iter().enumerate() {
        assert!(
            (v / 0.25 - want).abs() < 1e-5,
            "value {i}: {} vs {want}",
            v / 0.25
        );
    }
    // A lone bright long-frame pixel at (4, 4): its right neighbour gains ε/(1 + 27ε) of it.
    let bump = 10.0f32;
    let mut x2 = x;
    for c in 0..3 {
        x2[(6 * 2 + 3 + c) * n + 4 * w + 4] += bump;
    }
    let y2 = run(x2);
    let gain = (y2[4 * w + 5] - y[4 * w + 5]) / 0.25;
    let by_hand = eps * bump / (1.0 + 27.0 * eps);
    assert!((gain - by_hand).abs() < 1e-5, "{gain} vs {by_hand}");
}
