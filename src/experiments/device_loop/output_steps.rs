//! The loop's output-domain steps. The device-output check reads what the device's processing
//! does to its frames beyond noise: the radiance → code map under the toe (a black point that
//! crushes the shadows, the catalogue's `floor`) and JPEG's 8×8 blocks in the frames'
//! residuals (`jpeg`). Each one the check of the last step names is fitted on top of it
//! (`output::fit_output_effect`: the floor by a bisection on its threshold, JPEG's quality
//! read from the frames' own quantisation tables) and is one more step — handed on only where
//! the fit stays inside its range and makes its own gap (its statistic's |z|) smaller; the
//! report says why any other is not a step.

use super::{Checked, LoopOptions, check_options, stage};
use crate::capture::output::{self, OUTPUT_EFFECTS};
use crate::capture::scan::{FolderScan, ScanOptions};
use crate::error::Result;
use crate::sensor::profile::SensorProfile;
use std::path::{Path, PathBuf};

/// A fitted output step: its effect, its profile and the fitted parameter in words.
pub(super) struct Fitted {
    pub id: &'static str,
    pub profile: PathBuf,
    pub fitted: String,
}

/// `profiles/<id>.toml` for each output-domain effect the check names on the profile before
/// it (starting from `last_noise`) whose fit closes its gap; the report's sentences on every
/// effect; the checks made.
pub(super) fn output_steps(
    opts: &LoopOptions,
    folder: &FolderScan,
    cal_scan: &ScanOptions,
    last_noise: &Path,
    profiles: &Path,
) -> Result<(Vec<Fitted>, String, Checked)> {
    let mut profile = SensorProfile::load(last_noise)?;
    let options = check_options(cal_scan, true);
    let scan = folder.select(cal_scan)?;
    let mut check = output::check_scanned(scan.clone(), &profile, &options)?;
    let mut checked = vec![(last_noise.to_path_buf(), true, check.clone())];
    let (mut steps, mut notes) = (Vec::new(), String::new());
    for id in OUTPUT_EFFECTS {
        let Some(stat) = check.stats.iter().find(|s| s.names == id) else {
            continue;
        };
        let stat_text = format!(
            "{}: the frames {:+.3}, the last step's simulation {:+.3} ± {:.3}",
            stat.name, stat.measured, stat.sim_mean, stat.sim_sd
        );
        if !output::names(&check, id) {
            notes.push_str(&format!("`{id}`: {stat_text}: in line, no step.\n\n"));
            continue;
        }
        stage(opts, &format!("fitting `{id}` to the calibration frames"));
        let fit = match output::fit_output_effect(id, &scan, &profile, &check, &options) {
            Ok(f) => f,
            Err(e) => {
                let why = output::refusal(id, e)?;
                notes.push_str(&format!(
                    "`{id}`: {stat_text}; not fitted: {why}. No step.\n\n"
                ));
                continue;
            }
        };
        let text = fit.text(&check);
        if !fit.closes(&check) {
            let why = if fit.at_bound {
                "the fit reached its bound"
            } else {
                "the fit did not make its gap smaller"
            };
            notes.push_str(&format!(
                "`{id}`: {stat_text}; {text}: {why}, not a step.\n\n"
            ));
            continue;
        }
        let path = profiles.join(format!("{id}.toml"));
        fit.profile.save(&path)?;
        notes.push_str(&format!(
            "`{id}`: {stat_text}; {text}: a step of the loop (`profiles/{id}.toml`).\n\n"
        ));
        checked.push((path.clone(), true, fit.check.clone()));
        steps.push(Fitted {
            id,
            profile: path,
            fitted: fit.fitted,
        });
        profile = fit.profile;
        check = fit.check;
    }
    Ok((steps, notes, checked))
}
