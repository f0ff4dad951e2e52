//! Whole-image inference of an exported model in ONNX Runtime, through the same exact tiling as
//! Burn's (`eval::tiling`, `eval::infer`).
//!
//! A dynamic model takes every window as it is. A static model takes only its own size, so each
//! window (never larger than that size: the tile is chosen so) is extended at the bottom and
//! right by edge replication to it and the result cropped back. The window's origin, and with
//! it the network's 2^d grid, is unchanged and the added pixels lie farther than the receptive
//! radius from every kept pixel, so the result equals the dynamic model's.

use super::runtime::{Network, OnnxModel};
use crate::error::{Error, Result};
use crate::eval::blend::{BlendWeight, fuse, weight_from_probabilities};
use crate::eval::infer::{DEFAULT_TILE, planar_from_images};
use crate::eval::tiling::{Planar, Tiling, run_tiled};
use crate::io::Image;

/// The exact tiling of `model`: overlap = its receptive radius; for a static model the largest
/// tile whose windows fit its size.
pub fn default_tiling(model: &OnnxModel) -> Result<Tiling> {
    let (m, overlap) = (model.size_multiple, model.receptive_radius);
    let tile = match model.static_size {
        None => DEFAULT_TILE,
        Some((h, w)) => {
            let fits = |t: usize| (t + 2 * overlap).div_ceil(m) * m <= h.min(w);
            let t = (1..).map(|k| k * m).take_while(|&t| fits(t)).last();
            t.ok_or_else(|| {
                Error::config(
                    model.path(),
                    format!(
                        "a static {h}×{w} model is too small for exact tiling with overlap \
                         {overlap}: export at least {}×{} or --dynamic",
                        (m + 2 * overlap).div_ceil(m) * m,
                        (m + 2 * overlap).div_ceil(m) * m
                    ),
                )
            })?
        }
    };
    Ok(Tiling {
        tile,
        overlap,
        multiple: m,
    })
}

/// `win` (C×h×w) extended to `height`×`width` by edge replication at the bottom and right.
fn extend(win: &Planar, height: usize, width: usize) -> Result<Planar> {
    if win.height > height || win.width > width {
        return Err(Error::Invalid(format!(
            "tiling: window {}×{} is larger than the static model's {height}×{width}; use a \
             smaller --tile",
            win.height, win.width
        )));
    }
    let mut out = Planar::new(win.channels, width, height);
    for c in 0..win.channels {
        for y in 0..height {
            let sy = y.min(win.height - 1);
            for x in 0..width {
                out.data[(c * height + y) * width + x] = win.at(c, x.min(win.width - 1), sy);
            }
        }
    }
    Ok(out)
}

/// The top-left `height`×`width` of a C×H×W result.
fn crop(
    data: &[f32],
    channels: usize,
    (sh, sw): (usize, usize),
    height: usize,
    width: usize,
) -> Planar {
    let mut out = Planar::new(channels, width, height);
    for c in 0..channels {
        for y in 0..height {
            let src = (c * sh + y) * sw;
            out.data[(c * height + y) * width..(c * height + y + 1) * width]
                .copy_from_slice(&data[src..src + width]);
        }
    }
    out
}

/// Runs `f` on `win`, through the static size if the model has one; `f` gets the planar input
/// and its (h, w) and returns `channels`×h×w.
fn run_window(
    model: &mut OnnxModel,
    win: &Planar,
    channels: usize,
    mut f: impl FnMut(&mut OnnxModel, &Planar, (usize, usize)) -> Result<Vec<f32>>,
) -> Result<Planar> {
    let (h, w) = (win.height, win.width);
    match model.static_size {
        None => Ok(Planar {
            channels,
            width: w,
            height: h,
            data: f(model, win, (h, w))?,
        }),
        Some(size) => {
            let big = extend(win, size.0, size.1)?;
            let out = f(model, &big, size)?;
            Ok(crop(&out, channels, size, h, w))
        }
    }
}

/// Network-1's long-exposure weight per pixel (H×W) of the pair (EV−3, EV0) from an exported
/// model: its `blend_weight` output (expected weight) where it has one, else computed from its
/// probabilities.
pub fn network1_weight(
    model: &mut OnnxModel,
    low: &Image,
    high: &Image,
    tiling: Tiling,
    mode: BlendWeight,
) -> Result<Vec<f32>> {
    if model.network != Network::Network1 {
        return Err(Error::config(model.path(), "not a Network-1 model"));
    }
    let input = planar_from_images(&[low, high])?;
    let out = run_tiled(&input, 1, tiling, |win| {
        run_window(model, win, 1, |m, x, (h, w)| {
            let plane = 3 * h * w;
            let (low, high) = (&x.data[..plane], &x.data[plane..]);
            if m.has_weight && mode == BlendWeight::Expected {
                return m.network1_blend_weight(low, high, (1, h, w));
            }
            let (probs, _) = m.network1(low, high, (1, h, w))?;
            let classes = probs.len() / (h * w);
            weight_from_probabilities(&probs, classes, h * w, mode)
        })
    })?;
    Ok(out.data)
}

/// Network-1 on a whole pair: (weight, linear L output, tone-mapped T output).
pub fn network1_fuse(
    model: &mut OnnxModel,
    low: &Image,
    high: &Image,
    tiling: Tiling,
    mode: BlendWeight,
    tone_k: f32,
) -> Result<(Vec<f32>, Image, Image)> {
    let w = network1_weight(model, low, high, tiling, mode)?;
    let (linear, toned) = fuse(low, high, &w, tone_k)?;
    Ok((w, linear, toned))
}

/// Network-2 on three whole frames (EV −2, 0, +2) with exposure times relative to the
/// reference: linear HDR, 1 = the reference exposure's white (as `eval::infer::network2_hdr`).
pub fn network2_hdr(
    model: &mut OnnxModel,
    frames: [&Image; 3],
    times: [f32; 3],
    tiling: Tiling,
) -> Result<Image> {
    if model.network != Network::Network2 {
        return Err(Error::config(model.path(), "not a Network-2 model"));
    }
    let (w, h) = (frames[0].width, frames[0].height);
    let input = planar_from_images(&frames)?;
    let out = run_tiled(&input, 3, tiling, |win| {
        run_window(model, win, 3, |m, x, (h, w)| {
            let plane = 3 * h * w;
            m.network2(
                [
                    &x.data[..plane],
                    &x.data[plane..2 * plane],
                    &x.data[2 * plane..],
                ],
                &times,
                (1, h, w),
            )
        })
    })?;
    let plane = w * h;
    let mut img = Image::new(w, h);
    for (px, v) in img.data.chunks_exact_mut(3).enumerate() {
        for (c, x) in v.iter_mut().enumerate() {
            *x = out.data[c * plane + px];
        }
    }
    Ok(img)
}
