//! `hdrsynth calibrate colour`: arguments → [`CalibrateOptions`] →
//! `sensor::colour::calibrate::run` (the calibration and its steps: there and docs/colour.md).

use crate::sensor::colour::calibrate::{self, CalibrateOptions, SyntheticChart};
use crate::sensor::colour::chart::ChartRegion;
use crate::sensor::colour::fit::WhiteBalance;
use crate::sensor::profile::Response;
use anyhow::{Result, bail};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Fit a profile's colour transform T (real = T · synthetic) from a ColorChecker24 capture.
#[derive(Clone, Debug, clap::Args)]
pub struct Args {
    /// Real capture of the chart: DNG (raw), EXR/HDR (linear) or PNG/TIFF (code values).
    #[arg(long)]
    pub real: PathBuf,
    /// Synthetic image of the chart, or `render` to render the reference chart.
    #[arg(long, default_value = "render")]
    pub synthetic: String,
    /// Sensor profile (TOML) to update, or to create if it does not exist.
    #[arg(long)]
    pub out: PathBuf,
    /// Corners of the real chart's 6×4 patch area in pixels: top-left, top-right, bottom-right,
    /// bottom-left as x0,y0,x1,y1,x2,y2,x3,y3 (default: the chart fills the frame).
    #[arg(long, allow_hyphen_values = true)]
    pub corners: Option<String>,
    /// Corners of the chart in the synthetic image (default: it fills the frame).
    #[arg(long, allow_hyphen_values = true)]
    pub synthetic_corners: Option<String>,
    /// Also fit the root-polynomial (degree 2) and make the profile use it.
    #[arg(long)]
    pub root_polynomial: bool,
    /// White balance of the real patches.
    #[arg(long, value_enum, default_value = "neutral")]
    pub white_balance: WhiteBalance,
    /// Light of the rendered chart: D65 (default), D50, A, or linear RGB gains r,g,b.
    #[arg(long)]
    pub illuminant: Option<String>,
    /// Exposure multiplier of the rendered chart (default 1).
    #[arg(long)]
    pub exposure: Option<f64>,
    /// Response to linearise a PNG/TIFF real capture: srgb, linear or gamma:G (default: srgb
    /// for 8-bit files, linear for 16-bit files).
    #[arg(long)]
    pub real_response: Option<String>,
    /// Response to linearise a PNG/TIFF synthetic image (same default rule).
    #[arg(long)]
    pub synthetic_response: Option<String>,
    /// Clip level of the inputs in their own units (default 1: code value 1, or the DNG white
    /// level; EXR/HDR are not checked unless given).
    #[arg(long)]
    pub clip_level: Option<f64>,
    /// Black level in DN, for a new profile when the real capture is not a DNG.
    #[arg(long)]
    pub black: Option<f64>,
    /// White level in DN, for a new profile when the real capture is not a DNG.
    #[arg(long)]
    pub white: Option<f64>,
    /// Bits per sample, for a new profile when the real capture is not a DNG.
    #[arg(long)]
    pub bits: Option<u32>,
    /// Name of a new profile (default: the DNG's camera model, else the file stem of --out).
    #[arg(long)]
    pub name: Option<String>,
}

impl Args {
    /// The command line these arguments stand for.
    fn command_line(&self) -> String {
        let q = |s: &str| {
            if s.is_empty() || s.contains(|c: char| c.is_whitespace() || "'\"$\\".contains(c)) {
                format!("'{}'", s.replace('\'', r"'\''"))
            } else {
                s.to_string()
            }
        };
        let mut c = format!(
            "hdrsynth calibrate colour --real {} --synthetic {} --out {}",
            q(&self.real.display().to_string()),
            q(&self.synthetic),
            q(&self.out.display().to_string())
        );
        let mut opt = |name: &str, v: Option<String>| {
            if let Some(v) = v {
                let _ = write!(c, " --{name} {}", q(&v));
            }
        };
        opt("corners", self.corners.clone());
        opt("synthetic-corners", self.synthetic_corners.clone());
        if self.white_balance == WhiteBalance::None {
            opt("white-balance", Some("none".into()));
        }
        opt("illuminant", self.illuminant.clone());
        opt("exposure", self.exposure.map(|v| v.to_string()));
        opt("real-response", self.real_response.clone());
        opt("synthetic-response", self.synthetic_response.clone());
        opt("clip-level", self.clip_level.map(|v| v.to_string()));
        opt("black", self.black.map(|v| v.to_string()));
        opt("white", self.white.map(|v| v.to_string()));
        opt("bits", self.bits.map(|v| v.to_string()));
        opt("name", self.name.clone());
        if self.root_polynomial {
            c.push_str(" --root-polynomial");
        }
        c
    }

    /// The typed options; malformed or contradicting arguments are refused here.
    pub fn options(&self) -> Result<CalibrateOptions> {
        let response = |s: &Option<String>| {
            s.as_deref()
                .map(|r| r.parse::<Response>().map_err(anyhow::Error::msg))
                .transpose()
        };
        let region = |s: &Option<String>| {
            s.as_deref()
                .map_or(Ok(ChartRegion::FullFrame), ChartRegion::parse_corners)
        };
        let synthetic = if self.synthetic.eq_ignore_ascii_case("render") {
            if self.synthetic_corners.is_some() || self.synthetic_response.is_some() {
                bail!(
                    "--synthetic-corners and --synthetic-response apply to a synthetic image, not to `render`"
                );
            }
            SyntheticChart::Render {
                illuminant: self.illuminant.as_deref().unwrap_or("D65").parse()?,
                exposure: self.exposure.unwrap_or(1.0),
            }
        } else {
            if self.illuminant.is_some() || self.exposure.is_some() {
                bail!("--illuminant and --exposure apply to `--synthetic render` only");
            }
            SyntheticChart::Image {
                path: PathBuf::from(&self.synthetic),
                region: region(&self.synthetic_corners)?,
                response: response(&self.synthetic_response)?,
            }
        };
        Ok(CalibrateOptions {
            real: self.real.clone(),
            real_region: region(&self.corners)?,
            real_response: response(&self.real_response)?,
            synthetic,
            white_balance: self.white_balance,
            root_polynomial: self.root_polynomial,
            clip_level: self.clip_level,
            out: self.out.clone(),
            black: self.black,
            white: self.white,
            bits: self.bits,
            name: self.name.clone(),
            invocation: self.command_line(),
        })
    }
}

/// `hdrsynth calibrate colour ...`: calibrate, write the profile, return the report.
pub fn run(args: &Args) -> Result<String> {
    Ok(calibrate::run(&args.options()?)?)
}
