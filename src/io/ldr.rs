//! PNG and TIFF at 8 and 16 bits (and 8-bit JPEG, read only) through the `image` crate. Read values are code values
//! v / 255 or v / 65535 in [0, 1]; nothing is linearised.
//!
//! Both directions work on one flat byte buffer and one f32 buffer, converted in parallel,
//! with no per-pixel allocation (4032×3024 16-bit frames go through here).

use super::{BitDepth, Format, Image};
use crate::error::{Error, Result};
use image::codecs::jpeg::JpegDecoder;
use image::codecs::png::{PngDecoder, PngEncoder};
use image::codecs::tiff::{TiffDecoder, TiffEncoder};
use image::{ColorType, ExtendedColorType, ImageDecoder, ImageEncoder, ImageError};
use rayon::prelude::*;
use std::io::Cursor;
use std::path::Path;

fn image_err(path: &Path, what: &str, e: ImageError) -> Error {
    match e {
        ImageError::Unsupported(u) => Error::unsupported(path, format!("{what}: {u}")),
        other => Error::decode(path, format!("{what}: {other}")),
    }
}

pub(super) fn decode_bytes(path: &Path, format: Format, bytes: &[u8]) -> Result<(Image, BitDepth)> {
    match format {
        Format::Png => {
            check_png_depth(path, bytes)?;
            let decoder =
                PngDecoder::new(Cursor::new(bytes)).map_err(|e| image_err(path, "PNG", e))?;
            decode(path, "PNG", decoder)
        }
        Format::Tiff => {
            let decoder =
                TiffDecoder::new(Cursor::new(bytes)).map_err(|e| image_err(path, "TIFF", e))?;
            decode(path, "TIFF", decoder)
        }
        Format::Jpeg => {
            let decoder =
                JpegDecoder::new(Cursor::new(bytes)).map_err(|e| image_err(path, "JPEG", e))?;
            decode(path, "JPEG", decoder)
        }
        other => Err(Error::unsupported(
            path,
            format!("{other:?} is not an 8/16-bit integer format"),
        )),
    }
}

/// The `image` crate silently expands 1/2/4-bit PNGs to 8 bits; reject them instead, naming the
/// depth found. Palette images are accepted: their entries are 8-bit RGB(A) code values.
fn check_png_depth(path: &Path, bytes: &[u8]) -> Result<()> {
    const SIG: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
    // Signature, IHDR length, "IHDR", width, height, bit depth (24), colour type (25).
    if bytes.len() < 26 || bytes[..8] != SIG || &bytes[12..16] != b"IHDR" {
        return Ok(()); // let the decoder report what is wrong
    }
    let (depth, colour) = (bytes[24], bytes[25]);
    let name = match colour {
        0 => "grey",
        2 => "RGB",
        3 => return Ok(()),
        4 => "grey+alpha",
        6 => "RGBA",
        _ => return Ok(()),
    };
    if depth == 8 || depth == 16 {
        Ok(())
    } else {
        Err(Error::unsupported(
            path,
            format!("PNG with {depth}-bit {name} samples; need 8 or 16 bits"),
        ))
    }
}

fn decode(path: &Path, what: &str, mut decoder: impl ImageDecoder) -> Result<(Image, BitDepth)> {
    // The declared size is checked before anything is allocated (decompression bombs).
    let limits = super::limits::DecodeLimits::from_env()?;
    let (w, h) = decoder.dimensions();
    limits.check(path, what, w.into(), h.into())?;
    decoder
        .set_limits(limits.to_image_limits())
        .map_err(|e| image_err(path, what, e))?;
    let colour = decoder.color_type();
    let original = decoder.original_color_type();
    if original != ExtendedColorType::from(colour) {
        // e.g. 1-bit or CMYK TIFF, which the decoder would convert.
        return Err(Error::unsupported(
            path,
            format!(
                "{what} with {original:?} samples; need 8- or 16-bit grey, grey+alpha, RGB or RGBA"
            ),
        ));
    }
    let (channels, depth) = match colour {
        ColorType::L8 => (1, BitDepth::Eight),
        ColorType::La8 => (2, BitDepth::Eight),
        ColorType::Rgb8 => (3, BitDepth::Eight),
        ColorType::Rgba8 => (4, BitDepth::Eight),
        ColorType::L16 => (1, BitDepth::Sixteen),
        ColorType::La16 => (2, BitDepth::Sixteen),
        ColorType::Rgb16 => (3, BitDepth::Sixteen),
        ColorType::Rgba16 => (4, BitDepth::Sixteen),
        other => {
            return Err(Error::unsupported(
                path,
                format!(
                    "{what} with {other:?} samples (float or other depth); need 8- or 16-bit integer grey, grey+alpha, RGB or RGBA"
                ),
            ));
        }
    };
    let (w, h) = decoder.dimensions();
    let (w, h) = (w as usize, h as usize);
    let bytes_per_sample = match depth {
        BitDepth::Eight => 1,
        BitDepth::Sixteen => 2,
    };
    let total = usize::try_from(decoder.total_bytes())
        .map_err(|_| Error::unsupported(path, format!("{what}: image too large")))?;
    if total != w * h * channels * bytes_per_sample {
        return Err(Error::decode(
            path,
            format!("{what}: unexpected decoded size"),
        ));
    }
    let mut buf = vec![0u8; total];
    decoder
        .read_image(&mut buf)
        .map_err(|e| image_err(path, what, e))?;

    let mut img = Image::new(w, h);
    match depth {
        BitDepth::Eight => {
            check_alpha(path, what, &buf, channels, |s| u32::from(s[0]), 1, 255)?;
            convert(&buf, channels, 1, &mut img.data, |s| {
                f32::from(s[0]) / 255.0
            });
        }
        BitDepth::Sixteen => {
            let sample = |s: &[u8]| u16::from_ne_bytes([s[0], s[1]]);
            check_alpha(
                path,
                what,
                &buf,
                channels,
                |s| u32::from(sample(s)),
                2,
                65535,
            )?;
            convert(&buf, channels, 2, &mut img.data, |s| {
                f32::from(sample(s)) / 65535.0
            });
        }
    }
    Ok((img, depth))
}

/// Accept an alpha channel only when it is the same everywhere (it is then dropped).
fn check_alpha(
    path: &Path,
    what: &str,
    buf: &[u8],
    channels: usize,
    sample: impl Fn(&[u8]) -> u32 + Sync,
    bytes_per_sample: usize,
    max: u32,
) -> Result<()> {
    if channels != 2 && channels != 4 {
        return Ok(());
    }
    let px = channels * bytes_per_sample;
    let alpha_at = (channels - 1) * bytes_per_sample;
    let (lo, hi) = buf
        .par_chunks_exact(px)
        .map(|p| {
            let a = sample(&p[alpha_at..]);
            (a, a)
        })
        .reduce(
            || (u32::MAX, 0),
            |(l0, h0), (l1, h1)| (l0.min(l1), h0.max(h1)),
        );
    if lo < hi {
        return Err(Error::unsupported(
            path,
            format!(
                "{what} alpha varies over the image ({lo}..{hi} of {max}); only constant alpha is accepted"
            ),
        ));
    }
    Ok(())
}

/// Interleaved integer samples (1–4 channels) to RGB f32; grey is replicated, alpha dropped.
fn convert(
    buf: &[u8],
    channels: usize,
    bytes_per_sample: usize,
    out: &mut [f32],
    value: impl Fn(&[u8]) -> f32 + Sync,
) {
    let px = channels * bytes_per_sample;
    let b = bytes_per_sample;
    out.par_chunks_exact_mut(3)
        .zip(buf.par_chunks_exact(px))
        .for_each(|(o, p)| {
            if channels >= 3 {
                o[0] = value(&p[..b]);
                o[1] = value(&p[b..2 * b]);
                o[2] = value(&p[2 * b..3 * b]);
            } else {
                o.fill(value(&p[..b]));
            }
        });
}

pub(super) fn write(path: &Path, img: &Image, depth: BitDepth) -> Result<()> {
    let format = Format::from_path(path)?;
    if !matches!(format, Format::Png | Format::Tiff) {
        return Err(Error::encode(
            path,
            format!("{format:?} is not an 8/16-bit integer format (PNG or TIFF)"),
        ));
    }
    // ±Inf clamp to 0 or 1; NaN has no code value.
    if let Some(i) = img.data.iter().position(|v| v.is_nan()) {
        let count = img.data.iter().filter(|v| v.is_nan()).count();
        let p = i / 3;
        return Err(Error::encode(
            path,
            format!(
                "{count} NaN values cannot be quantised; first at x={}, y={}",
                p % img.width.max(1),
                p / img.width.max(1)
            ),
        ));
    }
    let too_big = || Error::encode(path, "image dimensions exceed 2^32 - 1");
    let w = u32::try_from(img.width).map_err(|_| too_big())?;
    let h = u32::try_from(img.height).map_err(|_| too_big())?;
    let max = depth.max_code();
    let quantise = move |v: f32| (v.clamp(0.0, 1.0) * max).round();

    let (buf, colour) = match depth {
        BitDepth::Eight => (
            img.data
                .par_iter()
                .map(|&v| quantise(v) as u8)
                .collect::<Vec<u8>>(),
            ExtendedColorType::Rgb8,
        ),
        BitDepth::Sixteen => {
            let mut buf = vec![0u8; img.data.len() * 2];
            buf.par_chunks_exact_mut(2)
                .zip(img.data.par_iter())
                .for_each(|(b, &v)| b.copy_from_slice(&(quantise(v) as u16).to_ne_bytes()));
            (buf, ExtendedColorType::Rgb16)
        }
    };

    let mut out = Cursor::new(Vec::with_capacity(buf.len() / 2 + 1024));
    let res = match format {
        Format::Png => PngEncoder::new(&mut out).write_image(&buf, w, h, colour),
        _ => TiffEncoder::new(&mut out).write_image(&buf, w, h, colour),
    };
    res.map_err(|e| Error::encode(path, e))?;
    super::atomic::write_atomic(path, &out.into_inner())
}
