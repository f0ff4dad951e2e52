//! The network the loop hands over, per seed: the row trained on the device's own frames where
//! the loop made one (`real_mix`, which keeps the simulation's moving subjects, before `real`;
//! their calibration-scene scores are in-sample, so those scenes cannot choose them), else the
//! network row that scores best on the validation set (the calibration scenes, which no test
//! scene is); then scored on the test scenes against the copied reference and the triangle
//! merge. Choosing on the calibration scenes keeps a fine-tune that hurts from being handed
//! over, and says so where the triangle merge is better than every network there.

use super::LoopOptions;
use crate::error::Result;
use crate::experiments::ablate::{self, AblateConfig, TestsetSpec};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// One row's PSNR-T per set, per seed (`None`: a classical row, every seed's).
use ablate::RunScores as Scores;

fn of_seed(s: &Scores, seed: u64) -> Option<&BTreeMap<String, f64>> {
    s.iter()
        .find(|(k, _)| *k == Some(seed))
        .or_else(|| s.iter().find(|(k, _)| k.is_none()))
        .map(|(_, v)| v)
}

fn mean(v: impl Iterator<Item = f64>) -> Option<f64> {
    let v: Vec<f64> = v.filter(|x| x.is_finite()).collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// The mean over the sets both hold of `a − b`.
fn paired(a: &BTreeMap<String, f64>, b: &BTreeMap<String, f64>) -> Option<f64> {
    mean(a.iter().filter_map(|(n, x)| b.get(n).map(|y| x - y)))
}

/// The rows trained on the device's own frames, in the order they are handed over.
const ON_REAL: [&str; 2] = [super::real::REAL_MIX, super::real::REAL];

/// The seed's first row of [`ON_REAL`] where there is one, else its row with the highest mean
/// PSNR-T on the validation set (never a row trained there); the first listed wins a tie
/// (candidates are listed from the least trained). With the row, its mean there.
fn choose<'a>(val: &[(&'a str, Scores)], seed: u64) -> Option<(&'a str, f64)> {
    let seed_mean = |s: &Scores| of_seed(s, seed).and_then(|v| mean(v.values().copied()));
    let is_real = |r: &str| ON_REAL.contains(&r);
    for on_real in ON_REAL {
        if let Some(hit) = val
            .iter()
            .find(|(r, _)| *r == on_real)
            .and_then(|(r, s)| seed_mean(s).map(|m| (*r, m)))
        {
            return Some(hit);
        }
    }
    let mut best: Option<(&str, f64)> = None;
    for (row, s) in val.iter().filter(|(r, _)| !is_real(r)) {
        let Some(m) = seed_mean(s) else {
            continue;
        };
        if best.is_none_or(|(_, b)| m > b) {
            best = Some((row, m));
        }
    }
    best
}

/// `loop.md`'s section on the handed-over network, and `OUT/handover.toml` naming its
/// checkpoint per seed. Empty where the config has no validation set.
pub(super) fn handover_text(
    opts: &LoopOptions,
    cfg: &AblateConfig,
    cfg_path: &Path,
    candidates: &[&str],
) -> Result<String> {
    let Some(val) = cfg.also.iter().find(|t| t.validation) else {
        return Ok(String::new());
    };
    let scores = |t: &TestsetSpec, row: &str| ablate::run_scores(cfg, t, row, "psnr_t");
    let val_rows: Vec<(&str, Scores)> = candidates
        .iter()
        .map(|r| Ok((*r, scores(val, r)?)))
        .collect::<Result<_>>()?;
    let (val_tri, test_tri, test_copy) = (
        scores(val, "triangle")?,
        scores(&cfg.testset, "triangle")?,
        scores(&cfg.testset, "copy")?,
    );
    let on_real = ON_REAL.into_iter().find(|r| candidates.contains(r));
    let mut s = match on_real {
        Some(row) => format!(
            "\n## The network the loop hands over\n\n\
             Per seed, the `{row}` row: the network fine-tuned on the calibration scenes' own \
             frames (its PSNR-T on them, below, is in-sample and chooses nothing), scored on the \
             test scenes. Its checkpoint per seed is in `handover.toml`.\n\n"
        ),
        None => "\n## The network the loop hands over\n\n\
                 Per seed, the network (Net_O, the control, the uncalibrated rows and every \
                 step) with the highest mean PSNR-T on the calibration scenes (`validation/`, a \
                 validation set: they calibrated the profiles, so the score there chooses and \
                 tests nothing), then scored on the test scenes. Its checkpoint per seed is in \
                 `handover.toml`.\n\n"
            .to_string(),
    };
    let real = on_real.is_some();
    s.push_str(
        "| seed | handed over | validation PSNR-T | triangle merge there | test PSNR-T | − triangle \
         merge | − copy |\n|---|---|---|---|---|---|---|\n",
    );
    let mut toml_text = match on_real {
        Some(row) => format!("# The network the loop hands over per seed: the `{row}` row.\n"),
        None => "# The network the loop hands over per seed: the best on the calibration scenes.\n"
            .to_string(),
    };
    let (mut beats, mut under_tri_on_val, mut n) = (0, Vec::new(), 0);
    for &seed in &cfg.seeds {
        let Some((row, v)) = choose(&val_rows, seed) else {
            continue;
        };
        n += 1;
        let test = scores(&cfg.testset, row)?;
        let t = of_seed(&test, seed);
        let t_mean = t.and_then(|t| mean(t.values().copied()));
        let vs = |other: &Scores| t.zip(of_seed(other, seed)).and_then(|(a, b)| paired(a, b));
        let (d_tri, d_copy) = (vs(&test_tri), vs(&test_copy));
        let v_tri = of_seed(&val_tri, seed).and_then(|v| mean(v.values().copied()));
        if d_tri.is_some_and(|d| d > 0.0) {
            beats += 1;
        }
        if v_tri.is_some_and(|x| x > v) {
            under_tri_on_val.push(seed.to_string());
        }
        let f = |x: Option<f64>, sign: bool| match (x, sign) {
            (Some(x), true) => format!("{x:+.2}").replace('-', "−"),
            (Some(x), false) => format!("{x:.2}"),
            (None, _) => "—".into(),
        };
        let _ = writeln!(
            s,
            "| {seed} | {row} | {v:.2} | {} | {} | {} | {} |",
            f(v_tri, false),
            f(t_mean, false),
            f(d_tri, true),
            f(d_copy, true)
        );
        if let Some(c) = ablate::run_checkpoint(cfg, cfg_path, row, Some(seed))? {
            let _ = writeln!(
                toml_text,
                "\n[seed{seed}]\nrow = {row:?}\ncheckpoint = {:?}",
                c.display().to_string()
            );
        }
    }
    let _ = writeln!(
        s,
        "\nThe handed-over network beats the triangle merge of its inputs on the test scenes in \
         {beats} of {n} seeds."
    );
    if !under_tri_on_val.is_empty() && !real {
        let _ = writeln!(
            s,
            "On the calibration scenes the triangle merge scores above every network in seed(s) \
             {}: for this device the classical merge is the better choice there.",
            under_tri_on_val.join(", ")
        );
    }
    crate::io::atomic::write_atomic(&opts.out.join("handover.toml"), toml_text.as_bytes())?;
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sets(v: &[(&str, f64)]) -> BTreeMap<String, f64> {
        v.iter().map(|(n, x)| (n.to_string(), *x)).collect()
    }

    #[test]
    fn the_best_validation_mean_is_chosen_per_seed_and_a_tie_keeps_the_first() {
        let val = vec![
            (
                "net_o",
                vec![
                    (Some(1), sets(&[("a", 30.0), ("b", 32.0)])),
                    (Some(2), sets(&[("a", 31.0)])),
                ],
            ),
            (
                "noise",
                vec![
                    (Some(1), sets(&[("a", 30.5), ("b", 32.5)])),
                    (Some(2), sets(&[("a", 31.0)])),
                ],
            ),
        ];
        assert_eq!(choose(&val, 1), Some(("noise", 31.5)));
        assert_eq!(choose(&val, 2), Some(("net_o", 31.0)));
        assert_eq!(choose(&val, 3), None);
        // A `real` row is handed over whatever its in-sample score.
        let mut with_real = val.clone();
        with_real.push(("real", vec![(Some(1), sets(&[("a", 20.0), ("b", 20.0)]))]));
        assert_eq!(choose(&with_real, 1), Some(("real", 20.0)));
        // Without one for a seed, the choice on the calibration scenes.
        assert_eq!(choose(&with_real, 2), Some(("net_o", 31.0)));
        // The mixed row before the `real` row, wherever it is listed.
        with_real.push(("real_mix", vec![(Some(1), sets(&[("a", 19.0)]))]));
        assert_eq!(choose(&with_real, 1), Some(("real_mix", 19.0)));
        assert_eq!(choose(&with_real, 2), Some(("net_o", 31.0)));
    }

    #[test]
    fn a_classical_row_serves_every_seed_and_differences_pair_by_set() {
        let tri: Scores = vec![(None, sets(&[("a", 29.0), ("b", 40.0)]))];
        assert_eq!(of_seed(&tri, 7).map(|v| v.len()), Some(2));
        // Only set "a" is in both: 31 − 29.
        assert_eq!(
            paired(
                &sets(&[("a", 31.0), ("c", 10.0)]),
                of_seed(&tri, 7).unwrap()
            ),
            Some(2.0)
        );
        assert_eq!(mean([f64::NAN, 1.0, 3.0].into_iter()), Some(2.0));
    }
}
