//! Running trained networks on whole images of any size: tensors per window of
//! [`tiling::run_tiled`](crate::eval::tiling), reduced on the device to what the output needs
//! (Network-1: one blend weight per pixel from each window's logits, never 256 class maps of a
//! full frame).

use crate::data::layout::SetInfo;
use crate::error::{Error, Result};
use crate::eval::blend::{BlendWeight, DEFAULT_TONE_K, fuse, weight_from_logits};
use crate::eval::metrics::mu_law;
use crate::eval::tiling::{Planar, Tiling, run_tiled};
use crate::io::{BitDepth, ExrPrecision, Image, read_image, write_exr, write_ldr};
use crate::models::{BlendUNet, BlendUNetConfig, WuConfig, WuNet};
use crate::sensor::profile::Response;
use burn::tensor::{Device, Tensor, TensorData};
use std::path::Path;

/// The engine flag of `infer`, `eval` and `ablate`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Engine {
    /// ONNX Runtime on a CPU device when this build has the `onnx` feature and
    /// ORT_DYLIB_PATH names its library; Burn otherwise.
    #[default]
    Auto,
    /// Burn on the chosen device.
    Burn,
    /// ONNX Runtime (feature `onnx`, ORT_DYLIB_PATH); an error when unavailable.
    Onnx,
}

/// Default core tile side for full-resolution inference (a multiple of 16).
pub const DEFAULT_TILE: usize = 384;

/// How to run a network on whole images (flags of `hdrsynth infer` and `hdrsynth eval`).
#[derive(clap::Args, Clone, Debug)]
pub struct NetworkOptions {
    /// Core tile side (a multiple of the network's 2^depth); default 384.
    #[arg(long, value_parser = tile_side)]
    pub tile: Option<usize>,
    /// Context per tile side; default: the network's receptive-field radius (exact tiling).
    #[arg(long)]
    pub overlap: Option<usize>,
    /// Network-1's blend weight from its class probabilities.
    #[arg(long, value_enum, default_value_t = BlendWeight::Expected)]
    pub weight: BlendWeight,
    /// Network-1's tone curve k: T(x) = (1 − e^(−kx)) / (1 − e^(−k)); 0 = none.
    #[arg(long, default_value_t = DEFAULT_TONE_K)]
    pub tone_k: f32,
    /// Inference engine for a checkpoint: auto (Network-1 in ONNX Runtime on CPU when built
    /// with `onnx` and ORT_DYLIB_PATH is set, else Burn; Network-2 in Burn), burn or onnx.
    #[arg(long, value_enum, default_value_t = Engine::Auto)]
    pub engine: Engine,
}

impl Default for NetworkOptions {
    fn default() -> Self {
        NetworkOptions {
            tile: None,
            overlap: None,
            weight: BlendWeight::Expected,
            tone_k: DEFAULT_TONE_K,
            engine: Engine::Auto,
        }
    }
}

impl NetworkOptions {
    /// `default` (a network's exact tiling) with the tile and overlap given here.
    pub fn tiling(&self, default: Tiling) -> Tiling {
        Tiling {
            tile: self.tile.unwrap_or(default.tile),
            overlap: self.overlap.unwrap_or(default.overlap),
            ..default
        }
    }
}

/// `--tile`: a whole number of pixels, at least 1.
fn tile_side(s: &str) -> std::result::Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!(
            "'{s}' is not a tile side: give a whole number of pixels ≥ 1"
        )),
    }
}

/// Planar C×H×W from interleaved images stacked channel-wise (e.g. (low, high) → 6 channels).
pub fn planar_from_images(frames: &[&Image]) -> Result<Planar> {
    let first = frames
        .first()
        .ok_or_else(|| Error::Invalid("no frames".into()))?;
    let (w, h) = (first.width, first.height);
    if let Some(f) = frames.iter().find(|f| (f.width, f.height) != (w, h)) {
        return Err(Error::Invalid(format!(
            "frames differ in size: {w}×{h} and {}×{}",
            f.width, f.height
        )));
    }
    let mut p = Planar::new(3 * frames.len(), w, h);
    for (k, f) in frames.iter().enumerate() {
        for (px, v) in f.data.chunks_exact(3).enumerate() {
            for (c, &x) in v.iter().enumerate() {
                p.data[(3 * k + c) * w * h + px] = x;
            }
        }
    }
    Ok(p)
}

/// Network-1's default tiling: the overlap covers the receptive field, so tiles are exact.
pub fn network1_tiling(cfg: &BlendUNetConfig) -> Tiling {
    Tiling {
        tile: DEFAULT_TILE,
        overlap: cfg.receptive_radius(),
        multiple: cfg.size_multiple(),
    }
}

/// Long-exposure blend weight per pixel (H×W) of the pair (low = EV−3, high = EV0), frames in
/// [0, 1] as the network was trained on. `model` must be an inference model (`valid()`) on
/// `device`.
pub fn network1_weight(
    model: &BlendUNet,
    low: &Image,
    high: &Image,
    tiling: Tiling,
    mode: BlendWeight,
    device: &Device,
) -> Result<Vec<f32>> {
    let input = planar_from_images(&[low, high])?;
    let classes = model.classes();
    let out = run_tiled(&input, 1, tiling, |win| {
        model.check_input(win.channels, win.height, win.width)?;
        let x = Tensor::<4>::from_data(
            TensorData::new(win.data.clone(), [1, win.channels, win.height, win.width]),
            device,
        );
        let logits = model
            .forward(x)
            .into_data()
            .try_to_vec::<f32>()
            .map_err(|e| Error::Invalid(format!("reading the class logits: {e:?}")))?;
        Ok(Planar {
            channels: 1,
            width: win.width,
            height: win.height,
            data: weight_from_logits(&logits, classes, win.width * win.height, mode)?,
        })
    })?;
    Ok(out.data)
}

/// Network-1 on a whole pair: (weight, linear L output, tone-mapped T output).
pub fn network1_fuse(
    model: &BlendUNet,
    low: &Image,
    high: &Image,
    tiling: Tiling,
    mode: BlendWeight,
    tone_k: f32,
    device: &Device,
) -> Result<(Vec<f32>, Image, Image)> {
    let w = network1_weight(model, low, high, tiling, mode, device)?;
    let (linear, toned) = fuse(low, high, &w, tone_k)?;
    Ok((w, linear, toned))
}

/// Network-2's default tiling: the overlap covers the receptive field, so tiles are exact.
pub fn network2_tiling(cfg: &WuConfig) -> Tiling {
    Tiling {
        tile: DEFAULT_TILE,
        overlap: cfg.receptive_radius(),
        multiple: cfg.size_multiple(),
    }
}

/// A set's Network-1 inputs ([`SetInfo::network1_pair`]), from its static frames where it
/// has them.
pub fn network1_frames(set: &SetInfo) -> Result<(Image, Image)> {
    let (lo, hi) = set.network1_pair()?;
    let frames = if set.static_frames.is_empty() {
        &set.dynamic_frames
    } else {
        &set.static_frames
    };
    Ok((read_image(&frames[lo])?, read_image(&frames[hi])?))
}

/// Network-1's outputs in `out`: linear.exr (the fused frame before the tone curve),
/// tonemapped.exr/.png (after it) and blend_weight.png (the long exposure's weight `w`).
pub fn write_network1(out: &Path, w: &[f32], linear: &Image, toned: &Image) -> Result<()> {
    write_exr(&out.join("linear.exr"), linear, ExrPrecision::Float)?;
    write_exr(&out.join("tonemapped.exr"), toned, ExrPrecision::Float)?;
    write_ldr(&out.join("tonemapped.png"), toned, BitDepth::Eight)?;
    let grey = Image::from_vec(
        linear.width,
        linear.height,
        w.iter().flat_map(|&v| [v, v, v]).collect(),
    );
    write_ldr(&out.join("blend_weight.png"), &grey, BitDepth::Eight)
}

/// Network-2's outputs in `out`: hdr.exr and its μ-law preview in the network's [0, 1] range.
pub fn write_network2(out: &Path, hdr: &Image, hdr_input_scale: f32) -> Result<()> {
    write_exr(&out.join("hdr.exr"), hdr, ExrPrecision::Float)?;
    let preview = hdr.map(|v| mu_law((v * hdr_input_scale).clamp(0.0, 1.0) as f64) as f32);
    write_ldr(&out.join("hdr_mulaw.png"), &preview, BitDepth::Eight)
}

/// A set's three Network-2 inputs (shortest, reference, longest exposure) and their exposure
/// times relative to the reference (2^EV), chosen as the loader does: the reference from the
/// static frames where the set has them (its ground truth is aligned to it), the others from
/// the dynamic frames where it has them.
pub fn network2_frames(set: &SetInfo) -> Result<([Image; 3], [f32; 3])> {
    if set.evs.len() < 3 {
        return Err(Error::layout(
            &set.dir,
            format!(
                "set '{}' has {} exposures; Network-2 needs three",
                set.name,
                set.evs.len()
            ),
        ));
    }
    let r = set.reference;
    let (lo, hi) = (0, set.evs.len() - 1);
    if r == lo || r == hi {
        return Err(Error::layout(
            &set.dir,
            format!(
                "set '{}': the reference (EV {}) is not between a shorter and a longer exposure",
                set.name, set.evs[r]
            ),
        ));
    }
    let pick = |i: usize| -> Result<Image> {
        let path = match set.reference_frame() {
            Some(p) if i == r => p,
            _ if set.dynamic_frames.is_empty() => &set.static_frames[i],
            _ => &set.dynamic_frames[i],
        };
        crate::data::layout::read_set_image(set, path)
    };
    let times = [lo, r, hi].map(|i| 2f32.powf(set.evs[i] - set.evs[r]));
    Ok(([pick(lo)?, pick(r)?, pick(hi)?], times))
}

/// Network-2's 18-channel input from three frames stacked planar (9 channels: RGB of each
/// frame, shortest first) and their exposure times relative to the reference: per frame 3 LDR
/// channels, then response⁻¹(LDR) / t with the network's input curve (the loader's layout;
/// Wu's LDR^2.2 for γ 2.2).
pub fn network2_input(ldr: &Planar, times: [f32; 3], curve: &Response) -> Planar {
    let (w, h) = (ldr.width, ldr.height);
    let mut input = Planar::new(18, w, h);
    let plane = w * h;
    for (k, &t) in times.iter().enumerate() {
        for c in 0..3 {
            let src = &ldr.data[(3 * k + c) * plane..(3 * k + c + 1) * plane];
            input.data[(6 * k + c) * plane..(6 * k + c + 1) * plane].copy_from_slice(src);
            let dst = &mut input.data[(6 * k + 3 + c) * plane..(6 * k + 4 + c) * plane];
            for (d, &v) in dst.iter_mut().zip(src) {
                *d = curve.invert_f32(v) / t;
            }
        }
    }
    input
}

/// Network-2 on a whole set of three frames (values in [0, 1]) with exposure times relative to
/// the reference: linear HDR relative to the reference exposure's white (the unit of the
/// loader's targets; the network's [0, 1] output divided by its `hdr_input_scale`). `model`
/// must be an inference model (`valid()`) on `device`.
pub fn network2_hdr(
    model: &WuNet,
    frames: [&Image; 3],
    times: [f32; 3],
    tiling: Tiling,
    device: &Device,
) -> Result<Image> {
    network2_hdr_with(
        model,
        frames,
        times,
        &model.config().input_response,
        tiling,
        device,
    )
}

/// [`network2_hdr`] with the HDR input channels formed through `curve` instead of the
/// network's own input curve.
pub fn network2_hdr_with(
    model: &WuNet,
    frames: [&Image; 3],
    times: [f32; 3],
    curve: &Response,
    tiling: Tiling,
    device: &Device,
) -> Result<Image> {
    let (w, h) = (frames[0].width, frames[0].height);
    let input = network2_input(&planar_from_images(&frames)?, times, curve);
    let plane = w * h;
    let unit = 1.0 / model.config().hdr_input_scale as f32;
    let out = run_tiled(&input, 3, tiling, |win| {
        model.check_input(win.channels, win.height, win.width)?;
        let x = Tensor::<4>::from_data(
            TensorData::new(win.data.clone(), [1, win.channels, win.height, win.width]),
            device,
        );
        let data = model
            .forward(x)
            .mul_scalar(unit)
            .into_data()
            .try_to_vec::<f32>()
            .map_err(|e| Error::Invalid(format!("reading the HDR output: {e:?}")))?;
        Ok(Planar {
            channels: 3,
            width: win.width,
            height: win.height,
            data,
        })
    })?;
    let mut img = Image::new(w, h);
    for (px, v) in img.data.chunks_exact_mut(3).enumerate() {
        for (c, x) in v.iter_mut().enumerate() {
            *x = out.data[c * plane + px];
        }
    }
    Ok(img)
}
