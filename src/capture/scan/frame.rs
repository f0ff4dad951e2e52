//! Reading a bracket frame: upright by its EXIF orientation, cut to its [`Region`], and what
//! identifies what was read ([`frame_source`]: a capture that calibrates a profile is never
//! scored).

use super::{BracketFrame, BracketSet, FrameKind, file_name};
use crate::error::{Error, Result};
use crate::io::source::Source;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A frame's pixels as stored, turned upright by its EXIF Orientation (LDR frames; DNG frames
/// are decoded by src/sensor/dng.rs and turned by [`orient`]).
pub fn read_frame_image(frame: &BracketFrame) -> Result<crate::io::Image> {
    orient(crate::io::read_image(&frame.path)?, frame)
}

/// The smallest side of a test set's frame (after its region): the metrics' SSIM needs its
/// 11×11 Gaussian window.
pub const MIN_FRAME_SIDE: usize = 11;

/// The size of `img`, read from `frame` (after its region and any alignment), or a refusal
/// where no test set can be scored on it: smaller than [`MIN_FRAME_SIDE`], naming the file and
/// the region that cut it.
pub fn scorable_size(frame: &BracketFrame, img: &crate::io::Image) -> Result<(usize, usize)> {
    let (w, h) = (img.width, img.height);
    if w < MIN_FRAME_SIDE || h < MIN_FRAME_SIDE {
        return Err(Error::decode(
            &frame.path,
            format!(
                "{w}×{h} pixels{}: a test set's frame needs at least \
                 {MIN_FRAME_SIDE}×{MIN_FRAME_SIDE} (the metrics' SSIM window)",
                frame
                    .region
                    .map_or(String::new(), |r| format!(" in region {r}"))
            ),
        ));
    }
    Ok((w, h))
}

/// `img` (decoded from `frame`) as displayed under the frame's EXIF Orientation, cut to the
/// frame's region: every reader of a bracket frame goes through here.
pub fn orient(img: crate::io::Image, frame: &BracketFrame) -> Result<crate::io::Image> {
    let img = match frame.exif.orientation.unwrap_or(1) {
        1 => img,
        o => img.oriented(o).ok_or_else(|| {
            Error::decode(
                &frame.path,
                format!("EXIF Orientation {o} is not one of 1–8"),
            )
        })?,
    };
    match frame.region {
        Some(r) => r.crop(img, &frame.path),
        None => Ok(img),
    }
}

/// A part of every frame of a folder, in the upright frame: a half, or a rectangle in pixels.
/// Halves split at ⌊w/2⌋ (⌊h/2⌋), so `left` and `right` (`top` and `bottom`) never share a
/// pixel: one capture can calibrate on one half and be scored on the other (docs/your_device.md,
/// "one scene").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Region {
    Left,
    Right,
    Top,
    Bottom,
    Rect {
        x: usize,
        y: usize,
        w: usize,
        h: usize,
    },
}

impl Region {
    /// Pixel bounds [x0, x1) × [y0, y1) in a w × h frame; `None` when the region lies outside
    /// it or is empty.
    pub fn bounds(&self, w: usize, h: usize) -> Option<[usize; 4]> {
        let b = match *self {
            Region::Left => [0, 0, w / 2, h],
            Region::Right => [w / 2, 0, w, h],
            Region::Top => [0, 0, w, h / 2],
            Region::Bottom => [0, h / 2, w, h],
            Region::Rect { x, y, w: rw, h: rh } => [x, y, x.checked_add(rw)?, y.checked_add(rh)?],
        };
        (b[0] < b[2] && b[1] < b[3] && b[2] <= w && b[3] <= h).then_some(b)
    }

    /// The region of `img` (decoded from `path`); an error naming the file when it does not
    /// fit.
    pub fn crop(&self, img: crate::io::Image, path: &Path) -> Result<crate::io::Image> {
        let [x0, y0, x1, y1] = self.bounds(img.width, img.height).ok_or_else(|| {
            Error::decode(
                path,
                format!(
                    "region {self} does not fit the {}×{} frame",
                    img.width, img.height
                ),
            )
        })?;
        Ok(crate::io::Image::from_fn(x1 - x0, y1 - y0, |x, y| {
            img.get(x0 + x, y0 + y)
        }))
    }
}

impl std::fmt::Display for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Region::Left => f.write_str("left"),
            Region::Right => f.write_str("right"),
            Region::Top => f.write_str("top"),
            Region::Bottom => f.write_str("bottom"),
            Region::Rect { x, y, w, h } => write!(f, "{x},{y},{w},{h}"),
        }
    }
}

impl std::str::FromStr for Region {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.trim() {
            "left" => Ok(Region::Left),
            "right" => Ok(Region::Right),
            "top" => Ok(Region::Top),
            "bottom" => Ok(Region::Bottom),
            t => {
                let v: Vec<usize> = t
                    .split(',')
                    .map(|p| p.trim().parse::<usize>())
                    .collect::<std::result::Result<_, _>>()
                    .map_err(|_| region_syntax(s))?;
                match v[..] {
                    [x, y, w, h] if w > 0 && h > 0 => Ok(Region::Rect { x, y, w, h }),
                    _ => Err(region_syntax(s)),
                }
            }
        }
    }
}

/// The [`Source`] of a frame: its file and its decoded pixels hashed, the region's pixels in
/// its upright size. The frame is read and decoded once.
pub fn frame_source(frame: &BracketFrame) -> Result<Source> {
    let bytes = crate::io::guard::read_input(&frame.path).map_err(|e| Error::io(&frame.path, e))?;
    let img = match frame.kind {
        FrameKind::Dng => crate::sensor::dng::read_dng_bytes(&bytes, &frame.path)?.image,
        FrameKind::Ldr => {
            let format = crate::io::Format::from_path(&frame.path)?;
            crate::io::read_image_bytes(&bytes, format, &frame.path)?.0
        }
    };
    let (w, h) = if frame.exif.orientation.unwrap_or(1) >= 5 {
        (img.height, img.width)
    } else {
        (img.width, img.height)
    };
    let pixels = match frame.region {
        None => [0, 0, w, h],
        Some(r) => r.bounds(w, h).ok_or_else(|| {
            Error::decode(
                &frame.path,
                format!("region {r} does not fit the {w}×{h} frame"),
            )
        })?,
    };
    Ok(Source {
        file: file_name(&frame.path),
        sha256: crate::io::sha256_hex(&bytes),
        pixels_sha256: Some(pixels_sha256(&img)),
        pixels,
    })
}

/// SHA-256 of decoded pixels as stored (width, height, then every value as an f32,
/// little-endian): the same for a lossless re-save under another name or format.
fn pixels_sha256(img: &crate::io::Image) -> String {
    use sha2::{Digest, Sha256};
    let mut hash = Sha256::new();
    hash.update((img.width as u64).to_le_bytes());
    hash.update((img.height as u64).to_le_bytes());
    for v in &img.data {
        hash.update(v.to_le_bytes());
    }
    hash.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// The error for a frame of another size than its set's first frame: every reader of a set
/// that needs one size says it alike.
pub fn size_mismatch(
    frame: &Path,
    (fw, fh): (usize, usize),
    first: &Path,
    (w, h): (usize, usize),
) -> Error {
    Error::layout(
        frame,
        format!(
            "{fw}×{fh}, but {} of the same set is {w}×{h}: every frame of a bracket must have \
             one size",
            first.display()
        ),
    )
}

/// The sources of every frame of `set`.
pub fn set_sources(set: &BracketSet) -> Result<Vec<Source>> {
    set.frames.iter().map(frame_source).collect()
}

fn region_syntax(s: &str) -> String {
    format!("'{s}': expected left, right, top, bottom or x,y,w,h in pixels (w, h > 0)")
}

/// Days since 1970-01-01 of a Gregorian date (Howard Hinnant's algorithm).
pub(super) fn days_from_civil(y: i64, m: u32, d: u32) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (i64::from(m) + 9) % 12;
    let doy = (153 * mp + 2) / 5 + i64::from(d) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}
