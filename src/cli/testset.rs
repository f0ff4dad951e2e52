//! `hdrsynth testset --radiance DIR --profile P --out OUT`: a static test set from real HDR
//! radiance rendered through a sensor profile (`data::testset`, docs/evaluation.md).

use crate::data::testset::{self, TestsetOptions, TestsetSummary};
use crate::sensor::metering::Metering;
use crate::sensor::profile::SensorProfile;
use crate::sensor::realism::NoiseModel;
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// A linear HDR radiance map (.exr/.hdr) or a folder of them (one scene each).
    #[arg(long)]
    pub radiance: PathBuf,
    /// Sensor profile (TOML), e.g. configs/sensors/canon_eos_550d.toml.
    #[arg(long)]
    pub profile: PathBuf,
    /// Output folder (hdrsynth layout; an interrupted run resumes).
    #[arg(long)]
    pub out: PathBuf,
    /// ISOs, one set per scene and ISO.
    #[arg(long, value_delimiter = ',', default_values_t = [100.0, 800.0, 3200.0])]
    pub isos: Vec<f64>,
    /// Bracket EVs (must include 0): -3,0 for Network-1, -2,0,2 for Network-2.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, default_values_t = [-3.0, 0.0])]
    pub evs: Vec<f32>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Factor on the automatic exposure key.
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f64,
    /// Auto-exposure: fraction of sensor white the scene's log-average luminance lands at.
    #[arg(long, default_value_t = Metering::default().mid_grey)]
    pub mid_grey: f64,
    /// Auto-exposure: largest fraction of pixels allowed to clip at EV0.
    #[arg(long, default_value_t = Metering::default().max_clipped)]
    pub max_clipped: f64,
    /// gaussian (the paper's N(0, aI+b)), poisson-gaussian (exact), none.
    #[arg(long, default_value = "gaussian", value_parser = parse_noise)]
    pub noise: NoiseModel,
    /// Skip the colour transform T (frames and ground truth).
    #[arg(long)]
    pub no_colour: bool,
    /// Frame bits: 8 or 16.
    #[arg(long, default_value_t = 8)]
    pub bits: u32,
    /// Resample each radiance map to WIDTHxHEIGHT first (e.g. 4032x3024).
    #[arg(long, value_parser = parse_size)]
    pub resize: Option<(usize, usize)>,
}

fn parse_noise(s: &str) -> Result<NoiseModel, String> {
    match s {
        "gaussian" => Ok(NoiseModel::Gaussian),
        "poisson-gaussian" => Ok(NoiseModel::PoissonGaussian),
        "none" => Ok(NoiseModel::None),
        _ => Err(format!(
            "'{s}': expected gaussian, poisson-gaussian or none"
        )),
    }
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
            metering: Metering {
                mid_grey: self.mid_grey,
                max_clipped: self.max_clipped,
            },
            noise: self.noise,
            colour: !self.no_colour,
            output_bits: self.bits,
            resize: self.resize,
        }
    }
}

pub fn build(args: &Args) -> Result<TestsetSummary> {
    let profile = SensorProfile::load(&args.profile)
        .with_context(|| format!("loading profile {}", args.profile.display()))?;
    Ok(testset::build(
        &args.radiance,
        &profile,
        &args.options(),
        &args.out,
    )?)
}

pub fn run(args: &Args) -> Result<String> {
    let s = build(args)?;
    let mut out = String::new();
    for n in &s.notes {
        let _ = writeln!(out, "note: {n}");
    }
    for b in &s.sets {
        let _ = writeln!(
            out,
            "{:<28} {}×{}  key {:.4e}  EV0 over {:.1} % under {:.1} %{}",
            b.name,
            b.width,
            b.height,
            b.key,
            100.0 * b.over_fraction,
            100.0 * b.under_fraction,
            if b.written { "" } else { "  (kept)" }
        );
    }
    let _ = write!(
        out,
        "{} set(s) in {} (hdrsynth layout; real radiance through the '{}' sensor model, not a \
         real bracketed capture)",
        s.sets.len(),
        args.out.display(),
        args.profile.display()
    );
    Ok(out)
}
