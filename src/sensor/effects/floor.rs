//! `floor`: the device's processing subtracts a pedestal from the linear signal before its
//! response, crushing every signal under `threshold` (a fraction of the white level) to code 0
//! and stretching the rest back to white: x → max(0, x − t)/(1 − t), applied after the noise
//! and the DN quantisation, at the output response (an ISP's black point, set above the
//! sensor's). Radiance under t then leaves the camera as the noise about code 0 only: codes
//! that carry no radiance, which no response curve can linearise.
//!
//! Raw bursts cannot show it (it is the output's, not the sensor's). Its statistic and fit are
//! the device-output check's on a bracket folder (src/capture/output/floor.rs): the mean code
//! of the pixels a longer frame of the same set puts between codes 4/255 and 16/255, against the code that
//! frame predicts through the profile's response, real and simulated alike.

use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary, not_fitted, table};
use crate::error::Result;

pub const ID: &str = id::FLOOR;

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "output black point above the sensor's: x → max(0, x − t)/(1 − t) at the response",
    needs: "a bracket folder (the device-output check: `diagnose --brackets --device-output`, \
            `hdrsynth loop`)",
    statistics,
    fit,
    adjust: None,
};

/// The normalised signal `x` (1 = white) after a floor `t`: what the response then encodes.
pub fn crush(x: f64, t: f64) -> f64 {
    if t <= 0.0 {
        return x;
    }
    ((x - t) / (1.0 - t)).max(0.0)
}

/// Raw bursts hold no statistic of an output-domain effect.
fn statistics(_: &Protocol, _: &[Summary], _: &mut Vec<Stat>) {}

fn fit(_: &FitCtx) -> Result<toml::Table> {
    Err(not_fitted(
        ID,
        "an output-domain effect: fitted from a bracket folder by the device-output check",
    ))
}

/// The effect's table for a threshold `t`.
pub fn params(t: f64) -> toml::Table {
    table(&[("threshold", super::float(t))])
}
