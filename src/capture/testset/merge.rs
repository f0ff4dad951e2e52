//! Choosing a bracket's three network inputs by metering, and the HDR merge of its frames.

use super::*;

/// The metering rule's thresholds, 8-bit code values: a pixel is clipped where any channel is
/// at or above [`CLIPPED_CODE`], dark where every channel is at or below [`DARK_CODE`].
pub const CLIPPED_CODE: f32 = 250.0;
pub const DARK_CODE: f32 = 5.0;

/// The largest [`clipped_or_dark`] fraction of a reference frame a test set is built from:
/// beyond it the frames hold no scene to score (all-black, all-white or flat).
pub const MAX_REFERENCE_CLIPPED_OR_DARK: f64 = 0.999;

/// Fraction of the pixels of `code` (a frame's values in [0, 1] as stored — JPEG/PNG/TIFF code
/// / maximum code; DNG: linear after levels and white balance) that are clipped or dark
/// ([`CLIPPED_CODE`], [`DARK_CODE`]).
pub fn clipped_or_dark(code: &Image) -> f64 {
    // A thousandth of a code absorbs the decoders' rounding of v / 255.
    let (hi, lo) = (CLIPPED_CODE - 1e-3, DARK_CODE + 1e-3);
    let bad = code
        .data
        .par_chunks_exact(3)
        .filter(|p| p.iter().any(|&v| v * 255.0 >= hi) || p.iter().all(|&v| v * 255.0 <= lo))
        .count();
    bad as f64 / code.pixel_count().max(1) as f64
}

/// Refuse a set whose reference frame (`frame`, [`clipped_or_dark`] fraction `bad`) holds no
/// scene: beyond [`MAX_REFERENCE_CLIPPED_OR_DARK`] (a test set's reference, a calibration's
/// metering frame).
pub fn refuse_sceneless(set: &scan::BracketSet, frame: &BracketFrame, bad: f64) -> Result<()> {
    if bad <= MAX_REFERENCE_CLIPPED_OR_DARK {
        return Ok(());
    }
    Err(Error::layout(
        &frame.path,
        format!(
            "set '{}': the reference frame is {:.2} % clipped or dark (a channel at code \
             {CLIPPED_CODE} or above, or every channel at {DARK_CODE} or below; at most {:.1} %): \
             the bracket holds no scene to score or measure (all-black, all-white or flat \
             frames?)",
            set.name,
            100.0 * bad,
            100.0 * MAX_REFERENCE_CLIPPED_OR_DARK
        ),
    ))
}

/// How the inputs of one set were chosen.
#[derive(Clone, Debug, PartialEq)]
pub struct InputSelection {
    pub indices: [usize; 3],
    /// In words, for the record and the report.
    pub how: String,
    /// [`clipped_or_dark`] of every reference considered (`auto` only): (index, fraction).
    pub metered: Vec<(usize, f64)>,
}

/// Steps within this many stops of the best achievable spacing are equally acceptable to
/// `auto`: EXIF times are marked in third stops.
pub const AUTO_STEP_TOLERANCE: f64 = 1.0 / 3.0;

/// `--inputs auto` on a set with exposure stops `stops` (ascending): of all triples i < j < k,
/// those whose larger deviation of a step from 2 stops, max(|s_j − s_i − 2|, |s_k − s_j − 2|),
/// is within [`AUTO_STEP_TOLERANCE`] of the smallest achievable are candidates (the network's
/// EV −2/0/+2 as nearly as the bracket allows); of these the one whose middle frame (the
/// reference) has the smallest `metered(j)` — [`clipped_or_dark`] — wins, ties going to the
/// smaller deviation, then the shorter frames. A metering rule computed from the frames alone.
pub fn auto_inputs(
    stops: &[f64],
    mut metered: impl FnMut(usize) -> Result<f64>,
) -> Result<InputSelection> {
    let n = stops.len();
    let mut triples = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                let d = (stops[j] - stops[i] - 2.0)
                    .abs()
                    .max((stops[k] - stops[j] - 2.0).abs());
                triples.push(([i, j, k], d));
            }
        }
    }
    let best = triples.iter().map(|t| t.1).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return Err(Error::flag(
            "--inputs",
            format!("auto needs at least three frames, the set has {n}"),
        ));
    }
    triples.retain(|t| t.1 <= best + AUTO_STEP_TOLERANCE + 1e-9);
    let mut fractions: Vec<(usize, f64)> = Vec::new();
    for (t, _) in &triples {
        if !fractions.iter().any(|f| f.0 == t[1]) {
            fractions.push((t[1], metered(t[1])?));
        }
    }
    fractions.sort_by_key(|f| f.0);
    let bad = |j: usize| fractions.iter().find(|f| f.0 == j).map_or(1.0, |f| f.1);
    let (idx, d) = triples
        .iter()
        .min_by(|a, b| {
            bad(a.0[1])
                .total_cmp(&bad(b.0[1]))
                .then(a.1.total_cmp(&b.1))
                .then(a.0.cmp(&b.0))
        })
        .copied()
        .ok_or_else(|| Error::flag("--inputs", "auto: no triple of frames"))?;
    let how = format!(
        "auto: steps {:.2}, {:.2} stops (largest deviation from 2 stops {d:.2}; candidates \
         within {:.2} of the best {best:.2}); reference {} of the candidates' references {} \
         with the fewest pixels clipped (a channel ≥ {CLIPPED_CODE}/255) or dark (all ≤ \
         {DARK_CODE}/255): {:.2} %",
        stops[idx[1]] - stops[idx[0]],
        stops[idx[2]] - stops[idx[1]],
        AUTO_STEP_TOLERANCE,
        idx[1],
        fractions
            .iter()
            .map(|(j, f)| format!("{j} ({:.2} %)", 100.0 * f))
            .collect::<Vec<_>>()
            .join(", "),
        100.0 * bad(idx[1])
    );
    Ok(InputSelection {
        indices: idx,
        how,
        metered: fractions,
    })
}

/// The weight [`hat_merge`] gives a frame's code value `z` (as stored, in [0, 1]): the hat
/// 1 − |2z − 1|, zero where the code is clipped (≥ [`CLIPPED_CODE`]/255) or dark
/// (≤ [`DARK_CODE`]/255) — the metering rule's thresholds, per channel.
pub fn code_weight(z: f32) -> f64 {
    let c = z * 255.0;
    if c >= CLIPPED_CODE - 1e-3 || c <= DARK_CODE + 1e-3 {
        0.0
    } else {
        1.0 - (2.0 * f64::from(z) - 1.0).abs()
    }
}

/// Refinements of [`hat_merge`] after its first pass. On the noisy bracket of tests/hat_merge.rs
/// the mean shadow ratio to the radiance goes +191 % (first pass), +3.6 %, +2.3 %, +2.0 %
/// (a third pass): two.
pub const HAT_REFINEMENTS: usize = 2;

/// The multi-exposure weighted average over any number of frames (Debevec & Malik 1997, Eq. 6,
/// in the linear domain, with the exposure-time factor of Robertson et al. 2003):
/// per pixel and channel H = Σ w_i · L_i / t_i / Σ w_i, where `frames` hold the values v_i as
/// written (L_i = v_i^γ), `codes` each frame's code values as stored (aligned and cropped like
/// `frames`), and w_i = [`code_weight`](ẑ_i) · t_i:
/// - the hat trusts each frame where it records mid values, and no frame for being an input;
/// - zero at clipped and dark codes: there an estimated response is set by its smoothness
///   term alone and a JPEG clips channel by channel;
/// - · t_i: photon noise makes the variance of L_i / t_i fall as 1/t_i, and a short frame's
///   error near its black floor is multiplied by 1/t_i — without it a frame 7 stops short
///   pulls dark regions up by its floor;
/// - ẑ_i is the code frame i is expected to record at the merged value, H · t_i through the
///   frame's own code ↔ value relation ([`expected_code_tables`]), not the code it did record:
///   a weight taken from the sample itself rises with the sample's noise (the hat climbs from
///   the dark end) and the dark cut-off keeps only upward excursions, so in shadows recorded
///   near the noise floor that merge sat far above the radiance (tests/hat_merge.rs: ×2.9
///   where the longest frame records codes 4–40). The first pass weighs by the recorded codes; each of
///   [`HAT_REFINEMENTS`] passes re-weighs by the codes expected at the previous pass's H, and
///   drops a sample whose recorded code is clipped (≥ [`CLIPPED_CODE`]: censored).
///
/// Where every weight is 0: the shortest frame's L/t when it is clipped there (white is a
/// lower bound), else the longest frame's that is not clipped; a refinement keeps the previous
/// pass's value there.
pub fn hat_merge(frames: &[Image], codes: &[Image], times: &[f64], gamma: f32) -> Result<Image> {
    hat_merge_covered(frames, codes, times, gamma).map(|(img, _)| img)
}

/// [`hat_merge`] and, per value, whether some frame carried weight in its last pass (`false`
/// where the value is the all-weights-zero fallback).
pub fn hat_merge_covered(
    frames: &[Image],
    codes: &[Image],
    times: &[f64],
    gamma: f32,
) -> Result<(Image, Vec<bool>)> {
    let Some(first) = frames.first() else {
        return Err(Error::Invalid("hat merge: no frames".to_string()));
    };
    if frames.len() != times.len() || frames.len() != codes.len() {
        return Err(Error::Invalid(format!(
            "hat merge: {} frames, {} code images and {} exposure times",
            frames.len(),
            codes.len(),
            times.len()
        )));
    }
    if times.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(Error::Invalid(format!(
            "hat merge: exposure times {times:?} must be finite and positive"
        )));
    }
    let (w, h) = (first.width, first.height);
    if let Some(f) = frames
        .iter()
        .chain(codes)
        .find(|f| (f.width, f.height) != (w, h))
    {
        return Err(Error::Invalid(format!(
            "hat merge: images differ in size ({}×{} and {w}×{h})",
            f.width, f.height
        )));
    }
    let g = f64::from(gamma);
    // Frames from the shortest exposure to the longest.
    let mut order: Vec<usize> = (0..times.len()).collect();
    order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
    let hdr = |i: usize, k: usize| f64::from(frames[i].data[k]).clamp(0.0, 1.0).powf(g) / times[i];
    let clipped = |i: usize, k: usize| codes[i].data[k] * 255.0 >= CLIPPED_CODE - 1e-3;
    let (mut merged, mut covered): (Vec<f32>, Vec<bool>) = (0..first.data.len())
        .into_par_iter()
        .map(|k| {
            let (mut num, mut den) = (0.0f64, 0.0f64);
            for i in 0..frames.len() {
                let wt = code_weight(codes[i].data[k]) * times[i];
                num += wt * hdr(i, k);
                den += wt;
            }
            if den > 0.0 {
                ((num / den) as f32, true)
            } else if clipped(order[0], k) {
                (hdr(order[0], k) as f32, false)
            } else {
                let i = order
                    .iter()
                    .rev()
                    .copied()
                    .find(|&i| !clipped(i, k))
                    .unwrap_or(order[0]);
                (hdr(i, k) as f32, false)
            }
        })
        .unzip();
    let tables = expected_code_tables(frames, codes);
    let inv_g = 1.0 / g;
    for _ in 0..HAT_REFINEMENTS {
        (merged, covered) = merged
            .par_iter()
            .enumerate()
            .map(|(k, &prev)| {
                let (mut num, mut den) = (0.0f64, 0.0f64);
                for i in 0..frames.len() {
                    let v = (f64::from(prev).max(0.0) * times[i]).powf(inv_g);
                    if v >= 1.0 || clipped(i, k) {
                        continue;
                    }
                    let wt = code_weight(tables[i][k % 3].code_at(v)) * times[i];
                    num += wt * hdr(i, k);
                    den += wt;
                }
                if den > 0.0 {
                    ((num / den) as f32, true)
                } else {
                    (prev, false)
                }
            })
            .unzip();
    }
    Ok((Image::from_vec(w, h, merged), covered))
}

/// A frame's code as stored against its value as written, per channel: the mean stored code
/// of the pixels whose written value falls in each of [`CodeTable::BINS`] bins over [0, 1],
/// empty bins interpolated between their neighbours (held flat beyond the first and last),
/// made non-decreasing. Read from the frame itself, so it holds for any response and any
/// stored kind (8- or 16-bit codes, linear DNG values) without being told which.
#[derive(Clone, Debug)]
pub struct CodeTable(Vec<f32>);

impl CodeTable {
    pub const BINS: usize = 1024;

    /// The stored code expected at written value `v` (in [0, 1]), interpolated between bins.
    pub fn code_at(&self, v: f64) -> f32 {
        let x = v.clamp(0.0, 1.0) * (Self::BINS - 1) as f64;
        let lo = x.floor() as usize;
        let hi = (lo + 1).min(Self::BINS - 1);
        let f = (x - lo as f64) as f32;
        self.0[lo] * (1.0 - f) + self.0[hi] * f
    }
}

/// [`CodeTable`] per frame and channel, from the pairs (written value, stored code) of every
/// pixel of `frames` and `codes`.
pub fn expected_code_tables(frames: &[Image], codes: &[Image]) -> Vec<[CodeTable; 3]> {
    frames
        .par_iter()
        .zip(codes)
        .map(|(f, c)| {
            let samples = f.data.iter().zip(&c.data).enumerate();
            let means = binned_means(
                samples.map(|(k, (&v, &z))| (k, f64::from(v), f64::from(z))),
                CodeTable::BINS,
            );
            means.map(|m| {
                let mut top = f32::MIN;
                CodeTable(
                    m.iter()
                        .map(|&z| {
                            top = top.max(z as f32);
                            top
                        })
                        .collect(),
                )
            })
        })
        .collect()
}

/// Per channel, the mean code `z` of the samples (value index k, of channel k % 3; value `v` in
/// [0, 1]; code `z`) whose `v` falls in each of `n` even bins over [0, 1], empty bins
/// interpolated between their neighbours and held flat beyond the first and last (0 where a
/// channel has no sample).
pub(crate) fn binned_means(
    samples: impl Iterator<Item = (usize, f64, f64)>,
    n: usize,
) -> [Vec<f64>; 3] {
    let mut sum = vec![[0.0f64; 3]; n];
    let mut count = vec![[0u64; 3]; n];
    for (k, v, z) in samples {
        let b = (v.clamp(0.0, 1.0) * (n - 1) as f64).round() as usize;
        sum[b][k % 3] += z;
        count[b][k % 3] += 1;
    }
    std::array::from_fn(|ch| {
        let seen: Vec<(usize, f64)> = (0..n)
            .filter(|&b| count[b][ch] > 0)
            .map(|b| (b, sum[b][ch] / count[b][ch] as f64))
            .collect();
        let mut t = vec![0.0; n];
        if seen.is_empty() {
            return t;
        }
        let mut j = 0;
        for (b, slot) in t.iter_mut().enumerate() {
            while j + 1 < seen.len() && seen[j + 1].0 <= b {
                j += 1;
            }
            let (b0, z0) = seen[j];
            *slot = match seen.get(j + 1) {
                Some(&(b1, z1)) if b > b0 => z0 + (z1 - z0) * (b - b0) as f64 / (b1 - b0) as f64,
                _ => z0,
            };
        }
        t
    })
}
