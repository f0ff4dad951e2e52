//! The notes of a diagnosis: what the report says beside the steps.

use crate::sensor::effects;

/// What the report notes beside the steps; each reads as one sentence (`Display`).
#[derive(Clone, Debug, PartialEq)]
pub enum Note {
    /// Bursts over `max_pixels` analysed on bands of rows: "'name' rows of full_rows" each.
    Banded {
        max_pixels: usize,
        bursts: Vec<String>,
    },
    /// No noise calibration (the error), so the base model is noise-free.
    NoCalibration(String),
    /// Scene bursts without a `scene` key grouped by frame size: each group's burst names.
    GroupedBySize(Vec<String>),
    /// An effect named by statistic `key` whose fit failed.
    NotFitted {
        effect: String,
        key: String,
        why: String,
    },
    /// An effect whose fitted parameters the profile refuses.
    Rejected { effect: String, why: String },
    /// An effect fitted and added that did not shrink the gap.
    NotKept {
        effect: String,
        evidence: String,
        gap_before: f64,
        gap_after: f64,
    },
    /// An exposure pair left unexplained that scales as exposure^measured.
    ToneCurve {
        key: String,
        measured: f64,
        simulated: f64,
    },
}

impl std::fmt::Display for Note {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Note::Banded { max_pixels, bursts } => write!(
                f,
                "bursts over {} pixels were analysed on evenly spread bands of {} rows, measured \
                 and simulated alike (rows: {}); --max-pixels 0 analyses every row (slower, more \
                 power)",
                max_pixels,
                effects::summary::BAND,
                bursts.join(", ")
            ),
            Note::NoCalibration(e) => write!(
                f,
                "no noise calibration ({e}): the base model is noise-free, so only statistics of \
                 means (response, exposure ratios) are compared"
            ),
            Note::GroupedBySize(groups) => write!(
                f,
                "scene bursts without a `scene` key were grouped by frame size, one size taken as \
                 one scene ({}); declare `scene = \"…\"` on each scene burst in captures.toml to \
                 group them explicitly",
                groups.join("; ")
            ),
            Note::NotFitted { effect, key, why } => {
                write!(f, "{effect} named by {key} but not fitted: {why}")
            }
            Note::Rejected { effect, why } => {
                write!(f, "{effect}: fitted parameters rejected: {why}")
            }
            Note::NotKept {
                effect,
                evidence,
                gap_before,
                gap_after,
            } => write!(
                f,
                "{effect} named by {evidence} but adding it did not shrink the gap ({gap_before:.2} \
                 → {gap_after:.2}); not kept"
            ),
            Note::ToneCurve {
                key,
                measured,
                simulated,
            } => write!(
                f,
                "{key}: the signal scales as exposure^{measured:.3} instead of \
                 exposure^{simulated:.3}: the frames hide a tone curve (not linear sensor data); a \
                 curve that differs between scenes is outside the catalogue's response shapes \
                 (power law, toe, shoulder)"
            ),
        }
    }
}

impl Note {
    /// Whether the note's text holds `pat`.
    pub fn contains(&self, pat: &str) -> bool {
        self.to_string().contains(pat)
    }
}
