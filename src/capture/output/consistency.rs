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
//! noise. Networks read such disagreement between frames of a static scene as motion. The
//! 4-pixel statistic is also taken per code band of the blocks (shadows, mid-tones,
//! highlights): a tone curve that changes near what a frame clips disagrees in the highlights
//! alone, which the pooled value dilutes.

use super::RECORDED;
use crate::capture::noise::Planes;

/// The block sizes, pixels.
pub(super) const SCALES: [usize; 2] = [4, 16];

/// Upper ends of the code bands the 4-pixel statistic is also taken in, by the block's mean
/// code: shadows, mid-tones, and highlights up to the recorded top (where a frame's neighbours
/// clip, and a tone curve that changes near clipping leaves its mark).
pub(super) const LEVELS: [f32; 3] = [64.0 / 255.0, 192.0 / 255.0, f32::INFINITY];

/// Σ block mean², Σ block variance, blocks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Sums {
    mean_sq: f64,
    var: f64,
    blocks: f64,
}

impl Sums {
    fn add(&mut self, o: &Sums) {
        self.mean_sq += o.mean_sq;
        self.var += o.var;
        self.blocks += o.blocks;
    }

    /// ½ ln(mean block mean² · `area` / mean variance); NaN with fewer than 16 blocks or no
    /// variance.
    fn value(&self, area: f64) -> f64 {
        if self.blocks < 16.0 || self.var <= 0.0 {
            return f64::NAN;
        }
        0.5 * (self.mean_sq * area / self.var).ln()
    }
}

/// Per scale the sums over every block, and the 4-pixel blocks' per code band.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct BandMoments {
    scale: [Sums; 2],
    level: [Sums; 3],
}

impl BandMoments {
    pub fn add(&mut self, o: &BandMoments) {
        for (a, b) in self.scale.iter_mut().zip(&o.scale) {
            a.add(b);
        }
        for (a, b) in self.level.iter_mut().zip(&o.level) {
            a.add(b);
        }
    }

    /// The statistic at scale index `s`.
    pub fn value(&self, s: usize) -> f64 {
        self.scale[s].value((SCALES[s] * SCALES[s]) as f64)
    }

    /// The 4-pixel statistic over the blocks of code band `k` ([`LEVELS`]).
    pub fn level_value(&self, k: usize) -> f64 {
        self.level[k].value((SCALES[0] * SCALES[0]) as f64)
    }
}

/// The moments of one unit.
pub(super) fn moments(p: Planes) -> BandMoments {
    let mut m = BandMoments::default();
    for (s, &b) in SCALES.iter().enumerate() {
        for c in 0..3 {
            for (level, sums) in blocks(&p, c, b) {
                m.scale[s].add(&sums);
                if s == 0 {
                    m.level[level].add(&sums);
                }
            }
        }
    }
    m
}

/// Channel `c`'s b×b blocks of `p` with every value recorded: each block's code band
/// ([`LEVELS`], by its mean code) and its sums.
fn blocks(p: &Planes, c: usize, b: usize) -> Vec<(usize, Sums)> {
    let (w, h) = (p.signal.width, p.signal.height);
    let n = (b * b) as f64;
    let mut out = Vec::new();
    for by in 0..h / b {
        'block: for bx in 0..w / b {
            let (mut s1, mut s2, mut code) = (0.0, 0.0, 0.0f32);
            for y in by * b..(by + 1) * b {
                for x in bx * b..(bx + 1) * b {
                    let i = (y * w + x) * 3 + c;
                    if !(RECORDED.0..=RECORDED.1).contains(&p.signal.data[i]) {
                        continue 'block;
                    }
                    let v = f64::from(p.noise.data[i]);
                    s1 += v;
                    s2 += v * v;
                    code += p.signal.data[i];
                }
            }
            let mean = s1 / n;
            let level = LEVELS
                .iter()
                .position(|&top| code / n as f32 <= top)
                .unwrap_or(LEVELS.len() - 1);
            out.push((
                level,
                Sums {
                    mean_sq: mean * mean,
                    var: (s2 / n - mean * mean).max(0.0),
                    blocks: 1.0,
                },
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::Image;

    /// Standard normal draws: Box–Muller on a small LCG, a fixed, outside-free white noise.
    fn gauss(mut state: u64) -> impl FnMut() -> f32 {
        move || {
            let mut u = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            ((-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()) as f32
        }
    }

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
        let mut gauss = gauss(12345);
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

    /// A disagreement only where the codes are high is seen in the highlights' band alone:
    /// the noise is white everywhere, and a ±0.01 shading is added where the signal is over
    /// 200/255.
    #[test]
    fn a_disagreement_in_the_highlights_is_seen_in_their_band_alone() {
        let (w, h) = (256, 256);
        let mut gauss = gauss(99);
        // Three vertical stripes: codes 0.1, 0.5 and 0.85.
        let signal = Image::from_fn(w, h, |x, _| [[0.1, 0.5, 0.85][x * 3 / w]; 3]);
        let noise = Image::from_fn(w, h, |x, y| {
            let shade = if x * 3 / w == 2 {
                0.01 * ((x as f32 / 6.0).sin() + (y as f32 / 6.0).cos())
            } else {
                0.0
            };
            [0; 3].map(|_| gauss() * 0.01 + shade)
        });
        let m = planes_of(&noise, &signal);
        assert!(m.level_value(0).abs() < 0.15, "{}", m.level_value(0));
        assert!(m.level_value(1).abs() < 0.15, "{}", m.level_value(1));
        assert!(m.level_value(2) > 0.5, "{}", m.level_value(2));
    }
}
