//! The calibration in the profile's convention, its provenance text and the text report.

use super::{CHANNELS, LevelSource, NoiseCalibration};
use crate::sensor::captures::BurstKind;
use crate::sensor::profile::NoiseAtIso;
use std::fmt::Write as _;

impl NoiseCalibration {
    /// The fits in the profile's normalised convention for levels (white, black):
    /// a_norm = a / (W − B), b_norm = b / (W − B)²; standard errors likewise. Negative values
    /// (possible for b when read noise is tiny) are clamped to 0; [`Self::clamped`] lists them.
    pub fn to_noise(&self, white: f64, black: f64) -> Vec<NoiseAtIso> {
        let r = white - black;
        self.isos
            .iter()
            .map(|f| NoiseAtIso {
                iso: f.iso,
                a: std::array::from_fn(|c| (f.channels[c].a / r).max(0.0)),
                b: std::array::from_fn(|c| (f.channels[c].b / (r * r)).max(0.0)),
                a_stderr: Some(std::array::from_fn(|c| f.channels[c].a_stderr / r)),
                b_stderr: Some(std::array::from_fn(|c| f.channels[c].b_stderr / (r * r))),
            })
            .collect()
    }

    /// "ISO 100 R: b = −0.3 DN²" for each fitted value below 0 (clamped by `to_noise`).
    pub fn clamped(&self) -> Vec<String> {
        let mut out = Vec::new();
        for f in &self.isos {
            for (c, ch) in f.channels.iter().enumerate() {
                for (p, v) in [("a", ch.a), ("b", ch.b)] {
                    if v < 0.0 {
                        out.push(format!(
                            "ISO {} {}: {p} = {v:.4} (DN units) < 0, written as 0",
                            f.iso, CHANNELS[c]
                        ));
                    }
                }
            }
        }
        out
    }

    /// Text for `provenance.noise`.
    pub fn provenance(&self) -> String {
        let isos: Vec<String> = self.isos.iter().map(|f| format!("{}", f.iso)).collect();
        let kinds = |k: BurstKind| self.bursts.iter().filter(|b| b.kind == k).count();
        format!(
            "hdrsynth {} calibrate noise on capture set {} ({} bursts: {} dark, {} flat, {} chart, \
             {} scene; ISO {}); black level {} DN ({}), white level {} DN ({}); per-pixel \
             temporal variance binned by mean, saturated/defective pixels excluded, weighted \
             least squares σ² = a·I + b per ISO and channel (docs/noise.md), converted to the \
             normalised convention with this profile's levels",
            env!("CARGO_PKG_VERSION"),
            self.source,
            self.bursts.len(),
            kinds(BurstKind::Dark),
            kinds(BurstKind::Flat),
            kinds(BurstKind::Chart),
            kinds(BurstKind::Scene),
            isos.join(", "),
            fmt_level(self.black_level),
            self.black_source.describe(),
            fmt_level(self.white_level),
            self.white_source.describe(),
        )
    }

    /// The report: levels, then a table per ISO and channel in DN and normalised with the
    /// levels (white, black) the profile uses.
    pub fn report(&self, white: f64, black: f64) -> String {
        let mut s = String::new();
        let frames: usize = self.bursts.iter().map(|b| b.frames).sum();
        let _ = writeln!(
            s,
            "Noise calibration of {}: {} bursts, {} frames",
            self.source,
            self.bursts.len(),
            frames
        );
        let _ = writeln!(
            s,
            "white level {} DN ({}); black level {} DN ({})",
            fmt_level(self.white_level),
            self.white_source.describe(),
            fmt_level(self.black_level),
            self.black_source.describe()
        );
        match (self.black_declared, self.black_estimated) {
            (Some(d), Some(e)) if (d - e).abs() > 0.5 => {
                let _ = writeln!(
                    s,
                    "WARNING: declared black level {} DN and the dark-frame estimate {e:.2} DN \
                     differ by {:+.2} DN",
                    fmt_level(d),
                    e - d
                );
            }
            (Some(d), Some(e)) => {
                let _ = writeln!(
                    s,
                    "declared black level {} DN agrees with the dark-frame estimate {e:.2} DN",
                    fmt_level(d)
                );
            }
            (None, Some(e)) if self.black_source != LevelSource::EstimatedFromDark => {
                let _ = writeln!(s, "dark-frame estimate of the black level: {e:.2} DN");
            }
            _ => {}
        }
        let r = white - black;
        let _ = writeln!(
            s,
            "model σ² = a·I + b, I = mean − black in DN; profile convention x = I/(W − B) with \
             W − B = {} DN: a_norm = a/(W − B), b_norm = b/(W − B)²",
            fmt_level(r)
        );
        if (white - self.white_level).abs() > 1e-9 || (black - self.black_level).abs() > 1e-9 {
            let _ = writeln!(
                s,
                "NOTE: normalised with the profile's levels (white {}, black {}), not the \
                 calibration's (white {}, black {})",
                fmt_level(white),
                fmt_level(black),
                fmt_level(self.white_level),
                fmt_level(self.black_level)
            );
        }
        let _ = writeln!(
            s,
            "\n{:>7} {:>2} {:>11} {:>10} {:>11} {:>10} {:>5} {:>8} {:>7} {:>7} {:>6} {:>7} {:>11} {:>11}",
            "ISO",
            "ch",
            "a [DN]",
            "± a",
            "b [DN²]",
            "± b",
            "bins",
            "pixels",
            "satur.",
            "defect",
            "zero",
            "χ²/dof",
            "a_norm",
            "b_norm"
        );
        for f in &self.isos {
            for (c, ch) in f.channels.iter().enumerate() {
                let _ = writeln!(
                    s,
                    "{:>7} {:>2} {:>11.5} {:>10.5} {:>11.4} {:>10.4} {:>5} {:>8} {:>7} {:>7} {:>6} {:>7.2} {:>11.4e} {:>11.4e}",
                    f.iso,
                    CHANNELS[c],
                    ch.a,
                    ch.a_stderr,
                    ch.b,
                    ch.b_stderr,
                    ch.bins.len(),
                    ch.counts.used,
                    ch.counts.saturated,
                    ch.counts.defective,
                    ch.counts.clipped_low,
                    ch.chi2_reduced,
                    ch.a.max(0.0) / r,
                    ch.b.max(0.0) / (r * r)
                );
            }
        }
        let _ = writeln!(
            s,
            "(pixels = pixel samples used; satur./defect/zero = excluded as saturated, defective \
             (hot, dead, stuck, noisy), clipped at 0 DN; summed over the ISO's bursts)"
        );
        for note in self.clamped() {
            let _ = writeln!(s, "clamped: {note}");
        }
        for note in &self.skipped {
            let _ = writeln!(s, "skipped: {note}");
        }
        s
    }
}

fn fmt_level(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{}", v as i64)
    } else {
        format!("{v:.3}")
    }
}
