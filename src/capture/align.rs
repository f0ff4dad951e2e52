//! Global alignment of hand-held brackets: median threshold bitmaps (Ward 2003, "Fast, Robust
//! Image Registration for Compositing High Dynamic Range Photographs from Hand-Held Exposures"),
//! as OpenCV's `AlignMTB::calculateShift` does it (the oracle, tools/crf_oracle.py): 8-bit grey
//! (0.299 R + 0.587 G + 0.114 B), a pyramid of halvings, per level the threshold bitmap
//! (grey > median) and the exclusion bitmap (|grey − median| > `exclude`), and the best of the
//! 3×3 shifts around twice the coarser level's shift by the count of differing, non-excluded
//! bits. Translation only, whole pixels. One deliberate difference: on ties the current shift is
//! kept (OpenCV takes the first candidate in its scan order, so a textureless frame drifts even
//! against itself).

use crate::io::Image;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MtbOptions {
    /// Pyramid levels − 1 bound: shifts up to ±(2^max_bits − 1) px (OpenCV default 6).
    pub max_bits: u32,
    /// Grey levels around the median left out of the comparison (OpenCV default 4).
    pub exclude: u8,
}

impl Default for MtbOptions {
    fn default() -> Self {
        MtbOptions {
            max_bits: 6,
            exclude: 4,
        }
    }
}

struct Grey {
    w: usize,
    h: usize,
    v: Vec<u8>,
}

fn grey(img: &Image) -> Grey {
    let v = img
        .pixels()
        .map(|p| {
            let g = 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
            (g.clamp(0.0, 1.0) * 255.0).round() as u8
        })
        .collect();
    Grey {
        w: img.width,
        h: img.height,
        v,
    }
}

/// Half size by the crate's box resize (the 2×2 mean, as OpenCV's linear halving).
fn half(g: &Grey) -> Grey {
    let img = Image::from_vec(
        g.w,
        g.h,
        g.v.iter()
            .flat_map(|&x| {
                let f = f32::from(x) / 255.0;
                [f, f, f]
            })
            .collect(),
    );
    let (w, h) = (g.w / 2, g.h / 2);
    let small = crate::io::resize(&img, w, h);
    Grey {
        w,
        h,
        v: small
            .data
            .chunks_exact(3)
            .map(|p| (p[0] * 255.0).round() as u8)
            .collect(),
    }
}

/// OpenCV's median: the first grey level whose cumulative count below it reaches half.
fn median(g: &Grey) -> i32 {
    let mut hist = [0usize; 256];
    for &v in &g.v {
        hist[v as usize] += 1;
    }
    let thresh = g.v.len() / 2;
    let (mut m, mut sum) = (0usize, 0usize);
    while sum < thresh && m < 256 {
        sum += hist[m];
        m += 1;
    }
    m as i32
}

/// (threshold, exclusion) bitmaps.
fn bitmaps(g: &Grey, exclude: u8) -> (Vec<bool>, Vec<bool>) {
    let m = median(g);
    let e = i32::from(exclude);
    let tb = g.v.iter().map(|&v| i32::from(v) > m).collect();
    let eb =
        g.v.iter()
            .map(|&v| {
                let v = i32::from(v);
                v < m - e || v > m + e
            })
            .collect();
    (tb, eb)
}

/// Bitmap moved by (dx, dy): out(x, y) = src(x − dx, y − dy), false outside.
fn shifted(b: &[bool], w: usize, h: usize, dx: i32, dy: i32) -> Vec<bool> {
    let mut out = vec![false; b.len()];
    for y in 0..h as i32 {
        let sy = y - dy;
        if sy < 0 || sy >= h as i32 {
            continue;
        }
        for x in 0..w as i32 {
            let sx = x - dx;
            if sx >= 0 && sx < w as i32 {
                out[(y as usize) * w + x as usize] = b[(sy as usize) * w + sx as usize];
            }
        }
    }
    out
}

/// The shift (dx, dy) that moves `img` onto `reference` (OpenCV's `calculateShift(reference,
/// img)`): `img` moved by it, out(x, y) = img(x − dx, y − dy), lines up with `reference`.
pub fn mtb_shift(reference: &Image, img: &Image, opts: MtbOptions) -> (i32, i32) {
    let (g0, g1) = (grey(reference), grey(img));
    let longest = g0.w.max(g0.h).max(1) as f64;
    let max_level = ((longest.ln() / 2f64.ln()) as i32 - 1)
        .min(opts.max_bits as i32 - 1)
        .max(0) as usize;
    let mut p0 = vec![g0];
    let mut p1 = vec![g1];
    for l in 1..=max_level {
        p0.push(half(&p0[l - 1]));
        p1.push(half(&p1[l - 1]));
    }
    let (mut sx, mut sy) = (0i32, 0i32);
    for l in (0..=max_level).rev() {
        sx *= 2;
        sy *= 2;
        let (a, b) = (&p0[l], &p1[l]);
        let (tb1, eb1) = bitmaps(a, opts.exclude);
        let (tb2, eb2) = bitmaps(b, opts.exclude);
        let err_at = |tx: i32, ty: i32| {
            let t2 = shifted(&tb2, b.w, b.h, tx, ty);
            let e2 = shifted(&eb2, b.w, b.h, tx, ty);
            (0..tb1.len())
                .filter(|&k| (tb1[k] != t2[k]) && eb1[k] && e2[k])
                .count()
        };
        // The current shift first, then OpenCV's scan order (x offset outer, y inner), strictly
        // smaller wins. OpenCV starts from "no candidate", so on ties (textureless frames,
        // where the exclusion bitmap hides every edge) it drifts to (−1, −1) per level — even
        // for a frame against itself; here a tie keeps the current shift.
        let mut best = (err_at(sx, sy), sx, sy);
        for i in -1..=1 {
            for j in -1..=1 {
                if (i, j) == (0, 0) {
                    continue;
                }
                let (tx, ty) = (sx + i, sy + j);
                let err = err_at(tx, ty);
                if err < best.0 {
                    best = (err, tx, ty);
                }
            }
        }
        (sx, sy) = (best.1, best.2);
    }
    (sx, sy)
}

/// Crop every frame to the region all of them cover once frame i is moved by `shifts[i]`
/// (out(x, y) = frame(x − dx, y − dy)); returns the cropped frames.
pub fn apply_shifts(frames: &[Image], shifts: &[(i32, i32)]) -> Vec<Image> {
    let region = common_region(frames[0].width, frames[0].height, shifts);
    frames
        .iter()
        .zip(shifts)
        .map(|(f, &s)| crop_shifted(f, s, region))
        .collect()
}

/// The region (x0, y0, width, height), in reference coordinates, that frames of size w×h
/// shifted by `shifts` all cover.
pub fn common_region(w: usize, h: usize, shifts: &[(i32, i32)]) -> (i32, i32, usize, usize) {
    let (w, h) = (w as i32, h as i32);
    // In reference coordinates, frame i covers x ∈ [dx, w + dx).
    let x0 = shifts.iter().map(|s| s.0).max().unwrap_or(0).max(0);
    let x1 = shifts.iter().map(|s| w + s.0).min().unwrap_or(w).min(w);
    let y0 = shifts.iter().map(|s| s.1).max().unwrap_or(0).max(0);
    let y1 = shifts.iter().map(|s| h + s.1).min().unwrap_or(h).min(h);
    (x0, y0, (x1 - x0).max(0) as usize, (y1 - y0).max(0) as usize)
}

/// `frame`, shifted by (dx, dy), cropped to `region` ([`common_region`]).
pub fn crop_shifted(
    frame: &Image,
    (dx, dy): (i32, i32),
    (x0, y0, cw, ch): (i32, i32, usize, usize),
) -> Image {
    Image::from_fn(cw, ch, |x, y| {
        frame.get((x as i32 + x0 - dx) as usize, (y as i32 + y0 - dy) as usize)
    })
}
