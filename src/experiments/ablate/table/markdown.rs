//! The Markdown of a grid's table: its title and reading, and the rows of means and paired
//! differences.

use super::*;

/// The Markdown's title and the paragraph that says what the numbers are.
pub(super) fn table_intro(
    cfg: &AblateConfig,
    t: &TestsetSpec,
    n_sets: usize,
    n_scenes: usize,
    ref_label: &str,
    runs_done: usize,
    runs_total: usize,
) -> String {
    let pct = cfg.eval.level * 100.0;
    let mut md = format!(
        "# {}{}\n\nTest set: `{}` ({} sets of {n_scenes} scenes; the sets of one scene are one \
         cluster{}).",
        cfg.title,
        t.label
            .as_ref()
            .or(t.name.as_ref())
            .map(|l| format!(" — {l}"))
            .unwrap_or_default(),
        t.dir.display(),
        n_sets,
        if t.noise_per_seed {
            "; test noise redrawn per seed"
        } else {
            ""
        },
    );
    let tests_text = if n_scenes >= MIN_SCENES_FOR_TESTS {
        format!(
            " Δ [{pct:.0} % paired t interval over scenes, each scene's Δ the mean over seeds] \
             p = Wilcoxon signed-rank p (two-sided); * = the t interval excludes 0; ≈ = \
             equivalent within ±{} dB PSNR / ±{} SSIM / ±{} ΔE2000 (TOST, α = {:.2}). ΔE2000: \
             lower is better. PSNR-T dark: over the pixels the reference frame under-exposes, \
             sets with at least 1 % of them.",
            cfg.eval.margin_psnr,
            cfg.eval.margin_ssim,
            cfg.eval.margin_delta_e,
            1.0 - cfg.eval.level
        )
    } else {
        format!(
            " With {n_scenes} scene(s) (fewer than {MIN_SCENES_FOR_TESTS}) the table shows \
             means only: no interval and no test."
        )
    };
    // The means' intervals, only where there are scenes enough for one.
    let ci_text = |what: &str| {
        if n_scenes >= MIN_SCENES_FOR_TESTS {
            format!(" [{pct:.0} % {what}; {} resamples]", cfg.eval.resamples)
        } else {
            String::new()
        }
    };
    if !cfg.seeds.is_empty() {
        let list: Vec<String> = cfg.seeds.iter().map(u64::to_string).collect();
        let _ = write!(
            md,
            " Seeds: {} ({}). Each value: mean over the seeds of the mean over the scenes{}. Δ: \
             difference to **{ref_label}** paired within seed, scene and set; (k/n) = the seeds \
             in which Δ has the sign of its mean.{tests_text} {runs_done} of {runs_total} runs \
             finished.\n\n",
            list.join(", "),
            if cfg.pretrained_per_seed.is_some() {
                "each seed has its own pretrained network and its own fine-tuning data stream"
            } else {
                "every trained cell once per seed; a cell that does not train is evaluated once \
                 and serves every seed"
            },
            ci_text("CI of a two-level bootstrap: seeds, then scenes"),
        );
    } else {
        let _ = write!(
            md,
            " Each value: mean over the scenes{}. Δ: paired difference to **{ref_label}** over \
             the same sets.{tests_text} {runs_done} of {runs_total} cells finished.\n\n",
            ci_text("bootstrap CI resampling scenes"),
        );
    }
    md
}

/// The tables themselves: without columns the paper's Tables 1–2 (one row per method, the
/// metrics across, then the differences), with columns its Tables 3–4 (one table per metric).
pub(super) fn table_body(
    md: &mut String,
    cfg: &AblateConfig,
    cell_text: &CellTexts,
    reference_row: usize,
    ref_label: &str,
) {
    let missing = "(not run yet)".to_string();
    let shown: Vec<usize> = (0..TABLE_METRICS.len())
        .filter(|&mi| {
            let mut texts = cell_text.iter().filter(|(k, _)| k.0 == mi).peekable();
            texts.peek().is_none() || texts.any(|(_, (v, _))| v != "–")
        })
        .collect();
    if cfg.columns.is_empty() {
        let rows = cfg.rows.iter().enumerate();
        metric_rows(md, "| method |", "", &shown, rows.clone(), |r, mi| {
            let t = cell_text.get(&(mi, r, None));
            t.map(|t| &t.0).unwrap_or(&missing).clone()
        });
        let head = format!("\n| Δ to {ref_label} |");
        let others = rows.filter(|(r, _)| *r != reference_row);
        metric_rows(md, &head, "Δ ", &shown, others, |r, mi| {
            let t = cell_text.get(&(mi, r, None));
            t.map(|t| &t.1).unwrap_or(&missing).clone()
        });
    } else {
        for &mi in &shown {
            let name = TABLE_METRICS[mi].1;
            let _ = write!(md, "## {name}\n\n| |");
            for col in &cfg.columns {
                let _ = write!(md, " {} |", col.label());
            }
            let _ = write!(md, "\n|---|");
            for _ in &cfg.columns {
                let _ = write!(md, "---|");
            }
            md.push('\n');
            for (r, row) in cfg.rows.iter().enumerate() {
                let _ = write!(md, "| {} |", row.label());
                for c in 0..cfg.columns.len() {
                    let t = cell_text.get(&(mi, r, Some(c)));
                    let _ = write!(
                        md,
                        " {} |",
                        t.map(|t| format!("{}<br>Δ {}", t.0, t.1))
                            .unwrap_or_else(|| missing.clone())
                    );
                }
                md.push('\n');
            }
            md.push('\n');
        }
    }
}

/// One Markdown table of rows × the `shown` [`TABLE_METRICS`]: `head` then each metric's name
/// after `prefix`, then one line per row with `text(row, metric index)`.
fn metric_rows<'a>(
    md: &mut String,
    head: &str,
    prefix: &str,
    shown: &[usize],
    rows: impl Iterator<Item = (usize, &'a Axis)>,
    text: impl Fn(usize, usize) -> String,
) {
    let _ = write!(md, "{head}");
    for &mi in shown {
        let _ = write!(md, " {prefix}{} |", TABLE_METRICS[mi].1);
    }
    let _ = write!(md, "\n|---|");
    for _ in shown {
        let _ = write!(md, "---|");
    }
    md.push('\n');
    for (r, row) in rows {
        let _ = write!(md, "| {} |", row.label());
        for &mi in shown {
            let _ = write!(md, " {} |", text(r, mi));
        }
        md.push('\n');
    }
}
