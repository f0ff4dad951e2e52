//! Gaussian and Laplacian pyramids and pyramid blending, exactly as OpenCV's `MergeMertens`
//! builds them (`buildPyramid`, `pyrDown`, `pyrUp` with their default border), so that the
//! ground truth (crate::data::ground_truth) reproduces `cv2.createMergeMertens` and Network-1's
//! inference blends its predicted weights the same way ([`laplacian_blend`]).
//!
//! Conventions (OpenCV's, see docs/ground_truth.md):
//! - Kernel: the 5-tap binomial [1 4 6 4 1], separable. Borders: BORDER_REFLECT_101
//!   (`dcb|abcd|cba`), OpenCV's default for both `pyrDown` and `pyrUp`.
//! - [`pyr_down`]: blur, keep even samples; output ((w+1)/2, (h+1)/2); weights /256 in 2-D.
//! - [`pyr_up`]: insert zeros between samples, blur with the same kernel ×4 (so /64 in 2-D),
//!   reflect-101 applied in the zero-inserted grid of size 2·w; the explicit output size may
//!   be 2w−1, 2w or 2w+1 per axis (2w±1: the 2w result cropped, or OpenCV's extra copy).
//! - Levels: [`max_level`] = ⌊log2 min(w, h)⌋ computed as MergeMertens does, in f32
//!   (`int(logf(min) / logf(2))`); a pyramid holds `max_level + 1` planes.
//!
//! Rows are processed in parallel with rayon.

use crate::error::{Error, Result};
use crate::io::Image;
use rayon::prelude::*;

/// The binomial kernel, unnormalised.
const KERNEL: [f32; 5] = [1.0, 4.0, 6.0, 4.0, 1.0];

/// Rows per rayon task: small planes (upper pyramid levels) are not worth splitting finely.
const MIN_ROWS_PER_TASK: usize = 4;

/// A plane of `channels` (1 or 3, or any other count) interleaved f32 samples, row-major:
/// pixel (x, y) channel c at `(y * width + x) * channels + c`. Pyramids of an [`Image`] use
/// 3 channels, pyramids of weight maps 1.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub data: Vec<f32>,
}

impl Plane {
    pub fn new(width: usize, height: usize, channels: usize) -> Plane {
        Plane {
            width,
            height,
            channels,
            data: vec![0.0; width * height * channels],
        }
    }

    /// Panics if `data.len() != width * height * channels` (a programming error).
    pub fn from_vec(width: usize, height: usize, channels: usize, data: Vec<f32>) -> Plane {
        assert_eq!(
            data.len(),
            width * height * channels,
            "Plane::from_vec: wrong length"
        );
        Plane {
            width,
            height,
            channels,
            data,
        }
    }

    /// A 3-channel plane holding a copy of `img`'s pixels.
    pub fn from_image(img: &Image) -> Plane {
        Plane::from_vec(img.width, img.height, 3, img.data.clone())
    }

    /// The 3-channel plane as an [`Image`]. Panics if `channels != 3`.
    pub fn into_image(self) -> Image {
        assert_eq!(self.channels, 3, "Plane::into_image: needs 3 channels");
        Image::from_vec(self.width, self.height, self.data)
    }

    #[inline]
    pub fn get(&self, x: usize, y: usize, c: usize) -> f32 {
        self.data[(y * self.width + x) * self.channels + c]
    }

    fn row_len(&self) -> usize {
        self.width * self.channels
    }
}

/// OpenCV's `borderInterpolate(p, len, BORDER_REFLECT_101)`: `gfedcb|abcdefgh|gfedcba`,
/// and 0 whenever `len == 1`.
pub fn reflect101(p: isize, len: usize) -> usize {
    assert!(len > 0, "reflect101: empty axis");
    if len == 1 {
        return 0;
    }
    let n = len as isize;
    let mut p = p;
    while p < 0 || p >= n {
        p = if p < 0 { -p } else { 2 * n - 2 - p };
    }
    p as usize
}

/// The top level index MergeMertens uses for a `width`×`height` image:
/// `int(logf(float(min(w, h))) / logf(2.0f))`, i.e. ⌊log2 min(w, h)⌋ as computed in f32.
pub fn max_level(width: usize, height: usize) -> usize {
    let m = width.min(height).max(1) as f32;
    (m.ln() / 2f32.ln()) as usize
}

/// Source taps of one output sample along one axis (at most 5; duplicates allowed).
#[derive(Clone, Copy, Debug)]
struct Taps {
    n: usize,
    idx: [usize; 5],
    w: [f32; 5],
}

impl Taps {
    fn push(&mut self, i: usize, w: f32) {
        self.idx[self.n] = i;
        self.w[self.n] = w;
        self.n += 1;
    }
}

const NO_TAPS: Taps = Taps {
    n: 0,
    idx: [0; 5],
    w: [0.0; 5],
};

/// pyrDown along one axis: output i reads source 2i−2 … 2i+2 (reflect-101 in the source).
fn down_taps(n_out: usize, n_src: usize) -> Vec<Taps> {
    (0..n_out)
        .map(|i| {
            let mut t = NO_TAPS;
            for (d, &w) in KERNEL.iter().enumerate() {
                t.push(reflect101(2 * i as isize + d as isize - 2, n_src), w);
            }
            t
        })
        .collect()
}

/// pyrUp along one axis: output X reads the zero-inserted grid u (u[2k] = src[k], odd = 0)
/// at X−2 … X+2, reflect-101 in the grid of size 2·n_src. Output 2·n_src (only when
/// `n_out == 2·n_src + 1`) copies OpenCV: the column of 2·n_src−1 horizontally, the row of
/// 2·n_src−2 vertically.
fn up_taps(n_out: usize, n_src: usize, vertical: bool) -> Vec<Taps> {
    let grid = 2 * n_src;
    let at = |x: usize| {
        let mut t = NO_TAPS;
        for (d, &w) in KERNEL.iter().enumerate() {
            let p = reflect101(x as isize + d as isize - 2, grid);
            if p.is_multiple_of(2) {
                t.push(p / 2, w);
            }
        }
        t
    };
    (0..n_out)
        .map(|x| {
            if x >= grid {
                at(if vertical { grid - 2 } else { grid - 1 })
            } else {
                at(x)
            }
        })
        .collect()
}

/// Separable filter-and-resample: horizontal taps `hx` per output column, vertical taps `vy`
/// per output row, result × `scale`.
fn separable(src: &Plane, hx: &[Taps], vy: &[Taps], scale: f32) -> Plane {
    let cn = src.channels;
    let (ow, oh) = (hx.len(), vy.len());
    let orow = ow * cn;
    let srow = src.row_len();
    if orow == 0 || oh == 0 {
        return Plane::new(ow, oh, cn);
    }
    // Horizontal pass over every source row.
    let mut tmp = vec![0f32; src.height * orow];
    tmp.par_chunks_mut(orow)
        .with_min_len(MIN_ROWS_PER_TASK)
        .enumerate()
        .for_each(|(y, out)| {
            let row = &src.data[y * srow..(y + 1) * srow];
            for (x, t) in hx.iter().enumerate() {
                for c in 0..cn {
                    let mut acc = 0f32;
                    for k in 0..t.n {
                        acc += t.w[k] * row[t.idx[k] * cn + c];
                    }
                    out[x * cn + c] = acc;
                }
            }
        });
    // Vertical pass per output row.
    let mut data = vec![0f32; oh * orow];
    data.par_chunks_mut(orow)
        .with_min_len(MIN_ROWS_PER_TASK)
        .enumerate()
        .for_each(|(y, out)| {
            let t = &vy[y];
            for k in 0..t.n {
                let r = &tmp[t.idx[k] * orow..(t.idx[k] + 1) * orow];
                let w = t.w[k];
                for (o, v) in out.iter_mut().zip(r) {
                    *o += w * v;
                }
            }
            for o in out.iter_mut() {
                *o *= scale;
            }
        });
    Plane::from_vec(ow, oh, cn, data)
}

/// OpenCV `pyrDown(src)` with BORDER_DEFAULT (reflect-101): 5×5 binomial blur /256, then every
/// other row and column; output ((w+1)/2, (h+1)/2).
pub fn pyr_down(src: &Plane) -> Plane {
    assert!(src.width > 0 && src.height > 0, "pyr_down: empty plane");
    let (ow, oh) = (src.width.div_ceil(2), src.height.div_ceil(2));
    separable(
        src,
        &down_taps(ow, src.width),
        &down_taps(oh, src.height),
        1.0 / 256.0,
    )
}

/// OpenCV `pyrUp(src, dst, Size(width, height))`: zero insertion and the 5×5 binomial ×4
/// (/64 in 2-D), reflect-101. Each output side must be 2·s−1, 2·s or 2·s+1 for the source
/// side s (OpenCV's `|dst − 2·src| == dst % 2`); otherwise an [`Error::Invalid`].
pub fn pyr_up(src: &Plane, width: usize, height: usize) -> Result<Plane> {
    let ok = |d: usize, s: usize| s > 0 && d.abs_diff(2 * s) == d % 2;
    if !ok(width, src.width) || !ok(height, src.height) {
        return Err(Error::Invalid(format!(
            "pyr_up: cannot upsample {}×{} to {width}×{height} (each side must be 2s−1, 2s or 2s+1)",
            src.width, src.height
        )));
    }
    Ok(pyr_up_unchecked(src, width, height))
}

fn pyr_up_unchecked(src: &Plane, width: usize, height: usize) -> Plane {
    separable(
        src,
        &up_taps(width, src.width, false),
        &up_taps(height, src.height, true),
        1.0 / 64.0,
    )
}

/// OpenCV `buildPyramid(src, pyr, max_level)`: `max_level + 1` planes, level 0 = `src`,
/// level l+1 = [`pyr_down`] of level l.
pub fn gaussian_pyramid(src: &Plane, max_level: usize) -> Vec<Plane> {
    let mut pyr = Vec::with_capacity(max_level + 1);
    pyr.push(src.clone());
    for l in 0..max_level {
        let next = pyr_down(&pyr[l]);
        pyr.push(next);
    }
    pyr
}

/// Laplacian pyramid as MergeMertens builds it: level l < max = G_l − pyrUp(G_{l+1}, size of
/// G_l); the last level is the Gaussian top G_max.
pub fn laplacian_pyramid(src: &Plane, max_level: usize) -> Vec<Plane> {
    let mut pyr = gaussian_pyramid(src, max_level);
    for l in 0..max_level {
        let up = pyr_up_unchecked(&pyr[l + 1], pyr[l].width, pyr[l].height);
        for (v, u) in pyr[l].data.iter_mut().zip(&up.data) {
            *v -= u;
        }
    }
    pyr
}

/// Collapse a Laplacian pyramid: from the top, level l−1 += pyrUp(level l). Returns level 0.
pub fn collapse(pyr: &[Plane]) -> Plane {
    assert!(!pyr.is_empty(), "collapse: empty pyramid");
    let mut acc = pyr[pyr.len() - 1].clone();
    for l in (0..pyr.len() - 1).rev() {
        let mut up = pyr_up_unchecked(&acc, pyr[l].width, pyr[l].height);
        for (u, v) in up.data.iter_mut().zip(&pyr[l].data) {
            *u += v;
        }
        acc = up;
    }
    acc
}

/// Pyramid blending as in OpenCV's MergeMertens: `Σ_i Laplacian(images[i]) · Gaussian(weights[i])`
/// level by level, then collapsed, with [`max_level`] of the image size. `weights[i]` holds one
/// weight per pixel of `images[i]` (row-major) and is used as given: callers pass weights
/// already normalised to sum 1 per pixel (Mertens) or a network's per-pixel blend weights.
/// No clipping of the result. Errors on no images, differing sizes or weight lengths.
pub fn laplacian_blend<W: AsRef<[f32]> + Sync>(images: &[Image], weights: &[W]) -> Result<Image> {
    let Some(first) = images.first() else {
        return Err(Error::Invalid("laplacian_blend: no images".into()));
    };
    let (w, h) = (first.width, first.height);
    if weights.len() != images.len() {
        return Err(Error::Invalid(format!(
            "laplacian_blend: {} images but {} weight maps",
            images.len(),
            weights.len()
        )));
    }
    for (i, (img, wt)) in images.iter().zip(weights).enumerate() {
        if (img.width, img.height) != (w, h) {
            return Err(Error::Invalid(format!(
                "laplacian_blend: image {i} is {}×{}, image 0 is {w}×{h}",
                img.width, img.height
            )));
        }
        if wt.as_ref().len() != w * h {
            return Err(Error::Invalid(format!(
                "laplacian_blend: weight map {i} has {} values for {w}×{h} pixels",
                wt.as_ref().len()
            )));
        }
    }
    if w == 0 || h == 0 {
        return Ok(Image::new(w, h));
    }
    let top = max_level(w, h);
    let mut result: Option<Vec<Plane>> = None;
    for (img, wt) in images.iter().zip(weights) {
        let mut lap = laplacian_pyramid(&Plane::from_image(img), top);
        let gw = gaussian_pyramid(&Plane::from_vec(w, h, 1, wt.as_ref().to_vec()), top);
        for (l, g) in lap.iter_mut().zip(&gw) {
            l.data
                .par_chunks_mut(3 * l.width.max(1))
                .zip(g.data.par_chunks(g.width.max(1)))
                .with_min_len(MIN_ROWS_PER_TASK)
                .for_each(|(row, grow)| {
                    for (px, &gv) in row.chunks_exact_mut(3).zip(grow) {
                        for v in px {
                            *v *= gv;
                        }
                    }
                });
        }
        match result.as_mut() {
            None => result = Some(lap),
            Some(acc) => {
                for (a, l) in acc.iter_mut().zip(&lap) {
                    for (x, y) in a.data.iter_mut().zip(&l.data) {
                        *x += y;
                    }
                }
            }
        }
    }
    let pyr = result.expect("at least one image");
    Ok(collapse(&pyr).into_image())
}
