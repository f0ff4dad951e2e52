//! Colour calibration (`hdrsynth calibrate colour`): fit a SensorProfile's colour transform T
//! (real = T · synthetic, the paper's Eq. 1) from a real capture of a ColorChecker24 and a
//! synthetic one (rendered by hdrsynth by default), report per-patch ΔE00 before/after and
//! leave-one-patch-out, and write the profile atomically (see docs/colour.md).
//!
//! Steps:
//! 1. Read the real capture. DNG: black-subtracted, normalised by (white − black), bilinear
//!    demosaic, camera RGB. EXR/HDR: linear as stored. PNG/TIFF: code values, linearised with
//!    the given response (default: sRGB for 8-bit files, linear for 16-bit files, which raw
//!    converters such as `dcraw -4 -T` write linear).
//! 2. Sample the 24 patches (central half of each cell; full frame or given corners); a clipped
//!    patch (any channel ≥ 0.98 of the input's clip level, judged in the input's own code
//!    values or normalised DN) is an error naming the patch and the file.
//! 3. The synthetic patches: the rendered chart (reference linear sRGB × illuminant gains ×
//!    exposure), or a synthetic image sampled the same way.
//! 4. `fit::fit_chart` (shared with `diagnose`): white balance `neutral` (default: real
//!    channels scaled by mean_G / mean_c over the neutral patches 20–23, so their mean is
//!    neutral; device linear RGB is white-balanced camera RGB), exposure normalisation on
//!    patches 20–23, T by least squares (and the root-polynomial if asked), ΔE00 with the
//!    colours treated as linear sRGB D65, Lab D50.
//! 5. Write the profile: an existing one keeps everything but `colour` and `provenance.colour`.

use super::chart::{self, COLORCHECKER24, ChartRegion, Illuminant, PatchSample};
use super::fit::{self, ChartFit, ChartFitError, Fitted, WhiteBalance};
use crate::error::{Error, Result};
use crate::io::{Format, Image, read_image_info};
use crate::linalg::Mat3;
use crate::sensor::dng::{DngInfo, read_dng};
use crate::sensor::profile::{Colour, Levels, Provenance, Response, SensorProfile};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The synthetic chart the real one is fitted to.
#[derive(Clone, Debug, PartialEq)]
pub enum SyntheticChart {
    /// The reference chart rendered under `illuminant` at `exposure` (> 0).
    Render {
        illuminant: Illuminant,
        exposure: f64,
    },
    /// A synthetic image of the chart, sampled like the real capture; `response` linearises a
    /// PNG/TIFF (same default rule as the real capture).
    Image {
        path: PathBuf,
        region: ChartRegion,
        response: Option<Response>,
    },
}

/// Everything a colour calibration needs: the inputs and the fit, then the profile it writes.
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrateOptions {
    /// Real capture of the chart: DNG (raw), EXR/HDR (linear) or PNG/TIFF (code values).
    pub real: PathBuf,
    /// Where the real chart's patch area lies.
    pub real_region: ChartRegion,
    /// Response to linearise a PNG/TIFF real capture (None: sRGB for 8-bit, linear for 16-bit).
    pub real_response: Option<Response>,
    pub synthetic: SyntheticChart,
    pub white_balance: WhiteBalance,
    /// Also fit the root-polynomial (degree 2) and make the profile use it.
    pub root_polynomial: bool,
    /// Clip level of the inputs in their own units (None: code value 1, or the DNG white level;
    /// EXR/HDR are not checked).
    pub clip_level: Option<f64>,
    /// Sensor profile (TOML) to update, or to create if it does not exist.
    pub out: PathBuf,
    /// Levels of a new profile when the real capture is not a DNG (all three or none).
    pub black: Option<f64>,
    pub white: Option<f64>,
    pub bits: Option<u32>,
    /// Name of a new profile (None: the DNG's camera model, else the file stem of `out`).
    pub name: Option<String>,
    /// How the calibration was asked for, quoted in the profile's provenance (the CLI gives its
    /// command line).
    pub invocation: String,
}

impl CalibrateOptions {
    /// The defaults: chart filling the frame, rendered under D65 at exposure 1, neutral white
    /// balance, 3×3 T only.
    pub fn new(real: PathBuf, out: PathBuf, invocation: String) -> CalibrateOptions {
        CalibrateOptions {
            real,
            real_region: ChartRegion::FullFrame,
            real_response: None,
            synthetic: SyntheticChart::Render {
                illuminant: Illuminant::D65,
                exposure: 1.0,
            },
            white_balance: WhiteBalance::Neutral,
            root_polynomial: false,
            clip_level: None,
            out,
            black: None,
            white: None,
            bits: None,
            name: None,
            invocation,
        }
    }
}

fn response_name(r: &Response) -> String {
    match r {
        Response::Linear => "linear".into(),
        Response::Srgb => "srgb".into(),
        Response::Gamma { gamma } => format!("gamma:{gamma}"),
        Response::Filmic => "filmic".into(),
        Response::Lut { lut } => format!("lut ({} samples)", lut.len()),
    }
}

/// An input image ready for sampling.
struct Input {
    path: PathBuf,
    /// Linear values.
    linear: Image,
    /// The image and level to judge clipping on (the input's own units), if any.
    clip: Option<(Image, f64)>,
    response: Response,
    dng: Option<DngInfo>,
    what: String,
}

fn load_input(path: &Path, given: Option<&Response>, clip_level: Option<f64>) -> Result<Input> {
    let is_dng = path
        .extension()
        .is_some_and(|e| e.to_string_lossy().eq_ignore_ascii_case("dng"));
    if let Some(c) = clip_level
        && !(c > 0.0 && c.is_finite())
    {
        return Err(Error::flag("--clip-level", format!("{c} must be > 0")));
    }
    if is_dng {
        if given.is_some_and(|r| *r != Response::Linear) {
            return Err(Error::config(
                path,
                "a raw DNG is linear; drop the response option",
            ));
        }
        let dng = read_dng(path)?;
        let what = format!("raw DNG, {}", dng.info.describe());
        let level = clip_level.unwrap_or(1.0);
        return Ok(Input {
            path: path.to_path_buf(),
            clip: Some((dng.image.clone(), level)),
            linear: dng.image,
            response: Response::Linear,
            dng: Some(dng.info),
            what,
        });
    }
    let (img, info) = read_image_info(path)?;
    match info.format {
        Format::Exr | Format::Hdr => {
            if given.is_some_and(|r| *r != Response::Linear) {
                return Err(Error::config(
                    path,
                    "EXR/HDR files hold linear values; drop the response option",
                ));
            }
            Ok(Input {
                path: path.to_path_buf(),
                clip: clip_level.map(|c| (img.clone(), c)),
                linear: img,
                response: Response::Linear,
                dng: None,
                what: "linear float image".into(),
            })
        }
        Format::Png | Format::Tiff | Format::Jpeg => {
            let bits = match info.bit_depth {
                Some(crate::io::BitDepth::Eight) => 8,
                _ => 16,
            };
            let r = given.cloned().unwrap_or(if bits == 8 {
                Response::Srgb
            } else {
                Response::Linear
            });
            let linear = if r == Response::Linear {
                img.clone()
            } else {
                img.map(|v| r.invert(v as f64) as f32)
            };
            let what = format!("{bits}-bit code values linearised as {}", response_name(&r));
            Ok(Input {
                path: path.to_path_buf(),
                clip: Some((img, clip_level.unwrap_or(1.0))),
                linear,
                response: r,
                dng: None,
                what,
            })
        }
    }
}

fn sample(input: &Input, region: &ChartRegion) -> Result<Vec<PatchSample>> {
    let ctx = |e: Error| {
        Error::within(format!(
            "{}: sampling the chart ({region})",
            input.path.display()
        ))(e)
    };
    if let Some((img, level)) = &input.clip {
        chart::sample_chart(img, region, Some(*level)).map_err(ctx)?;
    }
    let samples = chart::sample_chart(&input.linear, region, None).map_err(ctx)?;
    // A grey capture (a single-channel file, e.g. a Y-only EXR, read as R = G = B) makes every
    // fit singular; say so about this input rather than about the profile written from it.
    let grey = samples.iter().all(|s| {
        let m = s.mean;
        let tol = 1e-6 * m.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        (m[0] - m[1]).abs() <= tol && (m[1] - m[2]).abs() <= tol
    });
    if grey {
        return Err(Error::unsupported(
            &input.path,
            format!(
                "every chart patch ({region}) has R = G = B: the image holds no colour (a grey \
                 or single-channel file, e.g. a Y-only EXR); a colour calibration needs a \
                 colour capture"
            ),
        ));
    }
    Ok(samples)
}

/// What a colour calibration found.
#[derive(Clone, Debug)]
pub struct Calibration {
    pub fit: ChartFit,
    /// Per-patch standard deviation of the real samples, on the same scale as `fit.real`.
    pub real_std: Vec<[f64; 3]>,
}

/// Run the calibration without writing anything.
pub fn calibrate(opts: &CalibrateOptions) -> Result<(Calibration, InputsInfo)> {
    let real = load_input(&opts.real, opts.real_response.as_ref(), opts.clip_level)?;
    let real_samples = sample(&real, &opts.real_region)?;

    let (synthetic_samples, synthetic_what) = match &opts.synthetic {
        SyntheticChart::Render {
            illuminant,
            exposure,
        } => {
            let exposure = *exposure;
            if !(exposure > 0.0 && exposure.is_finite()) {
                return Err(Error::flag("--exposure", format!("{exposure} must be > 0")));
            }
            let img = chart::render_chart(600, 400, illuminant, exposure);
            let s = chart::sample_chart(&img, &ChartRegion::FullFrame, None)?;
            let g = illuminant.gains();
            (
                s,
                format!(
                    "rendered ColorChecker24 (reference linear sRGB × {illuminant} gains ({:.4}, {:.4}, {:.4}) × exposure {exposure})",
                    g[0], g[1], g[2]
                ),
            )
        }
        SyntheticChart::Image {
            path,
            region,
            response,
        } => {
            if path
                .extension()
                .is_some_and(|e| e.to_string_lossy().eq_ignore_ascii_case("dng"))
            {
                return Err(Error::config(path, "the synthetic chart cannot be a DNG"));
            }
            let syn = load_input(path, response.as_ref(), opts.clip_level)?;
            let what = format!("{} ({}), chart at {region}", path.display(), syn.what);
            (sample(&syn, region)?, what)
        }
    };

    let raw: Vec<[f64; 3]> = real_samples.iter().map(|s| s.mean).collect();
    let synthetic: Vec<[f64; 3]> = synthetic_samples.iter().map(|s| s.mean).collect();
    let fit = fit::fit_chart(&raw, &synthetic, opts.white_balance, opts.root_polynomial).map_err(
        |e| match e {
            ChartFitError::Fit(e) => e,
            e => Error::config(&opts.real, e),
        },
    )?;
    // The profile refuses a singular T; refuse it here, naming the capture it came from.
    if let Err(why) = crate::sensor::profile::check_colour_matrix(&fit.t()) {
        return Err(Error::config(
            &opts.real,
            format!("the chart fit gives an unusable colour matrix ({why})"),
        ));
    }
    let (g, k, s) = (fit.white_balance_gains, fit.exposure_scale, fit.chart_scale);
    let real_std: Vec<[f64; 3]> = real_samples
        .iter()
        .map(|p| std::array::from_fn(|c| p.std[c] * g[c] * k * s))
        .collect();
    Ok((
        Calibration { fit, real_std },
        InputsInfo {
            real_what: real.what.clone(),
            real_response: real.response.clone(),
            real_region: opts.real_region,
            dng: real.dng.clone(),
            synthetic_what,
        },
    ))
}

/// What the inputs were, for the report and provenance.
#[derive(Clone, Debug)]
pub struct InputsInfo {
    pub real_what: String,
    pub real_response: Response,
    pub real_region: ChartRegion,
    pub dng: Option<DngInfo>,
    pub synthetic_what: String,
}

fn fmt_matrix<const N: usize>(m: &[[f64; N]; 3]) -> String {
    m.iter()
        .map(|r| {
            let cells: Vec<String> = r.iter().map(|v| format!("{v:9.5}")).collect();
            format!("  [{}]", cells.join(", "))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The report table and summary.
pub fn report(cal: &Calibration, inputs: &InputsInfo) -> String {
    let c = &cal.fit;
    let mut r = String::new();
    let _ = writeln!(r, "real:      {}", inputs.real_what);
    let _ = writeln!(r, "           chart at {}", inputs.real_region);
    let _ = writeln!(r, "synthetic: {}", inputs.synthetic_what);
    let g = c.white_balance_gains;
    let _ = writeln!(
        r,
        "white balance gains (R, G, B): {:.5}, {:.5}, {:.5}; exposure scale of the real patches: {:.5}",
        g[0], g[1], g[2], c.exposure_scale
    );
    let _ = writeln!(r);
    let with_rp = c.root_polynomial.as_ref();
    let _ = write!(
        r,
        "{:>2} {:<22} {:>26} {:>26} {:>8} {:>7} {:>7} {:>7}",
        "#", "patch", "synthetic (R, G, B)", "real (R, G, B)", "real std", "ΔE00", "T", "T LOO"
    );
    if with_rp.is_some() {
        let _ = write!(r, " {:>7} {:>7}", "RP", "RP LOO");
    }
    let _ = writeln!(r);
    for (i, p) in COLORCHECKER24.iter().enumerate() {
        let (s, q, sd) = (c.synthetic[i], c.real[i], cal.real_std[i]);
        let _ = write!(
            r,
            "{:>2} {:<22} {:>26} {:>26} {:>8.5} {:>7.3} {:>7.3} {:>7.3}",
            p.number,
            p.name,
            format!("{:.5}, {:.5}, {:.5}", s[0], s[1], s[2]),
            format!("{:.5}, {:.5}, {:.5}", q[0], q[1], q[2]),
            sd.iter().fold(0.0f64, |a, &b| a.max(b)),
            c.matrix.before.per_patch[i],
            c.matrix.after.per_patch[i],
            c.matrix.loo.per_patch[i]
        );
        if let Some(rp) = with_rp {
            let _ = write!(
                r,
                " {:>7.3} {:>7.3}",
                rp.after.per_patch[i], rp.loo.per_patch[i]
            );
        }
        let _ = writeln!(r);
    }
    let _ = writeln!(r);
    let m = &c.matrix;
    let _ = writeln!(
        r,
        "ΔE00 before (identity): mean {:.3}, max {:.3}",
        m.before.mean, m.before.max
    );
    let _ = writeln!(
        r,
        "ΔE00 after T (3×3):     mean {:.3}, max {:.3}; leave-one-patch-out mean {:.3}, max {:.3}",
        m.after.mean, m.after.max, m.loo.mean, m.loo.max
    );
    if let Some(rp) = with_rp {
        let _ = writeln!(
            r,
            "ΔE00 after root-poly:   mean {:.3}, max {:.3}; leave-one-patch-out mean {:.3}, max {:.3}",
            rp.after.mean, rp.after.max, rp.loo.mean, rp.loo.max
        );
    }
    if let Fitted::Matrix(t) = &m.fitted {
        let _ = writeln!(r, "T (real = T · synthetic):\n{}", fmt_matrix(t));
    }
    if let Some(Fitted::RootPolynomial(rp)) = with_rp.map(|e| &e.fitted) {
        let _ = writeln!(
            r,
            "root-polynomial (R, G, B, √RG, √GB, √RB):\n{}",
            fmt_matrix(rp)
        );
    }
    r
}

/// Today's date and time in UTC, "YYYY-MM-DD HH:MM UTC".
fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0);
    let (days, rem) = (secs.div_euclid(86400), secs.rem_euclid(86400));
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02} UTC",
        rem / 3600,
        rem % 3600 / 60
    )
}

/// Calibrate, write the profile (created, or updated keeping everything but the colour), return
/// the report.
pub fn run(opts: &CalibrateOptions) -> Result<String> {
    let (cal, inputs) = calibrate(opts)?;
    let (mut profile, exists) =
        SensorProfile::load_or_create(&opts.out, || new_profile(opts, &inputs))?;
    let t = cal.fit.t();
    let rp = cal.fit.root_polynomial.as_ref().map(|e| match &e.fitted {
        Fitted::RootPolynomial(m) => *m,
        Fitted::Matrix(_) => unreachable!("root-polynomial evaluation holds a 3×6 matrix"),
    });
    profile.colour = Some(Colour {
        matrix: t,
        root_polynomial: rp,
        use_root_polynomial: rp.is_some(),
    });
    let m = &cal.fit.matrix;
    let mut prov = format!(
        "ColorChecker24 fit by `{}` on {}. Real: {} ({}), chart at {}. Synthetic: {}. White \
         balance: {}. 3×3 T least squares (real = T · synthetic): ΔE00 mean {:.3} (max {:.3}) \
         after, {:.3} (max {:.3}) before, leave-one-patch-out mean {:.3} (max {:.3}); ΔE00 on \
         colours treated as linear sRGB D65, Lab D50.",
        opts.invocation,
        utc_now(),
        opts.real.display(),
        inputs.real_what,
        inputs.real_region,
        inputs.synthetic_what,
        match opts.white_balance {
            WhiteBalance::Neutral => {
                let g = cal.fit.white_balance_gains;
                format!(
                    "neutral patches 20–23 (gains {:.4}, {:.4}, {:.4})",
                    g[0], g[1], g[2]
                )
            }
            WhiteBalance::None => "none".into(),
        },
        m.after.mean,
        m.after.max,
        m.before.mean,
        m.before.max,
        m.loo.mean,
        m.loo.max
    );
    if let Some(e) = &cal.fit.root_polynomial {
        let _ = write!(
            prov,
            " Root-polynomial degree 2 (used): ΔE00 mean {:.3} (max {:.3}), leave-one-patch-out \
             mean {:.3} (max {:.3}).",
            e.after.mean, e.after.max, e.loo.mean, e.loo.max
        );
    }
    profile.provenance.colour = prov;
    profile
        .validate()
        .map_err(|msg| Error::config(&opts.out, msg))?;
    profile.save(&opts.out)?;
    let mut text = report(&cal, &inputs);
    let _ = writeln!(
        text,
        "\n{} {} (colour{}).",
        if exists { "updated" } else { "created" },
        opts.out.display(),
        if exists {
            " and provenance.colour replaced; everything else kept"
        } else {
            ""
        }
    );
    if exists && (opts.black.is_some() || opts.white.is_some() || opts.bits.is_some()) {
        text.push_str(
            "note: --black/--white/--bits were not used: the profile already has levels.\n",
        );
    }
    Ok(text)
}

fn new_profile(opts: &CalibrateOptions, inputs: &InputsInfo) -> Result<SensorProfile> {
    let (levels, levels_prov) = match (&inputs.dng, opts.black, opts.white, opts.bits) {
        (_, Some(black), Some(white), Some(bits)) => (
            Levels {
                black_level: black,
                white_level: white,
                bit_depth: bits,
            },
            format!(
                "given on the command line (--black {black} --white {white} --bits {bits}) to \
                 `hdrsynth calibrate colour`"
            ),
        ),
        (Some(d), None, None, None) => (
            Levels {
                black_level: d.black_level_mean(),
                white_level: d.white_level,
                bit_depth: d.bits_per_sample,
            },
            format!(
                "BlackLevel (mean over the CFA), WhiteLevel and BitsPerSample tags of {} ({})",
                opts.real.display(),
                d.describe()
            ),
        ),
        _ => {
            return Err(Error::config(
                &opts.out,
                format!(
                    "does not exist and a new profile needs its levels: give --black, --white \
                     and --bits together{}",
                    if inputs.dng.is_some() {
                        " (or none of them to take them from the DNG)"
                    } else {
                        " (the real capture is not a DNG, whose tags would give them)"
                    }
                ),
            ));
        }
    };
    let name = opts
        .name
        .clone()
        .or_else(|| {
            inputs.dng.as_ref().and_then(|d| {
                d.unique_camera_model
                    .clone()
                    .or_else(|| match (&d.make, &d.model) {
                        (Some(a), Some(b)) => Some(format!("{a} {b}")),
                        _ => None,
                    })
            })
        })
        .or_else(|| {
            opts.out
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
        })
        .unwrap_or_else(|| "sensor".into());
    let response = inputs.real_response.clone();
    let response_why = if inputs.dng.is_some() {
        "linear: the real capture is a raw DNG (DN linear in exposure)".to_string()
    } else {
        format!(
            "{}: the response the real capture was linearised with",
            response_name(&response)
        )
    };
    Ok(SensorProfile::new_measured(
        name,
        levels,
        response,
        Provenance {
            colour: String::new(),
            noise: "no noise calibration yet (profile created by `hdrsynth calibrate colour`)"
                .into(),
            levels: levels_prov,
            response: format!(
                "defaults chosen by `hdrsynth calibrate colour`, not measured: response {response_why}; \
                 source_response filmic: the default display curve of `hdrsynth generate` \
                 (docs/scene.md); change it if the synthetic frames use another curve"
            ),
            metering: None,
            notes: None,
        },
    ))
}
/// `hdrsynth profile colour-from-matrix`: set the existing profile `out`'s T from a published
/// XYZ→camera matrix (`matrix`: nine numbers, row-major, as published, each divided by
/// `scale`; [`fit::t_from_camera_xyz`]), recording `source` and the numbers as provenance.
pub fn colour_from_matrix(matrix: &str, scale: f64, source: &str, out: &Path) -> Result<Mat3> {
    if source.trim().is_empty() {
        return Err(Error::flag(
            "--source",
            "must say where the matrix comes from",
        ));
    }
    let v = super::parse_floats(matrix, 9, "--matrix")?;
    let cam_xyz: Mat3 = std::array::from_fn(|r| std::array::from_fn(|c| v[r * 3 + c] / scale));
    let t = fit::t_from_camera_xyz(&cam_xyz)?;
    let mut p = SensorProfile::load(out)?;
    p.colour = Some(Colour {
        matrix: t,
        root_polynomial: None,
        use_root_polynomial: false,
    });
    p.provenance.colour = format!(
        "{}; XYZ→camera matrix [{matrix}]/{scale} converted by `hdrsynth profile \
         colour-from-matrix`: T = rownorm(M · sRGB→XYZ(D65)), rows scaled to sum 1 (dcraw's \
         cam_rgb normalisation)",
        source.trim(),
    );
    p.save(out)?;
    Ok(t)
}
