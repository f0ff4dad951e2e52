//! `hdrsynth infer --checkpoint C --inputs LOW HIGH --out DIR`: run a trained network on one
//! input of any size, tiled with bounded memory; the network is the checkpoint's.
//!
//! Network-1 writes `linear.exr` (the fused frame before the tone curve: the metrics' L),
//! `tonemapped.exr` and `tonemapped.png` (after it: T) and `blend_weight.png` (the long
//! exposure's weight, 0 black … 1 white).

use crate::device::device_from_name;
use crate::eval::blend::{BlendWeight, DEFAULT_TONE_K};
use crate::eval::infer::{network1_fuse, network1_tiling};
use crate::eval::tiling::Tiling;
use crate::io::{BitDepth, ExrPrecision, Image, read_image, write_exr, write_ldr};
use crate::train::checkpoint;
use crate::train::config::ModelConfig;
use anyhow::{Context, Result, bail};
use burn::module::Module;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// A checkpoint folder, or a run folder (its latest checkpoint).
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Network-1: the EV−3 and EV0 frames (PNG/TIFF/EXR, values in [0, 1]).
    #[arg(long, num_args = 2, value_names = ["LOW", "HIGH"])]
    pub inputs: Vec<PathBuf>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Core tile side (a multiple of the network's 2^depth).
    #[arg(long)]
    pub tile: Option<usize>,
    /// Context per tile side; default: the network's receptive-field radius (exact tiling).
    #[arg(long)]
    pub overlap: Option<usize>,
    /// Blend weight from the class probabilities.
    #[arg(long, value_enum, default_value_t = BlendWeight::Expected)]
    pub weight: BlendWeight,
    /// k of the tone curve T(x) = (1 − e^(−kx)) / (1 − e^(−k)); 0 = none.
    #[arg(long, default_value_t = DEFAULT_TONE_K)]
    pub tone_k: f32,
    /// Compute device: flex (CPU), ndarray, wgpu, cuda (those compiled in).
    #[arg(long, default_value = "flex")]
    pub backend: String,
}

pub fn run(args: &Args) -> Result<String> {
    let dir = checkpoint::resolve(&args.checkpoint)?;
    let state = checkpoint::read_state(&dir)?;
    let device = device_from_name(&args.backend)?;
    let began = Instant::now();
    match &state.model {
        ModelConfig::BlendUnet(cfg) => {
            let [low, high] = args.inputs.as_slice() else {
                bail!("Network-1 needs --inputs LOW HIGH (the EV−3 and EV0 frames)");
            };
            let read = |p: &PathBuf| -> Result<Image> {
                read_image(p).with_context(|| format!("reading input {}", p.display()))
            };
            let (low_img, high_img) = (read(low)?, read(high)?);
            let model = checkpoint::load_model(cfg.init(&device)?, &dir)?.valid();
            let mut tiling: Tiling = network1_tiling(cfg);
            if let Some(t) = args.tile {
                tiling.tile = t;
            }
            if let Some(o) = args.overlap {
                tiling.overlap = o;
            }
            let (w, linear, toned) = network1_fuse(
                &model,
                &low_img,
                &high_img,
                tiling,
                args.weight,
                args.tone_k,
                &device,
            )?;
            std::fs::create_dir_all(&args.out)
                .with_context(|| format!("creating {}", args.out.display()))?;
            write_exr(&args.out.join("linear.exr"), &linear, ExrPrecision::Float)?;
            write_exr(
                &args.out.join("tonemapped.exr"),
                &toned,
                ExrPrecision::Float,
            )?;
            write_ldr(&args.out.join("tonemapped.png"), &toned, BitDepth::Eight)?;
            let grey = Image::from_vec(
                linear.width,
                linear.height,
                w.iter().flat_map(|&v| [v, v, v]).collect(),
            );
            write_ldr(&args.out.join("blend_weight.png"), &grey, BitDepth::Eight)?;
            Ok(format!(
                "Network-1 ({}) on {}×{} in {:.1} s (tile {}, overlap {}): wrote linear.exr, \
                 tonemapped.exr, tonemapped.png, blend_weight.png to {}",
                dir.display(),
                linear.width,
                linear.height,
                began.elapsed().as_secs_f64(),
                tiling.tile,
                tiling.overlap,
                args.out.display()
            ))
        }
    }
}
