//! `hdrsynth loop`: the sim-to-real loop on a device's bracket folder
//! (`experiments::device_loop`, docs/your_device.md "The loop").

use crate::capture::scan::Region;
use crate::capture::testset::{GtFrames, InputChoice};
use crate::cli::scan::ScanArgs;
use crate::experiments::device_loop::{LoopOptions, run as run_loop};
use std::path::PathBuf;

#[derive(clap::Args, Clone, Debug)]
pub struct Args {
    /// The device's bracket folder: one set per scene (sub-folders or capture-time groups,
    /// exposures from EXIF or a sidecar, as `testset --brackets` reads it).
    pub brackets: PathBuf,
    /// The sets that calibrate the profile (comma-separated names); every other set is a test
    /// scene. Without it, --calibration-region and --test-region split every set in two.
    #[arg(long, value_delimiter = ',')]
    pub calibration: Vec<String>,
    /// Read only this region of the calibration frames (left, right, top, bottom, x,y,w,h).
    #[arg(long)]
    pub calibration_region: Option<Region>,
    /// Read only this region of the test frames.
    #[arg(long)]
    pub test_region: Option<Region>,
    /// A main job's output folder (`hdrsynth quickstart --out`): its pretrained networks
    /// (pretrain/seed<k>) and fine-tune config (configs/finetune.toml) are the loop's start.
    #[arg(long, default_value = "runs/quickstart")]
    pub quickstart: PathBuf,
    /// Seeds: every step is fine-tuned once per seed from that seed's pretrained network.
    #[arg(long, value_delimiter = ',', default_value = "1,2,3")]
    pub seeds: Vec<u64>,
    /// The test set's three inputs per set (as `testset --brackets --inputs`).
    #[arg(long)]
    pub inputs: Option<InputChoice>,
    /// The test set's ground truth: from the inputs, all frames of the set, or the others
    /// (the frames that are not inputs, where they reach).
    #[arg(long, default_value = "all")]
    pub gt_frames: GtFrames,
    #[command(flatten)]
    pub scan: ScanArgs,
    /// Output folder: profiles/, testset/, experiment/ (the grid), loop.md.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(args: &Args) -> anyhow::Result<String> {
    let s = run_loop(&LoopOptions {
        brackets: args.brackets.clone(),
        calibration: args.calibration.clone(),
        calibration_region: args.calibration_region,
        test_region: args.test_region,
        scan: args.scan.options(None),
        inputs: args.inputs.clone().unwrap_or_default(),
        gt_frames: args.gt_frames,
        quickstart: args.quickstart.clone(),
        seeds: args.seeds.clone(),
        out: args.out.clone(),
        progress: true,
    })?;
    Ok(format!(
        "{}\nwritten: {}",
        s.report,
        args.out.join("loop.md").display()
    ))
}
