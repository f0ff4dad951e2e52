//! Kalantari & Ramamoorthi 2017 layout: a set is a folder holding exactly three 16-bit TIFFs
//! (any names; file-name order = ascending exposure), `exposure.txt` (three log2 exposure
//! stops, one per TIFF in the same order) and `HDRImg.hdr` (linear ground truth aligned to the
//! middle frame). All three frames have motion: they are the set's dynamic frames.
//!
//! Units: the field's code (HDR-Transformer's `read_expo_times`) reads the stops as written,
//! t_i = 2^s_i, and `HDRImg.hdr` is in that unit (LDR_i^γ / t_i); [`SetInfo::file_to_reference`]
//! converts it to hdrsynth's (1 = the middle frame's white).

use super::{Entry, ExposureFile, GroundTruth, GroundTruthKind, SetInfo, SetRead};
use crate::error::{Error, Result};
use std::path::Path;

pub const EXPOSURE_FILE: &str = "exposure.txt";
/// Written by `hdrsynth testset --brackets` (src/capture/testset.rs) into sets made from
/// static brackets: its presence marks the three frames as static too (motion-free), so
/// Network-1's Mertens reference can be fused from them. Other tools ignore it.
pub const STATIC_MARKER: &str = "brackets.toml";
pub const GT_FILE: &str = "HDRImg.hdr";
/// Index of the reference (middle) frame.
pub const REFERENCE: usize = 1;

/// The file that makes a folder a Kalantari set for sure (exposure.txt or HDRImg.hdr).
pub(super) fn claims(files: &[Entry]) -> Option<String> {
    files
        .iter()
        .find(|f| f.lower == EXPOSURE_FILE || f.lower == GT_FILE.to_ascii_lowercase())
        .map(|f| f.name.clone())
}

/// TIFFs alone also suggest a Kalantari set (a broken one if exposure.txt is missing).
pub(super) fn has_tiffs(files: &[Entry]) -> bool {
    files.iter().any(is_tiff)
}

fn is_tiff(f: &Entry) -> bool {
    matches!(super::split_ext(&f.lower).1, "tif" | "tiff")
}

/// Read one Kalantari set folder; errors name the folder or file and what is wrong.
pub(super) fn read_set(dir: &Path, name: &str, files: &[Entry]) -> Result<SetRead> {
    let tiffs: Vec<&Entry> = files.iter().filter(|f| is_tiff(f)).collect();
    if tiffs.len() != 3 {
        let names: Vec<&str> = tiffs.iter().map(|f| f.name.as_str()).collect();
        return Err(Error::layout(
            dir,
            format!(
                "found {} TIFF file(s) [{}]; Kalantari sets have exactly three 16-bit TIFFs \
                 (one per exposure, in exposure order by file name)",
                tiffs.len(),
                names.join(", ")
            ),
        ));
    }
    let exposure = super::find_file(files, EXPOSURE_FILE)
        .map(|f| f.path.clone())
        .unwrap_or_else(|| dir.join(EXPOSURE_FILE));
    let stops = super::read_stops(
        &exposure,
        3,
        "Kalantari sets need log2 exposure stops for the three TIFFs",
    )?;
    if !(stops[0] < stops[1] && stops[1] < stops[2]) {
        return Err(Error::layout(
            &exposure,
            format!(
                "stops {stops:?} do not increase; they are taken in file-name order of the TIFFs \
                 ({}, {}, {}), which must be ascending exposure",
                tiffs[0].name, tiffs[1].name, tiffs[2].name
            ),
        ));
    }
    let evs = super::relative_evs(&exposure, &stops, REFERENCE)?;
    let gt = super::find_file(files, &GT_FILE.to_ascii_lowercase()).map(|f| f.path.clone());

    let frames: Vec<&Path> = tiffs.iter().map(|f| f.path.as_path()).collect();
    let (width, height, headers) = super::common_size(&frames, REFERENCE, gt.as_deref())?;
    for (p, h) in frames.iter().zip(&headers) {
        if h.bits != Some(16) {
            return Err(Error::layout(
                p,
                format!(
                    "{}-bit TIFF; Kalantari sets have 16-bit TIFFs",
                    h.bits.map_or("unknown".to_string(), |b| b.to_string())
                ),
            ));
        }
    }

    let dynamic: Vec<std::path::PathBuf> = tiffs.iter().map(|f| f.path.clone()).collect();
    let set = SetInfo {
        name: name.to_string(),
        dir: dir.to_path_buf(),
        width,
        height,
        evs,
        reference: REFERENCE,
        static_frames: if super::find_file(files, STATIC_MARKER).is_some() {
            dynamic.clone()
        } else {
            Vec::new()
        },
        dynamic_frames: dynamic,
        masks: Vec::new(),
        clean_frames: Vec::new(),
        ground_truth: gt.map(|path| GroundTruth {
            path,
            kind: GroundTruthKind::Linear,
        }),
        // HDR-Transformer's `read_expo_times` = 2^loadtxt: the stops as written, so the
        // ground truth is in the unit of a frame at stop 0 (for the dataset's "0 2 4" files:
        // the shortest frame).
        exposure: Some(ExposureFile {
            path: exposure,
            stops,
            origin: 0.0,
        }),
    };
    Ok((set, Vec::new()))
}
