//! The device-output check: a profile's simulation of a device's own bracket frames against
//! the frames, in the device's output domain (the codes a network sees). Each set's scene is
//! estimated from its frames (the weighted merge of every frame, smoothed so that the
//! estimate's own noise stays out), rendered back at every frame's exposure and ISO through
//! the profile (`Realism`: noise, its effects, the response, 8-bit output), K times with
//! different seeds; the same statistics are computed on the real and on every simulated frame
//! by the same code, and compared as `diagnose` compares (z against the replicates' spread,
//! a Bonferroni threshold and a minimum effect size per statistic, docs/diagnose.md).
//!
//! Every frame is read in its central 640×480 window (all of a smaller frame), the same window
//! for every frame of a set.
//!
//! Where the sets hold repeated captures (`ScanOptions::repeats`), the statistics are taken on
//! each pair of captures of one exposure (their difference, binned by their mean, as
//! `calibrate brackets` measures temporal noise), and each pair is simulated as two renders of
//! the same scene estimate with different seeds: the scene cancels on both sides, so texture
//! the smoothed estimate lacks cannot bias the comparison as it does for single frames.
//!
//! Without repeats, each frame's statistics are taken on its residual against the merge of the
//! set's other frames (`noise::cross_residuals`), real and simulated alike: the
//! scene cancels there too, so neither the texture of the real frames nor the smoothing of the
//! estimate enters the comparison.
//!
//! Statistics, per channel on flat pixels (the flattest half of each code bin, as
//! `calibrate brackets` measures): the noise level (pixel-weighted mean over the code bins
//! from 1/8 up of ln σ² of Immerkær's residual), the noise floor (the same over the code bins
//! under 1/8, where a read-noise floor b, not the signal's shot noise, sets σ²), the noise's
//! spatial correlation (the low/high-order residual ratio), and across channels the
//! correlation of the three channels' Immerkær residuals (chroma noise: a device that
//! denoises chroma harder than luma, or subsamples chroma as JPEG does, makes its channels'
//! noise move together). Each names what would close it: the profile's noise a and b, the
//! catalogue's `correlated_noise` and `channel_correlation`.
//!
//! On each set's frames as they are, the floor: the radiance → code map under the toe, read
//! from the frames that see those pixels at mid codes (output/floor.rs), which the
//! catalogue's `floor` closes; and on the units' residuals, JPEG's blockiness
//! (output/jpeg.rs), which the catalogue's `jpeg` closes, and the frames' disagreement at 4-
//! and 16-pixel scales (output/consistency.rs), which nothing in the catalogue closes yet.

use crate::capture::linearise::Linearise;
use crate::capture::linearise::{code_frame, linearise};
use crate::capture::noise::{self, CrossResidual, NoiseBin, Pair, Planes};
use crate::capture::scan::{self, ScanOptions};
use crate::capture::testset::{self, FIELD_GAMMA};
use crate::error::Result;
use crate::io::Image;
use crate::sensor::profile::SensorProfile;
use crate::sensor::realism::{NoiseModel, Realism, RealismOptions};
use std::path::Path;

/// The central window of `img` (`noise::window`, at most 640×480), the same for
/// every frame of a set.
fn window(img: Image) -> Image {
    let (x0, y0, w, h) = noise::window(&img);
    if (w, h) == (img.width, img.height) {
        return img;
    }
    Image::from_fn(w, h, |x, y| img.get(x0 + x, y0 + y))
}

/// Codes (of 1) between which a residual's value counts as recorded, for the blockiness and
/// the disagreement statistics.
const RECORDED: (f32, f32) = (3.0 / 255.0, 250.0 / 255.0);

/// Width of the Gaussian that smooths the scene estimate, pixels.
const SMOOTH_SIGMA: f32 = 1.5;

/// How a check is run.
#[derive(Clone, Debug)]
pub struct OutputCheckOptions {
    pub scan: ScanOptions,
    /// Simulated replicates of the whole folder.
    pub replicates: usize,
    pub seed: u64,
    /// Simulate without noise (the profile's response alone).
    pub noise: bool,
}

/// One statistic compared.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputStat {
    pub name: String,
    /// What would close a gap in it: a catalogue effect, the profile's noise, or none.
    pub names: &'static str,
    pub measured: f64,
    pub sim_mean: f64,
    pub sim_sd: f64,
    pub z: f64,
    pub min_effect: f64,
    /// |z| over the threshold and |measured − simulated| over the minimum effect.
    pub significant: bool,
}

#[derive(Clone, Debug, PartialEq)]
pub struct OutputCheck {
    pub stats: Vec<OutputStat>,
    pub threshold: f64,
    /// The largest |z| of a significant statistic (0 when none is).
    pub gap: f64,
    pub replicates: usize,
    /// The noise statistics' code bins, real against simulated.
    pub bins: Vec<BinOffset>,
}

/// One code bin of one channel: ln σ² of the codes on the real frames and its mean over the
/// simulated replicates.
#[derive(Clone, Debug, PartialEq)]
pub struct BinOffset {
    pub channel: usize,
    /// The bin's mean linear value under the profile's response.
    pub linear: f64,
    /// Under code 1/8: a bin of the noise floor, not of the level.
    pub dark: bool,
    /// The real frames' pixels in the bin.
    pub weight: f64,
    pub measured: f64,
    pub simulated: f64,
}

/// Per channel the bins' (ln σ², correlation ratio, pixels) by code bin, and the channel
/// correlation's moments (Σ rᵢ rⱼ for the pairs RG, GB, RB and Σ r² per channel).
#[derive(Clone, Debug, Default)]
struct FrameStats {
    bins: Vec<NoiseBin>,
    cross: [f64; 3],
    square: [f64; 3],
    floor: floor::FloorMoments,
    blocks: jpeg::BlockMoments,
    bands: consistency::BandMoments,
}

/// What the statistics are taken on: a frame, or, where the sets hold repeated captures, a
/// pair of captures of one exposure (their difference: no scene, so the scene estimate's
/// smoothing cannot bias the comparison).
enum Unit {
    Frame(Image),
    Pair(Pair),
    /// A frame of a set of two or more, against the others' merge: no scene texture.
    Residual(CrossResidual),
}

impl Unit {
    fn planes(&self) -> Planes<'_> {
        match self {
            Unit::Frame(code) => Planes::frame(code),
            Unit::Pair(p) => p.planes(),
            Unit::Residual(r) => r.planes(),
        }
    }
}

/// Replicate `r` of the units: each scene rendered through `profile` (a pair twice, with
/// different seeds), each set's frames taken against the others as the real ones are.
fn simulate(
    profile: &SensorProfile,
    prep: &Prepared,
    opts: &OutputCheckOptions,
    r: usize,
) -> Result<FrameStats> {
    let (mut units, firsts) = simulated_units(profile, prep, opts, r)?;
    let floor = prep.floor_of(|i| &firsts[i], &profile.response);
    drop(firsts);
    residualise(&mut units, &prep.groups, &profile.response)?;
    Ok(FrameStats {
        floor,
        ..measure(&units, &profile.response)
    })
}

/// Units with their ISO.
type Units = Vec<(Unit, f64)>;

/// Replicate `r`'s units before their residuals, and each unit's first render.
fn simulated_units(
    profile: &SensorProfile,
    prep: &Prepared,
    opts: &OutputCheckOptions,
    r: usize,
) -> Result<(Units, Vec<Image>)> {
    let units = prep
        .scenes
        .iter()
        .enumerate()
        .map(|(j, (scene, iso, pair))| {
            let (realism, seed) = render(profile, opts, *iso, r, j)?;
            let a = realism.apply(scene, seed(0));
            let unit = if *pair {
                Unit::Pair(Pair::new(&a, &realism.apply(scene, seed(1 << 40))))
            } else {
                Unit::Frame(a.clone())
            };
            Ok(((unit, *iso), a))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(units.into_iter().unzip())
}

/// The realism operator of scene `j` of replicate `r` (noise as `opts` asks), and the seeds
/// of its renders.
fn render(
    profile: &SensorProfile,
    opts: &OutputCheckOptions,
    iso: f64,
    r: usize,
    j: usize,
) -> Result<(Realism, impl Fn(u64) -> u64 + use<>)> {
    let realism = Realism::new(
        profile,
        &RealismOptions {
            iso,
            exposure: 1.0,
            noise: if opts.noise {
                NoiseModel::Gaussian
            } else {
                NoiseModel::None
            },
            colour: false,
            output_bits: 8,
        },
    )?;
    let base = opts.seed ^ crate::rng::mix64((r * 7919 + j) as u64);
    Ok((realism, move |k: u64| crate::rng::mix64(base ^ k)))
}

/// The units of each set of single frames (indices into the units, relative exposure times).
type Groups = Vec<(Vec<usize>, Vec<f64>)>;

/// Each set's frames replaced by their residuals against the set's other frames
/// ([`noise::cross_residuals`]), on the real and on every simulated side alike.
fn residualise(
    units: &mut [(Unit, f64)],
    groups: &Groups,
    response: &crate::sensor::profile::Response,
) -> Result<()> {
    for (indices, times) in groups {
        let frames: Vec<Image> = indices
            .iter()
            .filter_map(|&i| match &units[i].0 {
                Unit::Frame(img) => Some(img.clone()),
                _ => None,
            })
            .collect();
        if frames.len() != indices.len() {
            continue;
        }
        let residuals = noise::cross_residuals(&frames, times, response)?;
        for (&i, r) in indices.iter().zip(residuals) {
            units[i].0 = Unit::Residual(r);
        }
    }
    Ok(())
}

/// What is measured on a set of units (real, or one replicate), each with its ISO.
fn measure(units: &[(Unit, f64)], response: &crate::sensor::profile::Response) -> FrameStats {
    let mut s = FrameStats::default();
    for (unit, iso) in units {
        s.bins
            .extend(noise::noise_bins(unit.planes(), *iso, response));
        let (cross, square, _) = noise::channel_moments(unit.planes());
        for k in 0..3 {
            s.cross[k] += cross[k];
            s.square[k] += square[k];
        }
        s.blocks.add(&jpeg::moments(unit.planes()));
        s.bands.add(&consistency::moments(unit.planes()));
    }
    s.bins = noise::merge_bins(&s.bins);
    s
}

fn bin_of(b: &NoiseBin) -> usize {
    ((b.code * noise::BINS as f64) as usize).min(noise::BINS - 1)
}

/// ln σ² of a bin's codes, as the level and floor statistics average it.
fn ln_var(b: &NoiseBin) -> f64 {
    b.var_code.max(1e-12).ln()
}

impl FrameStats {
    /// Channel `c`'s code bin `k`, where these frames have it.
    fn bin(&self, c: usize, k: usize) -> Option<&NoiseBin> {
        self.bins.iter().find(|b| b.channel == c && bin_of(b) == k)
    }
}

/// Code bins (of [`noise::BINS`]) under the noise-floor statistic's ceiling, 1/8.
const DARK_BINS: usize = noise::BINS / 8;

/// The statistics' values of `s` over the bins `keys` (channel, bin, weight), in the order of
/// [`STATS`]: per channel the weighted mean ln σ² (weights: the real frames' pixels) over the
/// bins from [`DARK_BINS`] up, the same under it (NaN where no bin is there), and the median
/// correlation ratio (as `calibrate brackets` takes it: a bin whose noise falls under the
/// 8-bit step has a ratio without bound); then the mean channel correlation, the floor, the
/// blockiness and the frames' disagreement at each scale.
fn values(s: &FrameStats, keys: &[(usize, usize, f64)]) -> Vec<f64> {
    let mut out = Vec::new();
    for c in 0..3 {
        let mut level = [(0.0, 0.0); 2];
        let mut ratios = Vec::new();
        for &(kc, kb, w) in keys.iter().filter(|k| k.0 == c) {
            let Some(b) = s.bin(kc, kb) else {
                continue;
            };
            let l = &mut level[usize::from(kb < DARK_BINS)];
            l.0 += w * ln_var(b);
            l.1 += w;
            ratios.push(b.correlation_ratio);
        }
        out.extend(level.map(|(lv, w)| if w > 0.0 { lv / w } else { f64::NAN }));
        out.push(if ratios.is_empty() {
            f64::NAN
        } else {
            crate::stats::median(&mut ratios)
        });
    }
    let corr =
        |k: usize, a: usize, b: usize| s.cross[k] / (s.square[a] * s.square[b]).sqrt().max(1e-30);
    out.push((corr(0, 0, 1) + corr(1, 1, 2) + corr(2, 0, 2)) / 3.0);
    out.push(s.floor.value());
    out.push(s.blocks.value());
    out.extend((0..consistency::SCALES.len()).map(|k| s.bands.value(k)));
    out.extend((0..consistency::LEVELS.len()).map(|k| s.bands.level_value(k)));
    out
}

/// The check of `profile` on the bracket folder `dir`.
pub fn check(
    dir: &Path,
    profile: &SensorProfile,
    opts: &OutputCheckOptions,
) -> Result<OutputCheck> {
    check_scanned(scan::scan(dir, &opts.scan)?, profile, opts)
}

/// [`check`] on sets already scanned with `opts.scan` (a run that reads the folder once:
/// [`scan::FolderScan`]).
pub fn check_scanned(
    scan: scan::BracketScan,
    profile: &SensorProfile,
    opts: &OutputCheckOptions,
) -> Result<OutputCheck> {
    check_prepared(&Prepared::new(scan, profile)?, profile, opts)
}

/// The scene estimate is linear: rendered as it is, not read through the profile's source
/// curve (a measured profile's is the scene engine's display curve, which would darken every
/// simulated frame and compare the noise at other codes than the frames').
fn device(profile: &SensorProfile) -> SensorProfile {
    let mut device = profile.clone();
    device.source_response = crate::sensor::profile::Response::Linear;
    device
}

/// What a check reads of a folder, whatever profile it simulates (of one response: the one
/// the frames are linearised and their statistics binned with).
struct Prepared {
    /// The real units with their ISO, measured.
    measured: FrameStats,
    /// Sets of single frames: the units' indices and relative exposure times.
    groups: Groups,
    /// The scene at each unit's exposure (a pair: rendered twice) and its ISO.
    scenes: Vec<(Image, f64, bool)>,
    /// Per set, the unit of each of its frames (the first capture of an exposure) and the
    /// frames' relative exposure times: what the floor statistic reads.
    floor_groups: Groups,
}

impl Prepared {
    fn new(scan: scan::BracketScan, profile: &SensorProfile) -> Result<Prepared> {
        if let Some(f) = scan
            .sets
            .iter()
            .flat_map(|s| &s.frames)
            .find(|f| f.kind == scan::FrameKind::Dng)
        {
            return Err(crate::error::Error::layout(
                &f.path,
                "a DNG is linear raw, not the device's output: the device-output check reads \
                 JPEG/PNG/TIFF frames",
            ));
        }
        let lin = Linearise::Curve(profile.response.clone());
        let temporal = scan.sets.iter().any(|s| !s.repeats.is_empty());
        let mut real: Vec<(Unit, f64)> = Vec::new();
        let mut groups: Groups = Vec::new();
        let mut floor_groups: Groups = Vec::new();
        let mut scenes: Vec<(Image, f64, bool)> = Vec::new();
        let mut floor = floor::FloorMoments::default();
        for set in &scan.sets {
            let mut gamma = Vec::new();
            let mut stored = Vec::new();
            let mut times = Vec::new();
            for f in &set.frames {
                let code = window(code_frame(f)?);
                let linear = linearise(f, code.clone(), &lin);
                gamma.push(linear.map(|v| v.clamp(0.0, 1.0).powf(1.0 / FIELD_GAMMA)));
                stored.push(code);
                times.push(f.stop.exp2());
            }
            let frames: Vec<&Image> = stored.iter().collect();
            floor.add(&floor::moments(&frames, &times, &profile.response));
            let radiance = smooth(&testset::hat_merge(&gamma, &stored, &times, FIELD_GAMMA)?);
            if !temporal {
                groups.push((
                    (real.len()..real.len() + set.frames.len()).collect(),
                    times.clone(),
                ));
            }
            let mut firsts = Vec::new();
            for ((f, t), code) in set.frames.iter().zip(&times).zip(stored) {
                let iso = f.exif.iso.unwrap_or(100.0);
                let scene = radiance.map(|v| v * *t as f32);
                let first = real.len();
                if !temporal {
                    firsts.push(first);
                    real.push((Unit::Frame(code), iso));
                    scenes.push((scene, iso, false));
                    continue;
                }
                let mut prev = (code, &f.path);
                for r in set.repeats_of(f) {
                    let next = window(code_frame(r)?);
                    let pair = noise::checked_pair(&prev.0, &next, prev.1, &r.path)?;
                    real.push((Unit::Pair(pair), iso));
                    scenes.push((scene.clone(), iso, true));
                    prev = (next, &r.path);
                }
                if real.len() > first {
                    firsts.push(first);
                }
            }
            // A frame without repeats has no unit in a temporal check: no floor there.
            if firsts.len() == set.frames.len() {
                floor_groups.push((firsts, times));
            }
        }
        residualise(&mut real, &groups, &profile.response)?;
        let measured = FrameStats {
            floor,
            ..measure(&real, &profile.response)
        };
        Ok(Prepared {
            measured,
            groups,
            scenes,
            floor_groups,
        })
    }

    /// The floor moments of one side, `frame(i)` the codes of unit i's first render.
    fn floor_of<'a>(
        &self,
        frame: impl Fn(usize) -> &'a Image,
        response: &crate::sensor::profile::Response,
    ) -> floor::FloorMoments {
        let mut m = floor::FloorMoments::default();
        for (indices, times) in &self.floor_groups {
            let frames: Vec<&Image> = indices.iter().map(|&i| frame(i)).collect();
            m.add(&floor::moments(&frames, times, response));
        }
        m
    }

    /// The floor statistic of `profile`'s simulation, the mean over those of the first
    /// `replicates` replicates (the check's seeds) that have one (NaN where none has): only
    /// the frames the statistic reads are rendered.
    fn floor_value(
        &self,
        profile: &SensorProfile,
        opts: &OutputCheckOptions,
        replicates: usize,
    ) -> Result<f64> {
        let profile = &device(profile);
        let (mut sum, mut n) = (0.0, 0usize);
        for r in 0..replicates {
            let mut firsts: Vec<Option<Image>> = vec![None; self.scenes.len()];
            for &i in self.floor_groups.iter().flat_map(|g| &g.0) {
                let (scene, iso, _) = &self.scenes[i];
                let (realism, seed) = render(profile, opts, *iso, r, i)?;
                firsts[i] = Some(realism.apply(scene, seed(0)));
            }
            let empty = Image::new(0, 0);
            let v = self
                .floor_of(|i| firsts[i].as_ref().unwrap_or(&empty), &profile.response)
                .value();
            // A replicate with too few values under the toe has no statistic, as in the check.
            if v.is_finite() {
                sum += v;
                n += 1;
            }
        }
        Ok(if n == 0 { f64::NAN } else { sum / n as f64 })
    }
}

/// The check of `profile` on what `prep` read (`prep` made with the same response).
fn check_prepared(
    prep: &Prepared,
    profile: &SensorProfile,
    opts: &OutputCheckOptions,
) -> Result<OutputCheck> {
    let profile = &device(profile);
    let measured = &prep.measured;
    let sims = (0..opts.replicates)
        .map(|r| simulate(profile, prep, opts, r))
        .collect::<Result<Vec<_>>>()?;
    // The bins every replicate and the real frames have, weighted by the real pixels.
    let keys: Vec<(usize, usize, f64)> = measured
        .bins
        .iter()
        .filter(|b| b.var_code > 0.0 && b.correlation_ratio.is_finite())
        .map(|b| (b.channel, bin_of(b), b.pixels as f64))
        .filter(|&(c, k, _)| sims.iter().all(|s| s.bin(c, k).is_some()))
        .collect();
    let bins = keys
        .iter()
        .filter_map(|&(c, k, weight)| {
            let real = measured.bin(c, k)?;
            let sim: Vec<f64> = sims
                .iter()
                .filter_map(|s| s.bin(c, k).map(ln_var))
                .collect();
            Some(BinOffset {
                channel: c,
                linear: real.linear,
                dark: k < DARK_BINS,
                weight,
                measured: ln_var(real),
                simulated: sim.iter().sum::<f64>() / sim.len().max(1) as f64,
            })
        })
        .collect();
    Ok(OutputCheck {
        bins,
        ..compare(
            &values(measured, &keys),
            &sims.iter().map(|s| values(s, &keys)).collect::<Vec<_>>(),
        )
    })
}

/// `img` smoothed per channel by [`crate::data::ground_truth::gaussian_blur`] of width
/// [`SMOOTH_SIGMA`].
fn smooth(img: &Image) -> Image {
    let (w, h) = (img.width, img.height);
    let planes: Vec<Vec<f32>> = (0..3)
        .map(|c| {
            let plane: Vec<f32> = img.data.iter().skip(c).step_by(3).copied().collect();
            crate::data::ground_truth::gaussian_blur(&plane, w, h, SMOOTH_SIGMA)
        })
        .collect();
    Image::from_fn(w, h, |x, y| {
        let i = y * w + x;
        [planes[0][i], planes[1][i], planes[2][i]]
    })
}

mod consistency;
mod effects;
mod fit;
mod floor;
mod jpeg;
mod local_gain;
mod statistics;
use statistics::*;

pub use effects::{EffectFit, OUTPUT_EFFECTS, fit_output_effect, names, refusal};
pub use fit::{MAX_LEVEL_SCALE, NoiseFit, fit_noise_level};
pub use floor::{FloorFit, fit_floor, with_floor};
pub use jpeg::{JpegFit, fit_jpeg, folder_quality, with_jpeg};
pub use local_gain::{LocalGainFit, fit_local_gain, with_local_gain};

impl OutputCheck {
    /// Whether a channel's noise level or floor is a significant statistic (the profile's
    /// noise is too low or too high for the frames).
    pub fn level_off(&self) -> bool {
        LEVEL
            .iter()
            .chain(&FLOOR)
            .any(|&i| self.stats[i].significant)
    }

    /// The check as Markdown: one row per statistic, then what is named.
    pub fn markdown(&self) -> String {
        use std::fmt::Write as _;
        let mut s = format!(
            "| statistic | measured | simulated (mean ± sd, {} replicates) | z | significant | closed by |\n|---|---|---|---|---|---|\n",
            self.replicates
        );
        for st in &self.stats {
            let _ = writeln!(
                s,
                "| {} | {:.4} | {:.4} ± {:.4} | {:+.1} | {} | {} |",
                st.name,
                st.measured,
                st.sim_mean,
                st.sim_sd,
                st.z,
                if st.significant { "yes" } else { "no" },
                st.names
            );
        }
        let _ = writeln!(
            s,
            "\nGap (largest significant |z|; threshold {:.2}): {:.1}.\n\nNot tested by this check \
             (no statistic yet): sharpening halos, denoising, JPEG's ringing and chroma \
             subsampling.",
            self.threshold, self.gap
        );
        s
    }

    /// The floor statistic.
    pub fn floor_stat(&self) -> &OutputStat {
        &self.stats[FLOOR_STAT]
    }

    /// The blockiness statistic.
    pub fn block_stat(&self) -> &OutputStat {
        &self.stats[BLOCK_STAT]
    }

    /// The gap in the noise level and floor statistics alone (their largest |z|, significant
    /// or not): what the noise-level fit must shrink.
    pub fn level_gap(&self) -> f64 {
        LEVEL
            .iter()
            .chain(&FLOOR)
            .map(|&i| self.stats[i].z.abs())
            .filter(|z| z.is_finite())
            .fold(0.0, f64::max)
    }

    /// What the largest significant statistic names (None when nothing is significant).
    pub fn named(&self) -> Option<&OutputStat> {
        self.stats
            .iter()
            .filter(|s| s.significant)
            .max_by(|a, b| a.z.abs().total_cmp(&b.z.abs()))
    }
}
