//! report.md, report.json and the files `hdrsynth diagnose` writes.

use super::{Diagnosis, Evaluation, REPORT_FORMAT, Row, plots};
use crate::error::{Error, Result};
use crate::sensor::effects;
use std::fmt::Write as _;
use std::path::Path;

fn fmt_num(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e4 || v.abs() < 1e-3 {
        format!("{v:.3e}")
    } else {
        format!("{v:.4}")
    }
}

pub(super) fn evidence(r: &Row) -> String {
    let unit = if r.stat.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", r.stat.unit)
    };
    format!(
        "{} {}{unit} vs {} ± {} simulated (z = {:.1})",
        r.stat.key,
        fmt_num(r.stat.value),
        fmt_num(r.sim_mean),
        fmt_num(r.sim_sd),
        r.z
    )
}

/// serde_json's compact output with a space after `:` and `,`, and floats as Rust prints them
/// (`0.25`, `1148.0`, never an exponent): report.json's layout.
struct Spaced;

impl serde_json::ser::Formatter for Spaced {
    fn begin_array_value<W: ?Sized + std::io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> std::io::Result<()> {
        if first { Ok(()) } else { w.write_all(b", ") }
    }

    fn begin_object_key<W: ?Sized + std::io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> std::io::Result<()> {
        self.begin_array_value(w, first)
    }

    fn begin_object_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        w.write_all(b": ")
    }

    fn write_f64<W: ?Sized + std::io::Write>(&mut self, w: &mut W, v: f64) -> std::io::Result<()> {
        let s = v.to_string();
        w.write_all(s.as_bytes())?;
        if s.contains(['.', 'e']) {
            Ok(())
        } else {
            w.write_all(b".0")
        }
    }
}

/// One JSON value in report.json's layout (non-finite numbers are `null`).
fn json<T: serde::Serialize + ?Sized>(v: &T) -> String {
    let mut out = Vec::new();
    v.serialize(&mut serde_json::Serializer::with_formatter(
        &mut out, Spaced,
    ))
    .expect("strings, numbers and TOML tables serialise to JSON");
    String::from_utf8(out).expect("serde_json writes UTF-8")
}

fn round2(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}

impl Diagnosis {
    /// The command's summary: the gap before and after, each step, what is unexplained.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "gap {:.2} → {:.2} (threshold {:.2}), {} step(s):",
            self.initial_gap(),
            self.final_gap(),
            self.threshold,
            self.steps.len()
        );
        for st in &self.steps {
            let _ = writeln!(
                s,
                "  + {} {{{}}}: {:.2} → {:.2} ({})",
                st.effect,
                st.params.to_string().trim().replace('\n', ", "),
                st.gap_before,
                st.gap_after,
                st.evidence
            );
        }
        for u in &self.unexplained {
            let _ = writeln!(s, "  unexplained: {u}");
        }
        s
    }

    /// report.json (`hdrsynth-diagnosis/1`).
    pub fn report_json(&self) -> String {
        let mut s = String::from("{\n");
        let _ = writeln!(s, "  \"format\": {},", json(REPORT_FORMAT));
        let _ = writeln!(s, "  \"threshold\": {},", json(&round2(self.threshold)));
        let _ = writeln!(
            s,
            "  \"initial_gap\": {},",
            json(&round2(self.initial_gap()))
        );
        let _ = writeln!(s, "  \"final_gap\": {},", json(&round2(self.final_gap())));
        let steps: Vec<String> = self
            .steps
            .iter()
            .map(|st| {
                format!(
                    "    {{\"effect\": {}, \"params\": {}, \"gap_before\": {}, \"gap_after\": {},\n     \"evidence\": {}}}",
                    json(&st.effect),
                    json(&st.params),
                    json(&round2(st.gap_before)),
                    json(&round2(st.gap_after)),
                    json(&st.evidence)
                )
            })
            .collect();
        if steps.is_empty() {
            s.push_str("  \"steps\": [],\n");
        } else {
            let _ = writeln!(s, "  \"steps\": [\n{}\n  ],", steps.join(",\n"));
        }
        let _ = writeln!(s, "  \"unexplained\": {},", json(&self.unexplained));
        let _ = writeln!(s, "  \"skipped\": {}", json(&self.skipped));
        s.push_str("}\n");
        s
    }

    fn table_md(e: &Evaluation) -> String {
        let mut s = String::from(
            "| statistic | effect | measured | simulated mean ± sd | z | min effect |\n|---|---|---|---|---|---|\n",
        );
        for r in &e.rows {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} ± {} | {}{:.2} | {} |",
                r.stat.key,
                r.stat.effect.unwrap_or("(base model)"),
                fmt_num(r.stat.value),
                fmt_num(r.sim_mean),
                fmt_num(r.sim_sd),
                if r.significant { "**" } else { "" },
                r.z,
                fmt_num(r.stat.min_effect)
            );
        }
        s
    }

    /// report.md: a table per step.
    pub fn report_md(&self) -> String {
        let mut s = String::from("# Sim-to-real gap diagnosis\n\n");
        let _ = writeln!(s, "Starting model: {}.\n", self.base);
        let _ = writeln!(
            s,
            "Gap = largest |z| over statistics whose |measured − simulated| exceeds their minimum \
             effect; threshold {:.2} (Bonferroni over {} statistics, α = 0.05, at least 3); {} \
             bootstrap replicates per comparison. **Bold** z: significant.\n",
            self.threshold,
            self.initial.rows.len(),
            self.replicates
        );
        let _ = writeln!(
            s,
            "Initial gap {:.2}, final gap {:.2}.\n",
            self.initial_gap(),
            self.final_gap()
        );
        let _ = writeln!(
            s,
            "## Initial comparison\n\n{}",
            Self::table_md(&self.initial)
        );
        for (i, st) in self.steps.iter().enumerate() {
            let _ = writeln!(
                s,
                "## Step {}: {}\n\nEvidence: {}.\n\nFitted parameters: `{}`.\n\nGap {:.2} → {:.2}.\n\n{}",
                i + 1,
                st.effect,
                st.evidence,
                json(&st.params),
                st.gap_before,
                st.gap_after,
                Self::table_md(&st.after)
            );
        }
        s.push_str("## Result\n\n");
        if self.steps.is_empty() {
            s.push_str("No effect named: ");
        }
        if self.unexplained.is_empty() {
            let _ = writeln!(
                s,
                "the model matches the captures (gap {:.2} ≤ threshold {:.2}).",
                self.final_gap(),
                self.threshold
            );
        } else {
            s.push_str("still over the threshold, and no catalogue effect explains it:\n\n");
            for u in &self.unexplained {
                let _ = writeln!(s, "- {u}");
            }
        }
        for n in &self.notes {
            let _ = writeln!(s, "\nNote: {n}");
        }
        if !self.skipped.is_empty() {
            s.push_str("\n## Not tested by these captures\n\n");
            for k in &self.skipped {
                let _ = writeln!(s, "- {k}");
            }
        }
        s
    }

    /// Write DIR/profile.toml, report.md, report.json and the plots, each atomically.
    pub fn write(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        self.profile.save(&dir.join("profile.toml"))?;
        crate::io::atomic::write_atomic(&dir.join("report.md"), self.report_md().as_bytes())?;
        crate::io::atomic::write_atomic(&dir.join("report.json"), self.report_json().as_bytes())?;
        let gaps: Vec<f64> = std::iter::once(self.initial_gap())
            .chain(self.steps.iter().map(|s| s.gap_after))
            .collect();
        let labels: Vec<String> = std::iter::once("base".to_string())
            .chain(self.steps.iter().map(|s| format!("+{}", s.effect)))
            .collect();
        crate::io::write_ldr(
            &dir.join("gap.png"),
            &plots::gap(&gaps, &labels, self.threshold),
            crate::io::BitDepth::Eight,
        )?;
        if !self.radial.is_empty() {
            let k = effects::Plan::from_effects(&self.profile.effects)
                .map(|p| p.vignetting_k as f64)
                .unwrap_or(0.0);
            crate::io::write_ldr(
                &dir.join("radial.png"),
                &plots::radial(&self.radial, k),
                crate::io::BitDepth::Eight,
            )?;
        }
        if let Some(cal) = &self.calibration {
            cal.write_ptc_plot(&dir.join("ptc.png"))?;
        }
        Ok(())
    }
}
