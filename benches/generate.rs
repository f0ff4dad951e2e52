//! Scene-engine throughput: Mpix of output frames per second (static + dynamic display frames
//! per EV), rendering and tone mapping only (no file writes), at 1920×1080 and 4032×3024.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use hdrsynth::data::generate::GenerateConfig;
use hdrsynth::data::scene::Generator;
use std::time::Duration;

fn config(width: usize, height: usize) -> GenerateConfig {
    let text = format!(
        "seed = 7\ncount = 1\nwidth = {width}\nheight = {height}\nevs = [-2.0, 0.0, 2.0]\n"
    );
    toml::from_str(&text).expect("bench config")
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("generate");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    for (w, h) in [(1920usize, 1080usize), (4032, 3024)] {
        let cfg = config(w, h);
        let generator = Generator::new(&cfg).expect("generator");
        // Six output frames per sample: static and dynamic at three EVs.
        g.throughput(Throughput::Elements((6 * w * h) as u64));
        let mut index = 0u64;
        g.bench_function(format!("{w}x{h}"), |b| {
            b.iter(|| {
                let s = generator.render(index);
                index += 1;
                let curve = cfg.tone_curve;
                // Tone-map every display frame as `generate` does before encoding.
                let mut acc = 0.0f32;
                for (i, dynamic) in s.dynamic_radiance.iter().enumerate() {
                    for img in [&s.static_radiance, dynamic] {
                        let f = curve.display(img, s.frame_gain(i));
                        acc += f.data[0];
                    }
                }
                acc
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
