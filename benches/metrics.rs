//! Metric cost: SSIM (field convention, RGB) and the full `score` (PSNR-L/T, SSIM-L/T, PU21
//! PSNR/SSIM, ΔE2000, PSNR-T dark) at 1024×768 and at a 12 MP 4032×3024 frame, on the default
//! rayon pool.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use hdrsynth::eval::metrics::{
    MetricOptions, PixelMask, delta_e2000_mu, psnr, psnr_mu, psnr_mu_masked, pu21_psnr, pu21_ssim,
    score, ssim, ssim_mu,
};
use hdrsynth::io::Image;
use std::time::Duration;

fn pair(w: usize, h: usize) -> (Image, Image) {
    let gt = Image::from_fn(w, h, |x, y| {
        let v = ((x * 7 + y * 13) % 1000) as f32 / 1000.0;
        [v, (v * 0.8 + 0.1).min(1.0), 1.0 - v]
    });
    // A deterministic perturbation so no map is trivially constant.
    let pred = Image::from_fn(w, h, |x, y| {
        let p = gt.get(x, y);
        let e = (((x * 31 + y * 17) % 23) as f32 - 11.0) * 0.002;
        [(p[0] + e).max(0.0), p[1] * 0.98, (p[2] - e).max(0.0)]
    });
    (gt, pred)
}

fn bench(c: &mut Criterion) {
    let opts = MetricOptions::default();
    let mut g = c.benchmark_group("metrics");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for (w, h) in [(1024usize, 768usize), (4032, 3024)] {
        let (gt, pred) = pair(w, h);
        // A darkened ground truth stands in for the reference frame: about a third is dark.
        let dark = PixelMask::from_frame(&gt.map(|v| v * 0.15)).expect("mask");
        g.throughput(Throughput::Elements((w * h) as u64));
        g.bench_function(format!("ssim/{w}x{h}"), |b| {
            b.iter(|| ssim(&gt, &pred).expect("ssim"))
        });
        g.bench_function(format!("score/{w}x{h}"), |b| {
            b.iter(|| score(&gt, &pred, Some(&dark), &opts).expect("score"))
        });
    }
    // Where `score`'s time goes, at the smaller size.
    let (gt, pred) = pair(1024, 768);
    g.throughput(Throughput::Elements(1024 * 768));
    g.bench_function("psnr_l/1024x768", |b| b.iter(|| psnr(&gt, &pred, 1.0)));
    g.bench_function("psnr_t/1024x768", |b| b.iter(|| psnr_mu(&gt, &pred)));
    g.bench_function("ssim_t/1024x768", |b| b.iter(|| ssim_mu(&gt, &pred)));
    g.bench_function("pu21_psnr/1024x768", |b| {
        b.iter(|| pu21_psnr(&gt, &pred, &opts))
    });
    g.bench_function("pu21_ssim/1024x768", |b| {
        b.iter(|| pu21_ssim(&gt, &pred, &opts))
    });
    g.bench_function("delta_e2000/1024x768", |b| {
        b.iter(|| delta_e2000_mu(&gt, &pred))
    });
    let dark = PixelMask::from_frame(&gt.map(|v| v * 0.15)).expect("mask");
    g.bench_function("psnr_t_dark/1024x768", |b| {
        b.iter(|| psnr_mu_masked(&gt, &pred, &dark))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
