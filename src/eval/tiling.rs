//! Full-resolution inference by overlapping tiles with bounded memory.
//!
//! The image is covered by tiles of at most `tile`×`tile` pixels whose cores abut; each tile is
//! extended by `overlap` pixels of context on every side (clipped at the image border), padded
//! by reflection (OpenCV's reflect-101) up to a multiple of `multiple` (a U-Net with d
//! down-samplings needs 2^d), run through the operator, and only its core is kept. For an
//! operator whose receptive field reaches at most `overlap` pixels, the stitched result equals
//! the untiled one; memory is one padded tile of input and output at a time plus the result.

use crate::data::pyramid::reflect101;
use crate::error::{Error, Result};

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tiling {
    /// Core tile side in pixels.
    pub tile: usize,
    /// Context added on each side of a core (≥ the operator's receptive-field radius).
    pub overlap: usize,
    /// Padded tile sides are rounded up to a multiple of this.
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

/// Run `op` over `input` tile by tile; `op` maps a padded C×h×w tile to an `out_channels`×h×w
/// tile of the same size.
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
    let mut out = Planar::new(out_channels, w, h);
    let round_up = |v: usize| v.div_ceil(t.multiple) * t.multiple;
    for cy in (0..h).step_by(t.tile) {
        for cx in (0..w).step_by(t.tile) {
            let (cw, ch) = (t.tile.min(w - cx), t.tile.min(h - cy));
            // Context window, clipped to the image, then padded by reflection to the multiple.
            let (x0, y0) = (cx.saturating_sub(t.overlap), cy.saturating_sub(t.overlap));
            let (x1, y1) = ((cx + cw + t.overlap).min(w), (cy + ch + t.overlap).min(h));
            let (pw, ph) = (round_up(x1 - x0), round_up(y1 - y0));
            let mut tile = Planar::new(input.channels, pw, ph);
            for c in 0..input.channels {
                for ty in 0..ph {
                    // Reflect inside the context window, so padding mirrors what the operator
                    // would see at a true image border.
                    let sy = y0 + reflect101(ty as isize, y1 - y0);
                    for tx in 0..pw {
                        let sx = x0 + reflect101(tx as isize, x1 - x0);
                        tile.data[(c * ph + ty) * pw + tx] = input.at(c, sx, sy);
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
                    for x in 0..cw {
                        let v = res.at(c, cx - x0 + x, cy - y0 + y);
                        out.data[(c * h + cy + y) * w + cx + x] = v;
                    }
                }
            }
        }
    }
    Ok(out)
}
