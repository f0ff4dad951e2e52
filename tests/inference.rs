//! Tiled full-resolution inference and Network-1's fusion stage, against hand values and an
//! untiled reference.

use hdrsynth::error::Result;
use hdrsynth::eval::blend::{
    BlendWeight, fuse, tone_curve, weight_from_logits, weight_from_probabilities,
};
use hdrsynth::eval::tiling::{Planar, Tiling, run_tiled, run_untiled};
use hdrsynth::io::Image;

fn reflect101(p: isize, n: usize) -> usize {
    let n = n as isize;
    let mut p = p;
    while p < 0 || p >= n {
        p = if p < 0 { -p } else { 2 * n - 2 - p };
    }
    p as usize
}

/// A (2r+1)² box mean with reflect-101 borders: receptive-field radius r.
fn box_filter(x: &Planar, r: isize) -> Result<Planar> {
    let mut out = Planar::new(x.channels, x.width, x.height);
    for c in 0..x.channels {
        for y in 0..x.height {
            for xx in 0..x.width {
                let mut s = 0.0;
                for dy in -r..=r {
                    for dx in -r..=r {
                        s += x.at(
                            c,
                            reflect101(xx as isize + dx, x.width),
                            reflect101(y as isize + dy, x.height),
                        );
                    }
                }
                out.data[(c * x.height + y) * x.width + xx] =
                    s / ((2 * r + 1) * (2 * r + 1)) as f32;
            }
        }
    }
    Ok(out)
}

fn random_planar(c: usize, w: usize, h: usize) -> Planar {
    let mut p = Planar::new(c, w, h);
    let mut s = 12345u64;
    for v in &mut p.data {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        *v = (s >> 40) as f32 / (1u64 << 24) as f32;
    }
    p
}

fn max_diff(a: &Planar, b: &Planar) -> f32 {
    a.data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn tiled_equals_untiled_when_the_receptive_field_fits_the_overlap() {
    let input = random_planar(2, 101, 77);
    let whole = box_filter(&input, 3).expect("untiled");
    for (tile, multiple) in [(32, 8), (40, 1), (16, 4), (17, 1)] {
        let t = Tiling {
            tile,
            overlap: 4,
            multiple,
        };
        let tiled = run_tiled(&input, 2, t, |x| box_filter(x, 3)).expect("tiled");
        let worst = max_diff(&whole, &tiled);
        assert!(
            worst <= 1e-6,
            "tile {tile}, multiple {multiple}: max diff {worst}"
        );
    }
    // With too little overlap the seams show: the test can fail.
    let t = Tiling {
        tile: 32,
        overlap: 1,
        multiple: 8,
    };
    let tiled = run_tiled(&input, 2, t, |x| box_filter(x, 3)).expect("tiled");
    let worst = max_diff(&whole, &tiled);
    assert!(
        worst > 1e-3,
        "seams expected with overlap 1 < radius 3 (max diff {worst})"
    );
}

#[test]
fn tiles_must_come_back_the_size_they_went_in() {
    let input = random_planar(1, 20, 20);
    let t = Tiling {
        tile: 8,
        overlap: 2,
        multiple: 4,
    };
    let err = run_tiled(&input, 1, t, |x| Ok(Planar::new(1, x.width + 1, x.height)))
        .expect_err("size mismatch");
    assert!(err.to_string().contains("expected"), "{err}");
}

#[test]
fn blend_weights_from_probabilities_by_hand() {
    // 4 classes, 2 pixels, C×P layout. Pixel 0: p = [0.1, 0.2, 0.3, 0.4] → E[c]/3 =
    // (0.2 + 0.6 + 1.2)/3 = 2/3; argmax 3 → 1. Pixel 1: p = [0.7, 0.1, 0.1, 0.1] → (0.1 + 0.2 +
    // 0.3)/3 = 0.2; argmax 0 → 0.
    let probs = [0.1, 0.7, 0.2, 0.1, 0.3, 0.1, 0.4, 0.1];
    let e = weight_from_probabilities(&probs, 4, 2, BlendWeight::Expected).expect("expected");
    assert!(
        (e[0] - 2.0 / 3.0).abs() < 1e-6 && (e[1] - 0.2).abs() < 1e-6,
        "{e:?}"
    );
    let a = weight_from_probabilities(&probs, 4, 2, BlendWeight::Argmax).expect("argmax");
    assert_eq!(a, vec![1.0, 0.0]);
    assert!(weight_from_probabilities(&probs, 4, 3, BlendWeight::Expected).is_err());
}

#[test]
fn exponential_tone_curve_by_hand() {
    assert_eq!(tone_curve(0.0, 4.0), 0.0);
    assert!((tone_curve(1.0, 4.0) - 1.0).abs() < 1e-6);
    // (1 − e^−2)/(1 − e^−4) = 0.864665/0.981684 = 0.880797
    assert!((tone_curve(0.5, 4.0) - 0.880_797).abs() < 1e-5);
    assert_eq!(tone_curve(0.3, 0.0), 0.3);
}

#[test]
fn fusion_with_all_or_nothing_weights_returns_one_input() {
    let low = Image::from_fn(37, 29, |x, y| [x as f32 / 40.0, y as f32 / 30.0, 0.2]);
    let high = low.map(|v| (v * 8.0).min(1.0));
    let n = low.pixel_count();
    let (l1, _) = fuse(&low, &high, &vec![1.0; n], 4.0).expect("fuse");
    let (l0, t0) = fuse(&low, &high, &vec![0.0; n], 4.0).expect("fuse");
    for i in 0..l1.data.len() {
        assert!((l1.data[i] - high.data[i]).abs() < 1e-5);
        assert!((l0.data[i] - low.data[i]).abs() < 1e-5);
        assert!((t0.data[i] - tone_curve(l0.data[i], 4.0)).abs() < 1e-6);
    }
}

#[test]
fn tiles_off_the_down_sampling_grid_are_refused() {
    let input = random_planar(1, 40, 40);
    let t = Tiling {
        tile: 17,
        overlap: 2,
        multiple: 4,
    };
    let err = run_tiled(&input, 1, t, |x| Ok(x.clone())).expect_err("off grid");
    assert!(err.to_string().contains("multiple"), "{err}");
}

/// The real Network-1 (tiny widths, depth 2; receptive-field radius 28 px): tiles with overlap ≥ 28 reproduce the untiled output.
#[test]
fn blend_unet_tiled_equals_untiled_when_the_overlap_covers_the_receptive_field() {
    use burn::module::Module;
    use burn::tensor::{Device, Tensor, TensorData};
    use hdrsynth::models::BlendUNetConfig;
    let cfg = BlendUNetConfig {
        base_width: 4,
        depth: 2,
        batch_norm: true,
        classes: 256,
    };
    assert_eq!(cfg.receptive_radius(), 28);
    assert_eq!(BlendUNetConfig::default().receptive_radius(), 124);
    let dev = Device::flex();
    let model = hdrsynth::models::seeded_init(&dev, 5, || cfg.init(&dev))
        .expect("init")
        .valid();
    // Smooth-ish content with edges, 6 channels, a size that is no multiple of anything.
    let (w, h) = (150, 101);
    let mut input = Planar::new(6, w, h);
    for c in 0..6 {
        for y in 0..h {
            for x in 0..w {
                let v = ((x as f32 * 0.07 + c as f32).sin() * (y as f32 * 0.05).cos() + 1.0) / 2.0;
                let edge = if (x + 2 * y + 7 * c) % 53 < 20 {
                    0.3
                } else {
                    0.0
                };
                input.data[(c * h + y) * w + x] = (v + edge).min(1.0);
            }
        }
    }
    // One class's logit: the untrained softmax is nearly uniform, so logits show seams best.
    let logit = |win: &Planar| -> Result<Planar> {
        let x = Tensor::<4>::from_data(
            TensorData::new(win.data.clone(), [1, 6, win.height, win.width]),
            &dev,
        );
        let data = model
            .forward(x)
            .slice([0..1, 100..101, 0..win.height, 0..win.width])
            .into_data()
            .try_to_vec::<f32>()
            .expect("f32");
        Ok(Planar {
            channels: 1,
            width: win.width,
            height: win.height,
            data,
        })
    };
    let whole = run_untiled(&input, 1, 28, 4, logit).expect("untiled");
    for tile in [32, 48] {
        let t = Tiling {
            tile,
            overlap: 28,
            multiple: 4,
        };
        let tiled = run_tiled(&input, 1, t, logit).expect("tiled");
        let worst = max_diff(&whole, &tiled);
        println!("tile {tile}, overlap 28: max |tiled − untiled| = {worst:e}");
        assert!(worst <= 1e-4, "tile {tile}: max diff {worst}");
    }
    // Too little context: seams.
    let t = Tiling {
        tile: 32,
        overlap: 4,
        multiple: 4,
    };
    let tiled = run_tiled(&input, 1, t, logit).expect("tiled");
    let worst = max_diff(&whole, &tiled);
    println!("tile 32, overlap 4: max |tiled − untiled| = {worst:e}");
    assert!(
        worst > 1e-4,
        "seams expected with overlap 4 < 28 (max diff {worst})"
    );
}

#[test]
fn blend_weights_from_logits_equal_the_softmax_route() {
    // By hand: logits (0, ln 2, ln 3, ln 4) are the probabilities (0.1, 0.2, 0.3, 0.4) → 2/3;
    // pixel 2: logits (5, 0, 0, 0) → argmax 0. C×P layout, 4 classes, 2 pixels.
    let l = [0.0, 5.0, 2f32.ln(), 0.0, 3f32.ln(), 0.0, 4f32.ln(), 0.0];
    let e = weight_from_logits(&l, 4, 2, BlendWeight::Expected).expect("expected");
    assert!((e[0] - 2.0 / 3.0).abs() < 1e-6, "{e:?}");
    let a = weight_from_logits(&l, 4, 2, BlendWeight::Argmax).expect("argmax");
    assert_eq!(a, vec![1.0, 0.0]);
    // 256 classes, 5000 pixels (more than one parallel chunk), large logits: softmax in f64.
    let (c, n) = (256, 5000);
    let logits: Vec<f32> = random_planar(c, n, 1)
        .data
        .iter()
        .map(|v| 40.0 * v - 20.0)
        .collect();
    let mut probs = vec![0.0f32; c * n];
    for p in 0..n {
        let m = (0..c)
            .map(|k| logits[k * n + p] as f64)
            .fold(f64::MIN, f64::max);
        let z: f64 = (0..c).map(|k| (logits[k * n + p] as f64 - m).exp()).sum();
        for k in 0..c {
            probs[k * n + p] = ((logits[k * n + p] as f64 - m).exp() / z) as f32;
        }
    }
    for mode in [BlendWeight::Expected, BlendWeight::Argmax] {
        let a = weight_from_logits(&logits, c, n, mode).expect("logits");
        let b = weight_from_probabilities(&probs, c, n, mode).expect("probabilities");
        let worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f32::max);
        assert!(worst < 1e-5, "{mode:?}: {worst}");
    }
    assert!(weight_from_logits(&l, 4, 3, BlendWeight::Expected).is_err());
}
