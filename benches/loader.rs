//! Loader throughput (samples/s) with full realism: Network-2 samples at 256×256 and Network-1
//! samples at 128×128, on 1 and 2 workers. The dataset (16 sets, 512×384) is generated first.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use hdrsynth::config::parse_toml;
use hdrsynth::data::generate::GenerateConfig;
use hdrsynth::data::loader::{Loader, LoaderConfig};
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

fn dataset(evs: &str, dir: &Path) {
    let text = format!(
        "seed = 3\ncount = 16\nwidth = 512\nheight = 384\nevs = {evs}\nwrite_linear = false\n"
    );
    let mut c: GenerateConfig = parse_toml(&text, Path::new("bench.toml")).expect("config");
    c.source = None;
    hdrsynth::data::generate::generate(&c, dir, false).expect("generate");
}

fn bench(c: &mut Criterion) {
    let profile =
        hdrsynth::sensor::profile::SensorProfile::shipped_dir().join("canon_eos_550d.toml");
    let mut g = c.benchmark_group("loader");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for (kind, evs, patch) in [
        ("network2", "[-2.0, 0.0, 2.0]", 256),
        ("network1", "[-3.0, 0.0]", 128),
    ] {
        let dir = tempfile::tempdir().expect("tmp");
        dataset(evs, dir.path());
        for workers in [1usize, 2] {
            let text = format!(
                "dataset = {:?}\nkind = \"{kind}\"\npatch = {patch}\nbatch_size = 8\nworkers = {workers}\nseed = 1\n\
                 [realism]\nprofile = {:?}\nisos = [100.0, 800.0, 3200.0]\n",
                dir.path(),
                profile
            );
            let cfg: LoaderConfig =
                parse_toml(&text, Path::new("loader.toml")).expect("loader config");
            let loader = Arc::new(Loader::new(&cfg).expect("loader"));
            g.throughput(Throughput::Elements(loader.len() as u64));
            let mut e = 0u64;
            g.bench_function(format!("{kind}/{patch}px/{workers}w"), |b| {
                b.iter(|| {
                    e += 1;
                    loader
                        .epoch(e)
                        .map(|b| b.expect("batch").len())
                        .sum::<usize>()
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
