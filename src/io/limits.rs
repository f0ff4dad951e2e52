//! Decode limits: the one place that decides how large an image a file may declare.
//!
//! Every decoder (PNG/TIFF and Radiance .hdr through `image`, OpenEXR through `exr`, the DNG
//! reader) calls [`check`] with the size the file's header declares *before* allocating pixels,
//! so a 141-byte file claiming 100000×100000 is refused with the file named instead of aborting
//! the process on a 30 GB allocation.
//!
//! Defaults: at most 16384 pixels per side and 1 GiB for the decoded image, counted as the
//! H×W×3 f32 [`super::Image`] the readers return (12 bytes per pixel: about 89 megapixels, e.g.
//! 10924×8192; a 4032×3024 phone frame is 146 MB). Override with the environment variables
//! `HDRSYNTH_MAX_IMAGE_SIDE` (pixels) and `HDRSYNTH_MAX_DECODED_BYTES` (bytes; suffixes K, M, G
//! for KiB, MiB, GiB accepted). A malformed value is an error, not a silent default.

use crate::error::{Error, Result};
use std::path::Path;

pub const DEFAULT_MAX_SIDE: u64 = 16384;
pub const DEFAULT_MAX_DECODED_BYTES: u64 = 1 << 30;
pub const ENV_MAX_SIDE: &str = "HDRSYNTH_MAX_IMAGE_SIDE";
pub const ENV_MAX_BYTES: &str = "HDRSYNTH_MAX_DECODED_BYTES";

/// Bytes per pixel of the decoded [`super::Image`] (3 × f32), the unit of the byte limit.
pub const DECODED_BYTES_PER_PIXEL: u64 = 12;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DecodeLimits {
    pub max_side: u64,
    pub max_decoded_bytes: u64,
}

impl Default for DecodeLimits {
    fn default() -> Self {
        DecodeLimits {
            max_side: DEFAULT_MAX_SIDE,
            max_decoded_bytes: DEFAULT_MAX_DECODED_BYTES,
        }
    }
}

impl DecodeLimits {
    /// The limits in force: the defaults, overridden by the environment variables.
    pub fn from_env() -> Result<DecodeLimits> {
        Self::parse(
            std::env::var(ENV_MAX_SIDE).ok().as_deref(),
            std::env::var(ENV_MAX_BYTES).ok().as_deref(),
        )
    }

    /// Limits from the two variables' values (None = unset).
    pub fn parse(side: Option<&str>, bytes: Option<&str>) -> Result<DecodeLimits> {
        let mut l = DecodeLimits::default();
        if let Some(s) = side {
            l.max_side = parse_size(s)
                .filter(|&v| v > 0)
                .ok_or_else(|| bad_env(ENV_MAX_SIDE, s))?;
        }
        if let Some(s) = bytes {
            l.max_decoded_bytes = parse_size(s)
                .filter(|&v| v > 0)
                .ok_or_else(|| bad_env(ENV_MAX_BYTES, s))?;
        }
        Ok(l)
    }

    /// Refuse a declared `width`×`height` image that exceeds these limits, naming `path`.
    /// A side of 0 is refused too: such a file holds no pixel, and every later stage (crops,
    /// tiles, statistics) needs at least one.
    pub fn check(&self, path: &Path, what: &str, width: u64, height: u64) -> Result<()> {
        if width == 0 || height == 0 {
            return Err(Error::decode(
                path,
                format!(
                    "{what} declares {width}×{height} pixels: an image needs at least one pixel \
                     per side"
                ),
            ));
        }
        let bytes = width
            .saturating_mul(height)
            .saturating_mul(DECODED_BYTES_PER_PIXEL);
        if width > self.max_side || height > self.max_side {
            return Err(Error::unsupported(
                path,
                format!(
                    "{what} declares {width}×{height} pixels, over the decode limit of {} per \
                     side (set {ENV_MAX_SIDE} to raise it)",
                    self.max_side
                ),
            ));
        }
        if bytes > self.max_decoded_bytes {
            return Err(Error::unsupported(
                path,
                format!(
                    "{what} declares {width}×{height} pixels ({bytes} bytes decoded), over the \
                     decode limit of {} bytes (set {ENV_MAX_BYTES} to raise it)",
                    self.max_decoded_bytes
                ),
            ));
        }
        Ok(())
    }

    /// The same limits for the `image` crate's decoders, which bound their own intermediate
    /// allocations with them (our check comes first, so its message is the one users see).
    pub fn to_image_limits(&self) -> image::Limits {
        let side = u32::try_from(self.max_side).unwrap_or(u32::MAX);
        let mut l = image::Limits::default();
        l.max_image_width = Some(side);
        l.max_image_height = Some(side);
        // Raw decoded bytes are at most 8 per pixel (16-bit RGBA) or 12 (.hdr f32 RGB): bounded
        // by the f32 image's budget.
        l.max_alloc = Some(self.max_decoded_bytes);
        l
    }
}

/// Check a declared size against the limits in force ([`DecodeLimits::from_env`]).
pub fn check(path: &Path, what: &str, width: u64, height: u64) -> Result<()> {
    DecodeLimits::from_env()?.check(path, what, width, height)
}

fn parse_size(s: &str) -> Option<u64> {
    let s = s.trim();
    let (num, mul) = match s.char_indices().last()? {
        (i, 'K' | 'k') => (&s[..i], 1u64 << 10),
        (i, 'M' | 'm') => (&s[..i], 1 << 20),
        (i, 'G' | 'g') => (&s[..i], 1 << 30),
        _ => (s, 1),
    };
    num.trim().parse::<u64>().ok()?.checked_mul(mul)
}

fn bad_env(var: &str, value: &str) -> Error {
    Error::flag(
        format!("{var}={value:?}"),
        "is not a positive whole number (K/M/G suffixes allowed)",
    )
}
