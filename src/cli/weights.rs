//! `hdrsynth dataset weights DIR [--plot PNG]`: Network-1's class maps and class weights
//! (data::class_maps).

use crate::data::class_maps::{ClassMapOptions, write_class_maps};
use crate::data::ground_truth::MertensWeights;
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Dataset folder (hdrsynth layout, or any layout with static frames).
    pub dir: PathBuf,
    /// Also write a bar chart of class frequencies and weights (log y) to this PNG.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Exponent of Mertens' contrast measure (OpenCV default 1).
    #[arg(long, default_value_t = 1.0)]
    pub contrast_weight: f32,
    /// Exponent of Mertens' saturation measure (OpenCV default 1).
    #[arg(long, default_value_t = 1.0)]
    pub saturation_weight: f32,
    /// Exponent of Mertens' well-exposedness measure (OpenCV default 0; the paper's 1).
    #[arg(long, default_value_t = 0.0)]
    pub exposure_weight: f32,
}

/// Run `dataset weights`; returns the summary to print.
pub fn run(args: &Args) -> anyhow::Result<String> {
    Ok(write_class_maps(&ClassMapOptions {
        dir: args.dir.clone(),
        plot: args.plot.clone(),
        mertens: MertensWeights {
            contrast: args.contrast_weight,
            saturation: args.saturation_weight,
            exposure: args.exposure_weight,
        },
    })?)
}
