//! The output-domain effects of the catalogue the device-output check fits to a folder
//! (`floor`, `jpeg`, `local_gain`), one interface for `diagnose --brackets --device-output` and the loop:
//! the fit, its own gap before and after, and whether it is a step to hand on.

use super::{OutputCheck, OutputCheckOptions, fit_floor, fit_jpeg, fit_local_gain};
use crate::capture::scan;
use crate::error::Result;
use crate::sensor::effects::EffectSpec;
use crate::sensor::profile::SensorProfile;

/// `profile` with effect `id` at `params` (any `id` it held replaced), `note` added to the
/// provenance of its response (the output effects act at the response).
pub(super) fn with_effect(
    profile: &SensorProfile,
    id: &str,
    params: toml::Table,
    note: &str,
) -> SensorProfile {
    let mut p = profile.clone();
    p.effects.retain(|e| e.id != id);
    p.effects.push(EffectSpec {
        id: id.into(),
        params,
    });
    p.provenance.response = format!("{}; {note}", profile.provenance.response);
    p
}

/// An output-domain effect of the catalogue fitted to a folder by the device-output check
/// (`floor`, `jpeg`, `local_gain`).
#[derive(Clone, Debug)]
pub struct EffectFit {
    pub id: &'static str,
    /// The fitted parameter in words ("threshold 4.199e-4 of white").
    pub fitted: String,
    /// The fit reached its bound without closing its statistic.
    pub at_bound: bool,
    pub profile: SensorProfile,
    /// The check of `profile`.
    pub check: OutputCheck,
}

impl EffectFit {
    /// The gap in the statistics this effect closes (their largest |z|, significant or not)
    /// in check `c`.
    pub fn own_gap(&self, c: &OutputCheck) -> f64 {
        c.stats
            .iter()
            .filter(|s| s.names == self.id)
            .map(|s| s.z.abs())
            .filter(|z| z.is_finite())
            .fold(0.0, f64::max)
    }

    /// Inside its range and its own gap smaller than in `before` (the check of the profile it
    /// was fitted to): a step to hand on.
    pub fn closes(&self, before: &OutputCheck) -> bool {
        !self.at_bound && self.own_gap(&self.check) < self.own_gap(before)
    }

    /// One sentence: the fit and what it did to its gap and the check's.
    pub fn text(&self, before: &OutputCheck) -> String {
        format!(
            "`{}` {}{}: its gap (the |z| of its statistic) {:.1} → {:.1}, the check's {:.1} → {:.1}",
            self.id,
            self.fitted,
            if self.at_bound {
                " (the fit's bound)"
            } else {
                ""
            },
            self.own_gap(before),
            self.own_gap(&self.check),
            before.gap,
            self.check.gap
        )
    }
}

/// Output-domain effects the check can fit, in the order they are fitted: the floor acts on
/// the signal the JPEG stage then stores; the local gain last, since JPEG's blocks also raise
/// the frames' disagreement, which the gain field is fitted to.
pub const OUTPUT_EFFECTS: [&str; 3] = [
    crate::sensor::effects::floor::ID,
    crate::sensor::effects::jpeg::ID,
    crate::sensor::effects::local_gain::ID,
];

/// Whether `c` names effect `id` (one of [`OUTPUT_EFFECTS`]): its statistic is significant.
pub fn names(c: &OutputCheck, id: &str) -> bool {
    c.stats.iter().any(|s| s.names == id && s.significant)
}

/// Effect `id` (one of [`OUTPUT_EFFECTS`]) fitted to `scan` on top of `profile`, whose check
/// is `first`. A refusal (no such frames, nothing a floor can close) is
/// [`crate::sensor::effects::not_fitted`]'s key error on `id`: [`refusal`] reads it.
pub fn fit_output_effect(
    id: &str,
    scan: &scan::BracketScan,
    profile: &SensorProfile,
    first: &OutputCheck,
    opts: &OutputCheckOptions,
) -> Result<EffectFit> {
    if id == crate::sensor::effects::floor::ID {
        let f = fit_floor(scan, profile, first, opts)?;
        Ok(EffectFit {
            id: crate::sensor::effects::floor::ID,
            fitted: format!("threshold {:.3e} of white", f.threshold),
            at_bound: f.at_bound,
            profile: f.profile,
            check: f.check,
        })
    } else if id == crate::sensor::effects::jpeg::ID {
        let f = fit_jpeg(scan, profile, opts)?;
        Ok(EffectFit {
            id: crate::sensor::effects::jpeg::ID,
            fitted: format!(
                "quality {} (the frames' tables, {:.2} from libjpeg's on average)",
                f.quality, f.mismatch
            ),
            at_bound: false,
            profile: f.profile,
            check: f.check,
        })
    } else if id == crate::sensor::effects::local_gain::ID {
        let f = fit_local_gain(scan, profile, first, opts)?;
        Ok(EffectFit {
            id: crate::sensor::effects::local_gain::ID,
            fitted: format!("σ {:.3} of ln gain, {:.0} px", f.sigma, f.scale),
            at_bound: f.at_bound,
            profile: f.profile,
            check: f.check,
        })
    } else {
        Err(crate::sensor::effects::not_fitted(
            id,
            "not an output-domain effect the device-output check fits",
        ))
    }
}

/// Why a fit of effect `id` was refused, in words, where `e` is its refusal; any other error
/// as it is.
pub fn refusal(id: &str, e: crate::error::Error) -> Result<String> {
    match e {
        crate::error::Error::Key { ref key, .. } if key == id => {
            Ok(crate::sensor::effects::why_not_fitted(id, e))
        }
        e => Err(e),
    }
}
