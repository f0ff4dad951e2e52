//! hdrsynth's own dataset layout (documented in docs/layout.md). A set is complete once its
//! `meta.toml` exists: it is written last, atomically, so an interrupted run resumes by
//! regenerating only the sets without one.

use super::{DatasetInfo, GroundTruth, GroundTruthKind, LayoutKind, SetInfo};
use crate::config::parse_toml;
use crate::data::scene::config::GenerateConfig;
use crate::data::scene::{RenderedSample, SampleStats, ev_tag};
use crate::error::{Error, Result};
use crate::io::{Image, atomic::write_atomic, write_exr, write_ldr};
use crate::sensor::response::ToneCurve;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const FORMAT: &str = "hdrsynth-dataset/1";
pub const MANIFEST: &str = "dataset.toml";
pub const SET_META: &str = "meta.toml";

/// `static/clean_<ev tag>.png`: the noise-free rendering of a static frame (optional; written
/// by `hdrsynth testset`), e.g. `static/clean_ev-3.png`.
pub fn clean_frame_name(ev: f32) -> String {
    format!("clean_{}.png", ev_tag(ev))
}

/// `dataset.toml` at the dataset root.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    pub format: String,
    pub width: usize,
    pub height: usize,
    pub evs: Vec<f32>,
    /// Curve baked into the display frames.
    pub tone_curve: ToneCurve,
    pub bit_depth: u32,
    /// The config that generated the dataset (absent for sets made by other tools).
    pub generator: Option<GenerateConfig>,
}

/// `<set>/meta.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SetMeta {
    pub name: String,
    pub index: u64,
    pub width: usize,
    pub height: usize,
    pub evs: Vec<f32>,
    pub reference: usize,
    /// Frame times of the dynamic set in frame intervals (reference = 0).
    pub times: Vec<f32>,
    pub stats: SampleStats,
}

pub fn is_dataset(root: &Path) -> bool {
    root.join(MANIFEST).is_file()
}

pub fn set_name(index: u64) -> String {
    format!("{index:06}")
}

fn frame_path(dir: &Path, set: &str, ev: f32, ext: &str) -> PathBuf {
    dir.join(set).join(format!("{}.{ext}", ev_tag(ev)))
}

pub fn manifest_for(cfg: &GenerateConfig) -> Manifest {
    Manifest {
        format: FORMAT.into(),
        width: cfg.width,
        height: cfg.height,
        evs: cfg.evs.clone(),
        tone_curve: cfg.tone_curve,
        bit_depth: cfg.bit_depth,
        generator: Some(cfg.clone()),
    }
}

pub fn write_manifest(root: &Path, m: &Manifest) -> Result<()> {
    let path = root.join(MANIFEST);
    let text = toml::to_string(m).map_err(|e| Error::encode(&path, e))?;
    write_atomic(&path, text.as_bytes())
}

pub fn read_manifest(root: &Path) -> Result<Manifest> {
    let path = root.join(MANIFEST);
    let text = crate::io::guard::read_text(&path)?;
    parse_manifest(&text, &path)
}

/// A `dataset.toml`'s text, checked as [`read_manifest`] checks the file `path` (named in errors).
pub fn parse_manifest(text: &str, path: &Path) -> Result<Manifest> {
    let m: Manifest = parse_toml(text, path)?;
    if m.format != FORMAT {
        return Err(Error::layout(
            path,
            format!("format '{}' is not '{FORMAT}'", m.format),
        ));
    }
    Ok(m)
}

/// Whether set `index` is already complete under `root` (for resuming).
pub fn set_done(root: &Path, index: u64) -> bool {
    root.join(set_name(index)).join(SET_META).is_file()
}

/// Write one rendered sample as set `index`: display PNGs (tone curve applied), linear EXRs,
/// masks, ground truth, and last the set's meta.toml.
pub fn write_set(
    root: &Path,
    index: u64,
    sample: &RenderedSample,
    cfg: &GenerateConfig,
) -> Result<()> {
    let name = set_name(index);
    let dir = root.join(&name);
    let curve = cfg.tone_curve;
    let depth = cfg.bit_depth();
    // One job per file so frames encode in parallel.
    enum Job<'a> {
        Frame(&'a str, &'a Image, usize),
        Mask(usize),
        Truth,
    }
    let mut jobs = Vec::new();
    for i in 0..sample.evs.len() {
        jobs.push(Job::Frame("static", &sample.static_radiance, i));
        jobs.push(Job::Frame("dynamic", &sample.dynamic_radiance[i], i));
        jobs.push(Job::Mask(i));
    }
    jobs.push(Job::Truth);
    jobs.par_iter().try_for_each(|job| -> Result<()> {
        match job {
            Job::Frame(set, radiance, i) => {
                let ev = sample.evs[*i];
                if cfg.write_linear {
                    let lin = sample.linear_frame(radiance, *i);
                    write_exr(&frame_path(&dir, set, ev, "exr"), &lin, cfg.exr_precision)?;
                }
                let display = curve.display(radiance, sample.frame_gain(*i));
                write_ldr(&frame_path(&dir, set, ev, "png"), &display, depth)
            }
            Job::Mask(i) => {
                let m = &sample.masks[*i];
                let (w, h) = (sample.static_radiance.width, sample.static_radiance.height);
                let img = Image::from_vec(w, h, m.iter().flat_map(|&v| [v as f32; 3]).collect());
                let path = dir
                    .join("dynamic")
                    .join(format!("mask_{}.png", ev_tag(sample.evs[*i])));
                write_ldr(&path, &img, crate::io::BitDepth::Eight)
            }
            Job::Truth => write_exr(
                &dir.join("hdr_gt.exr"),
                &sample.ground_truth(),
                crate::io::ExrPrecision::Float,
            ),
        }
    })?;
    let meta = SetMeta {
        name: name.clone(),
        index,
        width: sample.static_radiance.width,
        height: sample.static_radiance.height,
        evs: sample.evs.clone(),
        reference: sample.reference,
        times: sample.times.clone(),
        stats: sample.stats.clone(),
    };
    let path = dir.join(SET_META);
    let text = toml::to_string(&meta).map_err(|e| Error::encode(&path, e))?;
    write_atomic(&path, text.as_bytes())
}

pub fn read_set_meta(dir: &Path) -> Result<SetMeta> {
    let path = dir.join(SET_META);
    let text = crate::io::guard::read_text(&path)?;
    parse_set_meta(&text, &path)
}

/// A set's `meta.toml` text, as [`read_set_meta`] reads the file `path` (named in errors).
pub fn parse_set_meta(text: &str, path: &Path) -> Result<SetMeta> {
    parse_toml(text, path)
}

/// Describe a dataset in hdrsynth's layout.
pub fn read(root: &Path) -> Result<DatasetInfo> {
    read_manifest(root)?;
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(root)
        .map_err(|e| Error::io(root, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    let mut sets = Vec::new();
    let mut skipped = Vec::new();
    for dir in dirs {
        if !dir.join(SET_META).is_file() {
            skipped.push((
                dir,
                "incomplete: no meta.toml (generation interrupted?)".to_string(),
            ));
            continue;
        }
        let meta = read_set_meta(&dir)?;
        let frames = |set: &str, ext: &str| -> Result<Vec<PathBuf>> {
            meta.evs
                .iter()
                .map(|&ev| {
                    let p = dir.join(set).join(format!("{}.{ext}", ev_tag(ev)));
                    if p.is_file() {
                        Ok(p)
                    } else {
                        Err(Error::layout(
                            &p,
                            "missing (listed by the set's meta.toml evs)",
                        ))
                    }
                })
                .collect()
        };
        let masks = meta
            .evs
            .iter()
            .map(|&ev| dir.join("dynamic").join(format!("mask_{}.png", ev_tag(ev))))
            .collect();
        // Clean frames are optional, but all or none: a partial set is a broken write.
        let clean: Vec<PathBuf> = meta
            .evs
            .iter()
            .map(|&ev| dir.join("static").join(clean_frame_name(ev)))
            .collect();
        let clean_frames = match clean.iter().filter(|p| p.is_file()).count() {
            0 => Vec::new(),
            n if n == clean.len() => clean,
            _ => {
                let missing = clean.iter().find(|p| !p.is_file()).expect("one is missing");
                return Err(Error::layout(
                    missing,
                    "missing: the set has noise-free frames for other EVs (all or none)",
                ));
            }
        };
        let gt = dir.join("hdr_gt.exr");
        sets.push(SetInfo {
            name: meta.name.clone(),
            width: meta.width,
            height: meta.height,
            evs: meta.evs.clone(),
            reference: meta.reference,
            static_frames: frames("static", "png")?,
            dynamic_frames: frames("dynamic", "png")?,
            masks,
            clean_frames,
            ground_truth: gt.is_file().then_some(GroundTruth {
                path: gt,
                kind: GroundTruthKind::Linear,
            }),
            // hdr_gt.exr is already the reference exposure's linear value.
            exposure: None,
            dir,
        });
    }
    Ok(DatasetInfo {
        root: root.to_path_buf(),
        layout: LayoutKind::Hdrsynth,
        sets,
        skipped,
    })
}
