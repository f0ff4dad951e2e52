//! The main job's report after its grid: the noise ceiling, the protocol's reading of the
//! primary comparison, the secondary and descriptive rows and the held-out-simulator matrix.

use crate::experiments::ablate::{self, AblateConfig, AblateSummary, DiffEntry, TestsetSpec};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Seeds a claim about newly trained networks needs (docs/protocol.md, "Statistics").
pub(super) const MIN_SEEDS_FOR_RUNS: usize = 5;

/// Name of the dynamic test set among the grid's `also` sets.
pub(crate) const DYNAMIC: &str = "dynamic";

/// The protocol's decision on the primary comparison (docs/protocol.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    Better,
    Worse,
    Equivalent,
    Inconclusive,
}

impl Decision {
    pub fn from_diff(d: &DiffEntry, alpha: f64) -> Decision {
        let Some(t) = &d.t else {
            return Decision::Inconclusive;
        };
        let p = d.wilcoxon_p.unwrap_or(1.0);
        let all_seeds = d.sign_holds == d.n_seeds;
        if t.ci_lower > 0.0 && p < alpha && all_seeds {
            Decision::Better
        } else if t.ci_upper < 0.0 && p < alpha && all_seeds {
            Decision::Worse
        } else if d.tost_p.is_some_and(|p| p < alpha) {
            Decision::Equivalent
        } else {
            Decision::Inconclusive
        }
    }

    fn text(self, margin: f64) -> String {
        match self {
            Decision::Better => "Net_S is better than Net_R".into(),
            Decision::Worse => "Net_S is worse than Net_R".into(),
            Decision::Equivalent => {
                format!("no effect larger than {margin} dB: Net_S and Net_R are equivalent")
            }
            Decision::Inconclusive => "inconclusive at this size".into(),
        }
    }
}

/// A signed dB value with a typographic minus, as the tables print it.
fn signed_db(v: f64) -> String {
    format!("{}{:.2}", if v < 0.0 { "−" } else { "+" }, v.abs())
}

/// One comparison for the reading: "+x dB [lo, hi], Wilcoxon p …, TOST p …, sign in k/n seeds".
pub(super) fn describe_diff(d: &DiffEntry) -> String {
    let mut text = format!("{} dB", signed_db(d.mean));
    if let Some(t) = &d.t {
        let _ = write!(
            text,
            " [{}, {}]",
            signed_db(t.ci_lower),
            signed_db(t.ci_upper)
        );
    }
    if let Some(p) = d.wilcoxon_p {
        let _ = write!(text, ", Wilcoxon p {}", ablate::format_p(p));
    }
    if let Some(p) = d.tost_p {
        let _ = write!(text, ", TOST (±{} dB) p {}", d.margin, ablate::format_p(p));
    }
    let _ = write!(text, ", sign in {}/{} seeds", d.sign_holds, d.n_seeds);
    if let Some(t) = &d.seed_t {
        // The training run as the unit: what a newly trained network would do.
        let _ = write!(
            text,
            "; over training runs [{}, {}] (t over the {} seeds' means, run-to-run sd {:.2} dB{})",
            signed_db(t.ci_lower),
            signed_db(t.ci_upper),
            t.n,
            t.sd,
            if t.n < MIN_SEEDS_FOR_RUNS {
                format!("; under {MIN_SEEDS_FOR_RUNS} seeds, these runs only")
            } else {
                String::new()
            }
        );
    }
    text
}

/// Why a real test set is absent, or its folder.
pub(super) type Optional = std::result::Result<PathBuf, Absent>;

/// A real test set's source that is neither given (`--FLAG`) nor at its shared default: a
/// reason the report gives, not a failure.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Absent {
    /// The shared default folder that does not exist.
    pub default: String,
    /// The flag, without its dashes, that names another.
    pub flag: String,
}

impl std::fmt::Display for Absent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} is absent; pass --{} DIR", self.default, self.flag)
    }
}

/// The report of the grid `exp` (its run `summary`, its `tables`, the noise `ceiling`), up to
/// the closing line the caller adds.
pub(super) fn report(
    exp: &AblateConfig,
    summary: &AblateSummary,
    tables: &[ablate::Table],
    ceiling: &[(f64, f64); 4],
    real_radiance: &Optional,
    real_capture: &Optional,
) -> String {
    let primary = &tables[0];
    let mut report = ablate::report(exp, summary);
    let alpha = 1.0 - exp.eval.level;
    let _ = write!(
        report,
        "\n\nNoise ceiling on the primary test set (triangle merge of each set's frames with \
         the true device response; mean over seeds): PSNR-T {:.2} from the noisy frames, {:.2} \
         from the noise-free frames (PSNR-L {:.2} / {:.2}).",
        ceiling[0].0, ceiling[0].1, ceiling[1].0, ceiling[1].1
    );
    let _ = write!(report, "\n\n## Reading (docs/protocol.md)\n\n");
    primary_reading(&mut report, primary, alpha);
    classical_reading(&mut report, exp, &exp.testset, "");
    dynamic_reading(&mut report, exp, tables);
    descriptive(&mut report, exp, tables);
    heldout_matrix(&mut report, exp, tables);
    if let Err(why) = real_radiance {
        let _ = writeln!(report, "- No real-radiance table: {why}.");
    }
    if let Err(why) = real_capture {
        let _ = writeln!(report, "- No real-capture table: {why}.");
    }
    report
}

/// The primary comparison's decision and the secondary differences.
fn primary_reading(report: &mut String, primary: &ablate::Table, alpha: f64) {
    match primary
        .entry("net_s", "psnr_t")
        .and_then(|e| e.diff.as_ref())
    {
        Some(d) => {
            let decision = Decision::from_diff(d, alpha);
            // A difference can be both real and smaller than the margin: say both.
            let decided = decision == Decision::Better || decision == Decision::Worse;
            let _ = writeln!(
                report,
                "- Primary, Net_S − Net_R, PSNR-T over {} scenes: {} → **{}**{}.",
                primary.entry("net_s", "psnr_t").map_or(0, |e| e.n_scenes),
                describe_diff(d),
                decision.text(d.margin),
                if decided && d.tost_p.is_some_and(|p| p < alpha) {
                    format!(
                        ", by less than the {} dB margin (the TOST also declares equivalence)",
                        d.margin
                    )
                } else {
                    String::new()
                }
            );
        }
        None => {
            let _ = writeln!(report, "- Primary: not every run has finished.");
        }
    }
    for (name, what) in [
        (
            "net_o",
            "Net_O − Net_R (what fine-tuning for the target's response buys)",
        ),
        ("control", "control − Net_R"),
        (
            "net_p",
            "Net_P − Net_R (the engine's display curve instead of the target's)",
        ),
    ] {
        if let Some(d) = primary.entry(name, "psnr_t").and_then(|e| e.diff.as_ref()) {
            let _ = writeln!(report, "- Secondary, {what}: {}.", describe_diff(d));
        }
    }
}

/// Whether the networks beat what a user has without one: Net_S and Net_R against the copied
/// reference and the triangle merge on test set `t`, paired within seed and set; `what` names
/// a test set other than the primary.
fn classical_reading(report: &mut String, exp: &AblateConfig, t: &TestsetSpec, what: &str) {
    for row in ["net_s", "net_r"] {
        for versus in ["copy", "triangle"] {
            let Ok(Some(d)) = ablate::paired_psnr_t(exp, t, row, versus) else {
                continue;
            };
            let per_seed: Vec<String> =
                d.per_seed.iter().map(|(_, v)| format!("{v:+.2}")).collect();
            let beats = d.per_seed.iter().filter(|(_, v)| *v > 0.0).count();
            let _ = writeln!(
                report,
                "- {what}{row} − {versus}, PSNR-T: {} (per seed {}): {} in {beats} of {} seeds.",
                describe_diff(&d),
                per_seed.join(", "),
                if beats == d.per_seed.len() {
                    "better"
                } else {
                    "not better"
                },
                d.per_seed.len()
            );
        }
    }
}

fn seeds_mean(t: &ablate::Table, row: &str) -> Option<f64> {
    t.entry(row, "psnr_t").map(|e| e.mean)
}

/// The dynamic test set: the networks against the classical rows where subjects move between
/// the frames (the triangle merge ghosts there), and every row's PSNR-T over the moving pixels.
fn dynamic_reading(report: &mut String, exp: &AblateConfig, tables: &[ablate::Table]) {
    let spec = exp.also.iter().find(|a| a.name.as_deref() == Some(DYNAMIC));
    let table = tables
        .iter()
        .find(|t| t.testset.as_deref() == Some(DYNAMIC));
    let (Some(spec), Some(table)) = (spec, table) else {
        return;
    };
    classical_reading(report, exp, spec, "Dynamic test set, ");
    let cells: Vec<String> = exp
        .rows
        .iter()
        .filter_map(|r| {
            let all = table.entry(&r.name, "psnr_t")?.mean;
            let moving = table.entry(&r.name, "psnr_t_moving")?.mean;
            Some(format!("{} {all:.2} ({moving:.2})", r.name))
        })
        .collect();
    if !cells.is_empty() {
        let _ = writeln!(
            report,
            "- Dynamic test set, PSNR-T over the image (over the moving pixels), mean over \
             seeds: {}.",
            cells.join(", ")
        );
    }
}

/// The real test sets' means (too few scenes for a test).
fn descriptive(report: &mut String, exp: &AblateConfig, tables: &[ablate::Table]) {
    let descriptive = tables.iter().skip(1).filter(|t| {
        !t.testset
            .as_deref()
            .is_some_and(|n| n.starts_with("heldout_") || n == DYNAMIC)
    });
    for (t, what) in descriptive.map(|t| {
        (
            t,
            match t.testset.as_deref() {
                Some("real_radiance") => "real radiance through the target model",
                Some("real_capture") => "the real capture",
                _ => "another test set",
            },
        )
    }) {
        let cells: Vec<String> = exp
            .rows
            .iter()
            .filter_map(|r| seeds_mean(t, &r.name).map(|v| format!("{} {v:.2}", r.name)))
            .collect();
        let _ = writeln!(
            report,
            "- Descriptive, {what} (PSNR-T, mean over seeds; too few scenes for a test): {}.",
            cells.join(", ")
        );
    }
}

/// The held-out-simulator matrix, where there are held-out test sets.
fn heldout_matrix(report: &mut String, exp: &AblateConfig, tables: &[ablate::Table]) {
    let matrix: Vec<&ablate::Table> = std::iter::once(&tables[0])
        .chain(tables.iter().filter(|t| {
            t.testset
                .as_deref()
                .is_some_and(|n| n.starts_with("heldout_"))
        }))
        .collect();
    if matrix.len() > 1 {
        let _ = write!(
            report,
            "\n### Held-out-simulator matrix (PSNR-T, mean over seeds; last column Net_S − Net_R)\n\n\
             | test rendering |"
        );
        for r in &exp.rows {
            let _ = write!(report, " {} |", r.name);
        }
        let _ = write!(report, " Net_S − Net_R |\n|---|");
        for _ in 0..=exp.rows.len() {
            let _ = write!(report, "---|");
        }
        report.push('\n');
        for t in matrix {
            let _ = write!(
                report,
                "| {} |",
                t.testset
                    .as_deref()
                    .unwrap_or("primary (the training simulator)")
            );
            for r in &exp.rows {
                let v = seeds_mean(t, &r.name).map_or("–".into(), |v| format!("{v:.2}"));
                let _ = write!(report, " {v} |");
            }
            let d = t
                .entry("net_s", "psnr_t")
                .and_then(|e| e.diff.as_ref())
                .map_or("–".into(), describe_diff);
            let _ = writeln!(report, " {d} |");
        }
        report.push('\n');
    }
}
