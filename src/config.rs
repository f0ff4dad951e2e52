//! Typed TOML configs. Unknown keys are errors; messages name the file and the line.

use crate::data::scene::{CameraConfig, SceneConfig, check_size};
use crate::error::{Error, Result};
use crate::io::{BitDepth, ExrPrecision};
use crate::sensor::response::ToneCurve;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Read and parse a TOML file into `T`; errors carry the file name and toml's line/column.
pub fn load_toml<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_toml(&text, path)
}

pub fn parse_toml<T: DeserializeOwned>(text: &str, path: &Path) -> Result<T> {
    toml::from_str(text).map_err(|e| {
        let line = e
            .span()
            .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
        let msg = e.message().to_string();
        match line {
            Some(l) => Error::config(format!("{}:{l}", path.display()), msg),
            None => Error::config(path, msg),
        }
    })
}

/// Merge `over` into `base`: tables merge key by key (recursively), anything else replaces.
/// How an ablation cell's settings are laid over its base training config.
pub fn merge_tables(base: &mut toml::Table, over: &toml::Table) {
    for (k, v) in over {
        match (base.get_mut(k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            _ => {
                base.insert(k.clone(), v.clone());
            }
        }
    }
}

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
/// Largest `scene.min_dynamic_range` (stops); the engine's scenes span about 16–24.
pub const MAX_DYNAMIC_RANGE: f32 = 32.0;

fn default_bits() -> u32 {
    8
}
fn yes() -> bool {
    true
}

impl GenerateConfig {
    pub fn load(path: &Path) -> Result<GenerateConfig> {
        let mut cfg: GenerateConfig = load_toml(path)?;
        cfg.source = Some(path.to_path_buf());
        cfg.validate()?;
        Ok(cfg)
    }

    fn origin(&self) -> PathBuf {
        self.source
            .clone()
            .unwrap_or_else(|| PathBuf::from("<config>"))
    }

    pub fn validate(&self) -> Result<()> {
        let p = self.origin();
        let bad = |msg: String| Err(Error::config(&p, msg));
        check_size(self.width, self.height, &p)?;
        if self.count == 0 {
            return bad("count must be ≥ 1".into());
        }
        if self.evs.is_empty() || !self.evs.contains(&0.0) {
            return bad(format!(
                "evs {:?} must contain 0 (the reference frame)",
                self.evs
            ));
        }
        if self.evs.windows(2).any(|w| w[0] >= w[1]) || self.evs.iter().any(|e| !e.is_finite()) {
            return bad(format!(
                "evs {:?} must be finite and strictly ascending",
                self.evs
            ));
        }
        if let Some(e) = self.evs.iter().find(|e| e.abs() > MAX_EV) {
            return bad(format!(
                "evs: {e} stops is beyond ±{MAX_EV}: such a frame is all black or all white at \
                 8 or 16 bits"
            ));
        }
        // Below 1 the probability applies only "when backgrounds_dir is set" (the shipped
        // configs keep 0.5 with the folder commented out); 1 demands a real background for
        // every sample, which no folder cannot give.
        if self.scene.real_background_probability == 1.0 && self.scene.backgrounds_dir.is_none() {
            return bad(
                "scene.real_background_probability = 1 (every sample on a real background) \
                 needs scene.backgrounds_dir"
                    .into(),
            );
        }
        if self.camera.candidates == 0 {
            return bad("camera.candidates = 0: at least one viewpoint must be tried".into());
        }
        let dr = self.scene.min_dynamic_range;
        if !(dr.is_finite() && (0.0..=MAX_DYNAMIC_RANGE).contains(&dr)) {
            return bad(format!(
                "scene.min_dynamic_range = {dr} must be in [0, {MAX_DYNAMIC_RANGE}] stops (the \
                 engine's scenes span about 16–24; a larger minimum is never met)"
            ));
        }
        if BitDepth::from_bits(self.bit_depth).is_none() {
            return bad(format!("bit_depth {} must be 8 or 16", self.bit_depth));
        }
        let s = &self.scene;
        if s.subjects[0] > s.subjects[1] {
            return bad(format!("scene.subjects {:?}: min > max", s.subjects));
        }
        for (name, v) in [
            ("scene.articulated_fraction", s.articulated_fraction),
            (
                "scene.real_background_probability",
                s.real_background_probability,
            ),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return bad(format!("{name} = {v} must be in [0, 1]"));
            }
        }
        if s.motion_scale.is_nan() || s.motion_scale < 0.0 {
            return bad("scene.motion_scale must be ≥ 0".into());
        }
        let c = &self.camera;
        if !(0.0..1.0).contains(&c.target_over)
            || !(0.0..1.0).contains(&c.target_under)
            || c.target_over + c.target_under >= 1.0
        {
            return bad(format!(
                "camera.target_over {} and target_under {} must be in [0,1) with a sum < 1",
                c.target_over, c.target_under
            ));
        }
        if !(c.under_threshold > 0.0
            && c.under_threshold < c.over_threshold
            && c.over_threshold < 1.0)
        {
            return bad("camera thresholds need 0 < under_threshold < over_threshold < 1".into());
        }
        Ok(())
    }

    /// Index of the reference frame (EV 0) in `evs`.
    pub fn reference_index(&self) -> usize {
        self.evs.iter().position(|&e| e == 0.0).unwrap_or(0)
    }

    pub fn bit_depth(&self) -> BitDepth {
        BitDepth::from_bits(self.bit_depth).unwrap_or(BitDepth::Eight)
    }
}
