//! Realism operator throughput at 4032×3024 (Mpix/s), on 1 and 2 threads, Gaussian noise
//! (the paper's model) and exact Poisson-Gaussian, output buffer reused as a loader would.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use hdrsynth::io::Image;
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::sensor::realism::{NoiseModel, Realism, RealismOptions};
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let profile = SensorProfile::load(&SensorProfile::shipped_dir().join("example_synthetic.toml"))
        .expect("profile");
    let (w, h) = (4032usize, 3024usize);
    let input = Image::from_fn(w, h, |x, y| {
        let v = ((x * 7 + y * 13) % 1000) as f32 / 1000.0;
        [v, (v * 0.8 + 0.1).min(1.0), 1.0 - v]
    });
    let mut g = c.benchmark_group("realism");
    g.sample_size(10).measurement_time(Duration::from_secs(15));
    g.throughput(Throughput::Elements((w * h) as u64));
    for noise in [
        NoiseModel::Gaussian,
        NoiseModel::None,
        NoiseModel::PoissonGaussian,
    ] {
        let mut opts = RealismOptions::new(800.0);
        opts.noise = noise;
        let r = Realism::new(&profile, &opts).expect("realism");
        for threads in [1usize, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            let mut seed = 0u64;
            let mut out = Image::new(w, h);
            g.bench_function(format!("{noise:?}/4032x3024/{threads}t"), |b| {
                b.iter(|| {
                    seed += 1;
                    pool.install(|| r.apply_into(&input, seed, &mut out))
                })
            });
        }
    }
    // The effect path (docs/diagnose.md): the profile with five catalogue effects.
    let mut with = profile.clone();
    for (id, params) in [
        ("vignetting", "strength = 0.2"),
        ("prnu", "sigma = 0.01\nseed = 1"),
        ("row_noise", "sigma_dn = 1.0"),
        ("column_noise", "sigma_dn = 1.0\nseed = 2"),
        ("dsnu", "sigma_dn = 1.0\nseed = 3"),
    ] {
        with.effects.push(hdrsynth::sensor::profile::EffectSpec {
            id: id.into(),
            params: params.parse().expect("params"),
        });
    }
    let r = Realism::new(&with, &RealismOptions::new(800.0)).expect("realism");
    let mut seed = 0u64;
    let mut out = Image::new(w, h);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    g.bench_function("Gaussian+5effects/4032x3024/1t", |b| {
        b.iter(|| {
            seed += 1;
            pool.install(|| r.apply_into(&input, seed, &mut out))
        })
    });
    // Chroma noise alone: the three draws of every pixel mixed.
    let mut chroma = profile.clone();
    chroma.effects.push(hdrsynth::sensor::profile::EffectSpec {
        id: "channel_correlation".into(),
        params: "rho = 0.3".parse().expect("params"),
    });
    let r = Realism::new(&chroma, &RealismOptions::new(800.0)).expect("realism");
    g.bench_function("Gaussian+channel_correlation/4032x3024/1t", |b| {
        b.iter(|| {
            seed += 1;
            pool.install(|| r.apply_into(&input, seed, &mut out))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
