//! Raw DNG reading: the CFA mosaic of a DNG, black-subtracted and normalised, demosaiced
//! bilinearly to linear camera RGB (not white balanced), plus the tags that say where it came
//! from (ColorMatrix1/2, AsShotNeutral, levels, CFA pattern).
//!
//! No permissively licensed Rust crate decodes these files: the `tiff` crate (MIT) refuses an
//! IFD whose PhotometricInterpretation is CFA (32803) before any tag can be read, the `dng` crate
//! is AGPL-3.0, and rawloader/rawler are LGPL. So this module carries a small TIFF/DNG IFD reader
//! of its own (classic TIFF, either byte order) that handles what DNG writers such as Magic
//! Lantern, smartphones and most converters produce *uncompressed*:
//! - the raw image in IFD 0 or in a SubIFD (NewSubfileType 0, PhotometricInterpretation 32803);
//! - Compression 1 (none), strips or tiles, 8–16 bits per sample, packed MSB-first without row
//!   padding as the DNG specification requires for depths other than 8/16 (16-bit samples in the
//!   file's byte order);
//! - a 2 × 2 Bayer CFAPattern (RGGB, BGGR, GRBG, GBRG), taken relative to the ActiveArea origin;
//! - LinearizationTable, BlackLevel (one value or one per CFA position via BlackLevelRepeatDim),
//!   BlackLevelDeltaH/V, WhiteLevel, ActiveArea, DefaultCropOrigin/Size.
//!
//! Lossless-JPEG (Compression 7), lossy JPEG (34892) and JPEG XL DNGs, LinearRaw (demosaiced)
//! DNGs and non-Bayer CFAs are refused with an error naming the file; convert such files to an
//! uncompressed DNG first (e.g. Adobe DNG Converter with compression off, or
//! `dng_validate -dng out.dng in.dng` from the DNG SDK).
//!
//! Output: values (DN − black) / (white − black) per photosite, not clipped (noise below black
//! stays negative, so patch means stay unbiased); then the ActiveArea, then the DefaultCrop.
//! Orientation is not applied.
#![allow(clippy::needless_range_loop)]

use crate::error::{Error, Result};
use crate::io::Image;
use std::collections::BTreeMap;
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
    let raw = tiff.decode_samples(&ifd, &info)?;
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

// ---------------------------------------------------------------------------------------------
// A minimal TIFF IFD reader
// ---------------------------------------------------------------------------------------------

const TAG_SUBFILE_TYPE: u16 = 254;
const TAG_WIDTH: u16 = 256;
const TAG_HEIGHT: u16 = 257;
const TAG_BITS: u16 = 258;
const TAG_COMPRESSION: u16 = 259;
const TAG_PHOTOMETRIC: u16 = 262;
const TAG_MAKE: u16 = 271;
const TAG_MODEL: u16 = 272;
const TAG_STRIP_OFFSETS: u16 = 273;
const TAG_SAMPLES: u16 = 277;
const TAG_ROWS_PER_STRIP: u16 = 278;
const TAG_STRIP_BYTES: u16 = 279;
const TAG_PLANAR: u16 = 284;
const TAG_TILE_WIDTH: u16 = 322;
const TAG_TILE_LENGTH: u16 = 323;
const TAG_TILE_OFFSETS: u16 = 324;
const TAG_TILE_BYTES: u16 = 325;
const TAG_SUB_IFDS: u16 = 330;
const TAG_SAMPLE_FORMAT: u16 = 339;
const TAG_CFA_REPEAT: u16 = 33421;
const TAG_CFA_PATTERN: u16 = 33422;
const TAG_UNIQUE_MODEL: u16 = 50708;
const TAG_CFA_PLANE_COLOR: u16 = 50710;
const TAG_CFA_LAYOUT: u16 = 50711;
const TAG_LINEARIZATION: u16 = 50712;
const TAG_BLACK_REPEAT: u16 = 50713;
const TAG_BLACK: u16 = 50714;
const TAG_BLACK_DELTA_H: u16 = 50715;
const TAG_BLACK_DELTA_V: u16 = 50716;
const TAG_WHITE: u16 = 50717;
const TAG_CROP_ORIGIN: u16 = 50719;
const TAG_CROP_SIZE: u16 = 50720;
const TAG_COLOR_MATRIX1: u16 = 50721;
const TAG_COLOR_MATRIX2: u16 = 50722;
const TAG_AS_SHOT_NEUTRAL: u16 = 50728;
const TAG_CAL_ILLUMINANT1: u16 = 50778;
const TAG_CAL_ILLUMINANT2: u16 = 50779;
const TAG_ACTIVE_AREA: u16 = 50829;

const PHOTOMETRIC_CFA: u32 = 32803;
const PHOTOMETRIC_LINEAR_RAW: u32 = 34892;

#[derive(Clone, Copy, Debug)]
struct Entry {
    typ: u16,
    count: u32,
    /// Offset of the value bytes in the file (inline values point into the entry).
    offset: usize,
}

type Ifd = BTreeMap<u16, Entry>;

struct Tiff<'a> {
    bytes: &'a [u8],
    little: bool,
    path: &'a Path,
    ifd0: Ifd,
    /// Every IFD found: IFD chain and one level of SubIFDs.
    all: Vec<Ifd>,
}

fn type_size(typ: u16) -> Option<usize> {
    match typ {
        1 | 2 | 6 | 7 => Some(1),
        3 | 8 => Some(2),
        4 | 9 | 11 | 13 => Some(4),
        5 | 10 | 12 => Some(8),
        _ => None,
    }
}

impl<'a> Tiff<'a> {
    fn parse(bytes: &'a [u8], path: &'a Path) -> Result<Tiff<'a>> {
        let little = match bytes.get(0..2) {
            Some(b"II") => true,
            Some(b"MM") => false,
            _ => {
                return Err(Error::decode(
                    path,
                    "not a TIFF/DNG file (no II/MM byte-order mark)",
                ));
            }
        };
        let mut t = Tiff {
            bytes,
            little,
            path,
            ifd0: Ifd::new(),
            all: Vec::new(),
        };
        match t.u16_at(2)? {
            42 => {}
            43 => {
                return Err(Error::unsupported(
                    path,
                    "BigTIFF DNG files are not supported",
                ));
            }
            m => return Err(Error::decode(path, format!("bad TIFF magic number {m}"))),
        }
        let mut next = t.u32_at(4)? as usize;
        let mut seen = std::collections::HashSet::new();
        while next != 0 && seen.insert(next) && t.all.len() < 64 {
            let (ifd, nxt) = t.read_ifd(next)?;
            if let Some(subs) = t.uints(&ifd, TAG_SUB_IFDS)? {
                for s in subs {
                    if seen.insert(s as usize) && t.all.len() < 64 {
                        let (sub, _) = t.read_ifd(s as usize)?;
                        t.all.push(sub);
                    }
                }
            }
            if t.ifd0.is_empty() {
                t.ifd0 = ifd.clone();
            }
            t.all.push(ifd);
            next = nxt;
        }
        if t.ifd0.is_empty() {
            return Err(Error::decode(path, "no image file directory"));
        }
        Ok(t)
    }

    fn slice(&self, off: usize, len: usize) -> Result<&'a [u8]> {
        off.checked_add(len)
            .and_then(|end| self.bytes.get(off..end))
            .ok_or_else(|| {
                Error::decode(
                    self.path,
                    format!("truncated: needs bytes {off}..{}", off.saturating_add(len)),
                )
            })
    }

    fn u16_at(&self, off: usize) -> Result<u16> {
        let b = self.slice(off, 2)?;
        Ok(if self.little {
            u16::from_le_bytes([b[0], b[1]])
        } else {
            u16::from_be_bytes([b[0], b[1]])
        })
    }

    fn u32_at(&self, off: usize) -> Result<u32> {
        let b: [u8; 4] = self.slice(off, 4)?.try_into().expect("4 bytes");
        Ok(if self.little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    fn read_ifd(&self, off: usize) -> Result<(Ifd, usize)> {
        let n = self.u16_at(off)? as usize;
        let mut ifd = Ifd::new();
        for k in 0..n {
            let e = off + 2 + 12 * k;
            let tag = self.u16_at(e)?;
            let typ = self.u16_at(e + 2)?;
            let count = self.u32_at(e + 4)?;
            let Some(size) = type_size(typ) else { continue };
            let len = size * count as usize;
            let offset = if len <= 4 {
                e + 8
            } else {
                self.u32_at(e + 8)? as usize
            };
            ifd.insert(tag, Entry { typ, count, offset });
        }
        let next = self.u32_at(off + 2 + 12 * n)? as usize;
        Ok((ifd, next))
    }

    /// Numeric values of a tag as f64 (integers, rationals, floats).
    fn floats(&self, ifd: &Ifd, tag: u16) -> Result<Option<Vec<f64>>> {
        let Some(e) = ifd.get(&tag) else {
            return Ok(None);
        };
        let size = type_size(e.typ).expect("known type");
        // Callers index the first value (found by tests/fuzz.rs: BlackLevel with count 0).
        if e.count == 0 {
            return Err(Error::decode(self.path, format!("tag {tag} has no values")));
        }
        // The values must lie in the file before `count` sizes any allocation: a corrupt count
        // of 2^32 would otherwise reserve 34 GB (found by tests/fuzz.rs).
        let len = size.checked_mul(e.count as usize).ok_or_else(|| {
            Error::decode(self.path, format!("tag {tag}: count {} overflows", e.count))
        })?;
        self.slice(e.offset, len)
            .map_err(|_| Error::decode(self.path, format!("tag {tag}: {} values of {size} bytes at offset {} run past the end of the file", e.count, e.offset)))?;
        let mut out = Vec::with_capacity(e.count as usize);
        for i in 0..e.count as usize {
            let o = e.offset + i * size;
            let v = match e.typ {
                1 | 7 => self.slice(o, 1)?[0] as f64,
                6 => self.slice(o, 1)?[0] as i8 as f64,
                3 => self.u16_at(o)? as f64,
                8 => self.u16_at(o)? as i16 as f64,
                4 | 13 => self.u32_at(o)? as f64,
                9 => self.u32_at(o)? as i32 as f64,
                5 => {
                    let (n, d) = (self.u32_at(o)?, self.u32_at(o + 4)?);
                    if d == 0 { 0.0 } else { n as f64 / d as f64 }
                }
                10 => {
                    let (n, d) = (self.u32_at(o)? as i32, self.u32_at(o + 4)? as i32);
                    if d == 0 { 0.0 } else { n as f64 / d as f64 }
                }
                11 => f32::from_bits(self.u32_at(o)?) as f64,
                12 => {
                    let b: [u8; 8] = self.slice(o, 8)?.try_into().expect("8 bytes");
                    if self.little {
                        f64::from_le_bytes(b)
                    } else {
                        f64::from_be_bytes(b)
                    }
                }
                _ => {
                    return Err(Error::decode(
                        self.path,
                        format!("tag {tag} has a text type where a number was expected"),
                    ));
                }
            };
            out.push(v);
        }
        Ok(Some(out))
    }

    fn uints(&self, ifd: &Ifd, tag: u16) -> Result<Option<Vec<u64>>> {
        match self.floats(ifd, tag)? {
            None => Ok(None),
            Some(v) => {
                if v.iter().any(|x| *x < 0.0 || x.fract() != 0.0) {
                    return Err(Error::decode(
                        self.path,
                        format!("tag {tag}: expected non-negative integers"),
                    ));
                }
                Ok(Some(v.into_iter().map(|x| x as u64).collect()))
            }
        }
    }

    fn uint(&self, ifd: &Ifd, tag: u16) -> Result<Option<u64>> {
        Ok(self.uints(ifd, tag)?.and_then(|v| v.first().copied()))
    }

    fn required(&self, ifd: &Ifd, tag: u16, name: &str) -> Result<u64> {
        self.uint(ifd, tag)?
            .ok_or_else(|| Error::decode(self.path, format!("raw image has no {name} tag ({tag})")))
    }

    fn ascii(&self, ifd: &Ifd, tag: u16) -> Result<Option<String>> {
        let Some(e) = ifd.get(&tag) else {
            return Ok(None);
        };
        if e.typ != 2 {
            return Ok(None);
        }
        let b = self.slice(e.offset, e.count as usize)?;
        let s = String::from_utf8_lossy(b)
            .trim_end_matches('\0')
            .trim()
            .to_string();
        Ok(if s.is_empty() { None } else { Some(s) })
    }

    fn bytes_of(&self, ifd: &Ifd, tag: u16) -> Result<Option<Vec<u8>>> {
        Ok(self
            .uints(ifd, tag)?
            .map(|v| v.into_iter().map(|x| x.min(255) as u8).collect()))
    }

    /// The full-resolution raw IFD: NewSubfileType 0 and PhotometricInterpretation CFA/LinearRaw.
    fn raw_ifd(&self) -> Result<Ifd> {
        let mut linear_raw = false;
        for ifd in &self.all {
            let subfile = self.uint(ifd, TAG_SUBFILE_TYPE)?.unwrap_or(0);
            let photometric = self.uint(ifd, TAG_PHOTOMETRIC)?.unwrap_or(0) as u32;
            if subfile != 0 {
                continue;
            }
            if photometric == PHOTOMETRIC_CFA {
                return Ok(ifd.clone());
            }
            linear_raw |= photometric == PHOTOMETRIC_LINEAR_RAW;
        }
        Err(if linear_raw {
            Error::unsupported(
                self.path,
                "LinearRaw (already demosaiced) DNG; only CFA (Bayer) raw DNGs are supported",
            )
        } else {
            Error::unsupported(
                self.path,
                "no CFA raw image (PhotometricInterpretation 32803) found; not a raw DNG?",
            )
        })
    }

    /// The raw samples, row-major, raw_width × raw_height.
    fn decode_samples(&self, ifd: &Ifd, info: &DngInfo) -> Result<Vec<u16>> {
        let (w, h, bits) = (
            info.raw_width,
            info.raw_height,
            info.bits_per_sample as usize,
        );
        let mut out = vec![0u16; w * h];
        // Chunks: (x0, y0, chunk width, chunk rows, data).
        let mut chunks: Vec<(usize, usize, usize, usize, usize, usize)> = Vec::new();
        if let Some(offs) = self.uints(ifd, TAG_TILE_OFFSETS)? {
            let tw = self.required(ifd, TAG_TILE_WIDTH, "TileWidth")? as usize;
            let tl = self.required(ifd, TAG_TILE_LENGTH, "TileLength")? as usize;
            let counts = self.uints(ifd, TAG_TILE_BYTES)?.unwrap_or_default();
            let across = w.div_ceil(tw.max(1));
            let down = h.div_ceil(tl.max(1));
            if tw == 0 || tl == 0 || offs.len() < across * down {
                return Err(Error::decode(
                    self.path,
                    "tile layout does not cover the raw image",
                ));
            }
            for (k, &o) in offs.iter().enumerate().take(across * down) {
                let len = counts.get(k).copied().unwrap_or(0) as usize;
                chunks.push((
                    (k % across) * tw,
                    (k / across) * tl,
                    tw,
                    tl,
                    o as usize,
                    len,
                ));
            }
        } else {
            let offs = self.uints(ifd, TAG_STRIP_OFFSETS)?.ok_or_else(|| {
                Error::decode(self.path, "raw image has neither strips nor tiles")
            })?;
            let rps = self
                .uint(ifd, TAG_ROWS_PER_STRIP)?
                .unwrap_or(h as u64)
                .min(h as u64) as usize;
            let counts = self.uints(ifd, TAG_STRIP_BYTES)?.unwrap_or_default();
            if rps == 0 || offs.len() < h.div_ceil(rps) {
                return Err(Error::decode(
                    self.path,
                    "strip layout does not cover the raw image",
                ));
            }
            for (k, &o) in offs.iter().enumerate().take(h.div_ceil(rps)) {
                let len = counts.get(k).copied().unwrap_or(0) as usize;
                // The last strip may hold fewer rows.
                chunks.push((0, k * rps, w, rps.min(h - k * rps), o as usize, len));
            }
        }
        for (x0, y0, cw, ch, off, len) in chunks {
            let need = (cw * ch * bits).div_ceil(8);
            if len != 0 && len < need {
                return Err(Error::decode(
                    self.path,
                    format!("raw data chunk at byte {off} holds {len} bytes, {need} needed"),
                ));
            }
            let data = self.slice(off, need)?;
            let mut bitpos = 0usize;
            for y in 0..ch {
                for x in 0..cw {
                    let v = match bits {
                        8 => data[y * cw + x] as u16,
                        16 => {
                            let i = 2 * (y * cw + x);
                            if self.little {
                                u16::from_le_bytes([data[i], data[i + 1]])
                            } else {
                                u16::from_be_bytes([data[i], data[i + 1]])
                            }
                        }
                        _ => {
                            // MSB-first bit packing, no row padding (DNG spec, BitsPerSample).
                            let mut v = 0u32;
                            let mut left = bits;
                            while left > 0 {
                                let byte = data[bitpos / 8] as u32;
                                let avail = 8 - bitpos % 8;
                                let take = avail.min(left);
                                let shifted = (byte >> (avail - take)) & ((1 << take) - 1);
                                v = (v << take) | shifted;
                                left -= take;
                                bitpos += take;
                            }
                            v as u16
                        }
                    };
                    let (gx, gy) = (x0 + x, y0 + y);
                    if gx < w && gy < h {
                        out[gy * w + gx] = v;
                    }
                }
            }
        }
        Ok(out)
    }
}

fn info_from(t: &Tiff, ifd: &Ifd) -> Result<DngInfo> {
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
    if samples != 1 {
        return Err(Error::unsupported(
            path,
            format!("{samples} samples per pixel in a CFA image"),
        ));
    }
    if !(8..=16).contains(&bits) {
        return Err(Error::unsupported(
            path,
            format!("{bits} bits per sample (8–16 supported)"),
        ));
    }
    if t.uint(ifd, TAG_SAMPLE_FORMAT)?.unwrap_or(1) != 1 {
        return Err(Error::unsupported(
            path,
            "floating-point or signed raw samples",
        ));
    }
    if t.uint(ifd, TAG_PLANAR)?.unwrap_or(1) != 1 {
        return Err(Error::unsupported(
            path,
            "planar configuration 2 in a CFA image",
        ));
    }
    // CFA.
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
    let cfa = [[pattern[0], pattern[1]], [pattern[2], pattern[3]]];
    // Levels.
    let white_level = t
        .floats(ifd, TAG_WHITE)?
        .and_then(|v| v.first().copied())
        .unwrap_or(((1u64 << bits) - 1) as f64);
    let black_v = t.floats(ifd, TAG_BLACK)?.unwrap_or(vec![0.0]);
    let brep = t.uints(ifd, TAG_BLACK_REPEAT)?.unwrap_or(vec![1, 1]);
    let black_level: [[f64; 2]; 2] = match (brep.as_slice(), black_v.len()) {
        (_, 1) => [[black_v[0]; 2]; 2],
        ([1, 1], _) => [[black_v[0]; 2]; 2],
        ([2, 2], 4) => [[black_v[0], black_v[1]], [black_v[2], black_v[3]]],
        ([1, 2], 2) => [[black_v[0], black_v[1]], [black_v[0], black_v[1]]],
        ([2, 1], 2) => [[black_v[0]; 2], [black_v[1]; 2]],
        _ => {
            return Err(Error::unsupported(
                path,
                format!(
                    "BlackLevel with repeat {brep:?} and {} values",
                    black_v.len()
                ),
            ));
        }
    };
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
    // Areas.
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
    let matrix = |tag| -> Result<Option<[[f64; 3]; 3]>> {
        Ok(t.floats(ifd, tag)?
            .or(t.floats(&t.ifd0, tag)?)
            .filter(|v| v.len() == 9)
            .map(|v| std::array::from_fn(|i| std::array::from_fn(|j| v[3 * i + j]))))
    };
    let tag0 =
        |tag| -> Result<Option<Vec<f64>>> { Ok(t.floats(ifd, tag)?.or(t.floats(&t.ifd0, tag)?)) };
    let ascii0 =
        |tag| -> Result<Option<String>> { Ok(t.ascii(&t.ifd0, tag)?.or(t.ascii(ifd, tag)?)) };
    Ok(DngInfo {
        make: ascii0(TAG_MAKE)?,
        model: ascii0(TAG_MODEL)?,
        unique_camera_model: ascii0(TAG_UNIQUE_MODEL)?,
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
        color_matrix1: matrix(TAG_COLOR_MATRIX1)?,
        color_matrix2: matrix(TAG_COLOR_MATRIX2)?,
        calibration_illuminant1: tag0(TAG_CAL_ILLUMINANT1)?
            .and_then(|v| v.first().map(|x| *x as u16)),
        calibration_illuminant2: tag0(TAG_CAL_ILLUMINANT2)?
            .and_then(|v| v.first().map(|x| *x as u16)),
        as_shot_neutral: tag0(TAG_AS_SHOT_NEUTRAL)?
            .filter(|v| v.len() == 3)
            .map(|v| [v[0], v[1], v[2]]),
    })
}
