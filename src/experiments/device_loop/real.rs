//! The loop's `real` row: the pretrained network fine-tuned on the calibration scenes' own
//! frames against their ground truth, with no simulation at all. A device's real frames carry
//! what no profile models yet (its processing, compression, the floor of its darkest codes);
//! their ground truth, merged from every frame of each set, is the same kind the test scenes
//! are scored against. It needs sets that hold more frames than the inputs: where the ground
//! truth is the inputs' own merge, training on it teaches the triangle merge back.

use super::LoopOptions;
use crate::capture::scan::{FolderScan, ScanOptions};
use crate::capture::testset::GtFrames;
use crate::error::Result;
use crate::experiments::ablate::{Axis, AxisKind};
use std::path::Path;

/// The row's name.
pub(super) const REAL: &str = "real";
/// The row trained on the device's frames and the simulation together.
pub(super) const REAL_MIX: &str = "real_mix";
/// The share of `real_mix`'s samples drawn from the simulation: fixed before any run, not
/// tuned.
const MIX_FRACTION: f64 = 0.5;

/// Why the loop has no `real` row: a reason the report gives, not a failure.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum NoRealRow {
    /// `--gt-frames inputs`: the ground truth is the inputs' own merge.
    GtIsInputs,
    /// The calibration set of this name holds only its three inputs.
    OnlyInputs(String),
    /// A calibration set smaller than the fine-tune's crops.
    TooSmall {
        set: String,
        width: usize,
        height: usize,
        patch: usize,
    },
}

impl std::fmt::Display for NoRealRow {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NoRealRow::GtIsInputs => write!(
                f,
                "the ground truth is the inputs' own merge (`--gt-frames inputs`)"
            ),
            NoRealRow::OnlyInputs(set) => write!(
                f,
                "calibration set '{set}' holds only its three inputs, so its ground truth is \
                 their own merge"
            ),
            NoRealRow::TooSmall {
                set,
                width,
                height,
                patch,
            } => write!(
                f,
                "calibration set '{set}' is {width}×{height}, smaller than the fine-tune's \
                 {patch}-pixel crops"
            ),
        }
    }
}

/// The row, where the calibration scenes' ground truth holds more than the inputs (every set
/// has more frames than the three inputs, and `--gt-frames` is not `inputs`) and every set
/// holds the fine-tune's crops of `patch` pixels; else why not.
pub(super) fn real_row(
    opts: &LoopOptions,
    folder: &FolderScan,
    cal_scan: &ScanOptions,
    validation: &Path,
    patch: usize,
) -> Result<std::result::Result<Axis, NoRealRow>> {
    if opts.gt_frames == GtFrames::Inputs {
        return Ok(Err(NoRealRow::GtIsInputs));
    }
    let sets = folder.select(cal_scan)?.sets;
    if let Some(s) = sets.iter().find(|s| s.all_frames().count() <= 3) {
        return Ok(Err(NoRealRow::OnlyInputs(s.name.clone())));
    }
    // The fine-tune crops `patch` pixels from each set: a smaller set is not refused later,
    // after every other row has run.
    let built = crate::data::layout::detect(validation)?;
    if let Some(s) = built
        .sets
        .iter()
        .find(|s| s.width < patch || s.height < patch)
    {
        return Ok(Err(NoRealRow::TooSmall {
            set: s.name.clone(),
            width: s.width,
            height: s.height,
            patch,
        }));
    }
    let mut data = toml::Table::new();
    data.insert("dataset".into(), validation.display().to_string().into());
    data.insert(
        "profile".into(),
        crate::data::loader::PURE_PROFILE.to_string().into(),
    );
    Ok(Ok(Axis {
        name: REAL.into(),
        label: Some(
            "real: fine-tuned on the calibration scenes' own frames against their ground truth \
             (every frame merged); no simulation"
                .into(),
        ),
        set: toml::Table::from_iter([("data".to_string(), data.into())]),
        train: true,
        checkpoint: None,
        kind: AxisKind::Finetune,
    }))
}

/// The `real_mix` row: the `real` row's fine-tune with a share of its samples (`[mix]`) from
/// the last step's simulated stream, `base_data` (the main job's `[data]`) laid under the
/// step's `[data]`. The calibration scenes hold no moving subject, so a fine-tune on them alone
/// unlearns deghosting; the simulated half keeps it while the real half carries what no step
/// models.
pub(super) fn mixed_row(real: &Axis, base_data: &toml::Table, last_step: &toml::Table) -> Axis {
    let mut sim = base_data.clone();
    if let Some(step) = last_step.get("data").and_then(|d| d.as_table()) {
        crate::config::merge_tables(&mut sim, step);
    }
    let mix = toml::Table::from_iter([
        ("fraction".to_string(), MIX_FRACTION.into()),
        ("data".to_string(), sim.into()),
    ]);
    let mut set = real.set.clone();
    set.insert("mix".into(), mix.into());
    Axis {
        name: REAL_MIX.into(),
        label: Some(format!(
            "real + simulation: the `real` row's fine-tune with {:.0} % of its samples from \
             the last step's simulated stream",
            100.0 * MIX_FRACTION
        )),
        set,
        ..real.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{BitDepth, Image, write_hdr, write_ldr};

    /// `dir/scene`: `n` grey PNG frames one stop apart with OpenCV's list.txt.
    fn bracket(dir: &Path, n: usize) {
        let d = dir.join("scene");
        std::fs::create_dir_all(&d).expect("mkdir");
        let mut list = String::new();
        for k in 0..n {
            let v = 0.1 * (k + 1) as f32;
            let name = format!("f{k}.png");
            write_ldr(
                &d.join(&name),
                &Image::from_fn(8, 8, |_, _| [v; 3]),
                BitDepth::Eight,
            )
            .expect("png");
            list += &format!("{name} {}\n", 2f32.powi(4 - k as i32));
        }
        std::fs::write(d.join("list.txt"), list).expect("list.txt");
    }

    /// `dir/set`: a Kalantari set of side `side`, as the loop's `validation/` holds.
    fn validation(dir: &Path, side: usize) {
        let d = dir.join("set");
        std::fs::create_dir_all(&d).expect("mkdir");
        let grey = Image::from_fn(side, side, |_, _| [0.5; 3]);
        for name in ["a.tif", "b.tif", "c.tif"] {
            write_ldr(&d.join(name), &grey, BitDepth::Sixteen).expect("tif");
        }
        std::fs::write(d.join("exposure.txt"), "0\n2\n4\n").expect("exposure.txt");
        write_hdr(&d.join("HDRImg.hdr"), &grey).expect("hdr");
    }

    fn row(frames: usize, side: usize, gt: GtFrames) -> std::result::Result<Axis, NoRealRow> {
        let tmp = tempfile::tempdir().expect("tmp");
        let (brackets, val) = (tmp.path().join("b"), tmp.path().join("v"));
        bracket(&brackets, frames);
        validation(&val, side);
        let scan = ScanOptions::default();
        let folder = FolderScan::new(&brackets, &scan).expect("scan");
        let opts = LoopOptions {
            brackets,
            calibration: vec!["scene".into()],
            calibration_region: None,
            test_region: None,
            scan: scan.clone(),
            inputs: Default::default(),
            gt_frames: gt,
            quickstart: tmp.path().join("q"),
            seeds: vec![1],
            out: tmp.path().join("out"),
            progress: false,
        };
        real_row(&opts, &folder, &scan, &val, 32).expect("row")
    }

    #[test]
    fn the_row_needs_more_frames_than_the_inputs_and_sets_that_hold_a_crop() {
        let made = row(5, 48, GtFrames::All).expect("made");
        assert_eq!(made.name, REAL);
        assert_eq!(made.set["data"]["profile"].as_str(), Some("pure"));
        let why = |r: std::result::Result<Axis, NoRealRow>| r.expect_err("no row").to_string();
        assert!(why(row(3, 48, GtFrames::All)).contains("only its three inputs"));
        assert!(why(row(5, 48, GtFrames::Inputs)).contains("--gt-frames inputs"));
        assert!(why(row(5, 16, GtFrames::All)).contains("smaller than the fine-tune's 32-pixel"));
    }

    #[test]
    fn the_mixed_row_is_the_real_row_with_the_last_steps_stream_laid_over_the_main_jobs() {
        let real = row(5, 48, GtFrames::All).expect("made");
        let base: toml::Table =
            toml::from_str("dataset = \"train\"\npatch = 64\nnoise = \"gaussian\"\n").unwrap();
        let step: toml::Table =
            toml::from_str("[data]\nprofile = \"level.toml\"\nnoise = \"none\"\n").unwrap();
        let mixed = mixed_row(&real, &base, &step);
        assert_eq!(mixed.name, REAL_MIX);
        // The real half is the `real` row's, unchanged.
        assert_eq!(mixed.set["data"], real.set["data"]);
        assert!(mixed.train && mixed.kind == real.kind);
        let mix = mixed.set["mix"].as_table().expect("[mix]");
        assert_eq!(mix["fraction"].as_float(), Some(0.5));
        // The main job's keys kept where the step sets none; the step's win where it does.
        let data = mix["data"].as_table().expect("[mix.data]");
        assert_eq!(data["dataset"].as_str(), Some("train"));
        assert_eq!(data["patch"].as_integer(), Some(64));
        assert_eq!(data["profile"].as_str(), Some("level.toml"));
        assert_eq!(data["noise"].as_str(), Some("none"));
    }
}
