//! The DNG specification's camera colour ("Mapping Camera Color Space to CIE XYZ Space"): the
//! camera-from-XYZ matrix for the white a shot was balanced for, interpolated between
//! ColorMatrix1 and ColorMatrix2 by inverse correlated colour temperature.
//!
//! CM_i = AnalogBalance · CameraCalibration_i · ColorMatrix_i (CameraCalibration only where
//! CameraCalibrationSignature equals ProfileCalibrationSignature, as the specification says;
//! identity otherwise). With two matrices calibrated at T1 < T2 and a white at CCT T, the weight
//! of CM_1 is g = (1/T − 1/T2) / (1/T1 − 1/T2), clamped to [0, 1], and CM = g·CM_1 +
//! (1 − g)·CM_2. AsShotNeutral gives the white in camera coordinates, so T depends on CM: the
//! specification's iteration starts from D50, interpolates CM at the current CCT, takes the xy
//! of CM⁻¹ · neutral and its CCT, and repeats until xy moves less than 1e-13 (at most 100
//! passes; a two-value oscillation ends on the mean of the last two, as the DNG SDK does).
//! AsShotWhiteXY, where given instead, is the white directly.
//!
//! Illuminant temperatures: the CIE standard illuminants at their correlated colour
//! temperatures (A 2856 K, B 4874 K, C 6774 K, D50 5003 K, D55 5503 K, D65 6504 K, D75 7504 K);
//! the other EXIF light sources at the DNG SDK's values. (The SDK rounds A to 2850 K and the
//! D series to 5000/5500/6500/7500 K.) CCT: Robertson's method, `cie::xy_to_cct`.

use super::tags::DngTags;
use crate::error::{Error, Result};
use crate::linalg::{Mat3, mul3, solve3};
use crate::sensor::colour::cie::{xy_to_cct, xyz_to_xy};
use std::path::Path;

/// The starting white of the iteration (the DNG SDK's D50 xy).
const D50_START: [f64; 2] = [0.3457, 0.3585];
const MAX_PASSES: usize = 100;
const TOLERANCE: f64 = 1e-13;

/// The DNG colour of one shot.
#[derive(Clone, Debug, PartialEq)]
pub struct DngColour {
    /// Correlated colour temperature (K) of the white the shot was balanced for.
    pub cct: f64,
    /// That white's chromaticity.
    pub white_xy: [f64; 2],
    /// The two calibration temperatures, lower first, with the weight g of the lower one's
    /// matrix; None with a single ColorMatrix (used as it is).
    pub interpolation: Option<([f64; 2], f64)>,
    /// Camera from XYZ at that white: AnalogBalance · CameraCalibration · ColorMatrix,
    /// interpolated.
    pub camera_from_xyz: Mat3,
}

/// Temperature (K) of an EXIF LightSource code used as a CalibrationIlluminant; None for
/// unknown (0), other (255) and codes that name no light.
pub fn illuminant_temperature(code: u16) -> Option<f64> {
    Some(match code {
        17 | 3 => 2856.0,
        18 => 4874.0,
        19 => 6774.0,
        20 => 5503.0,
        21 => 6504.0,
        22 => 7504.0,
        23 => 5003.0,
        1 | 4 | 9 => 5500.0,
        10 => 6500.0,
        11 => 7500.0,
        12 => 6400.0,
        13 => 5000.0,
        2 | 14 => 4150.0,
        15 => 3450.0,
        16 => 2925.0,
        24 => 3200.0,
        _ => return None,
    })
}

/// The name of an EXIF LightSource code.
pub fn illuminant_name(code: u16) -> &'static str {
    match code {
        0 => "unknown",
        1 => "daylight",
        2 => "fluorescent",
        3 => "tungsten",
        4 => "flash",
        9 => "fine weather",
        10 => "cloudy weather",
        11 => "shade",
        12 => "daylight fluorescent",
        13 => "day white fluorescent",
        14 => "cool white fluorescent",
        15 => "white fluorescent",
        16 => "warm white fluorescent",
        17 => "standard light A",
        18 => "standard light B",
        19 => "standard light C",
        20 => "D55",
        21 => "D65",
        22 => "D75",
        23 => "D50",
        24 => "ISO studio tungsten",
        255 => "other light source",
        _ => "not an EXIF light source",
    }
}

/// The white: AsShotNeutral (camera coordinates) or AsShotWhiteXY.
enum White {
    Neutral([f64; 3]),
    Xy([f64; 2]),
}

/// The DNG colour of the shot `tags` describe. Errors name the file and the tag at fault.
pub fn dng_colour(tags: &DngTags, path: &Path) -> Result<DngColour> {
    let white = match (tags.as_shot_neutral, tags.as_shot_white_xy) {
        (Some(n), _) if n.iter().all(|v| *v > 0.0) => White::Neutral(n),
        (Some(n), _) => {
            return Err(Error::decode(
                path,
                format!("AsShotNeutral {n:?} is not positive"),
            ));
        }
        (None, Some(xy)) if xy[0] > 0.0 && xy[1] > 0.0 && xy[0] + xy[1] < 1.0 => White::Xy(xy),
        (None, Some(xy)) => {
            return Err(Error::decode(
                path,
                format!("AsShotWhiteXY {xy:?} is not a chromaticity"),
            ));
        }
        (None, None) => {
            return Err(missing(
                path,
                "AsShotNeutral (50728) or AsShotWhiteXY (50729)",
            ));
        }
    };
    let (m1, m2) = calibrated_matrices(tags, path)?;
    let Some(Upper { m: m2, temps }) = m2 else {
        let xy = white_xy(&white, &m1, path)?;
        return Ok(DngColour {
            cct: xy_to_cct(xy),
            white_xy: xy,
            interpolation: None,
            camera_from_xyz: m1,
        });
    };
    let at = |xy: [f64; 2]| {
        let g = weight(xy_to_cct(xy), temps);
        lerp(&m1, &m2, g)
    };
    let xy = match white {
        White::Xy(xy) => xy,
        White::Neutral(_) => iterate(|xy| white_xy(&white, &at(xy), path))?,
    };
    let cct = xy_to_cct(xy);
    let g = weight(cct, temps);
    Ok(DngColour {
        cct,
        white_xy: xy,
        interpolation: Some((temps, g)),
        camera_from_xyz: lerp(&m1, &m2, g),
    })
}

/// The fixed point of `next` from D50: xy → the white's xy under the matrix at xy's CCT.
fn iterate(next: impl Fn([f64; 2]) -> Result<[f64; 2]>) -> Result<[f64; 2]> {
    let mut last = D50_START;
    for pass in 0..MAX_PASSES {
        let mut xy = next(last)?;
        if (xy[0] - last[0]).abs() + (xy[1] - last[1]).abs() < TOLERANCE {
            return Ok(xy);
        }
        if pass == MAX_PASSES - 1 {
            xy = [(xy[0] + last[0]) / 2.0, (xy[1] + last[1]) / 2.0];
        }
        last = xy;
    }
    Ok(last)
}

/// Weight of the lower-temperature matrix at CCT `t`.
fn weight(t: f64, [t1, t2]: [f64; 2]) -> f64 {
    ((1.0 / t - 1.0 / t2) / (1.0 / t1 - 1.0 / t2)).clamp(0.0, 1.0)
}

fn lerp(a: &Mat3, b: &Mat3, g: f64) -> Mat3 {
    std::array::from_fn(|i| std::array::from_fn(|j| g * a[i][j] + (1.0 - g) * b[i][j]))
}

/// The white's chromaticity under camera-from-XYZ `m`.
fn white_xy(white: &White, m: &Mat3, path: &Path) -> Result<[f64; 2]> {
    match white {
        White::Xy(xy) => Ok(*xy),
        White::Neutral(n) => solve3(*m, *n).and_then(xyz_to_xy).ok_or_else(|| {
            Error::decode(
                path,
                format!(
                    "AsShotNeutral {n:?} has no chromaticity under the colour matrix {m:?} \
                         (singular, or XYZ summing to ≤ 0)"
                ),
            )
        }),
    }
}

/// The higher-temperature calibration's matrix, with both temperatures (lower first).
struct Upper {
    m: Mat3,
    temps: [f64; 2],
}

/// CM_1 and, where there are two calibrations, CM_2 with the temperatures (lower first; the
/// pair is swapped so). A second matrix whose temperature equals the first's is not needed
/// (the DNG SDK then uses ColorMatrix1 alone; so does this).
fn calibrated_matrices(tags: &DngTags, path: &Path) -> Result<(Mat3, Option<Upper>)> {
    let [cm1, cm2] = tags.color_matrix;
    let cm1 = cm1.ok_or_else(|| missing(path, "ColorMatrix1 (50721)"))?;
    let ab = tags.analog_balance.unwrap_or([1.0; 3]);
    let ab: Mat3 =
        std::array::from_fn(|i| std::array::from_fn(|j| if i == j { ab[i] } else { 0.0 }));
    let use_cc = tags.camera_calibration_signature == tags.profile_calibration_signature;
    let identity: Mat3 = std::array::from_fn(|i| std::array::from_fn(|j| (i == j) as u8 as f64));
    let cm = |k: usize, m: &Mat3| {
        let cc = tags.camera_calibration[k]
            .filter(|_| use_cc)
            .unwrap_or(identity);
        mul3(&mul3(&ab, &cc), m)
    };
    let m1 = cm(0, &cm1);
    let Some(cm2) = cm2 else {
        return Ok((m1, None));
    };
    let temp = |k: usize| -> Result<f64> {
        let name = format!("CalibrationIlluminant{} ({})", k + 1, 50778 + k);
        let code = tags.calibration_illuminant[k].ok_or_else(|| missing(path, &name))?;
        illuminant_temperature(code).ok_or_else(|| {
            Error::unsupported(
                path,
                format!(
                    "{name} is {code} ({}): no colour temperature to interpolate ColorMatrix1 \
                     and ColorMatrix2 by",
                    illuminant_name(code)
                ),
            )
        })
    };
    let (t1, t2) = (temp(0)?, temp(1)?);
    let m2 = cm(1, &cm2);
    Ok(if t1 == t2 {
        (m1, None)
    } else if t1 < t2 {
        (
            m1,
            Some(Upper {
                m: m2,
                temps: [t1, t2],
            }),
        )
    } else {
        (
            m2,
            Some(Upper {
                m: m1,
                temps: [t2, t1],
            }),
        )
    })
}

/// The error for a missing tag.
pub(super) fn missing(path: &Path, tag: &str) -> Error {
    Error::unsupported(path, format!("no {tag} tag"))
}
