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
    use crate::onnx::export::{self, ExportOptions, InputSize};
    use crate::onnx::runtime::OnnxModel;
    use crate::onnx::verify::{self, Loaded};
    use anyhow::{Context, bail};
    use std::fmt::Write;

    let device = crate::device::device_from_name("flex")?;
    let (dir, state, loaded) = verify::load_checkpoint(&args.checkpoint, &device)?;
    let size = match (args.height, args.width) {
        (Some(height), Some(width)) => InputSize::Static { height, width },
        _ => InputSize::Dynamic,
    };
    let opts = ExportOptions {
        size,
        blend_weight: !args.no_blend_weight,
    };
    let model = loaded.to_onnx(&opts)?;
    export::save(&model, &args.out)?;
    let graph = model.graph.as_ref().expect("built with a graph");
    let (kind, frames) = match &loaded {
        Loaded::Network1(_) => (
            "Network-1",
            ["desk_2exp_ev-3.png", "desk_2exp_ev+0.png"].as_slice(),
        ),
        Loaded::Network2(_) => (
            "Network-2",
            [
                "desk_3exp_ev-2.png",
                "desk_3exp_ev+0.png",
                "desk_3exp_ev+2.png",
            ]
            .as_slice(),
        ),
    };
    let mut report = format!(
        "{kind} ({}, step {}) → {}: opset {}, {} nodes, {} initializers, {} bytes, inputs {}, \
         {}",
        dir.display(),
        state.step,
        args.out.display(),
        export::OPSET,
        graph.node.len(),
        graph.initializer.len(),
        std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0),
        graph
            .input
            .iter()
            .filter_map(|v| v.name.clone())
            .collect::<Vec<_>>()
            .join(", "),
        match size {
            InputSize::Static { height, width } => format!("static {height}×{width}"),
            InputSize::Dynamic => format!(
                "dynamic (H, W multiples of {}, at least {})",
                loaded.size_multiple(),
                loaded.min_size()
            ),
        }
    );
    if !args.verify {
        return Ok(report);
    }
    let mut onnx = OnnxModel::load(&args.out, None)?;
    let paths: Vec<PathBuf> = if args.verify_frames.is_empty() {
        let shared = PathBuf::from("../shared/data/oracles");
        frames.iter().map(|f| shared.join(f)).collect()
    } else {
        args.verify_frames.clone()
    };
    let images = if paths.iter().all(|p| p.is_file()) {
        Some(verify::read_images(&paths).context("reading the --verify frames")?)
    } else if !args.verify_frames.is_empty() {
        bail!("--verify-frames: not every file exists: {paths:?}");
    } else {
        None
    };
    let label = paths
        .iter()
        .filter_map(|p| p.file_name().map(|f| f.to_string_lossy().into_owned()))
        .collect::<Vec<_>>()
        .join(" + ");
    let checks = verify::verify(
        &loaded,
        &mut onnx,
        size,
        images.as_deref().map(|i| (i, label.as_str())),
        &device,
    )?;
    writeln!(report).ok();
    for c in &checks {
        writeln!(report, "  {c}").ok();
    }
    if images.is_none() {
        writeln!(
            report,
            "  real images: skipped ({} not found; pass --verify-frames)",
            paths[0].display()
        )
        .ok();
    }
    let worst = checks.iter().map(|c| c.max_abs_diff).fold(0.0f32, f32::max);
    if worst.is_nan() || worst > args.tolerance {
        bail!(
            "{report}ONNX Runtime differs from Burn by {worst:.3e} > tolerance {:.0e}",
            args.tolerance
        );
    }
    write!(
        report,
        "verified in ONNX Runtime ({}): max abs difference {worst:.3e} ≤ {:.0e}",
        crate::onnx::runtime::dylib_path()?.display(),
        args.tolerance
    )
    .ok();
    Ok(report)
}
