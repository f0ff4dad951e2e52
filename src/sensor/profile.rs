//! SensorProfile: one device's sensor model, serialised as TOML under configs/sensors/, with
//! the provenance of every number.
//!
//! Units and conventions:
//! - Colour: `colour.matrix` is T, mapping synthetic linear RGB (linear sRGB/Rec.709 primaries,
//!   what the scene engine and renders produce) to the device's linear RGB, real = T · synthetic
//!   (the paper's Eq. 1). Device linear RGB is white-balanced camera RGB: a neutral stays
//!   (approximately) neutral. `root_polynomial` (3×6, terms R, G, B, √RG, √GB, √RB) replaces T
//!   when `use_root_polynomial = true`.
//! - Signal: DN (digital numbers) as the sensor stores them, with `black_level` and
//!   `white_level` in DN and `bit_depth` bits per sample. Linear value 1.0 maps to the white
//!   level: DN = black + v · (white − black) · exposure.
//! - Noise: in darktable's normalised convention, σ²(x) = a · x + b with x = (DN − black) /
//!   (white − black) the signal normalised to [0, 1], per ISO and per channel (R, G, B). In DN:
//!   σ²_DN = a·(W−B)·I + b·(W−B)² for I DN above black. Between calibrated ISOs a and b are
//!   interpolated linearly in log(ISO); outside the calibrated range is an error, never a silent
//!   extrapolation. A profile may have no noise (or no colour) calibration yet: the realism
//!   operator then refuses to run the missing step unless told to skip it.

use crate::config::{KeyError, Range, each_in_range, in_range, in_range_because, load_checked};
use crate::error::{Error, Result};
pub use crate::sensor::effects::plan::EffectSpec;
use crate::sensor::effects::plan::Plan;
use crate::sensor::metering::{MeteredFrame, Metering, measured_rule};
use crate::sensor::response::ToneCurve;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Where each group of numbers came from. Free text, but every field is required: a profile
/// whose numbers have no source is not a device profile.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    pub colour: String,
    pub noise: String,
    pub levels: String,
    pub response: String,
    /// Where the exposure rule `[metering]` was measured; present exactly when it is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metering: Option<String>,
    #[serde(default)]
    pub notes: Option<String>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum ProfileKind {
    /// Every number measured on, or published for, the named real device.
    Measured,
    /// Real published numbers of *different* devices put together (e.g. one phone's noise,
    /// another's colour): realistic for a device class, but no single device; the provenance
    /// says which part comes from where.
    Composite,
    /// Invented numbers for examples and tests; never a real device.
    SyntheticExample,
}

impl ProfileKind {
    /// The label used in files, listings and reports (the TOML spelling).
    pub fn as_str(self) -> &'static str {
        match self {
            ProfileKind::Measured => "measured",
            ProfileKind::Composite => "composite",
            ProfileKind::SyntheticExample => "synthetic-example",
        }
    }
}

impl std::fmt::Display for ProfileKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Colour {
    /// T (3×3): synthetic linear RGB → device linear RGB.
    pub matrix: [[f64; 3]; 3],
    /// Optional root-polynomial degree-2 matrix (3×6: R, G, B, √RG, √GB, √RB).
    #[serde(default)]
    pub root_polynomial: Option<[[f64; 6]; 3]>,
    #[serde(default)]
    pub use_root_polynomial: bool,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Levels {
    pub black_level: f64,
    pub white_level: f64,
    pub bit_depth: u32,
}

/// Noise at one ISO: σ²(x) = a·x + b, x the signal normalised to [0, 1], per channel R, G, B.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseAtIso {
    pub iso: f64,
    pub a: [f64; 3],
    pub b: [f64; 3],
    /// Standard errors of a and b where the calibration reported them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a_stderr: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub b_stderr: Option<[f64; 3]>,
}

/// A response curve: linear value in [0, 1] → code value in [0, 1].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Response {
    Linear,
    Srgb,
    Gamma {
        gamma: f64,
    },
    /// The scene engine's display curve (docs/scene.md).
    Filmic,
    /// Sampled curve: `lut[i]` is the code value at linear i / (n − 1); monotone increasing.
    Lut {
        lut: Vec<f64>,
    },
}

/// A response named on the command line: `srgb`, `linear` or `gamma:G` (case and surrounding
/// spaces ignored).
impl std::str::FromStr for Response {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Response, String> {
        let t = s.trim().to_ascii_lowercase();
        match t.as_str() {
            "srgb" => Ok(Response::Srgb),
            "linear" => Ok(Response::Linear),
            _ => match t.strip_prefix("gamma:") {
                Some(g) => match g.parse::<f64>() {
                    Ok(gamma) if gamma > 0.0 && gamma.is_finite() => Ok(Response::Gamma { gamma }),
                    Ok(_) => Err(format!("response '{s}': gamma must be > 0")),
                    Err(_) => Err(format!("response '{s}': gamma '{g}' is not a number")),
                },
                None => Err(format!(
                    "response '{s}': expected srgb, linear or gamma:G (e.g. gamma:2.2)"
                )),
            },
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorProfile {
    pub format: String,
    pub name: String,
    pub kind: ProfileKind,
    pub provenance: Provenance,
    /// Absent until a colour calibration has been made.
    #[serde(default)]
    pub colour: Option<Colour>,
    pub levels: Levels,
    /// Ascending ISO; empty until a noise calibration has been made.
    #[serde(default)]
    pub noise: Vec<NoiseAtIso>,
    /// Device response: how the device turns linear signal into its output code values.
    pub response: Response,
    /// Source response: how to linearise the pure synthetic frames fed to this profile.
    pub source_response: Response,
    /// The device's own exposure rule, measured from the frames its camera exposed itself
    /// (`calibrate brackets`): training and `testset` expose with it unless told otherwise
    /// ([`Metering::resolve`]). Absent where none was measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metering: Option<Metering>,
    #[serde(default)]
    pub effects: Vec<EffectSpec>,
    /// The captures this profile was measured on (`calibrate brackets`, `diagnose --brackets`):
    /// a network fine-tuned with it is never scored on them (docs/your_device.md, "The loop").
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub calibrated_on: Vec<crate::io::source::Source>,
}

/// One ISO of [`SensorProfile::noise_table`]: σ per channel (R, G, B) at each signal fraction.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseTableRow {
    pub iso: f64,
    pub sigma: Vec<[f64; 3]>,
}

pub const PROFILE_FORMAT: &str = "hdrsynth-sensor/1";

/// The range of each noise coefficient a and b (normalised units, see the module docs).
const NOISE_COEFFICIENT: Range = Range::closed(-1.0, 1.0);
/// The range of a colour-matrix entry: device matrices (rows summing to about 1) stay within a
/// few units; beyond ±10 a matrix amplifies noise more than any camera's.
const COLOUR_ENTRY: Range = Range::closed(-10.0, 10.0);

impl Response {
    /// Linear → code value, both in [0, 1].
    pub fn apply(&self, x: f64) -> f64 {
        let x = x.clamp(0.0, 1.0);
        match self {
            Response::Linear => x,
            Response::Srgb => ToneCurve::Srgb.apply(x as f32) as f64,
            Response::Gamma { gamma } => x.powf(1.0 / gamma),
            Response::Filmic => ToneCurve::Filmic.apply(x as f32) as f64,
            Response::Lut { lut } => {
                let t = x * (lut.len() - 1) as f64;
                let i = (t.floor() as usize).min(lut.len() - 2);
                lut[i] + (lut[i + 1] - lut[i]) * (t - i as f64)
            }
        }
    }

    /// The TOML spelling of the kind ("srgb", "gamma 2.2", "lut (n samples)").
    pub fn label(&self) -> String {
        match self {
            Response::Linear => "linear".into(),
            Response::Srgb => "srgb".into(),
            Response::Gamma { gamma } => format!("gamma {gamma}"),
            Response::Filmic => "filmic".into(),
            Response::Lut { lut } => format!("lut ({} samples)", lut.len()),
        }
    }

    /// Code value → linear value (inverse of `apply` below clipping).
    pub fn invert(&self, v: f64) -> f64 {
        let v = v.clamp(0.0, 1.0);
        match self {
            Response::Linear => v,
            Response::Srgb => crate::io::srgb_decode(v as f32) as f64,
            Response::Gamma { gamma } => v.powf(*gamma),
            Response::Filmic => ToneCurve::Filmic.invert(v as f32) as f64,
            Response::Lut { lut } => {
                // Monotone: binary search the segment holding v.
                let i = lut.partition_point(|&c| c <= v).clamp(1, lut.len() - 1) - 1;
                let (c0, c1) = (lut[i], lut[i + 1]);
                let f = if c1 > c0 { (v - c0) / (c1 - c0) } else { 0.0 };
                ((i as f64 + f.clamp(0.0, 1.0)) / (lut.len() - 1) as f64).clamp(0.0, 1.0)
            }
        }
    }

    /// [`invert`](Self::invert) tabulated over the 65,536 16-bit codes, entry k at k/65535:
    /// exact for 8- and 16-bit inputs (k/255 = 257k/65535). The one table that the realism
    /// operator, the loader and the bracket jobs look codes up in.
    pub fn inverse_table(&self) -> Vec<f32> {
        self.inverse_table_scaled(1.0)
    }

    /// [`inverse_table`](Self::inverse_table) with code white at 1 (divided by `invert(1)`).
    pub fn inverse_table_to_white(&self) -> Vec<f32> {
        self.inverse_table_scaled(self.invert(1.0).max(1e-12))
    }

    fn inverse_table_scaled(&self, scale: f64) -> Vec<f32> {
        (0..=65535u32)
            .map(|k| (self.invert(f64::from(k) / 65535.0) / scale) as f32)
            .collect()
    }

    /// [`invert`](Self::invert) in f32 for network inputs; γ curves as Wu's LDR^γ (computed
    /// in f32, unclamped), so γ 2.2 gives exactly the values Network-2 has always been fed.
    pub fn invert_f32(&self, v: f32) -> f32 {
        match self {
            Response::Gamma { gamma } => v.powf(*gamma as f32),
            r => r.invert(v as f64) as f32,
        }
    }

    /// d(code)/d(linear) at x in (0, 1): exact for linear, sRGB and gamma; a central
    /// difference for filmic and LUT curves (their `apply` is only piecewise smooth).
    pub fn slope(&self, x: f64) -> f64 {
        match self {
            Response::Linear => 1.0,
            // IEC 61966-2-1: 12.92·x up to 0.0031308, then 1.055·x^(1/2.4) − 0.055.
            Response::Srgb if x <= 0.003_130_8 => 12.92,
            Response::Srgb => 1.055 / 2.4 * x.powf(1.0 / 2.4 - 1.0),
            Response::Gamma { gamma } => x.powf(1.0 / gamma - 1.0) / gamma,
            Response::Filmic | Response::Lut { .. } => {
                let h = 1e-3 * x.min(1.0 - x).max(1e-6);
                (self.apply(x + h) - self.apply(x - h)) / (2.0 * h)
            }
        }
    }

    /// gamma in (0, 10]; a LUT of ≥ 2 non-decreasing values in [0, 1]; keys relative to the
    /// response's table.
    fn validate(&self) -> std::result::Result<(), KeyError> {
        match self {
            Response::Gamma { gamma } => in_range("gamma", *gamma, Range::left_open(0.0, 10.0)),
            Response::Lut { lut } => {
                if lut.len() < 2 {
                    return Err(KeyError::new("lut", "needs at least 2 samples"));
                }
                each_in_range("lut", lut, Range::UNIT)?;
                match lut.windows(2).position(|w| w[1] < w[0]) {
                    Some(i) => Err(KeyError::new(
                        format!("lut[{}]", i + 1),
                        format!(
                            "{} is below the sample before it: a response never falls",
                            lut[i + 1]
                        ),
                    )),
                    None => Ok(()),
                }
            }
            _ => Ok(()),
        }
    }
}

impl SensorProfile {
    /// A new profile of a measured device whose levels and response are known and nothing is
    /// calibrated yet (no colour, no noise rows; source response the engine's filmic curve):
    /// the calibrations fill in what they measure and its provenance.
    pub fn new_measured(
        name: impl Into<String>,
        levels: Levels,
        response: Response,
        provenance: Provenance,
    ) -> SensorProfile {
        SensorProfile {
            format: PROFILE_FORMAT.into(),
            name: name.into(),
            kind: ProfileKind::Measured,
            provenance,
            colour: None,
            levels,
            noise: Vec::new(),
            response,
            source_response: Response::Filmic,
            metering: None,
            effects: Vec::new(),
            calibrated_on: Vec::new(),
        }
    }

    /// A measured profile whose noise comes from a calibration (`calibrate noise`, the
    /// darktable import, the gap workflow's base model): colour not calibrated yet, default
    /// responses.
    pub fn from_noise(
        name: &str,
        levels: Levels,
        levels_source: &str,
        noise: Vec<NoiseAtIso>,
        noise_source: &str,
    ) -> SensorProfile {
        let mut p = SensorProfile::new_measured(
            name,
            levels,
            Response::Srgb,
            Provenance {
                colour: "not calibrated yet (run `hdrsynth calibrate colour`)".into(),
                noise: noise_source.to_string(),
                levels: levels_source.to_string(),
                response: "defaults, not measured: response = srgb, source_response = filmic \
                           (the scene engine's display curve)"
                    .into(),
                metering: None,
                notes: None,
            },
        );
        p.noise = noise;
        p
    }

    /// The profile at `path` to update, None where there is no file. A file there that is not
    /// a valid profile is an error, so a calibration never overwrites something else.
    pub fn load_existing(path: &Path) -> Result<Option<SensorProfile>> {
        if !path.exists() {
            return Ok(None);
        }
        SensorProfile::load(path).map(Some).map_err(|e| {
            Error::config(
                path,
                format!("exists but is not a valid sensor profile ({e}); not overwriting it"),
            )
        })
    }

    /// `load_existing`, or `create()`'s profile where there is none; the flag says whether it
    /// existed.
    pub fn load_or_create<E: From<Error>>(
        path: &Path,
        create: impl FnOnce() -> std::result::Result<SensorProfile, E>,
    ) -> std::result::Result<(SensorProfile, bool), E> {
        match SensorProfile::load_existing(path)? {
            Some(p) => Ok((p, true)),
            None => Ok((create()?, false)),
        }
    }

    pub fn load(path: &Path) -> Result<SensorProfile> {
        load_checked(path, SensorProfile::validate)
    }

    /// Write atomically as TOML.
    pub fn save(&self, path: &Path) -> Result<()> {
        self.validate().map_err(|e| e.at(path, None))?;
        let text = toml::to_string(self).map_err(|e| Error::encode(path, e))?;
        crate::io::atomic::write_atomic(path, text.as_bytes())
    }

    /// Every value rule of the profile, keys as the file spells them. Ranges:
    /// docs/reliability.md, "Value ranges".
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        if self.format != PROFILE_FORMAT {
            return Err(KeyError::new(
                "format",
                format!("'{}' is not '{PROFILE_FORMAT}'", self.format),
            ));
        }
        let l = &self.levels;
        in_range("levels.bit_depth", l.bit_depth, Range::closed(1.0, 16.0))?;
        let max = ((1u32 << l.bit_depth) - 1) as f64;
        in_range(
            "levels.black_level",
            l.black_level,
            Range::half_open(0.0, max),
        )?;
        in_range_because(
            "levels.white_level",
            l.white_level,
            Range::left_open(l.black_level, max),
            "above black_level, at most 2^bit_depth − 1",
        )?;
        for (i, n) in self.noise.iter().enumerate() {
            let key = |k: &str| format!("noise[{i}].{k}");
            in_range(&key("iso"), n.iso, Range::POSITIVE)?;
            if i > 0 && n.iso <= self.noise[i - 1].iso {
                return Err(KeyError::new(
                    key("iso"),
                    format!(
                        "{} is not above the ISO before it ({}): ISOs must be strictly ascending",
                        n.iso,
                        self.noise[i - 1].iso
                    ),
                ));
            }
            // Negative a or b occur in real published fits (darktable has 1,155 such rows; a
            // shipped profile keeps one negative a): a profile may hold them and the realism
            // operator clamps the variance at 0. Beyond ±1 the noise would exceed the whole
            // signal range (x and σ² are normalised to it).
            each_in_range(&key("a"), &n.a, NOISE_COEFFICIENT)?;
            each_in_range(&key("b"), &n.b, NOISE_COEFFICIENT)?;
            for (k, se) in [("a_stderr", n.a_stderr), ("b_stderr", n.b_stderr)] {
                if let Some(se) = se {
                    each_in_range(&key(k), &se, Range::closed(0.0, 1.0))?;
                }
            }
        }
        if let Some(c) = &self.colour {
            for (r, row) in c.matrix.iter().enumerate() {
                each_in_range(&format!("colour.matrix[{r}]"), row, COLOUR_ENTRY)?;
            }
            check_colour_matrix(&c.matrix).map_err(|why| {
                KeyError::new(
                    "colour.matrix",
                    format!("{why}; calibrate it again or remove [colour]"),
                )
            })?;
            if let Some(rp) = &c.root_polynomial {
                for (r, row) in rp.iter().enumerate() {
                    each_in_range(&format!("colour.root_polynomial[{r}]"), row, COLOUR_ENTRY)?;
                }
            }
            if c.use_root_polynomial && c.root_polynomial.is_none() {
                return Err(KeyError::new(
                    "colour.use_root_polynomial",
                    "true but no root_polynomial matrix",
                ));
            }
        }
        self.response.validate().map_err(|e| e.within("response"))?;
        self.source_response
            .validate()
            .map_err(|e| e.within("source_response"))?;
        if let Some(m) = &self.metering {
            m.validate().map_err(|e| e.within("metering"))?;
        }
        match (&self.metering, &self.provenance.metering) {
            (Some(_), None) => {
                return Err(KeyError::new(
                    "provenance.metering",
                    "missing: [metering] needs the line saying where the rule was measured",
                ));
            }
            (None, Some(_)) => {
                return Err(KeyError::new(
                    "provenance.metering",
                    "given, but the profile has no [metering]: add the rule or remove the line",
                ));
            }
            _ => {}
        }
        // Ids and parameters: the same check the realism operator makes.
        Plan::check(&self.effects)
    }

    /// Set the exposure rule with its provenance line, or remove both (`None`); the rule the
    /// profile held before.
    pub fn set_metering(&mut self, rule: Option<(Metering, String)>) -> Option<Metering> {
        let before = self.metering.take();
        (self.metering, self.provenance.metering) = rule.unzip();
        before
    }

    /// Write the exposure rule a bracket folder's metered frames show ([`measured_rule`]), or
    /// remove the profile's where they mark no auto-exposed frame: a note when one was removed.
    pub fn record_measured_rule(&mut self, dir: &Path, frames: &[MeteredFrame]) -> Option<String> {
        let before = self.set_metering(measured_rule(dir, frames));
        match (before, self.metering) {
            (Some(old), None) => Some(format!(
                "the profile's exposure rule ({old}) was removed: no frame of {} marks the \
                 device's meter",
                dir.display()
            )),
            _ => None,
        }
    }

    /// Noise parameters (a, b) per channel at `iso`, interpolated linearly in log(ISO).
    pub fn noise_at(&self, iso: f64) -> Result<([f64; 3], [f64; 3])> {
        if self.noise.is_empty() {
            return Err(Error::profile(
                &self.name,
                "has no noise calibration (run `hdrsynth calibrate noise` or `hdrsynth profile \
                 import-darktable`)",
            ));
        }
        let first = &self.noise[0];
        let last = &self.noise[self.noise.len() - 1];
        let eps = 1e-9 * iso.abs();
        if !(iso >= first.iso - eps && iso <= last.iso + eps) {
            return Err(Error::profile(
                &self.name,
                format!(
                    "ISO {iso} is outside the calibrated range {}–{}",
                    first.iso, last.iso
                ),
            ));
        }
        let hi = self
            .noise
            .partition_point(|n| n.iso < iso - eps)
            .min(self.noise.len() - 1);
        if hi == 0 || (self.noise[hi].iso - iso).abs() <= eps {
            let n = &self.noise[hi];
            return Ok((n.a, n.b));
        }
        let (n0, n1) = (&self.noise[hi - 1], &self.noise[hi]);
        let w = (iso.ln() - n0.iso.ln()) / (n1.iso.ln() - n0.iso.ln());
        let lerp = |x: [f64; 3], y: [f64; 3]| std::array::from_fn(|c| x[c] + (y[c] - x[c]) * w);
        Ok((lerp(n0.a, n1.a), lerp(n0.b, n1.b)))
    }

    /// Noise in output code values (8-bit: `max_code` 255) at signal fraction x of white, per
    /// ISO and channel, by first-order propagation through the device response:
    /// σ_code = response'(x) · √max(a·x + b, 0) · max_code. Linearised: exact for small σ,
    /// and it leaves out the raw and output quantisation (≈ 0.29 DN and 0.29 code).
    pub fn noise_table(&self, fractions: &[f64], max_code: f64) -> Result<Vec<NoiseTableRow>> {
        if let Some(x) = fractions.iter().find(|x| !(**x > 0.0 && **x < 1.0)) {
            return Err(Error::flag(
                "--at",
                format!("signal fraction {x} must be in (0, 1)"),
            ));
        }
        Ok(self
            .noise
            .iter()
            .map(|n| NoiseTableRow {
                iso: n.iso,
                sigma: fractions
                    .iter()
                    .map(|&x| {
                        let k = self.response.slope(x) * max_code;
                        std::array::from_fn(|c| (n.a[c] * x + n.b[c]).max(0.0).sqrt() * k)
                    })
                    .collect(),
            })
            .collect())
    }

    /// [`Self::noise_table`] at 8 bits as a Markdown table, one column per fraction.
    pub fn noise_table_markdown(&self, fractions: &[f64]) -> Result<String> {
        let rows = self.noise_table(fractions, 255.0)?;
        let mut s = format!(
            "{} ({}), response {}: σ in 8-bit codes (R, G, B)\n\n| ISO |",
            self.name,
            self.kind,
            self.response.label()
        );
        for x in fractions {
            s.push_str(&format!(" {} % of white |", x * 100.0));
        }
        s.push_str("\n|---|");
        s.push_str(&"---|".repeat(fractions.len()));
        s.push('\n');
        for r in &rows {
            s.push_str(&format!("| {} |", r.iso));
            for v in &r.sigma {
                s.push_str(&format!(" {:.2}, {:.2}, {:.2} |", v[0], v[1], v[2]));
            }
            s.push('\n');
        }
        Ok(s)
    }

    /// The profile files shipped under configs/sensors/.
    pub fn shipped_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/sensors")
    }
}

/// Error unless the colour matrix T is regular. A singular T maps distinct colours to one (an
/// all-zero T gives black frames). Scale-free test: |det| against the product of the row norms
/// (1 for orthogonal rows, 0 for dependent ones).
pub fn check_colour_matrix(m: &[[f64; 3]; 3]) -> std::result::Result<(), String> {
    let det = crate::linalg::det3(m);
    let norms: f64 = m
        .iter()
        .map(|r| r.iter().map(|v| v * v).sum::<f64>().sqrt())
        .product();
    if !(norms > 0.0 && det.abs() > 1e-6 * norms) {
        return Err(format!(
            "{m:?} is singular (determinant {det:.3e}): it would map distinct colours to one"
        ));
    }
    Ok(())
}
