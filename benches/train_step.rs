//! One Network-1 training step — forward, softmax, Eq. 4 loss, backward, Adam update — at batch
//! 4 of 6×128×128 inputs with the default widths (32 … 512, BatchNorm, 256 classes), on the
//! flex CPU backend with autodiff. Throughput is reported in samples/s (4 per step).

use burn::optim::AdamConfig;
use burn::tensor::{Device, Int, Tensor, TensorData};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use hdrsynth::models::BlendUNetConfig;
use hdrsynth::train::network1_step;
use std::time::{Duration, Instant};

const BATCH: usize = 4;
const SIZE: usize = 128;

/// Deterministic values in [0, 1) (splitmix64).
fn values(n: usize, seed: u64) -> Vec<f32> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let dev = Device::flex().autodiff();
    dev.seed(1);
    let cfg = BlendUNetConfig::default();
    let mut model = Some(cfg.init(&dev).expect("init"));
    let x = Tensor::<4>::from_data(
        TensorData::new(values(BATCH * 6 * SIZE * SIZE, 2), [BATCH, 6, SIZE, SIZE]),
        &dev,
    );
    let classes: Vec<i32> = values(BATCH * SIZE * SIZE, 3)
        .iter()
        .map(|v| (v * 256.0) as i32)
        .collect();
    let target = Tensor::<3, Int>::from_data(TensorData::new(classes, [BATCH, SIZE, SIZE]), &dev);
    let alpha = Tensor::<1>::from_data(
        TensorData::new(values(256, 4).iter().map(|v| 0.5 + v).collect(), [256]),
        &dev,
    );
    let mut optim = AdamConfig::new().init();
    let mut step = || {
        let m = model.take().expect("model");
        let (m, loss) = network1_step(
            m,
            &mut optim,
            1e-4,
            x.clone(),
            target.clone(),
            alpha.clone(),
        );
        model = Some(m);
        loss.into_scalar::<f32>()
    };

    // A plain timing first, so the figure is in the log even without criterion's report.
    step();
    let n = 3;
    let t0 = Instant::now();
    for _ in 0..n {
        step();
    }
    let per = t0.elapsed().as_secs_f64() / n as f64;
    eprintln!(
        "train_step (flex, batch {BATCH}, {SIZE}×{SIZE}, {} trainable parameters): \
         {per:.3} s/step, {:.2} samples/s",
        cfg.trainable_parameters(),
        BATCH as f64 / per
    );

    let mut g = c.benchmark_group("train_step");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(20));
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function(format!("network1/flex/b{BATCH}/{SIZE}px"), |b| {
        b.iter(&mut step)
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
