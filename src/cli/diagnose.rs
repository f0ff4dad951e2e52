//! `hdrsynth diagnose CAPTURES [--profile P] --out DIR`: the sim-to-real gap workflow
//! (src/sensor/diagnose/, docs/diagnose.md). Writes DIR/profile.toml (the extended model),
//! DIR/report.md, DIR/report.json and plots (gap.png, radial.png, ptc.png); prints a summary.
//! `hdrsynth diagnose --brackets DIR [--profile P | --response R] --out OUT`: a bracket folder
//! as scene bursts (src/data/bracket_captures.rs), plus OUT/brackets.{md,toml} and OUT/captures.

use crate::capture::diagnose::{BracketDiagnoseOptions, diagnose_brackets};
use crate::capture::linearise::{ResponseChoice, ResponseSpec};
use crate::capture::scan::{Region, ScanOptions};
use crate::sensor::diagnose::{self, DiagnoseOptions};
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Capture set: a directory with captures.toml (or the manifest itself).
    #[arg(required_unless_present = "brackets", conflicts_with = "brackets")]
    pub captures: Option<PathBuf>,
    /// A bracket folder (JPEG/PNG/TIFF/DNG, as for `testset --brackets`) diagnosed as scene
    /// bursts, one per frame: response and exposure-ratio checks (docs/your_device.md).
    #[arg(long)]
    pub brackets: Option<PathBuf>,
    /// Starting model; without it the paper's base model is fitted from the captures. With
    /// --brackets: its device response linearises the frames.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// --brackets --profile: also compare the frames with the profile's simulation of them in
    /// the device's output domain (noise level, spatial and channel correlation;
    /// OUT/device_output.md; docs/your_device.md, section 7).
    #[arg(long, requires = "brackets", requires = "profile")]
    pub device_output: bool,
    /// --brackets: frames of one exposure within a set are repeated captures (as `calibrate
    /// brackets --repeats`); the device-output check then compares the differences of
    /// repeated pairs, which hold no scene.
    #[arg(long, requires = "brackets")]
    pub repeats: bool,
    /// --brackets without --profile: srgb, linear, gamma:G, debevec (default: one curve for the
    /// three channels), debevec-per-channel or robertson.
    #[arg(long, conflicts_with = "profile", requires = "brackets")]
    pub response: Option<ResponseSpec>,
    /// --brackets: declared EV steps in capture order, for frames without EXIF or sidecar.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        requires = "brackets"
    )]
    pub declared_evs: Option<Vec<f64>>,
    /// --brackets: largest gap between capture times within one set, seconds.
    #[arg(long, default_value_t = ScanOptions::default().max_gap_s)]
    pub max_gap: f64,
    /// --brackets: read only this part of every frame: left, right, top, bottom (halves of the upright
    /// frame, split at ⌊w/2⌋ or ⌊h/2⌋) or x,y,w,h in pixels.
    #[arg(long)]
    pub region: Option<Region>,
    /// --brackets: a frame whose exposure ratio is off the common response by more than this
    /// many stops is named and left out.
    #[arg(long, default_value_t = BracketDiagnoseOptions::default().ratio_tolerance_stops)]
    pub ratio_tolerance: f64,
    /// Output folder for profile.toml, report.md, report.json and the plots.
    #[arg(long)]
    pub out: PathBuf,
    /// Bootstrap replicates of the capture protocol per comparison.
    #[arg(long, default_value_t = DiagnoseOptions::default().replicates)]
    pub replicates: usize,
    #[arg(long, default_value_t = DiagnoseOptions::default().seed)]
    pub seed: u64,
    /// Analyse bursts larger than this on evenly spread bands of rows of about this many
    /// pixels, in the measurement and the simulation alike (0: every row; docs/diagnose.md).
    #[arg(long, default_value_t = DiagnoseOptions::default().max_pixels)]
    pub max_pixels: usize,
}

pub fn run(args: &Args) -> Result<String> {
    let t0 = Instant::now();
    let opts = DiagnoseOptions {
        replicates: args.replicates,
        seed: args.seed,
        max_pixels: args.max_pixels,
        ..DiagnoseOptions::default()
    };
    let (mut s, wrote) = match (&args.brackets, &args.captures) {
        (Some(dir), _) => {
            let opts = BracketDiagnoseOptions {
                scan: ScanOptions {
                    evs: args.declared_evs.clone(),
                    max_gap_s: args.max_gap,
                    region: args.region,
                    repeats: args.repeats,
                    ..ScanOptions::default()
                },
                response: ResponseChoice::new(args.profile.as_deref(), args.response.as_ref())?,
                diagnose: opts,
                ratio_tolerance_stops: args.ratio_tolerance,
                device_output: if args.device_output {
                    args.profile.clone()
                } else {
                    None
                },
            };
            let b = diagnose_brackets(dir, &opts, &args.out)
                .with_context(|| format!("diagnosing the brackets in {}", dir.display()))?;
            let files = if args.device_output {
                "brackets.md, brackets.toml, captures/, device_output.md, profile.toml, \
                 report.md, report.json, *.png"
            } else {
                "brackets.md, brackets.toml, captures/, profile.toml, report.md, report.json, \
                 *.png"
            };
            (b.summary(), files)
        }
        (None, Some(captures)) => {
            let d = diagnose::diagnose_folder(captures, args.profile.as_deref(), &opts, &args.out)?;
            (d.summary(), "profile.toml, report.md, report.json, *.png")
        }
        (None, None) => anyhow::bail!("give a capture set or --brackets DIR"),
    };
    let _ = write!(
        s,
        "wrote {}/{{{wrote}}} in {:.1} s",
        args.out.display(),
        t0.elapsed().as_secs_f64()
    );
    Ok(s)
}
