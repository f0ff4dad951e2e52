//! Resampling of linear images (test-set radiance maps, evaluation thumbnails, alignment
//! pyramids).

use crate::io::Image;
use rayon::prelude::*;

/// Resample to `w`×`h`, separably: each output pixel averages the input over its footprint
/// (a box filter, exact with fractional coverage) when shrinking, bilinear (pixel centres
/// aligned, edges clamped) when enlarging. Values are averaged as given (linear in, linear out).
pub fn resize(img: &Image, w: usize, h: usize) -> Image {
    if (w, h) == (img.width, img.height) || img.width == 0 || img.height == 0 {
        return img.clone();
    }
    let cols = taps(img.width, w);
    let rows = taps(img.height, h);
    // Horizontal pass into an intermediate w × source height image, then vertical.
    let mut mid = vec![0f32; w * img.height * 3];
    mid.par_chunks_mut(w * 3)
        .zip(img.data.par_chunks(img.width * 3))
        .for_each(|(o, src)| {
            for (x, t) in cols.iter().enumerate() {
                let mut acc = [0f32; 3];
                for &(i, wt) in t {
                    for c in 0..3 {
                        acc[c] += wt * src[i * 3 + c];
                    }
                }
                o[x * 3..x * 3 + 3].copy_from_slice(&acc);
            }
        });
    let mut out = Image::new(w, h);
    out.data
        .par_chunks_mut(w * 3)
        .zip(rows.par_iter())
        .for_each(|(o, t)| {
            for &(i, wt) in t {
                let src = &mid[i * w * 3..(i + 1) * w * 3];
                for (a, b) in o.iter_mut().zip(src) {
                    *a += wt * b;
                }
            }
        });
    out
}

/// Per output index, the (input index, weight) pairs of a 1-D resampling from n to m.
fn taps(n: usize, m: usize) -> Vec<Vec<(usize, f32)>> {
    let scale = n as f64 / m as f64;
    (0..m)
        .map(|o| {
            if scale > 1.0 {
                let (a, b) = (o as f64 * scale, (o + 1) as f64 * scale);
                let mut t = Vec::new();
                let mut i = a.floor() as usize;
                while (i as f64) < b && i < n {
                    let cover = (b.min(i as f64 + 1.0) - a.max(i as f64)).max(0.0);
                    if cover > 0.0 {
                        t.push((i, (cover / scale) as f32));
                    }
                    i += 1;
                }
                t
            } else {
                let x = ((o as f64 + 0.5) * scale - 0.5).clamp(0.0, (n - 1) as f64);
                let i = x.floor() as usize;
                let f = x - i as f64;
                if i + 1 < n && f > 0.0 {
                    vec![(i, (1.0 - f) as f32), (i + 1, f as f32)]
                } else {
                    vec![(i, 1.0)]
                }
            }
        })
        .collect()
}
