//! How code values of a device's frames become linear: a declared curve, a profile's device
//! response, or a response estimated from the brackets (Debevec–Malik, Robertson; OpenCV's
//! recipes), resolved once per run and applied to every frame. The test set, the profile, the
//! diagnosis and the device-output check all linearise through this module.

use crate::capture::scan::{self, BracketFrame, FrameKind};
use crate::error::{Error, Result};
use crate::io::Image;
use crate::sensor::crf::{self, DebevecOptions, RobertsonOptions};
use crate::sensor::profile::{Response, SensorProfile};
use std::path::Path;

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
    /// One curve for the three channels ([`DebevecOptions::one_curve`]).
    Debevec,
    /// OpenCV's recipe as it is: a curve per channel.
    DebevecPerChannel,
    Robertson,
}

impl std::str::FromStr for ResponseSpec {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<ResponseSpec, String> {
        match s {
            "debevec" => Ok(ResponseSpec::Debevec),
            "debevec-per-channel" => Ok(ResponseSpec::DebevecPerChannel),
            "robertson" => Ok(ResponseSpec::Robertson),
            _ => s.parse::<Response>().map(ResponseSpec::Curve).map_err(|e| {
                format!(
                    "{e}, or an estimator: debevec (Debevec–Malik, one curve for the three \
                     channels), debevec-per-channel or robertson (Robertson, per channel)"
                )
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
            (None, Some(ResponseSpec::DebevecPerChannel)) => {
                ResponseChoice::Debevec(DebevecOptions::default())
            }
            (None, Some(ResponseSpec::Debevec)) | (None, None) => {
                ResponseChoice::Debevec(DebevecOptions::one_curve())
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
                 recipe: {} samples, λ {}; {})",
                o.samples,
                o.lambda,
                if o.shared {
                    format!(
                        "one curve for the three channels: their {} samples pooled, λ {}",
                        3 * o.samples,
                        3.0 * o.lambda
                    )
                } else {
                    "a curve per channel".to_string()
                }
            ),
            ResponseChoice::Robertson(o) => format!(
                "Robertson response estimated from the brackets (OpenCV's CalibrateRobertson \
                 recipe: every pixel, at most {} iterations, threshold {})",
                o.max_iter, o.threshold
            ),
        }
    }
}

/// One frame, linear in [0, 1] with 1 = its clipping white.
pub fn linear_frame(frame: &BracketFrame, lin: &Linearise) -> Result<Image> {
    Ok(linearise(frame, code_frame(frame)?, lin))
}

/// One frame's values as stored, upright: LDR code / maximum code; DNG linear after its levels
/// and white balance.
pub fn code_frame(frame: &BracketFrame) -> Result<Image> {
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
            scan::orient(img, frame)
        }
        FrameKind::Ldr => scan::read_frame_image(frame),
    }
}

/// `code` ([`code_frame`] of `frame`) made linear: DNG values are already.
pub fn linearise(frame: &BracketFrame, code: Image, lin: &Linearise) -> Image {
    if frame.kind == FrameKind::Dng {
        return code;
    }
    match lin {
        Linearise::Curve(r) => {
            // 16-bit codes make a per-pixel inverse costly for LUT curves: tabulate it.
            let table = r.inverse_table();
            code.map(|v| table[(v.clamp(0.0, 1.0) * 65535.0).round() as usize])
        }
        Linearise::Table(t) => {
            let mut img = code;
            for p in img.data.chunks_exact_mut(3) {
                for (c, v) in p.iter_mut().enumerate() {
                    let z = v.clamp(0.0, 1.0) as f64 * 255.0;
                    let i = (z.floor() as usize).min(254);
                    let f = z - i as f64;
                    *v = (t[c][i] + (t[c][i + 1] - t[c][i]) * f) as f32;
                }
            }
            img
        }
    }
}

/// Refuse a set whose frames (as read, upright) differ in size, naming the first that
/// differs from the set's first frame.
fn same_size(set: &scan::BracketSet, frames: &[Image]) -> Result<()> {
    let (w, h) = (frames[0].width, frames[0].height);
    match frames.iter().position(|f| (f.width, f.height) != (w, h)) {
        None => Ok(()),
        Some(i) => Err(scan::size_mismatch(
            &set.frames[i].path,
            (frames[i].width, frames[i].height),
            &set.frames[0].path,
            (w, h),
        )),
    }
}

/// The linearisation of LDR frames for the scanned `sets` under `choice`: a curve as given, or
/// a response estimated from the first set whose frames are all LDR (all its frames, times
/// from their stops), written to `crf_dir` when given (OpenCV's convention) and noted. With no
/// LDR set (DNG brackets, linear after their levels) nothing is estimated.
pub fn resolve_linearisation(
    sets: &[scan::BracketSet],
    choice: &ResponseChoice,
    crf_dir: Option<&Path>,
    notes: &mut Vec<String>,
) -> Result<Linearise> {
    let (name, file) = match choice {
        ResponseChoice::Profile { response, .. } | ResponseChoice::Declared(response) => {
            return Ok(Linearise::Curve(response.clone()));
        }
        ResponseChoice::Debevec(_) => ("Debevec–Malik", CRF_FILE),
        ResponseChoice::Robertson(_) => ("Robertson", CRF_ROBERTSON_FILE),
    };
    let is_ldr = |s: &&scan::BracketSet| s.frames.iter().all(|f| f.kind == FrameKind::Ldr);
    let Some(set) = sets.iter().filter(is_ldr).find(|s| s.frames.len() >= 2) else {
        return match sets.iter().find(is_ldr) {
            // Bursts of one exposure (repeated captures) say nothing about the response.
            Some(burst) => Err(Error::layout(
                &burst.frames[0].path,
                format!(
                    "no set has two or more exposures to estimate the {name} response from; \
                     declare the response (--response srgb, gamma:G or a profile's)"
                ),
            )),
            None => Ok(Linearise::Curve(Response::Linear)),
        };
    };
    let frames = set
        .frames
        .iter()
        .map(scan::read_frame_image)
        .collect::<Result<Vec<Image>>>()?;
    same_size(set, &frames)?;
    refuse_no_signal(set, &frames, name)?;
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
    // The estimators leave the darkest codes to their priors: re-estimated from the frames
    // (crf::refine_toe) before the curve is written or used.
    let shared = matches!(choice, ResponseChoice::Debevec(o) if o.shared);
    crf::refine_toe(&frames, &times, &mut response, shared)?;
    let mut written = String::new();
    if let Some(crf_dir) = crf_dir {
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
        // Named by file: it is written where the output will appear.
        written = format!(", written as {file}");
    }
    notes.push(format!(
        "response: {name} estimated from set '{}' ({} frames){written}; codes under {} \
         re-estimated from the radiance its frames record at codes {}–{}",
        set.name,
        set.frames.len(),
        crf::TOE_CODES,
        crf::TOE_CODES,
        crf::TOE_SOURCE_TOP,
    ));
    if matches!(choice, ResponseChoice::Robertson(_)) {
        // Robertson's I(255) is the mean exposure of all clipped observations, far above the
        // clipping point; where the table cannot fit the white (crf::linearisation_table), it
        // is taken one code step beyond 254 instead.
        for r in &mut response {
            r[255] = r[254] + (r[254] - r[253]).max(0.0);
        }
    }
    Ok(Linearise::Table(crf::linearisation_table(&response)))
}

/// Fewest pixels per frame, and distinct codes between dark and clipped over a set's frames
/// and channels, that a response is estimated from (OpenCV's Debevec samples 70 pixels).
const MIN_RESPONSE_PIXELS: usize = 70;
const MIN_RESPONSE_CODES: usize = 16;

/// Refuse to estimate a response from frames that hold no signal: too few pixels, or too few
/// distinct codes between the dark and clipped limits (all-black, all-white or flat frames).
fn refuse_no_signal(set: &scan::BracketSet, frames: &[Image], name: &str) -> Result<()> {
    let pixels = frames.iter().map(|f| f.width * f.height).min().unwrap_or(0);
    let mut codes = [false; 256];
    for v in frames.iter().flat_map(|f| &f.data) {
        codes[crf::code8(*v)] = true;
    }
    let (dark, clipped) = (5, 250);
    let distinct = codes[dark + 1..clipped].iter().filter(|&&c| c).count();
    if pixels < MIN_RESPONSE_PIXELS || distinct < MIN_RESPONSE_CODES {
        return Err(Error::layout(
            set.folder(),
            format!(
                "set '{}' holds no signal to estimate the {name} response from: {pixels} \
                 pixel(s) per frame (at least {MIN_RESPONSE_PIXELS}), {distinct} distinct \
                 code(s) between {dark} and {clipped} over its frames (at least \
                 {MIN_RESPONSE_CODES}); all-dark, all-clipped or flat frames? Declare the \
                 response (--response srgb, gamma:G or a profile's) or capture a scene with \
                 mid tones",
                set.name
            ),
        ));
    }
    Ok(())
}
