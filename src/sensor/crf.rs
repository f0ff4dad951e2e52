//! Camera response from the brackets themselves: Debevec & Malik 1997, "Recovering High Dynamic
//! Range Radiance Maps from Photographs", computed as OpenCV's `CalibrateDebevec` computes it
//! (the oracle, tools/crf_oracle.py): per channel, unknowns g(0..255) and ln E_i of each sample
//! pixel; rows w(Z)·(g(Z) − ln E_i) = w(Z)·ln t_j for every sample and frame, g(128) = 0, and
//! λ·w(z)·(g(z−1) − 2g(z) + g(z+1)) = 0 for z = 1..254; triangle weights w(z) = z + 1 below 128,
//! 256 − z from 128; samples on OpenCV's regular grid (its default, `random = false`). Solved by
//! least squares (Householder QR, the full-rank solution OpenCV's SVD solve also gives).
//! The result is OpenCV's: exp(g(z)) per code and channel, the exposure giving code z.

use crate::error::{Error, Result};
use crate::io::Image;

pub const LDR_SIZE: usize = 256;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DebevecOptions {
    /// Sample pixels (OpenCV default 70).
    pub samples: usize,
    /// Smoothness weight λ (OpenCV default 10).
    pub lambda: f64,
}

impl Default for DebevecOptions {
    fn default() -> Self {
        DebevecOptions {
            samples: 70,
            lambda: 10.0,
        }
    }
}

fn weight(z: usize) -> f64 {
    if z < LDR_SIZE / 2 {
        z as f64 + 1.0
    } else {
        (LDR_SIZE - z) as f64
    }
}

/// OpenCV's regular sample grid for a `w`×`h` image.
fn sample_points(w: usize, h: usize, samples: usize) -> Vec<(usize, usize)> {
    let x_points = ((samples as f64 * w as f64 / h as f64).sqrt() as usize).clamp(1, w);
    let y_points = (samples / x_points).clamp(1, h);
    let (step_x, step_y) = (w / x_points, h / y_points);
    let mut pts = Vec::with_capacity(x_points * y_points);
    for i in 0..x_points {
        let x = step_x / 2 + i * step_x;
        for j in 0..y_points {
            let y = step_y / 2 + j * step_y;
            if x < w && y < h {
                pts.push((x, y));
            }
        }
    }
    pts
}

/// The response exp(g(z)) for z = 0..255 per channel (R, G, B) from frames of one static scene
/// (code values in [0, 1], quantised to 8 bits here) and their exposure times.
pub fn calibrate_debevec(
    frames: &[Image],
    times: &[f64],
    opts: DebevecOptions,
) -> Result<[Vec<f64>; 3]> {
    if frames.len() < 2 || frames.len() != times.len() {
        return Err(Error::Invalid(format!(
            "Debevec response: need two or more frames with one time each ({} frames, {} times)",
            frames.len(),
            times.len()
        )));
    }
    if times.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(Error::Invalid(format!(
            "Debevec response: times {times:?} must be positive"
        )));
    }
    let (w, h) = (frames[0].width, frames[0].height);
    if frames.iter().any(|f| (f.width, f.height) != (w, h)) || w == 0 || h == 0 {
        return Err(Error::Invalid(
            "Debevec response: frames differ in size".into(),
        ));
    }
    let pts = sample_points(w, h, opts.samples.max(1));
    let code = |f: &Image, x: usize, y: usize, c: usize| -> usize {
        (f.data[(y * w + x) * 3 + c].clamp(0.0, 1.0) * 255.0).round() as usize
    };
    let cols = LDR_SIZE + pts.len();
    let mut out: [Vec<f64>; 3] = Default::default();
    for (c, o) in out.iter_mut().enumerate() {
        let mut a: Vec<Vec<f64>> = Vec::new();
        let mut b: Vec<[f64; 1]> = Vec::new();
        for (i, &(x, y)) in pts.iter().enumerate() {
            for (f, t) in frames.iter().zip(times) {
                let z = code(f, x, y, c);
                let wz = weight(z);
                let mut row = vec![0.0; cols];
                row[z] = wz;
                row[LDR_SIZE + i] = -wz;
                a.push(row);
                b.push([wz * t.ln()]);
            }
        }
        let mut row = vec![0.0; cols];
        row[LDR_SIZE / 2] = 1.0;
        a.push(row);
        b.push([0.0]);
        for z in 0..LDR_SIZE - 2 {
            let lw = opts.lambda * weight(z + 1);
            let mut row = vec![0.0; cols];
            row[z] = lw;
            row[z + 1] = -2.0 * lw;
            row[z + 2] = lw;
            a.push(row);
            b.push([0.0]);
        }
        let x = crate::sensor::colour::least_squares("Debevec response", &a, &b)?;
        *o = x[..LDR_SIZE].iter().map(|g| g[0].exp()).collect();
    }
    Ok(out)
}

/// Code value → linear per channel from a response (exp g): normalised to 1 at code 255 and made
/// non-decreasing (the least-squares curve can wiggle where no sample constrains it).
pub fn linearisation_table(response: &[Vec<f64>; 3]) -> [Vec<f64>; 3] {
    response.clone().map(|r| {
        let top = r.last().copied().unwrap_or(1.0);
        let mut run = 0.0f64;
        r.iter()
            .map(|&e| {
                run = run.max(e / top);
                run.min(1.0)
            })
            .collect()
    })
}
