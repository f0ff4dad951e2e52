//! `hdrsynth calibrate brackets DIR --out PROFILE`: a device profile in the device's output
//! domain from its bracketed frames (`capture::profile`, docs/your_device.md).

use crate::capture::linearise::{ResponseChoice, ResponseSpec};
use crate::capture::profile::{BracketProfileOptions, calibrate_brackets};
use crate::capture::scan::{Region, ScanOptions};
use std::path::PathBuf;

#[derive(clap::Args, Clone, Debug)]
pub struct Args {
    /// A folder of bracketed JPEG/PNG/TIFF frames of the device (sets by sub-folder or capture
    /// time, exposures from EXIF or a sidecar, as `testset --brackets` reads them).
    pub dir: PathBuf,
    /// Sensor profile to write: an existing one keeps its name, kind, colour, levels and
    /// effects and gets its response and the measured ISOs' noise replaced.
    #[arg(long)]
    pub out: PathBuf,
    /// Name of a new profile.
    #[arg(long)]
    pub name: Option<String>,
    /// The frames' response: debevec (default: one curve for the three channels),
    /// debevec-per-channel or robertson, estimated from the brackets, or a declared srgb,
    /// linear or gamma:G.
    #[arg(long)]
    pub response: Option<ResponseSpec>,
    /// Declared EV steps in capture order, for frames without EXIF or sidecar.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub declared_evs: Option<Vec<f64>>,
    /// Largest gap between capture times within one set, seconds.
    #[arg(long, default_value_t = ScanOptions::default().max_gap_s)]
    pub max_gap: f64,
    /// Read only this part of every frame: left, right, top, bottom (halves of the upright
    /// frame, split at ⌊w/2⌋ or ⌊h/2⌋) or x,y,w,h in pixels.
    #[arg(long)]
    pub region: Option<Region>,
    /// Write the measured spatial correlation of the noise into the profile (the catalogue's
    /// correlated_noise, a and b raised to the per-pixel variance) when its lag-1 correlation
    /// reaches 0.02; otherwise the noise is white.
    #[arg(long)]
    pub correlated: bool,
    /// Frames of one exposure within a set are repeated captures of a static scene on a
    /// tripod (a burst): the noise is measured from the differences of repeated frames
    /// (temporal noise) instead of from each frame's flat regions. Only capture-time gaps and
    /// sub-folders then split sets.
    #[arg(long)]
    pub repeats: bool,
}

pub fn run(args: &Args) -> anyhow::Result<String> {
    let cal = calibrate_brackets(
        &args.dir,
        &BracketProfileOptions {
            scan: ScanOptions {
                evs: args.declared_evs.clone(),
                max_gap_s: args.max_gap,
                region: args.region,
                sets: Vec::new(),
                repeats: args.repeats,
            },
            response: ResponseChoice::new(None, args.response.as_ref())?,
            out: args.out.clone(),
            name: args.name.clone(),
            correlated: args.correlated,
        },
    )?;
    Ok(cal.report(&args.out))
}
