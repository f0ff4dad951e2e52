//! Burst summaries: everything the catalogue's statistics need from one burst, accumulated
//! frame by frame (frames are never all held in memory), for measured and simulated bursts
//! alike.
//!
//! Per value (pixel × channel): temporal mean M and unbiased variance v. Dark and flat bursts
//! add the *fixed residual* (M minus, for flats, a least-squares quadratic surface in x, y that
//! absorbs vignetting and illumination falloff, then minus row and column means: a two-way
//! decomposition) and a hot-value mask (fixed residual above 8 robust σ). Dark bursts with ≥ 2
//! frames also give pooled moments of the temporal residuals x_f − M (second and fourth, for
//! the kurtosis), their covariance at lags 1 and 2 vertically and horizontally, and the covariance over frames of the left-
//! and right-half means of each row (a row offset shared by both halves; no pixel-level noise
//! process correlates two half rows).

use crate::io::Image;
use crate::sensor::captures::BurstKind;
use crate::sensor::noise::bursts::BurstFrames;
use rayon::prelude::*;

/// The capture protocol (what was captured, not the pixels) plus the model levels that the
/// statistics need.
#[derive(Clone, Debug)]
pub struct Protocol {
    pub bursts: Vec<BurstInfo>,
    /// The model's black level in DN including any black-level offset effect.
    pub black: f64,
    pub white: f64,
    /// white − the profile's black level (the normalisation of signals).
    pub range: f64,
    /// The model's response curve (None: linear), to linearise flat and scene bursts.
    pub response: Option<super::curve::Curve>,
}

impl Protocol {
    /// The model's power-law exponent (1 when the response is linear or not a power law).
    pub fn exponent(&self) -> f64 {
        match self.response {
            Some(super::curve::Curve::Power(p)) => p,
            _ => 1.0,
        }
    }

    /// The model's inverse response on a normalised signal (identity when linear).
    pub fn linearise(&self, y: f64) -> f64 {
        self.response.map_or(y.max(0.0), |c| c.inverse(y))
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct BurstInfo {
    pub name: String,
    pub kind: BurstKind,
    pub iso: f64,
    pub exposure_s: f64,
    pub width: usize,
    pub height: usize,
    pub frames: usize,
    /// The `scene` key of a scene burst (captures.toml), if declared.
    pub scene: Option<String>,
    /// The frame rows analysed (ascending; `analysed_rows`): measured and simulated alike.
    pub rows: Vec<usize>,
}

/// Rows analysed in a `width` × `height` frame: all when it has at most `max_pixels` pixels
/// (0: no limit), else bands of `BAND` consecutive rows spaced evenly from the top to the
/// bottom edge, about `max_pixels` in all but at least `MIN_BANDS` bands (row and column
/// statistics need rows however wide the frame). Bands keep the vertical lags, neighbourhoods and row
/// statistics local; their spread keeps the whole field (vignetting, radial profiles).
/// Measurement and simulation use the same rows, so every statistic is computed the same way
/// on both sides and the comparison stays exact; only its power falls with the pixel count.
pub fn analysed_rows(width: usize, height: usize, max_pixels: usize) -> Vec<usize> {
    let bands = max_pixels.div_ceil(width.max(1) * BAND).max(MIN_BANDS);
    if max_pixels == 0 || width * height <= max_pixels || bands * BAND >= height {
        return (0..height).collect();
    }
    (0..bands)
        .flat_map(|k| {
            let top = k * (height - BAND) / (bands - 1);
            top..top + BAND
        })
        .collect()
}

/// Rows per band of `analysed_rows`, and the fewest bands.
pub const BAND: usize = 8;
pub const MIN_BANDS: usize = 8;

/// Rows `rows` of `frame`, stacked (the frame itself, not a copy, when they are all its rows).
pub fn crop_rows(frame: Image, rows: &[usize]) -> Image {
    if rows.len() == frame.height {
        return frame;
    }
    let w3 = frame.width * 3;
    let mut data = Vec::with_capacity(rows.len() * w3);
    for &y in rows {
        data.extend_from_slice(&frame.data[y * w3..(y + 1) * w3]);
    }
    Image::from_vec(frame.width, rows.len(), data)
}

impl BurstInfo {
    /// Exposure × ISO: the expected signal above black is proportional to it.
    pub fn exposure(&self) -> f64 {
        self.exposure_s * self.iso
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Residuals {
    /// Per channel, the pooled mean of (x_f − M)² and (x_f − M)⁴ over values and frames
    /// (per channel: pooling channels of different variance is a scale mixture, which has
    /// excess kurtosis of its own).
    pub m2: [f64; 3],
    pub m4: [f64; 3],
    /// Mean residual covariance r(x, y)·r(x, y + d) over pairs and frames, d = 1, 2 (same
    /// channel, channels pooled).
    pub cov_v: [f64; 2],
    /// The same horizontally, r(x, y)·r(x + d, y), d = 1, 2.
    pub cov_h: [f64; 2],
    /// The same between the channels of one pixel (R·G and G·B pooled).
    pub cov_c: f64,
    /// Mean over rows of the covariance over frames of the left- and right-half row means (DN²).
    pub row_cov: f64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    pub burst: usize,
    pub kind: BurstKind,
    pub iso: f64,
    pub exposure_s: f64,
    pub width: usize,
    /// Rows stored (`rows.len()`): `mean`, `var`, … hold `width` × `height` × 3 values.
    pub height: usize,
    /// The frame's height and the frame row of each stored row (geometry: surfaces, radii).
    pub full_height: usize,
    pub rows: Vec<usize>,
    pub frames: usize,
    /// The declared scene of a scene burst.
    pub scene: Option<String>,
    /// Temporal mean per value (DN).
    pub mean: Vec<f64>,
    /// Temporal unbiased variance per value (DN²); empty with one frame or for scene bursts.
    pub var: Vec<f64>,
    /// Dark and flat: fixed residual per value (DN); empty otherwise.
    pub fixed: Vec<f64>,
    /// Dark and flat: hot values (fixed residual > 8 robust σ); empty otherwise.
    pub hot: Vec<bool>,
    /// Variance of `fixed` over non-hot values, corrected for the fitted degrees of freedom.
    pub fixed_var: f64,
    /// Mean temporal variance per channel over non-hot values.
    pub temporal_var: [f64; 3],
    /// Robust σ of the fixed residual (the hot threshold is 8 of these).
    pub fixed_sigma: f64,
    pub resid: Option<Residuals>,
}

impl Summary {
    pub fn info(&self) -> (BurstKind, f64, f64) {
        (self.kind, self.iso, self.exposure_s)
    }

    pub fn exposure(&self) -> f64 {
        self.exposure_s * self.iso
    }

    pub fn temporal_mean(&self) -> f64 {
        self.temporal_var.iter().sum::<f64>() / 3.0
    }

    pub fn not_hot(&self, i: usize) -> bool {
        self.hot.get(i).is_none_or(|h| !h)
    }

    /// Centred coordinates (`normalised_xy`) of stored pixel (x, stored row r) in its frame.
    pub fn xy(&self, x: usize, r: usize) -> (f64, f64) {
        normalised_xy(x, self.rows[r], self.width, self.full_height)
    }
}

/// Whether stored rows r and r + d are frame rows y and y + d (inside one band).
fn adjacent(rows: &[usize], r: usize, d: usize) -> bool {
    rows.get(r + d).is_some_and(|&y| y == rows[r] + d)
}

/// Streaming per-burst accumulator: the burst's exact temporal sums (`BurstFrames`, which the
/// noise calibration bins too) and, for dark bursts, the residual moments that only the
/// statistics need.
pub struct Accumulator {
    kind: BurstKind,
    w: usize,
    h: usize,
    rows: Vec<usize>,
    sums: BurstFrames,
    /// Integer shift of the residual sums (the first frame's rounded mean): it keeps the power
    /// sums well conditioned.
    shift: f64,
    /// Dark bursts, per value: Σd³, Σd⁴ and the lag products Σd·d' (vertical lags 1, 2,
    /// horizontal lags 1, 2, the next channel), d = x − shift.
    resid: Vec<f64>,
    /// Per frame, per row: (left-half mean, right-half mean).
    halves: Vec<[f64; 2]>,
}

/// Residual sums per value of a dark burst.
const RESID: usize = 7;

impl Accumulator {
    /// `calibration`: the noise calibration will bin these sums too (`finish`'s second value),
    /// so a dark burst also keeps each frame's robust mean (its black-level estimate).
    pub fn new(info: &BurstInfo, calibration: bool) -> Accumulator {
        let dark = info.kind == BurstKind::Dark;
        // Neighbourhoods stay inside a band when only bands of rows are analysed.
        let band = if info.rows.len() == info.height {
            usize::MAX
        } else {
            BAND
        };
        let nv = info.width * info.rows.len() * 3;
        Accumulator {
            kind: info.kind,
            w: info.width,
            h: info.rows.len(),
            rows: info.rows.clone(),
            sums: BurstFrames::new(dark && calibration, band),
            shift: 0.0,
            resid: if dark {
                vec![0.0; nv * RESID]
            } else {
                Vec::new()
            },
            halves: Vec::new(),
        }
    }

    /// Add a frame of the analysed rows (`crop_rows`).
    pub fn add(&mut self, f: &Image) {
        assert_eq!((f.width, f.height), (self.w, self.h), "frame size");
        if self.sums.frames == 0 {
            self.shift = f.data.iter().map(|&v| v as f64).sum::<f64>() / f.data.len() as f64;
            self.shift = self.shift.round();
        }
        self.sums.add(f);
        if self.kind != BurstKind::Dark {
            return;
        }
        let (w3, c) = (self.w * 3, self.shift);
        let rows = &self.rows;
        let data = &f.data;
        self.resid
            .par_chunks_mut(w3 * RESID)
            .enumerate()
            .for_each(|(y, a)| {
                let row = &data[y * w3..(y + 1) * w3];
                let next = adjacent(rows, y, 1).then(|| &data[(y + 1) * w3..(y + 2) * w3]);
                let next2 = adjacent(rows, y, 2).then(|| &data[(y + 2) * w3..(y + 3) * w3]);
                for (i, (s, &v)) in a.chunks_exact_mut(RESID).zip(row).enumerate() {
                    let d = v as f64 - c;
                    let d2 = d * d;
                    s[0] += d2 * d;
                    s[1] += d2 * d2;
                    if let Some(nx) = next {
                        s[2] += d * (nx[i] as f64 - c);
                    }
                    if let Some(nx) = next2 {
                        s[3] += d * (nx[i] as f64 - c);
                    }
                    // Same channel, one and two pixels to the right.
                    if let Some(&r1) = row.get(i + 3) {
                        s[4] += d * (r1 as f64 - c);
                    }
                    if let Some(&r2) = row.get(i + 6) {
                        s[5] += d * (r2 as f64 - c);
                    }
                    // The next channel of the same pixel (R·G, G·B).
                    if i % 3 < 2 {
                        s[6] += d * (row[i + 1] as f64 - c);
                    }
                }
            });
        let half = (self.w / 2) * 3;
        let rows: Vec<[f64; 2]> = data
            .par_chunks(w3)
            .map(|r| {
                let l = r[..half].iter().map(|&v| v as f64).sum::<f64>() / half as f64;
                let rr = r[half..].iter().map(|&v| v as f64).sum::<f64>() / (w3 - half) as f64;
                [l, rr]
            })
            .collect();
        self.halves.extend(rows);
    }

    /// The burst's summary, and its sums for the noise calibration.
    pub fn finish(self, burst: usize, info: &BurstInfo) -> (Summary, BurstFrames) {
        let frames = self.sums.frames;
        let (n, c) = (frames as f64, self.shift);
        let nv = self.w * self.h * 3;
        // Σ(x − c), Σ(x − c)² per value.
        let power: Vec<(f64, f64)> = (0..nv).map(|i| self.sums.shifted_sums(i, c)).collect();
        let mean: Vec<f64> = power.iter().map(|&(s1, _)| c + s1 / n).collect();
        let var: Vec<f64> = if matches!(self.kind, BurstKind::Dark | BurstKind::Flat) && frames >= 2
        {
            power
                .iter()
                .map(|&(s1, s2)| ((s2 - s1 * s1 / n) / (n - 1.0)).max(0.0))
                .collect()
        } else {
            Vec::new()
        };
        let mut s = Summary {
            burst,
            kind: info.kind,
            iso: info.iso,
            exposure_s: info.exposure_s,
            width: self.w,
            height: self.h,
            full_height: info.height,
            rows: self.rows.clone(),
            frames,
            scene: info.scene.clone(),
            mean,
            var,
            fixed: Vec::new(),
            hot: Vec::new(),
            fixed_var: f64::NAN,
            temporal_var: [f64::NAN; 3],
            fixed_sigma: f64::NAN,
            resid: None,
        };
        if matches!(self.kind, BurstKind::Dark | BurstKind::Flat) {
            fixed_residual(&mut s, self.kind == BurstKind::Flat);
            if !s.var.is_empty() {
                s.temporal_var = std::array::from_fn(|ch| {
                    super::masked_mean(&s.var, |i| i % 3 == ch && s.not_hot(i))
                });
            }
        }
        if self.kind == BurstKind::Dark && frames >= 2 {
            let w3 = self.w * 3;
            let (mut r2, mut r4) = ([0.0; 3], [0.0; 3]);
            // (sum, pairs) of residual products: vertical lags 1, 2, horizontal lags 1, 2.
            let mut cv = [(0.0, 0usize); 5];
            let mean = |j: usize| power[j].0 / n;
            for i in 0..nv {
                let (s1, s2) = power[i];
                let a = &self.resid[i * RESID..(i + 1) * RESID];
                let m = s1 / n;
                r2[i % 3] += s2 - n * m * m;
                r4[i % 3] += a[1] - 4.0 * m * a[0] + 6.0 * m * m * s2 - 3.0 * n * m.powi(4);
                let x = (i % w3) / 3;
                let r = i / w3;
                let partner = [
                    adjacent(&self.rows, r, 1).then_some(i + w3),
                    adjacent(&self.rows, r, 2).then_some(i + 2 * w3),
                    (x + 1 < self.w).then_some(i + 3),
                    (x + 2 < self.w).then_some(i + 6),
                    (i % 3 < 2).then_some(i + 1),
                ];
                for (l, j) in partner.iter().enumerate() {
                    if let Some(j) = *j {
                        cv[l].0 += a[2 + l] - n * m * mean(j);
                        cv[l].1 += 1;
                    }
                }
            }
            let per = nv as f64 / 3.0 * n;
            let m2 = r2.map(|v| v / per);
            let m4 = r4.map(|v| v / per);
            let cov = |l: usize| cv[l].0 / (cv[l].1.max(1) as f64 * n);
            let h = self.h;
            let mut row_cov = 0.0;
            for y in 0..h {
                let (mut sl, mut sr, mut slr) = (0.0, 0.0, 0.0);
                for f in 0..frames {
                    let [l, r] = self.halves[f * h + y];
                    sl += l;
                    sr += r;
                    slr += l * r;
                }
                row_cov += (slr - sl * sr / n) / (n - 1.0);
            }
            s.resid = Some(Residuals {
                m2,
                m4,
                cov_v: [cov(0), cov(1)],
                cov_h: [cov(2), cov(3)],
                cov_c: cov(4),
                row_cov: row_cov / h as f64,
            });
        }
        (s, self.sums)
    }
}

/// Median of a sample of at most ~40k values (strided), for robust scales: its relative
/// standard error (≈ 1.25/√n) is 0.6 %, and selecting over millions of values took 14 % of a
/// diagnosis (perf, `cargo bench --bench diagnose` at 256²). Frames of ≤ 40k values (the tests)
/// use every value.
fn sampled_median(v: impl Iterator<Item = f64>, len: usize) -> f64 {
    let mut step = len.div_ceil(40_000).max(1);
    // Values interleave three channels: a stride of a multiple of 3 would sample only one.
    if step.is_multiple_of(3) {
        step += 1;
    }
    let mut s: Vec<f64> = v.step_by(step).filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return 0.0;
    }
    let mid = s.len() / 2;
    *s.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1
}

#[allow(clippy::needless_range_loop)] // (x, y, c) index arithmetic reads clearer
/// Fill `fixed`, `hot`, `fixed_var`, `fixed_sigma`: surface (flats), then two passes of
/// row/column removal per channel, the second with hot values left out of the means.
fn fixed_residual(s: &mut Summary, surface: bool) {
    let (w, h) = (s.width, s.height);
    let nv = w * h * 3;
    let mut base = s.mean.clone();
    if surface {
        for c in 0..3 {
            let coef = quadratic_fit(s, &base, c);
            for y in 0..h {
                for x in 0..w {
                    base[(y * w + x) * 3 + c] -= quadratic_eval(&coef, s.xy(x, y));
                }
            }
        }
    }
    let mut hot = vec![false; nv];
    let mut fixed = vec![0.0; nv];
    let mut sigma = 0.0;
    for _pass in 0..2 {
        for c in 0..3 {
            let mut row = vec![(0.0, 0usize); h];
            let mut col = vec![(0.0, 0usize); w];
            let mut all = (0.0, 0usize);
            for y in 0..h {
                for x in 0..w {
                    let i = (y * w + x) * 3 + c;
                    if !hot[i] {
                        row[y].0 += base[i];
                        row[y].1 += 1;
                        col[x].0 += base[i];
                        col[x].1 += 1;
                        all.0 += base[i];
                        all.1 += 1;
                    }
                }
            }
            let m = |(s, k): (f64, usize)| if k == 0 { 0.0 } else { s / k as f64 };
            let g = m(all);
            for y in 0..h {
                for x in 0..w {
                    let i = (y * w + x) * 3 + c;
                    fixed[i] = base[i] - m(row[y]) - m(col[x]) + g;
                }
            }
        }
        let med = sampled_median(fixed.iter().copied(), nv);
        let mad = sampled_median(fixed.iter().map(|v| (v - med).abs()), nv);
        // Floor: with tiny noise the MAD of integer-quantised means can be 0.
        sigma = (1.4826 * mad).max(0.05);
        let thr = 8.0 * sigma;
        for (hv, f) in hot.iter_mut().zip(&fixed) {
            *hv = f - med > thr.max(2.0);
        }
    }
    let (mut ss, mut k) = (0.0, 0usize);
    for (f, hv) in fixed.iter().zip(&hot) {
        if !hv {
            ss += f * f;
            k += 1;
        }
    }
    let dof = ((w as f64 - 1.0) * (h as f64 - 1.0) - if surface { 6.0 } else { 0.0 }).max(1.0);
    s.fixed_var = ss / k.max(1) as f64 * (w * h) as f64 / dof;
    s.fixed = fixed;
    s.hot = hot;
    s.fixed_sigma = sigma;
}

/// Coordinates normalised to the half-diagonal, centred.
pub fn normalised_xy(x: usize, y: usize, w: usize, h: usize) -> (f64, f64) {
    let hd = 0.5 * ((w * w + h * h) as f64).sqrt();
    (
        (x as f64 + 0.5 - w as f64 / 2.0) / hd,
        (y as f64 + 0.5 - h as f64 / 2.0) / hd,
    )
}

fn quad_terms((u, v): (f64, f64)) -> [f64; 6] {
    [1.0, u, v, u * u, u * v, v * v]
}

fn quadratic_eval(c: &[f64; 6], uv: (f64, f64)) -> f64 {
    quad_terms(uv).iter().zip(c).map(|(a, b)| a * b).sum()
}

/// Least-squares quadratic surface of channel `c` of `m` (laid out like `s.mean`).
fn quadratic_fit(s: &Summary, m: &[f64], c: usize) -> [f64; 6] {
    let (w, h) = (s.width, s.height);
    let mut a = [[0.0; 6]; 6];
    let mut b = [0.0; 6];
    for y in 0..h {
        for x in 0..w {
            let t = quad_terms(s.xy(x, y));
            let v = m[(y * w + x) * 3 + c];
            for i in 0..6 {
                b[i] += t[i] * v;
                for j in 0..6 {
                    a[i][j] += t[i] * t[j];
                }
            }
        }
    }
    crate::linalg::solve6(a, b)
}

/// Per-channel mean of the dark bursts of one ISO (non-hot values): the zero of signals
/// (EMVA 1288 measures every signal above the dark mean). None without a dark burst.
pub fn dark_mean(s: &[Summary], iso: f64) -> Option<[f64; 3]> {
    let darks: Vec<&Summary> = s
        .iter()
        .filter(|b| b.kind == BurstKind::Dark && b.iso == iso)
        .collect();
    if darks.is_empty() {
        return None;
    }
    Some(std::array::from_fn(|c| {
        darks
            .iter()
            .map(|b| super::masked_mean(&b.mean, |i| i % 3 == c && b.not_hot(i)))
            .sum::<f64>()
            / darks.len() as f64
    }))
}

/// Photon transfer of one ISO from burst summaries (DN, DN², per channel); `a` is None when
/// the ISO has no flat burst (darks alone fix b only).
#[derive(Clone, Debug, PartialEq)]
pub struct TemporalPtc {
    pub iso: f64,
    pub a: Option<[f64; 3]>,
    pub b: [f64; 3],
}

/// Photon transfer from the dark and flat summaries (EMVA 1288's method): per ISO and channel,
/// each burst's mean temporal variance over non-hot values (less the 1/12 DN² of integer
/// quantisation, which the simulation adds back, and `extra_var`, variance the model draws
/// separately, e.g. row offsets) against its mean signal above the same ISO's dark mean (above
/// `black` when the ISO has no dark burst), then a weighted straight line (`stats::wls`).
/// Temporal variances do not see fixed patterns (constant over frames), and measuring the
/// signal from the dark mean removes any pedestal, so neither a wrong black level nor column,
/// pixel or gain patterns move a or b; the mean variance over values is linear in the mean
/// signal, so vignetting and PRNU (signal spread within a burst) do not either.
pub fn temporal_ptc(s: &[Summary], black: f64, extra_var: f64) -> Vec<TemporalPtc> {
    use crate::sensor::noise::{Bin, calibrate::fit_bins};
    let usable =
        |b: &&Summary| matches!(b.kind, BurstKind::Dark | BurstKind::Flat) && !b.var.is_empty();
    let mut isos: Vec<f64> = s.iter().filter(usable).map(|b| b.iso).collect();
    isos.sort_by(f64::total_cmp);
    isos.dedup();
    let mut out = Vec::new();
    for iso in isos {
        let bursts: Vec<&Summary> = s.iter().filter(usable).filter(|b| b.iso == iso).collect();
        let chan_mean = |b: &Summary, c: usize, v: &[f64]| {
            super::masked_mean(v, |i| i % 3 == c && b.not_hot(i))
        };
        let zero = dark_mean(s, iso).unwrap_or([black; 3]);
        let mut a = [0.0; 3];
        let mut b = [0.0; 3];
        let mut has_a = true;
        for c in 0..3 {
            let bins: Vec<Bin> = bursts
                .iter()
                .map(|s| {
                    let keep = |i: usize| i % 3 == c && s.not_hot(i);
                    let n = s.var.iter().enumerate().filter(|(i, _)| keep(*i)).count();
                    let m = s.temporal_var[c];
                    let ss: f64 = s
                        .var
                        .iter()
                        .enumerate()
                        .filter(|(i, _)| keep(*i))
                        .map(|(_, v)| (v - m) * (v - m))
                        .sum();
                    let sd = (ss / (n.max(2) - 1) as f64).sqrt();
                    Bin {
                        burst: s.burst,
                        signal: chan_mean(s, c, &s.mean) - zero[c],
                        variance: m - 1.0 / 12.0 - extra_var,
                        stderr: sd / (n.max(1) as f64).sqrt(),
                        pixels: n,
                    }
                })
                .collect();
            match fit_bins(&bins) {
                Ok(f) => {
                    a[c] = f.a.max(0.0);
                    b[c] = f.b.max(0.0);
                }
                // One signal level only (darks alone): b is their mean variance.
                Err(_) => {
                    has_a = false;
                    let dark: Vec<&Bin> = bins.iter().filter(|x| x.signal.abs() < 1.0).collect();
                    if dark.is_empty() {
                        b[c] = f64::NAN;
                    } else {
                        b[c] = (dark.iter().map(|x| x.variance).sum::<f64>() / dark.len() as f64)
                            .max(0.0);
                    }
                }
            }
        }
        if b.iter().all(|v| v.is_finite()) {
            out.push(TemporalPtc {
                iso,
                a: has_a.then_some(a),
                b,
            });
        }
    }
    out
}
