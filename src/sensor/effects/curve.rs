//! The response curve of the `nonlinear_response` effect, shared by that effect and the
//! statistics' protocol ([`super::summary::Protocol`]).

use super::{float, table};

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
