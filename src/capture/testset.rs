//! `hdrsynth testset --brackets DIR --out OUT`: a user's own bracket folders
//! ([`crate::capture::scan`]) as a Kalantari-layout test set whose ground truth is made the way
//! the paper made testset-2's: the linear triangular merge of the static frames
//! (docs/your_device.md).
//!
//! Per set, three frames are the network's inputs ([`InputChoice`]): by default the shortest,
//! the one nearest the middle and the longest exposure; `--inputs I,J,K` names them;
//! `--inputs auto` picks steps as near 2 stops as the bracket allows and, among those, the
//! reference (middle input) with the fewest clipped or dark pixels ([`auto_inputs`]). Each frame
//! is linearised (1 = its clipping white) with the response chosen by [`ResponseChoice`] (DNG:
//! linear after black/white levels, white balanced by AsShotNeutral), optionally aligned to the
//! reference, and written as the field expects a Kalantari frame: a 16-bit TIFF holding
//! linear^(1/γ), γ = 2.2, so that the field's own linearisation LDR^γ recovers the linear frame.
//! Then:
//! - `exposure.txt`: log2 stops s_i relative to the shortest input, as EXIF (or the sidecar)
//!   gives them ("0 2 4" for EV −2/0/+2, "0 3 5" for a 3- then a 2-stop step), the field's
//!   reading t_i = 2^s_i (HDR-Transformer's `read_expo_times`);
//! - `HDRImg.hdr` ([`GtFrames`]): from the three inputs, the triangle merge
//!   ([`ground_truth::triangle_merge`], Kalantari's weights from the reference's TIFF value);
//!   from every frame of the set (`--gt-frames all`, when the set has more than the inputs),
//!   the weighted merge [`hat_merge`] — each frame weighted by the hat of the code it is
//!   expected to record at the merged value, and by its exposure time. In
//!   the field's unit either way: a frame at stop 0 (the shortest input) has white 1;
//!   `hdrsynth eval` converts it to its own unit (1 = the reference's white);
//! - `brackets.toml`: where every frame came from, its exposure, which frames are the inputs
//!   and how they were chosen, which formed the ground truth, the response and the alignment
//!   shifts.

use crate::capture::align::{self, MtbOptions};
use crate::capture::linearise::{Linearise, ResponseChoice, code_frame, resolve_linearisation};
use crate::capture::scan::{self, BracketFrame, BracketScan, FrameKind, ScanOptions};
use crate::data::encoding::FrameEncoding;
use crate::data::ground_truth;
use crate::error::{Error, Result};
use crate::io::source::Source;
use crate::io::{BitDepth, Image, write_hdr, write_ldr};
use crate::sensor::crf::DebevecOptions;
use crate::sensor::profile::{Response, SensorProfile};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

mod build;
mod encode;
mod merge;
pub use encode::*;
pub use merge::*;

/// γ of the written frames (the field's linearisation LDR^γ, Kalantari/Wu: 2.2).
pub const FIELD_GAMMA: f32 = 2.2;
pub const FRAME_NAMES: [&str; 3] = ["frame_1.tif", "frame_2.tif", "frame_3.tif"];
pub const RECORD: &str = crate::data::layout::kalantari::STATIC_MARKER;
#[derive(Clone, Debug, PartialEq)]
pub struct BracketOptions {
    pub scan: ScanOptions,
    pub response: ResponseChoice,
    /// Hand-held sets: align every frame to the reference (the middle input) by MTB
    /// ([`crate::capture::align`]) and crop to the region all merged frames cover. None: tripod
    /// sets, used as captured.
    pub align: Option<MtbOptions>,
    /// Which three frames of each set are written as the inputs (`--inputs`).
    pub inputs: InputChoice,
    /// Which frames the ground truth is merged from (`--gt-frames`).
    pub gt_frames: GtFrames,
    /// How the written inputs encode their linear signal (`--encode`).
    pub encode: EncodeSpec,
}

impl Default for BracketOptions {
    /// The command without flags: Debevec from the brackets, no alignment, the shortest,
    /// middle and longest frame, the ground truth from those three.
    fn default() -> Self {
        BracketOptions {
            scan: ScanOptions::default(),
            response: ResponseChoice::Debevec(DebevecOptions::one_curve()),
            align: None,
            inputs: InputChoice::default(),
            gt_frames: GtFrames::default(),
            encode: EncodeSpec::default(),
        }
    }
}

/// Which three frames of a set are the network's inputs (`--inputs`). Indices count the set's
/// frames sorted by exposure, shortest first, from 0.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum InputChoice {
    /// The shortest, the middle (index n/2 of n) and the longest frame (no `--inputs`).
    #[default]
    Spread,
    /// `--inputs auto`: [`auto_inputs`].
    Auto,
    /// `--inputs I,J,K`: three distinct frames in ascending exposure.
    Indices([usize; 3]),
}

impl std::str::FromStr for InputChoice {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<InputChoice, String> {
        if s.trim() == "auto" {
            return Ok(InputChoice::Auto);
        }
        let err = || {
            format!(
                "'{s}': expected auto or three 0-based frame indices I,J,K (the set's frames \
                 sorted by exposure, shortest first), e.g. 1,2,3"
            )
        };
        let v: Vec<usize> = s
            .split(',')
            .map(|t| t.trim().parse::<usize>().map_err(|_| err()))
            .collect::<std::result::Result<_, _>>()?;
        match v[..] {
            [i, j, k] => Ok(InputChoice::Indices([i, j, k])),
            _ => Err(err()),
        }
    }
}

/// Which frames the ground truth is merged from (`--gt-frames`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GtFrames {
    /// The three inputs, Kalantari's triangle merge: it holds the inputs' own noise, so a
    /// network that denoises is scored down and one that copies is scored up.
    Inputs,
    /// Every frame of the set (no `--gt-frames`): [`hat_merge`] (the triangle merge, exactly as
    /// `Inputs`, when the set holds only the three inputs: there is nothing to add, and the
    /// build says so).
    #[default]
    All,
    /// The frames that are not inputs, where they record the pixel (some weight of
    /// [`hat_merge`] above 0); elsewhere every frame. Independent of the inputs' noise
    /// wherever the other frames reach; a set of exactly three frames has only `Inputs`.
    Others,
}

impl std::str::FromStr for GtFrames {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<GtFrames, String> {
        match s.trim() {
            "inputs" => Ok(GtFrames::Inputs),
            "all" => Ok(GtFrames::All),
            "others" => Ok(GtFrames::Others),
            _ => Err(format!(
                "'{s}': expected inputs (the three input frames), all (every frame of the set) \
                 or others (the frames that are not inputs, where they reach)"
            )),
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RecordFrame {
    pub source: PathBuf,
    pub written: String,
    /// log2 stop as written to exposure.txt (relative to the shortest input).
    pub stop: f64,
    pub exposure_time_s: Option<f64>,
    pub iso: Option<f64>,
}

/// One frame merged into the ground truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GtRecordFrame {
    pub source: PathBuf,
    /// Index among the set's frames (ascending exposure, from 0).
    pub index: usize,
    /// log2 stop relative to the shortest input (negative for a shorter frame).
    pub stop: f64,
    /// Written as one of the three inputs.
    pub input: bool,
    /// MTB shift (dx, dy) applied; absent when not aligned.
    pub shift: Option<[i32; 2]>,
}

/// One written set (also `OUT/<set>/brackets.toml`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BuiltBracketSet {
    pub name: String,
    pub width: usize,
    pub height: usize,
    pub grouping: String,
    pub exposure_source: String,
    pub response: String,
    /// How the inputs encode their linear signal (`OUT/encoding.toml` holds the curve).
    pub encoding: String,
    /// Indices of the three written frames among the set's frames (ascending exposure, from 0).
    pub inputs: Vec<usize>,
    /// How the inputs were chosen (`--inputs`).
    pub selection: String,
    /// [`clipped_or_dark`] of the reference (the middle input), in its code values.
    pub reference_clipped_or_dark: f64,
    /// The ground truth's merge and weights (`--gt-frames`).
    pub gt_merge: String,
    /// log2 of the ratio of the 99.9th and 0.1st percentiles of the ground truth's luminance.
    pub gt_dynamic_range_stops: f64,
    pub frames: Vec<RecordFrame>,
    /// The frames merged into HDRImg.hdr.
    pub ground_truth: Vec<GtRecordFrame>,
    /// Frames of the bracket used neither as inputs nor in the ground truth.
    pub dropped: Vec<PathBuf>,
    /// MTB shifts (dx, dy) applied to the three inputs (the reference's is 0); empty when not
    /// aligned.
    pub shifts: Vec<[i32; 2]>,
    /// Every frame of the bracket (the scene a network is scored on): a profile calibrated on
    /// any of them may not be scored here ([`set_sources`]).
    pub sources: Vec<Source>,
}

/// The captures set folder `set_dir` was built from (its `brackets.toml`'s `sources`); `None`
/// for a set not built from brackets or built before sources were recorded.
pub fn set_sources(set_dir: &Path) -> Result<Option<Vec<Source>>> {
    #[derive(Deserialize)]
    struct Record {
        #[serde(default)]
        sources: Option<Vec<Source>>,
    }
    let path = set_dir.join(RECORD);
    if !path.is_file() {
        return Ok(None);
    }
    let text = crate::io::guard::read_text(&path)?;
    let r: Record = toml::from_str(&text).map_err(|e| Error::decode(&path, e))?;
    Ok(r.sources)
}

#[derive(Clone, Debug, PartialEq)]
pub struct BracketSummary {
    pub sets: Vec<BuiltBracketSet>,
    pub notes: Vec<String>,
}

impl BracketSummary {
    /// The command's report: notes, one line per set, and what was written to `out`.
    pub fn report(&self, out: &Path) -> String {
        let mut text = String::new();
        for n in &self.notes {
            let _ = writeln!(text, "note: {n}");
        }
        for b in &self.sets {
            let stops: Vec<String> = b.frames.iter().map(|f| format!("{:.2}", f.stop)).collect();
            let _ = writeln!(
                text,
                "{:<24} {}×{}  stops [{}]  exposure: {}  grouped: {}{}",
                b.name,
                b.width,
                b.height,
                stops.join(", "),
                b.exposure_source,
                b.grouping,
                if b.shifts.is_empty() {
                    String::new()
                } else {
                    format!("  MTB shifts {:?}", b.shifts)
                }
            );
            let names: Vec<String> = b
                .frames
                .iter()
                .zip(&b.inputs)
                .map(|(f, i)| {
                    let name = f.source.file_name().map_or_else(
                        || f.source.display().to_string(),
                        |n| n.to_string_lossy().into_owned(),
                    );
                    format!("{i}:{name}")
                })
                .collect();
            let _ = writeln!(
                text,
                "{:<24} inputs {}; reference clipped or dark {:.2} %; ground truth from {} \
                 frame(s), {:.1} stops (P0.1–P99.9)",
                "",
                names.join(", "),
                100.0 * b.reference_clipped_or_dark,
                b.ground_truth.len(),
                b.gt_dynamic_range_stops
            );
        }
        let response = self
            .sets
            .first()
            .map(|b| b.response.clone())
            .unwrap_or_default();
        let _ = write!(
            text,
            "{} set(s) in {} (Kalantari layout: 16-bit TIFFs, exposure.txt, HDRImg.hdr = merge \
             in the unit of the stop-0 frame); linearised with {response}; inputs encoded as {}",
            self.sets.len(),
            out.display(),
            self.sets
                .first()
                .map(|b| b.encoding.as_str())
                .unwrap_or_default()
        );
        text
    }
}

/// Scan `dir` and write every set to `out` in Kalantari's layout. What can be refused without
/// the response (the inputs of every set, `--encode`) is refused before any work; the test set
/// is staged and appears in `out` whole, or not at all.
pub fn build(dir: &Path, opts: &BracketOptions, out: &Path) -> Result<BracketSummary> {
    build_scanned(dir, None, opts, out)
}

/// [`build`] on the sets of `dir` already scanned with `opts.scan`, where `scanned` holds them
/// (a run that reads the folder once: [`scan::FolderScan`]).
pub fn build_scanned(
    dir: &Path,
    scanned: Option<BracketScan>,
    opts: &BracketOptions,
    out: &Path,
) -> Result<BracketSummary> {
    // A test set inside the bracket folder would be scanned as brackets by the next run.
    crate::io::guard::refuse_output_inside(dir, out)?;
    // One writer per output, held to the end.
    let lock = crate::io::guard::OutputLock::acquire(out, "testset --brackets")?;
    let BracketScan { sets, mut notes } = match scanned {
        Some(s) => s,
        None => scan::scan(dir, &opts.scan)?,
    };
    let selections = sets
        .iter()
        .map(|set| select_inputs(set, &opts.inputs))
        .collect::<Result<Vec<_>>>()?;
    let plan = plan_encoding(&opts.encode, &sets)?;
    let staged = lock.stage(false)?;
    let lin = resolve_linearisation(&sets, &opts.response, Some(staged.path()), &mut notes)?;
    let (encode, record) = plan.resolve(&lin, &opts.response);
    let how = build::Encoding {
        encode: &encode,
        record: &record,
    };
    let summary = build::build_sets(&sets, &selections, &lin, how, opts, staged.path(), notes)?;
    record.save(staged.path())?;
    staged.commit()?;
    Ok(summary)
}

/// The inputs of `set` under `choice`, checked against the set: errors name the set's folder.
pub fn select_inputs(set: &scan::BracketSet, choice: &InputChoice) -> Result<InputSelection> {
    let n = set.frames.len();
    let folder = set.folder();
    if n < 3 {
        return Err(Error::layout(
            folder,
            format!(
                "set '{}' has {n} frames ({}); a Kalantari-layout test set needs three exposures",
                set.name,
                set.frames
                    .iter()
                    .map(|f| f.path.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    let listing = || {
        set.frames
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let name = f.path.file_name().map_or_else(
                    || f.path.display().to_string(),
                    |n| n.to_string_lossy().into_owned(),
                );
                format!("{i} {name}")
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    match choice {
        InputChoice::Spread => Ok(InputSelection {
            indices: [0, n / 2, n - 1],
            how: "the shortest, middle and longest exposure".to_string(),
            metered: Vec::new(),
        }),
        InputChoice::Indices(idx) => {
            let [i, j, k] = *idx;
            if i == j || j == k || i == k {
                return Err(Error::layout(
                    folder,
                    format!(
                        "set '{}': --inputs {i},{j},{k} repeats a frame; give three distinct \
                         frames (0-based, shortest exposure first: {})",
                        set.name,
                        listing()
                    ),
                ));
            }
            if !(i < j && j < k) {
                return Err(Error::layout(
                    folder,
                    format!(
                        "set '{}': --inputs {i},{j},{k} is not in ascending exposure; give the \
                         shortest input first (0-based: {})",
                        set.name,
                        listing()
                    ),
                ));
            }
            if k >= n {
                return Err(Error::layout(
                    folder,
                    format!(
                        "set '{}': --inputs {i},{j},{k}: index {k} is out of range, the set has \
                         {n} frames (0–{}: {})",
                        set.name,
                        n - 1,
                        listing()
                    ),
                ));
            }
            Ok(InputSelection {
                indices: *idx,
                how: format!("--inputs {i},{j},{k}"),
                metered: Vec::new(),
            })
        }
        InputChoice::Auto => {
            let stops: Vec<f64> = set.frames.iter().map(|f| f.stop).collect();
            // Decoding errors name the file; fewer than three frames was refused above.
            auto_inputs(&stops, |j| {
                Ok(clipped_or_dark(&code_frame(&set.frames[j])?))
            })
        }
    }
}
