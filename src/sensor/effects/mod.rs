//! The effect catalogue: each effect = simulate (applied by the realism operator in physical
//! order) + diagnostic statistics + a fit from captures, one file each.
//!
//! A profile lists effects as `[[effects]]` tables `{ id = "...", <params> }`. The realism
//! operator compiles them into a [`Plan`] (what to do at each stage of the pixel pipeline):
//! plan.rs holds each effect's parameters and their checks, the plain data the profile stores
//! and checks on load, below the profile; the effect files, which fit and adjust profiles, are
//! above it. The gap workflow (src/sensor/diagnose/) evaluates every effect's `statistics` on
//! measured and simulated capture sets and calls `fit` on the one it names.
//!
//! Physical order inside the realism operator (docs/diagnose.md):
//! signal stage (before noise): vignetting gain → PRNU gain → nonlinear response;
//! noise stage: channel noise scales a, b per channel; heavy tails replace the Gaussian read
//! noise by a Student-t of the same variance; correlated noise filters the normal draws with a
//! separable Gaussian kernel;
//! offset stage (after the black level): black-level offset, row offsets (new every frame),
//! column offsets, DSNU, hot pixels (fixed patterns); then clip and quantise;
//! output stage (at the device response): a local gain field per frame; the output floor;
//! then JPEG storage of the frame.
//!
//! Fixed patterns (column, DSNU, PRNU, hot pixels) derive from the effect's `seed` parameter
//! and the pixel coordinates, so they are the same in every frame and every run; per-frame
//! draws (row offsets, noise) come from the frame seed.

use crate::error::{Error, Result};
use crate::rng::{hash, unit_f32};
use crate::sensor::captures::BurstKind;
use crate::sensor::profile::SensorProfile;

pub mod black_level;
pub mod channel_correlation;
pub mod channel_noise;
pub mod column_noise;
pub mod correlated_noise;
pub mod curve;
pub mod dsnu;
pub mod floor;
pub mod heavy_tailed_read_noise;
pub mod hot_pixels;
pub mod jpeg;
pub mod local_gain;
pub mod nonlinear_response;
pub mod params;
pub mod plan;
pub mod prnu;
pub mod row_noise;
pub mod summary;
pub mod vignetting;

pub use params::{float, seed_value, table};
pub use plan::{EffectSpec, Plan};
pub use summary::{Protocol, Summary};

/// One catalogue entry.
pub struct Entry {
    pub id: &'static str,
    /// One line: what the effect is.
    pub about: &'static str,
    /// The bursts its statistics need (reported when a capture set has none).
    pub needs: &'static str,
    /// The effect's diagnostic statistics of one capture set (measured or simulated).
    pub statistics: fn(&Protocol, &[Summary], &mut Vec<Stat>),
    /// Fit the parameters from the captures (measured statistics against the current model's
    /// simulated ones, the measured summaries); a refusal is [`not_fitted`].
    pub fit: fn(&FitCtx) -> Result<toml::Table>,
    /// Change the rest of a *given* profile when the effect is added (e.g. row noise is already
    /// in its b, which must then shrink by its variance). A base model fitted from the captures
    /// is refitted instead (`diagnose::refit_noise`).
    pub adjust: Option<fn(&mut SensorProfile, &toml::Table)>,
}

/// The catalogue in physical order (the order `statistics` are listed in reports).
pub const CATALOGUE: [Entry; 15] = [
    vignetting::ENTRY,
    prnu::ENTRY,
    nonlinear_response::ENTRY,
    channel_noise::ENTRY,
    heavy_tailed_read_noise::ENTRY,
    correlated_noise::ENTRY,
    channel_correlation::ENTRY,
    black_level::ENTRY,
    row_noise::ENTRY,
    column_noise::ENTRY,
    dsnu::ENTRY,
    hot_pixels::ENTRY,
    local_gain::ENTRY,
    floor::ENTRY,
    jpeg::ENTRY,
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

// The plan's fixed patterns, drawn by the effects' simulation code (the plan itself is plain
// data in plan.rs, which the profile checks).
impl Plan {
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
    pub fn excess_sigma(&self, effect: &str, name: &str, what: &str) -> Result<f64> {
        let v = self.mean_excess(effect, name)?;
        if v <= 0.0 {
            return Err(not_fitted(
                effect,
                format!("excess {what} {v:.4} DN² is not positive"),
            ));
        }
        Ok(v.sqrt())
    }

    /// Mean of measured − simulated over this effect's statistics named `name`.
    pub fn mean_excess(&self, effect: &str, name: &str) -> Result<f64> {
        let p = self.pairs(effect, name);
        if p.is_empty() {
            return Err(not_fitted(
                effect,
                format!("no '{name}' statistic in these captures"),
            ));
        }
        Ok(p.iter().map(|(m, s)| m - s).sum::<f64>() / p.len() as f64)
    }
}

/// Why effect `id`'s parameters cannot be fitted from these captures: a key error on the
/// effect (the parameters it would have).
pub fn not_fitted(id: &str, why: impl ToString) -> Error {
    Error::key(id, why)
}

/// The reason in a fit's error, without the effect's name where the error is
/// [`not_fitted`]'s for `id` (the diagnosis's note names the effect itself).
pub fn why_not_fitted(id: &str, e: Error) -> String {
    match e {
        Error::Key { key, msg } if key == id => msg,
        e => e.to_string(),
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

#[cfg(test)]
mod tests {
    /// The catalogue and the plan's parameter checks list the same effects in the same order.
    #[test]
    fn catalogue_matches_plan() {
        assert_eq!(super::known(), super::plan::ids());
    }
}
