//! The curve that turned linear signal into a set of frames' code values: what a network was
//! trained on and what a test set's frames hold. A network meets at test time the curve it
//! was trained on only when the two agree; `hdrsynth eval` compares them and warns.
//!
//! Where the curve is read from:
//! - a bracket test set (`testset --brackets`): `encoding.toml`, written with the frames;
//! - a test set rendered from real radiance (`testset`): its recipe's profile response;
//! - a pure training dataset (hdrsynth's layout): its manifest's display curve;
//! - a realistic training run: its profile's device response (`train::frame_encoding`).
//!
//! Kalantari's and Wu's datasets are camera JPEGs whose curves nobody recorded: unknown.

use crate::data::layout::hdrsynth as own;
use crate::data::testset::{RECIPE, Recipe};
use crate::error::{Error, Result};
use crate::sensor::profile::Response;
use crate::sensor::response::ToneCurve;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// `OUT/encoding.toml` of a bracket test set.
pub const ENCODING_FILE: &str = "encoding.toml";
pub const FORMAT: &str = "hdrsynth-encoding/1";
/// Two curves differ when they put one linear value more than this many code units apart
/// (of 1): two 8-bit codes, above JPEG rounding and the LUT sampling of estimated curves.
pub const TOLERANCE: f64 = 2.0 / 255.0;

/// A set of frames' encoding: code = `response`(linear), linear 1 = the clipping white.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameEncoding {
    pub format: String,
    /// Where the curve comes from, for reports.
    pub source: String,
    pub response: Response,
}

impl FrameEncoding {
    pub fn new(source: impl Into<String>, response: Response) -> FrameEncoding {
        FrameEncoding {
            format: FORMAT.into(),
            source: source.into(),
            response,
        }
    }

    pub fn describe(&self) -> String {
        format!("{} ({})", self.response.label(), self.source)
    }

    pub fn save(&self, dir: &Path) -> Result<()> {
        let path = dir.join(ENCODING_FILE);
        let text = toml::to_string(self).map_err(|e| Error::encode(&path, e))?;
        crate::io::atomic::write_atomic(&path, text.as_bytes())
    }

    pub fn load(path: &Path) -> Result<FrameEncoding> {
        let e: FrameEncoding = crate::config::load_toml(path)?;
        if e.format != FORMAT {
            return Err(Error::layout(
                path,
                format!("format '{}' is not '{FORMAT}'", e.format),
            ));
        }
        Ok(e)
    }

    /// The engine's display curve as an encoding with white 1: code = tone(x · saturation).
    pub fn of_tone_curve(curve: ToneCurve, source: &str) -> FrameEncoding {
        let response = match curve {
            ToneCurve::Linear => Response::Linear,
            ToneCurve::Srgb => Response::Srgb,
            ToneCurve::Filmic => {
                let s = curve.saturation();
                let n = 1024;
                Response::Lut {
                    lut: (0..=n)
                        .map(|i| f64::from(curve.apply(i as f32 / n as f32 * s)))
                        .collect(),
                }
            }
        };
        FrameEncoding::new(source, response)
    }
}

/// The largest difference in code value (of 1) between two curves over linear [0, 1].
pub fn max_code_difference(a: &Response, b: &Response) -> f64 {
    let n = 4096;
    (0..=n)
        .map(|i| {
            let x = i as f64 / n as f64;
            (a.apply(x) - b.apply(x)).abs()
        })
        .fold(0.0, f64::max)
}

/// The warning for a network trained on `trained` scored on frames encoded with `test`; None
/// when the curves agree within [`TOLERANCE`].
pub fn mismatch(trained: &FrameEncoding, test: &FrameEncoding) -> Option<String> {
    let d = max_code_difference(&trained.response, &test.response);
    (d > TOLERANCE).then(|| {
        format!(
            "the network was trained on frames encoded with {}, but the test set's frames are \
             encoded with {}: they differ by up to {:.1} 8-bit codes, so the network meets a \
             curve it was not trained on (a test set's curve is fixed when it is made: \
             testset --brackets --encode, or the profile of testset --radiance; \
             docs/your_device.md)",
            trained.describe(),
            test.describe(),
            d * 255.0
        )
    })
}

/// A test set's encoding: a bracket test set's `encoding.toml`, a rendered test set's profile
/// response; None where nothing records it (Kalantari's and Wu's camera JPEGs).
pub fn of_testset(dir: &Path) -> Result<Option<FrameEncoding>> {
    let file = dir.join(ENCODING_FILE);
    if file.is_file() {
        return FrameEncoding::load(&file).map(Some);
    }
    let recipe = dir.join(RECIPE);
    if recipe.is_file() {
        let r: Recipe = crate::config::load_toml(&recipe)?;
        return Ok(Some(FrameEncoding::new(
            format!("the device response of profile '{}'", r.profile.name),
            r.profile.response,
        )));
    }
    Ok(None)
}

/// A dataset's display frames' encoding as pure training reads them: hdrsynth's manifest
/// curve, or the record of a set folder built from a device's brackets (a loop's
/// calibration scenes); None for other layouts.
pub fn of_dataset(dir: &Path) -> Result<Option<FrameEncoding>> {
    if !dir.join(own::MANIFEST).is_file() {
        return of_testset(dir);
    }
    let m = own::read_manifest(dir)?;
    let name = match m.tone_curve {
        ToneCurve::Filmic => "filmic",
        ToneCurve::Srgb => "srgb",
        ToneCurve::Linear => "linear",
    };
    Ok(Some(FrameEncoding::of_tone_curve(
        m.tone_curve,
        &format!("the {name} display curve of dataset {}", dir.display()),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_and_gamma_22_differ_near_black() {
        // IEC 61966-2-1 at x = 0.001: 12.92 · 0.001 = 0.01292; 0.001^(1/2.2) = 0.04329.
        let d = max_code_difference(&Response::Srgb, &Response::Gamma { gamma: 2.2 });
        assert!(d >= 0.04329 - 0.01292 - 1e-4, "{d}");
        let a = FrameEncoding::new("a", Response::Srgb);
        let b = FrameEncoding::new("b", Response::Gamma { gamma: 2.2 });
        assert!(mismatch(&a, &b).is_some());
        assert!(mismatch(&a, &a).is_none());
    }

    #[test]
    fn a_sampled_srgb_agrees_with_srgb() {
        let lut = (0..=1024)
            .map(|i| Response::Srgb.apply(i as f64 / 1024.0))
            .collect();
        let d = max_code_difference(&Response::Srgb, &Response::Lut { lut });
        assert!(d < TOLERANCE, "{d}");
    }
}
