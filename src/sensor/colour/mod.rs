//! Colour calibration: the ColorChecker24 reference, colour maths (linear sRGB → XYZ → CIE Lab,
//! CIEDE2000), the least-squares fit of T (the paper's Eq. 1, real = T · synthetic) and its
//! root-polynomial variant, ΔE00 reports with leave-one-patch-out, synthetic chart rendering and
//! robust patch sampling (full frame or four corners through a homography).
//!
//! Conventions (see docs/colour.md):
//! - Linear sRGB is linear RGB with Rec. 709 primaries and D65 white, converted to XYZ with
//!   colour-science's sRGB matrix (IEC 61966-2-1, 4 decimals). Lab is CIE 1976 L*a*b* relative to
//!   D50, reached from D65 XYZ by the Bradford chromatic adaptation built exactly as colour-science
//!   builds it (`matrix_chromatic_adaptation_VonKries(..., 'Bradford')`). The D50 white is the
//!   ColorChecker dataset's own (xy 0.345702914918791, 0.358538596679933; XYZ 0.9642, 1, 0.8249,
//!   the ICC PCS white), so the shipped reference linear sRGB maps back to the shipped Lab.
//! - ΔE00 of a fit is always computed on colours treated as linear sRGB (D65), for the real and the
//!   synthetic set alike: device RGB is white-balanced camera RGB, not sRGB, so the number is a
//!   perceptual yardstick for the fit residual, not a colorimetric error of the camera.
//! - Chart geometry: the 24 patches form a 6 × 4 grid of equal cells in reading order (patch 1
//!   "dark skin" top-left, patch 24 "black" bottom-right). Image coordinates are continuous pixel
//!   coordinates: x right, y down, the image spans [0, W] × [0, H], pixel (i, j) covers
//!   [i, i + 1) × [j, j + 1) with its centre at (i + 0.5, j + 0.5).
//!
//! Where: `chart` (the ColorChecker24 reference, white balance on its neutral patches, the
//! rendered chart, locating and sampling the chart in an image), `cie` (linear sRGB → XYZ → Lab,
//! Bradford, CIEDE2000), `fit` (T and the root-polynomial by least squares, ΔE00 reports with
//! leave-one-patch-out, `fit_chart`: chart patch means → white balance → exposure → T, shared by
//! `calibrate colour` and `diagnose`, T from a published camera matrix), `calibrate`
//! (`calibrate colour`: a chart capture → T, written into a sensor profile).

pub mod calibrate;
pub mod chart;
pub mod cie;
pub mod fit;

use crate::error::{Error, Result};

/// Parse `n` comma-separated numbers.
/// `what` names the value (a flag or a key) in the error.
pub fn parse_floats(s: &str, n: usize, what: &str) -> Result<Vec<f64>> {
    floats(s, n).ok_or_else(|| Error::key(what, expected_floats(s, n)))
}

/// `n` comma-separated finite numbers, or None.
pub(crate) fn floats(s: &str, n: usize) -> Option<Vec<f64>> {
    let v: std::result::Result<Vec<f64>, _> =
        s.split(',').map(|t| t.trim().parse::<f64>()).collect();
    v.ok()
        .filter(|v| v.len() == n && v.iter().all(|x| x.is_finite()))
}

/// What [`parse_floats`] says of `s` when it holds no `n` numbers.
pub(crate) fn expected_floats(s: &str, n: usize) -> String {
    format!("expected {n} comma-separated numbers, got '{s}'")
}
