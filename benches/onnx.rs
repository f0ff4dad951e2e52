//! ONNX Runtime (CPU) vs Burn flex: whole-image inference of both networks at default widths,
//! through the same exact tiling, on the same machine (feature `onnx`, ORT_DYLIB_PATH):
//! `cargo bench --features onnx --bench onnx`. Untrained (seeded) weights: the cost does not
//! depend on them. Sizes: 512×512 in one window (tile 512) and 1024×768 in the default 384-px
//! tiles. One warm-up, then the best of `HDRSYNTH_BENCH_REPS` (default 2) runs.
//! `HDRSYNTH_BENCH_ONLY=<network>:<W>x<H>` (e.g. `1:512x512`) runs one row.

#[path = "../tests/common/mod.rs"]
mod common;

use hdrsynth::eval::blend::BlendWeight;
use hdrsynth::eval::infer::{network1_tiling, network1_weight, network2_hdr, network2_tiling};
use hdrsynth::eval::tiling::Tiling;
use hdrsynth::io::Image;
use hdrsynth::models::seeded_init;
use hdrsynth::models::{BlendUNetConfig, WuConfig};
use hdrsynth::onnx::export::{self, ExportOptions};
use hdrsynth::onnx::infer as oi;
use hdrsynth::onnx::runtime::OnnxModel;
use std::time::Instant;

fn frame(w: usize, h: usize, seed: u64) -> Image {
    Image::from_vec(w, h, common::values(3 * w * h, seed))
}

fn best(reps: usize, mut f: impl FnMut()) -> f64 {
    f();
    (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    // As the binary does (src/main.rs): keep freed activations in the heap.
    hdrsynth::device::retain_freed_memory();
    let reps: usize = std::env::var("HDRSYNTH_BENCH_REPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2);
    let dev = hdrsynth::device::device_from_name("flex").expect("flex");
    let tmp = tempfile::tempdir().expect("tmp");
    let sizes = [(512usize, 512usize, Some(512usize)), (1024, 768, None)];
    let only = std::env::var("HDRSYNTH_BENCH_ONLY").ok();
    let wanted = |net: usize, w: usize, h: usize| {
        only.as_deref()
            .is_none_or(|o| o == format!("{net}:{w}x{h}"))
    };

    let cfg1 = BlendUNetConfig::default();
    let m1 = seeded_init(&dev, 1, || cfg1.init(&dev)).expect("init");
    let p1 = tmp.path().join("n1.onnx");
    export::save(
        &export::network1(&m1, &ExportOptions::default()).unwrap(),
        &p1,
    )
    .unwrap();
    let mut o1 = OnnxModel::load(&p1, None).expect("load");
    let cfg2 = WuConfig::default();
    let m2 = seeded_init(&dev, 2, || cfg2.init(&dev)).expect("init");
    let p2 = tmp.path().join("n2.onnx");
    export::save(
        &export::network2(&m2, &ExportOptions::default()).unwrap(),
        &p2,
    )
    .unwrap();
    let mut o2 = OnnxModel::load(&p2, None).expect("load");

    println!("| network | size | tiling | Burn flex | ONNX Runtime | Burn / ORT |");
    println!("|---|---|---|---|---|---|");
    for (w, h, tile) in sizes {
        let f: Vec<Image> = (0..3).map(|k| frame(w, h, 10 + k)).collect();
        let t1 = network1_tiling(&cfg1);
        let t1 = Tiling {
            tile: tile.unwrap_or(t1.tile),
            ..t1
        };
        if wanted(1, w, h) {
            let burn = best(reps, || {
                network1_weight(&m1, &f[0], &f[1], t1, BlendWeight::Expected, &dev).unwrap();
            });
            let ort = best(reps, || {
                oi::network1_weight(&mut o1, &f[0], &f[1], t1, BlendWeight::Expected).unwrap();
            });
            println!(
                "| Network-1 (default) | {w}×{h} | tile {}, overlap {} | {burn:.2} s | {ort:.2} s | {:.2}× |",
                t1.tile,
                t1.overlap,
                burn / ort
            );
        }
        let t2 = network2_tiling(&cfg2);
        let t2 = Tiling {
            tile: tile.unwrap_or(t2.tile),
            ..t2
        };
        let times = [0.25, 1.0, 4.0];
        if !wanted(2, w, h) {
            continue;
        }
        let burn = best(reps, || {
            network2_hdr(&m2, [&f[0], &f[1], &f[2]], times, t2, &dev).unwrap();
        });
        let ort = best(reps, || {
            oi::network2_hdr(&mut o2, [&f[0], &f[1], &f[2]], times, t2).unwrap();
        });
        println!(
            "| Network-2 ResNet (default) | {w}×{h} | tile {}, overlap {} | {burn:.2} s | {ort:.2} s | {:.2}× |",
            t2.tile,
            t2.overlap,
            burn / ort
        );
    }
}
