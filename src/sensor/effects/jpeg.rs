//! `jpeg`: the device stores its frames as JPEG at IJG quality `quality` (1–100): the 8-bit
//! output frame is encoded with libjpeg's scaled Annex K tables and decoded again (the
//! `image` crate's baseline encoder, 4:4:4), the last stage of the realism operator. Its
//! block grid starts at the frame's (or the training crop's) top-left corner.
//!
//! Raw bursts cannot show it. Its statistic is the device-output check's blockiness of the
//! frames' residuals (src/capture/output/jpeg.rs), and its parameter is read from the
//! frames' own quantisation tables (`io::jpeg::file_quality`), not fitted.

use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary, not_fitted, table};
use crate::error::Result;
use crate::io::Image;

pub const ID: &str = id::JPEG;

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "JPEG storage at an IJG quality (8-bit output encoded and decoded again)",
    needs: "a folder of JPEG brackets (the device-output check: `diagnose --brackets \
            --device-output`, `hdrsynth loop`)",
    statistics,
    fit,
    adjust: None,
};

fn statistics(_: &Protocol, _: &[Summary], _: &mut Vec<Stat>) {}

fn fit(_: &FitCtx) -> Result<toml::Table> {
    Err(not_fitted(
        ID,
        "an output-domain effect: read from a JPEG bracket folder's quantisation tables",
    ))
}

/// The effect's table at `quality`.
pub fn params(quality: u32) -> toml::Table {
    table(&[("quality", toml::Value::Integer(i64::from(quality)))])
}

/// `img` (codes in [0, 1]) through a JPEG encode and decode at `quality`. A frame JPEG cannot
/// hold (a side of 0 or over 65,535 pixels) is left as it is.
pub fn round_trip(img: &mut Image, quality: u8) {
    use image::ImageEncoder;
    let (w, h) = (img.width, img.height);
    if w == 0 || h == 0 || w > 65_535 || h > 65_535 {
        return;
    }
    let bytes: Vec<u8> = img
        .data
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    let mut buf = Vec::new();
    let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, quality);
    if enc
        .write_image(&bytes, w as u32, h as u32, image::ExtendedColorType::Rgb8)
        .is_err()
    {
        return;
    }
    let Ok(back) = image::load_from_memory_with_format(&buf, image::ImageFormat::Jpeg) else {
        return;
    };
    for (o, v) in img.data.iter_mut().zip(back.to_rgb8().as_raw()) {
        *o = f32::from(*v) / 255.0;
    }
}
