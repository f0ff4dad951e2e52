//! Auto-exposure: how the camera picks the reference (EV0) exposure of a bracket. One rule for
//! training realism and for `hdrsynth testset`, so training frames and test frames are exposed
//! alike (docs/sensor.md, "Exposure").
//!
//! The rule is a phone's average metering with highlight protection:
//! 1. average metering: the scene's log-average luminance (geometric mean, Reinhard's "key")
//!    lands at `mid_grey` of sensor white; the default 0.128 is where ISO 12232's
//!    saturation-based speed puts an 18 % grey card (18 / 141 of saturation: half a stop of
//!    headroom above a 100 % reflector);
//! 2. highlight protection: at most `max_clipped` of the pixels reach white in any channel at
//!    EV0 (the exposure is lowered until the (1 − max_clipped) quantile of the per-pixel
//!    maximum channel sits at white).
//!
//! k = min(mid_grey / L_log-avg, 1 / Q_{1 − max_clipped}(max channel)), times a user factor.
//!
//! A device's own rule is measured from the frames its camera exposed itself
//! ([`metering_rule`], `hdrsynth calibrate brackets`) and kept in its profile; which rule
//! applies where a config or the command line also gives one is [`Metering::resolve`]'s.

use crate::config::{KeyError, Range, in_range};
use crate::io::{Image, luminance};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Metering {
    /// Fraction of sensor white the scene's log-average luminance is placed at.
    pub mid_grey: f64,
    /// Largest fraction of pixels allowed to clip (any channel ≥ white) at EV0.
    pub max_clipped: f64,
}

impl Default for Metering {
    fn default() -> Self {
        Metering {
            mid_grey: 0.128,
            max_clipped: 0.02,
        }
    }
}

/// What the rule decided for one scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exposure {
    /// Radiance → EV0 linear signal (1 = sensor white).
    pub key: f32,
    /// Whether highlight protection, not average metering, set the key.
    pub highlight_limited: bool,
}

/// Where the rule in use came from, in the order [`Metering::resolve`] tries them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RuleOrigin {
    /// Given explicitly: a config's `metering` table, `testset`'s `--mid-grey`/`--max-clipped`.
    Given,
    /// The profile's measured rule (its `[metering]`).
    Profile,
    /// Neither: [`Metering::default`].
    Default,
}

impl std::fmt::Display for RuleOrigin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            RuleOrigin::Given => "given explicitly",
            RuleOrigin::Profile => "the profile's measured rule",
            RuleOrigin::Default => "the default rule",
        })
    }
}

/// The rule that applies, and where it came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resolved {
    pub rule: Metering,
    pub origin: RuleOrigin,
}

impl std::fmt::Display for Resolved {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}; {}", self.rule, self.origin)
    }
}

impl std::fmt::Display for Metering {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "mid grey {:.4}, at most {:.2} % clipped",
            self.mid_grey,
            self.max_clipped * 100.0
        )
    }
}

impl Metering {
    /// The rule that applies: the one `given` explicitly, else the `profile`'s measured rule,
    /// else the default. A given rule replaces the profile's whole (keys it leaves out are the
    /// defaults), so two halves of different rules are never mixed.
    pub fn resolve(given: Option<Metering>, profile: Option<Metering>) -> Resolved {
        match (given, profile) {
            (Some(rule), _) => Resolved {
                rule,
                origin: RuleOrigin::Given,
            },
            (None, Some(rule)) => Resolved {
                rule,
                origin: RuleOrigin::Profile,
            },
            (None, None) => Resolved {
                rule: Metering::default(),
                origin: RuleOrigin::Default,
            },
        }
    }

    /// mid_grey in (0, 1) (a fraction of white), max_clipped in [0, 0.5) (clipping half the
    /// frame is not highlight protection); keys relative to the `metering` table.
    pub fn validate(&self) -> Result<(), KeyError> {
        in_range("mid_grey", self.mid_grey, Range::open(0.0, 1.0))?;
        in_range("max_clipped", self.max_clipped, Range::half_open(0.0, 0.5))
    }

    /// The EV0 key of a linear radiance map (any unit). Errors when the map is black.
    pub fn key(&self, radiance: &Image) -> Result<Exposure, String> {
        self.validate().map_err(|e| e.to_string())?;
        let px: Vec<(f32, f32)> = radiance
            .data
            .par_chunks_exact(3)
            .map(|p| {
                let p = [p[0].max(0.0), p[1].max(0.0), p[2].max(0.0)];
                (luminance(p), p[0].max(p[1]).max(p[2]))
            })
            .collect();
        // Black pixels carry no metering information (log 0); a meter sees them as its floor.
        let (sum, n) = px
            .iter()
            .filter(|(l, _)| *l > 0.0)
            .fold((0f64, 0usize), |(s, n), (l, _)| {
                (s + (*l as f64).ln(), n + 1)
            });
        if n == 0 {
            return Err("the radiance map is black: no exposure can be metered".into());
        }
        let average = self.mid_grey / (sum / n as f64).exp();
        let mut peak: Vec<f32> = px.into_iter().map(|(_, m)| m).collect();
        // Nearest-rank quantile: the pixel below which 1 − max_clipped of the pixels lie.
        let idx = (((1.0 - self.max_clipped) * peak.len() as f64).ceil() as usize)
            .clamp(1, peak.len())
            - 1;
        let (_, q, _) = peak.select_nth_unstable_by(idx, f32::total_cmp);
        let protect = if *q > 0.0 {
            1.0 / *q as f64
        } else {
            f64::INFINITY
        };
        Ok(Exposure {
            key: average.min(protect) as f32,
            highlight_limited: protect < average,
        })
    }
}

/// Where one set's auto-exposed frame put its signal.
#[derive(Clone, Debug, PartialEq)]
pub struct MeteredFrame {
    pub frame: PathBuf,
    /// How the frame was taken to be the auto-exposed one.
    pub how: String,
    /// exp(mean ln luminance) of the linear frame, fraction of white.
    pub log_average: f64,
    /// Fraction of pixels with a channel at or above 250/255.
    pub clipped: f64,
    /// The frame is marked as the device's own exposure (EXIF ExposureBiasValue 0 beside the
    /// others' offsets), not the middle frame of a manual bracket.
    pub auto_exposed: bool,
}

/// The device's exposure rule as a [`Metering`], from the sets whose auto-exposed frame EXIF
/// marks: the geometric mean of their log-average luminances (`mid_grey`) and the most any of
/// them let clip (`max_clipped`). `None` when no set marks one (a manual bracket says nothing
/// about the device's meter).
pub fn metering_rule(frames: &[MeteredFrame]) -> Option<Metering> {
    let auto: Vec<&MeteredFrame> = frames.iter().filter(|m| m.auto_exposed).collect();
    if auto.is_empty() {
        return None;
    }
    let ln = auto
        .iter()
        .map(|m| m.log_average.max(1e-6).ln())
        .sum::<f64>()
        / auto.len() as f64;
    Some(Metering {
        mid_grey: ln.exp().clamp(1e-4, 0.99),
        max_clipped: auto.iter().map(|m| m.clipped).fold(0.0, f64::max).min(0.49),
    })
}

/// [`metering_rule`] with the provenance line a profile keeps for it: the bracket folder, the
/// frames it was measured on and how.
pub fn measured_rule(dir: &Path, frames: &[MeteredFrame]) -> Option<(Metering, String)> {
    let rule = metering_rule(frames)?;
    let names: Vec<String> = frames
        .iter()
        .filter(|m| m.auto_exposed)
        .map(|m| m.frame.display().to_string())
        .collect();
    let why = format!(
        "the device's auto-exposed frames (EXIF ExposureBiasValue 0 beside the other frames' \
         offsets) of bracket folder {} (`hdrsynth calibrate brackets`): {}; mid_grey = the \
         geometric mean of their log-average luminance (fraction of white), max_clipped = the \
         largest fraction of pixels any of them clipped",
        dir.display(),
        names.join(", ")
    );
    Some((rule, why))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(values: &[[f32; 3]]) -> Image {
        let mut img = Image::new(values.len(), 1);
        for (d, v) in img.data.chunks_exact_mut(3).zip(values) {
            d.copy_from_slice(v);
        }
        img
    }

    #[test]
    fn a_flat_grey_scene_lands_at_mid_grey() {
        // Log-average of a constant 0.5 is 0.5: k = 0.128 / 0.5; nothing clips.
        let e = Metering::default().key(&image(&[[0.5; 3]; 100])).unwrap();
        assert!((e.key - 0.256).abs() < 1e-6, "{e:?}");
        assert!(!e.highlight_limited);
    }

    #[test]
    fn bright_highlights_over_the_budget_lower_the_exposure() {
        // 90 pixels at 0.1 and 10 at 100 (10 % of the frame, above the 2 % budget).
        // Average metering: log-average = exp(0.9 ln 0.1 + 0.1 ln 100) = 0.1^0.9 · 100^0.1,
        // k = 0.128 / that ≈ 0.128 / 0.19953 = 0.6415, which would clip the 10 % at 64 × white.
        // Protection: the 98th-percentile maximum channel (nearest rank: 98th of 100) is 100,
        // so k = 1 / 100.
        let mut v = vec![[0.1f32; 3]; 90];
        v.extend(vec![[100.0f32; 3]; 10]);
        let e = Metering::default().key(&image(&v)).unwrap();
        assert!((e.key - 0.01).abs() < 1e-7, "{e:?}");
        assert!(e.highlight_limited);
        // With a 12 % budget the highlights may clip and average metering decides.
        let m = Metering {
            max_clipped: 0.12,
            ..Metering::default()
        };
        let e = m.key(&image(&v)).unwrap();
        let want = 0.128 / (0.1f64.powf(0.9) * 100f64.powf(0.1));
        assert!((e.key as f64 - want).abs() < 1e-6, "{e:?} vs {want}");
        assert!(!e.highlight_limited);
    }

    #[test]
    fn clipping_counts_the_brightest_channel_not_luminance() {
        // A saturated blue light: luminance 0.0722 · 50 = 3.6, but blue is 50.
        let mut v = vec![[0.2f32; 3]; 95];
        v.extend(vec![[0.0, 0.0, 50.0]; 5]);
        let e = Metering::default().key(&image(&v)).unwrap();
        assert!((e.key - 0.02).abs() < 1e-7, "{e:?}");
    }

    #[test]
    fn black_maps_and_bad_settings_are_errors() {
        assert!(Metering::default().key(&image(&[[0.0; 3]; 4])).is_err());
        let bad = Metering {
            mid_grey: 0.0,
            ..Metering::default()
        };
        assert!(bad.key(&image(&[[1.0; 3]; 4])).is_err());
    }
}
