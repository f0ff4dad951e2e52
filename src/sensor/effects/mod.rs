//! The effect catalogue: each effect = simulate (applied by the realism operator in physical
//! order) + diagnostic statistics + a fit from captures, one file each.
//!
//! A profile lists effects as `[[effects]]` tables `{ id = "...", <params> }`. The realism
//! operator compiles them into a [`Plan`] (what to do at each stage of the pixel pipeline) with
//! each effect's `install`; the gap workflow (src/sensor/diagnose/) evaluates every effect's
//! `statistics` on measured and simulated capture sets and calls `fit` on the one it names.
//!
//! Physical order inside the realism operator (docs/diagnose.md):
//! signal stage (before noise): vignetting gain → PRNU gain → nonlinear response;
//! noise stage: channel noise scales a, b per channel; heavy tails replace the Gaussian read
//! noise by a Student-t of the same variance; correlated noise filters the normal draws with a
//! separable Gaussian kernel;
//! offset stage (after the black level): black-level offset, row offsets (new every frame),
//! column offsets, DSNU, hot pixels (fixed patterns); then clip and quantise.
//!
//! Fixed patterns (column, DSNU, PRNU, hot pixels) derive from the effect's `seed` parameter
//! and the pixel coordinates, so they are the same in every frame and every run; per-frame
//! draws (row offsets, noise) come from the frame seed.

use crate::config::KeyError;
use crate::rng::{hash, unit_f32};
use crate::sensor::captures::BurstKind;
use crate::sensor::profile::{EffectSpec, SensorProfile};

pub mod black_level;
pub mod channel_noise;
pub mod column_noise;
pub mod correlated_noise;
pub mod curve;
pub mod dsnu;
pub mod heavy_tailed_read_noise;
pub mod hot_pixels;
pub mod nonlinear_response;
pub mod params;
pub mod prnu;
pub mod row_noise;
pub mod summary;
pub mod vignetting;

pub use summary::{Protocol, Summary};

/// One catalogue entry.
pub struct Entry {
    pub id: &'static str,
    /// One line: what the effect is.
    pub about: &'static str,
    /// The bursts its statistics need (reported when a capture set has none).
    pub needs: &'static str,
    /// Check the parameters and add the effect to the plan.
    pub install: fn(&toml::Table, &mut Plan) -> Result<(), String>,
    /// The effect's diagnostic statistics of one capture set (measured or simulated).
    pub statistics: fn(&Protocol, &[Summary], &mut Vec<Stat>),
    /// Fit the parameters from the captures (measured statistics against the current model's
    /// simulated ones, the measured summaries).
    pub fit: fn(&FitCtx) -> Result<toml::Table, String>,
    /// Change the rest of a *given* profile when the effect is added (e.g. row noise is already
    /// in its b, which must then shrink by its variance). A base model fitted from the captures
    /// is refitted instead (`diagnose::refit_noise`).
    pub adjust: Option<fn(&mut SensorProfile, &toml::Table)>,
}

/// The catalogue in physical order (the order `statistics` are listed in reports).
pub const CATALOGUE: [Entry; 11] = [
    vignetting::ENTRY,
    prnu::ENTRY,
    nonlinear_response::ENTRY,
    channel_noise::ENTRY,
    heavy_tailed_read_noise::ENTRY,
    correlated_noise::ENTRY,
    black_level::ENTRY,
    row_noise::ENTRY,
    column_noise::ENTRY,
    dsnu::ENTRY,
    hot_pixels::ENTRY,
];

/// Ids of the effects this build implements, in physical order.
pub fn known() -> Vec<&'static str> {
    CATALOGUE.iter().map(|e| e.id).collect()
}

pub fn is_known(id: &str) -> bool {
    entry(id).is_some()
}

pub fn entry(id: &str) -> Option<&'static Entry> {
    CATALOGUE.iter().find(|e| e.id == id)
}

/// What the realism operator applies, compiled from a profile's effects. The default is the
/// paper's model (nothing extra).
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// Vignetting: gain 1 − k·r², r = distance from the centre / half-diagonal.
    pub vignetting_k: f32,
    /// PRNU: gain 1 + σ·z per value, (σ, seed).
    pub prnu: Option<(f32, u64)>,
    /// Nonlinear response: I → R·f(I/R), R = white − black.
    pub response: Option<nonlinear_response::Curve>,
    /// Channel noise: multipliers on a and b per channel.
    pub a_scale: [f32; 3],
    pub b_scale: [f32; 3],
    /// Heavy-tailed read noise: Student-t degrees of freedom.
    pub heavy_dof: Option<f32>,
    /// Correlated noise: half kernels (k(0)..k(R)) filtering the normal draws horizontally
    /// and vertically (separable, Σk² = 1 over each full kernel).
    pub corr_kernels: Option<(Vec<f32>, Vec<f32>)>,
    /// Black-level offset in DN.
    pub black_offset: f32,
    /// Row offsets: σ in DN, drawn anew in every frame.
    pub row_sigma: f32,
    /// Column offsets (σ DN, seed).
    pub column: Option<(f32, u64)>,
    /// DSNU (σ DN, seed).
    pub dsnu: Option<(f32, u64)>,
    /// Hot pixels (fraction of values, offset DN, seed).
    pub hot: Option<(f32, f32, u64)>,
}

impl Default for Plan {
    fn default() -> Self {
        Plan {
            vignetting_k: 0.0,
            prnu: None,
            response: None,
            a_scale: [1.0; 3],
            b_scale: [1.0; 3],
            heavy_dof: None,
            corr_kernels: None,
            black_offset: 0.0,
            row_sigma: 0.0,
            column: None,
            dsnu: None,
            hot: None,
        }
    }
}

impl Plan {
    pub fn from_effects(effects: &[EffectSpec]) -> Result<Plan, String> {
        Self::compile(effects).map_err(|(_, m)| m)
    }

    /// [`Plan::from_effects`]'s checks as a profile's key rule: an error names the
    /// `effects[i]` table and, in its message, the parameter.
    pub fn check(effects: &[EffectSpec]) -> Result<(), KeyError> {
        Self::compile(effects)
            .map(|_| ())
            .map_err(|(i, m)| KeyError::new(format!("effects[{i}]"), m))
    }

    /// The plan, or the index of the first effect refused and why.
    fn compile(effects: &[EffectSpec]) -> Result<Plan, (usize, String)> {
        let mut plan = Plan::default();
        let mut seen = Vec::new();
        for (i, e) in effects.iter().enumerate() {
            let entry = entry(&e.id).ok_or_else(|| {
                let m = format!(
                    "effects: '{}' is not in this build's effect catalogue ({})",
                    e.id,
                    known().join(", ")
                );
                (i, m)
            })?;
            if seen.contains(&e.id) {
                return Err((i, format!("effects: '{}' is listed twice", e.id)));
            }
            seen.push(e.id.clone());
            (entry.install)(&e.params, &mut plan)
                .map_err(|m| (i, format!("effect '{}': {m}", e.id)))?;
        }
        Ok(plan)
    }

    /// True when the plan changes nothing in the pixel loop (the realism fast path).
    pub fn per_pixel_neutral(&self) -> bool {
        let d = Plan::default();
        Plan {
            a_scale: d.a_scale,
            b_scale: d.b_scale,
            ..self.clone()
        } == d
    }

    /// Per-value gain (vignetting × PRNU) of a w×h frame, None when there is none.
    pub fn gain_map(&self, w: usize, h: usize) -> Option<Vec<f32>> {
        if self.vignetting_k == 0.0 && self.prnu.is_none() {
            return None;
        }
        let mut g = vec![1.0f32; w * h * 3];
        for y in 0..h {
            for x in 0..w {
                let v = vignetting::gain(self.vignetting_k, x, y, w, h);
                for c in 0..3 {
                    let p = self
                        .prnu
                        .map_or(1.0, |(s, seed)| prnu::gain(s, seed, x, y, c));
                    g[(y * w + x) * 3 + c] = v * p;
                }
            }
        }
        Some(g)
    }

    /// Per-value fixed offset (column + DSNU + hot pixels) of a w×h frame, in DN.
    pub fn offset_map(&self, w: usize, h: usize) -> Option<Vec<f32>> {
        if self.column.is_none() && self.dsnu.is_none() && self.hot.is_none() {
            return None;
        }
        let cols: Vec<f32> = (0..w)
            .map(|x| {
                self.column
                    .map_or(0.0, |(s, seed)| column_noise::offset(s, seed, x))
            })
            .collect();
        let mut o = vec![0.0f32; w * h * 3];
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let d = self
                        .dsnu
                        .map_or(0.0, |(s, seed)| dsnu::offset(s, seed, x, y, c));
                    let hp = self.hot.map_or(0.0, |(f, off, seed)| {
                        hot_pixels::offset(f, off, seed, x, y, c)
                    });
                    o[(y * w + x) * 3 + c] = cols[x] + d + hp;
                }
            }
        }
        Some(o)
    }
}

/// A standard normal from hashed bits (Box–Muller on two 24-bit uniforms): fixed patterns are
/// a pure function of (seed, coordinates), independent of evaluation order.
pub fn hashed_normal(seed: u64, parts: &[u64]) -> f32 {
    let h = hash(seed, parts);
    let u1 = (unit_f32(h) as f64 + 0.5 / (1u64 << 24) as f64).min(1.0);
    let u2 = unit_f32(crate::rng::mix64(h ^ 0x5851_f42d_4c95_7f2d)) as f64;
    ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
}

/// A uniform in [0, 1) from hashed bits.
pub fn hashed_unit(seed: u64, parts: &[u64]) -> f32 {
    unit_f32(hash(seed, parts))
}

// ---------------------------------------------------------------------------------------------
// Parameters (each effect's struct: `params::parse`)

/// A pattern seed as a TOML value (62 bits, so it fits an i64).
pub fn seed_value(seed: u64) -> toml::Value {
    toml::Value::Integer((seed >> 2) as i64)
}

pub fn table(items: &[(&str, toml::Value)]) -> toml::Table {
    items
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

/// A float rounded to 4 significant digits, for params that go into reports and profiles.
pub fn float(v: f64) -> toml::Value {
    if v == 0.0 || !v.is_finite() {
        return toml::Value::Float(v);
    }
    let p = 10f64.powi(3 - v.abs().log10().floor() as i32);
    toml::Value::Float((v * p).round() / p)
}

// ---------------------------------------------------------------------------------------------
// Statistics and fits

/// One diagnostic statistic of a capture set.
#[derive(Clone, Debug, PartialEq)]
pub struct Stat {
    /// Unique within a capture set: "<burst>: <name>".
    pub key: String,
    /// The catalogue effect this statistic is specific to (None: a base-model check).
    pub effect: Option<&'static str>,
    pub value: f64,
    /// Smallest |measured − simulated| that counts as a disagreement, in the statistic's unit.
    pub min_effect: f64,
    /// Floor of the simulated standard deviation (statistics that are constant under the model).
    pub sd_floor: f64,
    pub unit: &'static str,
}

impl Stat {
    /// A DN² statistic of a dark burst (row, column or pixel offsets): the smallest effect is
    /// 2 % of the burst's temporal variance, at least 0.05 DN².
    pub fn dark_dn2(
        p: &Protocol,
        b: &Summary,
        effect: &'static str,
        name: &str,
        value: f64,
    ) -> Stat {
        Stat {
            key: format!("{}: {name}", p.bursts[b.burst].name),
            effect: Some(effect),
            value,
            min_effect: (0.02 * b.temporal_mean()).max(0.05),
            sd_floor: 1e-4,
            unit: "DN²",
        }
    }
}

/// What a fit sees.
pub struct FitCtx<'a> {
    /// Measured statistics and, aligned with them, their mean over the bootstrap replicates
    /// of the current model.
    pub measured: &'a [Stat],
    pub simulated_mean: &'a [f64],
    pub summaries: &'a [Summary],
    pub protocol: &'a Protocol,
    pub profile: &'a SensorProfile,
    /// Seed for the fitted effect's fixed pattern.
    pub seed: u64,
}

impl FitCtx<'_> {
    /// (measured, simulated mean) of this effect's statistics whose key ends with `name`.
    pub fn pairs(&self, effect: &str, name: &str) -> Vec<(f64, f64)> {
        self.measured
            .iter()
            .zip(self.simulated_mean)
            .filter(|(s, _)| s.effect == Some(effect) && s.key.ends_with(name))
            .map(|(s, m)| (s.value, *m))
            .collect()
    }

    /// This effect's statistics with their simulated mean and the burst each was measured on
    /// (keys are "<burst>: <name>").
    pub fn per_burst(&self, effect: &str) -> Vec<(&Stat, f64, &Summary)> {
        self.measured
            .iter()
            .zip(self.simulated_mean)
            .filter(|(st, _)| st.effect == Some(effect))
            .filter_map(|(st, &sim)| {
                // Burst names are free text (may hold ": "): match the whole "<burst>: " prefix.
                let b = self.summaries.iter().find(|b| {
                    let name = &self.protocol.bursts[b.burst].name;
                    st.key
                        .strip_prefix(name.as_str())
                        .is_some_and(|r| r.starts_with(": "))
                })?;
                Some((st, sim, b))
            })
            .collect()
    }

    /// σ (DN) of offsets whose variance is the mean excess of the DN² statistics `name`
    /// (`what` names them when the excess is not positive).
    pub fn excess_sigma(&self, effect: &str, name: &str, what: &str) -> Result<f64, String> {
        let v = self.mean_excess(effect, name)?;
        if v <= 0.0 {
            return Err(format!("excess {what} {v:.4} DN² is not positive"));
        }
        Ok(v.sqrt())
    }

    /// Mean of measured − simulated over this effect's statistics named `name`.
    pub fn mean_excess(&self, effect: &str, name: &str) -> Result<f64, String> {
        let p = self.pairs(effect, name);
        if p.is_empty() {
            return Err(format!("no '{name}' statistic in these captures"));
        }
        Ok(p.iter().map(|(m, s)| m - s).sum::<f64>() / p.len() as f64)
    }
}

/// Mean of `v` over indices where `keep` holds.
pub fn masked_mean(v: &[f64], keep: impl Fn(usize) -> bool) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for (i, x) in v.iter().enumerate() {
        if keep(i) {
            s += x;
            n += 1;
        }
    }
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// Bursts of one kind.
pub fn of_kind(s: &[Summary], kind: BurstKind) -> impl Iterator<Item = &Summary> {
    s.iter().filter(move |b| b.kind == kind)
}
