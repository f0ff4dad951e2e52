//! `hdrsynth export onnx --checkpoint C --out model.onnx [--height H --width W | --dynamic]
//! [--verify]`: a checkpoint's network (Network-1 or Network-2, by its model kind) as a standard
//! ONNX model; `--verify` runs the file in ONNX Runtime and compares it with Burn. Needs the
//! cargo feature `onnx` (docs/onnx.md).

use anyhow::Result;
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug, Clone)]
pub enum ExportCommand {
    /// Write a checkpoint's network as an ONNX model (opset 17); --verify checks it in ONNX
    /// Runtime against Burn.
    Onnx(OnnxArgs),
}

#[derive(clap::Args, Debug, Clone)]
pub struct OnnxArgs {
    /// A checkpoint folder, or a run folder (its latest checkpoint).
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// The ONNX file to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Static input height (with --width; a multiple of the network's size multiple).
    #[arg(long, requires = "width", conflicts_with = "dynamic")]
    pub height: Option<usize>,
    /// Static input width (with --height).
    #[arg(long, requires = "height", conflicts_with = "dynamic")]
    pub width: Option<usize>,
    /// Symbolic batch, height and width (the default when no size is given).
    #[arg(long)]
    pub dynamic: bool,
    /// Network-1: leave out the `blend_weight` output (probabilities only).
    #[arg(long)]
    pub no_blend_weight: bool,
    /// Run the file in ONNX Runtime (ORT_DYLIB_PATH) on random inputs and a real image set and
    /// fail if any output differs from Burn's by more than --tolerance.
    #[arg(long)]
    pub verify: bool,
    /// Real frames for --verify: LOW HIGH (Network-1) or SHORT REFERENCE LONG (Network-2).
    /// Default: ../shared/data/oracles/desk_2exp_* or desk_3exp_* when present.
    #[arg(long, num_args = 2..=3)]
    pub verify_frames: Vec<PathBuf>,
    /// Largest absolute difference --verify accepts.
    #[arg(long, default_value_t = 1e-4)]
    pub tolerance: f32,
}

pub fn run(cmd: &ExportCommand) -> Result<String> {
    match cmd {
        ExportCommand::Onnx(args) => onnx(args),
    }
}

#[cfg(not(feature = "onnx"))]
fn onnx(_: &OnnxArgs) -> Result<String> {
    anyhow::bail!(
        "this hdrsynth was built without ONNX support: rebuild with \
         `cargo build --release --features onnx` (docs/onnx.md)"
    )
}

#[cfg(feature = "onnx")]
fn onnx(args: &OnnxArgs) -> Result<String> {
    use crate::onnx::export::{ExportOptions, InputSize};
    use crate::onnx::verify::{VerifyOptions, export_checkpoint};
    let size = match (args.height, args.width) {
        (Some(height), Some(width)) => InputSize::Static { height, width },
        _ => InputSize::Dynamic,
    };
    let opts = ExportOptions {
        size,
        blend_weight: !args.no_blend_weight,
    };
    let verify = args.verify.then(|| VerifyOptions {
        frames: args.verify_frames.clone(),
        tolerance: args.tolerance,
    });
    Ok(export_checkpoint(
        &args.checkpoint,
        &args.out,
        &opts,
        verify.as_ref(),
    )?)
}
