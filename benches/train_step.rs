//! One training step of each network exactly as the trainer runs it (`train::train_step`:
//! batch assembly from loader samples, forward, loss, loss read-back, backward, Adam update),
//! default widths, on the backend named by `HDRSYNTH_BENCH_BACKEND` (default flex) with
//! autodiff:
//! - Network-1: batch 4 of 6×128×128 (Eq. 4 loss);
//! - Network-2: batch 4 of 18×256×256 (μ-law L2), the authors' patch size.
//!
//! Throughput is reported in samples/s. `HDRSYNTH_BENCH_CONV=im2col` turns flex's Winograd
//! convolutions off (`kernels::conv::set_winograd`), to compare the two in one build.

#[path = "../tests/common/mod.rs"]
mod common;

use burn::optim::AdamConfig;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use hdrsynth::data::ground_truth::{ClassWeights, MertensWeights};
use hdrsynth::data::loader::{Sample, Target};
use hdrsynth::models::{BlendUNetConfig, WuConfig};
use hdrsynth::train::loss::Network1Reading;
use hdrsynth::train::task::{Network1, Network2, Task};
use hdrsynth::train::train_step;
use std::time::{Duration, Instant};

const BATCH: usize = 4;

fn samples(channels: usize, size: usize, hdr: bool) -> Vec<Sample> {
    (0..BATCH)
        .map(|i| Sample {
            input: common::values(channels * size * size, 10 + i as u64),
            channels,
            size,
            target: if hdr {
                Target::Hdr(common::values(3 * size * size, 20 + i as u64))
            } else {
                Target::Classes(
                    common::values(size * size, 20 + i as u64)
                        .iter()
                        .map(|v| (v * 256.0) as u8)
                        .collect(),
                )
            },
            exposure_times: vec![],
            set: format!("bench{i}"),
            iso: None,
        })
        .collect()
}

fn bench_task<T: Task>(c: &mut Criterion, name: &str, task: &T, batch: &[Sample]) {
    let backend = std::env::var("HDRSYNTH_BENCH_BACKEND").unwrap_or_else(|_| "flex".into());
    let dev = hdrsynth::device::device_from_name(&backend)
        .expect("backend")
        .autodiff();
    let mut model = Some(hdrsynth::models::seeded_init(&dev, 1, || task.init(&dev)).expect("init"));
    let mut optim = AdamConfig::new().init();
    let mut step = || {
        let (m, loss) = train_step(
            task,
            model.take().expect("model"),
            &mut optim,
            1e-4,
            batch,
            &dev,
        )
        .expect("step");
        model = Some(m);
        loss
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
        "{name} ({backend}): {per:.3} s/step, {:.2} samples/s",
        BATCH as f64 / per
    );
    let mut g = c.benchmark_group("train_step");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(20));
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function(format!("{name}/{backend}"), |b| b.iter(&mut step));
    g.finish();
}

fn bench(c: &mut Criterion) {
    // As the binary does (src/main.rs): keep freed activations in the heap.
    hdrsynth::device::retain_freed_memory();
    #[cfg(feature = "flex")]
    if std::env::var("HDRSYNTH_BENCH_CONV").is_ok_and(|v| v == "im2col") {
        hdrsynth::kernels::conv::set_winograd(false);
    }
    let alpha = ClassWeights::new(
        &std::array::from_fn(|i| 1 + i as u64),
        MertensWeights::OPENCV_DEFAULT,
        1,
    );
    // The paper's Eq. 4, the reading the recorded timings were taken with.
    let net1 = Network1 {
        config: BlendUNetConfig::default(),
        alpha,
        reading: Network1Reading::Literal,
        label_sigma: hdrsynth::train::config::DEFAULT_LABEL_SIGMA,
    };
    bench_task(c, "network1/b4/128px", &net1, &samples(6, 128, false));
    let net2 = Network2::new(WuConfig::default(), &Default::default());
    bench_task(c, "network2/b4/256px", &net2, &samples(18, 256, true));
}

criterion_group!(benches, bench);
criterion_main!(benches);
