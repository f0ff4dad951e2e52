//! `hdrsynth calibrate dng --out PROFILE FILE.dng...`: a sensor profile's colour, levels and
//! noise per ISO from DNG tags (`sensor::dng::profile`, docs/sensor.md).

use crate::sensor::dng::profile::{DngOptions, calibrate_dng};
use std::path::PathBuf;

#[derive(clap::Args, Clone, Debug)]
pub struct Args {
    /// DNG files of one camera model, one per ISO (only their tags are read: image data may
    /// be absent). The first gives the colour and the levels.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Sensor profile to write: an existing one keeps its name, kind, responses and effects
    /// and gets colour, levels, noise and their provenance replaced; a new one is created.
    #[arg(long)]
    pub out: PathBuf,
    /// Name of a new profile (default: the camera as the DNG names it).
    #[arg(long)]
    pub name: Option<String>,
    /// Do not read noise (for DNGs without NoiseProfile or ISO): the profile has no noise.
    #[arg(long)]
    pub no_noise: bool,
}

pub fn run(args: &Args) -> anyhow::Result<String> {
    let cal = calibrate_dng(&DngOptions {
        files: args.files.clone(),
        out: args.out.clone(),
        name: args.name.clone(),
        noise: !args.no_noise,
    })?;
    Ok(cal.report())
}
