//! The fit of the catalogue's `local_gain` effect (src/sensor/effects/local_gain.rs) from a
//! bracket folder: the gain field that makes the simulated frames disagree with each other as
//! much as the real ones do, at the device-output check's two block sizes.
//!
//! For each correlation length tried, a bisection on ln σ matches the 16-pixel statistic (the
//! disagreement rises with σ); of those, the length whose 4-pixel statistic then lies nearest
//! the frames' is kept. Every point is the mean of a few simulations with the same seeds, so
//! the statistic moves with the field alone.

use super::consistency::{BandMoments, SCALES};
use super::effects::with_effect;
use super::{
    OutputCheck, OutputCheckOptions, POOLED, Prepared, check_prepared, device, residualise,
    simulated_units,
};
use crate::capture::scan;
use crate::error::Result;
use crate::sensor::effects::local_gain::{self as effect, ID};
use crate::sensor::effects::not_fitted;
use crate::sensor::effects::plan::LOCAL_GAIN_MAX;
use crate::sensor::profile::SensorProfile;

/// Correlation lengths tried, pixels: from the smaller block size to four times the larger.
const LENGTHS: [f64; 4] = [4.0, 8.0, 16.0, 64.0];
/// Simulated replicates of each point of the fit.
const FIT_REPLICATES: usize = 2;
/// Bisection steps on ln σ.
const FIT_STEPS: usize = 8;
/// Smallest σ the fit tells from none.
const SIGMA_MIN: f64 = 1e-3;

/// `profile` with a local gain field of `sigma` and `scale` (any it held replaced).
pub fn with_local_gain(profile: &SensorProfile, sigma: f64, scale: f64) -> SensorProfile {
    let note = format!(
        "a local gain field (σ {sigma:.3} of ln gain, {scale:.0} px) fitted to the frames' \
         disagreement with each other (the device-output check's disagreement statistics)"
    );
    with_effect(profile, ID, effect::params(sigma, scale), &note)
}

/// What [`fit_local_gain`] found.
#[derive(Clone, Debug)]
pub struct LocalGainFit {
    pub sigma: f64,
    pub scale: f64,
    /// The fit reached [`LOCAL_GAIN_MAX`] at every length without closing the gap.
    pub at_bound: bool,
    pub profile: SensorProfile,
    /// The check of `profile`.
    pub check: OutputCheck,
}

impl Prepared {
    /// The disagreement statistics (4 and 16 px) of `profile`'s simulated frames, each the
    /// mean over `replicates` replicates that have it (NaN where none has).
    fn disagreement(
        &self,
        profile: &SensorProfile,
        opts: &OutputCheckOptions,
        replicates: usize,
    ) -> Result<[f64; 2]> {
        let profile = &device(profile);
        let (mut sum, mut n) = ([0.0; 2], [0usize; 2]);
        for r in 0..replicates {
            let (mut units, _) = simulated_units(profile, self, opts, r)?;
            residualise(&mut units, &self.groups, &profile.response)?;
            let mut m = BandMoments::default();
            for (unit, _) in &units {
                m.add(&super::consistency::moments(unit.planes()));
            }
            for s in 0..SCALES.len() {
                let v = m.value(s);
                if v.is_finite() {
                    sum[s] += v;
                    n[s] += 1;
                }
            }
        }
        Ok(std::array::from_fn(|s| {
            if n[s] == 0 {
                f64::NAN
            } else {
                sum[s] / n[s] as f64
            }
        }))
    }
}

/// The local gain field that makes the simulated frames of `profile` disagree as the frames
/// of `scan` do; `first` is the check of `profile`. A key error on `local_gain` where the
/// frames disagree no more than the simulation at 16 px: a gain field only adds disagreement.
pub fn fit_local_gain(
    scan: &scan::BracketScan,
    profile: &SensorProfile,
    first: &OutputCheck,
    opts: &OutputCheckOptions,
) -> Result<LocalGainFit> {
    let prep = Prepared::new(scan.clone(), profile)?;
    let measured: [f64; 2] = POOLED.map(|i| first.stats[i].measured);
    if !measured.iter().all(|v| v.is_finite()) {
        return Err(not_fitted(
            ID,
            "the frames hold too few blocks of recorded codes for the disagreement statistics",
        ));
    }
    let none = prep.disagreement(profile, opts, FIT_REPLICATES)?;
    // NaN (no simulated value) counts as not under the frames'.
    if none[1].is_nan() || measured[1] <= none[1] {
        return Err(not_fitted(
            ID,
            format!(
                "the frames disagree at 16 px by {:.2}, the simulation without a gain field by \
                 {:.2}: a gain field only adds disagreement",
                measured[1], none[1]
            ),
        ));
    }
    // Per length: (σ, its 4-px statistic, at the bound).
    let mut tried = Vec::new();
    for scale in LENGTHS {
        let at = |sigma: f64| {
            prep.disagreement(
                &with_local_gain(profile, sigma, scale),
                opts,
                FIT_REPLICATES,
            )
        };
        let top = at(LOCAL_GAIN_MAX)?;
        if top[1].is_nan() || top[1] < measured[1] {
            tried.push((LOCAL_GAIN_MAX, top[0], true, scale));
            continue;
        }
        let (mut lo, mut hi) = (SIGMA_MIN.ln(), LOCAL_GAIN_MAX.ln());
        for _ in 0..FIT_STEPS {
            let mid = 0.5 * (lo + hi);
            // A point without a value counts as under the frames'.
            if at(mid.exp())?[1] >= measured[1] {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let sigma = (0.5 * (lo + hi)).exp();
        tried.push((sigma, at(sigma)?[0], false, scale));
    }
    let miss = |v4: f64| {
        if v4.is_finite() {
            (v4 - measured[0]).abs()
        } else {
            f64::INFINITY
        }
    };
    let at_bound = tried.iter().all(|t| t.2);
    let &(sigma, _, _, scale) = tried
        .iter()
        .filter(|t| t.2 == at_bound)
        .min_by(|a, b| miss(a.1).total_cmp(&miss(b.1)))
        .expect("a length was tried");
    let profile = with_local_gain(profile, sigma, scale);
    let check = check_prepared(&prep, &profile, opts)?;
    Ok(LocalGainFit {
        sigma,
        scale,
        at_bound,
        profile,
        check,
    })
}
