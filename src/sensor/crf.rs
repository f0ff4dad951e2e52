//! Camera response from the brackets themselves: Debevec & Malik 1997, "Recovering High Dynamic
//! Range Radiance Maps from Photographs", computed as OpenCV's `CalibrateDebevec` computes it
//! (the oracle, tools/crf_oracle.py): per channel, unknowns g(0..255) and ln E_i of each sample
//! pixel; rows w(Z)·(g(Z) − ln E_i) = w(Z)·ln t_j for every sample and frame, g(128) = 0, and
//! λ·w(z)·(g(z−1) − 2g(z) + g(z+1)) = 0 for z = 1..254; triangle weights w(z) = z + 1 below 128,
//! 256 − z from 128; samples on OpenCV's regular grid (its default, `random = false`). Solved by
//! least squares (Householder QR, the full-rank solution OpenCV's SVD solve also gives).
//! The result is OpenCV's: exp(g(z)) per code and channel, the exposure giving code z.
//!
//! Robertson, Borman & Stevenson 1999/2003 ("Estimation-theoretic approach to dynamic range
//! enhancement using multiple exposures") is the second estimator, computed as OpenCV's
//! `CalibrateRobertson` computes it: every pixel (no sampling), response I(z) started linear
//! (z / 128), then alternately the weighted maximum-likelihood radiance
//! E = Σ t_j w(z) I(z) / Σ t_j² w(z) (OpenCV's `MergeRobertson`, Gaussian-like weights
//! w(z) = e⁴/(e⁴−1)·exp(−(z/63.75 − 2)²) + 1/(1−e⁴), zero at codes 0 and 255) and
//! I(z) = mean of t_j·E over every observation of code z, normalised to I(128) = 1, until the
//! summed change |ΔI| / 3 falls under the threshold or `max_iter` is reached.

use crate::error::{Error, Result};
use crate::io::Image;

pub const LDR_SIZE: usize = 256;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DebevecOptions {
    /// Sample pixels (OpenCV default 70).
    pub samples: usize,
    /// Smoothness weight λ (OpenCV default 10).
    pub lambda: f64,
    /// One curve for the three channels: OpenCV's recipe on the frames' channels laid side by
    /// side as one grey image three times as wide, with three times the samples and λ (a camera's
    /// JPEG engine applies one tone curve after white balance; per channel, the estimates of
    /// a real bracket differ by 10–40 % from code to code, which tints neutral grey). False:
    /// OpenCV's default, a curve per channel.
    pub shared: bool,
}

impl Default for DebevecOptions {
    fn default() -> Self {
        DebevecOptions {
            samples: 70,
            lambda: 10.0,
            shared: false,
        }
    }
}

impl DebevecOptions {
    /// OpenCV's recipe with one curve for the three channels ([`DebevecOptions::shared`]).
    pub fn one_curve() -> Self {
        DebevecOptions {
            shared: true,
            ..DebevecOptions::default()
        }
    }
}

/// Frames, times and sizes every estimator needs; the message names the estimator.
fn check_frames(what: &str, frames: &[Image], times: &[f64]) -> Result<(usize, usize)> {
    if frames.len() < 2 || frames.len() != times.len() {
        return Err(Error::Invalid(format!(
            "{what} response: need two or more frames with one time each ({} frames, {} times)",
            frames.len(),
            times.len()
        )));
    }
    if times.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(Error::Invalid(format!(
            "{what} response: times {times:?} must be positive"
        )));
    }
    let (w, h) = (frames[0].width, frames[0].height);
    if frames.iter().any(|f| (f.width, f.height) != (w, h)) || w == 0 || h == 0 {
        return Err(Error::Invalid(format!(
            "{what} response: frames differ in size"
        )));
    }
    Ok((w, h))
}

/// An 8-bit code of a [0, 1] value (as the frames were stored).
pub(crate) fn code8(v: f32) -> usize {
    (v.clamp(0.0, 1.0) * 255.0).round() as usize
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
/// (code values in [0, 1], quantised to 8 bits here) and their exposure times. With
/// `opts.shared` the three entries are one curve.
pub fn calibrate_debevec(
    frames: &[Image],
    times: &[f64],
    opts: DebevecOptions,
) -> Result<[Vec<f64>; 3]> {
    let (w, h) = check_frames("Debevec", frames, times)?;
    let plane = |f: &Image, c: usize| -> Vec<u8> {
        f.data
            .iter()
            .skip(c)
            .step_by(3)
            .map(|&v| code8(v) as u8)
            .collect()
    };
    if opts.shared {
        // The channels side by side, one grey image 3w wide, with three times the samples and
        // three times the smoothness weight: OpenCV's balance of the data term (one row per
        // sample and frame) against the smoothness term (one row per code). With λ alone the
        // pooled samples outweigh it and leave near-flat stretches where few samples fall (on
        // the Canon 550D stack codes 97–103 and 205–209, which carried its noise to linear
        // wrongly); with 3λ none.
        let tiled: Vec<Vec<u8>> = frames
            .iter()
            .map(|f| {
                let planes = [plane(f, 0), plane(f, 1), plane(f, 2)];
                (0..h)
                    .flat_map(|y| planes.iter().flat_map(move |p| &p[y * w..(y + 1) * w]))
                    .copied()
                    .collect()
            })
            .collect();
        let g = solve_debevec(
            &tiled,
            3 * w,
            h,
            times,
            opts.samples.max(1) * 3,
            opts.lambda * 3.0,
        )?;
        return Ok([g.clone(), g.clone(), g]);
    }
    let mut out: [Vec<f64>; 3] = Default::default();
    for (c, o) in out.iter_mut().enumerate() {
        let planes: Vec<Vec<u8>> = frames.iter().map(|f| plane(f, c)).collect();
        *o = solve_debevec(&planes, w, h, times, opts.samples.max(1), opts.lambda)?;
    }
    Ok(out)
}

/// Debevec's system for one plane of codes per frame (`w`×`h`): exp(g(z)) for z = 0..255.
fn solve_debevec(
    planes: &[Vec<u8>],
    w: usize,
    h: usize,
    times: &[f64],
    samples: usize,
    lambda: f64,
) -> Result<Vec<f64>> {
    let pts = sample_points(w, h, samples);
    let cols = LDR_SIZE + pts.len();
    let mut a: Vec<Vec<f64>> = Vec::new();
    let mut b: Vec<[f64; 1]> = Vec::new();
    for (i, &(x, y)) in pts.iter().enumerate() {
        for (p, t) in planes.iter().zip(times) {
            let z = usize::from(p[y * w + x]);
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
        let lw = lambda * weight(z + 1);
        let mut row = vec![0.0; cols];
        row[z] = lw;
        row[z + 1] = -2.0 * lw;
        row[z + 2] = lw;
        a.push(row);
        b.push([0.0]);
    }
    let x = crate::linalg::least_squares("Debevec response", &a, &b)?;
    Ok(x[..LDR_SIZE].iter().map(|g| g[0].exp()).collect())
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobertsonOptions {
    /// Iterations at most (OpenCV default 30).
    pub max_iter: usize,
    /// Stop when Σ|ΔI| / 3 over the 256 codes falls under this (OpenCV default 0.01).
    pub threshold: f64,
}

impl Default for RobertsonOptions {
    fn default() -> Self {
        RobertsonOptions {
            max_iter: 30,
            threshold: 0.01,
        }
    }
}

/// OpenCV's `RobertsonWeights`: a Gaussian over the codes, 0 at codes 0 and 255.
fn robertson_weight(z: usize) -> f64 {
    let q = (LDR_SIZE - 1) as f64 / 4.0;
    let e4 = 4.0f64.exp();
    let v = z as f64 / q - 2.0;
    e4 / (e4 - 1.0) * (-v * v).exp() + 1.0 / (1.0 - e4)
}

/// Robertson's response I(z) for z = 0..255 per channel (I(128) = 1), OpenCV's convention (the
/// exposure giving code z), from frames of one static scene (code values in [0, 1], quantised
/// to 8 bits here) and their exposure times. Codes never observed in a channel are NaN in
/// OpenCV's result (0 · 1/0); here they are interpolated linearly between the nearest observed
/// codes (held flat beyond them) so that the curve can linearise. As in OpenCV, an unobserved
/// code makes the change per iteration undefined, so the iteration then runs `max_iter` times.
pub fn calibrate_robertson(
    frames: &[Image],
    times: &[f64],
    opts: RobertsonOptions,
) -> Result<[Vec<f64>; 3]> {
    let (w, h) = check_frames("Robertson", frames, times)?;
    let n = w * h * 3;
    let codes: Vec<Vec<u8>> = frames
        .iter()
        .map(|f| f.data.iter().map(|&v| code8(v) as u8).collect())
        .collect();
    let wt: Vec<f64> = (0..LDR_SIZE).map(robertson_weight).collect();
    let mut card = [[0usize; LDR_SIZE]; 3];
    for f in &codes {
        for (i, &z) in f.iter().enumerate() {
            card[i % 3][z as usize] += 1;
        }
    }
    if (0..3).any(|c| card[c][LDR_SIZE / 2] == 0) {
        return Err(Error::Invalid(
            "Robertson response: code 128 (the normalisation point, I(128) = 1) never occurs \
             in some channel of the frames"
                .into(),
        ));
    }
    let all_seen = card.iter().all(|c| c.iter().all(|&k| k > 0));
    let mut resp: [Vec<f64>; 3] =
        std::array::from_fn(|_| (0..LDR_SIZE).map(|z| z as f64 / 128.0).collect());
    let mut rad = vec![0.0f64; n];
    for _ in 0..opts.max_iter {
        // MergeRobertson: maximum-likelihood radiance under the current response.
        for (i, r) in rad.iter_mut().enumerate() {
            let c = i % 3;
            let (mut num, mut den) = (0.0, 0.0);
            for (f, &t) in codes.iter().zip(times) {
                let z = f[i] as usize;
                num += t * wt[z] * resp[c][z];
                den += t * t * wt[z];
            }
            *r = num / (den + f64::EPSILON);
        }
        let mut new: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; LDR_SIZE]);
        for (f, &t) in codes.iter().zip(times) {
            for (i, &z) in f.iter().enumerate() {
                new[i % 3][z as usize] += t * rad[i];
            }
        }
        for c in 0..3 {
            for z in 0..LDR_SIZE {
                new[c][z] /= card[c][z] as f64;
            }
            let mid = new[c][LDR_SIZE / 2];
            for v in &mut new[c] {
                *v /= mid;
            }
        }
        let diff: f64 = (0..3)
            .flat_map(|c| (0..LDR_SIZE).map(move |z| (c, z)))
            .filter(|&(c, z)| card[c][z] > 0)
            .map(|(c, z)| (new[c][z] - resp[c][z]).abs())
            .sum::<f64>()
            / 3.0;
        resp = new;
        if all_seen && diff < opts.threshold {
            break;
        }
    }
    for c in 0..3 {
        fill_unseen(&mut resp[c], &card[c]);
    }
    Ok(resp)
}

/// Replace values at codes with no observation by linear interpolation between the nearest
/// observed codes (flat beyond the first and last).
fn fill_unseen(r: &mut [f64], card: &[usize; LDR_SIZE]) {
    let seen: Vec<usize> = (0..LDR_SIZE).filter(|&z| card[z] > 0).collect();
    let (Some(&first), Some(&last)) = (seen.first(), seen.last()) else {
        return;
    };
    for z in 0..LDR_SIZE {
        if card[z] > 0 {
            continue;
        }
        r[z] = if z < first {
            r[first]
        } else if z > last {
            r[last]
        } else {
            let hi = seen.partition_point(|&s| s < z);
            let (a, b) = (seen[hi - 1], seen[hi]);
            r[a] + (r[b] - r[a]) * (z - a) as f64 / (b - a) as f64
        };
    }
}

/// Codes under this one have their estimate re-made from the frames by [`refine_toe`]; codes
/// from it to [`TOE_SOURCE_TOP`] are the ones trusted to say what radiance a pixel has.
pub const TOE_CODES: usize = 26;

/// The highest code whose estimate [`refine_toe`] reads radiance from.
pub const TOE_SOURCE_TOP: usize = 230;

/// Fewest observations of a code for [`refine_toe`] to re-estimate it.
const TOE_MIN_OBSERVATIONS: usize = 20;

/// Most pixels [`refine_toe`] reads per frame (a regular stride beyond): medians of a million
/// observations per code are as good as of ten million, and a 12-MP bracket stays cheap.
const TOE_MAX_PIXELS: usize = 250_000;

/// Re-estimate an estimated response (exposure per code, any unit) at its darkest codes from
/// the frames themselves: for each code z under [`TOE_CODES`], the median over every pixel and
/// frame j recording z of t_j · E, where E is the pixel's radiance from the frames that record
/// it at codes [`TOE_CODES`]..=[`TOE_SOURCE_TOP`] (Debevec's triangle weights, through the
/// estimate there); codes with fewer than 20 such observations keep their estimate, and the
/// curve is made non-decreasing downwards from code [`TOE_CODES`].
///
/// Why: both estimators leave the darkest codes to something other than data. Debevec's weights
/// (z + 1) and smoothness term extrapolate the mid-tones' power law into the toe; Robertson's
/// radiance there is merged mostly from those same codes. On the Canon 550D's JPEG bracket
/// codes 9–12 linearised to 0.64× (Debevec, one curve) what the neighbouring frames give the
/// same pixels; re-estimated, 1.01× on held-out pixels. With `shared`, the three channels'
/// observations are pooled into one curve (the entries stay equal).
pub fn refine_toe(
    frames: &[Image],
    times: &[f64],
    response: &mut [Vec<f64>; 3],
    shared: bool,
) -> Result<()> {
    let (w, h) = check_frames("toe of the", frames, times)?;
    if response.iter().any(|r| r.len() != LDR_SIZE) {
        return Err(Error::Invalid(format!(
            "toe of the response: {LDR_SIZE} codes per channel expected"
        )));
    }
    let stride = (w * h).div_ceil(TOE_MAX_PIXELS).max(1);
    let codes: Vec<Vec<u8>> = frames
        .iter()
        .map(|f| f.data.iter().map(|&v| code8(v) as u8).collect())
        .collect();
    let curves = if shared { 1 } else { 3 };
    let mut seen: Vec<Vec<Vec<f64>>> = vec![vec![Vec::new(); TOE_CODES]; curves];
    for p in (0..w * h).step_by(stride) {
        for c in 0..3 {
            let i = p * 3 + c;
            let (mut num, mut den) = (0.0, 0.0);
            for (f, t) in codes.iter().zip(times) {
                let z = usize::from(f[i]);
                if (TOE_CODES..=TOE_SOURCE_TOP).contains(&z) {
                    num += weight(z) * response[c][z] / t;
                    den += weight(z);
                }
            }
            if den == 0.0 {
                continue;
            }
            let e = num / den;
            for (f, t) in codes.iter().zip(times) {
                let z = usize::from(f[i]);
                if z < TOE_CODES {
                    seen[if shared { 0 } else { c }][z].push(e * t);
                }
            }
        }
    }
    for (k, obs) in seen.iter_mut().enumerate() {
        let mut r = response[k].clone();
        for (z, o) in obs.iter_mut().enumerate() {
            if o.len() >= TOE_MIN_OBSERVATIONS {
                let mid = o.len() / 2;
                r[z] = *o.select_nth_unstable_by(mid, f64::total_cmp).1;
            }
        }
        for z in (0..TOE_CODES).rev() {
            r[z] = r[z].min(r[z + 1]);
        }
        if shared {
            *response = [r.clone(), r.clone(), r];
            break;
        }
        response[k] = r;
    }
    Ok(())
}

/// The codes, as fractions of the top code, over which each channel's white is fitted
/// ([`linearisation_table`]): 128/255 to 224/255.
pub const WHITE_FIT: (f64, f64) = (128.0 / 255.0, 224.0 / 255.0);

/// The highest code whose estimate the common white is set from ([`linearisation_table`]):
/// 249, one below the code from which the ground-truth merges treat a frame as clipped
/// (`capture::testset::CLIPPED_CODE`, 250).
pub const TRUSTED_TOP: usize = 249;

/// A channel's white fitted on its response `r` (exposure per code, any unit): least squares of
/// ln r(z) = ln W + γ·ln(z / top) over the codes of [`WHITE_FIT`]; W. None where the fit is
/// undefined (too few codes, a non-positive value, a curve that does not rise).
fn fit_white(r: &[f64]) -> Option<f64> {
    let top = r.len().checked_sub(1)?;
    let (lo, hi) = (
        (WHITE_FIT.0 * top as f64).round() as usize,
        (WHITE_FIT.1 * top as f64).round() as usize,
    );
    if lo == 0 || hi <= lo || hi >= top || r[lo..=hi].iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return None;
    }
    let pts: Vec<(f64, f64)> = (lo..=hi)
        .map(|z| ((z as f64 / top as f64).ln(), r[z].ln()))
        .collect();
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let gamma = sxy / sxx;
    let white = (my - gamma * mx).exp();
    (gamma.is_finite() && gamma > 0.0 && white.is_finite() && white > 0.0).then_some(white)
}

/// Code value → linear per channel from an estimated response (exp g, or Robertson's I):
/// non-decreasing, in [0, 1], 1 at the top code in every channel (the clipping white, the unit
/// of [`linear_frame`](crate::capture::linearise::linear_frame)).
///
/// The estimators fix each channel's unit at code 128 (g(128) = 0, I(128) = 1), which says
/// nothing about how the channels compare. The frames' encoding clips every channel at one
/// white, so the channels are compared there; but an estimate at the clipping code is set by
/// no unclipped sample (Debevec: the smoothness term and the clipped samples' pull, 11–33×
/// code 128's exposure on real JPEGs and different in each channel; Robertson: the mean
/// exposure of everything clipped), and dividing each channel by its own value at code 255
/// tinted every neutral grey (R/G 1.73 on a phone). So:
/// 1. each channel's white W is extrapolated from where data constrain its estimate:
///    ln r(z) = ln W + γ·ln(z/255) fitted over codes 128–224 ([`WHITE_FIT`]), exact for any
///    power-law curve whatever its γ per channel; a device whose channels share one tone
///    curve keeps equal codes equal in linear. Each channel becomes r/W, made non-decreasing;
/// 2. one common factor then brings the brightest value of any channel up to code 249
///    ([`TRUSTED_TOP`]) down to 1 where it exceeds 1 (a highlight shoulder above the fitted
///    power law, as in camera JPEGs, keeps its shape; the channels keep their ratios);
/// 3. values are capped at 1 and the top code is 1 (clipped) in every channel.
///
/// Where the fit is undefined (a flat curve) a channel's W is its value at the top code, the
/// rule before this one.
pub fn linearisation_table(response: &[Vec<f64>; 3]) -> [Vec<f64>; 3] {
    let over_white = response.clone().map(|r| {
        let white = fit_white(&r)
            .or_else(|| r.last().copied().filter(|w| w.is_finite() && *w > 0.0))
            .unwrap_or(1.0);
        let mut run = 0.0f64;
        r.iter()
            .map(|&e| {
                run = run.max(e / white);
                run
            })
            .collect::<Vec<f64>>()
    });
    let brightest = over_white
        .iter()
        .flat_map(|t| t.iter().take(TRUSTED_TOP + 1))
        .copied()
        .filter(|v| v.is_finite())
        .fold(1.0, f64::max);
    over_white.map(|t| {
        let top = t.len().saturating_sub(1);
        t.iter()
            .enumerate()
            .map(|(z, v)| {
                if z == top {
                    1.0
                } else {
                    (v / brightest).min(1.0)
                }
            })
            .collect()
    })
}
