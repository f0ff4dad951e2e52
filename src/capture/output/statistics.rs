//! The device-output check's statistics: each one's name, what would close it and its
//! minimum effect, in the order [`super::values`] gives them, and the comparison of the
//! frames' values with the simulated replicates'.

use super::{OutputCheck, OutputStat};

/// (name, what closes it, minimum effect) of each value of [`super::values`].
pub(super) const STATS: [(&str, &str, f64); 17] = [
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
    (
        "floor: mean code − the code a longer frame predicts there, codes 4–16/255 (×255)",
        "floor",
        // Half the 8-bit step: rounding alone moves a mean code by at most that.
        0.5,
    ),
    (
        "blockiness: neighbour differences across the strongest 8-pixel phase over the others (%)",
        "jpeg",
        1.0,
    ),
    (
        "disagreement between frames, 4-px blocks (½ ln of block-mean power over the noise's)",
        crate::sensor::effects::local_gain::ID,
        0.1,
    ),
    (
        "disagreement between frames, 16-px blocks (½ ln of block-mean power over the noise's)",
        crate::sensor::effects::local_gain::ID,
        0.1,
    ),
    (
        "disagreement between frames, 4-px blocks of codes 3–64",
        BY_LEVEL_NAMES,
        0.1,
    ),
    (
        "disagreement between frames, 4-px blocks of codes 64–192",
        BY_LEVEL_NAMES,
        0.1,
    ),
    (
        "disagreement between frames, 4-px blocks of codes 192–250",
        BY_LEVEL_NAMES,
        0.1,
    ),
];

/// What would close a disagreement in one code band over the others: nothing the catalogue
/// holds (`local_gain` is the same at every code).
const BY_LEVEL_NAMES: &str =
    "none in the catalogue (a tone curve that changes with the content, e.g. near clipping)";

pub(super) fn compare(measured: &[f64], sims: &[Vec<f64>]) -> OutputCheck {
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
            let significant = z.abs() > threshold
                && (measured[i] - mean).abs() > min_effect
                && z.is_finite()
                && (z > 0.0 || !DISAGREEMENT.contains(&i));
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

/// Indices in [`STATS`] of the three channels' noise level and noise floor.
pub(super) const LEVEL: [usize; 3] = [0, 3, 6];
pub(super) const FLOOR: [usize; 3] = [1, 4, 7];

/// Index in [`STATS`] of the floor statistic, and of the blockiness.
pub(super) const FLOOR_STAT: usize = 10;
pub(super) const BLOCK_STAT: usize = 11;

/// Indices in [`STATS`] of the disagreement statistics: one-sided. The scene estimate is
/// smoothed, and on a textured scene that alone raises the simulated value (tested: a textured
/// bracket's own profile, 16 px, −0.11); only frames that disagree more than their simulation
/// are named.
pub(super) const DISAGREEMENT: [usize; 5] = [12, 13, 14, 15, 16];
/// The disagreement statistics over every block, at 4 and 16 pixels (`local_gain`'s).
pub(super) const POOLED: [usize; 2] = [12, 13];
