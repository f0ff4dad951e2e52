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

use crate::data::layout::find_set;
use crate::device::device_from_name;
use crate::eval::blend::fuse;
use crate::eval::infer::{
    NetworkOptions, network1_frames, network2_frames, write_network1, write_network2,
};
use crate::io::{Image, read_image};
use crate::runner::{LoadedNetwork, Network};
use anyhow::{Context, Result, bail};
use std::path::PathBuf;
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

pub fn run(args: &Args) -> Result<String> {
    // One writer per output (two infers would mix their files). A folder the lock creates is
    // removed again if the command fails before writing.
    let _lock = crate::io::guard::OutputLock::acquire(&args.out, "infer")?;
    let began = Instant::now();
    let net = match (&args.onnx, &args.checkpoint) {
        (Some(onnx), _) => LoadedNetwork::from_onnx_file(onnx, &args.network)?,
        (None, Some(checkpoint)) => {
            let device = device_from_name(&args.backend)?;
            LoadedNetwork::from_checkpoint(checkpoint, &args.network, &device)?
        }
        (None, None) => bail!("--checkpoint or --onnx is required"),
    };
    let set = args.set.as_deref().map(find_set).transpose()?;
    let what = match net.network {
        Network::Network1 => {
            let (low, high) = match (&set, args.inputs.as_slice()) {
                (Some(set), _) => network1_frames(set)?,
                (None, [low, high]) => {
                    let read = |p: &PathBuf| -> Result<Image> {
                        read_image(p).with_context(|| format!("reading input {}", p.display()))
                    };
                    let (l, h) = (read(low)?, read(high)?);
                    if (l.width, l.height) != (h.width, h.height) {
                        bail!(
                            "--inputs: {} is {}×{} but {} is {}×{}: LOW and HIGH must be one \
                             size (the same view at two exposures)",
                            low.display(),
                            l.width,
                            l.height,
                            high.display(),
                            h.width,
                            h.height
                        );
                    }
                    (l, h)
                }
                _ => bail!("Network-1 needs --inputs LOW HIGH (the EV−3 and EV0 frames) or --set"),
            };
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
