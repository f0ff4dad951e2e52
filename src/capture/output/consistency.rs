//! The device-output check's inter-frame consistency: how much a set's frames disagree with
//! each other at coarse scales, over what their noise gives.
//!
//! On each unit's noise plane (a frame against the merge of its set's others, less the code
//! it is expected to record at that value: any global tone curve cancels; or a repeated
//! pair's difference), per channel, the plane is cut into B×B blocks (B = 4 and 16) whose
//! every value is recorded (codes 3–250). White noise gives a block mean of variance σ²/B²,
//! σ² the variance inside the blocks; a frame whose codes depend on more than its own value —
//! a tone curve that varies over the frame or with the neighbourhood (local tone mapping), a
//! per-frame shading, the noise's own correlation — gives block means beyond that. The
//! statistic per scale is ½ ln(mean block mean² · B² / mean block variance): 0 for white
//! noise. Networks read such disagreement between frames of a static scene as motion.

use super::RECORDED;
use crate::capture::noise::Planes;

/// The block sizes, pixels.
pub(super) const SCALES: [usize; 2] = [4, 16];

/// Per scale the sums of block mean², of block variance, and the blocks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct BandMoments {
    mean_sq: [f64; 2],
    var: [f64; 2],
    blocks: [f64; 2],
}

impl BandMoments {
    pub fn add(&mut self, o: &BandMoments) {
        for s in 0..SCALES.len() {
            self.mean_sq[s] += o.mean_sq[s];
            self.var[s] += o.var[s];
            self.blocks[s] += o.blocks[s];
        }
    }

    /// The statistic at scale index `s` (NaN with fewer than 16 blocks or no variance).
    pub fn value(&self, s: usize) -> f64 {
        let b2 = (SCALES[s] * SCALES[s]) as f64;
        if self.blocks[s] < 16.0 || self.var[s] <= 0.0 {
            return f64::NAN;
        }
        0.5 * (self.mean_sq[s] * b2 / self.var[s]).ln()
    }
}

/// The moments of one unit.
pub(super) fn moments(p: Planes) -> BandMoments {
    let mut m = BandMoments::default();
    for (s, &b) in SCALES.iter().enumerate() {
        for c in 0..3 {
            let (sq, var, n) = blocks(&p, c, b);
            m.mean_sq[s] += sq;
            m.var[s] += var;
            m.blocks[s] += n;
        }
    }
    m
}

/// Channel `c`'s b×b blocks of `p` with every value recorded: Σ mean², Σ variance, count.
fn blocks(p: &Planes, c: usize, b: usize) -> (f64, f64, f64) {
    let (w, h) = (p.signal.width, p.signal.height);
    let n = (b * b) as f64;
    let (mut sq, mut var, mut count) = (0.0, 0.0, 0.0);
    for by in 0..h / b {
        'block: for bx in 0..w / b {
            let (mut s1, mut s2) = (0.0, 0.0);
            for y in by * b..(by + 1) * b {
                for x in bx * b..(bx + 1) * b {
                    let i = (y * w + x) * 3 + c;
                    if !(RECORDED.0..=RECORDED.1).contains(&p.signal.data[i]) {
                        continue 'block;
                    }
                    let v = f64::from(p.noise.data[i]);
                    s1 += v;
                    s2 += v * v;
                }
            }
            let mean = s1 / n;
            sq += mean * mean;
            var += (s2 / n - mean * mean).max(0.0);
            count += 1.0;
        }
    }
    (sq, var, count)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::Image;

    fn planes_of(noise: &Image, signal: &Image) -> BandMoments {
        moments(Planes {
            signal,
            noise,
            flat_fraction: 1.0,
            quantum: 1e-7,
        })
    }

    /// White noise gives 0 at both scales (within its sampling error); a shading of one
    /// 16-pixel block's worth does not.
    #[test]
    fn white_noise_is_zero_and_a_shading_is_not() {
        let (w, h) = (256, 256);
        let mut state = 12345u64;
        let mut gauss = || {
            // Box–Muller on a small LCG: a fixed, outside-free white noise.
            let mut u = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            ((-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()) as f32
        };
        let noise = Image::from_fn(w, h, |_, _| {
            [gauss() * 0.01, gauss() * 0.01, gauss() * 0.01]
        });
        let signal = Image::from_fn(w, h, |_, _| [0.5; 3]);
        let white = planes_of(&noise, &signal);
        for s in 0..2 {
            assert!(white.value(s).abs() < 0.1, "scale {s}: {}", white.value(s));
        }
        // A slow shading of ±0.01 (the noise's σ): invisible per pixel, plain in 16-px means.
        let shaded = Image::from_fn(w, h, |x, y| {
            let d = 0.005 * ((x as f32 / 40.0).sin() + (y as f32 / 40.0).cos());
            noise.get(x, y).map(|v| v + d)
        });
        let m = planes_of(&shaded, &signal);
        assert!(m.value(1) > 1.0, "{}", m.value(1));
        assert!(m.value(0) > white.value(0));
        // Unrecorded values leave their blocks out: a frame with none has no statistic.
        let dark = Image::from_fn(w, h, |_, _| [0.0; 3]);
        assert!(planes_of(&noise, &dark).value(1).is_nan());
    }
}
