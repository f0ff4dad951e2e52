//! Wu et al. 2018 / the paper's Dataset-2 layout: a set folder holds
//! `input_{1,2,3}_aligned.{tif,png}` (frames with motion), optionally
//! `ref_{1,2,3}_aligned.{tif,png}` (the same exposures with motion stopped), `input_exp.txt`
//! (log2 stops of the inputs; frame 2 is the reference), optionally `ref_exp.txt` (stops of the
//! ref frames) and `ref_hdr_aligned*.hdr` (linear ground truth aligned to frame 2).
//!
//! Units: Wu et al.'s code subtracts the smallest stop and uses t_i = 2^(s_i − s_min), so the
//! ground truth is in the shortest frame's unit; [`SetInfo::file_to_reference`] converts it
//! to hdrsynth's (1 = frame 2's white).

use super::{Entry, ExposureFile, GroundTruth, GroundTruthKind, SetInfo, SetRead};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

pub const INPUT_EXP_FILE: &str = "input_exp.txt";
pub const REF_EXP_FILE: &str = "ref_exp.txt";
/// The preferred ground-truth name when several `ref_hdr_aligned*.hdr` exist.
pub const GT_FILE: &str = "ref_hdr_aligned.hdr";
/// Frame number (1-based) of the reference frame.
pub const REFERENCE_FRAME: usize = 2;
/// Relative EVs of the ref frames may differ from the inputs' by at most this (stops).
const EV_TOLERANCE: f32 = 1e-3;

/// `input_N_aligned.{tif,tiff,png}` → Some(N).
fn input_number(f: &Entry) -> Option<u32> {
    frame_number(f, "input_")
}

/// `ref_N_aligned.{tif,tiff,png}` → Some(N).
fn ref_number(f: &Entry) -> Option<u32> {
    frame_number(f, "ref_")
}

fn frame_number(f: &Entry, prefix: &str) -> Option<u32> {
    let (stem, ext) = super::split_ext(&f.lower);
    if !matches!(ext, "tif" | "tiff" | "png") {
        return None;
    }
    super::numbered(stem, prefix, "_aligned")
}

fn is_gt(f: &Entry) -> bool {
    let (stem, ext) = super::split_ext(&f.lower);
    ext == "hdr" && stem.starts_with("ref_hdr_aligned")
}

/// The first file whose name belongs to this layout.
pub(super) fn claims(files: &[Entry]) -> Option<String> {
    files
        .iter()
        .find(|f| {
            input_number(f).is_some()
                || ref_number(f).is_some()
                || is_gt(f)
                || f.lower == INPUT_EXP_FILE
                || f.lower == REF_EXP_FILE
        })
        .map(|f| f.name.clone())
}

/// Exactly frames 1, 2, 3 of one kind (`what` = "input" or "ref"), in frame order.
fn three_frames(
    dir: &Path,
    files: &[Entry],
    what: &str,
    number: fn(&Entry) -> Option<u32>,
) -> Result<Vec<PathBuf>> {
    let mut slots: [Option<&Entry>; 3] = [None; 3];
    for f in files {
        let Some(n) = number(f) else { continue };
        if !(1..=3).contains(&n) {
            return Err(Error::layout(
                &f.path,
                format!(
                    "frame number {n}; Wu sets have exactly three {what} frames, {what}_1..3_aligned"
                ),
            ));
        }
        let slot = &mut slots[n as usize - 1];
        if let Some(prev) = slot {
            return Err(Error::layout(
                &f.path,
                format!("{what} frame {n} is also stored as {}; keep one", prev.name),
            ));
        }
        *slot = Some(f);
    }
    slots
        .iter()
        .enumerate()
        .map(|(i, s)| match s {
            Some(f) => Ok(f.path.clone()),
            None => Err(Error::layout(
                dir.join(format!("{what}_{}_aligned.{{tif,png}}", i + 1)),
                format!("missing (Wu sets need three aligned {what} frames, {what}_1..3_aligned)"),
            )),
        })
        .collect()
}

/// Read one Wu set folder; errors name the folder or file and what is wrong.
pub(super) fn read_set(dir: &Path, name: &str, files: &[Entry]) -> Result<SetRead> {
    let inputs = three_frames(dir, files, "input", input_number)?;
    let has_refs = files.iter().any(|f| ref_number(f).is_some());
    let refs = if has_refs {
        three_frames(dir, files, "ref", ref_number)?
    } else {
        Vec::new()
    };

    let input_exp = super::find_file(files, INPUT_EXP_FILE)
        .map(|f| f.path.clone())
        .unwrap_or_else(|| dir.join(INPUT_EXP_FILE));
    let stops = super::read_stops(
        &input_exp,
        3,
        "Wu sets need log2 exposure stops of input_1..3_aligned",
    )?;
    let ev_by_frame = super::relative_evs(&input_exp, &stops, REFERENCE_FRAME - 1)?;

    if has_refs && let Some(ref_exp) = super::find_file(files, REF_EXP_FILE) {
        let ref_stops =
            super::read_stops(&ref_exp.path, 3, "log2 exposure stops of ref_1..3_aligned")?;
        let ref_evs = super::relative_evs(&ref_exp.path, &ref_stops, REFERENCE_FRAME - 1)?;
        if ref_evs
            .iter()
            .zip(&ev_by_frame)
            .any(|(a, b)| (a - b).abs() > EV_TOLERANCE)
        {
            return Err(Error::layout(
                &ref_exp.path,
                format!(
                    "ref frames' EVs {ref_evs:?} (relative to frame {REFERENCE_FRAME}) differ from \
                     the inputs' {ev_by_frame:?} in {INPUT_EXP_FILE}; static and dynamic frames \
                     must share exposures"
                ),
            ));
        }
    }

    // Ground truth: ref_hdr_aligned*.hdr; several → the exact name ref_hdr_aligned.hdr.
    let candidates: Vec<&Entry> = files.iter().filter(|f| is_gt(f)).collect();
    let mut notes = Vec::new();
    let gt = match candidates.len() {
        0 => None,
        1 => Some(candidates[0].path.clone()),
        _ => match candidates.iter().find(|f| f.lower == GT_FILE) {
            Some(chosen) => {
                for other in candidates.iter().filter(|f| f.path != chosen.path) {
                    notes.push((
                        other.path.clone(),
                        format!(
                            "ground-truth candidate not used: several ref_hdr_aligned*.hdr, took {}",
                            chosen.name
                        ),
                    ));
                }
                Some(chosen.path.clone())
            }
            None => {
                let names: Vec<&str> = candidates.iter().map(|f| f.name.as_str()).collect();
                return Err(Error::layout(
                    dir,
                    format!(
                        "several ground-truth candidates [{}] and none named {GT_FILE}; \
                         keep one or rename the right one to {GT_FILE}",
                        names.join(", ")
                    ),
                ));
            }
        },
    };

    // Order frames by ascending EV; the reference is wherever frame 2 lands.
    let mut order: Vec<usize> = (0..3).collect();
    order.sort_by(|&a, &b| ev_by_frame[a].total_cmp(&ev_by_frame[b]));
    let reference = order
        .iter()
        .position(|&i| i == REFERENCE_FRAME - 1)
        .expect("frame 2 is among the three");
    let evs: Vec<f32> = order.iter().map(|&i| ev_by_frame[i]).collect();
    let sorted_stops: Vec<f32> = order.iter().map(|&i| stops[i]).collect();
    let dynamic_frames: Vec<PathBuf> = order.iter().map(|&i| inputs[i].clone()).collect();
    let static_frames: Vec<PathBuf> = if refs.is_empty() {
        Vec::new()
    } else {
        order.iter().map(|&i| refs[i].clone()).collect()
    };

    let mut all: Vec<&Path> = dynamic_frames.iter().map(|p| p.as_path()).collect();
    all.extend(static_frames.iter().map(|p| p.as_path()));
    let (width, height, _) = super::common_size(&all, reference, gt.as_deref())?;

    let set = SetInfo {
        name: name.to_string(),
        dir: dir.to_path_buf(),
        width,
        height,
        evs,
        reference,
        static_frames,
        dynamic_frames,
        masks: Vec::new(),
        clean_frames: Vec::new(),
        ground_truth: gt.map(|path| GroundTruth {
            path,
            kind: GroundTruthKind::Linear,
        }),
        // Wu et al.'s code (`in_exps -= in_exps.min()`, then t = 2^s) puts the shortest
        // frame at t = 1, whatever the file's offset: the ground truth is in its unit.
        exposure: Some(ExposureFile {
            path: input_exp,
            origin: sorted_stops[0],
            stops: sorted_stops,
        }),
    };
    Ok((set, notes))
}
