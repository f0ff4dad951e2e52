//! Burn's LibTorch backend (`--features tch`): the device name resolves, and a short
//! seeded training of each network on it is repeatable bit for bit (same seed, same threads)
//! and lowers the loss on a fixed batch. Built only with the `tch` feature (not in CI: it needs
//! an installed libtorch, docs/training.md).
#![cfg(feature = "tch")]

mod common;

use burn::optim::AdamConfig;
use hdrsynth::data::ground_truth::{ClassWeights, MertensWeights};
use hdrsynth::data::loader::Sample;
use hdrsynth::models::seeded_init;
use hdrsynth::models::{BlendUNetConfig, WuConfig};
use hdrsynth::train::loss::Network1Reading;
use hdrsynth::train::task::{Network1, Network2, Task};
use hdrsynth::train::train_step;

fn batch(channels: usize, size: usize, hdr: bool) -> Vec<Sample> {
    common::samples(2, channels, size, hdr)
}

/// Losses of `steps` Adam steps on one fixed batch, from a seeded initialisation.
fn losses<T: Task>(task: &T, batch: &[Sample], steps: usize) -> Vec<f64> {
    let dev = hdrsynth::device::device_from_name("tch")
        .expect("tch device")
        .autodiff();
    let mut model = Some(seeded_init(&dev, 7, || task.init(&dev)).expect("init"));
    let mut optim = AdamConfig::new().init();
    (0..steps)
        .map(|_| {
            let m = model.take().expect("model");
            let (m, loss) = train_step(task, m, &mut optim, 1e-3, batch, &dev).expect("step");
            model = Some(m);
            loss
        })
        .collect()
}

fn check<T: Task>(name: &str, task: &T, batch: &[Sample]) {
    let a = losses(task, batch, 4);
    let b = losses(task, batch, 4);
    assert_eq!(a, b, "{name}: two seeded runs on tch differ");
    assert!(a.iter().all(|l| l.is_finite()), "{name}: {a:?}");
    assert!(
        a[3] < a[0],
        "{name}: the loss did not fall on a fixed batch: {a:?}"
    );
}

#[test]
fn libtorch_device_names() {
    assert!(hdrsynth::device::device_from_name("tch").is_ok());
    assert!(hdrsynth::device::device_from_name("libtorch").is_ok());
    assert!(hdrsynth::device::compiled_backends().contains(&"tch"));
}

#[test]
fn seeded_training_on_tch_is_repeatable_and_learns() {
    let net1 = Network1 {
        config: BlendUNetConfig {
            base_width: 4,
            depth: 2,
            ..BlendUNetConfig::default()
        },
        alpha: ClassWeights::new(
            &std::array::from_fn(|i| 1 + i as u64),
            MertensWeights::OPENCV_DEFAULT,
            1,
        ),
        reading: Network1Reading::Literal,
        label_sigma: hdrsynth::train::config::DEFAULT_LABEL_SIGMA,
    };
    check("Network-1", &net1, &batch(6, 32, false));
    let net2 = Network2 {
        unit: Default::default(),
        config: WuConfig {
            base_width: 4,
            res_blocks: 1,
            ..WuConfig::default()
        },
    };
    check("Network-2", &net2, &batch(18, 32, true));
}
