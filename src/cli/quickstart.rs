//! `hdrsynth quickstart`: the main job, the primary comparison of docs/protocol.md on embedded
//! defaults (README, docs/quickstart.md). What it runs is `experiments::quickstart`.

use crate::experiments::quickstart::{self, Options, Preset};
use anyhow::Result;
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Output folder (resumes if it holds an interrupted quickstart of the same preset).
    #[arg(long, default_value = "runs/quickstart")]
    pub out: PathBuf,
    #[arg(long, value_enum, default_value_t = Preset::Cpu)]
    pub preset: Preset,
    /// Compute device: flex (CPU), ndarray, wgpu, cuda (as compiled in). Default: flex for the
    /// cpu preset, cuda for the gpu preset.
    #[arg(long)]
    pub backend: Option<String>,
    /// Folder of real HDR radiance maps (.exr/.hdr) for the descriptive real-radiance table;
    /// default ../shared/data/real_hdr when it exists.
    #[arg(long)]
    pub radiance: Option<PathBuf>,
    /// A real bracket folder (JPEG/PNG/TIFF/DNG with EXIF exposures, ≥ 3 frames) for the
    /// descriptive real-capture table; default ../shared/data/real_brackets/canon_550d_room
    /// when it exists.
    #[arg(long)]
    pub brackets: Option<PathBuf>,
    /// The target device's sensor profile (TOML) for Net_S and the test set; default the
    /// shipped composite phone (configs/sensors/composite_phone.toml). E.g. your own phone's
    /// calibrated profile.
    #[arg(long)]
    pub target: Option<PathBuf>,
    /// Also score every network on held-out-simulator renderings of the test scenes (another
    /// response, Poisson-Gaussian noise, another metering rule): docs/protocol.md.
    #[arg(long)]
    pub heldout: bool,
    /// The full protocol (docs/protocol.md): the main job with the held-out matrix, then the
    /// colour × fine-tuning-ISO grid with its ISO diagonal and the Network-1 grid with its
    /// baselines and learning curves; report in OUT/protocol.md.
    #[arg(long)]
    pub full: bool,
    /// Seeds to train and score (default 1,2,3). A claim about newly trained networks needs 5
    /// (docs/protocol.md, "Statistics"); a folder that holds some of them keeps those and
    /// gains the others.
    #[arg(long, value_delimiter = ',')]
    pub seeds: Option<Vec<u64>>,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(args: &Args) -> Result<String> {
    let run = if args.full {
        crate::experiments::protocol::run
    } else {
        quickstart::run
    };
    Ok(run(&Options {
        out: args.out.clone(),
        preset: args.preset,
        backend: args.backend.clone(),
        radiance: args.radiance.clone(),
        brackets: args.brackets.clone(),
        target: args.target.clone(),
        heldout: args.heldout,
        seeds: args.seeds.clone(),
        progress: !args.quiet,
    })?)
}
