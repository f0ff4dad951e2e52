//! Full-resolution inference by overlapping tiles with bounded memory.
//!
//! Inference is defined as the operator applied to the image extended by reflection
//! (OpenCV's reflect-101) by `overlap` pixels on every side and, at the bottom and right, up to
//! a multiple of `multiple` (a U-Net with d down-samplings needs 2^d). Tiling computes exactly
//! that, one window at a time: the image is covered by cores of at most `tile`×`tile` pixels;
//! each core is run with `overlap` pixels of context on every side (read through the same
//! reflection where the context leaves the image), rounded up to the multiple; only the core of
//! the result is kept. A window that covers the whole image is the untiled computation, so for
//! an operator whose receptive field reaches at most `overlap` pixels the stitched result
//! equals the untiled one. Memory is one window of input and output at a time plus the result.
//!
//! Pooling and strided layers are not shift-invariant: the windows all start at
//! (core − overlap), so with `tile` a multiple of `multiple` every window sits on the same
//! 2^d grid as the untiled run (checked by [`run_tiled`]).

use crate::data::pyramid::reflect101;
use crate::error::{Error, Result};

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tiling {
    /// Core tile side in pixels.
    pub tile: usize,
    /// Context added on each side of a core (≥ the operator's receptive-field radius).
    pub overlap: usize,
    /// Window sides are rounded up to a multiple of this.
    pub multiple: usize,
}

/// A planar (C×H×W) image.
#[derive(Clone, Debug, PartialEq)]
pub struct Planar {
    pub channels: usize,
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
}

impl Planar {
    pub fn new(channels: usize, width: usize, height: usize) -> Planar {
        Planar {
            channels,
            width,
            height,
            data: vec![0.0; channels * width * height],
        }
    }
    #[inline]
    pub fn at(&self, c: usize, x: usize, y: usize) -> f32 {
        self.data[(c * self.height + y) * self.width + x]
    }
}

/// Run `op` over `input` window by window; `op` maps a C×h×w window to an `out_channels`×h×w
/// result of the same size.
pub fn run_tiled(
    input: &Planar,
    out_channels: usize,
    t: Tiling,
    mut op: impl FnMut(&Planar) -> Result<Planar>,
) -> Result<Planar> {
    if t.tile == 0 || t.multiple == 0 {
        return Err(Error::Invalid(
            "tiling: tile and multiple must be ≥ 1".into(),
        ));
    }
    let (w, h) = (input.width, input.height);
    if w == 0 || h == 0 {
        return Err(Error::Invalid("tiling: empty image".into()));
    }
    // Tiles smaller than the image must keep every window on the operator's grid.
    if (t.tile < w || t.tile < h) && !t.tile.is_multiple_of(t.multiple) {
        return Err(Error::Invalid(format!(
            "tiling: tile {} is not a multiple of {}; windows would fall off the network's \
             down-sampling grid",
            t.tile, t.multiple
        )));
    }
    let mut out = Planar::new(out_channels, w, h);
    let round_up = |v: usize| v.div_ceil(t.multiple) * t.multiple;
    let o = t.overlap as isize;
    for cy in (0..h).step_by(t.tile) {
        for cx in (0..w).step_by(t.tile) {
            let (cw, ch) = (t.tile.min(w - cx), t.tile.min(h - cy));
            let (pw, ph) = (round_up(cw + 2 * t.overlap), round_up(ch + 2 * t.overlap));
            let (x0, y0) = (cx as isize - o, cy as isize - o);
            let xs: Vec<usize> = (0..pw).map(|i| reflect101(x0 + i as isize, w)).collect();
            let mut tile = Planar::new(input.channels, pw, ph);
            for c in 0..input.channels {
                for ty in 0..ph {
                    let sy = reflect101(y0 + ty as isize, h);
                    let row = &mut tile.data[(c * ph + ty) * pw..(c * ph + ty + 1) * pw];
                    for (v, &sx) in row.iter_mut().zip(&xs) {
                        *v = input.at(c, sx, sy);
                    }
                }
            }
            let res = op(&tile)?;
            if (res.channels, res.width, res.height) != (out_channels, pw, ph) {
                return Err(Error::Invalid(format!(
                    "tiling: operator returned {}×{}×{}, expected {out_channels}×{ph}×{pw}",
                    res.channels, res.height, res.width
                )));
            }
            for c in 0..out_channels {
                for y in 0..ch {
                    let src = (c * ph + t.overlap + y) * pw + t.overlap;
                    let dst = (c * h + cy + y) * w + cx;
                    out.data[dst..dst + cw].copy_from_slice(&res.data[src..src + cw]);
                }
            }
        }
    }
    Ok(out)
}

/// The same computation in one window (the reference the tiles reproduce): `op` on the whole
/// image extended by reflection, cropped back.
pub fn run_untiled(
    input: &Planar,
    out_channels: usize,
    overlap: usize,
    multiple: usize,
    op: impl FnMut(&Planar) -> Result<Planar>,
) -> Result<Planar> {
    let tile = input.width.max(input.height);
    run_tiled(
        input,
        out_channels,
        Tiling {
            tile,
            overlap,
            multiple,
        },
        op,
    )
}
