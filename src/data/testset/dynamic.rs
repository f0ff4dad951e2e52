//! Test scenes with moving subjects: the sets of a dataset the scene engine generated with its
//! linear frames (`hdrsynth generate`, `write_linear = true`). Per set, the reference radiance
//! is `hdr_gt.exr`; frame i's radiance at its own time is `dynamic/<ev>.exr` ÷ 2^EV_i (the same
//! unit), taken where the set's motion mask marks a subject and the reference's elsewhere, so
//! the static and dynamic renderings agree outside the mask to the byte. `testset` renders
//! every frame through the sensor model; the ground truth is the reference's radiance, as in
//! Kalantari's and Wu's sets and the paper's training pairs.

use super::RECIPE;
use super::radiance::load_radiance;
use crate::data::layout::hdrsynth::{self as own};
use crate::data::scene::ev_tag;
use crate::error::{Error, Result};
use crate::io::{Image, read_image, resize};
use std::path::{Path, PathBuf};

/// A scene's radiance: the reference's, and per frame its moving version where it has one.
pub struct SceneRadiance {
    /// Radiance at the reference frame's time (the ground truth's and the static frames').
    pub reference: Image,
    pub moving: Option<Moving>,
}

impl SceneRadiance {
    /// A static scene of one radiance map.
    pub fn still(reference: Image) -> SceneRadiance {
        SceneRadiance {
            reference,
            moving: None,
        }
    }
}

/// The frames of a dynamic scene, in the test set's EV order.
pub struct Moving {
    /// Radiance at each frame's time, in the reference's unit.
    pub radiance: Vec<Image>,
    /// Per frame, 1 where a subject moved (in either pose), else 0: one value per pixel.
    pub masks: Vec<Vec<u8>>,
    /// Frame times in frame intervals (reference = 0).
    pub times: Vec<f32>,
    pub subjects: usize,
    pub articulated: usize,
}

impl Moving {
    /// 1 where any frame's mask is set.
    pub fn union(&self) -> Vec<u8> {
        let mut u = vec![0u8; self.masks.first().map_or(0, Vec::len)];
        for m in &self.masks {
            u.iter_mut().zip(m).for_each(|(a, &b)| *a |= b);
        }
        u
    }
}

/// Whether `input` is a generated dataset (not a test set, whose folder also holds a
/// manifest): its sets are dynamic scenes.
pub fn is_generated(input: &Path) -> bool {
    input.is_dir() && own::is_dataset(input) && !input.join(RECIPE).is_file()
}

/// The set folders of a generated dataset, in name order; an incomplete set is an error.
pub fn scene_dirs(input: &Path) -> Result<Vec<PathBuf>> {
    let info = own::read(input)?;
    if let Some((dir, why)) = info.skipped.first() {
        return Err(Error::layout(dir, why.clone()));
    }
    if info.sets.is_empty() {
        return Err(Error::layout(input, "a generated dataset with no sets"));
    }
    Ok(info.sets.into_iter().map(|s| s.dir).collect())
}

/// One generated set as a dynamic scene for a test set of `evs` (sorted), resized if asked.
/// Returns the scene and the notes of its radiance files.
pub fn load(
    dir: &Path,
    evs: &[f32],
    resize_to: Option<(usize, usize)>,
) -> Result<(SceneRadiance, Vec<String>)> {
    let meta = own::read_set_meta(dir)?;
    if meta.evs != evs {
        return Err(Error::layout(
            dir,
            format!(
                "the set's frames are at EV {:?}, the test set's at {evs:?}: generate the \
                 scenes with the test set's EVs",
                meta.evs
            ),
        ));
    }
    let mut notes = Vec::new();
    let (reference, note) = load_radiance(&dir.join("hdr_gt.exr"), resize_to)?;
    notes.extend(note);
    let (w, h) = (reference.width, reference.height);
    let mut radiance = Vec::with_capacity(evs.len());
    let mut masks = Vec::with_capacity(evs.len());
    for (i, &ev) in evs.iter().enumerate() {
        let tag = ev_tag(ev);
        let mask_path = dir.join("dynamic").join(format!("mask_{tag}.png"));
        let mut mask_img = read_image(&mask_path)?;
        if (mask_img.width, mask_img.height) != (w, h) {
            mask_img = resize(&mask_img, w, h);
        }
        // Any subject coverage after resampling counts as moving.
        let mask: Vec<u8> = mask_img
            .data
            .chunks_exact(3)
            .map(|p| u8::from(p[0].max(p[1]).max(p[2]) > 0.0))
            .collect();
        if i == meta.reference {
            if mask.iter().any(|&m| m != 0) {
                return Err(Error::layout(
                    &mask_path,
                    "the reference frame's motion mask must be empty (the reference defines \
                     the scene's time)",
                ));
            }
            radiance.push(reference.clone());
        } else {
            let path = dir.join("dynamic").join(format!("{tag}.exr"));
            if !path.is_file() {
                return Err(Error::layout(
                    &path,
                    "missing: the scenes were generated without their linear frames (set \
                     write_linear = true)",
                ));
            }
            let (mut frame, note) = load_radiance(&path, resize_to)?;
            notes.extend(note);
            if (frame.width, frame.height) != (w, h) {
                return Err(Error::layout(
                    &path,
                    format!(
                        "{}x{}, the set's ground truth is {w}x{h}",
                        frame.width, frame.height
                    ),
                ));
            }
            let scale = (-ev).exp2();
            for ((o, r), &m) in frame
                .data
                .chunks_exact_mut(3)
                .zip(reference.data.chunks_exact(3))
                .zip(&mask)
            {
                if m == 0 {
                    o.copy_from_slice(r);
                } else {
                    o.iter_mut().for_each(|v| *v *= scale);
                }
            }
            radiance.push(frame);
        }
        masks.push(mask);
    }
    Ok((
        SceneRadiance {
            reference,
            moving: Some(Moving {
                radiance,
                masks,
                times: meta.times,
                subjects: meta.stats.subjects,
                articulated: meta.stats.articulated,
            }),
        },
        notes,
    ))
}
