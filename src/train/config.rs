//! `hdrsynth train --config F`: the training config (TOML, unknown keys are errors). Paths are
//! relative to the working directory. See docs/training.md for every key.

use crate::config::{KeyError, Range, in_range, in_range_because, load_checked};
use crate::data::encoding::{self, FrameEncoding};
use crate::data::loader::{LoaderConfig, PURE_PROFILE, RealismConfig, SampleKind, TargetFrames};
use crate::error::{Error, Result};
use crate::models::ModelConfig;
use crate::sensor::metering::{Metering, Resolved};
use crate::train::loss::Network1Reading;
use serde::{Deserialize, Serialize, de};
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    pub run: RunConfig,
    pub model: ModelConfig,
    pub data: DataConfig,
    #[serde(default)]
    pub optim: OptimConfig,
    #[serde(default)]
    pub schedule: Schedule,
    /// Fine-tuning: start from a checkpoint's weights (the optimizer starts fresh).
    #[serde(default)]
    pub init: Option<InitConfig>,
    #[serde(default)]
    pub loss: LossConfig,
    #[serde(default)]
    pub validation: Option<ValidationConfig>,
    /// A second training stream mixed into `[data]`'s (e.g. a device's real frames with
    /// simulated moving subjects, so a fine-tune on the one does not unlearn the other).
    #[serde(default)]
    pub mix: Option<MixConfig>,
}

/// `[mix]`: a share of the training samples drawn from a second stream.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MixConfig {
    /// The share of samples from `data` (each sample's choice drawn from its stream index).
    pub fraction: f64,
    /// The second stream, a `[data]` table of its own; its `patch` and `batch_size` must be
    /// `[data]`'s.
    pub data: DataConfig,
}

/// Tag of the mixed-in stream's seed ([`TrainConfig::mix_loader`]).
const MIX_STREAM: u64 = 0x31c5;

/// Tag of a fine-tuning run's training stream ([`TrainConfig::stream_seed`]).
const FINE_TUNE_STREAM: u64 = 0xf17e;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunConfig {
    /// Run folder: checkpoints, log, the resolved config.
    pub out: PathBuf,
    /// Seeds the initialisation and the data stream (crops, flips, ISO, noise); a fine-tuning
    /// run's stream is derived from it ([`TrainConfig::stream_seed`]).
    pub seed: u64,
    /// Optimisation steps in total (one batch each).
    pub steps: u64,
    /// "flex" (CPU, default), "ndarray", "wgpu", "cuda[:N]": the backends compiled in.
    #[serde(default = "default_backend")]
    pub backend: String,
    /// Data-parallel training: device names (as `backend`), each taking a shard of every
    /// batch (`train::train_step_parallel`); the first holds the model. Empty: `backend` alone.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub devices: Vec<String>,
    #[serde(default = "default_checkpoint_every")]
    pub checkpoint_every: u64,
    /// Checkpoints kept (the newest); the final one is always kept.
    #[serde(default = "default_keep")]
    pub keep_checkpoints: usize,
    /// Steps averaged into one log line.
    #[serde(default = "default_log_every")]
    pub log_every: u64,
}

fn default_backend() -> String {
    "flex".into()
}
fn default_checkpoint_every() -> u64 {
    500
}
fn default_keep() -> usize {
    3
}
fn default_log_every() -> u64 {
    10
}

/// `[data]`: the training stream. Its keys are this struct's own and, written in `[data]`
/// itself, the loader's sensor realism (`RealismConfig`: `profile` — a sensor profile TOML, or
/// "pure": no realism, the paper's Net_P —, `isos`, `noise`, `exposure`, `metering`,
/// `ev_jitter`, `source`, `colour`). Deserialised by hand (below) rather than with
/// `#[serde(flatten)]`, which loses toml's key spans: an unknown or mistyped key is reported at
/// its own line, with the valid keys.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DataConfig {
    /// Training dataset folder in any known layout.
    pub dataset: PathBuf,
    /// When `dataset` does not exist yet: generate it first with this `generate` config.
    pub generate: Option<PathBuf>,
    pub patch: usize,
    pub batch_size: usize,
    /// Default 2.
    pub workers: usize,
    /// Default true.
    pub augment: bool,
    /// Between `augment` and `target_sigma`, so the serialised keys keep their order (a run's
    /// identity on resume is its resolved config's text).
    #[serde(flatten)]
    pub realism: RealismConfig,
    /// Network-1: σ (pixels) of the Gaussian smoothing of the Mertens weights behind the class
    /// targets (`LoaderConfig::target_sigma`); 0 = the paper's per-pixel targets.
    pub target_sigma: f32,
    /// Network-1: the frames behind the class targets, `clean` (default: the crop rendered
    /// without the noise draw) or `noisy` (the input frames themselves).
    pub target_frames: TargetFrames,
    /// Network-2: the fraction of samples whose frames all come from the static set (no
    /// motion between them); the others take the non-reference frames from the dynamic set.
    /// Default 0 (every sample dynamic, the paper's §4.2).
    #[serde(skip_serializing_if = "is_zero")]
    pub static_fraction: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// Network-1's default target smoothing, chosen by measurement (docs/network1.md).
pub const DEFAULT_TARGET_SIGMA: f32 = 4.0;
const DEFAULT_WORKERS: usize = 2;

/// Every key `[data]` accepts, in the order the error message lists them (the serialised
/// order): its own around the realism keys, which come from `RealismConfig`'s derive.
fn data_keys() -> &'static [&'static str] {
    static KEYS: std::sync::LazyLock<Vec<&'static str>> = std::sync::LazyLock::new(|| {
        let before = [
            "dataset",
            "generate",
            "patch",
            "batch_size",
            "workers",
            "augment",
        ];
        let realism = crate::config::struct_fields::<RealismConfig>();
        let after = ["target_sigma", "target_frames", "static_fraction"];
        [&before[..], realism, &after[..]].concat()
    });
    &KEYS
}

impl<'de> Deserialize<'de> for DataConfig {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        d.deserialize_map(DataVisitor)
    }
}

struct DataVisitor;

/// `[data]`'s own values, filled as the keys stream past.
#[derive(Default)]
struct Own {
    dataset: Option<PathBuf>,
    generate: Option<PathBuf>,
    patch: Option<usize>,
    batch_size: Option<usize>,
    workers: Option<usize>,
    augment: Option<bool>,
    target_sigma: Option<f32>,
    target_frames: Option<TargetFrames>,
    static_fraction: Option<f64>,
}

impl<'de> de::Visitor<'de> for DataVisitor {
    type Value = DataConfig;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("the [data] table")
    }

    fn visit_map<A: de::MapAccess<'de>>(
        self,
        mut map: A,
    ) -> std::result::Result<DataConfig, A::Error> {
        let mut own = Own::default();
        // The realism keys go to `RealismConfig`'s own derive, value by value, so that toml
        // still knows which key a type error belongs to.
        let realism = RealismConfig::deserialize(de::value::MapAccessDeserializer::new(Split {
            map: &mut map,
            own: &mut own,
        }))?;
        let missing = de::Error::missing_field;
        Ok(DataConfig {
            dataset: own.dataset.ok_or_else(|| missing("dataset"))?,
            generate: own.generate,
            patch: own.patch.ok_or_else(|| missing("patch"))?,
            batch_size: own.batch_size.ok_or_else(|| missing("batch_size"))?,
            workers: own.workers.unwrap_or(DEFAULT_WORKERS),
            augment: own.augment.unwrap_or(true),
            realism,
            target_sigma: own.target_sigma.unwrap_or(DEFAULT_TARGET_SIGMA),
            target_frames: own.target_frames.unwrap_or_default(),
            static_fraction: own.static_fraction.unwrap_or(0.0),
        })
    }
}

/// The `[data]` map as `RealismConfig` sees it: `DataConfig`'s own keys are taken out on the way.
struct Split<'a, A> {
    map: &'a mut A,
    own: &'a mut Own,
}

impl<'de, A: de::MapAccess<'de>> de::MapAccess<'de> for Split<'_, A> {
    type Error = A::Error;

    fn next_key_seed<K: de::DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> std::result::Result<Option<K::Value>, A::Error> {
        loop {
            let Some(key) = self.map.next_key_seed(KnownKey)? else {
                return Ok(None);
            };
            let o = &mut *self.own;
            match key.as_str() {
                "dataset" => o.dataset = Some(self.map.next_value()?),
                "generate" => o.generate = Some(self.map.next_value()?),
                "patch" => o.patch = Some(self.map.next_value()?),
                "batch_size" => o.batch_size = Some(self.map.next_value()?),
                "workers" => o.workers = Some(self.map.next_value()?),
                "augment" => o.augment = Some(self.map.next_value()?),
                "target_sigma" => o.target_sigma = Some(self.map.next_value()?),
                "target_frames" => o.target_frames = Some(self.map.next_value()?),
                "static_fraction" => o.static_fraction = Some(self.map.next_value()?),
                _ => {
                    return seed
                        .deserialize(de::IntoDeserializer::into_deserializer(key))
                        .map(Some);
                }
            }
        }
    }

    fn next_value_seed<V: de::DeserializeSeed<'de>>(
        &mut self,
        seed: V,
    ) -> std::result::Result<V::Value, A::Error> {
        self.map.next_value_seed(seed)
    }
}

/// A `[data]` key, refused while toml still reads it (so the error carries the key's line) when
/// neither `DataConfig` nor `RealismConfig` has it.
struct KnownKey;

impl<'de> de::DeserializeSeed<'de> for KnownKey {
    type Value = String;

    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> std::result::Result<String, D::Error> {
        let key = String::deserialize(d)?;
        if data_keys().contains(&key.as_str()) {
            Ok(key)
        } else {
            Err(de::Error::unknown_field(&key, data_keys()))
        }
    }
}

impl DataConfig {
    /// `[data]` with every optional key at its default.
    pub fn new(dataset: PathBuf, patch: usize, batch_size: usize, realism: RealismConfig) -> Self {
        DataConfig {
            dataset,
            generate: None,
            patch,
            batch_size,
            workers: DEFAULT_WORKERS,
            augment: true,
            realism,
            target_sigma: DEFAULT_TARGET_SIGMA,
            target_frames: TargetFrames::default(),
            static_fraction: 0.0,
        }
    }

    /// `[data]`'s rules, keys relative to it; `multiple`: the network's down-sampling factor.
    pub fn validate(&self, multiple: usize) -> std::result::Result<(), KeyError> {
        check_patch("patch", self.patch, multiple)?;
        in_range("batch_size", self.batch_size, Range::at_least(1.0))?;
        in_range("workers", self.workers, Range::at_least(1.0))?;
        in_range("target_sigma", self.target_sigma, Range::NON_NEGATIVE)?;
        in_range("static_fraction", self.static_fraction, Range::UNIT)?;
        self.realism.validate()
    }

    /// The loader config of this data section (training: augmentation as configured).
    pub fn loader(&self, kind: SampleKind, seed: u64) -> Result<LoaderConfig> {
        let realism =
            (self.realism.profile != Path::new(PURE_PROFILE)).then(|| self.realism.clone());
        Ok(LoaderConfig {
            dataset: self.dataset.clone(),
            kind,
            patch: self.patch,
            batch_size: self.batch_size,
            workers: self.workers,
            prefetch: (2 * self.batch_size).max(4),
            seed,
            augment: self.augment,
            realism,
            target_sigma: self.target_sigma,
            target_frames: self.target_frames,
            static_fraction: self.static_fraction,
            input_response: None,
        })
    }
}

impl DataConfig {
    /// The exposure rule training meters with, and where it came from: `[data.metering]` where
    /// the config gives it, else the profile's measured rule, else the default
    /// ([`Metering::resolve`]; pure mode has no profile).
    pub fn metering(&self) -> Result<Resolved> {
        let p = &self.realism.profile;
        let measured = if p == Path::new(PURE_PROFILE) {
            None
        } else {
            crate::sensor::profile::SensorProfile::load(p)?.metering
        };
        Ok(Metering::resolve(self.realism.metering, measured))
    }

    /// The curve the training frames were encoded with: the profile's device response, or in
    /// pure mode the dataset's display curve (None where its layout does not record one).
    pub fn frame_encoding(&self) -> Result<Option<FrameEncoding>> {
        let p = &self.realism.profile;
        if p == Path::new(PURE_PROFILE) {
            return encoding::of_dataset(&self.dataset);
        }
        let profile = crate::sensor::profile::SensorProfile::load(p)?;
        Ok(Some(FrameEncoding::new(
            format!("the device response of profile {}", p.display()),
            profile.response,
        )))
    }
}

/// What a run's training frames came from, as evaluation checks it.
#[derive(Clone, Debug, Default)]
pub struct TrainedOn {
    /// [`DataConfig::frame_encoding`].
    pub encoding: Option<FrameEncoding>,
    /// What ties the run to real captures: its sensor profile, or a pure training set built
    /// from a device's brackets (the loop's `real` row); none for synthetic pure data.
    pub profile: Option<PathBuf>,
    /// The captures behind it: those the profile was calibrated on, or those the pure
    /// training set's sets record (`brackets.toml`).
    pub calibrated_on: Vec<crate::io::source::Source>,
}

/// [`TrainedOn`] of the run in folder `run` (its `config.toml`).
pub fn run_trained_on(run: &Path) -> Result<TrainedOn> {
    let cfg: TrainConfig = crate::config::load_toml(&run.join(super::RUN_CONFIG))?;
    let p = &cfg.data.realism.profile;
    let (profile, calibrated_on) = if p == Path::new(PURE_PROFILE) {
        let captures = dataset_captures(&cfg.data.dataset)?;
        let from = (!captures.is_empty()).then(|| cfg.data.dataset.clone());
        (from, captures)
    } else {
        let profile = crate::sensor::profile::SensorProfile::load(p)?;
        (Some(p.clone()), profile.calibrated_on)
    };
    Ok(TrainedOn {
        encoding: cfg.data.frame_encoding()?,
        profile,
        calibrated_on,
    })
}

/// The captures a dataset's sets record they were built from: none for a synthetic dataset
/// (or one no longer there); a folder of sets built from brackets records its encoding.
fn dataset_captures(dataset: &Path) -> Result<Vec<crate::io::source::Source>> {
    let mut all = Vec::new();
    if !dataset.join(crate::data::encoding::ENCODING_FILE).is_file() {
        return Ok(all);
    }
    for set in crate::data::layout::detect(dataset)?.sets {
        all.extend(crate::capture::testset::set_sources(&set.dir)?.unwrap_or_default());
    }
    Ok(all)
}

/// Adam (Kingma and Ba) with decoupled-free L2 weight decay as Burn implements it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OptimConfig {
    pub lr: f64,
    pub beta1: f32,
    pub beta2: f32,
    pub epsilon: f32,
    pub weight_decay: f32,
}

/// A training crop side: ≥ 8 (the loader's smallest) and a multiple of the network's
/// down-sampling factor.
fn check_patch(key: &str, patch: usize, multiple: usize) -> std::result::Result<(), KeyError> {
    in_range(key, patch, Range::at_least(8.0))?;
    if !patch.is_multiple_of(multiple) {
        return Err(KeyError::new(
            key,
            format!("{patch} is not a multiple of {multiple}, the network's down-sampling factor"),
        ));
    }
    Ok(())
}

impl OptimConfig {
    /// Adam's rules: lr > 0 (no upper bound: a diverging run is stopped by the non-finite
    /// loss check), β1 and β2 in [0, 1) (β = 1 never forgets, and Adam's bias correction
    /// divides by 1 − β^t), ε in (0, 1] (it divides by √v + ε), weight decay ≥ 0.
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        in_range("lr", self.lr, Range::POSITIVE)?;
        in_range("beta1", self.beta1, Range::half_open(0.0, 1.0))?;
        in_range("beta2", self.beta2, Range::half_open(0.0, 1.0))?;
        in_range_because(
            "epsilon",
            self.epsilon,
            Range::left_open(0.0, 1.0),
            "Adam divides by √v + ε",
        )?;
        in_range_because(
            "weight_decay",
            self.weight_decay,
            Range::NON_NEGATIVE,
            "a negative one grows the weights",
        )
    }
}

impl Default for OptimConfig {
    fn default() -> Self {
        OptimConfig {
            lr: 1e-4,
            beta1: 0.9,
            beta2: 0.999,
            epsilon: 1e-8,
            weight_decay: 0.0,
        }
    }
}

/// Learning-rate schedule, a pure function of the step (so resuming needs no state): a
/// linear warm-up from 0 over `warmup_steps`, then the chosen decay of `optim.lr`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct Schedule {
    pub kind: ScheduleKind,
    pub warmup_steps: u64,
    /// `step`: multiply by `gamma` every `every` steps.
    pub every: Option<u64>,
    pub gamma: Option<f64>,
    /// `cosine`: the final learning rate (default 0).
    pub min_lr: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ScheduleKind {
    #[default]
    Constant,
    Step,
    Cosine,
}

impl Schedule {
    /// The schedule's rules, keys relative to `[schedule]`; `lr`: the base learning rate.
    pub fn validate(&self, lr: f64) -> std::result::Result<(), KeyError> {
        if self.kind == ScheduleKind::Step {
            for (key, given) in [
                ("every", self.every.is_some()),
                ("gamma", self.gamma.is_some()),
            ] {
                if !given {
                    return Err(KeyError::new(
                        key,
                        "kind = \"step\" needs `every` and `gamma`",
                    ));
                }
            }
        }
        if let Some(every) = self.every {
            in_range("every", every, Range::at_least(1.0))?;
        }
        if let Some(gamma) = self.gamma {
            in_range_because(
                "gamma",
                gamma,
                Range::left_open(0.0, 1.0),
                "the factor of each decay step",
            )?;
        }
        if let Some(min) = self.min_lr {
            in_range_because(
                "min_lr",
                min,
                Range::closed(0.0, lr),
                "the cosine schedule's end, at most optim.lr",
            )?;
        }
        Ok(())
    }

    /// Learning rate of step `step` (0-based) of `total`.
    pub fn lr(&self, base: f64, step: u64, total: u64) -> f64 {
        if step < self.warmup_steps {
            return base * (step + 1) as f64 / self.warmup_steps as f64;
        }
        let s = step - self.warmup_steps;
        match self.kind {
            ScheduleKind::Constant => base,
            ScheduleKind::Step => {
                let every = self.every.unwrap_or(1).max(1);
                base * self.gamma.unwrap_or(1.0).powi((s / every) as i32)
            }
            ScheduleKind::Cosine => {
                let span = total.saturating_sub(self.warmup_steps).max(1) as f64;
                let min = self.min_lr.unwrap_or(0.0);
                let t = (s as f64 / span).min(1.0);
                min + (base - min) * 0.5 * (1.0 + (std::f64::consts::PI * t).cos())
            }
        }
    }
}

/// Where fine-tuning starts: exactly one of a checkpoint (or run folder: its latest) or a
/// SafeTensors file of weights trained elsewhere (names: docs/network2.md). The optimizer
/// starts fresh either way.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct InitConfig {
    pub checkpoint: Option<PathBuf>,
    pub safetensors: Option<PathBuf>,
}

/// Network-1's class weights α: "stream" (inverse class frequencies of the training stream's
/// first samples, i.e. of the data actually trained on, realism included: real and synthetic
/// data have different α, paper Fig. 6), "uniform", "checkpoint" (those stored in the `init`
/// checkpoint), or the path of a `class_weights.toml` (`hdrsynth dataset weights`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LossConfig {
    pub alpha: String,
    /// Samples of the stream counted for `alpha = "stream"`.
    pub alpha_samples: u64,
    /// Network-1: how the loss reads the 256 classes — "literal" (paper Eq. 4 as written),
    /// "ordinal", "cross_entropy" or "soft" (docs/network1.md; default chosen by measurement).
    pub reading: Network1Reading,
    /// Network-1, `reading = "soft"`: σ of the soft labels, in classes.
    pub label_sigma: f32,
    /// Network-2: the unit its μ-law L2 is taken in — "output" (Wu's: the network's [0, 1]
    /// output, HDR × hdr_input_scale) or "reference" (HDR in units of the reference frame's
    /// white, the unit PSNR-T scores). The default is not written.
    #[serde(skip_serializing_if = "HdrUnit::is_output")]
    pub hdr_unit: HdrUnit,
    /// Network-2: how the μ-law L2 is averaged — "pixels" (Wu's: over every pixel of the
    /// batch) or "psnr" (per crop, then the crops' mean PSNR, as PSNR-T averages images).
    /// The default is not written.
    #[serde(skip_serializing_if = "LossAverage::is_pixels")]
    pub average: LossAverage,
}

/// How Network-2's μ-law L2 is averaged over a batch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LossAverage {
    /// Over every pixel of the batch (Wu et al.; `train::loss::mu_law_l2`).
    #[default]
    Pixels,
    /// Per crop, then minus the crops' mean PSNR (`train::loss::mu_law_psnr_loss`).
    Psnr,
}

impl LossAverage {
    fn is_pixels(&self) -> bool {
        *self == LossAverage::Pixels
    }
}

impl HdrUnit {
    fn is_output(&self) -> bool {
        *self == HdrUnit::Output
    }
}

/// The unit of Network-2's μ-law loss.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HdrUnit {
    /// The network's output unit, HDR × hdr_input_scale clipped to [0, 1] (Wu et al.).
    #[default]
    Output,
    /// HDR relative to the reference frame's white (as scored), clipped to the output's range.
    Reference,
}

/// Default σ of the soft labels, in classes (docs/network1.md).
pub const DEFAULT_LABEL_SIGMA: f32 = 8.0;

impl LossConfig {
    /// `[loss]`'s rules, keys relative to it.
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        in_range("alpha_samples", self.alpha_samples, Range::at_least(1.0))?;
        in_range_because(
            "label_sigma",
            self.label_sigma,
            Range::left_open(0.0, 256.0),
            "σ in classes, of 256",
        )
    }
}

impl Default for LossConfig {
    fn default() -> Self {
        LossConfig {
            // "uniform" by measurement (docs/network1.md): at CPU scale the inverse-frequency
            // α of the stream (the paper's) kept the held-out blend-weight MAE above the best
            // constant's.
            alpha: "uniform".into(),
            alpha_samples: 64,
            reading: Network1Reading::default(),
            label_sigma: DEFAULT_LABEL_SIGMA,
            hdr_unit: HdrUnit::Output,
            average: LossAverage::Pixels,
        }
    }
}

/// Held-out validation: a fixed set of samples (epoch 0, no augmentation) scored every
/// `every` steps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValidationConfig {
    pub dataset: PathBuf,
    #[serde(default)]
    pub generate: Option<PathBuf>,
    pub every: u64,
    /// Samples scored (at most one per set).
    #[serde(default = "default_val_samples")]
    pub samples: usize,
    /// Crop side; default: the training patch.
    #[serde(default)]
    pub patch: Option<usize>,
    /// Network-1: target smoothing σ of the validation class maps (pixels). Default 0: every
    /// run is scored against the paper's per-pixel targets, whatever it trained on.
    #[serde(default)]
    pub target_sigma: f32,
}

impl ValidationConfig {
    /// `[validation]`'s rules, keys relative to it; `multiple` as for the training patch.
    pub fn validate(&self, multiple: usize) -> std::result::Result<(), KeyError> {
        in_range("every", self.every, Range::at_least(1.0))?;
        in_range("samples", self.samples, Range::at_least(1.0))?;
        if let Some(p) = self.patch {
            check_patch("patch", p, multiple)?;
        }
        in_range("target_sigma", self.target_sigma, Range::NON_NEGATIVE)
    }
}

fn default_val_samples() -> usize {
    16
}

impl TrainConfig {
    pub fn load(path: &Path) -> Result<TrainConfig> {
        load_checked(path, TrainConfig::validate)
    }

    /// This config with the exposure rule it trains with written in (`[data.metering]`,
    /// [`DataConfig::metering`]): what a run records as its config, so that its identity holds
    /// the rule itself, wherever it came from.
    /// The config with Network-2's `linearise = "data"` resolved: `input_response` set to the
    /// training frames' curve ([`DataConfig::frame_encoding`]), so the run's config and every
    /// checkpoint hold the curve inference must use.
    pub fn with_resolved_model(&self) -> Result<TrainConfig> {
        let mut c = self.clone();
        if let ModelConfig::Wu(m) = &mut c.model
            && m.linearise == crate::models::wu::Linearise::Data
        {
            let enc = self.data.frame_encoding()?.ok_or_else(|| {
                Error::config(
                    &self.data.dataset,
                    "model.linearise = \"data\" needs the training frames' curve, and this \
                     dataset's layout does not record one (set model.input_response, or \
                     linearise = \"fixed\")",
                )
            })?;
            m.input_response = enc.response;
        }
        Ok(c)
    }

    /// The loader of this run's training data (its stream seed, and Network-2's input curve).
    pub fn loader(&self, kind: SampleKind) -> Result<LoaderConfig> {
        let mut lc = self.data.loader(kind, self.stream_seed())?;
        lc.input_response = self.model.input_response();
        Ok(lc)
    }

    /// The loader of `[mix]`'s stream (None without one): a seed of its own, Network-2's
    /// input curve as `[data]`'s.
    pub fn mix_loader(&self, kind: SampleKind) -> Result<Option<(LoaderConfig, f64)>> {
        let Some(m) = &self.mix else {
            return Ok(None);
        };
        let seed = crate::rng::hash(self.stream_seed(), &[MIX_STREAM]);
        let mut lc = m.data.loader(kind, seed)?;
        lc.input_response = self.model.input_response();
        Ok(Some((lc, m.fraction)))
    }

    /// Seed of the training stream (crops, flips, ISO, noise). A fine-tuning run (`[init]`)
    /// draws from a stream of its own: with `run.seed` itself it would replay the crops of
    /// its pretraining's first steps (the same scenes, same positions, same noise draws).
    pub fn stream_seed(&self) -> u64 {
        if self.init.is_some() {
            crate::rng::hash(self.run.seed, &[FINE_TUNE_STREAM])
        } else {
            self.run.seed
        }
    }

    pub fn with_resolved_metering(&self) -> Result<TrainConfig> {
        let mut c = self.clone();
        c.data.realism.metering = Some(self.data.metering()?.rule);
        Ok(c)
    }

    /// Every value rule of the config (ranges, and the rules between keys); keys as the file
    /// spells them. Ranges: docs/reliability.md, "Value ranges".
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        let r = &self.run;
        for (key, v) in [
            ("run.steps", r.steps),
            ("run.checkpoint_every", r.checkpoint_every),
            ("run.keep_checkpoints", r.keep_checkpoints as u64),
            ("run.log_every", r.log_every),
        ] {
            in_range(key, v, Range::at_least(1.0))?;
        }
        if r.devices.len() > self.data.batch_size {
            return Err(KeyError::new(
                "run.devices",
                format!(
                    "{} devices need data.batch_size ≥ {0} (one shard each), got {}",
                    r.devices.len(),
                    self.data.batch_size
                ),
            ));
        }
        self.model.validate().map_err(|e| e.within("model"))?;
        let m = self.model.size_multiple();
        self.data.validate(m).map_err(|e| e.within("data"))?;
        self.optim.validate().map_err(|e| e.within("optim"))?;
        self.schedule
            .validate(self.optim.lr)
            .map_err(|e| e.within("schedule"))?;
        if let Some(i) = &self.init
            && i.checkpoint.is_some() == i.safetensors.is_some()
        {
            return Err(KeyError::new(
                "init",
                "give exactly one of `checkpoint` and `safetensors`",
            ));
        }
        self.loss.validate().map_err(|e| e.within("loss"))?;
        if let Some(v) = &self.validation {
            v.validate(m).map_err(|e| e.within("validation"))?;
        }
        if let Some(x) = &self.mix {
            in_range("mix.fraction", x.fraction, Range::UNIT)?;
            x.data.validate(m).map_err(|e| e.within("mix.data"))?;
            if (x.data.patch, x.data.batch_size) != (self.data.patch, self.data.batch_size) {
                return Err(KeyError::new(
                    "mix.data",
                    "`patch` and `batch_size` must be [data]'s: one batch holds both streams",
                ));
            }
        }
        Ok(())
    }
}
