//! `hdrsynth diagnose` time on 12 bursts × 50 frames × 1 Mpix (1024×1024) against the time
//! just to decode those PNGs. Not a criterion bench: one diagnosis takes minutes.
//!
//! `cargo bench --bench diagnose` (env: HDRSYNTH_BENCH_DIR to keep the capture set between
//! runs, default a temp folder; HDRSYNTH_BENCH_REPLICATES, default 30; HDRSYNTH_BENCH_SIZE,
//! default 1024; HDRSYNTH_BENCH_FRAMES, default 50; HDRSYNTH_BENCH_MAX_PIXELS, default the
//! diagnosis's, 0 to analyse every row). The capture set: ISO 100, 400, 1600, each a
//! dark burst and flats at 10 %, 30 % and 60 % of the range, simulated from an invented
//! profile with no extra effects (so the diagnosis makes one comparison and names nothing).

use hdrsynth::io::{BitDepth, Image, write_ldr};
use hdrsynth::rng::hash;
use hdrsynth::sensor::captures::{Burst, BurstKind, CaptureManifest, CaptureSet, MANIFEST_NAME};
use hdrsynth::sensor::diagnose::{DiagnoseOptions, diagnose};
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::sensor::realism::{Realism, RealismOptions};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

const PROFILE: &str = r#"
format = "hdrsynth-sensor/1"
name = "bench-sensor"
kind = "synthetic-example"
source_response = { kind = "linear" }
response = { kind = "linear" }
[provenance]
colour = "invented"
noise = "invented"
levels = "invented"
response = "invented"
[levels]
black_level = 64.0
white_level = 4095.0
bit_depth = 12
[[noise]]
iso = 100.0
a = [1.5e-4, 1.5e-4, 1.5e-4]
b = [5.5e-7, 5.5e-7, 5.5e-7]
[[noise]]
iso = 1600.0
a = [2.4e-3, 2.4e-3, 2.4e-3]
b = [8.8e-6, 8.8e-6, 8.8e-6]
"#;

fn env(key: &str, default: usize) -> usize {
    std::env::var(key)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn write_set(dir: &Path, size: usize, frames: usize) {
    if dir.join(MANIFEST_NAME).is_file() {
        return;
    }
    let profile: SensorProfile = hdrsynth::config::parse_toml(PROFILE, Path::new("bench")).unwrap();
    let mut m = CaptureManifest::new();
    m.sensor.white_level = Some(4095.0);
    m.sensor.black_level = Some(64.0);
    for iso in [100.0, 400.0, 1600.0] {
        for (k, level) in [0.0, 0.1, 0.3, 0.6].iter().enumerate() {
            let kind = if k == 0 {
                BurstKind::Dark
            } else {
                BurstKind::Flat
            };
            let name = format!("{}_{iso}_{k}", if k == 0 { "dark" } else { "flat" });
            let mut opts = RealismOptions::new(iso);
            opts.colour = false;
            let r = Realism::new(&profile, &opts).unwrap();
            let target = Image::from_fn(size, size, |_, _| [*level as f32; 3]);
            let rel: Vec<String> = (0..frames).map(|f| format!("{name}/{f:03}.png")).collect();
            rel.par_iter().enumerate().for_each(|(f, p)| {
                let dn = r.to_dn(&target, hash(9, &[m.bursts.len() as u64, f as u64]));
                write_ldr(&dir.join(p), &dn.map(|v| v / 65535.0), BitDepth::Sixteen).unwrap();
            });
            m.bursts.push(Burst {
                name,
                kind,
                iso,
                exposure_s: level / 10.0 / iso * 100.0,
                frames: rel,
                scene: None,
            });
        }
    }
    let text = m.to_toml(&dir.join(MANIFEST_NAME)).unwrap();
    std::fs::write(dir.join(MANIFEST_NAME), text).unwrap();
}

fn main() {
    let size = env("HDRSYNTH_BENCH_SIZE", 1024);
    let frames = env("HDRSYNTH_BENCH_FRAMES", 50);
    let k = env("HDRSYNTH_BENCH_REPLICATES", 30);
    let dir = std::env::var("HDRSYNTH_BENCH_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|_| {
            std::env::temp_dir().join(format!("hdrsynth-bench-diagnose-{size}-{frames}"))
        });
    std::fs::create_dir_all(&dir).unwrap();
    let t = Instant::now();
    write_set(&dir, size, frames);
    eprintln!(
        "capture set ready in {:.1} s: {}",
        t.elapsed().as_secs_f64(),
        dir.display()
    );
    let set = CaptureSet::load(&dir).unwrap();
    let n: usize = set.bursts().iter().map(|b| b.frames.len()).sum();

    let t = Instant::now();
    let pixels: usize = (0..set.bursts().len())
        .flat_map(|b| (0..set.bursts()[b].frames.len()).map(move |f| (b, f)))
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&(b, f)| set.read_frame(b, f).unwrap().width)
        .sum();
    let decode = t.elapsed().as_secs_f64();
    assert_eq!(pixels, n * size);

    let t = Instant::now();
    let opts = DiagnoseOptions {
        replicates: k,
        max_pixels: env(
            "HDRSYNTH_BENCH_MAX_PIXELS",
            DiagnoseOptions::default().max_pixels,
        ),
        ..DiagnoseOptions::default()
    };
    let d = diagnose(&set, None, &opts).unwrap();
    let total = t.elapsed().as_secs_f64();
    println!(
        "diagnose {} bursts × {frames} frames × {size}×{size} ({n} PNGs), {k} replicates, \
         max_pixels {}, {} step(s), gap {:.2} → {:.2}, threads {}",
        set.bursts().len(),
        opts.max_pixels,
        d.steps.len(),
        d.initial_gap(),
        d.final_gap(),
        rayon::current_num_threads()
    );
    println!(
        "decode only: {decode:.1} s; diagnose: {total:.1} s; ratio {:.1}",
        total / decode
    );
}
