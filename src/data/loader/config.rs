//! The loader's configuration: which samples (network, patch, batch, seed, augmentation) and
//! how they are made realistic (`[realism]`: profile, ISOs, exposure metering and jitter).

use crate::config::{KeyError, Range, each_in_range, in_range, in_range_because, load_checked};
use crate::error::Result;
use crate::sensor::metering::Metering;
use crate::sensor::profile::Response;
use crate::sensor::realism::{NoiseModel, TargetSpace};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum SampleKind {
    Network1,
    Network2,
}

/// Which pixels the realism operator starts from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// The linear EXR of every frame when the dataset has them (hdrsynth's layout with
    /// `write_linear`), else the display frames.
    #[default]
    Auto,
    /// The frames' linear EXRs (float radiance: highlights keep their full precision).
    Linear,
    /// The display frames (8/16-bit, linearised with the profile's source response).
    Display,
}

impl std::fmt::Display for Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Source::Auto => "auto",
            Source::Linear => "linear EXR frames",
            Source::Display => "display frames linearised by the profile's source response",
        })
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RealismConfig {
    /// A sensor profile TOML; in a training config's `[data]`, "pure" for no realism.
    pub profile: PathBuf,
    /// ISO drawn uniformly per sample from this list (one entry = fixed ISO); the loader
    /// refuses an empty one. Optional in the file for `[data]`'s "pure" profile.
    #[serde(default)]
    pub isos: Vec<f64>,
    #[serde(default)]
    pub noise: NoiseModel,
    /// Extra factor on the metered exposure (1 = the auto-exposure rule's choice).
    #[serde(default = "one")]
    pub exposure: f64,
    /// The auto-exposure rule (src/sensor/metering.rs; the same rule `testset` uses). Absent:
    /// the profile's measured rule, else the default ([`Metering::resolve`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metering: Option<Metering>,
    /// Per-sample exposure jitter, uniform in ±`ev_jitter` stops around the metered exposure
    /// (a phone's meter is not exact either).
    #[serde(default = "half")]
    pub ev_jitter: f64,
    /// Linear EXR frames or display frames (`auto`: EXRs when every frame has one).
    #[serde(default)]
    pub source: Source,
    /// Apply the profile's colour transform (false for the colour ablation).
    #[serde(default = "yes")]
    pub colour: bool,
    /// Network-2's target space: `device` (default: T applied, as the inputs) or `scene`
    /// (scene-linear Rec. 709, T on the inputs only).
    #[serde(default, skip_serializing_if = "TargetSpace::is_device")]
    pub target_space: TargetSpace,
}

/// `[data]`'s `profile` value for no sensor realism (the paper's Net_P).
pub const PURE_PROFILE: &str = "pure";

/// Largest `ev_jitter`, stops: a meter off by more is not a meter.
pub const MAX_EV_JITTER: f64 = 4.0;

impl RealismConfig {
    /// The rules of these keys (relative to the table holding them): ISOs > 0 (and at least
    /// one unless the profile is "pure"), exposure factor > 0, jitter in [0, 4] stops, the
    /// metering rule's ranges.
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        if self.isos.is_empty() && self.profile != Path::new(PURE_PROFILE) {
            return Err(KeyError::new(
                "isos",
                format!(
                    "profile '{}' needs a non-empty `isos` list",
                    self.profile.display()
                ),
            ));
        }
        each_in_range("isos", &self.isos, Range::POSITIVE)?;
        in_range_because(
            "exposure",
            self.exposure,
            Range::POSITIVE,
            "a factor on the metered exposure",
        )?;
        in_range_because(
            "ev_jitter",
            self.ev_jitter,
            Range::closed(0.0, MAX_EV_JITTER),
            "stops",
        )?;
        match &self.metering {
            Some(m) => m.validate().map_err(|e| e.within("metering")),
            None => Ok(()),
        }
    }

    /// `profile` at `isos`, every other key at its default.
    pub fn new(profile: PathBuf, isos: Vec<f64>) -> Self {
        RealismConfig {
            profile,
            isos,
            noise: NoiseModel::default(),
            exposure: one(),
            metering: None,
            ev_jitter: half(),
            source: Source::default(),
            colour: yes(),
            target_space: TargetSpace::Device,
        }
    }
}

fn one() -> f64 {
    1.0
}
fn half() -> f64 {
    0.5
}
fn yes() -> bool {
    true
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoaderConfig {
    /// A dataset folder in any layout the readers know.
    pub dataset: PathBuf,
    pub kind: SampleKind,
    /// Square crop side in pixels (rot90 needs square crops).
    pub patch: usize,
    pub batch_size: usize,
    #[serde(default = "default_workers")]
    pub workers: usize,
    /// Samples computed ahead of the consumer, at most.
    #[serde(default = "default_prefetch")]
    pub prefetch: usize,
    pub seed: u64,
    /// Random horizontal/vertical flips and rot90.
    #[serde(default = "yes")]
    pub augment: bool,
    /// Absent: "pure" mode, no sensor realism (the Net_P baseline).
    #[serde(default)]
    pub realism: Option<RealismConfig>,
    /// Network-1 only: σ in pixels of the Gaussian that smooths each frame's Mertens weight
    /// before the blend classes are taken (`ground_truth::blend_classes_smoothed`); 0 (the
    /// default) gives the paper's per-pixel class maps.
    #[serde(default)]
    pub target_sigma: f32,
    /// Network-1 only: which frames the Mertens weights behind the class targets come from.
    #[serde(default)]
    pub target_frames: TargetFrames,
    /// Network-2 only: the fraction of samples whose three frames all come from the static
    /// set (no motion between them); 0: the non-reference frames always from the dynamic set.
    #[serde(default)]
    pub static_fraction: f64,
    /// Network-2 only: the curve its HDR input channels invert (the network's
    /// `input_response`, set by the trainer); None: LDR^2.2, Wu et al.'s.
    #[serde(skip)]
    pub input_response: Option<Response>,
}

/// Network-1's targets: the blend weights of the noise-free render of the sample's crop (what
/// a network that sees through the noise should predict), or of the noisy frames it is given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TargetFrames {
    /// The same crop, exposure, colour and quantisation, without the noise draw.
    #[default]
    Clean,
    /// The noisy input frames themselves: noise inflates Mertens' contrast term, so the targets
    /// carry noise-driven weights.
    Noisy,
}

fn default_workers() -> usize {
    2
}
fn default_prefetch() -> usize {
    8
}

impl LoaderConfig {
    pub fn load(path: &Path) -> Result<LoaderConfig> {
        load_checked(path, LoaderConfig::validate)
    }

    /// Crop ≥ 8 px, batch, workers and prefetch ≥ 1, target σ ≥ 0, the realism keys' rules.
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        in_range("patch", self.patch, Range::at_least(8.0))?;
        in_range("batch_size", self.batch_size, Range::at_least(1.0))?;
        in_range("workers", self.workers, Range::at_least(1.0))?;
        in_range("prefetch", self.prefetch, Range::at_least(1.0))?;
        in_range("target_sigma", self.target_sigma, Range::NON_NEGATIVE)?;
        match &self.realism {
            Some(r) => r.validate().map_err(|e| e.within("realism")),
            None => Ok(()),
        }
    }
}
