//! Dataset layouts on disk, auto-detected. Every reader produces the same description
//! ([`DatasetInfo`] of [`SetInfo`]s) so later stages never care where a set came from.
//!
//! Conventions for every layout: frames are ordered by ascending EV; `evs[i]` is frame i's
//! exposure in stops relative to the reference frame (`evs[reference] == 0`). Linear ground
//! truth is used in hdrsynth's unit, 1 = the reference exposure's white
//! ([`read_linear_ground_truth`]); the file's own unit follows from [`ExposureFile`].

pub mod hdrsynth;
pub mod info;
pub mod kalantari;
pub mod paper1;
pub mod wu;

use crate::error::{Error, Result};
use crate::io::{Format, Image};
use image::ImageDecoder;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayoutKind {
    /// hdrsynth's own layout (docs/layout.md).
    Hdrsynth,
    /// Kalantari & Ramamoorthi 2017: three 16-bit TIFFs, exposure.txt, HDRImg.hdr.
    Kalantari,
    /// Wu et al. 2018 / the paper's Dataset-2: input_*_aligned, ref_*_aligned, *_exp.txt, ref_hdr_aligned*.hdr.
    Wu,
    /// The paper's Dataset-1: input_1..4.png and hdr_gt.png (8-bit display ground truth).
    PaperDataset1,
}

impl std::fmt::Display for LayoutKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            LayoutKind::Hdrsynth => "hdrsynth",
            LayoutKind::Kalantari => "kalantari",
            LayoutKind::Wu => "wu",
            LayoutKind::PaperDataset1 => "paper-dataset-1",
        })
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroundTruthKind {
    /// Linear HDR radiance (EXR / .hdr), scaled to the reference exposure.
    Linear,
    /// Display-referred 8-bit image (the paper's Dataset-1 `hdr_gt.png`).
    Display,
}

#[derive(Clone, Debug, PartialEq)]
pub struct GroundTruth {
    pub path: PathBuf,
    pub kind: GroundTruthKind,
}

/// One multi-exposure set, described but not loaded.
#[derive(Clone, Debug, PartialEq)]
pub struct SetInfo {
    pub name: String,
    pub dir: PathBuf,
    pub width: usize,
    pub height: usize,
    /// Stops relative to the reference frame, ascending.
    pub evs: Vec<f32>,
    /// Index of the reference frame in `evs`.
    pub reference: usize,
    /// Frames with motion stopped (empty where the layout has none, e.g. Kalantari).
    pub static_frames: Vec<PathBuf>,
    /// Frames with motion (what a network sees at test time on a dynamic scene).
    pub dynamic_frames: Vec<PathBuf>,
    /// Motion masks per dynamic frame, where the layout has them.
    pub masks: Vec<PathBuf>,
    /// Noise-free renderings of the static frames (same exposure and quantisation), one per EV,
    /// where the set has them (`hdrsynth testset` writes them); empty otherwise.
    pub clean_frames: Vec<PathBuf>,
    pub ground_truth: Option<GroundTruth>,
    /// The exposure file's stops and the unit of the set's linear ground truth, for layouts
    /// that have one (Kalantari, Wu); None where the ground truth is already in hdrsynth's
    /// unit (1 = the reference exposure's white: hdrsynth's own layout).
    pub exposure: Option<ExposureFile>,
}

/// Absolute exposure stops as a layout's exposure file writes them, and the stop of the unit
/// exposure time in the field's reading of that file: its code linearises frame i as
/// LDR^γ / 2^(s_i − origin), and the set's ground truth is in that unit.
#[derive(Clone, Debug, PartialEq)]
pub struct ExposureFile {
    pub path: PathBuf,
    /// Log2 stops as written, in the set's frame order (ascending EV).
    pub stops: Vec<f32>,
    /// The stop whose exposure time is 1 in the field's code: 0 for Kalantari's `exposure.txt`
    /// (HDR-Transformer: t = 2^s as written), the smallest stop for Wu's `input_exp.txt`
    /// (Wu et al.'s code subtracts the minimum first).
    pub origin: f32,
}

impl SetInfo {
    /// Factor from the unit of the set's files (linear ground truth, predictions made by the
    /// field's tools) to hdrsynth's unit, 1 = the reference exposure's white.
    ///
    /// The field's code writes HDR = LDR_i^γ / 2^(s_i − origin) for every well-exposed frame
    /// i, hdrsynth's unit is LDR_i^γ / 2^(s_i − s_ref); their ratio is 2^(s_ref − origin).
    /// E.g. Kalantari's "0 2 4": 2^2 = 4 (the file's unit is the shortest frame's white).
    pub fn file_to_reference(&self) -> f32 {
        match &self.exposure {
            Some(e) => (e.stops[self.reference] - e.origin).exp2(),
            None => 1.0,
        }
    }

    /// The reference (EV 0) input frame as Network-2 is given it: the static one where the set
    /// has static frames, else the dynamic one. None when the set lists no frame at the
    /// reference index.
    pub fn reference_frame(&self) -> Option<&Path> {
        let frames = if self.static_frames.is_empty() {
            &self.dynamic_frames
        } else {
            &self.static_frames
        };
        frames.get(self.reference).map(PathBuf::as_path)
    }

    /// Indices (short, long) of Network-1's pair and of the blend-class ground truth: EV−3 and
    /// the reference when the set has both (the paper's pair), else its lowest EV and the
    /// reference.
    pub fn network1_pair(&self) -> Result<(usize, usize)> {
        let r = self.reference;
        if let Some(i) = self.evs.iter().position(|&e| e == -3.0)
            && i != r
        {
            return Ok((i, r));
        }
        match (0..self.evs.len()).min_by(|&a, &b| self.evs[a].total_cmp(&self.evs[b])) {
            Some(lo) if self.evs[lo] < self.evs[r] => Ok((lo, r)),
            _ => Err(Error::layout(
                &self.dir,
                format!(
                    "set '{}': EVs {:?} hold no frame shorter than the reference; Network-1 and \
                     its blend classes need a short and a long exposure",
                    self.name, self.evs
                ),
            )),
        }
    }
}

/// The loaded pixels of a set. LDR frames are code values in [0,1] as stored.
#[derive(Clone, Debug)]
pub struct LoadedSet {
    pub static_frames: Vec<Image>,
    pub dynamic_frames: Vec<Image>,
    pub ground_truth: Option<Image>,
}

#[derive(Clone, Debug)]
pub struct DatasetInfo {
    pub root: PathBuf,
    pub layout: LayoutKind,
    pub sets: Vec<SetInfo>,
    /// Sub-folders that were looked at and not taken, with the reason (reported to the user).
    pub skipped: Vec<(PathBuf, String)>,
}

/// What each layout looks for, for messages that tell the user what was expected.
const LAYOUT_HINTS: &str = "Kalantari: three 16-bit .tif + exposure.txt + HDRImg.hdr; \
     Wu: input_{1,2,3}_aligned.{tif,png} + input_exp.txt + ref_hdr_aligned*.hdr; \
     paper Dataset-1: input_1..4.png + hdr_gt.png; hdrsynth: dataset.toml";

/// The set in folder `dir`: a set of the dataset that contains it, or a dataset of one set.
pub fn find_set(dir: &Path) -> Result<SetInfo> {
    let want = dir
        .canonicalize()
        .map_err(|e| Error::context(format!("set folder {}", dir.display()), e))?;
    if let Some(parent) = want.parent()
        && let Ok(info) = detect(parent)
        && let Some(set) = info
            .sets
            .into_iter()
            .find(|s| s.dir.canonicalize().is_ok_and(|d| d == want))
    {
        return Ok(set);
    }
    let info = detect(&want)?;
    match <[SetInfo; 1]>::try_from(info.sets) {
        Ok([set]) => Ok(set),
        Err(sets) => Err(Error::layout(
            dir,
            format!(
                "not a set folder (a dataset of {} sets); pass one set's folder",
                sets.len()
            ),
        )),
    }
}

/// Detect the layout of `root` and describe its sets.
///
/// Order: hdrsynth's own layout (root/dataset.toml); else `root` itself as one set; else each
/// sub-folder (sorted by name) and, for a sub-folder that is not a set itself, its sub-folders
/// (e.g. Kalantari's `Training/<scene>`; such sets are named `Training/<scene>`). All sets must
/// share one layout. Folders that look like a set but are broken are an error naming the
/// folder or file; folders that look like no set are listed in [`DatasetInfo::skipped`].
pub fn detect(root: &Path) -> Result<DatasetInfo> {
    if !root.exists() {
        return Err(Error::io(
            root,
            std::io::Error::new(std::io::ErrorKind::NotFound, "dataset folder not found"),
        ));
    }
    if !root.is_dir() {
        return Err(Error::layout(
            root,
            "not a folder (a dataset is a folder of sets)",
        ));
    }
    if hdrsynth::is_dataset(root) {
        return hdrsynth::read(root);
    }

    let root_name = root
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| root.display().to_string());
    let root_probe = match classify(root, &root_name)? {
        Probe::Set { layout, set, notes } => {
            return Ok(DatasetInfo {
                root: root.to_path_buf(),
                layout,
                sets: vec![*set],
                skipped: notes,
            });
        }
        Probe::NotASet(n) => n,
    };

    let mut found: Vec<(LayoutKind, SetInfo)> = Vec::new();
    let mut skipped: Vec<(PathBuf, String)> = Vec::new();
    let listing = list_dir(root)?;
    for sub in &listing.dirs {
        match classify(&sub.path, &sub.name)? {
            Probe::Set { layout, set, notes } => {
                found.push((layout, *set));
                skipped.extend(notes);
            }
            Probe::NotASet(not) => scan_below(sub, not, &mut found, &mut skipped)?,
        }
    }
    if !found.is_empty() && root_probe.has_images {
        skipped.insert(0, (root.to_path_buf(), root_probe.reason.clone()));
    }
    if found.is_empty() {
        return Err(no_sets(root, &listing, &root_probe, &skipped));
    }
    let layout = one_layout(root, &found)?;
    Ok(DatasetInfo {
        root: root.to_path_buf(),
        layout,
        sets: found.into_iter().map(|(_, s)| s).collect(),
        skipped,
    })
}

/// The sub-folders of `sub`, a folder that is not a set itself (e.g. Kalantari's `Training`):
/// their sets go into `found`, the rest into `skipped`, and so does `sub` when it holds
/// images of its own or nothing below it is a set.
fn scan_below(
    sub: &Entry,
    not: NotASet,
    found: &mut Vec<(LayoutKind, SetInfo)>,
    skipped: &mut Vec<(PathBuf, String)>,
) -> Result<()> {
    let inner = list_dir(&sub.path)?;
    let mut inner_found = 0usize;
    let mut inner_skipped = Vec::new();
    for d in &inner.dirs {
        let name = format!("{}/{}", sub.name, d.name);
        match classify(&d.path, &name)? {
            Probe::Set { layout, set, notes } => {
                found.push((layout, *set));
                skipped.extend(notes);
                inner_found += 1;
            }
            Probe::NotASet(n) => inner_skipped.push((d.path.clone(), n.reason)),
        }
    }
    if inner_found > 0 {
        if not.has_images {
            skipped.push((sub.path.clone(), not.reason));
        }
        skipped.extend(inner_skipped);
    } else if inner.dirs.is_empty() {
        skipped.push((sub.path.clone(), not.reason));
    } else {
        skipped.push((
            sub.path.clone(),
            format!(
                "{}; none of its {} sub-folder(s) is a set either",
                not.reason,
                inner.dirs.len()
            ),
        ));
    }
    Ok(())
}

/// The error for a dataset folder without sets: where [`detect`] looked and, for the first
/// ten things skipped, why.
fn no_sets(
    root: &Path,
    listing: &Listing,
    root_probe: &NotASet,
    skipped: &[(PathBuf, String)],
) -> Error {
    let mut msg = format!(
        "no sets found: looked at the folder itself, its sub-folders and one level below \
         for a known layout ({LAYOUT_HINTS})"
    );
    if listing.dirs.is_empty() || root_probe.has_images {
        msg.push_str(&format!("; the folder itself: {}", root_probe.reason));
    }
    if !skipped.is_empty() {
        msg.push_str("; skipped: ");
        let parts: Vec<String> = skipped
            .iter()
            .take(10)
            .map(|(p, r)| format!("{} ({r})", p.display()))
            .collect();
        msg.push_str(&parts.join(", "));
        if skipped.len() > 10 {
            msg.push_str(&format!(", … {} more", skipped.len() - 10));
        }
    }
    Error::layout(root, msg)
}

/// The one layout of the sets found (`found` is not empty), or an error counting each
/// layout's sets with an example.
fn one_layout(root: &Path, found: &[(LayoutKind, SetInfo)]) -> Result<LayoutKind> {
    let layout = found[0].0;
    if found.iter().all(|(l, _)| *l == layout) {
        return Ok(layout);
    }
    let mut groups: Vec<(LayoutKind, usize, String)> = Vec::new();
    for (l, s) in found {
        match groups.iter_mut().find(|g| g.0 == *l) {
            Some(g) => g.1 += 1,
            None => groups.push((*l, 1, s.name.clone())),
        }
    }
    let parts: Vec<String> = groups
        .iter()
        .map(|(l, n, first)| format!("{n} {l} set(s) (e.g. {first})"))
        .collect();
    Err(Error::layout(
        root,
        format!(
            "mixed layouts: {}; a dataset folder must hold sets of one layout \
             (point at a sub-folder or separate them)",
            parts.join(", ")
        ),
    ))
}

/// A linear ground truth in hdrsynth's unit (1 = the reference exposure's white): the file's
/// values × [`SetInfo::file_to_reference`]. Display-referred ground truth is returned as is.
pub fn to_reference_unit(set: &SetInfo, gt: &GroundTruth, mut img: Image) -> Image {
    let k = set.file_to_reference();
    if gt.kind == GroundTruthKind::Linear && k != 1.0 {
        img.data.par_iter_mut().for_each(|v| *v *= k);
    }
    img
}

/// A set's linear ground truth in hdrsynth's unit (1 = the reference exposure's white), checked
/// against the set's size. Errors name the file (or the set when it has none, or when its
/// ground truth is display-referred).
pub fn read_linear_ground_truth(set: &SetInfo) -> Result<Image> {
    match &set.ground_truth {
        Some(gt) if gt.kind == GroundTruthKind::Linear => {
            let img = read_set_image(set, &gt.path)?;
            Ok(to_reference_unit(set, gt, img))
        }
        Some(gt) => Err(Error::layout(
            &gt.path,
            format!(
                "set '{}': the ground truth is display-referred (8-bit), so linear HDR outputs \
                 cannot be scored against it",
                set.name
            ),
        )),
        None => Err(Error::layout(
            &set.dir,
            format!("set '{}' has no ground truth", set.name),
        )),
    }
}

/// Read one image of `set` (a frame, mask, clean frame, ground truth or a frame's linear
/// sibling), refusing it unless it has the set's size: a size is never trusted from the set's
/// metadata alone (a short frame would otherwise panic a crop, a larger one be used silently).
pub fn read_set_image(set: &SetInfo, path: &Path) -> Result<Image> {
    let img = crate::io::read_image(path)?;
    check_size(path, img.width, img.height, set.width, set.height)?;
    Ok(img)
}

/// Every file a set refers to (frames, masks, clean frames, ground truth), in that order.
pub fn set_files(set: &SetInfo) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = set
        .static_frames
        .iter()
        .chain(&set.dynamic_frames)
        .chain(&set.masks)
        .chain(&set.clean_frames)
        .cloned()
        .collect();
    files.extend(set.ground_truth.as_ref().map(|g| g.path.clone()));
    files.dedup();
    files
}

/// Decode every file of every set (plus each frame's linear `.exr` sibling where there is one,
/// as the loader reads it) and check its size against its set. Returns the files that fail,
/// each with its error; empty when the dataset is sound. Costs one full decode per file.
pub fn verify(info: &DatasetInfo) -> Vec<(PathBuf, Error)> {
    let jobs: Vec<(&SetInfo, PathBuf)> = info
        .sets
        .iter()
        .flat_map(|set| {
            let mut files = set_files(set);
            for f in set.static_frames.iter().chain(&set.dynamic_frames) {
                let sib = f.with_extension("exr");
                if sib != *f && sib.exists() && !files.contains(&sib) {
                    files.push(sib);
                }
            }
            files.into_iter().map(move |f| (set, f))
        })
        .collect();
    jobs.par_iter()
        .filter_map(|(set, f)| read_set_image(set, f).err().map(|e| (f.clone(), e)))
        .collect()
}

/// Load a set's frames and ground truth (linear ground truth in hdrsynth's unit, see
/// [`to_reference_unit`]). Every image must have the set's size.
pub fn load_set(set: &SetInfo) -> Result<LoadedSet> {
    let read = |path: &PathBuf| -> Result<Image> { read_set_image(set, path) };
    let static_frames = set
        .static_frames
        .par_iter()
        .map(read)
        .collect::<Result<Vec<_>>>()?;
    let dynamic_frames = set
        .dynamic_frames
        .par_iter()
        .map(read)
        .collect::<Result<Vec<_>>>()?;
    let ground_truth = set
        .ground_truth
        .as_ref()
        .map(|gt| read(&gt.path).map(|img| to_reference_unit(set, gt, img)))
        .transpose()?;
    Ok(LoadedSet {
        static_frames,
        dynamic_frames,
        ground_truth,
    })
}

// ---------------------------------------------------------------------------------------------
// Shared helpers for the layout readers.

/// Result of looking at one folder.
enum Probe {
    Set {
        layout: LayoutKind,
        // Boxed: a SetInfo is ten times the size of the other variant (clippy).
        set: Box<SetInfo>,
        /// Things looked at and not taken inside the set (e.g. a second GT candidate).
        notes: Vec<(PathBuf, String)>,
    },
    NotASet(NotASet),
}

struct NotASet {
    reason: String,
    has_images: bool,
}

/// A set reader's result: the set plus notes for [`DatasetInfo::skipped`].
pub(crate) type SetRead = (SetInfo, Vec<(PathBuf, String)>);

/// Classify one folder: a set of exactly one layout, a broken set (error), or not a set.
fn classify(dir: &Path, name: &str) -> Result<Probe> {
    let listing = list_dir(dir)?;
    let files = &listing.files;
    let mut claims: Vec<(LayoutKind, String)> = Vec::new();
    if let Some(f) = wu::claims(files) {
        claims.push((LayoutKind::Wu, f));
    }
    if let Some(f) = paper1::claims(files) {
        claims.push((LayoutKind::PaperDataset1, f));
    }
    if let Some(f) = kalantari::claims(files) {
        claims.push((LayoutKind::Kalantari, f));
    }
    let layout = match claims.len() {
        0 if kalantari::has_tiffs(files) => LayoutKind::Kalantari,
        0 => {
            let images: Vec<&Entry> = files.iter().filter(|f| is_image_name(&f.lower)).collect();
            return Ok(Probe::NotASet(if images.is_empty() {
                NotASet {
                    reason: "no image files".into(),
                    has_images: false,
                }
            } else {
                NotASet {
                    reason: format!(
                        "{} image file(s) (e.g. {}) but no known layout's file names ({LAYOUT_HINTS})",
                        images.len(),
                        images[0].name
                    ),
                    has_images: true,
                }
            }));
        }
        1 => claims[0].0,
        _ => {
            let parts: Vec<String> = claims.iter().map(|(l, f)| format!("{l} ({f})")).collect();
            return Err(Error::layout(
                dir,
                format!(
                    "holds files of several layouts: {}; a set folder must match exactly one",
                    parts.join(", ")
                ),
            ));
        }
    };
    let (set, notes) = match layout {
        LayoutKind::Kalantari => kalantari::read_set(dir, name, files)?,
        LayoutKind::Wu => wu::read_set(dir, name, files)?,
        LayoutKind::PaperDataset1 => paper1::read_set(dir, name, files)?,
        LayoutKind::Hdrsynth => unreachable!("hdrsynth datasets are read by hdrsynth::read"),
    };
    Ok(Probe::Set {
        layout,
        set: Box::new(set),
        notes,
    })
}

/// A directory entry; names starting with '.' (including macOS `._*` forks) are ignored.
#[derive(Clone, Debug)]
pub(crate) struct Entry {
    pub name: String,
    /// `name` in ASCII lower case, for case-insensitive matching.
    pub lower: String,
    pub path: PathBuf,
}

pub(crate) struct Listing {
    /// Files, sorted by name.
    pub files: Vec<Entry>,
    /// Sub-folders, sorted by name.
    pub dirs: Vec<Entry>,
}

pub(crate) fn list_dir(dir: &Path) -> Result<Listing> {
    let mut files = Vec::new();
    let mut dirs = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        let path = entry.path();
        // Follow symlinks: datasets are often assembled from links.
        let meta = std::fs::metadata(&path).map_err(|e| Error::io(&path, e))?;
        let e = Entry {
            lower: name.to_ascii_lowercase(),
            name,
            path,
        };
        if meta.is_dir() {
            dirs.push(e);
        } else if meta.is_file() {
            files.push(e);
        }
    }
    files.sort_by(|a, b| a.name.cmp(&b.name));
    dirs.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(Listing { files, dirs })
}

pub(crate) fn find_file<'a>(files: &'a [Entry], lower_name: &str) -> Option<&'a Entry> {
    files.iter().find(|f| f.lower == lower_name)
}

/// Lower-case extension of a (lower-case) file name, and the stem before it.
pub(crate) fn split_ext(lower: &str) -> (&str, &str) {
    match lower.rfind('.') {
        Some(i) if i > 0 => (&lower[..i], &lower[i + 1..]),
        _ => (lower, ""),
    }
}

/// `stem == prefix + digits + suffix` → the number.
pub(crate) fn numbered(stem: &str, prefix: &str, suffix: &str) -> Option<u32> {
    let digits = stem.strip_prefix(prefix)?.strip_suffix(suffix)?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

fn is_image_name(lower: &str) -> bool {
    matches!(
        split_ext(lower).1,
        "png" | "tif" | "tiff" | "hdr" | "pic" | "exr" | "jpg" | "jpeg" | "bmp" | "dng"
    )
}

/// Read `expected` exposure values (log2 stops, whitespace separated) from a text file.
/// `what` says what the values are for, used in the messages.
pub(crate) fn read_stops(path: &Path, expected: usize, what: &str) -> Result<Vec<f32>> {
    let text = match crate::io::guard::read_input_text(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(Error::layout(path, format!("missing ({what})")));
        }
        Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
            return Err(Error::layout(path, "not a text file (expected numbers)"));
        }
        Err(e) => return Err(Error::io(path, e)),
    };
    parse_stops(&text, path, expected)
}

/// The values of an exposure file's text, as [`read_stops`] reads them from `path` (named in
/// errors); in memory so the fuzzer can run it without a file.
pub fn parse_stops(text: &str, path: &Path, expected: usize) -> Result<Vec<f32>> {
    let text = text.trim_start_matches('\u{feff}');
    let mut values = Vec::new();
    for tok in text.split_whitespace() {
        match tok.parse::<f32>() {
            Ok(v) if v.is_finite() => values.push(v),
            _ => {
                return Err(Error::layout(
                    path,
                    format!("'{tok}' is not a number (expected {expected} log2 exposure stops)"),
                ));
            }
        }
    }
    if values.len() != expected {
        return Err(Error::layout(
            path,
            format!(
                "holds {} value(s), expected {expected} log2 exposure stops (one per frame)",
                values.len()
            ),
        ));
    }
    Ok(values)
}

/// What a file's header says, without decoding the pixels where the format allows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Header {
    pub width: usize,
    pub height: usize,
    /// Bits per sample for PNG/TIFF; None for float formats.
    pub bits: Option<u32>,
}

pub(crate) fn read_header(path: &Path) -> Result<Header> {
    let format = Format::from_path(path)?;
    if format == Format::Exr {
        let img = crate::io::read_image(path)?;
        return Ok(Header {
            width: img.width,
            height: img.height,
            bits: None,
        });
    }
    let image_err = |e: image::ImageError| match e {
        image::ImageError::IoError(io)
            if matches!(
                io.kind(),
                std::io::ErrorKind::NotFound | std::io::ErrorKind::PermissionDenied
            ) =>
        {
            Error::io(path, io)
        }
        other => Error::decode(path, other),
    };
    let file = crate::io::guard::open_input(path).map_err(|e| Error::io(path, e))?;
    let mut reader = image::ImageReader::new(std::io::BufReader::new(file));
    if let Ok(f) = image::ImageFormat::from_path(path) {
        reader.set_format(f);
    }
    let decoder = match reader.into_decoder() {
        Ok(d) => d,
        // Old .pic files without the RADIANCE signature: io's reader accepts them.
        Err(_) if format == Format::Hdr => {
            let img = crate::io::read_image(path)?;
            return Ok(Header {
                width: img.width,
                height: img.height,
                bits: None,
            });
        }
        Err(e) => return Err(image_err(e)),
    };
    let (w, h) = decoder.dimensions();
    // The decode limits before the size is trusted (as the set's size, say): a frame declaring
    // 100000×100000 or 0×64 is blamed itself, not the frames that differ from it.
    crate::io::limits::check(path, format.name(), w.into(), h.into())?;
    let ct = decoder.original_color_type();
    let bits = match format {
        Format::Png | Format::Tiff => {
            Some(ct.bits_per_pixel() as u32 / (ct.channel_count() as u32).max(1))
        }
        _ => None,
    };
    Ok(Header {
        width: w as usize,
        height: h as usize,
        bits,
    })
}

/// Error naming `path` when its size differs from the set's.
pub(crate) fn check_size(
    path: &Path,
    w: usize,
    h: usize,
    set_w: usize,
    set_h: usize,
) -> Result<()> {
    if (w, h) != (set_w, set_h) {
        return Err(Error::layout(
            path,
            format!("size {w}×{h} differs from the set's {set_w}×{set_h} (reference frame)"),
        ));
    }
    Ok(())
}

/// Read the headers of `frames` (the reference at `reference`) and the ground truth; all
/// must have the reference frame's size. Returns (width, height, per-frame headers).
pub(crate) fn common_size(
    frames: &[&Path],
    reference: usize,
    gt: Option<&Path>,
) -> Result<(usize, usize, Vec<Header>)> {
    let headers = frames
        .par_iter()
        .map(|p| read_header(p))
        .collect::<Result<Vec<_>>>()?;
    let r = headers[reference];
    for (p, h) in frames.iter().zip(&headers) {
        check_size(p, h.width, h.height, r.width, r.height)?;
    }
    if let Some(gt) = gt {
        let h = read_header(gt)?;
        check_size(gt, h.width, h.height, r.width, r.height)?;
    }
    Ok((r.width, r.height, headers))
}

/// EVs relative to frame `reference` of `stops`; error naming `path` when two are equal.
pub fn relative_evs(path: &Path, stops: &[f32], reference: usize) -> Result<Vec<f32>> {
    for i in 0..stops.len() {
        for j in i + 1..stops.len() {
            if stops[i] == stops[j] {
                return Err(Error::layout(
                    path,
                    format!(
                        "frames {} and {} have the same exposure ({}); a bracket needs distinct exposures",
                        i + 1,
                        j + 1,
                        stops[i]
                    ),
                ));
            }
        }
    }
    Ok(stops.iter().map(|s| s - stops[reference]).collect())
}
