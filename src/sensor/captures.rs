//! Capture sets: bursts of real frames (dark, flat, chart, scene) described by a
//! `captures.toml` manifest, the input of noise calibration and of the sim-to-real gap workflow.
//!
//! Format (`hdrsynth-captures/1`): a directory with `captures.toml` and the frames at the
//! relative paths it lists.
//!
//! ```toml
//! format = "hdrsynth-captures/1"
//!
//! [sensor]              # optional table; every key optional
//! name = "my-phone"
//! white_level = 4095    # DN at saturation
//! black_level = 64      # declared pedestal in DN (may be wrong or missing)
//!
//! [[burst]]             # one per burst, any number
//! name = "flat_iso100_0"
//! kind = "flat"         # dark | flat | chart | scene
//! iso = 100
//! exposure_s = 0.0068
//! frames = ["flat_iso100_0/000.png", "flat_iso100_0/001.png"]
//! # scene = "street"  # scene bursts only, optional: bursts with one `scene` show one scene
//! ```
//!
//! Frames are 8- or 16-bit PNG (TIFF is read too), RGB (grey is replicated), and their code
//! values are sensor DN as stored, not rescaled: a 16-bit PNG sample 1234 is 1234 DN. A `chart`
//! burst shows the ColorChecker24 filling the frame as a 6×4 grid of equal cells in reading
//! order ([`chart_patch_rects`]). Exposure and ISO are honest: the expected signal above black
//! is proportional to `exposure_s × iso` for the same target.
//!
//! Loading validates everything that can be checked without decoding pixels (keys, fields,
//! kinds, names, that every frame file exists and that the frames of a burst have one size);
//! every error names the manifest, the burst and, where one is involved, the frame file.

use crate::config::{KeyError, Range, in_range, in_range_because, parse_checked, parse_toml};
use crate::error::{Error, Result};
use crate::io::{BitDepth, Format, Image};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const CAPTURES_FORMAT: &str = "hdrsynth-captures/1";
/// File name of the manifest inside a capture-set directory.
pub const MANIFEST_NAME: &str = "captures.toml";

/// What a burst shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BurstKind {
    /// No light reaches the sensor (lens cap on): black level, read noise, hot pixels.
    Dark,
    /// A uniform neutral target (may be vignetted).
    Flat,
    /// The ColorChecker24 filling the frame as a 6×4 grid of equal cells in reading order.
    Chart,
    /// Any static scene.
    Scene,
}

impl BurstKind {
    pub const ALL: [&str; 4] = ["dark", "flat", "chart", "scene"];

    pub fn as_str(self) -> &'static str {
        match self {
            BurstKind::Dark => "dark",
            BurstKind::Flat => "flat",
            BurstKind::Chart => "chart",
            BurstKind::Scene => "scene",
        }
    }
}

/// The optional `[sensor]` table.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorInfo {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// DN at saturation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub white_level: Option<f64>,
    /// Declared pedestal in DN (may be wrong; noise calibration reports a disagreement with
    /// the dark frames).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub black_level: Option<f64>,
}

impl SensorInfo {
    fn is_empty(&self) -> bool {
        self.name.is_none() && self.white_level.is_none() && self.black_level.is_none()
    }
}

/// One `[[burst]]`: frames of one static target under one setting.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Burst {
    pub name: String,
    pub kind: BurstKind,
    pub iso: f64,
    pub exposure_s: f64,
    /// Frame paths relative to the capture-set directory ('/' separated).
    pub frames: Vec<String>,
    /// Scene bursts only, optional: the scene shown. Scene bursts with the same `scene` are one
    /// static scene at different exposures (the gap workflow compares their responses);
    /// without the key, scene bursts of one frame size are taken as one scene (a fallback the
    /// diagnosis report names).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<String>,
}

/// The whole `captures.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaptureManifest {
    pub format: String,
    #[serde(default, skip_serializing_if = "SensorInfo::is_empty")]
    pub sensor: SensorInfo,
    #[serde(default, rename = "burst")]
    pub bursts: Vec<Burst>,
}

const TOP_KEYS: [&str; 3] = ["format", "sensor", "burst"];
const SENSOR_KEYS: [&str; 3] = ["name", "white_level", "black_level"];
const BURST_KEYS: [&str; 5] = ["name", "kind", "iso", "exposure_s", "frames"];
/// Optional `[[burst]]` keys.
const BURST_OPTIONAL: [&str; 1] = ["scene"];

impl CaptureManifest {
    pub fn new() -> CaptureManifest {
        CaptureManifest {
            format: CAPTURES_FORMAT.to_string(),
            sensor: SensorInfo::default(),
            bursts: Vec::new(),
        }
    }

    /// Parse manifest text; `path` names the file in errors. Checks keys and fields per burst
    /// (so the messages name the burst), then the values ([`CaptureManifest::validate`]).
    pub fn parse(text: &str, path: &Path) -> Result<CaptureManifest> {
        let table: toml::Table = parse_toml(text, path)?;
        check_keys(&table, path)?;
        parse_checked(text, path, CaptureManifest::validate)
    }

    /// Value checks (not touching files); keys as the file spells them (`burst[2].iso`), the
    /// message names the burst.
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        if self.format != CAPTURES_FORMAT {
            return Err(KeyError::new(
                "format",
                format!("'{}' is not '{CAPTURES_FORMAT}'", self.format),
            ));
        }
        let s = &self.sensor;
        if let Some(w) = s.white_level {
            in_range("sensor.white_level", w, Range::POSITIVE)?;
        }
        if let Some(b) = s.black_level {
            let below = s.white_level.unwrap_or(f64::INFINITY);
            in_range_because(
                "sensor.black_level",
                b,
                Range::half_open(0.0, below),
                "DN, below white_level",
            )?;
        }
        let mut names = std::collections::HashSet::new();
        for (i, b) in self.bursts.iter().enumerate() {
            let at = burst_label(i, Some(&b.name));
            let key = |k: &str| format!("burst[{i}].{k}");
            let bad = |k: &str, m: String| Err(KeyError::new(key(k), format!("{at}: {m}")));
            if b.name.trim().is_empty() {
                return bad("name", "name must not be empty".into());
            }
            if !names.insert(b.name.as_str()) {
                return bad("name", "the name is used by an earlier burst".into());
            }
            in_range(&key("iso"), b.iso, Range::POSITIVE)?;
            // 0 s is a dark burst's (no light either way); an hour is beyond any burst.
            let exposure = match b.kind {
                BurstKind::Dark => Range::closed(0.0, 3600.0),
                _ => Range::left_open(0.0, 3600.0),
            };
            in_range(&key("exposure_s"), b.exposure_s, exposure)?;
            if b.frames.is_empty() {
                return bad("frames", "frames is empty".into());
            }
            match &b.scene {
                Some(_) if b.kind != BurstKind::Scene => {
                    return bad(
                        "scene",
                        format!(
                            "'scene' names the scene of a scene burst; this burst is '{}'",
                            b.kind.as_str()
                        ),
                    );
                }
                Some(sc) if sc.trim().is_empty() => {
                    return bad("scene", "scene must not be empty".into());
                }
                _ => {}
            }
            for (j, f) in b.frames.iter().enumerate() {
                let frame = format!("frames[{j}]");
                let p = Path::new(f);
                if f.is_empty()
                    || p.is_absolute()
                    || p.components().any(|c| {
                        matches!(
                            c,
                            std::path::Component::ParentDir | std::path::Component::Prefix(_)
                        )
                    })
                {
                    return bad(
                        &frame,
                        format!(
                            "frame '{f}' must be a relative path inside the capture set (no \
                             '..', not absolute)"
                        ),
                    );
                }
                match Format::from_path(p) {
                    Ok(Format::Png | Format::Tiff) => {}
                    _ => {
                        return bad(
                            &frame,
                            format!("frame '{f}' must be a PNG (or TIFF) of sensor DN"),
                        );
                    }
                }
            }
            let mut seen = std::collections::HashSet::new();
            if let Some(j) = b.frames.iter().position(|f| !seen.insert(f.as_str())) {
                return bad(
                    &format!("frames[{j}]"),
                    format!("frame '{}' is listed twice", b.frames[j]),
                );
            }
        }
        Ok(())
    }

    /// The manifest's TOML text (an error names `path`, where it is to be written).
    pub fn to_toml(&self, path: &Path) -> Result<String> {
        toml::to_string(self).map_err(|e| Error::encode(path, e))
    }
}

impl Default for CaptureManifest {
    fn default() -> Self {
        CaptureManifest::new()
    }
}

fn burst_label(i: usize, name: Option<&str>) -> String {
    match name {
        Some(n) => format!("burst '{n}' (#{})", i + 1),
        None => format!("burst #{}", i + 1),
    }
}

/// Key-level checks on the raw table, so that unknown keys, missing fields and unknown kinds
/// are reported with the burst they belong to.
fn check_keys(table: &toml::Table, path: &Path) -> Result<()> {
    let bad = |m: String| Err(Error::config(path, m));
    for k in table.keys() {
        if !TOP_KEYS.contains(&k.as_str()) {
            return bad(format!(
                "unknown key '{k}' at top level (expected {})",
                TOP_KEYS.join(", ")
            ));
        }
    }
    if !table.contains_key("format") {
        return bad(format!(
            "missing field 'format' (expected format = \"{CAPTURES_FORMAT}\")"
        ));
    }
    if let Some(s) = table.get("sensor") {
        let Some(s) = s.as_table() else {
            return bad("[sensor] must be a table".into());
        };
        for k in s.keys() {
            if !SENSOR_KEYS.contains(&k.as_str()) {
                return bad(format!(
                    "unknown key '{k}' in [sensor] (expected {})",
                    SENSOR_KEYS.join(", ")
                ));
            }
        }
    }
    let Some(bursts) = table.get("burst") else {
        return Ok(());
    };
    let Some(bursts) = bursts.as_array() else {
        return bad("'burst' must be an array of tables ([[burst]])".into());
    };
    for (i, b) in bursts.iter().enumerate() {
        let Some(b) = b.as_table() else {
            return bad(format!("{} is not a table", burst_label(i, None)));
        };
        let at = burst_label(i, b.get("name").and_then(|n| n.as_str()));
        for k in b.keys() {
            if !BURST_KEYS.contains(&k.as_str()) && !BURST_OPTIONAL.contains(&k.as_str()) {
                return bad(format!(
                    "{at}: unknown key '{k}' (expected {}, optionally {})",
                    BURST_KEYS.join(", "),
                    BURST_OPTIONAL.join(", ")
                ));
            }
        }
        for k in BURST_KEYS {
            if !b.contains_key(k) {
                return bad(format!("{at}: missing field '{k}'"));
            }
        }
        match b.get("kind").and_then(|k| k.as_str()) {
            Some(k) if BurstKind::ALL.contains(&k) => {}
            Some(k) => {
                return bad(format!(
                    "{at}: unknown kind '{k}' (expected {})",
                    BurstKind::ALL.join(", ")
                ));
            }
            None => return bad(format!("{at}: kind must be a string")),
        }
        let is_number = |v: Option<&toml::Value>| {
            matches!(v, Some(toml::Value::Integer(_) | toml::Value::Float(_)))
        };
        for k in ["iso", "exposure_s"] {
            if !is_number(b.get(k)) {
                return bad(format!("{at}: {k} must be a number"));
            }
        }
        let frames_ok = b
            .get("frames")
            .and_then(|f| f.as_array())
            .is_some_and(|a| a.iter().all(|v| v.is_str()));
        if !frames_ok {
            return bad(format!("{at}: frames must be an array of path strings"));
        }
    }
    Ok(())
}

/// A loaded, validated capture set.
#[derive(Clone, Debug)]
pub struct CaptureSet {
    /// The capture-set directory.
    pub dir: PathBuf,
    /// Its `captures.toml`.
    pub manifest_path: PathBuf,
    pub manifest: CaptureManifest,
    /// Frame size (width, height) of each burst, from the file headers.
    pub sizes: Vec<(usize, usize)>,
}

impl CaptureSet {
    /// Load a capture set from its directory or from its `captures.toml`. Checks the manifest,
    /// that every frame exists, and that the frames of each burst share one size (headers only;
    /// pixels are read by [`CaptureSet::read_frame`]).
    pub fn load(path: &Path) -> Result<CaptureSet> {
        let (dir, manifest_path) = if path.is_dir() {
            (path.to_path_buf(), path.join(MANIFEST_NAME))
        } else {
            let dir = path
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
                .unwrap_or(Path::new("."))
                .to_path_buf();
            (dir, path.to_path_buf())
        };
        let text = crate::io::guard::read_input_text(&manifest_path).map_err(|e| {
            let e = if e.kind() == std::io::ErrorKind::NotFound {
                std::io::Error::new(
                    e.kind(),
                    format!("no capture-set manifest here (expected {MANIFEST_NAME})"),
                )
            } else {
                e
            };
            Error::io(&manifest_path, e)
        })?;
        let manifest = CaptureManifest::parse(&text, &manifest_path)?;
        let mut set = CaptureSet {
            dir,
            manifest_path,
            manifest,
            sizes: Vec::new(),
        };
        for i in 0..set.manifest.bursts.len() {
            let size = set.check_burst_files(i)?;
            set.sizes.push(size);
        }
        Ok(set)
    }

    pub fn bursts(&self) -> &[Burst] {
        &self.manifest.bursts
    }

    pub fn burst_index(&self, name: &str) -> Option<usize> {
        self.manifest.bursts.iter().position(|b| b.name == name)
    }

    /// "burst 'name' (#i)" for messages.
    pub fn burst_label(&self, burst: usize) -> String {
        burst_label(burst, Some(&self.manifest.bursts[burst].name))
    }

    pub fn frame_path(&self, burst: usize, frame: usize) -> PathBuf {
        self.dir.join(&self.manifest.bursts[burst].frames[frame])
    }

    /// An error about one frame of one burst: names the manifest, the burst and the file.
    pub fn frame_error(&self, burst: usize, frame: usize, msg: impl std::fmt::Display) -> Error {
        Error::config(
            &self.manifest_path,
            format!(
                "{}: frame {}: {msg}",
                self.burst_label(burst),
                self.frame_path(burst, frame).display()
            ),
        )
    }

    /// An error about a burst as a whole (names the manifest, the burst and its first frame).
    pub fn burst_error(&self, burst: usize, msg: impl std::fmt::Display) -> Error {
        Error::config(
            &self.manifest_path,
            format!(
                "{} (first frame {}): {msg}",
                self.burst_label(burst),
                self.frame_path(burst, 0).display()
            ),
        )
    }

    /// Error unless the burst has at least `min` frames (temporal statistics need 2).
    pub fn require_frames(&self, burst: usize, min: usize) -> Result<()> {
        let n = self.manifest.bursts[burst].frames.len();
        if n < min {
            return Err(self.burst_error(
                burst,
                format!("has {n} frame(s); at least {min} are needed for temporal statistics"),
            ));
        }
        Ok(())
    }

    fn check_burst_files(&self, burst: usize) -> Result<(usize, usize)> {
        let mut size = None;
        for j in 0..self.manifest.bursts[burst].frames.len() {
            let p = self.frame_path(burst, j);
            if !p.is_file() {
                return Err(self.frame_error(burst, j, "file not found"));
            }
            let (w, h) = image::image_dimensions(&p)
                .map_err(|e| self.frame_error(burst, j, format!("cannot read header: {e}")))?;
            let s = (w as usize, h as usize);
            match size {
                None => size = Some(s),
                Some(first) if first != s => {
                    return Err(self.frame_error(
                        burst,
                        j,
                        format!(
                            "is {}×{} but the burst's first frame {} is {}×{}; all frames of a \
                             burst must have one size",
                            s.0,
                            s.1,
                            self.frame_path(burst, 0).display(),
                            first.0,
                            first.1
                        ),
                    ));
                }
                Some(_) => {}
            }
        }
        Ok(size.unwrap_or((0, 0)))
    }

    /// Frame `frame` of burst `burst` as DN (f32, exact integers).
    pub fn read_frame(&self, burst: usize, frame: usize) -> Result<Image> {
        let p = self.frame_path(burst, frame);
        let img = read_dn_frame(&p).map_err(|e| self.frame_error(burst, frame, e))?;
        let (w, h) = self.sizes[burst];
        if (img.width, img.height) != (w, h) {
            return Err(self.frame_error(
                burst,
                frame,
                format!(
                    "decoded as {}×{}, expected {w}×{h} like the burst's first frame",
                    img.width, img.height
                ),
            ));
        }
        Ok(img)
    }

    /// All frames of a burst as DN images.
    pub fn load_burst(&self, burst: usize) -> Result<Vec<Image>> {
        (0..self.manifest.bursts[burst].frames.len())
            .map(|j| self.read_frame(burst, j))
            .collect()
    }
}

/// Read an integer PNG/TIFF whose code values are DN: returns DN as f32 (exact integers).
pub fn read_dn_frame(path: &Path) -> Result<Image> {
    let (img, info) = crate::io::read_image_info(path)?;
    let Some(depth) = info.bit_depth else {
        return Err(Error::unsupported(
            path,
            "a capture frame must be an 8- or 16-bit integer PNG (or TIFF) of DN",
        ));
    };
    let max = depth.max_code();
    Ok(img.map(|v| (v * max).round()))
}

/// Write a capture set: each frame as a 16-bit PNG holding its DN (stored as code value
/// DN / 65535 through [`crate::io::write_ldr`], which reads back as exactly DN), then
/// `captures.toml`, each file atomically. `frames[i][j]` is frame j of burst i, in DN; every
/// value must be an integer in 0..=65535 (values are rounded to the nearest integer first).
/// Everything is checked before the first file is written.
pub fn write_capture_set(
    dir: &Path,
    manifest: &CaptureManifest,
    frames: &[Vec<Image>],
) -> Result<()> {
    let manifest_path = dir.join(MANIFEST_NAME);
    let bad = |m: String| Err(Error::config(&manifest_path, m));
    manifest
        .validate()
        .map_err(|e| e.at(&manifest_path, None))?;
    if frames.len() != manifest.bursts.len() {
        return bad(format!(
            "{} bursts in the manifest but {} frame lists given",
            manifest.bursts.len(),
            frames.len()
        ));
    }
    for (i, (b, imgs)) in manifest.bursts.iter().zip(frames).enumerate() {
        let at = burst_label(i, Some(&b.name));
        if imgs.len() != b.frames.len() {
            return bad(format!(
                "{at}: the manifest lists {} frames but {} images were given",
                b.frames.len(),
                imgs.len()
            ));
        }
        for (j, img) in imgs.iter().enumerate() {
            if (img.width, img.height) != (imgs[0].width, imgs[0].height) {
                return bad(format!(
                    "{at}: frame '{}' is {}×{} but frame '{}' is {}×{}",
                    b.frames[j], img.width, img.height, b.frames[0], imgs[0].width, imgs[0].height
                ));
            }
            if img.width == 0 || img.height == 0 {
                return bad(format!("{at}: frame '{}' is empty", b.frames[j]));
            }
            if let Some(v) = img
                .data
                .iter()
                .find(|v| !(v.is_finite() && (-0.5..65535.5).contains(*v)))
            {
                return bad(format!(
                    "{at}: frame '{}' holds {v}, not a DN in 0..=65535",
                    b.frames[j]
                ));
            }
        }
    }
    let text = manifest.to_toml(&manifest_path)?;
    for (b, imgs) in manifest.bursts.iter().zip(frames) {
        for (rel, img) in b.frames.iter().zip(imgs) {
            let code = img.map(|v| v.round() / 65535.0);
            let p = dir.join(rel);
            // write_ldr picks PNG or TIFF by extension; the manifest was checked to be one.
            crate::io::write_ldr(&p, &code, BitDepth::Sixteen)?;
        }
    }
    crate::io::atomic::write_atomic(&manifest_path, text.as_bytes())
}

/// A rectangle of pixels [x0, x1) × [y0, y1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PatchRect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

/// The sampling rectangle of each ColorChecker24 patch in a `chart` frame: the frame is a 6×4
/// grid of equal cells in reading order (patch i at column i % 6, row i / 6), and each patch is
/// sampled over the central half of its cell in each dimension (from 1/4 to 3/4 of the cell
/// width and height; a quarter of the cell's area).
pub fn chart_patch_rects(width: usize, height: usize) -> [PatchRect; 24] {
    std::array::from_fn(|i| {
        let (col, row) = (i % 6, i / 6);
        let cx0 = col as f64 * width as f64 / 6.0;
        let cy0 = row as f64 * height as f64 / 4.0;
        let (cw, ch) = (width as f64 / 6.0, height as f64 / 4.0);
        let x0 = (cx0 + cw / 4.0).round() as usize;
        let x1 = ((cx0 + 3.0 * cw / 4.0).round() as usize)
            .max(x0 + 1)
            .min(width);
        let y0 = (cy0 + ch / 4.0).round() as usize;
        let y1 = ((cy0 + 3.0 * ch / 4.0).round() as usize)
            .max(y0 + 1)
            .min(height);
        PatchRect { x0, y0, x1, y1 }
    })
}

/// Mean RGB of each ColorChecker24 patch of a `chart` frame over [`chart_patch_rects`].
pub fn chart_patch_means(img: &Image) -> [[f64; 3]; 24] {
    let rects = chart_patch_rects(img.width, img.height);
    std::array::from_fn(|i| {
        let r = rects[i];
        let mut sum = [0.0f64; 3];
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                let p = img.get(x, y);
                for c in 0..3 {
                    sum[c] += p[c] as f64;
                }
            }
        }
        let n = ((r.x1 - r.x0) * (r.y1 - r.y0)).max(1) as f64;
        sum.map(|s| s / n)
    })
}
