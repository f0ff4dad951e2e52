//! The loop's report (`loop.md`): the split, what was measured, each step's device-output
//! check, the gain of each step, what a user gets, the pictures.

use super::*;
use crate::io::{BitDepth, Image, write_ldr};

/// What the calibration measured: the noise rows and the spatial correlation's fit.
pub(super) fn measured_text(cal: &BracketCalibration, extra: &Extra) -> String {
    let fit = &cal.correlation;
    let step = |taken: bool| {
        if taken {
            "a step of the loop".to_string()
        } else {
            format!("below the minimum effect {MIN_RHO}: not a step")
        }
    };
    format!(
        "Measured on the calibration scenes: {}; spatial correlation of the output noise: \
         low/high-order ratio {:.3} {:.3} {:.3} → lag-1 correlation {:.3} ({}); correlation \
         of the channels' noise {:.3} ({}).\n\n",
        cal.profile
            .noise
            .iter()
            .map(|r| format!(
                "ISO {} a [{:.3e}, {:.3e}, {:.3e}] b [{:.3e}, {:.3e}, {:.3e}]",
                r.iso, r.a[0], r.a[1], r.a[2], r.b[0], r.b[1], r.b[2]
            ))
            .collect::<Vec<_>>()
            .join("; "),
        fit.ratio[0],
        fit.ratio[1],
        fit.ratio[2],
        fit.rho,
        step(extra.correlated.is_some()),
        cal.channel_correlation,
        step(extra.chroma.is_some()),
    ) + &extra.notes
        + &match metering_rule(&cal.metering) {
            Some(m) => format!(
                "Exposure rule of the auto-exposed frames: mid grey {:.4}, at most {:.2} % \
             clipped (a step of the loop).\n\n",
                m.mid_grey,
                100.0 * m.max_clipped
            ),
            None => "Exposure rule: not measured — no set marks its auto-exposed frame by EXIF \
                 ExposureBiasValue (a manual bracket says nothing about the device's meter); \
                 the main job's rule stays.\n\n"
                .to_string(),
        }
}

/// Each step's device-output check on the calibration scenes: the gap, what it names, and
/// every statistic.
pub(super) fn checks_text(steps: &[Step], checks: &[OutputCheck], out: &Path) -> Result<String> {
    let plots = check_plots(steps, checks, &out.join(PICTURES))?;
    let mut s = String::from(
        "## The device-output check of each step (calibration scenes)\n\n\
         Each step's profile renders the calibration scenes back at every frame's exposure and \
         ISO; its statistics are compared with the real frames' (docs/your_device.md, \
         \"The device-output check\").\n\n",
    );
    let links: Vec<String> = plots
        .iter()
        .map(|(what, file)| format!("[{what}]({PICTURES}/{file})"))
        .collect();
    let _ = writeln!(
        s,
        "Plots (|z| on a log axis, red: the threshold): {}.\n",
        links.join(", ")
    );
    s.push_str("| step | gap | largest significant statistic | closed by |\n|---|---|---|---|\n");
    for (st, c) in steps.iter().zip(checks) {
        let (stat, by) = c.named().map_or(("none".to_string(), "–"), |n| {
            (format!("{} (z {:+.1})", n.name, n.z), n.names)
        });
        let _ = writeln!(s, "| {} | {:.1} | {stat} | {by} |", st.name, c.gap);
    }
    for (st, c) in steps.iter().zip(checks) {
        let _ = write!(s, "\n### {}: {}\n\n{}", st.name, st.label, c.markdown());
    }
    s.push('\n');
    Ok(s)
}

/// The check's plots in `dir`: the gap of every step, and each step's |z| per statistic.
/// Returns (what, file name) per plot.
fn check_plots(
    steps: &[Step],
    checks: &[OutputCheck],
    dir: &Path,
) -> Result<Vec<(String, String)>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let threshold = checks.first().map_or(3.0, |c| c.threshold);
    let mut written = Vec::new();
    let mut plot = |what: String, file: String, img: Image| -> Result<()> {
        write_ldr(&dir.join(&file), &img, BitDepth::Eight)?;
        written.push((what, file));
        Ok(())
    };
    let names: Vec<String> = steps.iter().map(|st| st.name.to_string()).collect();
    let gaps: Vec<f64> = checks.iter().map(|c| c.gap).collect();
    let title = "device-output check: gap (largest significant |z|) per step";
    plot(
        "the gap of every step".to_string(),
        "device_output_gap.png".to_string(),
        crate::plot::log_bars(&gaps, &names, threshold, title),
    )?;
    for (st, c) in steps.iter().zip(checks) {
        let z: Vec<f64> = c.stats.iter().map(|x| x.z.abs()).collect();
        let labels: Vec<String> = c.stats.iter().map(|x| short_statistic(&x.name)).collect();
        plot(
            format!("{}'s statistics", st.name),
            format!("device_output_{}.png", st.name),
            crate::plot::log_bars(
                &z,
                &labels,
                threshold,
                &format!("{}: |z| per statistic", st.name),
            ),
        )?;
    }
    Ok(written)
}

/// A statistic's name in a few characters, for a plot's axis: "R level", "G spatial",
/// "chroma", "toe", "JPEG blocks".
fn short_statistic(name: &str) -> String {
    let channel = name.split_whitespace().next().unwrap_or("");
    if name.contains("channel correlation") {
        "chroma".to_string()
    } else if name.contains("noise level") {
        format!("{channel} level")
    } else if name.contains("noise floor") {
        format!("{channel} floor")
    } else if name.contains("spatial correlation") {
        format!("{channel} spatial")
    } else if name.starts_with("floor:") {
        "toe".to_string()
    } else if name.starts_with("blockiness") {
        "JPEG blocks".to_string()
    } else {
        name.chars().take(10).collect()
    }
}

/// What the split was, and what it allows.
pub(super) fn split_text(opts: &LoopOptions, cal: &[String], test: &[String]) -> String {
    let mut s = String::from("# The sim-to-real loop\n\n");
    let region =
        |r: Option<Region>| r.map_or("whole frames".to_string(), |r| format!("region {r}"));
    let _ = writeln!(
        s,
        "Calibration scenes ({}): {} ({}). Test scenes ({}): {} ({}).\n",
        cal.len(),
        cal.join(", "),
        region(opts.calibration_region),
        test.len(),
        test.join(", "),
        region(opts.test_region)
    );
    if cal.iter().any(|c| test.contains(c)) {
        s.push_str(
            "**Not a scene split.** The same captures calibrate and are scored, on disjoint \
             regions: the test pixels never entered the profile, but the scene, its light, the \
             device's settings and the moment are shared, so the table measures generalisation \
             across pixels of one scene, not to new scenes.\n\n",
        );
    }
    if test.len() < ablate::MIN_SCENES_FOR_TESTS {
        let _ = writeln!(
            s,
            "With {} test scene(s) (fewer than {}) no interval or test over scenes is \
             computed: each difference is the mean over seeds, with the seeds that share its \
             sign. It says what these scenes show, not what the device's scenes in general \
             would.\n",
            test.len(),
            ablate::MIN_SCENES_FOR_TESTS
        );
    }
    s
}

/// What the `real` row is, or why the loop has none.
pub(super) fn real_text(real: &std::result::Result<Axis, super::real::NoRealRow>) -> String {
    match real {
        Ok(_) => "The `real` row fine-tunes the pretrained network of each seed on the \
                  calibration scenes' own frames (`validation/`) against their ground truth, \
                  merged from every frame of each set, with no simulation: what the device's \
                  frames carry that no step models. The `real_mix` row is the same fine-tune \
                  with half its samples from the last step's simulated stream, whose moving \
                  subjects keep the deghosting that static calibration scenes cannot teach. \
                  Their scores on the calibration scenes are in-sample; the test scenes never \
                  enter them.\n\n"
            .into(),
        Err(why) => {
            format!("No `real` row (fine-tuning on the calibration scenes' own frames): {why}.\n\n")
        }
    }
}

/// `OUT/pictures/<set>.png` for every test scene and the report's links to them.
pub(super) fn pictures_text(
    cfg: &AblateConfig,
    testset: &Path,
    steps: &[Step],
    out: &Path,
) -> Result<String> {
    let rows: Vec<(String, &str)> = [
        ("triangle merge", "triangle"),
        ("Net_O", "net_o"),
        ("Net_S", NET_S),
    ]
    .into_iter()
    .map(|(l, n)| (l.to_string(), n))
    .chain(steps.iter().map(|st| (st.name.to_string(), st.name)))
    .chain(
        [real::REAL, real::REAL_MIX]
            .into_iter()
            .filter(|n| cfg.rows.iter().any(|r| r.name == *n))
            .map(|n| (n.to_string(), n)),
    )
    .collect();
    let written = pictures::write(cfg, testset, &rows, &out.join(PICTURES))?;
    let mut s = format!(
        "\n## Pictures\n\nPer test scene, the crop (up to {0}×{0}) of the ground truth with the \
         widest range: the reference frame as the device wrote it, the triangle merge, Net_O, \
         every step's network and the rows trained on real frames where there are (seed {1}), then the \
         ground truth, the HDR images tone-mapped alike (μ-law, the T of PSNR-T).\n\n",
        pictures::CROP,
        cfg.seeds.first().map_or("–".to_string(), u64::to_string)
    );
    for (set, _) in &written {
        let _ = writeln!(s, "- [{set}]({PICTURES}/{set}.png)");
    }
    Ok(s)
}

/// The loop's folder of per-scene pictures.
pub const PICTURES: &str = "pictures";

/// The table's reading for a user: which networks beat what they already have (the copied
/// reference frame, the triangle merge of the same inputs) in PSNR-T, paired within seed and
/// scene. "Beats" needs the 95 % t interval over scenes above 0 where there is one, else the
/// same sign in every seed.
pub(super) fn what_a_user_gets(cfg: &AblateConfig, names: &[&str]) -> Result<String> {
    let mut s = String::from(
        "\n## What a user gets\n\nPSNR-T of each network against what the user already has, \
         paired within seed and scene; \"beats\" and \"loses to\" need the 95 % t interval over \
         scenes on one side of 0 where there is one (10 or more scenes), else the same sign in \
         every seed; otherwise \"no difference shown\".\n\n",
    );
    for (versus, what) in [
        ("copy", "the copied reference frame"),
        ("triangle", "the triangle merge of the inputs"),
    ] {
        let (mut beats, mut loses, mut neither) = (Vec::new(), Vec::new(), Vec::new());
        for row in names {
            let Some(d) = ablate::paired_psnr_t(cfg, &cfg.testset, row, versus)? else {
                continue;
            };
            let text = format!("{row} ({} dB)", format!("{:+.2}", d.mean).replace('-', "−"));
            let every_seed = d.sign_holds == d.n_seeds;
            match d.t {
                Some(t) if t.ci_lower > 0.0 => beats.push(text),
                Some(t) if t.ci_upper < 0.0 => loses.push(text),
                None if every_seed && d.mean > 0.0 => beats.push(text),
                None if every_seed && d.mean < 0.0 => loses.push(text),
                _ => neither.push(text),
            }
        }
        let list = |v: &[String]| {
            if v.is_empty() {
                "none".to_string()
            } else {
                v.join(", ")
            }
        };
        let _ = writeln!(
            s,
            "- Against {what}: beat it {}; lose to it {}; no difference shown {}.",
            list(&beats),
            list(&loses),
            list(&neither)
        );
    }
    Ok(s)
}

/// Where subjects move (the main job's dynamic test set, where the loop has it): each
/// network against the triangle merge, which ghosts there, paired within seed and scene. A
/// fine-tune on static calibration scenes can unlearn the deghosting the pretraining taught;
/// this is where that shows.
pub(super) fn dynamic_text(cfg: &AblateConfig, names: &[&str]) -> Result<String> {
    let Some(spec) = cfg
        .also
        .iter()
        .find(|t| t.name.as_deref() == Some(super::DYNAMIC))
    else {
        return Ok(String::new());
    };
    let mut s = String::from(
        "\n## Where subjects move\n\nThe main job's dynamic test set (simulated moving \
         subjects through its stock sensor, not this device's): PSNR-T of each network minus \
         the triangle merge's, paired within seed and scene.\n\n\
         | network | mean Δ | seeds with its sign | per seed |\n|---|---|---|---|\n",
    );
    for row in names {
        let Some(d) = ablate::paired_psnr_t(cfg, spec, row, "triangle")? else {
            continue;
        };
        let signed = |x: f64| format!("{x:+.2}").replace('-', "−");
        let per_seed: Vec<String> = d
            .per_seed
            .iter()
            .map(|(k, v)| match k {
                Some(k) => format!("s{k} {}", signed(*v)),
                None => signed(*v),
            })
            .collect();
        let _ = writeln!(
            s,
            "| {row} | {} | {}/{} | {} |",
            signed(d.mean),
            d.sign_holds,
            d.n_seeds,
            per_seed.join(", ")
        );
    }
    Ok(s)
}

/// The gain each step buys over the step before (and each step against Net_O, the control,
/// the classical rows and the uncalibrated rows: calibrating against not calibrating), PSNR-T
/// and SSIM-T, every seed.
pub(super) fn steps_table(cfg: &AblateConfig, steps: &[Step]) -> Result<String> {
    let mut s = String::from(
        "## The gain of each step\n\n\
         | step | versus | metric | mean Δ | seeds with its sign | per seed | 95 % t over scenes | TOST p |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    let mut pairs: Vec<(&str, &str)> = steps.windows(2).map(|w| (w[1].name, w[0].name)).collect();
    for st in steps {
        pairs
            .extend(["net_o", "control", GENERIC, NET_S, "copy", "triangle"].map(|v| (st.name, v)));
    }
    // The rows trained on real frames against the same, and against the last simulated step.
    for on_real in [real::REAL, real::REAL_MIX] {
        if cfg.rows.iter().any(|r| r.name == on_real) {
            let versus = ["net_o", "control", GENERIC, NET_S]
                .into_iter()
                .chain(steps.last().map(|s| s.name))
                .chain(["copy", "triangle"]);
            pairs.extend(versus.map(|v| (on_real, v)));
        }
    }
    for (row, versus) in pairs {
        for e in ablate::paired_rows(cfg, &cfg.testset, row, versus)? {
            if !matches!(e.metric, "psnr_t" | "ssim_t") {
                continue;
            }
            let Some(d) = &e.diff else { continue };
            let prec = if e.metric == "ssim_t" { 4 } else { 2 };
            let per_seed: Vec<String> = d
                .per_seed
                .iter()
                .map(|(k, v)| match k {
                    Some(k) => format!("s{k} {v:+.prec$}"),
                    None => format!("{v:+.prec$}"),
                })
                .collect();
            let t = d.t.map_or("–".into(), |t| {
                format!("[{:+.prec$}, {:+.prec$}]", t.ci_lower, t.ci_upper)
            });
            let tost = d.tost_p.map_or("–".into(), ablate::format_p);
            let _ = writeln!(
                s,
                "| {row} | {versus} | {} | {:+.prec$} | {}/{} | {} | {t} | {tost} |",
                e.metric,
                d.mean,
                d.sign_holds,
                d.n_seeds,
                per_seed.join(", ")
            );
        }
    }
    Ok(s)
}
