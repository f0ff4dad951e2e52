//! The resumable dataset writer behind `hdrsynth generate` and its config: sets that are
//! complete (meta.toml present) are kept; a different config in the folder is refused.

use crate::config::load_toml;
use crate::data::layout::hdrsynth as layout;
use crate::data::scene::{CameraConfig, Generator, SceneConfig, check_size};
use crate::error::{Error, Result};
use crate::io::{BitDepth, ExrPrecision};
use crate::sensor::response::ToneCurve;
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

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

#[derive(Debug)]
pub struct Summary {
    pub generated: usize,
    pub resumed: usize,
    pub seconds: f64,
    pub frames_mpix: f64,
    pub over: Vec<f32>,
    pub under: Vec<f32>,
    pub dynamic_range: Vec<f32>,
}

pub fn generate(cfg: &GenerateConfig, out: &Path, progress: bool) -> Result<Summary> {
    let generator = Generator::new(cfg)?;
    let manifest = layout::manifest_for(cfg);
    // One generator per dataset folder: two with different configs would mix their sets.
    let _lock = crate::io::guard::OutputLock::acquire(out, "generate")?;
    // Under the lock, temp files in the folder are a killed run's.
    crate::io::atomic::remove_stale_temps(out)?;
    if layout::is_dataset(out) {
        let existing = layout::read_manifest(out)?;
        // Compare everything but where the config was read from.
        let same = match &existing.generator {
            Some(g) => {
                let mut g = g.clone();
                g.source = cfg.source.clone();
                g == *cfg
            }
            None => false,
        };
        if !same {
            return Err(Error::Invalid(format!(
                "{} holds a dataset made with a different config; choose another --out \
                 (or delete it) rather than mixing sets",
                out.display()
            )));
        }
    } else {
        std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
        layout::write_manifest(out, &manifest)?;
    }
    let bar = if progress {
        ProgressBar::new(cfg.count as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} sets {msg}",
        )
        .expect("static template"),
    );
    let start = Instant::now();
    let mut s = Summary {
        generated: 0,
        resumed: 0,
        seconds: 0.0,
        frames_mpix: 0.0,
        over: Vec::new(),
        under: Vec::new(),
        dynamic_range: Vec::new(),
    };
    for index in 0..cfg.count as u64 {
        if layout::set_done(out, index) {
            let meta = layout::read_set_meta(&out.join(layout::set_name(index)))?;
            s.over.push(meta.stats.over_fraction);
            s.under.push(meta.stats.under_fraction);
            s.dynamic_range.push(meta.stats.dynamic_range_stops);
            s.resumed += 1;
            bar.inc(1);
            continue;
        }
        let sample = generator.render(index);
        layout::write_set(out, index, &sample, cfg).map_err(|e| {
            Error::Invalid(format!("writing set {index} under {}: {e}", out.display()))
        })?;
        s.over.push(sample.stats.over_fraction);
        s.under.push(sample.stats.under_fraction);
        s.dynamic_range.push(sample.stats.dynamic_range_stops);
        s.generated += 1;
        // Output frames: static and dynamic display frames per EV.
        s.frames_mpix += (2 * cfg.evs.len() * cfg.width * cfg.height) as f64 / 1e6;
        bar.set_message(format!("DR {:.1} stops", sample.stats.dynamic_range_stops));
        bar.inc(1);
    }
    bar.finish_and_clear();
    s.seconds = start.elapsed().as_secs_f64();
    Ok(s)
}

fn stats(v: &[f32]) -> String {
    if v.is_empty() {
        return "-".into();
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    format!(
        "min {:.3} / median {:.3} / max {:.3}",
        s[0],
        s[s.len() / 2],
        s[s.len() - 1]
    )
}

impl Summary {
    pub fn report(&self, out: &Path) -> String {
        let rate = if self.seconds > 0.0 {
            self.frames_mpix / self.seconds
        } else {
            0.0
        };
        format!(
            "wrote {} sets to {} ({} already complete, kept) in {:.1} s — {:.2} Mpix/s of output frames\n\
             over-exposed at EV0:  {}\n\
             under-exposed at EV0: {}\n\
             dynamic range (stops, 99.9/0.1 percentile): {}",
            self.generated,
            out.display(),
            self.resumed,
            self.seconds,
            rate,
            stats(&self.over),
            stats(&self.under),
            stats(&self.dynamic_range)
        )
    }
}
