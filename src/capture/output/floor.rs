//! The device-output check's floor statistic and the fit of the catalogue's `floor` effect
//! (src/sensor/effects/floor.rs) from a bracket folder.
//!
//! The statistic reads the radiance → code map under the toe from the frames that see those
//! pixels at mid codes: for each frame, each value that a frame of the same set exposed at
//! least twice as long holds at a mid code (26–230 of 255) is predicted at the shorter
//! exposure through the profile's response (the longer frame's code linearised, scaled by the
//! exposure ratio, encoded back); where that prediction is between codes 4/255 and 16/255 —
//! where the map must rise out of the noise about code 0 — the frame's own code is compared
//! with it. The statistic is the mean of (code − predicted code) over those
//! values, ×255, on the real frames and on every simulated replicate alike. A device whose
//! processing crushes its shadows (the 550D: radiance that predicts code 12 comes out at 4)
//! shows a negative value the simulation without a floor lacks. Under code 4/255 the codes are
//! the noise about code 0, whose mean the floor's threshold does not set; the band leaves them
//! out.

use super::effects::with_effect;
use super::{OutputCheck, OutputCheckOptions, Prepared, check_prepared};
use crate::capture::scan;
use crate::error::Result;
use crate::io::Image;
use crate::sensor::effects::floor::{self as effect, ID};
use crate::sensor::effects::plan::FLOOR_MAX;
use crate::sensor::profile::{Response, SensorProfile};

/// Codes at which a longer frame reads a pixel's radiance.
const MID: (f32, f32) = (26.0 / 255.0, 230.0 / 255.0);
/// Predicted codes in this band are the statistic's: where the radiance → code map must rise
/// out of the noise about code 0 (under 4/255 the noise's own mean, not the map, sets the
/// codes).
pub(super) const BAND: (f64, f64) = (4.0 / 255.0, 16.0 / 255.0);
/// A longer frame reads a shorter one's radiance where it is exposed at least this much longer.
const MIN_RATIO: f64 = 2.0;
/// Entries of the prediction table over the longer frame's code.
const TABLE: usize = 4096;
/// Fewer values than this: no statistic (NaN).
const MIN_VALUES: f64 = 200.0;

/// Sums over the values the statistic reads: the frames' codes and the codes predicted there.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct FloorMoments {
    code: f64,
    predicted: f64,
    n: f64,
}

impl FloorMoments {
    pub fn add(&mut self, o: &FloorMoments) {
        self.code += o.code;
        self.predicted += o.predicted;
        self.n += o.n;
    }

    /// Mean (code − predicted) ×255, NaN with too few values.
    pub fn value(&self) -> f64 {
        if self.n < MIN_VALUES {
            f64::NAN
        } else {
            255.0 * (self.code - self.predicted) / self.n
        }
    }
}

/// The moments of one set: `frames` (codes of one window) exposed for `times`.
pub(super) fn moments(frames: &[&Image], times: &[f64], response: &Response) -> FloorMoments {
    let mut m = FloorMoments::default();
    for (i, frame) in frames.iter().enumerate() {
        // The longer frames, shortest first: the first at a mid code reads the value.
        let mut longer: Vec<usize> = (0..frames.len())
            .filter(|&j| times[j] >= MIN_RATIO * times[i])
            .collect();
        longer.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
        let tables: Vec<Vec<f32>> = longer
            .iter()
            .map(|&j| prediction_table(response, times[i] / times[j]))
            .collect();
        for (k, &u) in frame.data.iter().enumerate() {
            let read = longer.iter().zip(&tables).find_map(|(&j, t)| {
                let v = frames[j].data[k];
                (MID.0..=MID.1)
                    .contains(&v)
                    .then(|| t[(v * (TABLE - 1) as f32).round() as usize])
            });
            if let Some(p) = read.filter(|&p| (BAND.0..BAND.1).contains(&(p as f64))) {
                m.code += u as f64;
                m.predicted += p as f64;
                m.n += 1.0;
            }
        }
    }
    m
}

/// The code predicted at exposure `ratio` of a longer frame's code k/(TABLE − 1).
fn prediction_table(response: &Response, ratio: f64) -> Vec<f32> {
    (0..TABLE)
        .map(|k| response.apply(response.invert(k as f64 / (TABLE - 1) as f64) * ratio) as f32)
        .collect()
}

/// `profile` with the output floor `t` (any floor it held replaced).
pub fn with_floor(profile: &SensorProfile, t: f64) -> SensorProfile {
    let note = format!(
        "an output floor at {t:.3e} of white fitted to the frames' codes under the toe (the \
         device-output check's floor statistic)"
    );
    with_effect(profile, ID, effect::params(t), &note)
}

/// What [`fit_floor`] found.
#[derive(Clone, Debug)]
pub struct FloorFit {
    pub threshold: f64,
    /// The fit reached [`FLOOR_MAX`] without closing the gap: not a step to hand on.
    pub at_bound: bool,
    pub profile: SensorProfile,
    /// The check of `profile`.
    pub check: OutputCheck,
}

/// Simulated replicates of each evaluation of the fit (the same seeds for every threshold, so
/// the statistic moves with the threshold alone).
const FIT_REPLICATES: usize = 4;
/// Bisection steps on ln t.
const FIT_STEPS: usize = 14;
/// Smallest threshold the fit tells from none.
const FLOOR_MIN: f64 = 1e-5;

/// The output floor that makes the simulated floor statistic match the frames': a bisection
/// on ln t over [1e-5, [`FLOOR_MAX`]], the statistic falling as t grows, each point the mean
/// of [`FIT_REPLICATES`] simulations of the frames the statistic reads. `first` is the check
/// of `profile`. An error (a key error on `floor`) where the frames' codes are not under the
/// simulated ones: no floor closes that.
pub fn fit_floor(
    scan: &scan::BracketScan,
    profile: &SensorProfile,
    first: &OutputCheck,
    opts: &OutputCheckOptions,
) -> Result<FloorFit> {
    let prep = Prepared::new(scan.clone(), profile)?;
    let measured = first.floor_stat().measured;
    if !measured.is_finite() {
        return Err(crate::sensor::effects::not_fitted(
            ID,
            "no value of these frames is read by a longer frame at a mid code and predicted \
             between codes 4/255 and 16/255",
        ));
    }
    let at = |t: f64| prep.floor_value(&with_floor(profile, t), opts, FIT_REPLICATES);
    let none = at(0.0)?;
    if !none.is_finite() {
        return Err(crate::sensor::effects::not_fitted(
            ID,
            "the simulated frames hold too few values between codes 4/255 and 16/255 for the \
             statistic",
        ));
    }
    if measured >= none {
        return Err(crate::sensor::effects::not_fitted(
            ID,
            format!(
                "the frames' codes under the toe are {measured:+.2} from their prediction, the \
                 simulation's without a floor {none:+.2}: a floor only lowers them"
            ),
        ));
    }
    let (mut lo, mut hi) = (FLOOR_MIN.ln(), FLOOR_MAX.ln());
    // A point without a value (every replicate too few values) counts as still above.
    let above = |t: f64| -> Result<bool> {
        let v = at(t)?;
        Ok(v.is_nan() || v > measured)
    };
    let at_bound = above(FLOOR_MAX)?;
    if !at_bound {
        for _ in 0..FIT_STEPS {
            let mid = 0.5 * (lo + hi);
            if above(mid.exp())? {
                lo = mid;
            } else {
                hi = mid;
            }
        }
    }
    let threshold = if at_bound {
        FLOOR_MAX
    } else {
        (0.5 * (lo + hi)).exp()
    };
    let profile = with_floor(profile, threshold);
    let check = check_prepared(&prep, &profile, opts)?;
    Ok(FloorFit {
        threshold,
        at_bound,
        profile,
        check,
    })
}
