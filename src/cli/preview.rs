//! `hdrsynth dataset preview DIR --profile P --out sheet.png`: data::preview's contact sheet.

use crate::data::loader::SampleKind;
use crate::data::preview::{PreviewOptions, preview};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A dataset folder in any known layout.
    pub dir: PathBuf,
    /// Sensor profile for the realistic column.
    #[arg(long)]
    pub profile: PathBuf,
    #[arg(long, default_value_t = 800.0)]
    pub iso: f64,
    /// network1 (EV −3/0 pairs) or network2 (EV −2/0/+2); default from the dataset's EVs.
    #[arg(long, value_enum)]
    pub kind: Option<SampleKind>,
    #[arg(long, default_value_t = 4)]
    pub count: usize,
    #[arg(long, default_value_t = 192)]
    pub patch: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(args: &Args) -> anyhow::Result<String> {
    Ok(preview(&PreviewOptions {
        dir: args.dir.clone(),
        profile: args.profile.clone(),
        iso: args.iso,
        kind: args.kind,
        count: args.count,
        patch: args.patch,
        seed: args.seed,
        out: args.out.clone(),
    })?)
}
