//! Test sets from HDR radiance rendered through a measured sensor model (`hdrsynth testset`,
//! docs/evaluation.md): static ones from radiance maps, dynamic ones from a generated dataset's
//! moving scenes ([`dynamic`]).
//!
//! Per radiance map (scene) and ISO one set named `<scene>_iso<N>` in hdrsynth's own layout
//! (docs/layout.md), so `layout::detect`, the loader and `hdrsynth eval` read it back:
//! - the radiance, converted to linear Rec. 709 primaries where the EXR says otherwise, is
//!   scaled by the key k of the auto-exposure rule (src/sensor/metering.rs: average metering
//!   with highlight protection, the rule training realism uses too), times the user's
//!   `exposure` factor;
//! - each bracket frame is the realism operator (colour T, noise at that ISO, levels, device
//!   response, 8-bit) applied to radiance · k · 2^EV with the profile's source response set to
//!   linear, seeded by (seed, scene, ISO, EV);
//! - `static/clean_<ev>.png` is the same frame with `NoiseModel::None` (Network-1's
//!   reference weights come from it);
//! - `hdr_gt.exr` is the radiance in the device's linear space at EV0, `T · radiance · k`
//!   ([`Realism::device_linear`], 1 = sensor white), the Network-2 loader's target convention
//!   (with `ground_truth = "scene"`: `radiance · k` in scene-linear Rec. 709, T on the frames
//!   only, matching the loader's `target_space = "scene"`),
//!   clipped per channel at the shortest frame's white (2^−EV_min): what a merge of the bracket
//!   can know, as in a real bracket's merged ground truth. Radiance above it is clipped in every
//!   frame; a ground truth holding it would score every method on values no input carries (and
//!   the Network-2 loader clips its targets at the same point).
//!
//! From a radiance map the scene is static: the dynamic frames are copies of the static ones
//! and every motion mask is 0. From a generated dataset each non-reference frame's dynamic
//! rendering sees the subjects where they were at its time, with the generator's motion mask;
//! the static frames and the ground truth are the reference's. Either way this is radiance
//! through a measured sensor model, not a real bracketed capture: real brackets in a known
//! layout are evaluated directly.

use crate::config::{KeyError, Range, each_in_range, in_range};
use crate::data::layout::hdrsynth::{self as own, Manifest, SET_META, SetMeta};
use crate::data::scene::{Camera, SampleStats, ev_tag};
use crate::error::{Error, Result};
use crate::io::atomic::write_atomic;
use crate::io::{BitDepth, ExrPrecision, Image, write_exr, write_ldr};
use crate::rng::hash;
use crate::sensor::metering::Metering;
use crate::sensor::profile::{Response, SensorProfile};
use crate::sensor::realism::{NoiseModel, Realism, RealismOptions, TargetSpace};
use crate::sensor::response::ToneCurve;
use dynamic::SceneRadiance;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub mod dynamic;
pub mod radiance;
use radiance::{load_radiance, radiance_files};

/// The recipe, written to `OUT/testset.toml` (read by nothing else; provenance and resume).
pub const RECIPE: &str = "testset.toml";
/// Version 2: the ground truth is clipped at the shortest frame's white (version 1 was not), so
/// a version-1 test set is refused rather than silently mixed with version-2 sets.
pub const RECIPE_FORMAT: &str = "hdrsynth-testset/2";

/// Every key is optional in TOML (missing keys take the defaults below).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TestsetOptions {
    /// One set per ISO (within the profile's calibrated range).
    pub isos: Vec<f64>,
    /// Bracket EVs relative to the reference; must hold 0.
    pub evs: Vec<f32>,
    pub seed: u64,
    /// Extra factor on the automatic exposure key (1 = the metering rule's choice).
    pub exposure: f64,
    /// The auto-exposure rule (src/sensor/metering.rs), the same one training realism uses.
    /// Absent: the profile's measured rule, else the default ([`Metering::resolve`]); the
    /// recipe records the rule used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub metering: Option<Metering>,
    pub noise: NoiseModel,
    /// Apply the profile's colour transform T (frames and ground truth alike).
    pub colour: bool,
    /// Bits of the frames (8 or 16).
    pub output_bits: u32,
    /// Resample every radiance map to this size (width, height) first.
    pub resize: Option<(usize, usize)>,
    /// The ground truth's space: `device` (T applied, as in the frames) or `scene`
    /// (scene-linear Rec. 709, T on the frames only).
    #[serde(skip_serializing_if = "TargetSpace::is_device")]
    pub ground_truth: TargetSpace,
}

impl Default for TestsetOptions {
    fn default() -> Self {
        TestsetOptions {
            isos: vec![100.0, 800.0, 3200.0],
            evs: vec![-3.0, 0.0],
            seed: 0,
            exposure: 1.0,
            metering: None,
            noise: NoiseModel::Gaussian,
            colour: true,
            output_bits: 8,
            resize: None,
            ground_truth: TargetSpace::Device,
        }
    }
}

/// `testset.toml`: what was rendered from what.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Recipe {
    pub format: String,
    pub note: String,
    pub profile: SensorProfile,
    pub options: TestsetOptions,
    pub scenes: Vec<SceneEntry>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneEntry {
    pub name: String,
    pub file: PathBuf,
}

/// One written set.
#[derive(Clone, Debug, PartialEq)]
pub struct BuiltSet {
    pub name: String,
    pub iso: f64,
    pub width: usize,
    pub height: usize,
    /// Radiance → EV0 linear (1 = sensor white before T).
    pub key: f32,
    /// Fraction of EV0 pixels with a channel at ≥ 0.98 code value, and ≤ 0.02.
    pub over_fraction: f32,
    pub under_fraction: f32,
    /// False when the set was already complete (resumed run).
    pub written: bool,
}

#[derive(Clone, Debug)]
pub struct TestsetSummary {
    pub sets: Vec<BuiltSet>,
    /// The scenes were a generated dataset's moving ones ([`dynamic`]), not radiance maps.
    pub dynamic: bool,
    /// Notes for the user (e.g. primaries converted).
    pub notes: Vec<String>,
}

impl TestsetSummary {
    /// The command's report: notes, one line per set, and what was written to `out` through
    /// which profile.
    pub fn report(&self, out: &Path, profile: &Path) -> String {
        use std::fmt::Write as _;
        let mut text = String::new();
        for n in &self.notes {
            let _ = writeln!(text, "note: {n}");
        }
        for b in &self.sets {
            let _ = writeln!(
                text,
                "{:<28} {}×{}  key {:.4e}  EV0 over {:.1} % under {:.1} %{}",
                b.name,
                b.width,
                b.height,
                b.key,
                100.0 * b.over_fraction,
                100.0 * b.under_fraction,
                if b.written { "" } else { "  (kept)" }
            );
        }
        let _ = write!(
            text,
            "{} set(s) in {} (hdrsynth layout; {} through the '{}' sensor model, not a real \
             bracketed capture)",
            self.sets.len(),
            out.display(),
            if self.dynamic {
                "generated scenes with moving subjects"
            } else {
                "real radiance"
            },
            profile.display()
        );
        text
    }
}

/// Scene name from a file stem: characters other than ASCII letters, digits, '-' and '_'
/// become '_' so the name is a safe folder and file name.
pub fn scene_name(path: &Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    stem.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// `<scene>_iso<N>` (N as the shortest decimal, e.g. `iso100`, `iso12.5`).
pub fn set_name(scene: &str, iso: f64) -> String {
    format!("{scene}_iso{iso}")
}

/// The scene of a set named by `set_name`: `<scene>_iso<N>` with N a positive number, else
/// `None`.
pub fn scene_of_set_name(set: &str) -> Option<&str> {
    let (scene, iso) = set.rsplit_once("_iso")?;
    let iso: f64 = iso.parse().ok()?;
    (!scene.is_empty() && iso.is_finite() && iso > 0.0).then_some(scene)
}

/// Which scene each set of the test set in `dir` shows, for statistics that resample scenes
/// (the sets of one scene at several ISOs are not independent). In order of trust: the recipe
/// `dir/testset.toml` (a set is `set_name(scene, iso)` of a listed scene and ISO), else the
/// `<scene>_iso<N>` naming convention, else the set is its own scene (e.g. Kalantari's folders).
/// A recipe that cannot be read is an error naming it.
pub fn scenes_of_sets<'a>(
    dir: &Path,
    sets: impl IntoIterator<Item = &'a str>,
) -> Result<BTreeMap<String, String>> {
    // Only the scene names and ISOs: the rest of the recipe (the profile) is not needed here.
    #[derive(Deserialize)]
    struct Scenes {
        #[serde(default)]
        options: Isos,
        scenes: Vec<SceneEntry>,
    }
    #[derive(Deserialize, Default)]
    struct Isos {
        #[serde(default)]
        isos: Vec<f64>,
    }
    let path = dir.join(RECIPE);
    let mut known = BTreeMap::new();
    if path.is_file() {
        let recipe: Scenes = crate::config::load_toml(&path)?;
        for scene in &recipe.scenes {
            for &iso in &recipe.options.isos {
                known.insert(set_name(&scene.name, iso), scene.name.clone());
            }
        }
    }
    Ok(sets
        .into_iter()
        .map(|set| {
            let scene = known
                .get(set)
                .cloned()
                .or_else(|| scene_of_set_name(set).map(str::to_string))
                .unwrap_or_else(|| set.to_string());
            (set.to_string(), scene)
        })
        .collect())
}

impl TestsetOptions {
    /// The options' rules, keys as an `[testset.options]` table spells them: ISOs > 0 (at
    /// least one), EVs distinct, within ±16 stops and holding 0, exposure factor > 0, the
    /// metering rule's ranges, 8 or 16 output bits, a resize of at least 1×1.
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        if self.isos.is_empty() {
            return Err(KeyError::new("isos", "no ISOs given"));
        }
        each_in_range("isos", &self.isos, Range::POSITIVE)?;
        if !self.evs.contains(&0.0) {
            return Err(KeyError::new(
                "evs",
                format!("{:?} must include 0 (the reference frame)", self.evs),
            ));
        }
        let max = crate::data::scene::config::MAX_EV as f64;
        each_in_range("evs", &self.evs, Range::closed(-max, max))?;
        let mut sorted = self.evs.clone();
        sorted.sort_by(f32::total_cmp);
        if sorted.windows(2).any(|w| w[0] == w[1]) {
            return Err(KeyError::new(
                "evs",
                format!("{:?} must be distinct", self.evs),
            ));
        }
        if let Some(m) = &self.metering {
            m.validate().map_err(|e| e.within("metering"))?;
        }
        in_range("exposure", self.exposure, Range::POSITIVE)?;
        if BitDepth::from_bits(self.output_bits).is_none() {
            return Err(KeyError::new(
                "output_bits",
                format!("{} must be 8 or 16", self.output_bits),
            ));
        }
        if let Some((w, h)) = self.resize {
            each_in_range("resize", &[w, h], Range::at_least(1.0))?;
        }
        Ok(())
    }
}

fn validate(opts: &TestsetOptions, profile: &SensorProfile) -> Result<()> {
    opts.validate()?;
    if opts.noise != NoiseModel::None {
        for &iso in &opts.isos {
            profile.noise_at(iso)?;
        }
    }
    Ok(())
}

/// Build the test set under `out` from the radiance file or folder `input`. Sets already
/// complete under `out` (same recipe) are kept; a different recipe there is an error.
pub fn build(
    input: &Path,
    profile: &SensorProfile,
    opts: &TestsetOptions,
    out: &Path,
) -> Result<TestsetSummary> {
    let mut opts = opts.clone();
    opts.evs.sort_by(f32::total_cmp);
    validate(&opts, profile)?;
    // The recipe holds the rule itself, wherever it came from: a test set from a profile whose
    // measured rule changed is another test set.
    let metering = Metering::resolve(opts.metering, profile.metering);
    opts.metering = Some(metering.rule);
    let dynamic = dynamic::is_generated(input);
    let scenes = scene_entries(input, dynamic)?;
    // The frames are rendered from scene-linear radiance: the source is linear, whatever the
    // profile's source response for synthetic frames is.
    let mut device = profile.clone();
    device.source_response = Response::Linear;
    let recipe = Recipe {
        format: RECIPE_FORMAT.into(),
        note: if dynamic {
            "generated scenes with moving subjects rendered through a measured sensor model \
             (colour, noise, levels, response); the ground truth is the reference frame's"
        } else {
            "real scene radiance rendered through a measured sensor model (colour, noise, \
             levels, response); not a real bracketed capture"
        }
        .into(),
        profile: device.clone(),
        options: opts.clone(),
        scenes: scenes.clone(),
    };
    // Never inside the radiance folder; one writer per output. A new test set is built in a
    // hidden staging sibling that a rerun resumes, and appears at `out` only when complete,
    // so a failure on the second radiance file leaves no 1-set test set for readers to accept.
    // An existing `out` (complete, or from before staging) is continued in place.
    crate::io::guard::refuse_output_inside(input, out)?;
    // A test set (or another dataset, refused below) already there is handled in place.
    let existed = out.join(RECIPE).is_file() || out.join(own::MANIFEST).is_file();
    let lock = crate::io::guard::OutputLock::acquire(out, "testset")?;
    let staged = if existed {
        None
    } else {
        Some(lock.stage(true)?)
    };
    let out = staged.as_ref().map_or(out, |s| s.path());
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    crate::io::atomic::remove_stale_temps(out)?;
    let recipe_path = out.join(RECIPE);
    if recipe_path.is_file() {
        let old: Recipe = crate::config::load_toml(&recipe_path)?;
        if old != recipe {
            return Err(Error::layout(
                &recipe_path,
                "this folder holds a test set made with a different recipe (radiance, profile \
                 or options); choose another output folder or delete it",
            ));
        }
    } else if out.join(own::MANIFEST).is_file() {
        return Err(Error::layout(
            out,
            "holds an hdrsynth dataset that is not a test set; choose another output folder",
        ));
    }
    let text = toml::to_string(&recipe).map_err(|e| Error::encode(&recipe_path, e))?;
    write_atomic(&recipe_path, text.as_bytes())?;

    let mut sets = Vec::new();
    let mut notes = vec![format!("exposure rule: {metering}")];
    let mut manifest_written = false;
    for (si, scene) in scenes.iter().enumerate() {
        let radiance = if dynamic {
            let (r, n) = dynamic::load(&scene.file, &opts.evs, opts.resize)?;
            notes.extend(n);
            r
        } else {
            let (r, n) = load_radiance(&scene.file, opts.resize)?;
            notes.extend(n);
            SceneRadiance::still(r)
        };
        let key =
            exposure_key(&radiance.reference, &opts).map_err(|m| Error::layout(&scene.file, m))?;
        if !manifest_written {
            // Sets may differ in size; each set's meta.toml has its own. The manifest carries
            // the first one for tools that want a nominal size.
            let r = &radiance.reference;
            write_manifest(out, &device, &opts, r.width, r.height)?;
            manifest_written = true;
        }
        for (ii, &iso) in opts.isos.iter().enumerate() {
            let index = (si * opts.isos.len() + ii) as u64;
            sets.push(write_set(
                out, scene, index, iso, &radiance, key, &device, &opts,
            )?);
        }
    }
    if let Some(s) = staged {
        s.commit()?;
    }
    Ok(TestsetSummary {
        sets,
        dynamic,
        notes,
    })
}

/// The scenes of `input`: a generated dataset's sets (`dynamic`) or its radiance files; two
/// scenes of one name are refused.
fn scene_entries(input: &Path, dynamic: bool) -> Result<Vec<SceneEntry>> {
    let files = if dynamic {
        dynamic::scene_dirs(input)?
    } else {
        radiance_files(input)?
    };
    let scenes: Vec<SceneEntry> = files
        .iter()
        .map(|f| SceneEntry {
            name: scene_name(f),
            file: f.clone(),
        })
        .collect();
    for (i, a) in scenes.iter().enumerate() {
        if let Some(b) = scenes[i + 1..].iter().find(|b| b.name == a.name) {
            return Err(Error::layout(
                &b.file,
                format!(
                    "scene name '{}' is also that of {}; rename one",
                    a.name,
                    a.file.display()
                ),
            ));
        }
    }
    Ok(scenes)
}

fn write_manifest(
    out: &Path,
    device: &SensorProfile,
    opts: &TestsetOptions,
    width: usize,
    height: usize,
) -> Result<()> {
    // The manifest's curve vocabulary is the engine's; a gamma or sampled device response is
    // recorded exactly in testset.toml.
    let tone_curve = match device.response {
        Response::Linear => ToneCurve::Linear,
        Response::Filmic => ToneCurve::Filmic,
        _ => ToneCurve::Srgb,
    };
    own::write_manifest(
        out,
        &Manifest {
            format: own::FORMAT.into(),
            width,
            height,
            evs: opts.evs.clone(),
            tone_curve,
            bit_depth: opts.output_bits,
            generator: None,
        },
    )
}

/// FNV-1a of the scene name: a seed part that does not depend on which other scenes exist.
fn name_hash(name: &str) -> u64 {
    name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Noise seed of one frame.
pub fn frame_seed(seed: u64, scene: &str, iso: f64, ev: f32) -> u64 {
    hash(
        seed,
        &[name_hash(scene), iso.to_bits(), ev.to_bits() as u64],
    )
}

#[allow(clippy::too_many_arguments)]
fn write_set(
    out: &Path,
    scene: &SceneEntry,
    index: u64,
    iso: f64,
    scene_radiance: &SceneRadiance,
    key: f32,
    device: &SensorProfile,
    opts: &TestsetOptions,
) -> Result<BuiltSet> {
    let name = set_name(&scene.name, iso);
    let dir = out.join(&name);
    let radiance = &scene_radiance.reference;
    let (w, h) = (radiance.width, radiance.height);
    if dir.join(SET_META).is_file() {
        let meta = own::read_set_meta(&dir)?;
        return Ok(BuiltSet {
            name,
            iso,
            width: w,
            height: h,
            key,
            over_fraction: meta.stats.over_fraction,
            under_fraction: meta.stats.under_fraction,
            written: false,
        });
    }
    let depth = BitDepth::from_bits(opts.output_bits)
        .ok_or_else(|| Error::flag("--bits", format!("{} must be 8 or 16", opts.output_bits)))?;
    // The device at `ev` stops from the metered key, with the configured noise or none.
    let realism = |ev: f32, noise: NoiseModel| {
        Realism::new(
            device,
            &RealismOptions {
                iso,
                exposure: key as f64 * (ev as f64).exp2(),
                noise,
                colour: opts.colour,
                output_bits: opts.output_bits,
            },
        )
    };
    let (mut over, mut under) = (0.0, 0.0);
    for (i, &ev) in opts.evs.iter().enumerate() {
        let seed = frame_seed(opts.seed, &scene.name, iso, ev);
        let frame = realism(ev, opts.noise)?.apply(radiance, seed);
        if ev == 0.0 {
            (over, under) = clip_fractions(&frame);
        }
        match &scene_radiance.moving {
            // The same noise seed as the static frame: outside the mask the two agree.
            Some(m) if ev != 0.0 => {
                let moving = realism(ev, opts.noise)?.apply(&m.radiance[i], seed);
                write_moving_frame(&dir, ev, frame, moving, &m.masks[i], depth)?
            }
            _ => write_frame(&dir, ev, frame, depth)?,
        }
        // The same frame without noise (same exposure, colour, levels, response and
        // quantisation): Network-1's reference takes its blend weights from these, so it does
        // not reward imitating noise-driven weights (docs/evaluation.md).
        let clean = realism(ev, NoiseModel::None)?
            .apply(radiance, frame_seed(opts.seed, &scene.name, iso, ev));
        write_ldr(
            &dir.join("static").join(own::clean_frame_name(ev)),
            &clean,
            depth,
        )?;
    }
    let mut gt = realism(0.0, opts.noise)?.target_linear(radiance, opts.ground_truth);
    let white = ground_truth_white(&opts.evs);
    gt.data.iter_mut().for_each(|v| *v = v.min(white));
    write_exr(&dir.join("hdr_gt.exr"), &gt, ExrPrecision::Float)?;
    drop(gt);
    let mut meta = set_meta(&name, index, scene, radiance, key, (over, under), opts);
    if let Some(m) = &scene_radiance.moving {
        meta.times = m.times.clone();
        meta.stats.subjects = m.subjects;
        meta.stats.articulated = m.articulated;
    }
    let path = dir.join(SET_META);
    let text = toml::to_string(&meta).map_err(|e| Error::encode(&path, e))?;
    write_atomic(&path, text.as_bytes())?;
    Ok(BuiltSet {
        name,
        iso,
        width: w,
        height: h,
        key,
        over_fraction: over,
        under_fraction: under,
        written: true,
    })
}

/// One frame of a set at `ev`: static/<tag>.png and, as the scene is static, the same file as
/// the dynamic capture with an all-zero motion mask.
fn write_frame(dir: &Path, ev: f32, frame: Image, depth: BitDepth) -> Result<()> {
    let (w, h) = (frame.width, frame.height);
    let tag = ev_tag(ev);
    let path = dir.join("static").join(format!("{tag}.png"));
    write_ldr(&path, &frame, depth)?;
    drop(frame);
    // A static scene: the "dynamic" capture is the same frame (same noise, byte-identical
    // file) and no pixel moves, so every mask is 0.
    let bytes = crate::io::guard::read_file(&path)?;
    write_atomic(&dir.join("dynamic").join(format!("{tag}.png")), &bytes)?;
    write_ldr(
        &dir.join("dynamic").join(format!("mask_{tag}.png")),
        &Image::new(w, h),
        BitDepth::Eight,
    )
}

/// One frame of a dynamic scene at `ev`: the static rendering, the moving one and its mask.
fn write_moving_frame(
    dir: &Path,
    ev: f32,
    still: Image,
    moving: Image,
    mask: &[u8],
    depth: BitDepth,
) -> Result<()> {
    let (w, h) = (still.width, still.height);
    let tag = ev_tag(ev);
    write_ldr(
        &dir.join("static").join(format!("{tag}.png")),
        &still,
        depth,
    )?;
    write_ldr(
        &dir.join("dynamic").join(format!("{tag}.png")),
        &moving,
        depth,
    )?;
    let m = Image::from_vec(w, h, mask.iter().flat_map(|&v| [v as f32; 3]).collect());
    write_ldr(
        &dir.join("dynamic").join(format!("mask_{tag}.png")),
        &m,
        BitDepth::Eight,
    )
}

/// set.toml's description of a set made from one radiance map: exposure key and clipping
/// (`clip`: the EV0 frame's over- and under-exposed fractions), no camera motion, no subjects.
fn set_meta(
    name: &str,
    index: u64,
    scene: &SceneEntry,
    radiance: &Image,
    key: f32,
    clip: (f32, f32),
    opts: &TestsetOptions,
) -> SetMeta {
    let (w, h) = (radiance.width, radiance.height);
    let (over, under) = clip;
    let reference = opts.evs.iter().position(|&e| e == 0.0).unwrap_or(0);
    SetMeta {
        name: name.to_string(),
        index,
        width: w,
        height: h,
        evs: opts.evs.clone(),
        reference,
        times: vec![0.0; opts.evs.len()],
        stats: SampleStats {
            exposure_key: key,
            over_fraction: over,
            under_fraction: under,
            dynamic_range_stops: crate::io::dynamic_range_stops(radiance, 0.1, 99.9).unwrap_or(0.0)
                as f32,
            camera: Camera {
                cx: 0.0,
                cy: 0.0,
                view_w: w as f32,
                width: w,
                height: h,
            },
            background: scene
                .file
                .file_name()
                .map(|n| n.to_string_lossy().into_owned()),
            subjects: 0,
            articulated: 0,
        },
    }
}

/// The ground truth's clipping point in EV0 units: the shortest frame's white, 2^−EV_min (1 when
/// no frame is shorter than the reference).
pub fn ground_truth_white(evs: &[f32]) -> f32 {
    let shortest = evs.iter().copied().fold(0.0f32, f32::min);
    (-shortest).exp2()
}

/// Fractions of pixels over- and under-exposed as the scene engine counts them: largest
/// channel ≥ 0.98 (over), largest channel ≤ 0.02 (under).
fn clip_fractions(frame: &Image) -> (f32, f32) {
    let n = frame.pixel_count().max(1) as f32;
    let (o, u) = frame
        .data
        .par_chunks_exact(3)
        .map(|p| {
            let m = p[0].max(p[1]).max(p[2]);
            ((m >= 0.98) as u32, (m <= 0.02) as u32)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    (o as f32 / n, u as f32 / n)
}

/// k (radiance → EV0 linear signal, 1 = sensor white): the metering rule's key
/// (src/sensor/metering.rs) times the user's `exposure` factor. The rule is `opts.metering` as
/// [`build`] resolved it against the profile; absent, the default.
pub fn exposure_key(radiance: &Image, opts: &TestsetOptions) -> std::result::Result<f32, String> {
    let rule = Metering::resolve(opts.metering, None).rule;
    Ok(rule.key(radiance)?.key * opts.exposure as f32)
}
