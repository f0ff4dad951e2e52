//! Radiance RGBE (.hdr / .pic) through the `image` crate. Values are returned as stored (no
//! EXPOSURE header is applied), linear f32.

use super::Image;
use crate::error::{Error, Result};
use image::codecs::hdr::{HdrDecoder, HdrEncoder};
use image::{ImageDecoder, ImageError, Rgb};
use rayon::prelude::*;
use std::io::Cursor;
use std::path::Path;

fn image_err(path: &Path, e: ImageError) -> Error {
    match e {
        ImageError::Unsupported(u) => Error::unsupported(path, u),
        other => Error::decode(path, format!("Radiance HDR: {other}")),
    }
}

pub(super) fn decode(path: &Path, bytes: &[u8]) -> Result<Image> {
    // Strict first (needs the "#?RADIANCE"/"#?RGBE" signature); old .pic files have none.
    let mut decoder = match HdrDecoder::new(Cursor::new(bytes)) {
        Ok(d) => d,
        Err(strict_err) => HdrDecoder::new_nonstrict(Cursor::new(bytes))
            .map_err(|_| image_err(path, strict_err))?,
    };
    // The declared size is checked before anything is allocated (decompression bombs).
    let limits = super::limits::DecodeLimits::from_env()?;
    let (w, h) = decoder.dimensions();
    limits.check(path, "Radiance HDR", w.into(), h.into())?;
    decoder
        .set_limits(limits.to_image_limits())
        .map_err(|e| image_err(path, e))?;
    let (w, h) = (w as usize, h as usize);
    let total = usize::try_from(decoder.total_bytes())
        .map_err(|_| Error::unsupported(path, "Radiance HDR: image too large"))?;
    if total != w * h * 3 * 4 {
        return Err(Error::decode(path, "Radiance HDR: unexpected decoded size"));
    }
    let mut buf = vec![0u8; total];
    decoder
        .read_image(&mut buf)
        .map_err(|e| image_err(path, e))?;
    let mut img = Image::new(w, h);
    img.data
        .par_iter_mut()
        .zip(buf.par_chunks_exact(4))
        .for_each(|(d, b)| *d = f32::from_ne_bytes([b[0], b[1], b[2], b[3]]));
    Ok(img)
}

/// Largest value written; just below 2^127, where the encoder's exponent byte would wrap.
const RGBE_MAX: f32 = 1.7e38;

pub(super) fn write(path: &Path, img: &Image) -> Result<()> {
    if let Some((count, x, y)) = img.non_finite() {
        return Err(Error::encode(
            path,
            format!(
                "{count} non-finite values (NaN/Inf) cannot be stored in RGBE; first at x={x}, y={y}"
            ),
        ));
    }
    let pixels: Vec<Rgb<f32>> = img
        .data
        .par_chunks_exact(3)
        .map(|p| {
            // The encoder's exponent byte wraps outside 2^-128..2^127: flush values too small to
            // matter to 0 and clamp the (absurdly) large ones.
            let c = |v: f32| v.clamp(0.0, RGBE_MAX);
            let px = [c(p[0]), c(p[1]), c(p[2])];
            if px[0].max(px[1]).max(px[2]) < f32::MIN_POSITIVE {
                Rgb([0.0; 3])
            } else {
                Rgb(px)
            }
        })
        .collect();
    let mut out = Vec::with_capacity(img.pixel_count() * 4 + 128);
    HdrEncoder::new(&mut out)
        .encode(&pixels, img.width, img.height)
        .map_err(|e| Error::encode(path, e))?;
    super::atomic::write_atomic(path, &out)
}
