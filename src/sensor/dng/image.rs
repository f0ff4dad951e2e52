//! The raw image of an uncompressed CFA DNG: decoding, normalising, demosaicing (what the
//! module docs of `dng` describe).
#![allow(clippy::needless_range_loop)]

use super::tags::DngTags;
use super::tiff::*;
use crate::error::{Error, Result};
use crate::io::Image;
use std::path::Path;

/// What the DNG says about itself.
#[derive(Clone, Debug, PartialEq)]
pub struct DngInfo {
    pub make: Option<String>,
    pub model: Option<String>,
    pub unique_camera_model: Option<String>,
    /// Size of the returned image (after ActiveArea and DefaultCrop).
    pub width: usize,
    pub height: usize,
    /// Size of the stored raw image.
    pub raw_width: usize,
    pub raw_height: usize,
    pub bits_per_sample: u32,
    pub compression: u16,
    /// Colour (0 = R, 1 = G, 2 = B) of the CFA at row r, column c of the active area: `[r][c]`.
    pub cfa: [[u8; 2]; 2],
    /// Black level per CFA position (`BlackLevelRepeatDim` expanded to 2 × 2) before the deltas.
    pub black_level: [[f64; 2]; 2],
    pub white_level: f64,
    /// ActiveArea: top, left, bottom, right.
    pub active_area: [usize; 4],
    /// DefaultCrop origin (x, y) and size (w, h) within the active area.
    pub default_crop: [usize; 4],
    /// ColorMatrix1/2 (XYZ → camera), row-major 3 × 3, and their calibration illuminants
    /// (EXIF LightSource codes, e.g. 17 = Standard Light A, 21 = D65).
    pub color_matrix1: Option<[[f64; 3]; 3]>,
    pub color_matrix2: Option<[[f64; 3]; 3]>,
    pub calibration_illuminant1: Option<u16>,
    pub calibration_illuminant2: Option<u16>,
    /// AsShotNeutral: the camera-RGB coordinates of the white the camera was balanced for.
    pub as_shot_neutral: Option<[f64; 3]>,
}

impl DngInfo {
    /// The CFA pattern as letters in reading order, e.g. "RGGB".
    pub fn cfa_string(&self) -> String {
        self.cfa
            .iter()
            .flatten()
            .map(|&c| ['R', 'G', 'B'][c as usize])
            .collect()
    }

    /// One number for the black level: the mean over the CFA positions.
    pub fn black_level_mean(&self) -> f64 {
        self.black_level.iter().flatten().sum::<f64>() / 4.0
    }

    /// A one-line description for provenance.
    pub fn describe(&self) -> String {
        let camera = self
            .unique_camera_model
            .clone()
            .or_else(|| match (&self.make, &self.model) {
                (Some(a), Some(b)) => Some(format!("{a} {b}")),
                (a, b) => a.clone().or(b.clone()),
            })
            .unwrap_or_else(|| "unknown camera".into());
        format!(
            "{camera}, {}×{} ({}-bit, {}, black {}, white {})",
            self.width,
            self.height,
            self.bits_per_sample,
            self.cfa_string(),
            fmt_num(self.black_level_mean()),
            fmt_num(self.white_level)
        )
    }
}

fn fmt_num(v: f64) -> String {
    if v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v}")
    }
}

/// The normalised CFA mosaic of the active area: one value per photosite.
#[derive(Clone, Debug, PartialEq)]
pub struct Mosaic {
    pub width: usize,
    pub height: usize,
    /// Row-major, (DN − black) / (white − black).
    pub data: Vec<f32>,
    /// Colour at (row % 2, col % 2).
    pub cfa: [[u8; 2]; 2],
}

/// A decoded DNG: linear camera RGB (not white balanced) and the tags.
#[derive(Clone, Debug)]
pub struct Dng {
    pub image: Image,
    pub info: DngInfo,
}

/// Read a DNG, demosaic bilinearly, crop to the DefaultCrop.
pub fn read_dng(path: &Path) -> Result<Dng> {
    let bytes = crate::io::guard::read_file(path)?;
    read_dng_bytes(&bytes, path)
}

/// [`read_dng`] of a file held in memory (`path` names it in errors): the same code path.
pub fn read_dng_bytes(bytes: &[u8], path: &Path) -> Result<Dng> {
    let (mosaic, info) = mosaic_from_bytes(bytes, path)?;
    let full = demosaic_bilinear(&mosaic);
    let [cx, cy, cw, ch] = info.default_crop;
    let image = if [cx, cy, cw, ch] == [0, 0, full.width, full.height] {
        full
    } else {
        Image::from_fn(cw, ch, |x, y| full.get(cx + x, cy + y))
    };
    Ok(Dng { image, info })
}

/// The tags only (the pixels are not decoded).
pub fn read_dng_info(path: &Path) -> Result<DngInfo> {
    let bytes = crate::io::guard::read_file(path)?;
    let tiff = Tiff::parse(&bytes, path)?;
    let ifd = tiff.raw_ifd()?;
    info_from(&tiff, &ifd)
}

/// Read the active area's normalised mosaic (before demosaicing and the DefaultCrop).
pub fn read_dng_mosaic(path: &Path) -> Result<(Mosaic, DngInfo)> {
    let bytes = crate::io::guard::read_file(path)?;
    mosaic_from_bytes(&bytes, path)
}

fn mosaic_from_bytes(bytes: &[u8], path: &Path) -> Result<(Mosaic, DngInfo)> {
    let tiff = Tiff::parse(bytes, path)?;
    let ifd = tiff.raw_ifd()?;
    let info = info_from(&tiff, &ifd)?;
    // Before the raw buffer is allocated (decompression bombs); the demosaiced image is the
    // largest buffer this reader makes.
    crate::io::limits::check(path, "DNG", info.raw_width as u64, info.raw_height as u64)?;
    let raw = decode_samples(&tiff, &ifd, &info)?;
    let lin = tiff
        .uints(&ifd, TAG_LINEARIZATION)?
        .filter(|t| !t.is_empty());
    let dh = tiff.floats(&ifd, TAG_BLACK_DELTA_H)?.unwrap_or_default();
    let dv = tiff.floats(&ifd, TAG_BLACK_DELTA_V)?.unwrap_or_default();
    let [top, left, bottom, right] = info.active_area;
    let (w, h) = (right - left, bottom - top);
    if (!dh.is_empty() && dh.len() != w) || (!dv.is_empty() && dv.len() != h) {
        return Err(Error::unsupported(
            path,
            "BlackLevelDeltaH/V do not match the ActiveArea size",
        ));
    }
    let white = info.white_level;
    let mut data = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut v = raw[(top + y) * info.raw_width + left + x] as usize;
            if let Some(t) = &lin {
                v = t[v.min(t.len() - 1)] as usize;
            }
            let mut black = info.black_level[y % 2][x % 2];
            if !dh.is_empty() {
                black += dh[x];
            }
            if !dv.is_empty() {
                black += dv[y];
            }
            data[y * w + x] = ((v as f64 - black) / (white - black)) as f32;
        }
    }
    Ok((
        Mosaic {
            width: w,
            height: h,
            data,
            cfa: info.cfa,
        },
        info,
    ))
}

/// Bilinear demosaic of a 2 × 2 Bayer mosaic: each missing colour is the mean of the same-colour
/// photosites in the 3 × 3 neighbourhood (for a Bayer CFA this is bilinear interpolation: two or
/// four neighbours), using whichever exist at the borders.
pub fn demosaic_bilinear(m: &Mosaic) -> Image {
    let (w, h) = (m.width, m.height);
    Image::from_fn(w, h, |x, y| {
        let own = m.cfa[y % 2][x % 2] as usize;
        let mut sum = [0.0f32; 3];
        let mut n = [0u32; 3];
        for yy in y.saturating_sub(1)..(y + 2).min(h) {
            for xx in x.saturating_sub(1)..(x + 2).min(w) {
                let c = m.cfa[yy % 2][xx % 2] as usize;
                if c != own {
                    sum[c] += m.data[yy * w + xx];
                    n[c] += 1;
                }
            }
        }
        std::array::from_fn(|c| {
            if c == own {
                m.data[y * w + x]
            } else if n[c] > 0 {
                sum[c] / n[c] as f32
            } else {
                0.0
            }
        })
    })
}

/// One strip or tile of the raw image: its origin, size, and where its bytes lie.
struct Chunk {
    x0: usize,
    y0: usize,
    width: usize,
    rows: usize,
    offset: usize,
    /// The stored byte count (0: not given).
    len: usize,
}

/// The raw samples, row-major, raw_width × raw_height.
fn decode_samples(t: &Tiff, ifd: &Ifd, info: &DngInfo) -> Result<Vec<u16>> {
    let (w, h, bits) = (
        info.raw_width,
        info.raw_height,
        info.bits_per_sample as usize,
    );
    let mut out = vec![0u16; w * h];
    for c in chunks(t, ifd, w, h)? {
        let need = (c.width * c.rows * bits).div_ceil(8);
        if c.len != 0 && c.len < need {
            return Err(Error::decode(
                t.path,
                format!(
                    "raw data chunk at byte {} holds {} bytes, {need} needed",
                    c.offset, c.len
                ),
            ));
        }
        let data = t.slice(c.offset, need)?;
        let mut bitpos = 0usize;
        for y in 0..c.rows {
            for x in 0..c.width {
                let v = match bits {
                    8 => data[y * c.width + x] as u16,
                    16 => {
                        let i = 2 * (y * c.width + x);
                        if t.little {
                            u16::from_le_bytes([data[i], data[i + 1]])
                        } else {
                            u16::from_be_bytes([data[i], data[i + 1]])
                        }
                    }
                    _ => unpack_msb_first(data, &mut bitpos, bits),
                };
                let (gx, gy) = (c.x0 + x, c.y0 + y);
                if gx < w && gy < h {
                    out[gy * w + gx] = v;
                }
            }
        }
    }
    Ok(out)
}

/// The next `bits`-bit sample at `bitpos`: MSB-first bit packing, no row padding (DNG spec,
/// BitsPerSample).
fn unpack_msb_first(data: &[u8], bitpos: &mut usize, bits: usize) -> u16 {
    let mut v = 0u32;
    let mut left = bits;
    while left > 0 {
        let byte = data[*bitpos / 8] as u32;
        let avail = 8 - *bitpos % 8;
        let take = avail.min(left);
        let shifted = (byte >> (avail - take)) & ((1 << take) - 1);
        v = (v << take) | shifted;
        left -= take;
        *bitpos += take;
    }
    v as u16
}

/// The tiles or strips covering the w × h raw image.
fn chunks(t: &Tiff, ifd: &Ifd, w: usize, h: usize) -> Result<Vec<Chunk>> {
    let mut chunks = Vec::new();
    if let Some(offs) = t.uints(ifd, TAG_TILE_OFFSETS)? {
        let tw = t.required(ifd, TAG_TILE_WIDTH, "TileWidth")? as usize;
        let tl = t.required(ifd, TAG_TILE_LENGTH, "TileLength")? as usize;
        let counts = t.uints(ifd, TAG_TILE_BYTES)?.unwrap_or_default();
        let across = w.div_ceil(tw.max(1));
        let down = h.div_ceil(tl.max(1));
        if tw == 0 || tl == 0 || offs.len() < across * down {
            return Err(Error::decode(
                t.path,
                "tile layout does not cover the raw image",
            ));
        }
        for (k, &o) in offs.iter().enumerate().take(across * down) {
            chunks.push(Chunk {
                x0: (k % across) * tw,
                y0: (k / across) * tl,
                width: tw,
                rows: tl,
                offset: o as usize,
                len: counts.get(k).copied().unwrap_or(0) as usize,
            });
        }
        return Ok(chunks);
    }
    let offs = t
        .uints(ifd, TAG_STRIP_OFFSETS)?
        .ok_or_else(|| Error::decode(t.path, "raw image has neither strips nor tiles"))?;
    let rps = t
        .uint(ifd, TAG_ROWS_PER_STRIP)?
        .unwrap_or(h as u64)
        .min(h as u64) as usize;
    let counts = t.uints(ifd, TAG_STRIP_BYTES)?.unwrap_or_default();
    if rps == 0 || offs.len() < h.div_ceil(rps) {
        return Err(Error::decode(
            t.path,
            "strip layout does not cover the raw image",
        ));
    }
    for (k, &o) in offs.iter().enumerate().take(h.div_ceil(rps)) {
        chunks.push(Chunk {
            x0: 0,
            y0: k * rps,
            width: w,
            // The last strip may hold fewer rows.
            rows: rps.min(h - k * rps),
            offset: o as usize,
            len: counts.get(k).copied().unwrap_or(0) as usize,
        });
    }
    Ok(chunks)
}

fn info_from(t: &Tiff, ifd: &Ifd) -> Result<DngInfo> {
    let path = t.path;
    let (raw_width, raw_height, bits, compression) = raw_format(t, ifd)?;
    let cfa = bayer_cfa(t, ifd)?;
    let tags = DngTags::from_raw_ifd(t, ifd, PHOTOMETRIC_CFA)?;
    let white_level = match &tags.white_level {
        Some(w) => w[0],
        None => ((1u64 << bits) - 1) as f64,
    };
    let [rr, rc] = tags.black_level_repeat;
    if tags.black_level.as_ref().is_some_and(|b| b.len() > 1) && (rr > 2 || rc > 2) {
        return Err(Error::unsupported(
            path,
            format!(
                "BlackLevel with repeat {:?} (at most 2 × 2 is supported)",
                [rr, rc]
            ),
        ));
    }
    let black_level: [[f64; 2]; 2] =
        std::array::from_fn(|r| std::array::from_fn(|c| tags.black_at(r, c, 0)));
    if black_level
        .iter()
        .flatten()
        .any(|&b| !(b >= 0.0 && b < white_level))
    {
        return Err(Error::decode(
            path,
            format!("black level {black_level:?} is not below the white level {white_level}"),
        ));
    }
    let (active_area, default_crop) = areas(t, ifd, raw_width, raw_height)?;
    Ok(DngInfo {
        make: tags.make,
        model: tags.model,
        unique_camera_model: tags.unique_camera_model,
        width: default_crop[2],
        height: default_crop[3],
        raw_width,
        raw_height,
        bits_per_sample: bits,
        compression,
        cfa,
        black_level,
        white_level,
        active_area,
        default_crop,
        color_matrix1: tags.color_matrix[0],
        color_matrix2: tags.color_matrix[1],
        calibration_illuminant1: tags.calibration_illuminant[0],
        calibration_illuminant2: tags.calibration_illuminant[1],
        as_shot_neutral: tags.as_shot_neutral,
    })
}

/// Size, bits per sample and compression of the raw image, refusing what the decoder cannot
/// read.
fn raw_format(t: &Tiff, ifd: &Ifd) -> Result<(usize, usize, u32, u16)> {
    let path = t.path;
    let raw_width = t.required(ifd, TAG_WIDTH, "ImageWidth")? as usize;
    let raw_height = t.required(ifd, TAG_HEIGHT, "ImageLength")? as usize;
    let bits_v = t.uints(ifd, TAG_BITS)?.unwrap_or(vec![1]);
    let bits = bits_v[0] as u32;
    let compression = t.uint(ifd, TAG_COMPRESSION)?.unwrap_or(1) as u16;
    let samples = t.uint(ifd, TAG_SAMPLES)?.unwrap_or(1);
    if raw_width == 0 || raw_height == 0 || raw_width > 1 << 16 || raw_height > 1 << 16 {
        return Err(Error::decode(
            path,
            format!("raw image size {raw_width}×{raw_height}"),
        ));
    }
    match compression {
        1 => {}
        7 => {
            return Err(Error::unsupported(
                path,
                "lossless-JPEG compressed raw data (Compression 7); only uncompressed DNGs are \
                 read: convert it to an uncompressed DNG first (Adobe DNG Converter with \
                 compression off, or the DNG SDK's dng_validate)",
            ));
        }
        c => {
            return Err(Error::unsupported(
                path,
                format!("raw data compression {c} (only 1, uncompressed, is supported)"),
            ));
        }
    }
    let refuse = |msg: String| Err(Error::unsupported(path, msg));
    if samples != 1 {
        return refuse(format!("{samples} samples per pixel in a CFA image"));
    }
    if !(8..=16).contains(&bits) {
        return refuse(format!("{bits} bits per sample (8–16 supported)"));
    }
    if t.uint(ifd, TAG_SAMPLE_FORMAT)?.unwrap_or(1) != 1 {
        return refuse("floating-point or signed raw samples".into());
    }
    if t.uint(ifd, TAG_PLANAR)?.unwrap_or(1) != 1 {
        return refuse("planar configuration 2 in a CFA image".into());
    }
    Ok((raw_width, raw_height, bits, compression))
}

/// The 2 × 2 Bayer pattern (colour at row r, column c: `[r][c]`); other CFAs are refused.
fn bayer_cfa(t: &Tiff, ifd: &Ifd) -> Result<[[u8; 2]; 2]> {
    let path = t.path;
    let dim = t.uints(ifd, TAG_CFA_REPEAT)?.unwrap_or(vec![2, 2]);
    let pattern = t
        .bytes_of(ifd, TAG_CFA_PATTERN)?
        .ok_or_else(|| Error::decode(path, "CFA raw image without a CFAPattern tag"))?;
    let plane = t
        .bytes_of(ifd, TAG_CFA_PLANE_COLOR)?
        .unwrap_or(vec![0, 1, 2]);
    let layout = t.uint(ifd, TAG_CFA_LAYOUT)?.unwrap_or(1);
    const BAYER: [[u8; 4]; 4] = [[0, 1, 1, 2], [2, 1, 1, 0], [1, 0, 2, 1], [1, 2, 0, 1]];
    let bayer = dim == [2, 2]
        && plane == [0, 1, 2]
        && layout == 1
        && BAYER.iter().any(|b| pattern.as_slice() == b.as_slice());
    if !bayer {
        return Err(Error::unsupported(
            path,
            format!(
                "CFA pattern {pattern:?} (repeat {dim:?}, plane colours {plane:?}, layout \
                 {layout}); only 2×2 Bayer patterns RGGB, BGGR, GRBG, GBRG are supported"
            ),
        ));
    }
    Ok([[pattern[0], pattern[1]], [pattern[2], pattern[3]]])
}

/// ActiveArea (top, left, bottom, right) and the DefaultCrop (x, y, w, h) within it; a
/// DefaultCrop that does not fit is ignored.
fn areas(
    t: &Tiff,
    ifd: &Ifd,
    raw_width: usize,
    raw_height: usize,
) -> Result<([usize; 4], [usize; 4])> {
    let path = t.path;
    let aa =
        t.uints(ifd, TAG_ACTIVE_AREA)?
            .unwrap_or(vec![0, 0, raw_height as u64, raw_width as u64]);
    if aa.len() != 4 {
        return Err(Error::decode(
            path,
            format!("ActiveArea has {} values, not 4", aa.len()),
        ));
    }
    let active_area = [
        aa[0] as usize,
        aa[1] as usize,
        aa[2] as usize,
        aa[3] as usize,
    ];
    if active_area[0] >= active_area[2]
        || active_area[1] >= active_area[3]
        || active_area[2] > raw_height
        || active_area[3] > raw_width
    {
        return Err(Error::decode(
            path,
            format!("ActiveArea {aa:?} outside the {raw_width}×{raw_height} raw image"),
        ));
    }
    let (aw, ah) = (
        active_area[3] - active_area[1],
        active_area[2] - active_area[0],
    );
    let origin = t.floats(ifd, TAG_CROP_ORIGIN)?.unwrap_or(vec![0.0, 0.0]);
    let size = t
        .floats(ifd, TAG_CROP_SIZE)?
        .unwrap_or(vec![aw as f64, ah as f64]);
    let default_crop = if origin.len() == 2 && size.len() == 2 {
        let c = [
            origin[0].round(),
            origin[1].round(),
            size[0].round(),
            size[1].round(),
        ];
        if c.iter().all(|v| *v >= 0.0)
            && c[0] + c[2] <= aw as f64
            && c[1] + c[3] <= ah as f64
            && c[2] >= 1.0
            && c[3] >= 1.0
        {
            c.map(|v| v as usize)
        } else {
            [0, 0, aw, ah]
        }
    } else {
        [0, 0, aw, ah]
    };
    Ok((active_area, default_crop))
}
