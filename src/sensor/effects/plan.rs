//! What a profile's `[[effects]]` tables mean: each effect's parameters, their checks, and the
//! [`Plan`] the realism operator applies, compiled from them.
//!
//! This is the plain-data part of the catalogue. The profile stores [`EffectSpec`]s and checks
//! them here when it is loaded; the effect files above it (statistics, fits, adjustments of a
//! profile, the fixed patterns' pixel values) use the profile. So the profile depends on this
//! file and this file on nothing above it: only parameter parsing ([`super::params`]) and the
//! response curve ([`super::curve`]).

use super::curve::{Curve, curve};
use super::params::{Finite, OffsetPattern, Seed, Triple, fault, parse};
use crate::config::KeyError;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// An extra physical effect, applied by the realism operator in physical order. Filled by the
/// gap workflow; `id` must name an effect of the catalogue (src/sensor/effects/).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EffectSpec {
    pub id: String,
    #[serde(flatten)]
    pub params: toml::Table,
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
    pub response: Option<Curve>,
    /// Channel noise: multipliers on a and b per channel.
    pub a_scale: [f32; 3],
    pub b_scale: [f32; 3],
    /// Heavy-tailed read noise: Student-t degrees of freedom.
    pub heavy_dof: Option<f32>,
    /// Correlated noise: half kernels (k(0)..k(R)) filtering the normal draws horizontally
    /// and vertically (separable, Σk² = 1 over each full kernel).
    pub corr_kernels: Option<(Vec<f32>, Vec<f32>)>,
    /// Channel correlation: each pixel's three normal draws mixed as a·z_c + b·z̄√3 (z̄ their
    /// mean), which keeps unit variance and correlates every two channels by ρ.
    pub channel_mix: Option<(f32, f32)>,
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
    /// Local gain: a smooth gain field per frame (σ of ln gain, correlation length in pixels),
    /// applied to the DN frame before the output response.
    pub local_gain: Option<(f32, f32)>,
    /// Output floor: the fraction of white the output response subtracts first (0: none).
    pub floor: f64,
    /// JPEG storage at this IJG quality.
    pub jpeg: Option<u8>,
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
            channel_mix: None,
            black_offset: 0.0,
            row_sigma: 0.0,
            column: None,
            dsnu: None,
            hot: None,
            local_gain: None,
            floor: 0.0,
            jpeg: None,
        }
    }
}

impl Plan {
    pub fn from_effects(effects: &[EffectSpec]) -> Result<Plan> {
        Self::compile(effects).map_err(|(_, e)| e)
    }

    /// [`Plan::from_effects`]'s checks as a profile's key rule: an error names the
    /// `effects[i]` table and, in its message, the parameter.
    pub fn check(effects: &[EffectSpec]) -> Result<(), KeyError> {
        Self::compile(effects)
            .map(|_| ())
            .map_err(|(i, e)| KeyError::new(format!("effects[{i}]"), e.to_string()))
    }

    /// The plan, or the index of the first effect refused and why.
    fn compile(effects: &[EffectSpec]) -> Result<Plan, (usize, Error)> {
        let mut plan = Plan::default();
        let mut seen = Vec::new();
        for (i, e) in effects.iter().enumerate() {
            let (_, install) = INSTALL.iter().find(|(id, _)| *id == e.id).ok_or_else(|| {
                let m = format!(
                    "'{}' is not in this build's effect catalogue ({})",
                    e.id,
                    ids().join(", ")
                );
                (i, Error::key("effects", m))
            })?;
            if seen.contains(&e.id) {
                let m = format!("'{}' is listed twice", e.id);
                return Err((i, Error::key("effects", m)));
            }
            seen.push(e.id.clone());
            install(&e.params, &mut plan).map_err(|err| (i, err))?;
        }
        Ok(plan)
    }

    /// True when the plan changes nothing in the pixel loop (the realism fast path): the
    /// noise scales act on a and b, the floor on the output table, the local gain and JPEG on
    /// the whole frame.
    pub fn per_pixel_neutral(&self) -> bool {
        let d = Plan::default();
        Plan {
            a_scale: d.a_scale,
            b_scale: d.b_scale,
            local_gain: d.local_gain,
            floor: d.floor,
            jpeg: d.jpeg,
            ..self.clone()
        } == d
    }
}

/// The effects' ids (each effect file's `ID`).
pub mod id {
    pub const VIGNETTING: &str = "vignetting";
    pub const PRNU: &str = "prnu";
    pub const NONLINEAR_RESPONSE: &str = "nonlinear_response";
    pub const CHANNEL_NOISE: &str = "channel_noise";
    pub const HEAVY_TAILED_READ_NOISE: &str = "heavy_tailed_read_noise";
    pub const CORRELATED_NOISE: &str = "correlated_noise";
    pub const CHANNEL_CORRELATION: &str = "channel_correlation";
    pub const BLACK_LEVEL: &str = "black_level";
    pub const ROW_NOISE: &str = "row_noise";
    pub const COLUMN_NOISE: &str = "column_noise";
    pub const DSNU: &str = "dsnu";
    pub const HOT_PIXELS: &str = "hot_pixels";
    pub const LOCAL_GAIN: &str = "local_gain";
    pub const FLOOR: &str = "floor";
    pub const JPEG: &str = "jpeg";
}

/// Check an effect's parameters and add it to the plan (an error names the effect:
/// [`fault`]).
type Install = fn(&toml::Table, &mut Plan) -> Result<()>;

/// Every effect's install, in physical order (the order of `effects::CATALOGUE`).
const INSTALL: [(&str, Install); 15] = [
    (id::VIGNETTING, vignetting),
    (id::PRNU, prnu),
    (id::NONLINEAR_RESPONSE, nonlinear_response),
    (id::CHANNEL_NOISE, channel_noise),
    (id::HEAVY_TAILED_READ_NOISE, heavy_tailed_read_noise),
    (id::CORRELATED_NOISE, correlated_noise),
    (id::CHANNEL_CORRELATION, channel_correlation),
    (id::BLACK_LEVEL, black_level),
    (id::ROW_NOISE, row_noise),
    (id::COLUMN_NOISE, column_noise),
    (id::DSNU, dsnu),
    (id::HOT_PIXELS, hot_pixels),
    (id::LOCAL_GAIN, local_gain),
    (id::FLOOR, floor),
    (id::JPEG, jpeg),
];

/// Ids of the effects this build implements, in physical order.
pub fn ids() -> Vec<&'static str> {
    INSTALL.iter().map(|(id, _)| *id).collect()
}

// ---------------------------------------------------------------------------------------------
// Each effect's parameters (the effect files' module docs say what they mean)

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Vignetting {
    strength: Finite,
}

fn vignetting(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let Vignetting {
        strength: Finite(k),
    } = parse(id::VIGNETTING, p)?;
    if !(0.0..1.0).contains(&k) {
        return Err(fault(
            id::VIGNETTING,
            format!("strength {k} must be in [0, 1)"),
        ));
    }
    plan.vignetting_k = k as f32;
    Ok(())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Prnu {
    sigma: Finite,
    seed: Seed,
}

fn prnu(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let Prnu {
        sigma: Finite(s),
        seed,
    } = parse(id::PRNU, p)?;
    if !(0.0..0.5).contains(&s) {
        return Err(fault(id::PRNU, format!("sigma {s} must be in [0, 0.5)")));
    }
    plan.prnu = Some((s as f32, seed.0));
    Ok(())
}

fn nonlinear_response(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    plan.response = Some(curve(p)?);
    Ok(())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ChannelNoise {
    a_scale: Triple,
    b_scale: Triple,
}

fn channel_noise(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let ChannelNoise {
        a_scale: Triple(a),
        b_scale: Triple(b),
    } = parse(id::CHANNEL_NOISE, p)?;
    for c in 0..3 {
        plan.a_scale[c] *= a[c] as f32;
        plan.b_scale[c] *= b[c] as f32;
    }
    Ok(())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct HeavyTailedReadNoise {
    dof: Finite,
}

fn heavy_tailed_read_noise(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let HeavyTailedReadNoise { dof: Finite(d) } = parse(id::HEAVY_TAILED_READ_NOISE, p)?;
    if !(d > 4.0 && d.is_finite()) {
        return Err(fault(
            id::HEAVY_TAILED_READ_NOISE,
            format!("dof {d} must be > 4 (finite kurtosis)"),
        ));
    }
    plan.heavy_dof = Some(d as f32);
    Ok(())
}

/// Largest lag-1 correlation of the correlated-noise family (kernel radius 7).
pub const RHO_MAX: f64 = 0.95;

/// Half kernel (k(0), k(1), …, k(R)) of width `s`, normalised so the full kernel has Σk² = 1.
pub fn kernel(s: f64) -> Vec<f64> {
    if s <= 0.0 {
        return vec![1.0];
    }
    let r = (3.0 * s).ceil().max(1.0) as usize;
    let mut k: Vec<f64> = (0..=r)
        .map(|i| (-((i * i) as f64) / (2.0 * s * s)).exp())
        .collect();
    let ss = k[0] * k[0] + 2.0 * k[1..].iter().map(|v| v * v).sum::<f64>();
    for v in &mut k {
        *v /= ss.sqrt();
    }
    k
}

/// Lag-`d` correlation of white noise filtered by the full kernel of half kernel `k`.
pub fn lag_correlation(k: &[f64], d: usize) -> f64 {
    let r = k.len() as isize - 1;
    let at = |i: isize| {
        if i.abs() <= r {
            k[i.unsigned_abs()]
        } else {
            0.0
        }
    };
    (-r..=r).map(|i| at(i) * at(i + d as isize)).sum()
}

/// Kernel width whose lag-1 correlation is `rho` (bisection; the correlation grows with s).
pub fn width(rho: f64) -> f64 {
    if rho <= 0.0 {
        return 0.0;
    }
    crate::stats::bisect(0.0, 4.0, 60, |s| lag_correlation(&kernel(s), 1) < rho)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CorrelatedNoise {
    rho: Option<Finite>,
    rho_h: Option<Finite>,
    rho_v: Option<Finite>,
}

fn rho(r: Option<Finite>, key: &str) -> Result<Option<f64>> {
    match r {
        Some(Finite(r)) if !(0.0..=RHO_MAX).contains(&r) => Err(fault(
            id::CORRELATED_NOISE,
            format!("{key} {r} must be in [0, {RHO_MAX}]"),
        )),
        r => Ok(r.map(|r| r.0)),
    }
}

fn correlated_noise(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let CorrelatedNoise {
        rho: r,
        rho_h,
        rho_v,
    } = parse(id::CORRELATED_NOISE, p)?;
    let both = rho(r, "rho")?;
    let (h, v) = (rho(rho_h, "rho_h")?.or(both), rho(rho_v, "rho_v")?.or(both));
    let (Some(h), Some(v)) = (h, v) else {
        return Err(fault(
            id::CORRELATED_NOISE,
            "needs rho_h and rho_v (or rho for both axes)",
        ));
    };
    let f = |r: f64| kernel(width(r)).iter().map(|&x| x as f32).collect();
    plan.corr_kernels = Some((f(h), f(v)));
    Ok(())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ChannelCorrelation {
    rho: Finite,
}

/// The mix (a, b) of [`Plan::channel_mix`] for correlation `rho` between every two channels:
/// with s = z̄√3 (unit variance, correlation 1/√3 with each z_c), a·z_c + b·s has variance
/// a² + 2ab/√3 + b² = 1 and covariance 2ab/√3 + b² = ρ with the other channels' — so
/// a = √(1 − ρ) and b = −a/√3 + √(a²/3 + ρ).
pub fn channel_mix(rho: f64) -> (f64, f64) {
    let a = (1.0 - rho).sqrt();
    let r3 = 3f64.sqrt();
    (a, -a / r3 + (a * a / 3.0 + rho).sqrt())
}

fn channel_correlation(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let ChannelCorrelation { rho: Finite(r) } = parse(id::CHANNEL_CORRELATION, p)?;
    if !(0.0..=RHO_MAX).contains(&r) {
        return Err(fault(
            id::CHANNEL_CORRELATION,
            format!("rho {r} must be in [0, {RHO_MAX}]"),
        ));
    }
    let (a, b) = channel_mix(r);
    plan.channel_mix = Some((a as f32, b as f32));
    Ok(())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BlackLevel {
    offset_dn: Finite,
}

fn black_level(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let BlackLevel { offset_dn } = parse(id::BLACK_LEVEL, p)?;
    plan.black_offset += offset_dn.0 as f32;
    Ok(())
}

/// `row_noise`'s parameters (its adjustment of a profile reads them too).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RowNoise {
    pub sigma_dn: Finite,
}

fn row_noise(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let RowNoise {
        sigma_dn: Finite(s),
    } = parse(id::ROW_NOISE, p)?;
    if s < 0.0 {
        return Err(fault(id::ROW_NOISE, format!("sigma_dn {s} must be ≥ 0")));
    }
    plan.row_sigma = s as f32;
    Ok(())
}

fn column_noise(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    plan.column = Some(parse::<OffsetPattern>(id::COLUMN_NOISE, p)?.checked(id::COLUMN_NOISE)?);
    Ok(())
}

fn dsnu(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    plan.dsnu = Some(parse::<OffsetPattern>(id::DSNU, p)?.checked(id::DSNU)?);
    Ok(())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct HotPixels {
    fraction: Finite,
    offset_dn: Finite,
    seed: Seed,
}

fn hot_pixels(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let HotPixels {
        fraction: Finite(f),
        offset_dn: Finite(o),
        seed,
    } = parse(id::HOT_PIXELS, p)?;
    if !(0.0..0.1).contains(&f) || o < 0.0 {
        let m = format!("fraction {f} must be in [0, 0.1) and offset_dn {o} ≥ 0");
        return Err(fault(id::HOT_PIXELS, m));
    }
    plan.hot = Some((f as f32, o as f32, seed.0));
    Ok(())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LocalGain {
    sigma: Finite,
    scale: Finite,
}

/// Largest local gain, σ of ln gain: ±1 σ is then ±35 %, more than any tone mapper's
/// disagreement between the frames of a static scene.
pub const LOCAL_GAIN_MAX: f64 = 0.3;

fn local_gain(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let LocalGain {
        sigma: Finite(sigma),
        scale: Finite(scale),
    } = parse(id::LOCAL_GAIN, p)?;
    if !(0.0..=LOCAL_GAIN_MAX).contains(&sigma) || !(1.0..=4096.0).contains(&scale) {
        return Err(fault(
            id::LOCAL_GAIN,
            format!(
                "sigma {sigma} must be in [0, {LOCAL_GAIN_MAX}] (ln gain) and scale {scale} in \
                 [1, 4096] (pixels)"
            ),
        ));
    }
    plan.local_gain = Some((sigma as f32, scale as f32));
    Ok(())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Floor {
    threshold: Finite,
}

/// Largest output floor, a fraction of white: beyond it a fit is papering over a wrong
/// response, not finding a black point.
pub const FLOOR_MAX: f64 = 0.05;

fn floor(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let Floor {
        threshold: Finite(t),
    } = parse(id::FLOOR, p)?;
    if !(0.0..=FLOOR_MAX).contains(&t) {
        return Err(fault(
            id::FLOOR,
            format!("threshold {t} must be in [0, {FLOOR_MAX}] (a fraction of white)"),
        ));
    }
    plan.floor = t;
    Ok(())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Jpeg {
    quality: Finite,
}

fn jpeg(p: &toml::Table, plan: &mut Plan) -> Result<()> {
    let Jpeg { quality: Finite(q) } = parse(id::JPEG, p)?;
    if !(1.0..=100.0).contains(&q) || q.fract() != 0.0 {
        return Err(fault(
            id::JPEG,
            format!("quality {q} must be a whole number in [1, 100] (IJG quality)"),
        ));
    }
    plan.jpeg = Some(q as u8);
    Ok(())
}
