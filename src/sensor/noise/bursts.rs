//! Per-pixel temporal statistics of a burst, streamed frame by frame.

use super::MAD_TO_SIGMA;
use crate::io::Image;
use rayon::prelude::*;

pub(super) struct BurstStats {
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) frames: usize,
    /// Interleaved RGB, like `Image::data`.
    pub(super) mean: Vec<f32>,
    pub(super) var: Vec<f32>,
    pub(super) min: Vec<u16>,
    pub(super) max: Vec<u16>,
    pub(super) white: f64,
}

/// THE burst accumulator: exact per-value temporal sums of a burst, frame by frame (frames are
/// never all held in memory). Frames are integer DN in [0, 65535] (decoded captures:
/// `read_dn_frame`; simulated ones are quantised), so the sums are exact integers: offsets from
/// the first frame in i32/u64, and any other shift of them (`shifted_sums`) is exact too. The
/// noise calibration bins its per-pixel statistics (`finish`); the effects' burst summaries
/// (`effects::summary::Accumulator`) build on the same sums. Frames may be bands of `band` rows
/// of a larger frame stacked (`summary::crop_rows`): neighbourhoods then stay inside a band.
pub struct BurstFrames {
    dark: bool,
    band: usize,
    width: usize,
    height: usize,
    pub(crate) frames: usize,
    k: Vec<u16>,
    s1: Vec<i32>,
    s2: Vec<u64>,
    min: Vec<u16>,
    max: Vec<u16>,
    /// Dark bursts: each frame's outlier-clipped mean (the black-level estimate).
    pub(super) frame_means: Vec<f64>,
}

fn to_u16(v: f32) -> u16 {
    v.clamp(0.0, 65535.0) as u16
}

impl BurstFrames {
    pub fn new(dark: bool, band: usize) -> BurstFrames {
        BurstFrames {
            dark,
            band: band.max(1),
            width: 0,
            height: 0,
            frames: 0,
            k: Vec::new(),
            s1: Vec::new(),
            s2: Vec::new(),
            min: Vec::new(),
            max: Vec::new(),
            frame_means: Vec::new(),
        }
    }

    /// Add one frame (every frame of a burst has the burst's size: `CaptureSet::read_frame`).
    pub fn add(&mut self, f: &Image) {
        debug_assert!(
            f.data.iter().all(|&v| v == to_u16(v) as f32),
            "integer DN frames"
        );
        if self.dark {
            self.frame_means.push(robust_frame_mean(f));
        }
        self.frames += 1;
        if self.frames == 1 {
            self.width = f.width;
            self.height = f.height;
            self.k = f.data.iter().map(|&v| to_u16(v)).collect();
            self.s1 = vec![0; self.k.len()];
            self.s2 = vec![0; self.k.len()];
            self.min = self.k.clone();
            self.max = self.k.clone();
            return;
        }
        // Chunks of values, not single values, per task: the sums run once per simulated
        // frame of every bootstrap replicate.
        const CHUNK: usize = 4096;
        (self.s1.par_chunks_mut(CHUNK), self.s2.par_chunks_mut(CHUNK))
            .into_par_iter()
            .zip((
                self.min.par_chunks_mut(CHUNK),
                self.max.par_chunks_mut(CHUNK),
            ))
            .zip((self.k.par_chunks(CHUNK), f.data.par_chunks(CHUNK)))
            .for_each(|(((s1, s2), (lo, hi)), (k, x))| {
                for i in 0..x.len() {
                    let v = to_u16(x[i]);
                    let d = v as i32 - k[i] as i32;
                    s1[i] += d;
                    s2[i] += (d as i64 * d as i64) as u64;
                    lo[i] = lo[i].min(v);
                    hi[i] = hi[i].max(v);
                }
            });
    }

    /// Σ(x − c) and Σ(x − c)² over the frames of value `i`, for an integer shift `c` in
    /// [0, 65535]: exact integers (i32 sums bound the frames to n · 65535 < 2^31, so every term
    /// is below 2^49), equal to the same sums streamed in f64.
    pub fn shifted_sums(&self, i: usize, c: f64) -> (f64, f64) {
        let (n, off) = (self.frames as i64, self.k[i] as i64 - c as i64);
        let s1 = self.s1[i] as i64;
        let t1 = s1 + n * off;
        let t2 = self.s2[i] as i64 + 2 * off * s1 + n * off * off;
        (t1 as f64, t2 as f64)
    }

    /// Per-band statistics.
    pub(super) fn finish(self, white: f64) -> Vec<BurstStats> {
        let nf = self.frames as f64;
        let (mean, var): (Vec<f32>, Vec<f32>) =
            (self.k.par_iter(), self.s1.par_iter(), self.s2.par_iter())
                .into_par_iter()
                .map(|(&k, &s1, &s2)| {
                    let s1 = s1 as f64;
                    let m = k as f64 + s1 / nf;
                    let v = ((s2 as f64 - s1 * s1 / nf) / (nf - 1.0)).max(0.0);
                    (m as f32, v as f32)
                })
                .unzip();
        let w3 = self.width * 3;
        (0..self.height)
            .step_by(self.band)
            .map(|y0| {
                let y1 = (y0 + self.band).min(self.height);
                let r = y0 * w3..y1 * w3;
                BurstStats {
                    width: self.width,
                    height: y1 - y0,
                    frames: self.frames,
                    mean: mean[r.clone()].to_vec(),
                    var: var[r.clone()].to_vec(),
                    min: self.min[r.clone()].to_vec(),
                    max: self.max[r].to_vec(),
                    white,
                }
            })
            .collect()
    }
}

/// Mean of a frame's samples within 8 robust σ of its median (hot pixels and other outliers
/// left out); samples are integer DN, so median and MAD come from a histogram.
fn robust_frame_mean(img: &Image) -> f64 {
    let mut hist = vec![0u64; 65536];
    for &v in &img.data {
        hist[v.clamp(0.0, 65535.0) as usize] += 1;
    }
    let n = img.data.len() as u64;
    let quantile = |hist: &[u64], target: u64| -> usize {
        let mut acc = 0;
        for (i, &c) in hist.iter().enumerate() {
            acc += c;
            if acc > target {
                return i;
            }
        }
        hist.len() - 1
    };
    let med = quantile(&hist, n / 2);
    let mut dev = vec![0u64; 65536];
    for (i, &c) in hist.iter().enumerate() {
        dev[i.abs_diff(med)] += c;
    }
    let mad = quantile(&dev, n / 2) as f64;
    let limit = (8.0 * MAD_TO_SIGMA * mad).max(2.0);
    let (mut sum, mut cnt) = (0.0, 0u64);
    for (i, &c) in hist.iter().enumerate() {
        if (i as f64 - med as f64).abs() <= limit {
            sum += i as f64 * c as f64;
            cnt += c;
        }
    }
    sum / cnt.max(1) as f64
}
