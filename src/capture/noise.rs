//! The output-domain noise of bracket frames, per ISO, channel and code bin: from each frame's
//! flat regions (Immerkær's residual) or, where a set has repeated captures of one exposure,
//! from the differences of repeated frames (temporal noise: no scene in the residual).

mod residual;
use crate::capture::scan::{self, BracketFrame, BracketSet};
use crate::error::{Error, Result};
use crate::io::Image;
use crate::sensor::effects::plan;
use crate::sensor::profile::{NoiseAtIso, Response};
use residual::crop_window;
pub(crate) use residual::{CrossResidual, cross_residuals};
use std::path::Path;

/// Code bins of the noise measurement (of the 3×3 mean code).
pub(crate) const BINS: usize = 16;
/// Fewest flat pixels for a bin's σ.
const MIN_PIXELS: usize = 200;
/// Of each bin's pixels, the flattest fraction (smallest local gradient) is measured.
pub(super) const FLAT_FRACTION: f64 = 0.5;
/// Codes at or beyond these (of 255) are clipped or crushed: no noise survives there.
const LOW_CODE: f64 = 3.0 / 255.0;
pub(super) const HIGH_CODE: f64 = 250.0 / 255.0;
/// One 8-bit code step (frames of more bits are measured as if 8-bit).
const CODE: f64 = 1.0 / 255.0;
/// MAD → σ for a normal distribution.
const MAD_SIGMA: f64 = 1.482_602_218_505_602;
/// Largest share of a repeated pair's difference variance in 32×32 block means: white noise
/// puts 1/1024 there, noise correlated by a Gaussian kernel of width s about 4πs²/1024 (5 %
/// at s = 2 px); a changed scene, light or exposure puts most of it there.
const MAX_BLOCK_SHARE: f64 = 0.25;
/// A one-pixel shift that matches a repeated pair this much better than none: not aligned.
const SHIFT_GAIN: f64 = 0.01;

/// What the noise is measured on: `signal` bins and selects the pixels (its 3×3 window must
/// lie within the unclipped codes), `noise` gives the residuals. One frame: both its codes.
/// A repeated pair (a, b): the mean code, and (a − b)/√2, which has one frame's noise
/// variance (and one frame's 8-bit rounding) and no scene.
#[derive(Clone, Copy)]
pub(crate) struct Planes<'a> {
    pub signal: &'a Image,
    pub noise: &'a Image,
    /// Of each bin, the flattest fraction of `signal` is measured (1: every pixel).
    pub flat_fraction: f64,
    /// The lattice `noise` lies on: 8-bit codes (1/255), a pair's difference over √2.
    pub quantum: f64,
}

impl<'a> Planes<'a> {
    /// One frame's codes (flat regions only: the scene is in the residual elsewhere).
    pub fn frame(code: &'a Image) -> Self {
        Planes {
            signal: code,
            noise: code,
            flat_fraction: FLAT_FRACTION,
            quantum: CODE,
        }
    }
}

/// A repeated pair as [`Planes`]' images: (signal, noise). The signal is 0 (outside every bin)
/// where either frame is clipped or crushed.
pub(crate) struct Pair {
    pub signal: Image,
    pub noise: Image,
}

impl Pair {
    pub fn planes(&self) -> Planes<'_> {
        Planes {
            signal: &self.signal,
            noise: &self.noise,
            flat_fraction: 1.0,
            quantum: CODE / std::f64::consts::SQRT_2,
        }
    }
}

/// Read two repeated captures and check they are of one static scene, aligned: refused,
/// naming both files, when their sizes differ, when a one-pixel shift matches better than
/// none (the camera moved) or when the difference is mostly smooth (the scene, the light or
/// the exposure changed between them).
pub(crate) fn repeated_pair(a: &BracketFrame, b: &BracketFrame) -> Result<Pair> {
    let (ia, ib) = (scan::read_frame_image(a)?, scan::read_frame_image(b)?);
    checked_pair(&ia, &ib, &a.path, &b.path)
}

/// [`repeated_pair`] of two frames already read (from files `pa`, `pb`).
pub(crate) fn checked_pair(ia: &Image, ib: &Image, pa: &Path, pb: &Path) -> Result<Pair> {
    let both = || format!("{} and {}", pa.display(), pb.display());
    if (ia.width, ia.height) != (ib.width, ib.height) {
        return Err(Error::layout(
            pb,
            format!(
                "repeated captures {} differ in size ({}×{} and {}×{})",
                both(),
                ia.width,
                ia.height,
                ib.width,
                ib.height
            ),
        ));
    }
    if let Some((dx, dy, gain)) = better_shift(ia, ib) {
        return Err(Error::layout(
            pb,
            format!(
                "repeated captures {} are not aligned: shifted by ({dx}, {dy}) px they match \
                 {:.1} % better than as taken; temporal noise needs a static scene from a \
                 fixed camera (drop the pair or leave out --repeats)",
                both(),
                100.0 * gain
            ),
        ));
    }
    let share = block_share(ia, ib);
    if share > MAX_BLOCK_SHARE {
        return Err(Error::layout(
            pb,
            format!(
                "repeated captures {} differ by more than noise: {:.0} % of their difference \
                 is smooth over 32×32 blocks (noise alone puts a few per cent there); the \
                 scene, light or exposure changed between them",
                both(),
                100.0 * share
            ),
        ));
    }
    Ok(Pair::new(ia, ib))
}

impl Pair {
    /// The planes of two captures of one exposure, unchecked (simulated pairs are aligned).
    pub fn new(ia: &Image, ib: &Image) -> Pair {
        let mut signal = ia.clone();
        let mut noise = ia.clone();
        for ((s, n), (&x, &y)) in signal
            .data
            .iter_mut()
            .zip(noise.data.iter_mut())
            .zip(ia.data.iter().zip(&ib.data))
        {
            let (x, y) = (f64::from(x), f64::from(y));
            let inside = |v: f64| v > LOW_CODE && v < HIGH_CODE;
            *s = if inside(x) && inside(y) {
                (0.5 * (x + y)) as f32
            } else {
                0.0
            };
            *n = ((x - y) / std::f64::consts::SQRT_2) as f32;
        }
        Pair { signal, noise }
    }
}

/// The pair checks and the device-output check read at most this central window of a frame:
/// their statistics need the native resolution, not every pixel of a 12-megapixel phone frame.
const WINDOW: (usize, usize) = (640, 480);

/// The central [`WINDOW`] of `img` (all of a smaller frame): x0, y0, w, h.
pub(crate) fn window(img: &Image) -> (usize, usize, usize, usize) {
    let (w, h) = (img.width.min(WINDOW.0), img.height.min(WINDOW.1));
    ((img.width - w) / 2, (img.height - h) / 2, w, h)
}

/// The one-pixel shift (dx, dy) that matches `b` to `a` better than no shift by more than
/// [`SHIFT_GAIN`] of the unshifted squared difference, and by how much.
fn better_shift(a: &Image, b: &Image) -> Option<(i64, i64, f64)> {
    let (x0, y0, w, h) = window(a);
    if w < 8 || h < 8 {
        return None;
    }
    let ssd = |dx: i64, dy: i64| {
        let mut s = 0.0;
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let (xa, ya) = (x0 + x, y0 + y);
                let (xb, yb) = ((xa as i64 + dx) as usize, (ya as i64 + dy) as usize);
                for c in 0..3 {
                    let d = f64::from(a.data[(ya * a.width + xa) * 3 + c])
                        - f64::from(b.data[(yb * b.width + xb) * 3 + c]);
                    s += d * d;
                }
            }
        }
        s
    };
    let none = ssd(0, 0);
    let mut best: Option<(i64, i64, f64)> = None;
    for dy in -1..=1 {
        for dx in -1..=1 {
            if (dx, dy) == (0, 0) {
                continue;
            }
            let gain = 1.0 - ssd(dx, dy) / none.max(1e-30);
            if gain > SHIFT_GAIN && best.is_none_or(|b| gain > b.2) {
                best = Some((dx, dy, gain));
            }
        }
    }
    best
}

/// The share of the pair's difference variance (window, all channels) in 32×32 block means.
fn block_share(a: &Image, b: &Image) -> f64 {
    const B: usize = 32;
    let (x0, y0, w, h) = window(a);
    let d = |x: usize, y: usize, c: usize| {
        let i = ((y0 + y) * a.width + x0 + x) * 3 + c;
        f64::from(a.data[i]) - f64::from(b.data[i])
    };
    let (mut total, mut n) = (0.0, 0usize);
    let mut sum = 0.0;
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let v = d(x, y, c);
                total += v * v;
                sum += v;
                n += 1;
            }
        }
    }
    if n == 0 || h < B || w < B {
        return 0.0;
    }
    let mean = sum / n as f64;
    let var = total / n as f64 - mean * mean;
    let (mut blocks, mut nb) = (0.0, 0usize);
    for by in 0..h / B {
        for bx in 0..w / B {
            for c in 0..3 {
                let mut m = 0.0;
                for y in 0..B {
                    for x in 0..B {
                        m += d(bx * B + x, by * B + y, c);
                    }
                }
                let m = m / (B * B) as f64 - mean;
                blocks += m * m;
                nb += 1;
            }
        }
    }
    if var <= 0.0 {
        return 0.0;
    }
    blocks / nb as f64 / var
}
/// The channels' Immerkær residuals of `p.noise` on the flattest `p.flat_fraction` of the
/// pixels whose 3×3 windows of `p.signal` are unclipped in every channel: (Σ r_R r_G,
/// Σ r_G r_B, Σ r_R r_B), (Σ r_R², Σ r_G², Σ r_B²) and the pixel count.
pub(crate) fn channel_moments(p: Planes) -> ([f64; 3], [f64; 3], usize) {
    let (w, h) = (p.signal.width, p.signal.height);
    let mut px: Vec<(f64, [f64; 3])> = Vec::new();
    if w < 5 || h < 5 {
        return ([0.0; 3], [0.0; 3], 0);
    }
    let sig = |x: usize, y: usize, c: usize| f64::from(p.signal.data[(y * w + x) * 3 + c]);
    for y in 2..h - 2 {
        'pixel: for x in 2..w - 2 {
            let mut r = [0.0; 3];
            let mut g = 0.0;
            for (c, rc) in r.iter_mut().enumerate() {
                for dy in 0..3 {
                    for dx in 0..3 {
                        let v = sig(x + dx - 1, y + dy - 1, c);
                        if v <= LOW_CODE || v >= HIGH_CODE {
                            continue 'pixel;
                        }
                    }
                }
                *rc = immerkaer(p.noise, x, y, c);
                let s = |x, y| sig(x, y, c);
                g += (s(x + 2, y) - s(x - 2, y)).abs() + (s(x, y + 2) - s(x, y - 2)).abs();
            }
            px.push((g, r));
        }
    }
    px.sort_by(|a, b| a.0.total_cmp(&b.0));
    let keep = &px[..(px.len() as f64 * p.flat_fraction) as usize];
    let mut cross = [0.0; 3];
    let mut square = [0.0; 3];
    for (_, r) in keep {
        cross[0] += r[0] * r[1];
        cross[1] += r[1] * r[2];
        cross[2] += r[0] * r[2];
        for c in 0..3 {
            square[c] += r[c] * r[c];
        }
    }
    (cross, square, keep.len())
}

/// Immerkær's residual (mask [1 −2 1; −2 4 −2; 1 −2 1]) of channel `c` at interior (x, y).
fn immerkaer(img: &Image, x: usize, y: usize, c: usize) -> f64 {
    let v = |x: usize, y: usize| f64::from(img.data[(y * img.width + x) * 3 + c]);
    4.0 * v(x, y) - 2.0 * (v(x - 1, y) + v(x + 1, y) + v(x, y - 1) + v(x, y + 1))
        + v(x - 1, y - 1)
        + v(x + 1, y - 1)
        + v(x - 1, y + 1)
        + v(x + 1, y + 1)
}

/// One code bin of one channel at one ISO.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseBin {
    pub iso: f64,
    pub channel: usize,
    /// Mean code (of 1) and its linear value under the profile's response.
    pub code: f64,
    pub linear: f64,
    /// σ² in codes² (of 1), quantisation removed, and carried to linear.
    pub var_code: f64,
    pub var_linear: f64,
    /// Low-order over Immerkær residual variance (1 for white noise).
    pub correlation_ratio: f64,
    pub pixels: usize,
}

/// What [`measure_noise`] found.
pub(crate) struct Measured {
    pub bins: Vec<NoiseBin>,
    /// Each ISO's σ² = a·x + b where two or more code levels per channel allow a fit.
    pub rows: Vec<NoiseAtIso>,
    /// [`channel_correlation_of`] over every frame or pair measured.
    pub channel_correlation: f64,
    /// Repeated pairs measured (0: each frame's flat regions).
    pub pairs: usize,
    /// Frames whose correlation was read from their residual against the rest of their set.
    pub cross_frames: usize,
}

/// The noise of the sets, pooled per ISO (EXIF; 100 where absent, noted): from repeated
/// captures where any set has them (each exposure's frames in capture order, consecutive
/// pairs), else from every frame's flat regions. The noise's spatial and channel correlation
/// come from the same pairs or, without repeats, from each frame's [`cross_residuals`] against
/// the other frames of its set: on a single frame's flat regions scene texture passes for
/// correlated noise (tests/brackets/noise_correlation.rs: on gratings of 15 % contrast, white
/// noise read as lag-1 0.226 and channel correlation 0.066; on the residual, under 0.02 and
/// 0.05).
pub(crate) fn measure_noise(
    sets: &[BracketSet],
    response: &Response,
    notes: &mut Vec<String>,
) -> Result<Measured> {
    let iso_of = |f: &BracketFrame| f.exif.iso.unwrap_or(100.0);
    let with_repeats = sets.iter().filter(|s| !s.repeats.is_empty()).count();
    if with_repeats > 0 && with_repeats < sets.len() {
        notes.push(format!(
            "noise from the repeated captures of {with_repeats} of {} sets; the sets without \
             repeats do not enter it",
            sets.len()
        ));
    }
    let measured: Vec<&BracketFrame> = sets
        .iter()
        .filter(|s| with_repeats == 0 || !s.repeats.is_empty())
        .flat_map(|s| s.all_frames())
        .collect();
    if measured.iter().any(|f| f.exif.iso.is_none()) {
        notes.push("frames without EXIF ISO are taken as ISO 100".into());
    }
    // Per ISO and channel, the noise bins and, separately, the bins the correlation is read from.
    let (mut level, mut spatial) = (Vec::new(), Vec::new());
    let mut moments = Moments::default();
    let mut pairs = 0;
    let mut cross_frames = 0;
    for set in sets {
        if with_repeats > 0 {
            for f in &set.frames {
                let mut chain = vec![f];
                chain.extend(set.repeats_of(f));
                for w in chain.windows(2) {
                    let pair = repeated_pair(w[0], w[1])?;
                    let bins = noise_bins(pair.planes(), iso_of(w[0]), response);
                    spatial.extend(bins.iter().cloned());
                    level.extend(bins);
                    moments.add(pair.planes());
                    pairs += 1;
                }
            }
            continue;
        }
        // Each frame's flat regions give its noise level; its central window is kept for the
        // residual against the others (a set holds two frames or more: `scan::scan`).
        let mut windows = Vec::with_capacity(set.frames.len());
        for f in &set.frames {
            let code = scan::read_frame_image(f)?;
            level.extend(noise_bins(Planes::frame(&code), iso_of(f), response));
            windows.push(crop_window(&code));
        }
        let times: Vec<f64> = set.frames.iter().map(|f| f.stop.exp2()).collect();
        for (f, r) in set
            .frames
            .iter()
            .zip(cross_residuals(&windows, &times, response)?)
        {
            spatial.extend(noise_bins(r.planes(), iso_of(f), response));
            moments.add(r.planes());
            cross_frames += 1;
        }
    }
    let mut isos: Vec<f64> = measured.iter().map(|f| iso_of(f)).collect();
    isos.sort_by(f64::total_cmp);
    isos.dedup();
    let (mut bins, mut rows) = (Vec::new(), Vec::new());
    for iso in isos {
        let at = |v: &[NoiseBin]| {
            merge_bins(
                &v.iter()
                    .filter(|b| b.iso == iso)
                    .cloned()
                    .collect::<Vec<_>>(),
            )
        };
        let mut merged = at(&level);
        // Each bin's correlation ratio is the one measured where the correlation is read.
        let correlation = at(&spatial);
        let bin = |b: &NoiseBin| ((b.code * BINS as f64) as usize).min(BINS - 1);
        for b in &mut merged {
            b.correlation_ratio = correlation
                .iter()
                .find(|o| o.channel == b.channel && bin(o) == bin(b))
                .map_or(f64::NAN, |o| o.correlation_ratio);
        }
        match fit_row(iso, &merged) {
            Some(row) => rows.push(row),
            None => notes.push(format!(
                "ISO {iso}: too few flat pixels at two or more code levels per channel for a \
                 noise fit; no noise row"
            )),
        }
        bins.extend(merged);
    }
    Ok(Measured {
        bins,
        rows,
        channel_correlation: channel_correlation_of(moments.cross, moments.square, moments.count),
        pairs,
        cross_frames,
    })
}

/// Sums of [`channel_moments`] over frames or pairs.
#[derive(Default)]
struct Moments {
    cross: [f64; 3],
    square: [f64; 3],
    count: usize,
}

impl Moments {
    fn add(&mut self, p: Planes) {
        let (c, q, n) = channel_moments(p);
        for k in 0..3 {
            self.cross[k] += c[k];
            self.square[k] += q[k];
        }
        self.count += n;
    }
}

/// One interior pixel of one channel: the scene's local gradient, Immerkær's residual, the
/// low-order residual (pixel − 3×3 mean) and the 3×3 mean code.
#[derive(Clone, Copy)]
struct Residual {
    gradient: f64,
    immerkaer: f64,
    low_order: f64,
    mean: f64,
}

/// The noise bins of `p` (codes of 1), per channel.
pub(crate) fn noise_bins(p: Planes, iso: f64, response: &Response) -> Vec<NoiseBin> {
    let (w, h) = (p.signal.width, p.signal.height);
    let mut out = Vec::new();
    if w < 5 || h < 5 {
        return out;
    }
    for c in 0..3 {
        let v = |x: usize, y: usize| f64::from(p.signal.data[(y * w + x) * 3 + c]);
        let n = |x: usize, y: usize| f64::from(p.noise.data[(y * w + x) * 3 + c]);
        let mut per_bin: Vec<Vec<Residual>> = vec![Vec::new(); BINS];
        for y in 2..h - 2 {
            for x in 2..w - 2 {
                let (mut sum, mut noise_sum) = (0.0, 0.0);
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for dy in 0..3 {
                    for dx in 0..3 {
                        let q = v(x + dx - 1, y + dy - 1);
                        sum += q;
                        noise_sum += n(x + dx - 1, y + dy - 1);
                        lo = lo.min(q);
                        hi = hi.max(q);
                    }
                }
                if lo <= LOW_CODE || hi >= HIGH_CODE {
                    continue;
                }
                let mean = sum / 9.0;
                // The local gradient of the scene, on 3-pixel baselines so noise weighs less.
                let gx = (v(x + 2, y) - v(x - 2, y)).abs();
                let gy = (v(x, y + 2) - v(x, y - 2)).abs();
                let bin = ((mean * BINS as f64) as usize).min(BINS - 1);
                per_bin[bin].push(Residual {
                    gradient: gx + gy,
                    immerkaer: immerkaer(p.noise, x, y, c),
                    low_order: n(x, y) - noise_sum / 9.0,
                    mean,
                });
            }
        }
        for px in per_bin.iter_mut() {
            if px.len() < 2 * MIN_PIXELS {
                continue;
            }
            px.sort_by(|a, b| a.gradient.total_cmp(&b.gradient));
            let keep = &px[..(px.len() as f64 * p.flat_fraction) as usize];
            // Immerkær's residual of codes on the lattice q is on q; the low-order one on q/9.
            let mad = |f: fn(&Residual) -> f64, q: f64| {
                MAD_SIGMA * crate::stats::lattice_abs_median(keep.iter().map(f), q)
            };
            let s_imm = mad(|p| p.immerkaer, p.quantum);
            let s_low = mad(|p| p.low_order, p.quantum / 9.0);
            let var_imm = s_imm * s_imm / 36.0;
            let mean = keep.iter().map(|p| p.mean).sum::<f64>() / keep.len() as f64;
            let var_code = var_imm - 1.0 / (12.0 * 255.0 * 255.0);
            let (x, var_linear) = linear_variance(response, keep, var_code);
            out.push(NoiseBin {
                iso,
                channel: c,
                code: mean,
                linear: x,
                var_code,
                var_linear,
                correlation_ratio: if var_imm > 0.0 {
                    s_low * s_low / (8.0 / 9.0) / var_imm
                } else {
                    f64::NAN
                },
                pixels: keep.len(),
            });
        }
    }
    out
}

/// Gauss–Hermite nodes and weights for E[f(z)], z ~ N(0, 1) (five points, exact to degree 9).
const HERMITE: [(f64, f64); 5] = [
    (0.0, 0.533_333_333_333_333),
    (1.355_626_179_974_266, 0.222_075_922_005_613),
    (-1.355_626_179_974_266, 0.222_075_922_005_613),
    (2.856_970_013_872_806, 0.011_257_411_327_720_7),
    (-2.856_970_013_872_806, 0.011_257_411_327_720_7),
];

/// The bin's mean linear value and the linear noise variance v whose simulation gives the
/// measured code variance: over (up to 256 of) the bin's pixels x = R⁻¹(3×3 mean code), the
/// mean of Var R(x + √v·z), z ~ N(0, 1), equals `var_code` (v by bisection in log v). This
/// is what the realism operator does with the profile (noise in linear, then the response),
/// so the profile reproduces the measured code variance even where the curve's slope varies
/// within the noise's span — as an estimated curve's does from one code to the next, which a
/// single slope at the bin's mean code turns into errors of 2–4× per bin.
fn linear_variance(response: &Response, keep: &[Residual], var_code: f64) -> (f64, f64) {
    let step = keep.len().div_ceil(256).max(1);
    let xs: Vec<f64> = keep
        .iter()
        .step_by(step)
        .map(|p| response.invert(p.mean))
        .collect();
    let n = xs.len() as f64;
    let x_mean = xs.iter().sum::<f64>() / n;
    if var_code <= 0.0 {
        return (x_mean, var_code);
    }
    let simulated = |v: f64| {
        let sd = v.sqrt();
        xs.iter()
            .map(|&x| {
                let (m1, m2) = HERMITE.iter().fold((0.0, 0.0), |(m1, m2), &(z, w)| {
                    let c = response.apply(x + sd * z);
                    (m1 + w * c, m2 + w * c * c)
                });
                m2 - m1 * m1
            })
            .sum::<f64>()
            / n
    };
    let ln_v = crate::stats::bisect(1e-16f64.ln(), 0.25f64.ln(), 50, |m| {
        simulated(m.exp()) < var_code
    });
    (x_mean, ln_v.exp())
}

/// Bins of several frames at one ISO pooled per channel and code bin (pixel-weighted).
pub(crate) fn merge_bins(bins: &[NoiseBin]) -> Vec<NoiseBin> {
    let mut out: Vec<NoiseBin> = Vec::new();
    for b in bins {
        let key = |o: &NoiseBin| {
            o.channel == b.channel
                && ((o.code * BINS as f64) as usize).min(BINS - 1)
                    == ((b.code * BINS as f64) as usize).min(BINS - 1)
        };
        match out.iter_mut().find(|o| key(o)) {
            Some(o) => {
                let (n0, n1) = (o.pixels as f64, b.pixels as f64);
                let mix = |a: f64, c: f64| (a * n0 + c * n1) / (n0 + n1);
                o.code = mix(o.code, b.code);
                o.linear = mix(o.linear, b.linear);
                o.var_code = mix(o.var_code, b.var_code);
                o.var_linear = mix(o.var_linear, b.var_linear);
                o.correlation_ratio = mix(o.correlation_ratio, b.correlation_ratio);
                o.pixels += b.pixels;
            }
            None => out.push(b.clone()),
        }
    }
    out.sort_by(|a, b| {
        (a.channel, a.code)
            .partial_cmp(&(b.channel, b.code))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    out
}

/// σ²_lin = a·x + b per channel over the bins with positive variance; a, b ≥ 0.
fn fit_row(iso: f64, bins: &[NoiseBin]) -> Option<NoiseAtIso> {
    let mut a = [0.0; 3];
    let mut b = [0.0; 3];
    for c in 0..3 {
        let points: Vec<crate::stats::Point> = bins
            .iter()
            .filter(|k| k.channel == c && k.var_linear > 0.0 && k.linear > 0.0)
            .map(|k| crate::stats::Point {
                x: k.linear,
                y: k.var_linear,
                // A MAD variance has about 2.7/n relative variance for normal data.
                se: k.var_linear * (2.7 / k.pixels as f64).sqrt(),
                n: k.pixels,
            })
            .collect();
        if points.len() < 2 {
            return None;
        }
        let fit = crate::stats::wls(&points)?;
        a[c] = fit.a.max(0.0);
        b[c] = fit.b.max(0.0);
    }
    Some(NoiseAtIso {
        iso,
        a,
        b,
        a_stderr: None,
        b_stderr: None,
    })
}

/// 8-bit rounding's variance, codes² of 1.
pub(super) const ROUNDING: f64 = 1.0 / (12.0 * 255.0 * 255.0);

/// The correlation of the channels' noise from [`channel_moments`] summed over frames, with
/// 8-bit rounding (independent per channel, 36/12 code² in Immerkær's residual) taken out of
/// each channel's variance: the mean over the pairs RG, GB, RB, in [0, RHO_MAX]; NaN (not
/// measured) without pixels.
pub fn channel_correlation_of(cross: [f64; 3], square: [f64; 3], n: usize) -> f64 {
    if n == 0 {
        return f64::NAN;
    }
    let q = 36.0 * ROUNDING * n as f64;
    let v = square.map(|s| (s - q).max(1e-30));
    let pairs = [(0, 0, 1), (1, 1, 2), (2, 0, 2)];
    let r = pairs
        .iter()
        .map(|&(k, a, b)| cross[k] / (v[a] * v[b]).sqrt())
        .sum::<f64>()
        / 3.0;
    r.clamp(0.0, plan::RHO_MAX)
}
