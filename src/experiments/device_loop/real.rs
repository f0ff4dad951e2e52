//! The loop's `real` row: the pretrained network fine-tuned on the calibration scenes' own
//! frames against their ground truth, with no simulation at all. A device's real frames carry
//! what no profile models yet (its processing, compression, the floor of its darkest codes);
//! their ground truth, merged from every frame of each set, is the same kind the test scenes
//! are scored against. It needs sets that hold more frames than the inputs: where the ground
//! truth is the inputs' own merge, training on it teaches the triangle merge back.

use super::LoopOptions;
use crate::data::bracket_testset::GtFrames;
use crate::data::brackets::{FolderScan, ScanOptions};
use crate::error::Result;
use crate::experiments::ablate::{Axis, AxisKind};
use std::path::Path;

/// The row's name.
pub(super) const REAL: &str = "real";

/// The row, where the calibration scenes' ground truth holds more than the inputs (every set
/// has more frames than the three inputs, and `--gt-frames` is not `inputs`); else why not.
pub(super) fn real_row(
    opts: &LoopOptions,
    folder: &FolderScan,
    cal_scan: &ScanOptions,
    validation: &Path,
) -> Result<std::result::Result<Axis, String>> {
    if opts.gt_frames == GtFrames::Inputs {
        return Ok(Err(
            "the ground truth is the inputs' own merge (`--gt-frames inputs`)".into(),
        ));
    }
    let sets = folder.select(cal_scan)?.sets;
    if let Some(s) = sets.iter().find(|s| s.all_frames().count() <= 3) {
        return Ok(Err(format!(
            "calibration set '{}' holds only its three inputs, so its ground truth is their \
             own merge",
            s.name
        )));
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
