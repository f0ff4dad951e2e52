//! `hdrsynth calibrate brackets DIR --out PROFILE`: a device profile in the device's output
//! domain from its bracketed frames (`capture::profile`, docs/your_device.md).

use crate::capture::linearise::{ResponseChoice, ResponseSpec};
use crate::capture::profile::{BracketProfileOptions, calibrate_brackets};
use crate::cli::scan::{RegionArg, ScanArgs};
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
    /// Write the measured spatial correlation of the noise into the profile (the catalogue's
    /// correlated_noise, a and b raised to the per-pixel variance) when its lag-1 correlation
    /// reaches 0.02; otherwise the noise is white.
    #[arg(long)]
    pub correlated: bool,
    #[command(flatten)]
    pub scan: ScanArgs,
    #[command(flatten)]
    pub region: RegionArg,
}

pub fn run(args: &Args) -> anyhow::Result<String> {
    let cal = calibrate_brackets(
        &args.dir,
        &BracketProfileOptions {
            scan: args.scan.options(args.region.region),
            response: ResponseChoice::new(None, args.response.as_ref())?,
            out: args.out.clone(),
            name: args.name.clone(),
            correlated: args.correlated,
        },
    )?;
    Ok(cal.report(&args.out))
}
