//! `hdrsynth infer --checkpoint C (--inputs LOW HIGH | --set DIR) --out OUT`: run a trained
//! network on one input of any size, tiled with bounded memory; the network is the
//! checkpoint's.
//!
//! Network-1 (`--inputs LOW HIGH`, or `--set` with an EV−3/EV0 pair) writes `linear.exr` (the
//! fused frame before the tone curve: the metrics' L), `tonemapped.exr` and `tonemapped.png`
//! (after it: T) and `blend_weight.png` (the long exposure's weight, 0 black … 1 white).
//! Network-2 (`--set DIR`, a set with three exposures; the EVs come from the set) writes
//! `hdr.exr` (linear, 1 = the reference exposure's white) and `hdr_mulaw.png` (μ-law preview
//! of the network's [0, 1] range).

use crate::data::layout::{self, SetInfo};
use crate::device::device_from_name;
use crate::eval::blend::fuse;
use crate::eval::engine::{LoadedNetwork, Network};
use crate::eval::infer::{NetworkOptions, network2_frames};
use crate::eval::metrics::mu_law;
use crate::io::{BitDepth, ExrPrecision, Image, read_image, write_exr, write_ldr};
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// A checkpoint folder, or a run folder (its latest checkpoint).
    #[arg(long, required_unless_present = "onnx", conflicts_with = "onnx")]
    pub checkpoint: Option<PathBuf>,
    /// An exported model (`hdrsynth export onnx`) run in ONNX Runtime instead of a checkpoint
    /// (cargo feature `onnx`, ORT_DYLIB_PATH); same tiling, same outputs.
    #[arg(long)]
    pub onnx: Option<PathBuf>,
    /// Network-1: the EV−3 and EV0 frames (PNG/TIFF/EXR, values in [0, 1]).
    #[arg(long, num_args = 2, value_names = ["LOW", "HIGH"], conflicts_with = "set")]
    pub inputs: Vec<PathBuf>,
    /// A set folder of any known layout (frames and EVs read from it).
    #[arg(long)]
    pub set: Option<PathBuf>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub network: NetworkOptions,
    /// Compute device: flex (CPU), ndarray, wgpu, cuda (those compiled in).
    #[arg(long, default_value = "flex")]
    pub backend: String,
}

/// The set in folder `dir`: a set of the dataset that contains it, or a dataset of one set.
pub fn find_set(dir: &Path) -> Result<SetInfo> {
    let want = dir
        .canonicalize()
        .with_context(|| format!("set folder {}", dir.display()))?;
    if let Some(parent) = want.parent()
        && let Ok(info) = layout::detect(parent)
        && let Some(set) = info
            .sets
            .into_iter()
            .find(|s| s.dir.canonicalize().is_ok_and(|d| d == want))
    {
        return Ok(set);
    }
    let info = layout::detect(&want)?;
    match <[SetInfo; 1]>::try_from(info.sets) {
        Ok([set]) => Ok(set),
        Err(sets) => bail!(
            "{}: not a set folder (a dataset of {} sets); pass one set's folder",
            dir.display(),
            sets.len()
        ),
    }
}

/// Network-1's (EV−3, EV0) frames from `--set` or `--inputs`.
fn network1_frames(args: &Args, set: Option<&SetInfo>) -> Result<(Image, Image)> {
    Ok(match (set, args.inputs.as_slice()) {
        (Some(set), _) => {
            let (lo, hi) = set.network1_pair()?;
            let frames = if set.static_frames.is_empty() {
                &set.dynamic_frames
            } else {
                &set.static_frames
            };
            (read_image(&frames[lo])?, read_image(&frames[hi])?)
        }
        (None, [low, high]) => {
            let read = |p: &PathBuf| -> Result<Image> {
                read_image(p).with_context(|| format!("reading input {}", p.display()))
            };
            (read(low)?, read(high)?)
        }
        _ => bail!("Network-1 needs --inputs LOW HIGH (the EV−3 and EV0 frames) or --set"),
    })
}

/// Network-1's outputs: linear.exr, tonemapped.exr/.png, blend_weight.png.
fn write_network1(out: &Path, w: &[f32], linear: &Image, toned: &Image) -> Result<()> {
    write_exr(&out.join("linear.exr"), linear, ExrPrecision::Float)?;
    write_exr(&out.join("tonemapped.exr"), toned, ExrPrecision::Float)?;
    write_ldr(&out.join("tonemapped.png"), toned, BitDepth::Eight)?;
    let grey = Image::from_vec(
        linear.width,
        linear.height,
        w.iter().flat_map(|&v| [v, v, v]).collect(),
    );
    write_ldr(&out.join("blend_weight.png"), &grey, BitDepth::Eight)?;
    Ok(())
}

/// Network-2's outputs: hdr.exr and its μ-law preview in the network's [0, 1] range.
fn write_network2(out: &Path, hdr: &Image, hdr_input_scale: f32) -> Result<()> {
    write_exr(&out.join("hdr.exr"), hdr, ExrPrecision::Float)?;
    let preview = hdr.map(|v| mu_law((v * hdr_input_scale).clamp(0.0, 1.0) as f64) as f32);
    write_ldr(&out.join("hdr_mulaw.png"), &preview, BitDepth::Eight)?;
    Ok(())
}

pub fn run(args: &Args) -> Result<String> {
    // One writer per output (two infers would mix their files). A folder the lock creates is
    // removed again if the command fails before writing.
    let _lock = crate::io::guard::OutputLock::acquire(&args.out, "infer")?;
    let began = Instant::now();
    let net = match (&args.onnx, &args.checkpoint) {
        (Some(onnx), _) => from_onnx_file(onnx, &args.network)?,
        (None, Some(checkpoint)) => {
            let device = device_from_name(&args.backend)?;
            LoadedNetwork::from_checkpoint(checkpoint, &args.network, &device)?
        }
        (None, None) => bail!("--checkpoint or --onnx is required"),
    };
    let set = args.set.as_deref().map(find_set).transpose()?;
    let what = match net.network {
        Network::Network1 => {
            let (low, high) = network1_frames(args, set.as_ref())?;
            let w = net.network1_weight(&low, &high, args.network.weight)?;
            let (linear, toned) = fuse(&low, &high, &w, args.network.tone_k)?;
            write_network1(&args.out, &w, &linear, &toned)?;
            format!(
                "Network-1 on {}×{}: wrote linear.exr, tonemapped.exr, tonemapped.png, \
                 blend_weight.png",
                linear.width, linear.height
            )
        }
        Network::Network2 => {
            let Some(set) = &set else {
                bail!("Network-2 needs --set DIR (three exposures and their EVs)");
            };
            let (frames, times) = network2_frames(set)?;
            let [a, b, c] = &frames;
            let hdr = net.network2_hdr([a, b, c], times)?;
            write_network2(&args.out, &hdr, net.hdr_input_scale.unwrap_or(1.0))?;
            format!(
                "Network-2 on set {} ({}×{}, t = {times:?}): wrote hdr.exr, hdr_mulaw.png",
                set.name, hdr.width, hdr.height
            )
        }
    };
    Ok(format!(
        "{what} to {} in {:.1} s ({})",
        args.out.display(),
        began.elapsed().as_secs_f64(),
        net.describe()
    ))
}

#[cfg(feature = "onnx")]
fn from_onnx_file(path: &Path, opts: &NetworkOptions) -> Result<LoadedNetwork> {
    Ok(LoadedNetwork::from_onnx_file(path, opts)?)
}

#[cfg(not(feature = "onnx"))]
fn from_onnx_file(_: &Path, _: &NetworkOptions) -> Result<LoadedNetwork> {
    bail!(
        "--onnx: this hdrsynth was built without ONNX support: rebuild with \
         `cargo build --release --features onnx` (docs/onnx.md)"
    )
}
