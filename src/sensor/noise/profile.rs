//! A noise calibration written into a sensor profile (`hdrsynth calibrate noise`): fit
//! σ² = a·I + b per ISO and channel from a capture set (`sensor::noise`, docs/noise.md) and write
//! it into a SensorProfile, with a photon-transfer-curve plot. Nothing is written when anything
//! fails.

use super::{self as noise, CalibrateOptions, LevelSource};
use crate::error::{Error, Result};
use crate::sensor::captures::{BurstKind, CaptureSet};
use crate::sensor::profile::{Levels, SensorProfile};
use std::path::{Path, PathBuf};

/// What to calibrate from and where to write it.
#[derive(Clone, Debug)]
pub struct NoiseProfileOptions {
    /// Capture-set directory (or its captures.toml) with dark and flat bursts.
    pub captures: PathBuf,
    /// Sensor profile to write: an existing one gets its noise and provenance.noise replaced;
    /// a new one is created (kind measured, levels from the capture set, no colour).
    pub out: PathBuf,
    /// Photon-transfer-curve plot (PNG); default: next to the profile, <profile>.ptc.png.
    pub plot: Option<PathBuf>,
    /// White level in DN, overriding [sensor].white_level.
    pub white_level: Option<f64>,
    /// Black level in DN, overriding [sensor].black_level and the dark-frame estimate.
    pub black_level: Option<f64>,
}

/// Default plot path: the profile's path with extension `.ptc.png`.
pub fn default_plot_path(profile: &Path) -> PathBuf {
    profile.with_extension("ptc.png")
}

/// Run the calibration and write the profile and its plot; returns the report text.
pub fn calibrate_noise_profile(args: &NoiseProfileOptions) -> Result<String> {
    let set = CaptureSet::load(&args.captures)?;
    let existing = SensorProfile::load_existing(&args.out)?;
    let sensor = &set.manifest.sensor;
    let mut opts = CalibrateOptions {
        white_level: args.white_level,
        black_level: args.black_level,
    };
    let mut notes = Vec::new();
    if let Some(p) = &existing {
        if opts.white_level.is_none() && sensor.white_level.is_none() {
            opts.white_level = Some(p.levels.white_level);
            notes.push(format!(
                "white level {} DN taken from the existing profile {}",
                p.levels.white_level,
                args.out.display()
            ));
        }
        let has_dark = set.bursts().iter().any(|b| b.kind == BurstKind::Dark);
        if opts.black_level.is_none() && sensor.black_level.is_none() && !has_dark {
            opts.black_level = Some(p.levels.black_level);
            notes.push(format!(
                "black level {} DN taken from the existing profile {}",
                p.levels.black_level,
                args.out.display()
            ));
        }
    }
    let cal = noise::calibrate(&set, &opts)?;

    let profile = match existing {
        Some(mut p) => {
            // The profile's own levels define its normalised convention.
            p.noise = cal.to_noise(p.levels.white_level, p.levels.black_level);
            p.provenance.noise = cal.provenance();
            p
        }
        None => {
            let name = match &sensor.name {
                Some(n) => n.clone(),
                None => {
                    let n = set
                        .dir
                        .canonicalize()
                        .ok()
                        .and_then(|d| d.file_name().map(|f| f.to_string_lossy().into_owned()))
                        .unwrap_or_else(|| "unnamed".into());
                    notes.push(format!(
                        "no [sensor].name in the capture set: profile named '{n}' after its directory"
                    ));
                    n
                }
            };
            let white_src = match cal.white_source {
                LevelSource::Override => "--white-level".to_string(),
                _ => format!("[sensor].white_level of {}", set.manifest_path.display()),
            };
            let black_src = match cal.black_source {
                LevelSource::Override => "--black-level".to_string(),
                LevelSource::Declared => {
                    format!("[sensor].black_level of {}", set.manifest_path.display())
                }
                LevelSource::EstimatedFromDark => format!(
                    "estimated from the dark bursts of {} (median of outlier-clipped frame means)",
                    set.dir.display()
                ),
            };
            let levels = Levels {
                black_level: cal.black_level,
                white_level: cal.white_level,
                bit_depth: noise::bits_for_white(cal.white_level),
            };
            let levels_source = format!(
                "white level {} DN from {white_src}; black level {} DN from {black_src}; bit depth \
                 ceil(log2(white + 1))",
                cal.white_level, cal.black_level
            );
            SensorProfile::from_noise(
                &name,
                levels,
                &levels_source,
                cal.to_noise(cal.white_level, cal.black_level),
                &cal.provenance(),
            )
        }
    };
    profile
        .validate()
        .map_err(|m| Error::config(&args.out, m))?;

    let plot = args
        .plot
        .clone()
        .unwrap_or_else(|| default_plot_path(&args.out));
    let mut report = cal.report(profile.levels.white_level, profile.levels.black_level);
    for n in notes {
        report.push_str(&format!("note: {n}\n"));
    }
    cal.write_ptc_plot(&plot)?;
    profile.save(&args.out)?;
    report.push_str(&format!(
        "wrote {} (noise at {} ISO(s)) and the photon-transfer plot {}\n",
        args.out.display(),
        profile.noise.len(),
        plot.display()
    ));
    Ok(report)
}
