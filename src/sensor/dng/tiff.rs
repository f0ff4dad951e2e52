//! A minimal TIFF IFD reader (classic TIFF, either byte order): the IFD chain, one level of
//! SubIFDs and the EXIF IFD; tag values as numbers or text. Shared by the image decoder
//! (`image`) and the tag reader (`tags`).

use crate::error::{Error, Result};
use std::collections::BTreeMap;
use std::path::Path;

pub(super) const TAG_SUBFILE_TYPE: u16 = 254;
pub(super) const TAG_WIDTH: u16 = 256;
pub(super) const TAG_HEIGHT: u16 = 257;
pub(super) const TAG_BITS: u16 = 258;
pub(super) const TAG_COMPRESSION: u16 = 259;
pub(super) const TAG_PHOTOMETRIC: u16 = 262;
pub(super) const TAG_MAKE: u16 = 271;
pub(super) const TAG_MODEL: u16 = 272;
pub(super) const TAG_STRIP_OFFSETS: u16 = 273;
pub(super) const TAG_SAMPLES: u16 = 277;
pub(super) const TAG_ROWS_PER_STRIP: u16 = 278;
pub(super) const TAG_STRIP_BYTES: u16 = 279;
pub(super) const TAG_PLANAR: u16 = 284;
pub(super) const TAG_TILE_WIDTH: u16 = 322;
pub(super) const TAG_TILE_LENGTH: u16 = 323;
pub(super) const TAG_TILE_OFFSETS: u16 = 324;
pub(super) const TAG_TILE_BYTES: u16 = 325;
pub(super) const TAG_SUB_IFDS: u16 = 330;
pub(super) const TAG_SAMPLE_FORMAT: u16 = 339;
pub(super) const TAG_CFA_REPEAT: u16 = 33421;
pub(super) const TAG_CFA_PATTERN: u16 = 33422;
pub(super) const TAG_UNIQUE_MODEL: u16 = 50708;
pub(super) const TAG_CFA_PLANE_COLOR: u16 = 50710;
pub(super) const TAG_CFA_LAYOUT: u16 = 50711;
pub(super) const TAG_LINEARIZATION: u16 = 50712;
pub(super) const TAG_BLACK_REPEAT: u16 = 50713;
pub(super) const TAG_BLACK: u16 = 50714;
pub(super) const TAG_BLACK_DELTA_H: u16 = 50715;
pub(super) const TAG_BLACK_DELTA_V: u16 = 50716;
pub(super) const TAG_WHITE: u16 = 50717;
pub(super) const TAG_CROP_ORIGIN: u16 = 50719;
pub(super) const TAG_CROP_SIZE: u16 = 50720;
pub(super) const TAG_COLOR_MATRIX1: u16 = 50721;
pub(super) const TAG_COLOR_MATRIX2: u16 = 50722;
pub(super) const TAG_AS_SHOT_NEUTRAL: u16 = 50728;
pub(super) const TAG_CAL_ILLUMINANT1: u16 = 50778;
pub(super) const TAG_CAL_ILLUMINANT2: u16 = 50779;
pub(super) const TAG_ACTIVE_AREA: u16 = 50829;
pub(super) const TAG_EXIF_IFD: u16 = 34665;
/// EXIF ISOSpeedRatings (EXIF 2.3: PhotographicSensitivity), also TIFF/EP's tag in IFD 0.
pub(super) const TAG_ISO: u16 = 34855;
pub(super) const TAG_RECOMMENDED_EXPOSURE_INDEX: u16 = 34866;
pub(super) const TAG_ISO_SPEED: u16 = 34867;
pub(super) const TAG_CAMERA_CALIBRATION1: u16 = 50723;
pub(super) const TAG_CAMERA_CALIBRATION2: u16 = 50724;
pub(super) const TAG_ANALOG_BALANCE: u16 = 50727;
pub(super) const TAG_AS_SHOT_WHITE_XY: u16 = 50729;
pub(super) const TAG_CAMERA_CAL_SIGNATURE: u16 = 50931;
pub(super) const TAG_PROFILE_CAL_SIGNATURE: u16 = 50932;
pub(super) const TAG_NOISE_PROFILE: u16 = 51041;

pub(super) const PHOTOMETRIC_CFA: u32 = 32803;
pub(super) const PHOTOMETRIC_LINEAR_RAW: u32 = 34892;

#[derive(Clone, Copy, Debug)]
pub(super) struct Entry {
    pub(super) typ: u16,
    pub(super) count: u32,
    /// Offset of the value bytes in the file (inline values point into the entry).
    pub(super) offset: usize,
}

pub(super) type Ifd = BTreeMap<u16, Entry>;

pub(super) struct Tiff<'a> {
    pub(super) bytes: &'a [u8],
    pub(super) little: bool,
    pub(super) path: &'a Path,
    pub(super) ifd0: Ifd,
    /// Every IFD found: IFD chain and one level of SubIFDs.
    pub(super) all: Vec<Ifd>,
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
    pub(super) fn parse(bytes: &'a [u8], path: &'a Path) -> Result<Tiff<'a>> {
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

    pub(super) fn slice(&self, off: usize, len: usize) -> Result<&'a [u8]> {
        off.checked_add(len)
            .and_then(|end| self.bytes.get(off..end))
            .ok_or_else(|| {
                Error::decode(
                    self.path,
                    format!("truncated: needs bytes {off}..{}", off.saturating_add(len)),
                )
            })
    }

    pub(super) fn u16_at(&self, off: usize) -> Result<u16> {
        let b = self.slice(off, 2)?;
        Ok(if self.little {
            u16::from_le_bytes([b[0], b[1]])
        } else {
            u16::from_be_bytes([b[0], b[1]])
        })
    }

    pub(super) fn u32_at(&self, off: usize) -> Result<u32> {
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
    pub(super) fn floats(&self, ifd: &Ifd, tag: u16) -> Result<Option<Vec<f64>>> {
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

    pub(super) fn uints(&self, ifd: &Ifd, tag: u16) -> Result<Option<Vec<u64>>> {
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

    pub(super) fn uint(&self, ifd: &Ifd, tag: u16) -> Result<Option<u64>> {
        Ok(self.uints(ifd, tag)?.and_then(|v| v.first().copied()))
    }

    pub(super) fn required(&self, ifd: &Ifd, tag: u16, name: &str) -> Result<u64> {
        self.uint(ifd, tag)?
            .ok_or_else(|| Error::decode(self.path, format!("raw image has no {name} tag ({tag})")))
    }

    pub(super) fn ascii(&self, ifd: &Ifd, tag: u16) -> Result<Option<String>> {
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

    pub(super) fn bytes_of(&self, ifd: &Ifd, tag: u16) -> Result<Option<Vec<u8>>> {
        Ok(self
            .uints(ifd, tag)?
            .map(|v| v.into_iter().map(|x| x.min(255) as u8).collect()))
    }

    /// A text tag: ASCII, or UTF-8 in BYTE/UNDEFINED (as the DNG signature tags may be stored).
    pub(super) fn text(&self, ifd: &Ifd, tag: u16) -> Result<Option<String>> {
        match ifd.get(&tag) {
            Some(e) if matches!(e.typ, 1 | 7) => {
                let b = self.slice(e.offset, e.count as usize)?;
                let s = String::from_utf8_lossy(b)
                    .trim_end_matches('\0')
                    .to_string();
                Ok(Some(s))
            }
            _ => self.ascii(ifd, tag),
        }
    }

    /// The EXIF IFD that IFD 0 points to, if any.
    pub(super) fn exif_ifd(&self) -> Result<Option<Ifd>> {
        match self.uint(&self.ifd0, TAG_EXIF_IFD)? {
            Some(off) => Ok(Some(self.read_ifd(off as usize)?.0)),
            None => Ok(None),
        }
    }

    /// The main image's IFD (NewSubfileType 0) holding raw data, CFA or LinearRaw, with its
    /// PhotometricInterpretation. Only its tags are needed: the image data may be absent.
    pub(super) fn main_raw_ifd(&self) -> Result<(Ifd, u32)> {
        for ifd in &self.all {
            let subfile = self.uint(ifd, TAG_SUBFILE_TYPE)?.unwrap_or(0);
            let photometric = self.uint(ifd, TAG_PHOTOMETRIC)?.unwrap_or(0) as u32;
            if subfile == 0 && matches!(photometric, PHOTOMETRIC_CFA | PHOTOMETRIC_LINEAR_RAW) {
                return Ok((ifd.clone(), photometric));
            }
        }
        Err(Error::unsupported(
            self.path,
            "no raw image IFD (NewSubfileType 0 with PhotometricInterpretation CFA 32803 or \
             LinearRaw 34892); not a raw DNG?",
        ))
    }

    /// The full-resolution raw IFD: NewSubfileType 0 and PhotometricInterpretation CFA/LinearRaw.
    pub(super) fn raw_ifd(&self) -> Result<Ifd> {
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
}
