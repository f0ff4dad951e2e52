//! The contact sheet of `hdrsynth dataset preview`: what a network will see — per sample, the pure synthetic frames, the same crops after sensor realism, and
//! the target (Network-1: the blend-class map as grey; Network-2: the HDR target, μ-law tone
//! mapped) — built by the training loader itself, so the sheet cannot drift from training.

use crate::data::loader::{Loader, LoaderConfig, RealismConfig, SampleKind, Target};
use crate::error::{Error, Result};
use crate::io::{BitDepth, Image, write_ldr};
use crate::sensor::realism::NoiseModel;
use std::path::PathBuf;

#[derive(Clone, Debug)]
pub struct PreviewOptions {
    /// A dataset folder in any known layout.
    pub dir: PathBuf,
    /// Sensor profile for the realistic column.
    pub profile: PathBuf,
    pub iso: f64,
    /// None: from the dataset's EVs (an EV −3 frame means Network-1).
    pub kind: Option<SampleKind>,
    pub count: usize,
    pub patch: usize,
    pub seed: u64,
    pub out: PathBuf,
}

fn kind_of(args: &PreviewOptions) -> Result<SampleKind> {
    Ok(match args.kind {
        Some(k) => k,
        None => {
            let info = crate::data::layout::detect(&args.dir)?;
            let evs = &info
                .sets
                .first()
                .ok_or_else(|| Error::layout(&args.dir, "dataset has no sets"))?
                .evs;
            if evs.iter().any(|e| (e + 3.0).abs() < 1e-3) {
                SampleKind::Network1
            } else {
                SampleKind::Network2
            }
        }
    })
}

/// Channel block `k` (3 planes, C×H×W) of a sample input as an image.
fn block(input: &[f32], size: usize, k: usize) -> Image {
    let n = size * size;
    Image::from_fn(size, size, |x, y| {
        std::array::from_fn(|c| input[(k * 3 + c) * n + y * size + x])
    })
}

/// Write the sheet to `args.out`; returns the line that says what it holds.
pub fn preview(args: &PreviewOptions) -> Result<String> {
    let kind = kind_of(args)?;
    let base = LoaderConfig {
        dataset: args.dir.clone(),
        kind,
        patch: args.patch,
        batch_size: 1,
        workers: 1,
        prefetch: 1,
        seed: args.seed,
        augment: false,
        realism: None,
        target_sigma: 0.0,
        target_frames: Default::default(),
        static_fraction: 0.0,
        input_response: None,
    };
    let mut real_cfg = base.clone();
    real_cfg.realism = Some(RealismConfig {
        profile: args.profile.clone(),
        isos: vec![args.iso],
        noise: NoiseModel::Gaussian,
        exposure: 1.0,
        // The profile's measured rule, else the default: as training meters.
        metering: None,
        ev_jitter: 0.0,
        source: Default::default(),
        colour: true,
        target_space: Default::default(),
    });
    let pure = Loader::new(&base)?;
    let real = Loader::new(&real_cfg)?;
    // Frame blocks in the input: Network-1 [low, high]; Network-2 LDR blocks 0, 2, 4 of 6.
    let blocks: &[usize] = match kind {
        SampleKind::Network1 => &[0, 1],
        SampleKind::Network2 => &[0, 2, 4],
    };
    let count = args.count.min(pure.len()).max(1);
    let p = args.patch;
    let cols = 2 * blocks.len() + 1;
    let gap = 4;
    let mut sheet = Image::new(cols * (p + gap), count * (p + gap));
    let mut paste = |img: &Image, row: usize, col: usize| {
        for y in 0..p {
            for x in 0..p {
                sheet.set(col * (p + gap) + x, row * (p + gap) + y, img.get(x, y));
            }
        }
    };
    for i in 0..count {
        let a = pure.sample(0, i)?;
        let b = real.sample(0, i)?;
        for (j, &k) in blocks.iter().enumerate() {
            paste(&block(&a.input, p, k), i, j);
            paste(&block(&b.input, p, k), i, blocks.len() + j);
        }
        let target = match &b.target {
            Target::Classes(c) => Image::from_fn(p, p, |x, y| [c[y * p + x] as f32 / 255.0; 3]),
            Target::Hdr(h) => {
                let mu = |v: f32| crate::io::mu_law::curve(v.max(0.0));
                Image::from_fn(p, p, |x, y| {
                    std::array::from_fn(|c| mu(h[c * p * p + y * p + x]))
                })
            }
        };
        paste(&target, i, 2 * blocks.len());
    }
    write_ldr(&args.out, &sheet, BitDepth::Eight)?;
    Ok(format!(
        "wrote {} ({count} samples; columns: {} pure frame(s), the same after '{}' at ISO {}, target)",
        args.out.display(),
        blocks.len(),
        args.profile.display(),
        args.iso
    ))
}
