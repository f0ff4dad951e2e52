//! The loop's noise-level step. The profile's noise is measured on the calibration frames'
//! flat regions; the device-output check compares the noise the frames hold against the
//! other frames of their set with what the profile simulates there, over the codes from 1/8
//! (the level) and under it (the floor, where a read-noise floor b sets σ²). Where either
//! differs significantly for the last noise step, the same profile with each channel's noise
//! scaled, and a floor added where the floor is off, until the check's statistics match
//! (`output::fit_noise_level`) is one more step: the missing effect named, fitted,
//! and its gap shown closing. A fit that reaches its bound or leaves its own statistics' gap
//! as large is said so in the report and is not a step.

use super::{Checked, LoopOptions, check_options, stage};
use crate::capture::output::{self, MAX_LEVEL_SCALE};
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

/// `profiles/level.toml` where the check of `start` (the last noise step's profile, or the
/// floor step's) finds the frames' noise level off and the fit makes its own gap (the level
/// and floor statistics' largest |z|) smaller without reaching its bound; `None` otherwise, with why in the report's sentence. `checked`
/// holds the check of `start` (made by the floor step); the level's fit is added to it.
pub(super) fn level_step(
    opts: &LoopOptions,
    folder: &FolderScan,
    cal_scan: &ScanOptions,
    start: &Path,
    profiles: &Path,
    checked: &mut Checked,
) -> Result<(Option<Level>, String)> {
    let profile = SensorProfile::load(start)?;
    let check = check_options(cal_scan, true);
    let scan = folder.select(cal_scan)?;
    let before = match checked.iter().find(|(p, noise, _)| p == start && *noise) {
        Some((_, _, c)) => c.clone(),
        None => {
            let c = output::check_scanned(scan.clone(), &profile, &check)?;
            checked.push((start.to_path_buf(), true, c.clone()));
            c
        }
    };
    let gap = before.gap;
    if !before.level_off() {
        let note = "The device-output check finds the frames' noise level and floor as the last \
                    step simulates them: no noise-level step.\n\n";
        return Ok((None, note.into()));
    }
    stage(
        opts,
        "fitting the noise level and floor the frames hold against each other",
    );
    let fit = output::fit_noise_level(&scan, &profile, &before, &check, ROUNDS)?;
    let at_bound = fit
        .scale
        .iter()
        .any(|k| k.ln().abs() >= MAX_LEVEL_SCALE.ln() - 1e-9);
    let own = (before.level_gap(), fit.check.level_gap());
    if at_bound || own.1 >= own.0 {
        let why = if at_bound {
            format!("a channel's scale reached the fit's bound ×{MAX_LEVEL_SCALE} or its inverse")
        } else {
            "the fit did not make the gap smaller".to_string()
        };
        let note = format!(
            "The device-output check finds the frames' noise level or floor off the last step's \
             simulation (their gap {:.1}, the check's {gap:.1}); the fitted scale ({:.3}, {:.3}, \
             {:.3}) gives {:.1} and {:.1}: {why}, not a step.\n\n",
            own.0, fit.scale[0], fit.scale[1], fit.scale[2], own.1, fit.check.gap
        );
        return Ok((None, note));
    }
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
    let note = level.note();
    checked.push((path, true, fit.check));
    Ok((Some(level), note))
}

impl Level {
    /// The report's sentence on the step.
    fn note(&self) -> String {
        let floor = if self.floor.iter().any(Option::is_some) {
            let b = |v: [f64; 3]| format!("{:.2e}, {:.2e}, {:.2e}", v[0], v[1], v[2]);
            let per_iso: Vec<String> = self
                .b
                .iter()
                .map(|(iso, before, after)| {
                    format!("{} at ISO {iso} (was {})", b(*after), b(*before))
                })
                .collect();
            format!(
                ", and, where the floor (codes under 1/8) was still off, a read-noise floor \
                 fitted into b: b = {}",
                per_iso.join("; ")
            )
        } else {
            String::new()
        };
        format!(
            "The device-output check finds the frames' noise level or floor off the last \
             step's simulation (gap {:.1}): the same profile with a, b scaled by {:.3}, {:.3}, \
             {:.3} (R, G, B){floor}, is a step of the loop (gap {:.1} after the fit; \
             `profiles/level.toml`).\n\n",
            self.gap.0, self.scale[0], self.scale[1], self.scale[2], self.gap.1
        )
    }
}
