//! The response curve of the `nonlinear_response` effect and its parameters (read and
//! written), shared by that effect, the realism plan ([`super::plan::Plan`]) and the
//! statistics' protocol ([`super::summary::Protocol`]).

use super::params::{Finite, fault, float, parse, table};
use super::plan::id::NONLINEAR_RESPONSE as ID;
use crate::error::Result;
use serde::Deserialize;
use serde::de::IgnoredAny;

/// A response curve on the normalised signal u = I/R (`nonlinear_response`'s module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Curve {
    Power(f64),
    /// `toe` t ≥ 0 (0: none), `shoulder` s > 0 (∞: none).
    ToeShoulder {
        toe: f64,
        shoulder: f64,
    },
}

/// Largest normalised linear signal the inverse returns (the shoulder's inverse diverges at s).
pub(super) const MAX_LINEAR: f64 = 1e3;

impl Curve {
    pub fn apply(&self, u: f64) -> f64 {
        let u = u.max(0.0);
        match *self {
            Curve::Power(p) => u.powf(p),
            Curve::ToeShoulder { toe, shoulder } => {
                let v = (u * u + toe * toe).sqrt() - toe;
                if shoulder.is_finite() {
                    v / (1.0 + (v / shoulder).powi(4)).powf(0.25)
                } else {
                    v
                }
            }
        }
    }

    /// f⁻¹ (values at or above a shoulder's level map to `MAX_LINEAR`).
    pub fn inverse(&self, y: f64) -> f64 {
        let y = y.max(0.0);
        match *self {
            Curve::Power(p) => y.powf(1.0 / p),
            Curve::ToeShoulder { toe, shoulder } => {
                let v = if shoulder.is_finite() {
                    let q = 1.0 - (y / shoulder).powi(4);
                    if q <= 0.0 {
                        return MAX_LINEAR;
                    }
                    y / q.powf(0.25)
                } else {
                    y
                };
                ((v + toe).powi(2) - toe * toe)
                    .max(0.0)
                    .sqrt()
                    .min(MAX_LINEAR)
            }
        }
    }

    /// The shape's name as profiles and reports write it.
    pub fn shape(&self) -> &'static str {
        match *self {
            Curve::Power(_) => "power_law",
            Curve::ToeShoulder { toe, shoulder } => match (toe > 0.0, shoulder.is_finite()) {
                (true, true) => "toe_shoulder",
                (false, true) => "shoulder",
                _ => "toe",
            },
        }
    }

    /// Profile parameters (shape and its values, 4 significant digits).
    pub fn params(&self) -> toml::Table {
        let shape = ("shape", toml::Value::String(self.shape().into()));
        match *self {
            Curve::Power(p) => table(&[shape, ("exponent", float(p))]),
            Curve::ToeShoulder { toe, shoulder } => {
                let mut t = table(&[shape]);
                if toe > 0.0 {
                    t.insert("toe".into(), float(toe));
                }
                if shoulder.is_finite() {
                    t.insert("shoulder".into(), float(shoulder));
                }
                t
            }
        }
    }
}

/// The curve of a profile's `nonlinear_response` parameters (`shape` defaults to `power_law`,
/// which is what profiles written before the toe/shoulder family hold).
pub fn curve(p: &toml::Table) -> Result<Curve> {
    let shape = match p.get("shape") {
        None => "power_law",
        Some(toml::Value::String(s)) => s.as_str(),
        Some(v) => return Err(fault(ID, format!("'shape' must be a string, got {v}"))),
    };
    let (toe, shoulder) = match shape {
        "power_law" => {
            let PowerLaw {
                exponent: Finite(e),
                ..
            } = parse(ID, p)?;
            if !(0.2..=5.0).contains(&e) {
                return Err(fault(ID, format!("exponent {e} must be in [0.2, 5]")));
            }
            return Ok(Curve::Power(e));
        }
        "toe" => (Some(parse::<Toe>(ID, p)?.toe.0), None),
        "shoulder" => (None, Some(parse::<Shoulder>(ID, p)?.shoulder.0)),
        "toe_shoulder" => {
            let t: ToeShoulder = parse(ID, p)?;
            (Some(t.toe.0), Some(t.shoulder.0))
        }
        s => {
            return Err(fault(
                ID,
                format!("unknown shape '{s}' (expected power_law, toe, shoulder or toe_shoulder)"),
            ));
        }
    };
    if let Some(toe) = toe.filter(|t| !(*t > 0.0 && *t <= 0.5)) {
        return Err(fault(
            ID,
            format!("toe {toe} must be in (0, 0.5] (a fraction of the range)"),
        ));
    }
    if let Some(shoulder) = shoulder.filter(|s| !(0.2..=20.0).contains(s)) {
        return Err(fault(
            ID,
            format!("shoulder {shoulder} must be in [0.2, 20] (a fraction of the range)"),
        ));
    }
    Ok(Curve::ToeShoulder {
        toe: toe.unwrap_or(0.0),
        shoulder: shoulder.unwrap_or(f64::INFINITY),
    })
}

// The parameters of each shape (`shape` itself is read first, by `curve`).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PowerLaw {
    #[serde(rename = "shape")]
    _shape: Option<IgnoredAny>,
    exponent: Finite,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Toe {
    #[serde(rename = "shape")]
    _shape: IgnoredAny,
    toe: Finite,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Shoulder {
    #[serde(rename = "shape")]
    _shape: IgnoredAny,
    shoulder: Finite,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ToeShoulder {
    #[serde(rename = "shape")]
    _shape: IgnoredAny,
    toe: Finite,
    shoulder: Finite,
}
