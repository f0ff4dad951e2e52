//! Image I/O: one image type and readers/writers for OpenEXR, Radiance .hdr, PNG and TIFF, and a
//! reader for 8-bit JPEG (bracket folders off a phone or camera, src/capture/scan.rs).
//!
//! Conventions: EXR and .hdr hold linear values and are returned as stored. PNG, TIFF and JPEG
//! are returned as code values in [0, 1] (v / 255 or v / 65535), with no transfer function undone:
//! the caller knows whether the file is sRGB, a device response or raw DN.

pub mod atomic;
mod exr;
pub mod guard;
mod hdr;
pub mod image;
pub mod jpeg;
mod ldr;
pub mod limits;
pub mod mu_law;
mod resize;
pub mod source;
pub mod srgb;

pub use image::{Image, dynamic_range_stops, luminance};
pub use resize::resize;
pub use srgb::{srgb_decode, srgb_decode_f64, srgb_encode, srgb_encode_fast};

use crate::error::{Error, Result};
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Exr,
    Hdr,
    Png,
    Tiff,
    /// Read only (8-bit baseline/progressive, grey or YCbCr → RGB); never written.
    Jpeg,
}

impl Format {
    /// The format's name as messages spell it.
    pub fn name(self) -> &'static str {
        match self {
            Format::Exr => "EXR",
            Format::Hdr => "Radiance HDR",
            Format::Png => "PNG",
            Format::Tiff => "TIFF",
            Format::Jpeg => "JPEG",
        }
    }

    pub fn from_path(path: &Path) -> Result<Format> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "exr" => Ok(Format::Exr),
            "hdr" | "pic" => Ok(Format::Hdr),
            "png" => Ok(Format::Png),
            "tif" | "tiff" => Ok(Format::Tiff),
            "jpg" | "jpeg" => Ok(Format::Jpeg),
            _ => Err(Error::unsupported(
                path,
                format!(
                    "unknown image extension '.{ext}' (expected exr, hdr, png, tif, tiff, jpg, jpeg)"
                ),
            )),
        }
    }
}

/// Bit depth of an integer (LDR) file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum BitDepth {
    #[serde(rename = "8")]
    Eight,
    #[serde(rename = "16")]
    Sixteen,
}

impl BitDepth {
    pub fn max_code(self) -> f32 {
        match self {
            BitDepth::Eight => 255.0,
            BitDepth::Sixteen => 65535.0,
        }
    }
    pub fn from_bits(bits: u32) -> Option<BitDepth> {
        match bits {
            8 => Some(BitDepth::Eight),
            16 => Some(BitDepth::Sixteen),
            _ => None,
        }
    }
}

/// Sample type written to EXR.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ExrPrecision {
    Half,
    #[default]
    Float,
}

/// What a reader found besides the pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadInfo {
    pub format: Format,
    /// Bits per sample for PNG/TIFF integer files; None for float formats.
    pub bit_depth: Option<BitDepth>,
}

/// Read any supported image; fails with the file named on missing, truncated, corrupt or
/// unsupported files, and on NaN/Inf pixels.
/// Lower-case hex SHA-256 of `bytes`, as `sha256sum` prints it.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

pub fn read_image(path: &Path) -> Result<Image> {
    read_image_info(path).map(|(img, _)| img)
}

pub fn read_image_info(path: &Path) -> Result<(Image, ReadInfo)> {
    let format = Format::from_path(path)?;
    let bytes = match guard::read_input(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(Error::io(
                path,
                std::io::Error::new(std::io::ErrorKind::NotFound, "file not found"),
            ));
        }
        Err(e) => return Err(Error::io(path, e)),
    };
    read_image_bytes(&bytes, format, path)
}

/// Decode an image held in memory, as [`read_image_info`] does for a file (it calls this):
/// the same decoders, decode limits and checks. `path` only names the source in errors.
pub fn read_image_bytes(bytes: &[u8], format: Format, path: &Path) -> Result<(Image, ReadInfo)> {
    let (img, bit_depth) = match format {
        Format::Exr => (exr::decode(path, bytes)?, None),
        Format::Hdr => (hdr::decode(path, bytes)?, None),
        Format::Png | Format::Tiff | Format::Jpeg => {
            let (img, d) = ldr::decode_bytes(path, format, bytes)?;
            (img, Some(d))
        }
    };
    if let Some((count, x, y)) = img.non_finite() {
        return Err(Error::NonFinite {
            path: path.to_path_buf(),
            count,
            x,
            y,
        });
    }
    Ok((img, ReadInfo { format, bit_depth }))
}

/// Write linear values to OpenEXR (RGB, ZIP compression), atomically.
pub fn write_exr(path: &Path, img: &Image, precision: ExrPrecision) -> Result<()> {
    exr::write(path, img, precision, true)
}

/// [`write_exr`] in f32 without compression, for a network's or a merge's output: ZIP shrinks
/// the noise of such an image by about 3 % (a clean render by half) and took a tenth of an
/// evaluation's time.
pub fn write_exr_uncompressed(path: &Path, img: &Image) -> Result<()> {
    exr::write(path, img, ExrPrecision::Float, false)
}

/// Write linear values to Radiance RGBE (.hdr), atomically. Negative values are clamped to 0.
pub fn write_hdr(path: &Path, img: &Image) -> Result<()> {
    hdr::write(path, img)
}

/// Write code values in [0, 1] to PNG or TIFF (by extension) at 8 or 16 bits, atomically:
/// clamped to [0, 1], quantised as round(v · (2^bits − 1)).
pub fn write_ldr(path: &Path, img: &Image, depth: BitDepth) -> Result<()> {
    ldr::write(path, img, depth)
}

/// Write by extension with defaults: EXR float, .hdr, PNG/TIFF 16-bit.
pub fn write_image(path: &Path, img: &Image) -> Result<()> {
    match Format::from_path(path)? {
        Format::Exr => write_exr(path, img, ExrPrecision::Float),
        Format::Hdr => write_hdr(path, img),
        Format::Png | Format::Tiff => write_ldr(path, img, BitDepth::Sixteen),
        Format::Jpeg => Err(Error::encode(
            path,
            "JPEG is read only (lossy); write PNG or TIFF",
        )),
    }
}
