//! The config of `hdrsynth generate` (the scene engine's and the dataset writer's settings),
//! here beside the engine that reads it so that the engine, the layout writer and the writer
//! loop all depend on it from below.

use crate::config::{KeyError, Range, in_range, in_range_because, load_checked};
use crate::data::scene::{CameraConfig, SceneConfig, check_size};
use crate::error::Result;
use crate::io::{BitDepth, ExrPrecision};
use crate::sensor::response::ToneCurve;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// `hdrsynth generate`: a pure synthetic multi-exposure dataset from the scene engine.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GenerateConfig {
    /// Master seed: sample i is a pure function of (seed, i).
    pub seed: u64,
    /// Number of samples (sets).
    pub count: usize,
    pub width: usize,
    pub height: usize,
    /// Bracket in stops relative to the reference; must contain 0 (the reference), ascending.
    pub evs: Vec<f32>,
    /// Curve baked into the display frames: "filmic" (engine default), "srgb" or "linear".
    #[serde(default)]
    pub tone_curve: ToneCurve,
    /// Bits of the display PNGs: 8 or 16.
    #[serde(default = "default_bits")]
    pub bit_depth: u32,
    /// Sample type of the linear EXRs.
    #[serde(default)]
    pub exr_precision: ExrPrecision,
    /// Write each frame's linear radiance as EXR next to its display PNG.
    #[serde(default = "yes")]
    pub write_linear: bool,
    #[serde(default)]
    pub scene: SceneConfig,
    #[serde(default)]
    pub camera: CameraConfig,
    /// Where the config was read from (for messages); not part of the file.
    #[serde(skip)]
    pub source: Option<PathBuf>,
}

/// Largest |EV| of a bracket frame: beyond it the frame is all black or all white at 8 or 16
/// bits (16 stops is the whole code range of a 16-bit frame).
pub const MAX_EV: f32 = 16.0;

fn default_bits() -> u32 {
    8
}
fn yes() -> bool {
    true
}

impl GenerateConfig {
    /// A config with every optional key at its default (a config file's `seed`, `count`,
    /// `width`, `height` and `evs` alone).
    pub fn new(seed: u64, count: usize, (width, height): (usize, usize), evs: Vec<f32>) -> Self {
        GenerateConfig {
            seed,
            count,
            width,
            height,
            evs,
            tone_curve: ToneCurve::default(),
            bit_depth: default_bits(),
            exr_precision: ExrPrecision::default(),
            write_linear: yes(),
            scene: SceneConfig::default(),
            camera: CameraConfig::default(),
            source: None,
        }
    }

    pub fn load(path: &Path) -> Result<GenerateConfig> {
        let mut cfg: GenerateConfig = load_checked(path, GenerateConfig::validate)?;
        cfg.source = Some(path.to_path_buf());
        Ok(cfg)
    }

    /// Where the config was read from, for messages.
    pub(crate) fn origin(&self) -> PathBuf {
        self.source
            .clone()
            .unwrap_or_else(|| PathBuf::from("<config>"))
    }

    /// Every value rule of the config, keys as the file spells them. Ranges:
    /// docs/reliability.md, "Value ranges".
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        check_size(self.width, self.height)?;
        in_range("count", self.count, Range::at_least(1.0))?;
        if !self.evs.contains(&0.0) {
            return Err(KeyError::new(
                "evs",
                format!("{:?} must contain 0 (the reference frame)", self.evs),
            ));
        }
        for (i, &ev) in self.evs.iter().enumerate() {
            in_range_because(
                &format!("evs[{i}]"),
                ev,
                Range::closed(-MAX_EV as f64, MAX_EV as f64),
                "beyond, a frame is all black or all white at 8 or 16 bits",
            )?;
        }
        if self.evs.windows(2).any(|w| w[0] >= w[1]) {
            return Err(KeyError::new(
                "evs",
                format!("{:?} must be strictly ascending", self.evs),
            ));
        }
        if BitDepth::from_bits(self.bit_depth).is_none() {
            return Err(KeyError::new(
                "bit_depth",
                format!("{} must be 8 or 16", self.bit_depth),
            ));
        }
        self.scene.validate().map_err(|e| e.within("scene"))?;
        self.camera.validate().map_err(|e| e.within("camera"))
    }

    /// Index of the reference frame (EV 0) in `evs`.
    pub fn reference_index(&self) -> usize {
        self.evs.iter().position(|&e| e == 0.0).unwrap_or(0)
    }

    pub fn bit_depth(&self) -> BitDepth {
        BitDepth::from_bits(self.bit_depth).unwrap_or(BitDepth::Eight)
    }
}
