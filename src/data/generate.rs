//! The resumable dataset writer behind `hdrsynth generate` and its config: sets that are
//! complete (meta.toml present) are kept; a different config in the folder is refused.

use crate::config::{KeyError, Range, in_range, in_range_because, load_checked};
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
