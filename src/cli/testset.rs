//! `hdrsynth testset --radiance DIR --profile P --out OUT`: a test set from HDR radiance
//! rendered through a sensor profile (`data::testset`, docs/evaluation.md): static from radiance
//! maps, dynamic from a generated dataset's moving scenes.
//! `hdrsynth testset --brackets DIR --out OUT`: a Kalantari-layout test set from the user's own
//! bracket folders (`capture::testset`, docs/your_device.md).

use crate::capture::align::MtbOptions;
use crate::capture::linearise::{ResponseChoice, ResponseSpec};
use crate::capture::testset::{BracketOptions, EncodeSpec, GtFrames, InputChoice};
use crate::cli::scan::{RegionArg, ScanArgs};
use crate::data::testset::{self, TestsetOptions, TestsetSummary};
use crate::sensor::metering::Metering;
use crate::sensor::profile::SensorProfile;
use crate::sensor::realism::{NoiseModel, TargetSpace};
use anyhow::{Context, Result};
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// A linear HDR radiance map (.exr/.hdr) or a folder of them (one scene each), or a
    /// dataset `hdrsynth generate` wrote with its linear frames (moving scenes: a dynamic test
    /// set).
    #[arg(
        long,
        required_unless_present = "brackets",
        conflicts_with = "brackets"
    )]
    pub radiance: Option<PathBuf>,
    /// A folder of bracketed captures (JPEG/PNG/TIFF/DNG; sets by sub-folder or capture time)
    /// → a Kalantari-layout test set with the triangle-merge ground truth.
    #[arg(long)]
    pub brackets: Option<PathBuf>,
    /// Sensor profile (TOML), e.g. configs/sensors/canon_eos_550d.toml. With --brackets its
    /// device response linearises the frames.
    #[arg(long, required_unless_present = "brackets")]
    pub profile: Option<PathBuf>,
    /// --brackets: the frames' response when no profile is given: srgb, linear, gamma:G,
    /// debevec (default: one curve for the three channels, OpenCV's CalibrateDebevec on the
    /// channels side by side), debevec-per-channel or robertson (OpenCV's CalibrateDebevec /
    /// CalibrateRobertson per channel).
    #[arg(long, conflicts_with = "profile")]
    pub response: Option<ResponseSpec>,
    /// --brackets: align hand-held sets to the middle frame (MTB, Ward 2003) and crop.
    #[arg(long)]
    pub align: bool,
    /// --brackets: the three inputs per set: auto (2-stop steps, the reference with the fewest
    /// clipped/dark pixels) or I,J,K (0-based, shortest exposure first). Default: the shortest,
    /// middle and longest.
    #[arg(long)]
    pub inputs: Option<InputChoice>,
    /// --brackets: how the folder is scanned.
    #[command(flatten)]
    pub scan: ScanArgs,
    /// --brackets: the part of every frame that is read.
    #[command(flatten)]
    pub region: RegionArg,
    /// --brackets: ground truth from the inputs (Kalantari's merge), all frames of the set, or
    /// the others (the frames that are not inputs, where they reach; all frames elsewhere).
    #[arg(long, default_value = "all")]
    pub gt_frames: GtFrames,
    /// --brackets: how the written inputs encode their linear signal: auto (device for
    /// JPEG/PNG/TIFF, field for DNG), device (the frames' own codes), field (linear^(1/2.2)) or
    /// profile:PATH (re-encoded with that profile's device response). Recorded in
    /// OUT/encoding.toml; `eval` warns when a network was trained on another curve.
    #[arg(long, default_value = "auto")]
    pub encode: EncodeSpec,
    /// Output folder (hdrsynth layout; an interrupted run resumes).
    #[arg(long)]
    pub out: PathBuf,
    /// ISOs, one set per scene and ISO.
    #[arg(long, conflicts_with = "brackets", value_delimiter = ',', default_values_t = [100.0, 800.0, 3200.0])]
    pub isos: Vec<f64>,
    /// Bracket EVs (must include 0): -3,0 for Network-1, -2,0,2 for Network-2.
    #[arg(long, conflicts_with = "brackets", value_delimiter = ',', allow_hyphen_values = true, default_values_t = [-3.0, 0.0])]
    pub evs: Vec<f32>,
    #[arg(long, conflicts_with = "brackets", default_value_t = 0)]
    pub seed: u64,
    /// Factor on the automatic exposure key.
    #[arg(long, conflicts_with = "brackets", default_value_t = 1.0)]
    pub exposure: f64,
    /// Auto-exposure: fraction of sensor white the scene's log-average luminance lands at.
    /// Either flag replaces the profile's measured rule (the other flag at its default,
    /// 0.128 / 0.02); without both, the profile's rule, else the default.
    #[arg(long, conflicts_with = "brackets")]
    pub mid_grey: Option<f64>,
    /// Auto-exposure: largest fraction of pixels allowed to clip at EV0 (see --mid-grey).
    #[arg(long, conflicts_with = "brackets")]
    pub max_clipped: Option<f64>,
    /// gaussian (the paper's N(0, aI+b)), poisson-gaussian (exact), none.
    #[arg(
        long,
        conflicts_with = "brackets",
        value_enum,
        default_value = "gaussian"
    )]
    pub noise: NoiseModel,
    /// Skip the colour transform T (frames and ground truth).
    #[arg(long, conflicts_with = "brackets")]
    pub no_colour: bool,
    /// The ground truth's space: device (T applied, as in the frames) or scene (scene-linear
    /// Rec. 709; T on the frames only, as a device's ISP renders).
    #[arg(
        long,
        conflicts_with = "brackets",
        value_enum,
        default_value = "device"
    )]
    pub ground_truth: TargetSpace,
    /// Frame bits: 8 or 16.
    #[arg(long, conflicts_with = "brackets", default_value_t = 8)]
    pub bits: u32,
    /// Resample each radiance map to WIDTHxHEIGHT first (e.g. 4032x3024).
    #[arg(long, conflicts_with = "brackets", value_parser = parse_size)]
    pub resize: Option<(usize, usize)>,
}

fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let err = || format!("'{s}': expected WIDTHxHEIGHT, e.g. 4032x3024");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(err)?;
    let w: usize = w.trim().parse().map_err(|_| err())?;
    let h: usize = h.trim().parse().map_err(|_| err())?;
    Ok((w, h))
}

impl Args {
    pub fn options(&self) -> TestsetOptions {
        TestsetOptions {
            isos: self.isos.clone(),
            evs: self.evs.clone(),
            seed: self.seed,
            exposure: self.exposure,
            // Not given: `testset::build` takes the profile's rule, else the default.
            metering: (self.mid_grey.is_some() || self.max_clipped.is_some()).then(|| {
                let d = Metering::default();
                Metering {
                    mid_grey: self.mid_grey.unwrap_or(d.mid_grey),
                    max_clipped: self.max_clipped.unwrap_or(d.max_clipped),
                }
            }),
            noise: self.noise,
            colour: !self.no_colour,
            output_bits: self.bits,
            resize: self.resize,
            ground_truth: self.ground_truth,
        }
    }
}

fn load_profile(path: &std::path::Path) -> Result<SensorProfile> {
    SensorProfile::load(path).with_context(|| format!("loading profile {}", path.display()))
}

pub fn build(args: &Args) -> Result<TestsetSummary> {
    let (Some(radiance), Some(profile)) = (&args.radiance, &args.profile) else {
        anyhow::bail!("--radiance and --profile are both needed (or --brackets)");
    };
    let profile = load_profile(profile)?;
    Ok(testset::build(
        radiance,
        &profile,
        &args.options(),
        &args.out,
    )?)
}

/// `--brackets`: the options of the bracket test set.
pub fn bracket_options(args: &Args) -> Result<BracketOptions> {
    let response = ResponseChoice::new(args.profile.as_deref(), args.response.as_ref())?;
    Ok(BracketOptions {
        scan: args.scan.options(args.region.region),
        response,
        align: args.align.then(MtbOptions::default),
        inputs: args.inputs.clone().unwrap_or_default(),
        gt_frames: args.gt_frames,
        encode: args.encode.clone(),
    })
}

pub fn run(args: &Args) -> Result<String> {
    if let Some(dir) = &args.brackets {
        let s = crate::capture::testset::build(dir, &bracket_options(args)?, &args.out)?;
        return Ok(s.report(&args.out));
    }
    let s = build(args)?;
    let profile = args.profile.as_deref().unwrap_or(std::path::Path::new(""));
    Ok(s.report(&args.out, profile))
}
