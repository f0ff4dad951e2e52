//! The loop's floor step. The device-output check reads the radiance → code map under the toe
//! from the calibration frames that see those pixels at mid codes; where the frames' codes
//! there are significantly under the last noise step's simulation (a device whose processing
//! crushes its shadows), the same profile with the catalogue's `floor` fitted to them
//! (`output::fit_floor`) is one more step — handed on only where the fit stays inside its
//! range and makes the check's gap smaller.

use super::{Checked, LoopOptions, check_options, stage};
use crate::capture::output;
use crate::capture::scan::{FolderScan, ScanOptions};
use crate::error::Result;
use crate::sensor::profile::SensorProfile;
use std::path::{Path, PathBuf};

/// The fitted step's profile, its threshold and the check's gap before and after.
pub(super) struct Floor {
    pub profile: PathBuf,
    pub threshold: f64,
}

/// `profiles/floor.toml` where the check of `last_noise` finds the frames' codes under the
/// toe off and the fit closes it; `None` otherwise. With the report's sentence on it and the
/// checks it made.
pub(super) fn floor_step(
    opts: &LoopOptions,
    folder: &FolderScan,
    cal_scan: &ScanOptions,
    last_noise: &Path,
    profiles: &Path,
) -> Result<(Option<Floor>, String, Checked)> {
    let profile = SensorProfile::load(last_noise)?;
    let check = check_options(cal_scan, true);
    let scan = folder.select(cal_scan)?;
    let before = output::check_scanned(scan.clone(), &profile, &check)?;
    let stat = before.floor_stat().clone();
    let gap = before.gap;
    let mut checked = vec![(last_noise.to_path_buf(), true, before)];
    let stat_text = format!(
        "the frames' codes under code 16/255 are {:+.2} codes from what a longer frame predicts, \
         the last noise step's simulation {:+.2} ± {:.2}",
        stat.measured, stat.sim_mean, stat.sim_sd
    );
    if !stat.significant {
        let note = format!("Output floor: {stat_text}: in line, no floor step.\n\n");
        return Ok((None, note, checked));
    }
    stage(opts, "fitting the output floor the frames hold under the toe");
    let fit = match output::fit_floor(&scan, &profile, &checked[0].2, &check) {
        Ok(f) => f,
        Err(e) => {
            let why = output::floor_refusal(e)?;
            let note = format!("Output floor: {stat_text}; not fitted: {why}. No floor step.\n\n");
            return Ok((None, note, checked));
        }
    };
    let after = fit.check.floor_stat();
    let fitted = format!(
        "the floor fitted at {:.3e} of white simulates {:+.2} there; the check's gap {gap:.1} → \
         {:.1}",
        fit.threshold, after.sim_mean, fit.check.gap
    );
    if fit.at_bound || fit.check.gap >= gap {
        let why = if fit.at_bound {
            "the fit reached its bound without closing the gap"
        } else {
            "the fit did not make the gap smaller"
        };
        let note = format!("Output floor: {stat_text}; {fitted}: {why}, not a step.\n\n");
        return Ok((None, note, checked));
    }
    let path = profiles.join("floor.toml");
    fit.profile.save(&path)?;
    let note = format!(
        "Output floor: {stat_text}; {fitted}: a step of the loop (`profiles/floor.toml`).\n\n"
    );
    checked.push((path.clone(), true, fit.check));
    Ok((
        Some(Floor {
            profile: path,
            threshold: fit.threshold,
        }),
        note,
        checked,
    ))
}
