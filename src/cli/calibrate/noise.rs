//! `hdrsynth calibrate noise CAPTURES --out PROFILE`: the noise calibration written into a
//! sensor profile (`sensor::noise::profile`, docs/noise.md).

use crate::sensor::noise::profile::{NoiseProfileOptions, calibrate_noise_profile};
use std::path::PathBuf;

#[derive(clap::Args, Clone, Debug)]
pub struct Args {
    /// Capture-set directory (or its captures.toml) with dark and flat bursts.
    pub captures: PathBuf,
    /// Sensor profile to write: an existing one gets its noise and provenance.noise replaced;
    /// a new one is created (kind measured, levels from the capture set, no colour).
    #[arg(long)]
    pub out: PathBuf,
    /// Photon-transfer-curve plot (PNG); default: next to the profile, <profile>.ptc.png.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// White level in DN, overriding [sensor].white_level.
    #[arg(long)]
    pub white_level: Option<f64>,
    /// Black level in DN, overriding [sensor].black_level and the dark-frame estimate.
    #[arg(long)]
    pub black_level: Option<f64>,
}

pub fn run(args: &Args) -> anyhow::Result<String> {
    Ok(calibrate_noise_profile(&NoiseProfileOptions {
        captures: args.captures.clone(),
        out: args.out.clone(),
        plot: args.plot.clone(),
        white_level: args.white_level,
        black_level: args.black_level,
    })?)
}
