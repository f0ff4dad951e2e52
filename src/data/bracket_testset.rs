//! `hdrsynth testset --brackets DIR --out OUT`: a user's own bracket folders
//! ([`crate::data::brackets`]) as a Kalantari-layout test set whose ground truth is made the way
//! the paper made testset-2's: the linear triangular merge of the static frames
//! (docs/your_device.md).
//!
//! Per set, three frames are used: the shortest, the one nearest the middle and the longest
//! exposure (others are reported as dropped). Each frame is linearised (1 = its clipping white)
//! with the response chosen by [`ResponseChoice`] (DNG: linear after black/white levels, white
//! balanced by AsShotNeutral), optionally aligned to the middle frame, and written as the
//! field expects a Kalantari frame: a 16-bit TIFF holding linear^(1/γ), γ = 2.2, so that the
//! field's own linearisation LDR^γ recovers the linear frame. Then:
//! - `exposure.txt`: log2 stops s_i relative to the shortest frame ("0 2 4" for EV −2/0/+2),
//!   the field's reading t_i = 2^s_i (HDR-Transformer's `read_expo_times`);
//! - `HDRImg.hdr`: the triangle merge ([`ground_truth::triangle_merge`], Kalantari's weights
//!   from the middle frame's TIFF value) of the written (quantised) frames, Σ w·L_i^γ / t_i /
//!   Σ w — in the field's unit, a frame at stop 0 (the shortest) has white 1; `hdrsynth eval`
//!   converts it to its own unit (1 = the middle frame's white);
//! - `brackets.toml`: where every frame came from, its exposure, the response used and the
//!   alignment shifts.

use crate::data::align::{self, MtbOptions};
use crate::data::brackets::{self, BracketFrame, BracketScan, FrameKind, ScanOptions};
use crate::data::ground_truth;
use crate::error::{Error, Result};
use crate::io::{BitDepth, Image, write_hdr, write_ldr};
use crate::sensor::crf::{self, DebevecOptions, RobertsonOptions};
use crate::sensor::profile::{Response, SensorProfile};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// γ of the written frames (the field's linearisation LDR^γ, Kalantari/Wu: 2.2).
pub const FIELD_GAMMA: f32 = 2.2;
pub const FRAME_NAMES: [&str; 3] = ["frame_1.tif", "frame_2.tif", "frame_3.tif"];
pub const RECORD: &str = crate::data::layout::kalantari::STATIC_MARKER;
/// `--response debevec`: the estimated response exp(g(z)), OpenCV's convention.
pub const CRF_FILE: &str = "crf_debevec.csv";
/// `--response robertson`: the estimated response I(z), OpenCV's convention (I(128) = 1).
pub const CRF_ROBERTSON_FILE: &str = "crf_robertson.csv";

/// How code values of LDR frames become linear.
#[derive(Clone, Debug, PartialEq)]
pub enum ResponseChoice {
    /// The device response of a sensor profile (named for the report).
    Profile { name: String, response: Response },
    /// A response the user declared (`--response srgb|linear|gamma:G`).
    Declared(Response),
    /// Debevec–Malik from the brackets (`--response debevec`): estimated on the first set with
    /// LDR frames, all its frames, and used for every set (one device).
    Debevec(DebevecOptions),
    /// Robertson et al. from the brackets (`--response robertson`), OpenCV's
    /// CalibrateRobertson; estimated and used like `Debevec`.
    Robertson(RobertsonOptions),
}

/// `--response`: a declared curve, or an estimator run on the brackets.
#[derive(Clone, Debug, PartialEq)]
pub enum ResponseSpec {
    Curve(Response),
    Debevec,
    Robertson,
}

impl std::str::FromStr for ResponseSpec {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<ResponseSpec, String> {
        match s {
            "debevec" => Ok(ResponseSpec::Debevec),
            "robertson" => Ok(ResponseSpec::Robertson),
            _ => s.parse::<Response>().map(ResponseSpec::Curve).map_err(|e| {
                format!("{e}, or an estimator: debevec (Debevec–Malik) or robertson (Robertson)")
            }),
        }
    }
}

impl ResponseChoice {
    /// The linearisation of bracket frames from a sensor profile (its device response) or a
    /// declared response; neither: Debevec.
    pub fn new(profile: Option<&Path>, response: Option<&ResponseSpec>) -> Result<Self> {
        Ok(match (profile, response) {
            (Some(p), _) => ResponseChoice::Profile {
                name: p.display().to_string(),
                response: SensorProfile::load(p)
                    .map_err(|e| Error::context(format!("loading profile {}", p.display()), e))?
                    .response,
            },
            (None, Some(ResponseSpec::Curve(r))) => ResponseChoice::Declared(r.clone()),
            (None, Some(ResponseSpec::Robertson)) => {
                ResponseChoice::Robertson(RobertsonOptions::default())
            }
            (None, Some(ResponseSpec::Debevec)) | (None, None) => {
                ResponseChoice::Debevec(DebevecOptions::default())
            }
        })
    }
}

/// A resolved linearisation of LDR code values.
#[derive(Clone, Debug, PartialEq)]
pub enum Linearise {
    Curve(Response),
    /// Linear per 8-bit code and channel (interpolated for 16-bit codes).
    Table([Vec<f64>; 3]),
}

impl ResponseChoice {
    pub fn describe(&self) -> String {
        match self {
            ResponseChoice::Profile { name, response } => {
                format!(
                    "the device response of profile {name} ({})",
                    response.label()
                )
            }
            ResponseChoice::Declared(r) => format!("declared response {}", r.label()),
            ResponseChoice::Debevec(o) => format!(
                "Debevec–Malik response estimated from the brackets (OpenCV's CalibrateDebevec \
                 recipe: {} samples, λ {})",
                o.samples, o.lambda
            ),
            ResponseChoice::Robertson(o) => format!(
                "Robertson response estimated from the brackets (OpenCV's CalibrateRobertson \
                 recipe: every pixel, at most {} iterations, threshold {})",
                o.max_iter, o.threshold
            ),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct BracketOptions {
    pub scan: ScanOptions,
    pub response: ResponseChoice,
    /// Hand-held sets: align every frame to the middle one by MTB ([`crate::data::align`]) and
    /// crop to the region all frames cover. None: tripod sets, used as captured.
    pub align: Option<MtbOptions>,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RecordFrame {
    pub source: PathBuf,
    pub written: String,
    /// log2 stop as written to exposure.txt (relative to the shortest frame).
    pub stop: f64,
    pub exposure_time_s: Option<f64>,
    pub iso: Option<f64>,
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
    pub frames: Vec<RecordFrame>,
    /// Frames of the bracket not used (the set had more than three).
    pub dropped: Vec<PathBuf>,
    /// MTB shifts (dx, dy) applied to the three frames (the middle one's is 0); empty when not
    /// aligned.
    pub shifts: Vec<[i32; 2]>,
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
        }
        let response = self
            .sets
            .first()
            .map(|b| b.response.clone())
            .unwrap_or_default();
        let _ = write!(
            text,
            "{} set(s) in {} (Kalantari layout: 16-bit TIFFs = linear^(1/2.2), exposure.txt, \
             HDRImg.hdr = triangle merge in the unit of the stop-0 frame); linearised with \
             {response}",
            self.sets.len(),
            out.display()
        );
        text
    }
}

/// Indices of the shortest, middle and longest frame of an ascending bracket.
fn pick_three(n: usize) -> [usize; 3] {
    [0, n / 2, n - 1]
}

/// One frame, linear in [0, 1] with 1 = its clipping white.
pub fn linear_frame(frame: &BracketFrame, lin: &Linearise) -> Result<Image> {
    match frame.kind {
        FrameKind::Dng => {
            let dng = crate::sensor::dng::read_dng(&frame.path)?;
            // White balance by AsShotNeutral, scaled so that no channel exceeds 1 at raw white.
            let n = dng.info.as_shot_neutral.unwrap_or([1.0; 3]);
            if n.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(Error::decode(
                    &frame.path,
                    format!("AsShotNeutral {n:?} must be positive"),
                ));
            }
            let lo = n.iter().copied().fold(f64::INFINITY, f64::min);
            let gain = n.map(|v| (lo / v) as f32);
            let mut img = dng.image;
            for p in img.data.chunks_exact_mut(3) {
                for c in 0..3 {
                    p[c] = (p[c] * gain[c]).clamp(0.0, 1.0);
                }
            }
            brackets::orient(img, frame)
        }
        FrameKind::Ldr => {
            let img = brackets::read_frame_image(frame)?;
            match lin {
                Linearise::Curve(r) => {
                    // 16-bit codes make a per-pixel inverse costly for LUT curves: tabulate it.
                    let table: Vec<f32> = (0..=65535)
                        .map(|k| r.invert(f64::from(k) / 65535.0) as f32)
                        .collect();
                    Ok(img.map(|v| table[(v.clamp(0.0, 1.0) * 65535.0).round() as usize]))
                }
                Linearise::Table(t) => {
                    let mut img = img;
                    for p in img.data.chunks_exact_mut(3) {
                        for (c, v) in p.iter_mut().enumerate() {
                            let z = v.clamp(0.0, 1.0) as f64 * 255.0;
                            let i = (z.floor() as usize).min(254);
                            let f = z - i as f64;
                            *v = (t[c][i] + (t[c][i + 1] - t[c][i]) * f) as f32;
                        }
                    }
                    Ok(img)
                }
            }
        }
    }
}

/// The linearisation of LDR frames for the scanned `sets` under `choice`: a curve as given, or
/// a response estimated from the first set whose frames are all LDR (all its frames, times
/// from their stops), written to `crf_dir` (OpenCV's convention) and noted. With no LDR set
/// (DNG brackets, linear after their levels) nothing is estimated.
pub fn resolve_linearisation(
    sets: &[brackets::BracketSet],
    choice: &ResponseChoice,
    crf_dir: &Path,
    notes: &mut Vec<String>,
) -> Result<Linearise> {
    let (name, file) = match choice {
        ResponseChoice::Profile { response, .. } | ResponseChoice::Declared(response) => {
            return Ok(Linearise::Curve(response.clone()));
        }
        ResponseChoice::Debevec(_) => ("Debevec–Malik", CRF_FILE),
        ResponseChoice::Robertson(_) => ("Robertson", CRF_ROBERTSON_FILE),
    };
    let ldr = sets
        .iter()
        .find(|s| s.frames.iter().all(|f| f.kind == FrameKind::Ldr));
    let Some(set) = ldr else {
        return Ok(Linearise::Curve(Response::Linear));
    };
    let frames = set
        .frames
        .iter()
        .map(brackets::read_frame_image)
        .collect::<Result<Vec<Image>>>()?;
    // Only ratios matter: times relative to the shortest frame.
    let times: Vec<f64> = set
        .frames
        .iter()
        .map(|f| (f.stop - set.frames[0].stop).exp2())
        .collect();
    let mut response = match choice {
        ResponseChoice::Robertson(o) => crf::calibrate_robertson(&frames, &times, *o)?,
        ResponseChoice::Debevec(o) => crf::calibrate_debevec(&frames, &times, *o)?,
        _ => unreachable!("curves returned above"),
    };
    let mut csv = String::from("code,r,g,b\n");
    for (z, ((r, g), b)) in response[0]
        .iter()
        .zip(&response[1])
        .zip(&response[2])
        .enumerate()
    {
        csv.push_str(&format!("{z},{r},{g},{b}\n"));
    }
    std::fs::create_dir_all(crf_dir).map_err(|e| Error::io(crf_dir, e))?;
    let path = crf_dir.join(file);
    crate::io::atomic::write_atomic(&path, csv.as_bytes())?;
    notes.push(format!(
        "response: {name} estimated from set '{}' ({} frames), written to {}",
        set.name,
        set.frames.len(),
        path.display()
    ));
    if matches!(choice, ResponseChoice::Robertson(_)) {
        // Robertson's I(255) is the mean exposure of all clipped observations, far above the
        // clipping point; the clipping white is taken one code step beyond 254 instead.
        for r in &mut response {
            r[255] = r[254] + (r[254] - r[253]).max(0.0);
        }
    }
    Ok(Linearise::Table(crf::linearisation_table(&response)))
}

/// Scan `dir` and write every set to `out` in Kalantari's layout.
pub fn build(dir: &Path, opts: &BracketOptions, out: &Path) -> Result<BracketSummary> {
    // A test set inside the bracket folder would be scanned as brackets by the next run.
    crate::io::guard::refuse_output_inside(dir, out)?;
    // One writer per output (issue 16), held to the end.
    let _lock = crate::io::guard::OutputLock::acquire(out, "testset --brackets")?;
    let BracketScan { sets, mut notes } = brackets::scan(dir, &opts.scan)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let lin = resolve_linearisation(&sets, &opts.response, out, &mut notes)?;
    build_sets(&sets, &lin, opts, out, notes)
}

fn build_sets(
    sets: &[brackets::BracketSet],
    lin: &Linearise,
    opts: &BracketOptions,
    out: &Path,
    mut notes: Vec<String>,
) -> Result<BracketSummary> {
    let mut built = Vec::with_capacity(sets.len());
    for set in sets {
        let idx = pick_three(set.frames.len());
        if set.frames.len() < 3 {
            return Err(Error::layout(
                &set.frames[0].path,
                format!(
                    "set '{}' has {} frames ({}); a Kalantari-layout test set needs three \
                     exposures",
                    set.name,
                    set.frames.len(),
                    set.frames
                        .iter()
                        .map(|f| f.path.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        let chosen: Vec<&BracketFrame> = idx.iter().map(|&i| &set.frames[i]).collect();
        let dropped: Vec<PathBuf> = (0..set.frames.len())
            .filter(|i| !idx.contains(i))
            .map(|i| set.frames[i].path.clone())
            .collect();
        if !dropped.is_empty() {
            notes.push(format!(
                "set '{}': {} frames; used the shortest, middle and longest, dropped {}",
                set.name,
                set.frames.len(),
                dropped.len()
            ));
        }
        let linear = chosen
            .iter()
            .map(|f| linear_frame(f, lin))
            .collect::<Result<Vec<Image>>>()?;
        let (w, h) = (linear[1].width, linear[1].height);
        for (f, img) in chosen.iter().zip(&linear) {
            if (img.width, img.height) != (w, h) {
                return Err(Error::layout(
                    &f.path,
                    format!(
                        "{}×{}, but the set's middle frame {} is {w}×{h}",
                        img.width,
                        img.height,
                        chosen[1].path.display()
                    ),
                ));
            }
        }
        // Stops relative to the shortest frame, rounded as written so the merge uses exactly
        // what the field's code will read back.
        let stops: Vec<f64> = chosen
            .iter()
            .map(|f| {
                format!("{:.6}", f.stop - chosen[0].stop)
                    .parse()
                    .unwrap_or(0.0)
            })
            .collect();
        let inv_g = 1.0 / FIELD_GAMMA;
        let mut codes: Vec<Image> = linear
            .iter()
            .map(|img| img.map(|v| (v.clamp(0.0, 1.0).powf(inv_g) * 65535.0).round() / 65535.0))
            .collect();
        let mut shifts = Vec::new();
        if let Some(mtb) = opts.align {
            // MTB on the γ-encoded frames: its median thresholds need no response.
            let s: Vec<(i32, i32)> = codes
                .iter()
                .map(|c| align::mtb_shift(&codes[1], c, mtb))
                .collect();
            codes = align::apply_shifts(&codes, &s);
            if codes[1].width == 0 || codes[1].height == 0 {
                return Err(Error::layout(
                    &chosen[1].path,
                    format!("set '{}': MTB shifts {s:?} leave no common area", set.name),
                ));
            }
            shifts = s.iter().map(|&(x, y)| [x, y]).collect();
        }
        let (w, h) = (codes[1].width, codes[1].height);
        let times = [0, 1, 2].map(|i| stops[i].exp2() as f32);
        let hdr = ground_truth::triangle_merge(
            &[codes[0].clone(), codes[1].clone(), codes[2].clone()],
            times,
            FIELD_GAMMA,
        )?;

        let set_dir = out.join(&set.name);
        std::fs::create_dir_all(&set_dir).map_err(|e| Error::io(&set_dir, e))?;
        for (img, name) in codes.iter().zip(FRAME_NAMES) {
            write_ldr(&set_dir.join(name), img, BitDepth::Sixteen)?;
        }
        let expo = set_dir.join(crate::data::layout::kalantari::EXPOSURE_FILE);
        let text = stops
            .iter()
            .map(|s| format!("{s}"))
            .collect::<Vec<_>>()
            .join("\n")
            + "\n";
        crate::io::atomic::write_atomic(&expo, text.as_bytes())?;
        write_hdr(&set_dir.join(crate::data::layout::kalantari::GT_FILE), &hdr)?;
        let record = BuiltBracketSet {
            name: set.name.clone(),
            width: w,
            height: h,
            grouping: set.grouping.clone(),
            exposure_source: set.exposure_source.clone(),
            response: if chosen.iter().all(|f| f.kind == FrameKind::Dng) {
                "linear raw (DNG black/white levels)".to_string()
            } else {
                opts.response.describe()
            },
            frames: chosen
                .iter()
                .zip(FRAME_NAMES)
                .zip(&stops)
                .map(|((f, name), &stop)| RecordFrame {
                    source: f.path.clone(),
                    written: name.to_string(),
                    stop,
                    exposure_time_s: f.exif.exposure_time,
                    iso: f.exif.iso,
                })
                .collect(),
            dropped,
            shifts,
        };
        let toml =
            toml::to_string_pretty(&record).map_err(|e| Error::encode(set_dir.join(RECORD), e))?;
        crate::io::atomic::write_atomic(&set_dir.join(RECORD), toml.as_bytes())?;
        built.push(record);
    }
    Ok(BracketSummary { sets: built, notes })
}
