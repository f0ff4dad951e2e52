//! Bracket folders as they come off a phone or camera (docs/your_device.md): find the frames,
//! their exposures and which frames form one bracketed set.
//!
//! Frames: JPEG, PNG, 8/16-bit TIFF (code values, linearised later with a response) and
//! uncompressed Bayer DNG (linear after black/white levels, src/sensor/dng.rs).
//!
//! Exposure of each frame, first source that applies:
//! 1. `--declared-evs` given by the user: EV steps in capture order, the same for every set;
//! 2. a sidecar in the frame's folder: OpenCV's `list.txt` ("name value" lines, value = 1 / the
//!    exposure time in seconds, as OpenCV's `loadExposureSeq` reads it) or `exposure.txt` (log2
//!    stops, one per image file in file-name order, Kalantari's convention);
//! 3. EXIF (kamadak-exif): ExposureTime × ISO / FNumber² — ISO and FNumber only where every
//!    frame of the folder has them, so one missing tag never mixes units — else
//!    ExposureBiasValue where every frame has it. DNG BaselineExposure is reported, not applied:
//!    it is a rendering hint and does not change the raw values.
//!
//! Grouping: each folder (the root and each direct sub-folder) is split into sets in capture
//! order (EXIF DateTimeOriginal + SubSecTimeOriginal when every frame has it, else file-name
//! order); a new set starts where an exposure repeats within the current set or where the
//! capture times are more than `max_gap_s` apart. With `repeats`, frames of one exposure and
//! ISO stay in their set as repeated captures (a burst, for temporal noise); only time gaps,
//! sub-folders and declared EVs split. How each set was grouped, and anything ambiguous (sets
//! of differing sizes, times missing on some frames), is reported.
//! Frames whose exposure cannot be determined are refused, named.
//!
//! Orientation: the EXIF/TIFF Orientation tag (1–8) is read with the exposure tags and applied
//! when a frame is read ([`read_frame_image`], [`orient`]), so portrait brackets come out
//! upright; a set whose frames differ in orientation is refused, every file named.

use crate::error::{Error, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod folder;
mod frame;
mod grouping;
pub use folder::FolderScan;
use folder::select;
use frame::days_from_civil;
pub use frame::{
    MIN_FRAME_SIDE, Region, frame_source, orient, read_frame_image, scorable_size, set_sources,
    size_mismatch,
};

/// OpenCV's sidecar (`samples/cpp/tutorial_code/photo/hdr_imaging`): "name 1/t" per line.
pub const LIST_TXT: &str = "list.txt";
/// Kalantari's sidecar: log2 stops, one per frame in file-name order.
pub const EXPOSURE_TXT: &str = "exposure.txt";
/// Two exposures closer than this (in stops) are the same exposure.
const SAME_STOP: f64 = 0.05;
/// Exposure times a camera can give, in seconds (1 µs to about 2.8 hours): a time outside is
/// a damaged tag or sidecar, refused rather than merged into a constant ground truth.
pub const EXPOSURE_TIME_RANGE_S: (f64, f64) = (1e-6, 1e4);
/// The most a set's declared exposures may span, in stops (the range above).
const MAX_SPAN_STOPS: f64 = 33.3;

/// `t` (seconds) inside [`EXPOSURE_TIME_RANGE_S`], else the error `at` makes of why not (the
/// file and the place in it that gave `t`).
fn physical_time(t: f64, at: impl FnOnce(String) -> Error) -> Result<f64> {
    let (lo, hi) = EXPOSURE_TIME_RANGE_S;
    if t.is_finite() && (lo..=hi).contains(&t) {
        Ok(t)
    } else {
        Err(at(format!(
            "{t:e} s is not an exposure time a camera gives ({lo:e} … {hi:e} s)"
        )))
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct ScanOptions {
    /// Declared EV steps in capture order (each set has exactly these many frames).
    pub evs: Option<Vec<f64>>,
    /// Largest gap between capture times within one set, seconds.
    pub max_gap_s: f64,
    /// Read only this part of every frame (after its EXIF orientation).
    pub region: Option<Region>,
    /// Keep only the sets of these names (empty: every set); a name not found is an error.
    pub sets: Vec<String>,
    /// Frames of one exposure within a set are repeated captures ([`BracketSet::repeats`]),
    /// not the start of a new set.
    pub repeats: bool,
}

impl Default for ScanOptions {
    fn default() -> Self {
        ScanOptions {
            evs: None,
            max_gap_s: 5.0,
            region: None,
            sets: Vec::new(),
            repeats: false,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameKind {
    /// Code values through a camera response (JPEG, PNG, TIFF).
    Ldr,
    /// Linear raw (DNG).
    Dng,
}

/// What EXIF says about a frame (every field where present).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExifExposure {
    pub exposure_time: Option<f64>,
    /// ShutterSpeedValue, APEX Tv (time = 2^−Tv s).
    pub shutter_speed_apex: Option<f64>,
    pub iso: Option<f64>,
    pub f_number: Option<f64>,
    pub bias_ev: Option<f64>,
    pub baseline_exposure: Option<f64>,
    /// Seconds since 0000-01-01 (only differences are used), with sub-seconds.
    pub captured_s: Option<f64>,
    /// EXIF/TIFF Orientation (1–8) where present; frames are read upright through it.
    pub orientation: Option<u16>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct BracketFrame {
    pub path: PathBuf,
    pub kind: FrameKind,
    pub exif: ExifExposure,
    /// log2 of the exposure (time · gain) in the set's own unit; only differences matter.
    pub stop: f64,
    /// The part of the upright frame that is read; `None`: all of it.
    pub region: Option<Region>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct BracketSet {
    pub name: String,
    /// Ascending exposure.
    pub frames: Vec<BracketFrame>,
    /// Where the exposures came from ("EXIF ExposureTime × ISO", "list.txt", ...).
    pub exposure_source: String,
    /// How the set was grouped.
    pub grouping: String,
    /// Repeated captures (only with [`ScanOptions::repeats`]): each has the exposure and ISO
    /// of one of `frames`; in capture order.
    pub repeats: Vec<BracketFrame>,
}

impl BracketSet {
    /// The folder the set's frames lie in, for errors about the set.
    pub fn folder(&self) -> &Path {
        self.frames[0].path.parent().unwrap_or(&self.frames[0].path)
    }

    /// Every frame of the set: its exposures, then its repeated captures.
    pub fn all_frames(&self) -> impl Iterator<Item = &BracketFrame> {
        self.frames.iter().chain(&self.repeats)
    }

    /// The repeated captures of `frame`'s exposure, in capture order.
    pub fn repeats_of<'a>(
        &'a self,
        frame: &'a BracketFrame,
    ) -> impl Iterator<Item = &'a BracketFrame> + 'a {
        self.repeats
            .iter()
            .filter(move |r| (r.stop - frame.stop).abs() < SAME_STOP)
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct BracketScan {
    pub sets: Vec<BracketSet>,
    /// Ambiguities and things the user should know (printed by the CLI).
    pub notes: Vec<String>,
}

fn is_frame(path: &Path) -> Option<FrameKind> {
    let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
    match ext.as_str() {
        "jpg" | "jpeg" | "png" | "tif" | "tiff" => Some(FrameKind::Ldr),
        "dng" => Some(FrameKind::Dng),
        _ => None,
    }
}

fn list_dir(dir: &Path) -> Result<(Vec<PathBuf>, Vec<PathBuf>)> {
    let rd = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let (mut files, mut dirs) = (Vec::new(), Vec::new());
    for e in rd {
        let p = e.map_err(|e| Error::io(dir, e))?.path();
        if p.is_dir() {
            dirs.push(p);
        } else if is_frame(&p).is_some() {
            files.push(p);
        }
    }
    files.sort();
    dirs.sort();
    Ok((files, dirs))
}

/// Whether `path` begins with a JPEG, PNG or TIFF (DNG) signature.
fn looks_like_an_image(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    let n = crate::io::guard::open_input(path)
        .and_then(|mut f| f.read(&mut head))
        .unwrap_or(0);
    let head = &head[..n];
    head.starts_with(&[0xFF, 0xD8, 0xFF])
        || head.starts_with(b"\x89PNG\r\n\x1a\n")
        || head.starts_with(b"II*\0")
        || head.starts_with(b"MM\0*")
}

/// Read the exposure tags of one file; a file without EXIF gives all `None`.
pub fn read_exif(path: &Path) -> Result<ExifExposure> {
    use exif::{In, Tag, Value};
    let file = crate::io::guard::open_input(path).map_err(|e| Error::io(path, e))?;
    let exif = match exif::Reader::new().read_from_container(&mut std::io::BufReader::new(file)) {
        Ok(x) => x,
        Err(exif::Error::NotFound(_)) | Err(exif::Error::BlankValue(_)) => {
            return Ok(ExifExposure::default());
        }
        Err(exif::Error::Io(e)) => return Err(Error::io(path, e)),
        // The EXIF reader meets a file that is not an image first: say that, not its words.
        Err(exif::Error::InvalidFormat(_)) if !looks_like_an_image(path) => {
            let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
            return Err(Error::decode(
                path,
                if size == 0 {
                    "an empty file (0 bytes), not an image".to_string()
                } else {
                    format!(
                        "not an image: its {size} bytes do not begin as a JPEG, PNG, TIFF or \
                         DNG does"
                    )
                },
            ));
        }
        Err(e) => return Err(Error::decode(path, format!("EXIF: {e}"))),
    };
    let field = |tag: Tag| exif.get_field(tag, In::PRIMARY).map(|f| &f.value);
    let real = |tag: Tag| -> Option<f64> {
        let v = match field(tag)? {
            Value::Rational(v) => v.first().map(|r| r.to_f64()),
            Value::SRational(v) => v.first().map(|r| r.to_f64()),
            Value::Short(v) => v.first().map(|&x| f64::from(x)),
            Value::Long(v) => v.first().map(|&x| f64::from(x)),
            // Some software writes RATIONAL tags as DOUBLE or FLOAT: the same number.
            Value::Double(v) => v.first().copied(),
            Value::Float(v) => v.first().map(|&x| f64::from(x)),
            _ => None,
        }?;
        v.is_finite().then_some(v)
    };
    let ascii = |tag: Tag| -> Option<Vec<u8>> {
        match field(tag)? {
            Value::Ascii(v) => v.first().cloned(),
            _ => None,
        }
    };
    let captured_s = ascii(Tag::DateTimeOriginal)
        .or_else(|| ascii(Tag::DateTime))
        .and_then(|a| exif::DateTime::from_ascii(&a).ok())
        .map(|d| {
            // Days from a proleptic calendar: only differences within a shoot matter, but they
            // must be right across midnight and month ends.
            let days = days_from_civil(i64::from(d.year), u32::from(d.month), u32::from(d.day));
            let sub = ascii(Tag::SubSecTimeOriginal)
                .and_then(|s| {
                    let s = String::from_utf8_lossy(&s).trim().to_string();
                    (!s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
                        .then(|| format!("0.{s}").parse::<f64>().ok())
                        .flatten()
                })
                .unwrap_or(0.0);
            days as f64 * 86400.0
                + f64::from(d.hour) * 3600.0
                + f64::from(d.minute) * 60.0
                + f64::from(d.second)
                + sub
        });
    let orientation = match field(Tag::Orientation) {
        None => None,
        Some(v) if v.get_uint(0).is_some_and(|o| (1..=8).contains(&o)) => {
            v.get_uint(0).map(|o| o as u16)
        }
        Some(v) => {
            return Err(Error::decode(
                path,
                format!("EXIF Orientation {v:?} is not one of the values 1–8"),
            ));
        }
    };
    Ok(ExifExposure {
        orientation,
        exposure_time: real(Tag::ExposureTime)
            .map(|t| {
                physical_time(t, |why| {
                    Error::decode(path, format!("EXIF ExposureTime: {why}"))
                })
            })
            .transpose()?,
        shutter_speed_apex: real(Tag::ShutterSpeedValue),
        iso: real(Tag::PhotographicSensitivity).filter(|&s| s > 0.0),
        f_number: real(Tag::FNumber).filter(|&n| n > 0.0),
        bias_ev: real(Tag::ExposureBiasValue),
        // DNG BaselineExposure (tag 50730, SRATIONAL, in IFD 0).
        baseline_exposure: real(Tag(exif::Context::Tiff, 50730)),
        captured_s,
    })
}

/// Stops of the files of one folder from a sidecar, if the folder has one.
fn sidecar_stops(dir: &Path, files: &[PathBuf]) -> Result<Option<(Vec<f64>, String)>> {
    let list = dir.join(LIST_TXT);
    if list.is_file() {
        let text = crate::io::guard::read_text(&list)?;
        let mut by_name = BTreeMap::new();
        for (n, line) in text.lines().enumerate() {
            let mut tok = line.split_whitespace();
            let (Some(name), Some(val)) = (tok.next(), tok.next()) else {
                if line.trim().is_empty() {
                    continue;
                }
                return Err(Error::layout(
                    &list,
                    format!(
                        "line {}: expected \"name value\" (value = 1 / exposure time)",
                        n + 1
                    ),
                ));
            };
            let v: f64 = val
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite() && *v > 0.0)
                .ok_or_else(|| {
                    Error::layout(
                        &list,
                        format!(
                            "line {}: '{val}' is not a positive number (1 / exposure time)",
                            n + 1
                        ),
                    )
                })?;
            let t = physical_time(1.0 / v, |why| {
                Error::layout(&list, format!("line {}: 1/{val}: {why}", n + 1))
            })?;
            if let Some((first, _)) = by_name.insert(name.to_string(), (n + 1, t.log2())) {
                return Err(Error::layout(
                    &list,
                    format!(
                        "'{name}' is listed twice (lines {first} and {}); give one exposure per \
                         image",
                        n + 1
                    ),
                ));
            }
        }
        let mut stops = Vec::new();
        let mut missing = Vec::new();
        for f in files {
            let name = file_name(f);
            match by_name.get(&name) {
                Some(&(_, s)) => stops.push(s),
                None => missing.push(name),
            }
        }
        if !missing.is_empty() {
            return Err(Error::layout(
                &list,
                format!(
                    "has no exposure for {}; OpenCV's list.txt needs one \"name 1/t\" line per image",
                    missing.join(", ")
                ),
            ));
        }
        return Ok(Some((
            stops,
            format!("{LIST_TXT} (OpenCV: value = 1 / exposure time)"),
        )));
    }
    let expo = dir.join(EXPOSURE_TXT);
    if expo.is_file() {
        let stops = crate::data::layout::read_stops(
            &expo,
            files.len(),
            "log2 exposure stops, one per image in file-name order",
        )?;
        let (lo, hi) = stops
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &v| {
                (l.min(v), h.max(v))
            });
        if f64::from(hi - lo) > MAX_SPAN_STOPS {
            return Err(Error::layout(
                &expo,
                format!(
                    "the stops span {} stops; the exposure times a camera gives ({:e} … {:e} s) \
                     span at most {MAX_SPAN_STOPS}",
                    hi - lo,
                    EXPOSURE_TIME_RANGE_S.0,
                    EXPOSURE_TIME_RANGE_S.1
                ),
            ));
        }
        return Ok(Some((
            stops.into_iter().map(f64::from).collect(),
            format!("{EXPOSURE_TXT} (log2 stops in file-name order)"),
        )));
    }
    Ok(None)
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Marked shutter speeds of the cameras' third- and half-stop scales, seconds: labels that stand
/// for powers of two and their thirds or halves (1/125 for 2^−7).
const MARKED_TIMES: [f64; 67] = [
    30.0,
    25.0,
    20.0,
    15.0,
    13.0,
    10.0,
    8.0,
    6.0,
    5.0,
    4.0,
    3.2,
    3.0,
    2.5,
    2.0,
    1.6,
    1.5,
    1.3,
    1.0,
    0.8,
    0.7,
    0.6,
    0.5,
    0.4,
    0.35,
    0.3,
    1.0 / 4.0,
    1.0 / 5.0,
    1.0 / 6.0,
    1.0 / 8.0,
    1.0 / 10.0,
    1.0 / 13.0,
    1.0 / 15.0,
    1.0 / 20.0,
    1.0 / 25.0,
    1.0 / 30.0,
    1.0 / 40.0,
    1.0 / 45.0,
    1.0 / 50.0,
    1.0 / 60.0,
    1.0 / 80.0,
    1.0 / 90.0,
    1.0 / 100.0,
    1.0 / 125.0,
    1.0 / 160.0,
    1.0 / 180.0,
    1.0 / 200.0,
    1.0 / 250.0,
    1.0 / 320.0,
    1.0 / 350.0,
    1.0 / 400.0,
    1.0 / 500.0,
    1.0 / 640.0,
    1.0 / 750.0,
    1.0 / 800.0,
    1.0 / 1000.0,
    1.0 / 1250.0,
    1.0 / 1500.0,
    1.0 / 1600.0,
    1.0 / 2000.0,
    1.0 / 2500.0,
    1.0 / 3000.0,
    1.0 / 3200.0,
    1.0 / 4000.0,
    1.0 / 5000.0,
    1.0 / 6000.0,
    1.0 / 6400.0,
    1.0 / 8000.0,
];

/// The exact time behind a frame's EXIF ExposureTime: 2^−Tv where the ExposureTime is a marked
/// shutter speed (a label, within 0.5 % of [`MARKED_TIMES`]) and ShutterSpeedValue Tv lies within
/// 1/6 stop of it (the largest label rounding, 1/30 for 1/32, is 0.09 stops); else None.
/// A device that writes a measured time (a phone's 1/121 s) keeps it: it is not a label.
pub fn exact_time(e: &ExifExposure) -> Option<f64> {
    let t = e.exposure_time?;
    let tv = e.shutter_speed_apex?;
    let apex = (-tv).exp2();
    let marked = MARKED_TIMES.iter().any(|&m| (t / m - 1.0).abs() < 0.005);
    (marked && apex.is_finite() && apex > 0.0 && (apex / t).log2().abs() <= 1.0 / 6.0)
        .then_some(apex)
}

/// Stops of a folder's frames from EXIF (see the module doc), or the files that lack them.
fn exif_stops(
    frames: &[(PathBuf, ExifExposure)],
) -> std::result::Result<(Vec<f64>, String), Vec<String>> {
    let all = |f: fn(&ExifExposure) -> bool| frames.iter().all(|(_, e)| f(e));
    if all(|e| e.exposure_time.is_some()) {
        let iso = all(|e| e.iso.is_some());
        let fnum = all(|e| e.f_number.is_some());
        // All frames or none: one folder's stops never mix labels with exact times.
        let apex = all(|e| exact_time(e).is_some());
        let stops = frames
            .iter()
            .map(|(_, e)| {
                let mut h = if apex {
                    exact_time(e).unwrap_or(1.0)
                } else {
                    e.exposure_time.unwrap_or(1.0)
                };
                if iso {
                    h *= e.iso.unwrap_or(100.0) / 100.0;
                }
                if fnum {
                    h /= e.f_number.unwrap_or(1.0).powi(2);
                }
                h.log2()
            })
            .collect();
        let mut what = if apex {
            "EXIF ShutterSpeedValue (APEX 2^−Tv behind the marked ExposureTime)".to_string()
        } else {
            "EXIF ExposureTime".to_string()
        };
        if iso {
            what.push_str(" × ISO/100");
        }
        if fnum {
            what.push_str(" / FNumber²");
        }
        return Ok((stops, what));
    }
    if all(|e| e.bias_ev.is_some()) {
        return Ok((
            frames
                .iter()
                .map(|(_, e)| e.bias_ev.unwrap_or(0.0))
                .collect(),
            "EXIF ExposureBiasValue (no ExposureTime)".to_string(),
        ));
    }
    Err(frames
        .iter()
        .filter(|(_, e)| e.exposure_time.is_none())
        .map(|(p, _)| p.display().to_string())
        .collect())
}

/// Find the bracketed sets under `root` (the root's own frames and each direct sub-folder's).
pub fn scan(root: &Path, opts: &ScanOptions) -> Result<BracketScan> {
    if !root.is_dir() {
        return Err(Error::layout(
            root,
            if root.exists() {
                "is a file, not a bracket folder: give the folder that holds the frames (or \
                 their sets' sub-folders)"
            } else {
                "no such bracket folder"
            },
        ));
    }
    if opts.max_gap_s.is_nan() || opts.max_gap_s <= 0.0 {
        return Err(Error::flag(
            "--max-gap",
            format!("{} s must be positive", opts.max_gap_s),
        ));
    }
    if let Some(evs) = &opts.evs {
        let span = evs.iter().fold(f64::NEG_INFINITY, |m, &e| m.max(e))
            - evs.iter().fold(f64::INFINITY, |m, &e| m.min(e));
        if evs.len() < 2 || evs.iter().any(|e| !e.is_finite()) || span > MAX_SPAN_STOPS {
            return Err(Error::flag(
                "--declared-evs",
                format!(
                    "{evs:?}: need at least two finite values spanning at most \
                     {MAX_SPAN_STOPS} stops (the exposure times a camera gives, {:e} … {:e} s)",
                    EXPOSURE_TIME_RANGE_S.0, EXPOSURE_TIME_RANGE_S.1
                ),
            ));
        }
    }
    let (files, dirs) = list_dir(root)?;
    let mut folders = vec![(root.to_path_buf(), files, String::new())];
    // A link back to a folder already read (`loop -> .`) would make its frames a second scene.
    let canonical = |d: &Path| d.canonicalize().map_err(|e| Error::io(d, e));
    let mut seen = vec![canonical(root)?];
    for d in dirs {
        let real = canonical(&d)?;
        if let Some(first) = seen.iter().find(|s| **s == real) {
            return Err(Error::layout(
                &d,
                format!(
                    "is {} again (a link); its frames would be read twice, as two scenes: \
                     remove the link or give the folder it points to",
                    first.display()
                ),
            ));
        }
        seen.push(real);
        let (f, _) = list_dir(&d)?;
        folders.push((d.clone(), f, file_name(&d)));
    }
    let mut scan = BracketScan {
        sets: Vec::new(),
        notes: Vec::new(),
    };
    let mut undetermined = Vec::new();
    for (dir, files, prefix) in folders {
        if files.is_empty() {
            continue;
        }
        match scan_folder(&dir, &files, &prefix, opts, &mut scan)? {
            Ok(()) => {}
            Err(mut names) => undetermined.append(&mut names),
        }
    }
    if !undetermined.is_empty() {
        return Err(Error::layout(
            root,
            format!(
                "the exposure of {} frame(s) cannot be determined (no EXIF ExposureTime or \
                 ExposureBiasValue, no list.txt/exposure.txt sidecar; declare EV steps with \
                 --declared-evs): {}",
                undetermined.len(),
                undetermined.join(", ")
            ),
        ));
    }
    if scan.sets.is_empty() {
        return Err(Error::layout(
            root,
            "no bracket frames (.jpg, .jpeg, .png, .tif, .tiff, .dng) here or in its sub-folders",
        ));
    }
    select(root, scan, opts)
}

/// A folder's frames as read: path, EXIF exposure tags, kind.
type Frames = [(PathBuf, ExifExposure, FrameKind)];

/// One folder's frames into sets; `Err(files)` lists frames without a determinable exposure.
fn scan_folder(
    dir: &Path,
    files: &[PathBuf],
    prefix: &str,
    opts: &ScanOptions,
    out: &mut BracketScan,
) -> Result<std::result::Result<(), Vec<String>>> {
    let mut frames = Vec::with_capacity(files.len());
    for f in files {
        let kind = is_frame(f).unwrap_or(FrameKind::Ldr);
        frames.push((f.clone(), read_exif(f)?, kind));
    }
    // Capture order: EXIF time where every frame has one, else file names.
    let timed = frames.iter().all(|(_, e, _)| e.captured_s.is_some());
    let some_timed = frames.iter().any(|(_, e, _)| e.captured_s.is_some());
    let where_ = if prefix.is_empty() {
        dir.display().to_string()
    } else {
        prefix.to_string()
    };
    if some_timed && !timed {
        out.notes.push(format!(
            "ambiguous: {where_}: only some frames have an EXIF capture time; grouped in \
             file-name order"
        ));
    }
    let order = capture_order(&frames, timed);
    let (stops, source) = match folder_stops(dir, files, &frames, &order, opts)? {
        Ok(s) => s,
        Err(missing) => return Ok(Err(missing)),
    };

    let mut baselines: Vec<f64> = frames
        .iter()
        .filter_map(|(_, e, _)| e.baseline_exposure)
        .collect();
    baselines.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    if baselines.len() > 1 {
        out.notes.push(format!(
            "{where_}: DNG BaselineExposure differs between frames ({baselines:?}); it is a \
             rendering hint and is not applied to the exposures"
        ));
    }

    let (groups, gaps) = grouping::group_sets(&frames, &order, &stops, timed, opts);
    let how = grouping::grouping_text(groups.len(), prefix, timed, opts);
    if gaps > 0 {
        out.notes.push(format!(
            "{where_}: {gaps} set boundar{} from capture-time gaps alone (no repeated exposure)",
            if gaps == 1 { "y" } else { "ies" }
        ));
    }
    for (k, g) in groups.iter().enumerate() {
        let name = match (prefix.is_empty(), groups.len()) {
            (false, 1) => prefix.to_string(),
            (false, _) => format!("{prefix}_{:03}", k + 1),
            (true, _) => format!("set_{:03}", k + 1),
        };
        let (set_frames, repeats) =
            grouping::set_frames(&name, &how, g, &frames, &stops, opts.repeats)?;
        out.sets.push(BracketSet {
            name,
            frames: set_frames,
            exposure_source: source.clone(),
            grouping: how.clone(),
            repeats,
        });
    }
    Ok(Ok(()))
}

/// Frame indices in capture order: by EXIF capture time (then name) when `timed`, else as
/// given (file-name order).
fn capture_order(frames: &Frames, timed: bool) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..frames.len()).collect();
    if timed {
        idx.sort_by(|&a, &b| {
            frames[a]
                .1
                .captured_s
                .unwrap_or(0.0)
                .total_cmp(&frames[b].1.captured_s.unwrap_or(0.0))
                .then_with(|| frames[a].0.cmp(&frames[b].0))
        });
    }
    idx
}

/// Stops in file-name order (sidecars are by name), or the declared EVs by position, with
/// where they came from; `Err(files)` lists frames without a determinable exposure.
#[allow(clippy::type_complexity)]
fn folder_stops(
    dir: &Path,
    files: &[PathBuf],
    frames: &Frames,
    order: &[usize],
    opts: &ScanOptions,
) -> Result<std::result::Result<(Vec<f64>, String), Vec<String>>> {
    if let Some(evs) = &opts.evs {
        if !frames.len().is_multiple_of(evs.len()) {
            return Err(Error::layout(
                dir,
                format!(
                    "{} frame(s) do not divide into sets of the {} declared EVs {evs:?}",
                    frames.len(),
                    evs.len()
                ),
            ));
        }
        let mut s = vec![0.0; frames.len()];
        for (pos, &i) in order.iter().enumerate() {
            s[i] = evs[pos % evs.len()];
        }
        return Ok(Ok((s, format!("declared EVs {evs:?} in capture order"))));
    }
    if let Some(s) = sidecar_stops(dir, files)? {
        return Ok(Ok(s));
    }
    let exif: Vec<(PathBuf, ExifExposure)> = frames
        .iter()
        .map(|(p, e, _)| (p.clone(), e.clone()))
        .collect();
    Ok(exif_stops(&exif))
}
