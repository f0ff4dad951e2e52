//! The tags of a raw DNG that describe its sensor, read without touching the image data (so a
//! DNG whose image data was pruned, only its IFDs left, reads the same): camera names, the EXIF
//! ISO, the colour tags of the DNG specification's colour model, the levels and NoiseProfile.
//!
//! Where the tags live: the colour tags and names in IFD 0, the levels and NoiseProfile in the
//! main raw IFD (NewSubfileType 0, CFA or LinearRaw; IFD 0 or a SubIFD). Each is looked up in
//! its own IFD first and then in the other, as writers differ. The ISO is TIFF/EP's
//! ISOSpeedRatings in IFD 0 or EXIF's (PhotographicSensitivity) in the EXIF IFD.

use super::tiff::*;
use crate::error::{Error, Result};
use crate::linalg::Mat3;
use crate::sensor::profile::Levels;
use std::path::Path;

/// How the main raw image holds its colour planes.
#[derive(Clone, Debug, PartialEq)]
pub enum RawLayout {
    /// A colour filter array: `pattern[r * dims[1] + c]` is the colour plane at row r, column c
    /// of the repeat tile (`dims` = CFARepeatPatternDim: rows, columns).
    Cfa { dims: [usize; 2], pattern: Vec<u8> },
    /// LinearRaw: every pixel holds all colour planes, one sample each.
    LinearRaw { samples: usize },
}

/// The sensor-describing tags of a DNG, as stored (no defaults filled in except where noted).
#[derive(Clone, Debug, PartialEq)]
pub struct DngTags {
    pub make: Option<String>,
    pub model: Option<String>,
    pub unique_camera_model: Option<String>,
    /// ISO (EXIF ISOSpeedRatings/PhotographicSensitivity; where that says 65535, "higher",
    /// RecommendedExposureIndex or ISOSpeed). None when absent or 0 (not recorded).
    pub iso: Option<f64>,
    pub layout: RawLayout,
    /// Colour (0 = R, 1 = G, 2 = B, …) of each colour plane: CFAPlaneColor for a CFA (default
    /// R, G, B), the sample order for LinearRaw.
    pub plane_colours: Vec<u8>,
    pub bits_per_sample: u32,
    /// ColorMatrix1/2: XYZ → reference camera, row-major.
    pub color_matrix: [Option<Mat3>; 2],
    /// CalibrationIlluminant1/2: EXIF LightSource codes.
    pub calibration_illuminant: [Option<u16>; 2],
    pub camera_calibration: [Option<Mat3>; 2],
    pub camera_calibration_signature: Option<String>,
    pub profile_calibration_signature: Option<String>,
    pub analog_balance: Option<[f64; 3]>,
    /// AsShotNeutral: the camera-RGB coordinates of the white the camera was balanced for.
    pub as_shot_neutral: Option<[f64; 3]>,
    /// AsShotWhiteXY: the same white as a chromaticity (an alternative to AsShotNeutral).
    pub as_shot_white_xy: Option<[f64; 2]>,
    /// BlackLevel: over the BlackLevelRepeatDim tile row-major, samples innermost.
    pub black_level: Option<Vec<f64>>,
    /// BlackLevelRepeatDim (rows, columns); default 1 × 1.
    pub black_level_repeat: [usize; 2],
    pub black_level_delta_h: Vec<f64>,
    pub black_level_delta_v: Vec<f64>,
    /// WhiteLevel, one per sample (or one for all).
    pub white_level: Option<Vec<f64>>,
    /// NoiseProfile: (S, O) pairs, one for all planes or one per plane.
    pub noise_profile: Option<Vec<f64>>,
}

/// Black and white level per colour channel (R, G, B) in DN, and the profile's single levels.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelLevels {
    pub black: [f64; 3],
    pub white: [f64; 3],
    /// The profile's levels: black the mean over the photosites of the repeat pattern (plus
    /// the mean BlackLevelDeltaH and DeltaV), white the lowest channel's, bits enough to hold
    /// it (at least BitsPerSample).
    pub levels: Levels,
}

/// Read the sensor-describing tags of a DNG (the image data is not read).
pub fn read_dng_tags(path: &Path) -> Result<DngTags> {
    let bytes = crate::io::guard::read_file(path)?;
    read_dng_tags_bytes(&bytes, path)
}

/// [`read_dng_tags`] of a file held in memory (`path` names it in errors).
pub fn read_dng_tags_bytes(bytes: &[u8], path: &Path) -> Result<DngTags> {
    let tiff = Tiff::parse(bytes, path)?;
    let (ifd, photometric) = tiff.main_raw_ifd()?;
    let mut tags = DngTags::from_raw_ifd(&tiff, &ifd, photometric)?;
    tags.iso = read_iso(&tiff)?;
    Ok(tags)
}

impl DngTags {
    /// Every tag but the ISO, from the main raw IFD `ifd` and IFD 0.
    pub(super) fn from_raw_ifd(t: &Tiff, ifd: &Ifd, photometric: u32) -> Result<DngTags> {
        let path = t.path;
        let ifd0 = &t.ifd0;
        let (layout, plane_colours) = read_layout(t, ifd, photometric)?;
        let text0 =
            |tag| -> Result<Option<String>> { Ok(t.text(ifd0, tag)?.or(t.text(ifd, tag)?)) };
        let nums0 = |tag| -> Result<Option<Vec<f64>>> { first_of(t, [ifd0, ifd], tag) };
        let nums_raw = |tag| -> Result<Option<Vec<f64>>> { first_of(t, [ifd, ifd0], tag) };
        let matrix = |tag: u16, name: &str| -> Result<Option<Mat3>> {
            Ok(fixed::<9>(path, nums0(tag)?, name)?.map(to_mat3))
        };
        let illuminant = |tag| -> Result<Option<u16>> {
            Ok(nums0(tag)?.and_then(|v| v.first().map(|x| x.clamp(0.0, 65535.0) as u16)))
        };
        let bits = nums_raw(TAG_BITS)?
            .and_then(|v| v.first().copied())
            .unwrap_or(1.0);
        let repeat = nums_raw(TAG_BLACK_REPEAT)?.unwrap_or(vec![1.0, 1.0]);
        let black_level_repeat = match repeat.as_slice() {
            [r, c] if (1.0..=16.0).contains(r) && (1.0..=16.0).contains(c) => {
                [*r as usize, *c as usize]
            }
            _ => {
                return Err(Error::decode(
                    path,
                    format!("BlackLevelRepeatDim {repeat:?}"),
                ));
            }
        };
        let tags = DngTags {
            make: text0(TAG_MAKE)?,
            model: text0(TAG_MODEL)?,
            unique_camera_model: text0(TAG_UNIQUE_MODEL)?,
            iso: None,
            layout,
            plane_colours,
            bits_per_sample: bits.clamp(0.0, 64.0) as u32,
            color_matrix: [
                matrix(TAG_COLOR_MATRIX1, "ColorMatrix1")?,
                matrix(TAG_COLOR_MATRIX2, "ColorMatrix2")?,
            ],
            calibration_illuminant: [
                illuminant(TAG_CAL_ILLUMINANT1)?,
                illuminant(TAG_CAL_ILLUMINANT2)?,
            ],
            camera_calibration: [
                matrix(TAG_CAMERA_CALIBRATION1, "CameraCalibration1")?,
                matrix(TAG_CAMERA_CALIBRATION2, "CameraCalibration2")?,
            ],
            camera_calibration_signature: text0(TAG_CAMERA_CAL_SIGNATURE)?,
            profile_calibration_signature: text0(TAG_PROFILE_CAL_SIGNATURE)?,
            analog_balance: fixed::<3>(path, nums0(TAG_ANALOG_BALANCE)?, "AnalogBalance")?,
            as_shot_neutral: fixed::<3>(path, nums0(TAG_AS_SHOT_NEUTRAL)?, "AsShotNeutral")?,
            as_shot_white_xy: fixed::<2>(path, nums0(TAG_AS_SHOT_WHITE_XY)?, "AsShotWhiteXY")?,
            black_level: nums_raw(TAG_BLACK)?,
            black_level_repeat,
            black_level_delta_h: nums_raw(TAG_BLACK_DELTA_H)?.unwrap_or_default(),
            black_level_delta_v: nums_raw(TAG_BLACK_DELTA_V)?.unwrap_or_default(),
            white_level: nums_raw(TAG_WHITE)?,
            noise_profile: nums_raw(TAG_NOISE_PROFILE)?,
        };
        tags.check(path)?;
        Ok(tags)
    }

    /// Values that would make later arithmetic meaningless: non-finite numbers, level counts
    /// that do not fit the layout.
    fn check(&self, path: &Path) -> Result<()> {
        let finite = |name: &str, v: &[f64]| {
            if v.iter().all(|x| x.is_finite()) {
                Ok(())
            } else {
                Err(Error::decode(
                    path,
                    format!("{name} holds a non-finite value: {v:?}"),
                ))
            }
        };
        for (name, m) in [
            ("ColorMatrix1", self.color_matrix[0]),
            ("ColorMatrix2", self.color_matrix[1]),
            ("CameraCalibration1", self.camera_calibration[0]),
            ("CameraCalibration2", self.camera_calibration[1]),
        ] {
            if let Some(m) = m {
                finite(name, m.as_flattened())?;
            }
        }
        finite("AnalogBalance", &self.analog_balance.unwrap_or_default())?;
        finite("AsShotNeutral", &self.as_shot_neutral.unwrap_or_default())?;
        finite("AsShotWhiteXY", &self.as_shot_white_xy.unwrap_or_default())?;
        finite(
            "BlackLevel",
            self.black_level.as_deref().unwrap_or_default(),
        )?;
        finite("BlackLevelDeltaH", &self.black_level_delta_h)?;
        finite("BlackLevelDeltaV", &self.black_level_delta_v)?;
        finite(
            "WhiteLevel",
            self.white_level.as_deref().unwrap_or_default(),
        )?;
        finite(
            "NoiseProfile",
            self.noise_profile.as_deref().unwrap_or_default(),
        )?;
        let [r, c] = self.black_level_repeat;
        let want = r * c * self.samples();
        match &self.black_level {
            Some(b) if b.len() != 1 && b.len() != want => Err(Error::decode(
                path,
                format!(
                    "BlackLevel has {} values; BlackLevelRepeatDim {r}×{c} with {} sample(s) \
                     per pixel needs {want}",
                    b.len(),
                    self.samples()
                ),
            )),
            _ => Ok(()),
        }
    }

    /// Samples per pixel of the raw image: 1 for a CFA.
    pub fn samples(&self) -> usize {
        match self.layout {
            RawLayout::Cfa { .. } => 1,
            RawLayout::LinearRaw { samples } => samples,
        }
    }

    /// The camera as the DNG names it: UniqueCameraModel, else "Make Model".
    pub fn camera(&self) -> Option<String> {
        self.unique_camera_model
            .clone()
            .or_else(|| match (&self.make, &self.model) {
                (Some(a), Some(b)) => Some(format!("{a} {b}")),
                (a, b) => a.clone().or(b.clone()),
            })
    }

    /// BlackLevel of sample `s` at row r, column c of the image (BlackLevelRepeatDim tiled),
    /// before the deltas; 0 where the tag is absent (the DNG default).
    pub fn black_at(&self, r: usize, c: usize, s: usize) -> f64 {
        let Some(b) = &self.black_level else {
            return 0.0;
        };
        if b.len() == 1 {
            return b[0];
        }
        let [rr, rc] = self.black_level_repeat;
        b[((r % rr) * rc + c % rc) * self.samples() + s]
    }

    /// The colour planes as R, G, B: the channel of each plane, checked to be one plane per
    /// channel (an error for other colour models, e.g. CMY or four-colour CFAs).
    pub fn rgb_planes(&self, path: &Path) -> Result<[usize; 3]> {
        let p = &self.plane_colours;
        let mut seen = [false; 3];
        for &c in p {
            if let Some(s) = seen.get_mut(c as usize) {
                *s = true;
            }
        }
        if p.len() != 3 || seen != [true; 3] {
            return Err(Error::unsupported(
                path,
                format!("colour planes {p:?} are not one red, one green and one blue plane"),
            ));
        }
        Ok([p[0] as usize, p[1] as usize, p[2] as usize])
    }

    /// Black and white level per channel and the profile's levels.
    pub fn channel_levels(&self, path: &Path) -> Result<ChannelLevels> {
        let planes = self.rgb_planes(path)?;
        let mean = |v: &[f64]| {
            if v.is_empty() {
                0.0
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        let delta = mean(&self.black_level_delta_h) + mean(&self.black_level_delta_v);
        let [rr, rc] = self.black_level_repeat;
        let (mut per, mut all) = ([(); 3].map(|_| Vec::new()), Vec::new());
        match &self.layout {
            RawLayout::Cfa { dims, pattern } => {
                // One period of both the CFA and the black-level tile.
                for r in 0..lcm(dims[0], rr) {
                    for c in 0..lcm(dims[1], rc) {
                        let plane = pattern[(r % dims[0]) * dims[1] + c % dims[1]] as usize;
                        let b = self.black_at(r, c, 0);
                        per[planes[plane]].push(b);
                        all.push(b);
                    }
                }
            }
            RawLayout::LinearRaw { .. } => {
                for r in 0..rr {
                    for c in 0..rc {
                        for (s, &ch) in planes.iter().enumerate() {
                            per[ch].push(self.black_at(r, c, s));
                            all.push(self.black_at(r, c, s));
                        }
                    }
                }
            }
        }
        let black: [f64; 3] = std::array::from_fn(|ch| mean(&per[ch]) + delta);
        let white = self.channel_whites(path, planes)?;
        self.levels_from(path, black, white, mean(&all) + delta)
    }

    /// WhiteLevel per channel; absent: 2^BitsPerSample − 1 (the DNG default).
    fn channel_whites(&self, path: &Path, planes: [usize; 3]) -> Result<[f64; 3]> {
        let default = (2f64.powi(self.bits_per_sample.min(32) as i32) - 1.0).max(1.0);
        let w = self.white_level.clone().unwrap_or(vec![default]);
        let mut white = [w[0]; 3];
        if w.len() != 1 {
            if w.len() != self.samples() || self.samples() != 3 {
                return Err(Error::decode(
                    path,
                    format!(
                        "WhiteLevel has {} values for {} sample(s)",
                        w.len(),
                        self.samples()
                    ),
                ));
            }
            for (s, &ch) in planes.iter().enumerate() {
                white[ch] = w[s];
            }
        }
        Ok(white)
    }

    fn levels_from(
        &self,
        path: &Path,
        black: [f64; 3],
        white: [f64; 3],
        black_mean: f64,
    ) -> Result<ChannelLevels> {
        let white_min = white.iter().copied().fold(f64::INFINITY, f64::min);
        if (0..3).any(|c| !(black[c] >= 0.0 && black[c] < white[c])) || black_mean >= white_min {
            return Err(Error::decode(
                path,
                format!("black levels {black:?} are not below the white levels {white:?}"),
            ));
        }
        // Bits to hold the white level: 2^bits − 1 ≥ white.
        let need = (white_min + 1.0).log2().ceil() as u32;
        let bit_depth = self.bits_per_sample.max(need);
        if bit_depth > 16 {
            return Err(Error::unsupported(
                path,
                format!("white level {white_min} needs {bit_depth} bits; profiles hold ≤ 16"),
            ));
        }
        Ok(ChannelLevels {
            black,
            white,
            levels: Levels {
                black_level: black_mean,
                white_level: white_min,
                bit_depth,
            },
        })
    }

    /// NoiseProfile as (S, O) per channel R, G, B: σ² = S·x + O, x the channel's signal
    /// normalised to [0, 1] ((DN − black) / (white − black) after any linearisation). One pair
    /// applies to every plane; otherwise plane p's pair goes to the channel of plane p.
    pub fn noise_per_channel(&self, path: &Path) -> Result<Option<[[f64; 2]; 3]>> {
        let Some(v) = &self.noise_profile else {
            return Ok(None);
        };
        let planes = self.rgb_planes(path)?;
        let mut out = [[0.0; 2]; 3];
        match v.len() {
            2 => out = [[v[0], v[1]]; 3],
            6 => {
                for (p, &ch) in planes.iter().enumerate() {
                    out[ch] = [v[2 * p], v[2 * p + 1]];
                }
            }
            n => {
                return Err(Error::decode(
                    path,
                    format!("NoiseProfile has {n} values: 2, or 2 per colour plane (6), expected"),
                ));
            }
        }
        // The DNG SDK's rule (dng_noise_function: scale positive, offset non-negative), and a
        // noise under the whole range at white: beyond it the tag is damaged, not a sensor.
        for (c, [s, o]) in out.iter().enumerate() {
            let ok = s.is_finite() && o.is_finite() && *s > 0.0 && *o >= 0.0 && s + o < 1.0;
            if !ok {
                return Err(Error::decode(
                    path,
                    format!(
                        "NoiseProfile (51041) of channel {}: S = {s:e}, O = {o:e}: σ² = S·x + O \
                         needs S > 0, O ≥ 0 and S + O < 1 (a noise below the whole range at \
                         white); the tag is damaged (or give --no-noise)",
                        ["R", "G", "B"][c]
                    ),
                ));
            }
        }
        Ok(Some(out))
    }
}

fn lcm(a: usize, b: usize) -> usize {
    let gcd = |mut a: usize, mut b: usize| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    a / gcd(a, b).max(1) * b
}

fn to_mat3(v: [f64; 9]) -> Mat3 {
    std::array::from_fn(|i| std::array::from_fn(|j| v[3 * i + j]))
}

/// The values of `tag` in the first of `ifds` that has it.
fn first_of(t: &Tiff, ifds: [&Ifd; 2], tag: u16) -> Result<Option<Vec<f64>>> {
    for ifd in ifds {
        if let Some(v) = t.floats(ifd, tag)? {
            return Ok(Some(v));
        }
    }
    Ok(None)
}

/// Exactly N values, or an error naming the tag.
fn fixed<const N: usize>(path: &Path, v: Option<Vec<f64>>, name: &str) -> Result<Option<[f64; N]>> {
    match v {
        None => Ok(None),
        Some(v) => v.as_slice().try_into().map(Some).map_err(|_| {
            Error::unsupported(
                path,
                format!(
                    "{name} has {} values; {N} expected (a 3-colour camera)",
                    v.len()
                ),
            )
        }),
    }
}

/// The CFA pattern or LinearRaw sample count, and the colour of each plane.
fn read_layout(t: &Tiff, ifd: &Ifd, photometric: u32) -> Result<(RawLayout, Vec<u8>)> {
    let path = t.path;
    if photometric == PHOTOMETRIC_LINEAR_RAW {
        let samples = t.uint(ifd, TAG_SAMPLES)?.unwrap_or(1).min(16) as usize;
        let colours = (0..samples as u8).collect();
        return Ok((RawLayout::LinearRaw { samples }, colours));
    }
    let dim = t.uints(ifd, TAG_CFA_REPEAT)?.unwrap_or(vec![2, 2]);
    let pattern = t
        .bytes_of(ifd, TAG_CFA_PATTERN)?
        .ok_or_else(|| Error::decode(path, "CFA raw image without a CFAPattern tag (33422)"))?;
    let plane_colours = t
        .bytes_of(ifd, TAG_CFA_PLANE_COLOR)?
        .unwrap_or(vec![0, 1, 2]);
    let dims = match dim.as_slice() {
        [r, c] if (1..=16).contains(r) && (1..=16).contains(c) => [*r as usize, *c as usize],
        _ => return Err(Error::decode(path, format!("CFARepeatPatternDim {dim:?}"))),
    };
    if pattern.len() != dims[0] * dims[1]
        || pattern.iter().any(|&p| p as usize >= plane_colours.len())
    {
        return Err(Error::decode(
            path,
            format!(
                "CFAPattern {pattern:?} does not fit CFARepeatPatternDim {dim:?} and the \
                 {} colour planes of CFAPlaneColor",
                plane_colours.len()
            ),
        ));
    }
    Ok((RawLayout::Cfa { dims, pattern }, plane_colours))
}

/// The ISO: TIFF/EP's ISOSpeedRatings in IFD 0, else EXIF's. 65535 means "65535 or higher" in
/// EXIF 2.3; RecommendedExposureIndex or ISOSpeed then holds the value. 0 means not recorded.
fn read_iso(t: &Tiff) -> Result<Option<f64>> {
    let exif = t.exif_ifd()?;
    let mut ifds = vec![&t.ifd0];
    ifds.extend(exif.as_ref());
    for ifd in ifds {
        let Some(v) = t.floats(ifd, TAG_ISO)? else {
            continue;
        };
        let iso = v[0];
        if iso == 65535.0 {
            for tag in [TAG_RECOMMENDED_EXPOSURE_INDEX, TAG_ISO_SPEED] {
                if let Some(x) = t.floats(ifd, tag)?.and_then(|x| x.first().copied()) {
                    return Ok((x > 0.0).then_some(x));
                }
            }
        }
        return Ok((iso > 0.0 && iso.is_finite()).then_some(iso));
    }
    Ok(None)
}
