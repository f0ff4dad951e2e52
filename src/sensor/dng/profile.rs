//! A sensor profile from DNG tags (`hdrsynth calibrate dng`): colour, noise per ISO and levels
//! from the tags of one or more DNGs of one camera model, no pixels read (docs/sensor.md,
//! "Profiles from DNG tags").
//!
//! - Colour: the first file's camera-from-XYZ matrix at its shot's white (`colour`), turned
//!   into the profile's T as `profile colour-from-matrix` does: T = rownorm(CM · sRGB→XYZ(D65)).
//! - Levels: the first file's (`tags::ChannelLevels`).
//! - Noise: each file's NoiseProfile at its ISO. NoiseProfile says σ² = S_c·x_c + O_c with x_c
//!   the channel's raw signal normalised by its own levels, x_c = (DN − B_c) / (W_c − B_c); the
//!   profile's x = (DN − B) / (W − B) uses the profile's single levels. With r_c = (W_c − B_c) /
//!   (W − B): σ²_DN = S_c·(W_c − B_c)·I + O_c·(W_c − B_c)², so in the profile's units
//!   a_c = S_c·r_c and b_c = O_c·r_c² (exact; r_c = 1 where the levels agree).

use super::colour::{DngColour, dng_colour, illuminant_name};
use super::tags::{ChannelLevels, DngTags, RawLayout, read_dng_tags};
use crate::error::{Error, Result};
use crate::linalg::Mat3;
use crate::sensor::colour::fit::t_from_camera_xyz;
use crate::sensor::profile::{Colour, NoiseAtIso, Provenance, Response, SensorProfile};
use std::path::{Path, PathBuf};

/// What `calibrate dng` is asked for.
#[derive(Clone, Debug)]
pub struct DngOptions {
    pub files: Vec<PathBuf>,
    /// Profile to write: an existing one keeps its name, kind, responses and effects and gets
    /// colour, levels, noise and their provenance replaced; a new one is created.
    pub out: PathBuf,
    /// Name of a new profile (default: the camera's name in the DNG).
    pub name: Option<String>,
    /// Read the noise (NoiseProfile and ISO are then needed); false leaves the profile without
    /// noise.
    pub noise: bool,
}

/// One DNG's contribution.
#[derive(Clone, Debug)]
pub struct DngFile {
    pub path: PathBuf,
    pub camera: String,
    pub tags: DngTags,
    pub colour: DngColour,
    /// The profile's T from this file's colour.
    pub t: Mat3,
    pub levels: ChannelLevels,
    /// NoiseProfile per channel R, G, B as (S, O).
    pub noise_profile: Option<[[f64; 2]; 3]>,
}

/// The result of `calibrate dng`: the profile written and the files it came from.
#[derive(Clone, Debug)]
pub struct DngCalibration {
    pub out: PathBuf,
    pub existed: bool,
    pub profile: SensorProfile,
    pub files: Vec<DngFile>,
}

/// Read one DNG's tags and everything derived from them; refuses a file without the tags a
/// profile needs, naming them all.
pub fn read_dng_file(path: &Path, noise: bool) -> Result<DngFile> {
    let tags = read_dng_tags(path)?;
    let lacking = missing_tags(&tags, noise);
    if !lacking.is_empty() {
        let hint = if noise && (tags.noise_profile.is_none() || tags.iso.is_none()) {
            " (`calibrate dng --no-noise` builds a profile without noise)"
        } else {
            ""
        };
        return Err(Error::unsupported(
            path,
            format!(
                "lacks DNG tag(s) a sensor profile needs: {}{hint}",
                lacking.join(", ")
            ),
        ));
    }
    let colour = dng_colour(&tags, path)?;
    let t = t_from_camera_xyz(&colour.camera_from_xyz).map_err(|e| Error::decode(path, e))?;
    Ok(DngFile {
        path: path.to_path_buf(),
        camera: tags.camera().unwrap_or_else(|| "unknown camera".into()),
        levels: tags.channel_levels(path)?,
        noise_profile: if noise {
            tags.noise_per_channel(path)?
        } else {
            None
        },
        colour,
        t,
        tags,
    })
}

/// The tags a profile needs that `tags` lacks, as "Name (code)".
fn missing_tags(tags: &DngTags, noise: bool) -> Vec<&'static str> {
    let mut out = Vec::new();
    if tags.color_matrix[0].is_none() {
        out.push("ColorMatrix1 (50721)");
    }
    if tags.color_matrix[1].is_some() {
        if tags.calibration_illuminant[0].is_none() {
            out.push("CalibrationIlluminant1 (50778)");
        }
        if tags.calibration_illuminant[1].is_none() {
            out.push("CalibrationIlluminant2 (50779)");
        }
    }
    if tags.as_shot_neutral.is_none() && tags.as_shot_white_xy.is_none() {
        out.push("AsShotNeutral (50728)");
    }
    if noise && tags.noise_profile.is_none() {
        out.push("NoiseProfile (51041)");
    }
    if noise && tags.iso.is_none() {
        out.push("ISO (EXIF ISOSpeedRatings/PhotographicSensitivity, 34855; absent or 0)");
    }
    out
}

/// The profile's noise row from a NoiseProfile per channel (S, O) measured against `levels`
/// (the file's), in the units of `profile` levels (the module docs).
pub fn noise_row(
    iso: f64,
    noise_profile: &[[f64; 2]; 3],
    levels: &ChannelLevels,
    profile: &crate::sensor::profile::Levels,
) -> NoiseAtIso {
    let range = profile.white_level - profile.black_level;
    let r: [f64; 3] = std::array::from_fn(|c| (levels.white[c] - levels.black[c]) / range);
    NoiseAtIso {
        iso,
        a: std::array::from_fn(|c| noise_profile[c][0] * r[c]),
        b: std::array::from_fn(|c| noise_profile[c][1] * r[c] * r[c]),
        a_stderr: None,
        b_stderr: None,
    }
}

/// Read `opts.files`, check they are one camera model with distinct ISOs, and write the
/// profile (atomically; validated by `SensorProfile::save`).
pub fn calibrate_dng(opts: &DngOptions) -> Result<DngCalibration> {
    if opts.files.is_empty() {
        return Err(Error::Invalid("calibrate dng: no DNG files given".into()));
    }
    let files = opts
        .files
        .iter()
        .map(|p| read_dng_file(p, opts.noise))
        .collect::<Result<Vec<_>>>()?;
    let first = &files[0];
    if let Some(f) = files.iter().find(|f| f.camera != first.camera) {
        return Err(Error::config(
            &f.path,
            format!(
                "is a \"{}\" but {} is a \"{}\": one profile describes one camera model",
                f.camera,
                first.path.display(),
                first.camera
            ),
        ));
    }
    let noise = if opts.noise {
        noise_rows(&files)?
    } else {
        Vec::new()
    };
    let (mut profile, existed) = SensorProfile::load_or_create(&opts.out, || {
        Ok::<_, Error>(new_profile(
            opts.name.as_deref().unwrap_or(&first.camera),
            first,
        ))
    })?;
    profile.colour = Some(Colour {
        matrix: first.t,
        root_polynomial: None,
        use_root_polynomial: false,
    });
    profile.levels = first.levels.levels.clone();
    profile.noise = noise;
    profile.provenance.colour = colour_provenance(first);
    profile.provenance.levels = levels_provenance(first);
    profile.provenance.noise = if opts.noise {
        noise_provenance(&files)
    } else {
        "not calibrated yet (`calibrate dng --no-noise`)".into()
    };
    profile.save(&opts.out)?;
    Ok(DngCalibration {
        out: opts.out.clone(),
        existed,
        profile,
        files,
    })
}

/// Noise rows in the first file's levels, ascending ISO; one file per ISO.
fn noise_rows(files: &[DngFile]) -> Result<Vec<NoiseAtIso>> {
    let levels = &files[0].levels.levels;
    let mut rows = Vec::new();
    for f in files {
        let (Some(iso), Some(np)) = (f.tags.iso, f.noise_profile) else {
            return Err(Error::unsupported(&f.path, "no ISO or no NoiseProfile"));
        };
        rows.push((noise_row(iso, &np, &f.levels, levels), f.path.as_path()));
    }
    rows.sort_by(|a, b| a.0.iso.total_cmp(&b.0.iso));
    if let Some(w) = rows.windows(2).find(|w| w[0].0.iso == w[1].0.iso) {
        return Err(Error::config(
            w[1].1,
            format!(
                "ISO {}, as {} is: one NoiseProfile per ISO",
                w[0].0.iso,
                w[0].1.display()
            ),
        ));
    }
    Ok(rows.into_iter().map(|(r, _)| r).collect())
}

/// A new profile: measured, levels from the first file, default responses (not in DNG tags).
fn new_profile(name: &str, first: &DngFile) -> SensorProfile {
    SensorProfile::new_measured(
        name,
        first.levels.levels.clone(),
        Response::Srgb,
        Provenance {
            colour: String::new(),
            noise: String::new(),
            levels: String::new(),
            response: "not in DNG tags: defaults, not measured: response = srgb, \
                       source_response = filmic (the scene engine's display curve)"
                .into(),
            metering: None,
            notes: None,
        },
    )
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.display().to_string())
}

fn colour_provenance(f: &DngFile) -> String {
    let tags = &f.tags;
    let c = &f.colour;
    let matrices = match c.interpolation {
        Some(([t1, t2], g)) => {
            let ill =
                |k: usize| illuminant_name(tags.calibration_illuminant[k].unwrap_or(0)).to_string();
            format!(
                "ColorMatrix1 ({}) and ColorMatrix2 ({}) interpolated by inverse CCT between \
                 {t1} K and {t2} K, weight {g:.4} on the {t1} K matrix",
                ill(0),
                ill(1)
            )
        }
        None => "ColorMatrix1 alone".into(),
    };
    let white = match tags.as_shot_neutral {
        Some(n) => format!("AsShotNeutral {n:?}"),
        None => "AsShotWhiteXY".into(),
    };
    let cc = match (
        tags.camera_calibration.iter().any(Option::is_some),
        tags.camera_calibration_signature == tags.profile_calibration_signature,
    ) {
        (false, _) => "",
        (true, true) => " · CameraCalibration",
        (true, false) => " (CameraCalibration ignored: its signature is not the profile's)",
    };
    format!(
        "DNG tags of {} ({}): {matrices}, at {:.0} K (xy {:.4}, {:.4}), the white of {white}; \
         CM = AnalogBalance{cc} · ColorMatrix, the DNG specification's colour model; \
         T = rownorm(CM · sRGB→XYZ(D65)), rows scaled to sum 1 (dcraw's cam_rgb normalisation)",
        file_name(&f.path),
        f.camera,
        c.cct,
        c.white_xy[0],
        c.white_xy[1],
    )
}

fn levels_provenance(f: &DngFile) -> String {
    let tags = &f.tags;
    let l = &f.levels.levels;
    let black = match &tags.black_level {
        Some(v) => format!("BlackLevel {v:?} (repeat {:?})", tags.black_level_repeat),
        None => "no BlackLevel (0, the DNG default)".into(),
    };
    let deltas = if tags.black_level_delta_h.is_empty() && tags.black_level_delta_v.is_empty() {
        ""
    } else {
        " plus the mean BlackLevelDeltaH and DeltaV"
    };
    let white = match &tags.white_level {
        Some(v) => format!("WhiteLevel {v:?}"),
        None => "no WhiteLevel (2^BitsPerSample − 1, the DNG default)".into(),
    };
    let linear = match tags.layout {
        RawLayout::LinearRaw { .. } => {
            "; a LinearRaw DNG: the levels of its stored linear image, not the sensor ADC's"
        }
        RawLayout::Cfa { .. } => "",
    };
    format!(
        "DNG tags of {}: {black} → black {} (the mean over the repeat pattern{deltas}), {white} \
         → white {} (the lowest channel's), {} bits (BitsPerSample {}){linear}",
        file_name(&f.path),
        l.black_level,
        l.white_level,
        l.bit_depth,
        tags.bits_per_sample
    )
}

fn noise_provenance(files: &[DngFile]) -> String {
    let mut s = String::from(
        "DNG NoiseProfile tags (σ² = S·x + O, x the raw signal normalised to [0, 1]), per \
         channel R, G, B, converted to this profile's levels as a = S·r, b = O·r², r = \
         (W_c − B_c)/(W − B) (1 where the levels agree):",
    );
    let mut sorted: Vec<&DngFile> = files.iter().collect();
    sorted.sort_by(|a, b| {
        a.tags
            .iso
            .unwrap_or(0.0)
            .total_cmp(&b.tags.iso.unwrap_or(0.0))
    });
    for f in sorted {
        let np = f.noise_profile.unwrap_or_default();
        s.push_str(&format!(
            " {} ISO {}: S {:?}, O {:?};",
            file_name(&f.path),
            f.tags.iso.unwrap_or(0.0),
            np.map(|p| p[0]),
            np.map(|p| p[1])
        ));
    }
    s.push_str(
        " the raw sensor's noise as the DNG writer modelled it (for a LinearRaw DNG, its \
         linear image's)",
    );
    s
}

impl DngCalibration {
    /// A plain-text summary for the command line.
    pub fn report(&self) -> String {
        let p = &self.profile;
        let parts = if p.noise.is_empty() {
            "colour and levels (no noise)"
        } else {
            "colour, levels and noise"
        };
        let mut s = format!(
            "{} {} ({}): {parts} from the tags of {} DNG(s)\n",
            if self.existed { "updated" } else { "wrote" },
            self.out.display(),
            p.name,
            self.files.len()
        );
        for f in &self.files {
            let iso = f
                .tags
                .iso
                .map(|v| format!("ISO {v}"))
                .unwrap_or("no ISO".into());
            s.push_str(&format!(
                "  {}: {}, {iso}, white at {:.1} K\n",
                f.path.display(),
                f.camera,
                f.colour.cct
            ));
        }
        let l = &p.levels;
        s.push_str(&format!(
            "levels: black {}, white {}, {} bits\nT (real = T · synthetic), from the first file:\n",
            l.black_level, l.white_level, l.bit_depth
        ));
        for row in &self.files[0].t {
            s.push_str(&format!(
                "  [{:>9.5}, {:>9.5}, {:>9.5}]\n",
                row[0], row[1], row[2]
            ));
        }
        for n in &p.noise {
            s.push_str(&format!("noise ISO {}: a {:?}, b {:?}\n", n.iso, n.a, n.b));
        }
        s
    }
}
