//! Exporting a checkpoint and checking the file in ONNX Runtime against Burn's forward pass.

use super::export::{self, ExportOptions, InputSize};
use super::proto::ModelProto;
use super::runtime::OnnxModel;
use crate::data::pyramid::reflect101;
use crate::error::{Error, Result};
use crate::eval::blend::{BlendWeight, weight_from_logits};
use crate::eval::infer::{network2_input, planar_from_images};
use crate::eval::tiling::Planar;
use crate::io::{Image, read_image};
use crate::models::{BlendUNet, ModelConfig, WuNet};
use crate::rng::Rng;
use crate::train::checkpoint::{self, CheckpointState};
use burn::module::Module;
use burn::tensor::activation::softmax;
use burn::tensor::{Device, Tensor, TensorData};
use std::path::{Path, PathBuf};

/// A checkpoint's network, loaded for inference.
pub enum Loaded {
    Network1(BlendUNet),
    Network2(WuNet),
}

impl Loaded {
    /// H and W must be multiples of this.
    pub fn size_multiple(&self) -> usize {
        match self {
            Loaded::Network1(m) => 1 << m.depth(),
            Loaded::Network2(m) => m.size_multiple(),
        }
    }

    /// The smallest H and W the export accepts.
    pub fn min_size(&self) -> usize {
        match self {
            Loaded::Network1(m) => export::network1_min_size(m),
            Loaded::Network2(m) => export::network2_min_size(m.config()),
        }
    }

    /// The ONNX graph of this network.
    pub fn to_onnx(&self, opts: &ExportOptions) -> Result<ModelProto> {
        match self {
            Loaded::Network1(m) => export::network1(m, opts),
            Loaded::Network2(m) => export::network2(m, opts),
        }
    }
}

/// The network of a checkpoint (or a run's latest), by its model kind, on `device`.
pub fn load_checkpoint(path: &Path, device: &Device) -> Result<(PathBuf, CheckpointState, Loaded)> {
    let dir = checkpoint::resolve(path)?;
    let state = checkpoint::read_state(&dir)?;
    // Initialisation is overwritten by the checkpoint; seeded only so nothing is left to chance.
    let loaded = match &state.model {
        ModelConfig::BlendUnet(cfg) => {
            let m = crate::models::seeded_init(device, 0, || cfg.init(device))?;
            Loaded::Network1(checkpoint::load_model(m, &dir)?.valid())
        }
        ModelConfig::Wu(cfg) => {
            let m = crate::models::seeded_init(device, 0, || cfg.init(device))?;
            Loaded::Network2(checkpoint::load_model(m, &dir)?.valid())
        }
    };
    Ok((dir, state, loaded))
}

/// One comparison of ONNX Runtime with Burn.
#[derive(Clone, Debug)]
pub struct Check {
    /// What was fed ("random", or the image files).
    pub input: String,
    pub height: usize,
    pub width: usize,
    /// Largest |ONNX Runtime − Burn| over every output value (Network-1: probabilities and
    /// blend weight; Network-2: HDR).
    pub max_abs_diff: f32,
    /// Network-1 with a `blend_weight` output: the largest difference of the weight alone.
    pub weight_max_abs_diff: Option<f32>,
}

impl std::fmt::Display for Check {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:>4}×{:<4} {}: max |ONNX Runtime − Burn| = {:.3e}",
            self.height, self.width, self.input, self.max_abs_diff
        )?;
        if let Some(w) = self.weight_max_abs_diff {
            write!(f, " (blend weight alone {w:.3e})")?;
        }
        Ok(())
    }
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> Result<f32> {
    if a.len() != b.len() {
        return Err(Error::Invalid(format!(
            "ONNX Runtime returned {} values, Burn {}",
            a.len(),
            b.len()
        )));
    }
    // NaN anywhere counts as an infinite difference.
    Ok(a.iter().zip(b).fold(0.0f32, |m, (x, y)| {
        let d = (x - y).abs();
        if d.is_nan() { f32::INFINITY } else { m.max(d) }
    }))
}

fn to_vec(t: Tensor<4>) -> Result<Vec<f32>> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .map_err(|e| Error::Invalid(format!("reading a Burn output: {e:?}")))
}

/// Compares ONNX Runtime and Burn on one input: `frames` are planar `[3, h, w]` frames (two
/// for Network-1, three for Network-2), `times` Network-2's exposure times.
pub fn compare(
    burn: &Loaded,
    onnx: &mut OnnxModel,
    frames: &[Planar],
    times: [f32; 3],
    device: &Device,
    input: &str,
) -> Result<Check> {
    let (h, w) = (frames[0].height, frames[0].width);
    let stacked = |fs: &[Planar]| -> Planar {
        let mut p = Planar::new(3 * fs.len(), w, h);
        for (k, f) in fs.iter().enumerate() {
            p.data[k * 3 * w * h..(k + 1) * 3 * w * h].copy_from_slice(&f.data);
        }
        p
    };
    let tensor = |p: &Planar| {
        Tensor::<4>::from_data(
            TensorData::new(p.data.clone(), [1, p.channels, p.height, p.width]),
            device,
        )
    };
    match burn {
        Loaded::Network1(m) => {
            if frames.len() != 2 {
                return Err(Error::Invalid("Network-1 takes two frames".into()));
            }
            let logits = m.forward(tensor(&stacked(frames)));
            let probs = to_vec(softmax(logits.clone(), 1))?;
            let logits = to_vec(logits)?;
            let (p_onnx, w_onnx) = onnx.network1(&frames[0].data, &frames[1].data, (1, h, w))?;
            let mut worst = max_abs_diff(&p_onnx, &probs)?;
            let weight_diff = match w_onnx {
                Some(wo) => {
                    let wb =
                        weight_from_logits(&logits, m.classes(), h * w, BlendWeight::Expected)?;
                    let d = max_abs_diff(&wo, &wb)?;
                    worst = worst.max(d);
                    Some(d)
                }
                None => None,
            };
            Ok(Check {
                input: input.into(),
                height: h,
                width: w,
                max_abs_diff: worst,
                weight_max_abs_diff: weight_diff,
            })
        }
        Loaded::Network2(m) => {
            if frames.len() != 3 {
                return Err(Error::Invalid("Network-2 takes three frames".into()));
            }
            let x = network2_input(&stacked(frames), times, &m.config().input_response);
            let unit = 1.0 / m.config().hdr_input_scale as f32;
            let hdr = to_vec(m.forward(tensor(&x)).mul_scalar(unit))?;
            let out = onnx.network2(
                [&frames[0].data, &frames[1].data, &frames[2].data],
                &times,
                (1, h, w),
            )?;
            Ok(Check {
                input: input.into(),
                height: h,
                width: w,
                max_abs_diff: max_abs_diff(&out, &hdr)?,
                weight_max_abs_diff: None,
            })
        }
    }
}

/// Frames of uniform random values in [0, 1) (seeded).
pub fn random_frames(count: usize, height: usize, width: usize, seed: u64) -> Vec<Planar> {
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|_| {
            let mut p = Planar::new(3, width, height);
            p.data.iter_mut().for_each(|v| *v = rng.f32());
            p
        })
        .collect()
}

/// The centred `height`×`width` window of each image, planar; where the window is larger than
/// the image it continues by reflection (OpenCV's reflect-101, as the tiling does).
pub fn crop_frames(images: &[Image], height: usize, width: usize) -> Result<Vec<Planar>> {
    let mut out = Vec::new();
    for img in images {
        if img.width == 0 || img.height == 0 {
            return Err(Error::Invalid("crop: empty image".into()));
        }
        let x0 = (img.width as isize - width as isize) / 2;
        let y0 = (img.height as isize - height as isize) / 2;
        let xs: Vec<usize> = (0..width)
            .map(|x| reflect101(x0 + x as isize, img.width))
            .collect();
        let mut c = Image::new(width, height);
        for y in 0..height {
            let sy = reflect101(y0 + y as isize, img.height);
            for (x, &sx) in xs.iter().enumerate() {
                let (d, s) = ((y * width + x) * 3, (sy * img.width + sx) * 3);
                c.data[d..d + 3].copy_from_slice(&img.data[s..s + 3]);
            }
        }
        out.push(planar_from_images(&[&c])?);
    }
    Ok(out)
}

/// The exposure times of Network-2's checks: EV −2, 0, +2 relative to the reference.
pub const CHECK_TIMES: [f32; 3] = [0.25, 1.0, 4.0];

/// Sizes to check a model at: its static size, or (dynamic) two non-square sizes, neither of
/// them square or equal to each other.
pub fn check_sizes(loaded: &Loaded, size: InputSize) -> Vec<(usize, usize)> {
    match size {
        InputSize::Static { height, width } => vec![(height, width)],
        InputSize::Dynamic => {
            let m = loaded.size_multiple();
            let a = loaded.min_size().max(64).div_ceil(m) * m;
            vec![(a, a + m), (a + 2 * m, a)]
        }
    }
}

/// Runs every check of `hdrsynth export onnx --verify`: random inputs at [`check_sizes`], and
/// the real `images` (two or three frames, centre-cropped to the static size or, dynamic, to
/// the largest accepted size up to 256 per side; a static size larger than the images
/// continues them by reflection).
pub fn verify(
    loaded: &Loaded,
    onnx: &mut OnnxModel,
    size: InputSize,
    images: Option<(&[Image], &str)>,
    device: &Device,
) -> Result<Vec<Check>> {
    let frames_needed = match loaded {
        Loaded::Network1(_) => 2,
        Loaded::Network2(_) => 3,
    };
    let mut checks = Vec::new();
    for (k, (h, w)) in check_sizes(loaded, size).into_iter().enumerate() {
        let frames = random_frames(frames_needed, h, w, 0x0_1d5e + k as u64);
        checks.push(compare(
            loaded,
            onnx,
            &frames,
            CHECK_TIMES,
            device,
            "random",
        )?);
    }
    if let Some((images, label)) = images {
        if images.len() != frames_needed {
            return Err(Error::flag(
                "--verify-frames",
                format!(
                    "{label}: {} images given, the network takes {frames_needed}",
                    images.len()
                ),
            ));
        }
        let (h, w) = match size {
            InputSize::Static { height, width } => (height, width),
            InputSize::Dynamic => {
                let m = loaded.size_multiple();
                let fit = |v: usize| (v.min(256) / m) * m;
                (fit(images[0].height), fit(images[0].width))
            }
        };
        if h < loaded.min_size() || w < loaded.min_size() {
            return Err(Error::flag(
                "--verify-frames",
                format!(
                    "{label}: images {}×{} are too small for this network",
                    images[0].height, images[0].width
                ),
            ));
        }
        let frames = crop_frames(images, h, w)?;
        checks.push(compare(loaded, onnx, &frames, CHECK_TIMES, device, label)?);
    }
    Ok(checks)
}

/// Reads the verification images.
pub fn read_images(paths: &[PathBuf]) -> Result<Vec<Image>> {
    paths.iter().map(|p| read_image(p)).collect()
}

/// `--verify`: the real frames (empty: the desk oracle frames of ../shared/data when present)
/// and the largest absolute difference accepted.
#[derive(Clone, Debug)]
pub struct VerifyOptions {
    pub frames: Vec<PathBuf>,
    pub tolerance: f32,
}

/// `hdrsynth export onnx`: the network of `checkpoint` (a checkpoint or run folder) written to
/// `out` as ONNX; with `verify`, the file run in ONNX Runtime and compared with Burn. Returns
/// the report; a difference over the tolerance is an error that carries the report.
pub fn export_checkpoint(
    checkpoint: &Path,
    out: &Path,
    opts: &ExportOptions,
    verify: Option<&VerifyOptions>,
) -> Result<String> {
    use std::fmt::Write;
    let device = crate::device::device_from_name("flex")?;
    let (dir, state, loaded) = load_checkpoint(checkpoint, &device)?;
    let model = loaded.to_onnx(opts)?;
    export::save(&model, out)?;
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
        out.display(),
        export::OPSET,
        graph.node.len(),
        graph.initializer.len(),
        std::fs::metadata(out).map(|m| m.len()).unwrap_or(0),
        graph
            .input
            .iter()
            .filter_map(|v| v.name.clone())
            .collect::<Vec<_>>()
            .join(", "),
        match opts.size {
            InputSize::Static { height, width } => format!("static {height}×{width}"),
            InputSize::Dynamic => format!(
                "dynamic (H, W multiples of {}, at least {})",
                loaded.size_multiple(),
                loaded.min_size()
            ),
        }
    );
    let Some(v) = verify else {
        return Ok(report);
    };
    let mut onnx = OnnxModel::load(out, None)?;
    let paths: Vec<PathBuf> = if v.frames.is_empty() {
        let shared = PathBuf::from("../shared/data/oracles");
        frames.iter().map(|f| shared.join(f)).collect()
    } else {
        v.frames.clone()
    };
    let images = if paths.iter().all(|p| p.is_file()) {
        Some(read_images(&paths).map_err(|e| Error::context("reading the --verify frames", e))?)
    } else if !v.frames.is_empty() {
        return Err(Error::flag(
            "--verify-frames",
            format!("not every file exists: {paths:?}"),
        ));
    } else {
        None
    };
    let label = paths
        .iter()
        .filter_map(|p| p.file_name().map(|f| f.to_string_lossy().into_owned()))
        .collect::<Vec<_>>()
        .join(" + ");
    let checks = self::verify(
        &loaded,
        &mut onnx,
        opts.size,
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
    if worst.is_nan() || worst > v.tolerance {
        return Err(Error::Invalid(format!(
            "{report}ONNX Runtime differs from Burn by {worst:.3e} > tolerance {:.0e}",
            v.tolerance
        )));
    }
    write!(
        report,
        "verified in ONNX Runtime ({}): max abs difference {worst:.3e} ≤ {:.0e}",
        super::runtime::dylib_path()?.display(),
        v.tolerance
    )
    .ok();
    Ok(report)
}
