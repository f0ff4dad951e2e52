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
//! set's other frames (`bracket_profile::cross_residuals`), real and simulated alike: the
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

use crate::data::bracket_profile::{self, CrossResidual, NoiseBin, Pair, Planes};
use crate::data::bracket_testset::{self, FIELD_GAMMA, Linearise};
use crate::data::brackets::{self, ScanOptions};
use crate::error::Result;
use crate::io::Image;
use crate::sensor::profile::SensorProfile;
use crate::sensor::realism::{NoiseModel, Realism, RealismOptions};
use std::path::Path;

/// The central window of `img` (`bracket_profile::window`, at most 640×480), the same for
/// every frame of a set.
fn window(img: Image) -> Image {
    let (x0, y0, w, h) = bracket_profile::window(&img);
    if (w, h) == (img.width, img.height) {
        return img;
    }
    Image::from_fn(w, h, |x, y| img.get(x0 + x, y0 + y))
}

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
    scenes: &[(Image, f64, bool)],
    groups: &Groups,
    opts: &OutputCheckOptions,
    r: usize,
) -> Result<FrameStats> {
    let mut units = scenes
        .iter()
        .enumerate()
        .map(|(j, (scene, iso, pair))| {
            let realism = Realism::new(
                profile,
                &RealismOptions {
                    iso: *iso,
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
            let seed = |k: u64| {
                crate::rng::mix64(opts.seed ^ crate::rng::mix64((r * 7919 + j) as u64) ^ k)
            };
            let a = realism.apply(scene, seed(0));
            let unit = if *pair {
                Unit::Pair(Pair::new(&a, &realism.apply(scene, seed(1 << 40))))
            } else {
                Unit::Frame(a)
            };
            Ok((unit, *iso))
        })
        .collect::<Result<Vec<_>>>()?;
    residualise(&mut units, groups, &profile.response)?;
    Ok(measure(&units, &profile.response))
}

/// The units of each set of single frames (indices into the units, relative exposure times).
type Groups = Vec<(Vec<usize>, Vec<f64>)>;

/// Each set's frames replaced by their residuals against the set's other frames
/// ([`bracket_profile::cross_residuals`]), on the real and on every simulated side alike.
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
        let residuals = bracket_profile::cross_residuals(&frames, times, response)?;
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
            .extend(bracket_profile::noise_bins(unit.planes(), *iso, response));
        let (cross, square, _) = bracket_profile::channel_moments(unit.planes());
        for k in 0..3 {
            s.cross[k] += cross[k];
            s.square[k] += square[k];
        }
    }
    s.bins = bracket_profile::merge_bins(&s.bins);
    s
}

fn bin_of(b: &NoiseBin) -> usize {
    ((b.code * bracket_profile::BINS as f64) as usize).min(bracket_profile::BINS - 1)
}

/// Code bins (of [`bracket_profile::BINS`]) under the noise-floor statistic's ceiling, 1/8.
const DARK_BINS: usize = bracket_profile::BINS / 8;

/// The statistics' values of `s` over the bins `keys` (channel, bin, weight), in the order of
/// [`STATS`]: per channel the weighted mean ln σ² (weights: the real frames' pixels) over the
/// bins from [`DARK_BINS`] up, the same under it (NaN where no bin is there), and the median
/// correlation ratio (as `calibrate brackets` takes it: a bin whose noise falls under the
/// 8-bit step has a ratio without bound); then the mean channel correlation.
fn values(s: &FrameStats, keys: &[(usize, usize, f64)]) -> Vec<f64> {
    let mut out = Vec::new();
    for c in 0..3 {
        let mut level = [(0.0, 0.0); 2];
        let mut ratios = Vec::new();
        for &(kc, kb, w) in keys.iter().filter(|k| k.0 == c) {
            let Some(b) = s.bins.iter().find(|b| b.channel == kc && bin_of(b) == kb) else {
                continue;
            };
            let l = &mut level[usize::from(kb < DARK_BINS)];
            l.0 += w * b.var_code.max(1e-12).ln();
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
    out
}

/// The check of `profile` on the bracket folder `dir`.
pub fn check(
    dir: &Path,
    profile: &SensorProfile,
    opts: &OutputCheckOptions,
) -> Result<OutputCheck> {
    check_scanned(brackets::scan(dir, &opts.scan)?, profile, opts)
}

/// [`check`] on sets already scanned with `opts.scan` (a run that reads the folder once:
/// [`brackets::FolderScan`]).
pub fn check_scanned(
    scan: brackets::BracketScan,
    profile: &SensorProfile,
    opts: &OutputCheckOptions,
) -> Result<OutputCheck> {
    if let Some(f) = scan
        .sets
        .iter()
        .flat_map(|s| &s.frames)
        .find(|f| f.kind == brackets::FrameKind::Dng)
    {
        return Err(crate::error::Error::layout(
            &f.path,
            "a DNG is linear raw, not the device's output: the device-output check reads \
             JPEG/PNG/TIFF frames",
        ));
    }
    let lin = Linearise::Curve(profile.response.clone());
    // The scene estimate is linear: rendered as it is, not read through the profile's source
    // curve (a measured profile's is the scene engine's display curve, which would darken
    // every simulated frame and compare the noise at other codes than the frames').
    let mut device = profile.clone();
    device.source_response = crate::sensor::profile::Response::Linear;
    let profile = &device;
    let temporal = scan.sets.iter().any(|s| !s.repeats.is_empty());
    // Per set: the real units with their ISO, and the scene at each unit's exposure (a pair:
    // rendered twice).
    let mut real: Vec<(Unit, f64)> = Vec::new();
    // Sets of single frames: the units' indices and relative exposure times.
    let mut groups: Groups = Vec::new();
    let mut scenes: Vec<(Image, f64, bool)> = Vec::new();
    for set in &scan.sets {
        let mut gamma = Vec::new();
        let mut stored = Vec::new();
        let mut times = Vec::new();
        for f in &set.frames {
            let code = window(bracket_testset::code_frame(f)?);
            let linear = bracket_testset::linearise(f, code.clone(), &lin);
            gamma.push(linear.map(|v| v.clamp(0.0, 1.0).powf(1.0 / FIELD_GAMMA)));
            stored.push(code);
            times.push(f.stop.exp2());
        }
        let radiance = smooth(&bracket_testset::hat_merge(
            &gamma,
            &stored,
            &times,
            FIELD_GAMMA,
        )?);
        if !temporal {
            groups.push((
                (real.len()..real.len() + set.frames.len()).collect(),
                times.clone(),
            ));
        }
        for ((f, t), code) in set.frames.iter().zip(&times).zip(stored) {
            let iso = f.exif.iso.unwrap_or(100.0);
            let scene = radiance.map(|v| v * *t as f32);
            if !temporal {
                real.push((Unit::Frame(code), iso));
                scenes.push((scene, iso, false));
                continue;
            }
            let mut prev = (code, &f.path);
            for r in set.repeats_of(f) {
                let next = window(bracket_testset::code_frame(r)?);
                let pair = bracket_profile::checked_pair(&prev.0, &next, prev.1, &r.path)?;
                real.push((Unit::Pair(pair), iso));
                scenes.push((scene.clone(), iso, true));
                prev = (next, &r.path);
            }
        }
    }
    residualise(&mut real, &groups, &profile.response)?;
    let measured = measure(&real, &profile.response);
    let sims = (0..opts.replicates)
        .map(|r| simulate(profile, &scenes, &groups, opts, r))
        .collect::<Result<Vec<_>>>()?;
    // The bins every replicate and the real frames have, weighted by the real pixels.
    let keys: Vec<(usize, usize, f64)> = measured
        .bins
        .iter()
        .filter(|b| b.var_code > 0.0 && b.correlation_ratio.is_finite())
        .map(|b| (b.channel, bin_of(b), b.pixels as f64))
        .filter(|&(c, k, _)| {
            sims.iter()
                .all(|s| s.bins.iter().any(|b| b.channel == c && bin_of(b) == k))
        })
        .collect();
    let ln_var = |s: &FrameStats, c: usize, k: usize| {
        s.bins
            .iter()
            .find(|b| b.channel == c && bin_of(b) == k)
            .map(|b| b.var_code.max(1e-12).ln())
    };
    let bins = keys
        .iter()
        .filter_map(|&(c, k, weight)| {
            let real = measured
                .bins
                .iter()
                .find(|b| b.channel == c && bin_of(b) == k)?;
            let sim: Vec<f64> = sims.iter().filter_map(|s| ln_var(s, c, k)).collect();
            Some(BinOffset {
                channel: c,
                linear: real.linear,
                dark: k < DARK_BINS,
                weight,
                measured: real.var_code.max(1e-12).ln(),
                simulated: sim.iter().sum::<f64>() / sim.len().max(1) as f64,
            })
        })
        .collect();
    Ok(OutputCheck {
        bins,
        ..compare(
            &values(&measured, &keys),
            &sims.iter().map(|s| values(s, &keys)).collect::<Vec<_>>(),
        )
    })
}

/// (name, what closes it, minimum effect) of each value of [`values`].
const STATS: [(&str, &str, f64); 10] = [
    (
        "R noise level (mean ln σ², codes from 1/8)",
        "noise a, b",
        0.1,
    ),
    (
        "R noise floor (mean ln σ², codes under 1/8)",
        "noise b",
        0.1,
    ),
    (
        "R spatial correlation (median low/high-order ratio)",
        "correlated_noise",
        0.05,
    ),
    (
        "G noise level (mean ln σ², codes from 1/8)",
        "noise a, b",
        0.1,
    ),
    (
        "G noise floor (mean ln σ², codes under 1/8)",
        "noise b",
        0.1,
    ),
    (
        "G spatial correlation (median low/high-order ratio)",
        "correlated_noise",
        0.05,
    ),
    (
        "B noise level (mean ln σ², codes from 1/8)",
        "noise a, b",
        0.1,
    ),
    (
        "B noise floor (mean ln σ², codes under 1/8)",
        "noise b",
        0.1,
    ),
    (
        "B spatial correlation (median low/high-order ratio)",
        "correlated_noise",
        0.05,
    ),
    (
        "channel correlation of the noise (mean of RG, GB, RB)",
        "channel_correlation",
        0.05,
    ),
];

fn compare(measured: &[f64], sims: &[Vec<f64>]) -> OutputCheck {
    let k = sims.len().max(1) as f64;
    let m = STATS.len() as f64;
    let threshold = (crate::stats::normal_quantile(1.0 - 0.05 / (2.0 * m))).max(3.0);
    let stats: Vec<OutputStat> = STATS
        .iter()
        .enumerate()
        .map(|(i, &(name, names, min_effect))| {
            let v: Vec<f64> = sims
                .iter()
                .map(|s| s[i])
                .filter(|x| x.is_finite())
                .collect();
            let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
            let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>()
                / (v.len().max(2) - 1) as f64)
                .sqrt()
                .max(1e-4);
            let z = (measured[i] - mean) / (sd * (1.0 + 1.0 / k).sqrt());
            let significant =
                z.abs() > threshold && (measured[i] - mean).abs() > min_effect && z.is_finite();
            OutputStat {
                name: name.into(),
                names,
                measured: measured[i],
                sim_mean: mean,
                sim_sd: sd,
                z,
                min_effect,
                significant,
            }
        })
        .collect();
    let gap = stats
        .iter()
        .filter(|s| s.significant)
        .map(|s| s.z.abs())
        .fold(0.0, f64::max);
    OutputCheck {
        stats,
        threshold,
        gap,
        replicates: sims.len(),
        bins: Vec::new(),
    }
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

/// Indices in [`STATS`] of the three channels' noise level and noise floor.
const LEVEL: [usize; 3] = [0, 3, 6];
const FLOOR: [usize; 3] = [1, 4, 7];
/// The fitted scale of a channel's noise stays within this factor of the measured one: a
/// larger gap is not a level error the fit should paper over.
const MAX_LEVEL_SCALE: f64 = 16.0;

/// What [`fit_noise_level`] found.
#[derive(Clone, Debug)]
pub struct NoiseFit {
    /// The profile with every ISO's a_c and b_c scaled by `scale[c]`, `floor[c]`·a_c added to
    /// b_c (before scaling) where a floor is fitted.
    pub profile: SensorProfile,
    pub scale: [f64; 3],
    /// The floor fitted per channel, as the linear signal whose shot noise equals it (None:
    /// the check found that channel's floor in line with its level).
    pub floor: [Option<f64>; 3],
    /// The check of `profile`.
    pub check: OutputCheck,
}

/// The noise level the check compares, fitted: every ISO's a and b of channel c scaled by
/// k_c so that the simulated frames' noise-level statistic (mean ln σ² of the codes from 1/8)
/// matches the real frames' (a secant on ln k: the first step assumes the statistic moves by
/// ln k, as it does for noise well above the 8-bit step; quantisation, clipping and a
/// response with a steep toe bend it). Then, in each channel whose noise floor (the codes
/// under 1/8) the check still finds significant at that level (more than a scale mends), a
/// floor f_c·a_c is added to b_c before the scaling (f_c a linear signal: the floor follows
/// each ISO's gain as the shot noise does), k_c and f_c fitted together to the level and the
/// floor bin by bin: each bin's simulated ln σ² moves with ln(k·(x + b/a + f)) at its linear
/// value x, so the two statistics' offsets give the next (k, f) in closed form (a bisection
/// on f), and a check of them the next offsets. `rounds` checks for each, `first` being the
/// check of `profile` itself; the round whose largest |measured − simulated| statistic
/// fitted is smallest wins, and the fit with floors only where that is the smaller. The
/// statistics are the ones the check takes (pairs, or each frame against the others'
/// merge): the noise the frames hold beyond what the profile's flat-region measurement gave,
/// whatever its source (JPEG processing, a read-noise floor the flat regions hid), is then in
/// the simulation.
pub fn fit_noise_level(
    scan: &brackets::BracketScan,
    profile: &SensorProfile,
    first: &OutputCheck,
    opts: &OutputCheckOptions,
    rounds: usize,
) -> Result<NoiseFit> {
    let fit = NoiseFitter {
        scan,
        profile,
        opts,
    };
    let level = fit.level(first, rounds)?;
    let floors = FLOOR.map(|i| level.check.stats[i].significant);
    if !floors.contains(&true) {
        return Ok(level);
    }
    let with_floors = fit.floors(&level, floors, rounds)?;
    Ok(
        if NoiseFitter::worst(&with_floors.check, floors) < NoiseFitter::worst(&level.check, floors)
        {
            with_floors
        } else {
            level
        },
    )
}

/// The two fits of [`fit_noise_level`].
struct NoiseFitter<'a> {
    scan: &'a brackets::BracketScan,
    profile: &'a SensorProfile,
    opts: &'a OutputCheckOptions,
}

/// Range of a fitted floor, as a linear signal.
const FLOOR_RANGE: (f64, f64) = (1e-7, 0.5);

impl NoiseFitter<'_> {
    fn off(c: &OutputCheck, i: usize) -> f64 {
        c.stats[i].measured - c.stats[i].sim_mean
    }

    /// The largest |measured − simulated| of the levels and of the floors `floors` marks.
    fn worst(c: &OutputCheck, floors: [bool; 3]) -> f64 {
        (0..3)
            .flat_map(|ch| [Some(LEVEL[ch]), floors[ch].then_some(FLOOR[ch])])
            .flatten()
            .map(|i| Self::off(c, i).abs())
            .fold(0.0, f64::max)
    }

    /// `profile` with `scale` and `floor`, its check, and how far it is off.
    fn try_fit(
        &self,
        scale: [f64; 3],
        floor: [Option<f64>; 3],
        floors: [bool; 3],
    ) -> Result<(f64, NoiseFit)> {
        let profile = scaled_noise(self.profile, scale, floor);
        let check = check_scanned(self.scan.clone(), &profile, self.opts)?;
        let worst = Self::worst(&check, floors);
        Ok((
            worst,
            NoiseFit {
                profile,
                scale,
                floor,
                check,
            },
        ))
    }

    /// The level alone: `rounds` secant steps on ln k from the profile (check `first`).
    fn level(&self, first: &OutputCheck, rounds: usize) -> Result<NoiseFit> {
        let limit = MAX_LEVEL_SCALE.ln();
        let mut ln_k = [0.0f64; 3];
        let mut prev: [Option<(f64, f64)>; 3] = [None; 3];
        let mut d = LEVEL.map(|i| Self::off(first, i));
        let mut best = (
            Self::worst(first, [false; 3]),
            NoiseFit {
                profile: self.profile.clone(),
                scale: [1.0; 3],
                floor: [None; 3],
                check: first.clone(),
            },
        );
        for _ in 0..rounds {
            for c in 0..3 {
                if !d[c].is_finite() {
                    continue;
                }
                // The statistic's slope in ln k from the last two rounds, else 1.
                let slope = prev[c]
                    .filter(|&(x, _)| (ln_k[c] - x).abs() > 1e-9)
                    .map_or(1.0, |(x, e)| ((e - d[c]) / (ln_k[c] - x)).clamp(0.1, 10.0));
                prev[c] = Some((ln_k[c], d[c]));
                ln_k[c] = (ln_k[c] + d[c] / slope).clamp(-limit, limit);
            }
            let tried = self.try_fit(ln_k.map(f64::exp), [None; 3], [false; 3])?;
            d = LEVEL.map(|i| Self::off(&tried.1.check, i));
            if tried.0 < best.0 {
                best = tried;
            }
        }
        Ok(best.1)
    }

    /// Level and floor together in the channels `floors` marks, from `from` (the level's
    /// fit): `rounds` rounds of the bin model's closed form, each checked.
    fn floors(&self, from: &NoiseFit, floors: [bool; 3], rounds: usize) -> Result<NoiseFit> {
        // Each channel's own floor b/a in the profile, as a linear signal.
        let own = [0, 1, 2].map(|c| {
            let r: Vec<f64> = self
                .profile
                .noise
                .iter()
                .map(|n| n.b[c] / n.a[c].max(1e-30))
                .collect();
            r.iter().sum::<f64>() / r.len().max(1) as f64
        });
        let mut scale = from.scale;
        let mut floor = [0.0f64; 3];
        let mut check = from.check.clone();
        let mut best: Option<(f64, NoiseFit)> = None;
        for _ in 0..rounds {
            for c in (0..3).filter(|&c| floors[c]) {
                let bins: Vec<&BinOffset> = check.bins.iter().filter(|b| b.channel == c).collect();
                (scale[c], floor[c]) = model_step(&bins, own[c], scale[c], floor[c]);
            }
            let f = [0, 1, 2].map(|c| floors[c].then_some(floor[c]));
            let tried = self.try_fit(scale, f, floors)?;
            check = tried.1.check.clone();
            if best.as_ref().is_none_or(|b| tried.0 < b.0) {
                best = Some(tried);
            }
        }
        Ok(best.map_or_else(|| from.clone(), |b| b.1))
    }
}

/// The next (k, f) of one channel from its bins, checked at (k, f): each bin's simulated
/// ln σ² taken to move by ln(k'·(x + own + f')) − ln(k·(x + own + f)), f' is the floor whose
/// predicted offset of the dark bins from the light ones matches the real frames' (a
/// bisection on ln f', the offset growing with f'), and k' the scale that then matches the
/// light bins (the level). Pixel-weighted means, as the statistics take them.
fn model_step(bins: &[&BinOffset], own: f64, k: f64, f: f64) -> (f64, f64) {
    let mean = |dark: bool, v: &dyn Fn(&BinOffset) -> f64| {
        let (s, w) = bins
            .iter()
            .filter(|b| b.dark == dark)
            .fold((0.0, 0.0), |(s, w), b| (s + b.weight * v(b), w + b.weight));
        if w > 0.0 { s / w } else { f64::NAN }
    };
    let gain = |g: f64| move |b: &BinOffset| ((b.linear + own + g) / (b.linear + own + f)).ln();
    let off = |b: &BinOffset| b.measured - b.simulated;
    let want = mean(true, &off) - mean(false, &off);
    let shape = |g: f64| mean(true, &gain(g)) - mean(false, &gain(g));
    if !want.is_finite() || !shape(f).is_finite() {
        return (k, f);
    }
    let (mut lo, mut hi) = (FLOOR_RANGE.0.ln(), FLOOR_RANGE.1.ln());
    let next = if shape(0.0) >= want {
        0.0
    } else if shape(hi.exp()) <= want {
        hi.exp()
    } else {
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if shape(mid.exp()) < want {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        (0.5 * (lo + hi)).exp()
    };
    let ln_k = mean(false, &off) - mean(false, &gain(next));
    let limit = MAX_LEVEL_SCALE.ln();
    ((k.ln() + ln_k).clamp(-limit, limit).exp(), next)
}

/// `profile` with `floor[c]`·a added to every ISO's b of channel c where a floor is given,
/// then that channel's a and b multiplied by `k[c]`.
fn scaled_noise(profile: &SensorProfile, k: [f64; 3], floor: [Option<f64>; 3]) -> SensorProfile {
    let mut p = profile.clone();
    for row in &mut p.noise {
        for c in 0..3 {
            row.b[c] = k[c] * (row.b[c] + floor[c].unwrap_or(0.0) * row.a[c]);
            row.a[c] *= k[c];
        }
        // The standard errors were the flat-region fit's; they do not describe the scaled one.
        row.a_stderr = None;
        row.b_stderr = None;
    }
    let floors = if floor.iter().any(Option::is_some) {
        let f = floor.map(|f| f.map_or("none".to_string(), |f| format!("{f:.3e}")));
        format!(
            ", with a floor of the shot noise at linear ({}, {}, {}) added to b first to match \
             their noise under code 1/8",
            f[0], f[1], f[2]
        )
    } else {
        String::new()
    };
    p.provenance.noise = format!(
        "{}; scaled by ({:.3}, {:.3}, {:.3}) per channel to match the frames' noise level on \
         their cross-frame residuals (the device-output check's statistic){floors}",
        profile.provenance.noise, k[0], k[1], k[2]
    );
    p
}

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
             (no statistic yet): local or scene-dependent tone mapping, sharpening halos, \
             compression artefacts.",
            self.threshold, self.gap
        );
        s
    }

    /// What the largest significant statistic names (None when nothing is significant).
    pub fn named(&self) -> Option<&OutputStat> {
        self.stats
            .iter()
            .filter(|s| s.significant)
            .max_by(|a, b| a.z.abs().total_cmp(&b.z.abs()))
    }
}
