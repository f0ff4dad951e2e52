//! The paper's Dataset-1 layout: a set folder holds `input_1.png` (static, high exposure, EV 0),
//! `input_2.png` (static, low exposure, EV −3), `input_3.png` / `input_4.png` (the same two
//! exposures with motion: high / low) and `hdr_gt.png` (8-bit display-referred ground truth).
//! There is no exposure file: after sorting by ascending EV the set has evs [−3, 0],
//! static_frames [input_2, input_1], dynamic_frames [input_4, input_3] and reference 1.

use super::{Entry, GroundTruth, GroundTruthKind, SetInfo, SetRead};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

pub const GT_FILE: &str = "hdr_gt.png";
/// EV of the low exposure relative to the high (reference) one.
pub const LOW_EV: f32 = -3.0;

/// `input_N.png` → Some(N).
fn input_number(f: &Entry) -> Option<u32> {
    let (stem, ext) = super::split_ext(&f.lower);
    if ext != "png" {
        return None;
    }
    super::numbered(stem, "input_", "")
}

/// The first file whose name belongs to this layout.
pub(super) fn claims(files: &[Entry]) -> Option<String> {
    files
        .iter()
        .find(|f| f.lower == GT_FILE || input_number(f).is_some())
        .map(|f| f.name.clone())
}

/// Read one Dataset-1 set folder; errors name the folder or file and what is wrong.
pub(super) fn read_set(dir: &Path, name: &str, files: &[Entry]) -> Result<SetRead> {
    let mut slots: [Option<PathBuf>; 4] = [None, None, None, None];
    for f in files {
        let Some(n) = input_number(f) else { continue };
        if !(1..=4).contains(&n) {
            return Err(Error::layout(
                &f.path,
                format!(
                    "frame number {n}; Dataset-1 sets have exactly four frames, input_1..4.png"
                ),
            ));
        }
        slots[n as usize - 1] = Some(f.path.clone());
    }
    let mut inputs = Vec::with_capacity(4);
    for (i, s) in slots.into_iter().enumerate() {
        match s {
            Some(p) => inputs.push(p),
            None => {
                return Err(Error::layout(
                    dir.join(format!("input_{}.png", i + 1)),
                    "missing (Dataset-1 sets need input_1.png static high, input_2.png static low, \
                     input_3.png dynamic high, input_4.png dynamic low)",
                ));
            }
        }
    }
    let gt = super::find_file(files, GT_FILE).map(|f| f.path.clone());

    // Ascending EV: [low, high]; the high exposure (EV 0) is the reference.
    let static_frames = vec![inputs[1].clone(), inputs[0].clone()];
    let dynamic_frames = vec![inputs[3].clone(), inputs[2].clone()];
    let reference = 1;
    let mut all: Vec<&Path> = static_frames.iter().map(|p| p.as_path()).collect();
    all.extend(dynamic_frames.iter().map(|p| p.as_path()));
    let (width, height, _) = super::common_size(&all, reference, gt.as_deref())?;

    let set = SetInfo {
        name: name.to_string(),
        dir: dir.to_path_buf(),
        width,
        height,
        evs: vec![LOW_EV, 0.0],
        reference,
        static_frames,
        dynamic_frames,
        masks: Vec::new(),
        clean_frames: Vec::new(),
        ground_truth: gt.map(|path| GroundTruth {
            path,
            kind: GroundTruthKind::Display,
        }),
        exposure: None,
    };
    Ok((set, Vec::new()))
}
