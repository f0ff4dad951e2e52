//! The loop's noise-level step. The profile's noise is measured on the calibration frames'
//! flat regions; the device-output check compares the noise the frames hold against the
//! other frames of their set with what the profile simulates there, over the codes from 1/8
//! (the level) and under it (the floor, where a read-noise floor b sets σ²). Where either
//! differs significantly for the last noise step, the same profile with each channel's noise
//! scaled, and a floor added where the floor is off, until the check's statistics match
//! (`output::fit_noise_level`) is one more step: the missing effect named, fitted,
//! and its gap shown closing.

use super::{Checked, LoopOptions, check_options, stage};
use crate::capture::output;
use crate::capture::scan::{FolderScan, ScanOptions};
use crate::error::Result;
use crate::sensor::profile::SensorProfile;
use std::path::{Path, PathBuf};

/// Checks the fit may take for the level, and as many again for level and floor together
/// (`output::fit_noise_level`).
const ROUNDS: usize = 4;

/// The fitted step's profile, its per-channel scale and the check's gap before and after.
pub(super) struct Level {
    pub profile: PathBuf,
    pub scale: [f64; 3],
    /// Per channel the floor added to b, as the linear signal whose shot noise equals it.
    pub floor: [Option<f64>; 3],
    /// Per ISO the read-noise floor b (R, G, B) before the fit and after it.
    pub b: Vec<(f64, [f64; 3], [f64; 3])>,
    pub gap: (f64, f64),
}

/// `profiles/level.toml` where the check of `last_noise` (the last noise step's profile) finds
/// the frames' noise level off; `None` where it does not. Fitted on every run (deterministic:
/// a rerun writes the same profile). Also the checks it made, for the steps' own.
pub(super) fn level_step(
    opts: &LoopOptions,
    folder: &FolderScan,
    cal_scan: &ScanOptions,
    last_noise: &Path,
    profiles: &Path,
) -> Result<(Option<Level>, Checked)> {
    let profile = SensorProfile::load(last_noise)?;
    let check = check_options(cal_scan, true);
    let scan = folder.select(cal_scan)?;
    let before = output::check_scanned(scan.clone(), &profile, &check)?;
    let gap = before.gap;
    let mut checked = vec![(last_noise.to_path_buf(), true, before)];
    if !checked[0].2.level_off() {
        return Ok((None, checked));
    }
    stage(
        opts,
        "fitting the noise level and floor the frames hold against each other",
    );
    let fit = output::fit_noise_level(&scan, &profile, &checked[0].2, &check, ROUNDS)?;
    let path = profiles.join("level.toml");
    fit.profile.save(&path)?;
    let level = Level {
        profile: path.clone(),
        scale: fit.scale,
        floor: fit.floor,
        b: profile
            .noise
            .iter()
            .zip(&fit.profile.noise)
            .map(|(before, after)| (before.iso, before.b, after.b))
            .collect(),
        gap: (gap, fit.check.gap),
    };
    checked.push((path, true, fit.check));
    Ok((Some(level), checked))
}
