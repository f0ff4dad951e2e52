//! Radiance maps as a test set reads them: the files of a folder, linear Rec. 709 RGB.

use crate::error::{Error, Result};
use crate::io::{Image, read_image, resize};
use crate::linalg::{Mat3, inverse3, mul3};
use crate::sensor::colour::cie::{bradford, xy_to_xyz};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The radiance files of `input`: the file itself, or every .exr/.hdr directly in the folder,
/// sorted by name.
pub fn radiance_files(input: &Path) -> Result<Vec<PathBuf>> {
    let is_hdr = |p: &Path| {
        matches!(
            p.extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase)
                .as_deref(),
            Some("exr" | "hdr" | "pic")
        )
    };
    if input.is_file() {
        return if is_hdr(input) {
            Ok(vec![input.to_path_buf()])
        } else {
            Err(Error::unsupported(
                input,
                "radiance must be linear HDR (.exr or .hdr)",
            ))
        };
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(input)
        .map_err(|e| Error::io(input, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && is_hdr(p))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(Error::layout(
            input,
            "holds no radiance maps (.exr or .hdr files)",
        ));
    }
    Ok(files)
}

/// Read a radiance map as linear Rec. 709 RGB (negatives clamped to 0), resized if asked.
/// Returns a note when the primaries were converted.
pub fn load_radiance(
    path: &Path,
    resize_to: Option<(usize, usize)>,
) -> Result<(Image, Option<String>)> {
    let mut img = read_image(path)?;
    let mut note = None;
    if let Some(m) = to_rec709_matrix(path)? {
        img.data.par_chunks_exact_mut(3).for_each(|p| {
            let v = [p[0], p[1], p[2]];
            for (o, row) in p.iter_mut().zip(&m) {
                *o = row[0] * v[0] + row[1] * v[1] + row[2] * v[2];
            }
        });
        note = Some(format!(
            "{}: converted from the file's chromaticities to linear Rec. 709 (Bradford to D65)",
            path.display()
        ));
    }
    img.data.par_iter_mut().for_each(|v| *v = v.max(0.0));
    if let Some((w, h)) = resize_to
        && (w, h) != (img.width, img.height)
    {
        img = resize(&img, w, h);
    }
    Ok((img, note))
}

/// Rec. 709 primaries and D65 white, as (x, y): red, green, blue, white.
const REC709: [[f64; 2]; 4] = [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06], [0.3127, 0.3290]];

/// RGB → XYZ of a set of primaries (columns scaled so RGB (1,1,1) is the white at Y = 1).
fn rgb_to_xyz(c: [[f64; 2]; 4]) -> Option<Mat3> {
    let cols = [xy_to_xyz(c[0]), xy_to_xyz(c[1]), xy_to_xyz(c[2])];
    let p: Mat3 = std::array::from_fn(|i| std::array::from_fn(|j| cols[j][i]));
    let w = xy_to_xyz(c[3]);
    let inv = inverse3(&p)?;
    let s: [f64; 3] = std::array::from_fn(|i| (0..3).map(|k| inv[i][k] * w[k]).sum());
    Some(std::array::from_fn(|i| {
        std::array::from_fn(|j| p[i][j] * s[j])
    }))
}

/// The file's RGB → linear Rec. 709 RGB (Bradford adaptation of its white to D65), or None
/// when the file has no chromaticities attribute (OpenEXR's default is Rec. 709) or already
/// has Rec. 709 / D65 ones, or is not an EXR (Radiance .hdr: Rec. 709 assumed).
pub fn to_rec709_matrix(path: &Path) -> Result<Option<[[f32; 3]; 3]>> {
    if crate::io::Format::from_path(path)? != crate::io::Format::Exr {
        return Ok(None);
    }
    let file = crate::io::guard::open_input(path).map_err(|e| Error::io(path, e))?;
    let mut reader = std::io::BufReader::new(file);
    // Unvalidated header read, as the image reader does (it accepts subsampled chroma).
    let meta = exr::meta::MetaData::read_from_buffered(&mut reader, false)
        .map_err(|e| Error::decode(path, format!("EXR header: {e}")))?;
    let Some(ch) = meta
        .headers
        .first()
        .and_then(|h| h.shared_attributes.chromaticities)
    else {
        return Ok(None);
    };
    let c = [ch.red, ch.green, ch.blue, ch.white].map(|v| [v.x() as f64, v.y() as f64]);
    if c.iter()
        .flatten()
        .zip(REC709.iter().flatten())
        .all(|(a, b)| (a - b).abs() < 1e-4)
    {
        return Ok(None);
    }
    let bad = || Error::unsupported(path, format!("degenerate chromaticities {c:?}"));
    let src = rgb_to_xyz(c).ok_or_else(bad)?;
    let dst_inv = inverse3(&rgb_to_xyz(REC709).expect("Rec. 709 is well formed"))
        .expect("Rec. 709 is invertible");
    let adapt = bradford(xy_to_xyz(c[3]), xy_to_xyz(REC709[3])).ok_or_else(bad)?;
    let m = mul3(&dst_inv, &mul3(&adapt, &src));
    Ok(Some(m.map(|r| r.map(|v| v as f32))))
}
