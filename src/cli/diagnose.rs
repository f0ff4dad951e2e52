//! `hdrsynth diagnose CAPTURES [--profile P] --out DIR`: the sim-to-real gap workflow
//! (src/sensor/diagnose/, docs/diagnose.md). Writes DIR/profile.toml (the extended model),
//! DIR/report.md, DIR/report.json and plots (gap.png, radial.png, ptc.png); prints a summary.
//! `hdrsynth diagnose --brackets DIR [--profile P | --response R] --out OUT`: a bracket folder
//! as scene bursts (src/capture/diagnose.rs), plus OUT/brackets.{md,toml} and OUT/captures.

use crate::capture::diagnose::{BracketDiagnoseOptions, diagnose_brackets};
use crate::capture::linearise::{ResponseChoice, ResponseSpec};
use crate::cli::scan::{RegionArg, ScanArgs};
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
    /// --brackets without --profile: srgb, linear, gamma:G, debevec (default: one curve for the
    /// three channels), debevec-per-channel or robertson.
    #[arg(long, conflicts_with = "profile", requires = "brackets")]
    pub response: Option<ResponseSpec>,
    /// --brackets: how the folder is scanned.
    #[command(flatten)]
    pub scan: ScanArgs,
    /// --brackets: the part of every frame that is read.
    #[command(flatten)]
    pub region: RegionArg,
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
    // The scan's flags read a bracket folder: without --brackets they would be ignored.
    let scan = &args.scan;
    if args.brackets.is_none()
        && (scan.declared_evs.is_some() || scan.repeats || args.region.region.is_some())
    {
        anyhow::bail!(
            "--declared-evs, --repeats and --region read a bracket folder: give --brackets"
        );
    }
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
                scan: args.scan.options(args.region.region),
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
                 profile_<effect>.toml (each output effect fitted), report.md, report.json, *.png"
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
