//! Fitting the colour correction: T (3×3, the paper's Eq. 1, real = T · synthetic) and the
//! root-polynomial by least squares, ΔE00 before, after and leave-one-patch-out, the chart fit
//! that `calibrate colour` and `diagnose` share (patch means → white balance → exposure → T),
//! applying a fit to images, and T from a published camera matrix.
#![allow(clippy::needless_range_loop)]

use super::chart;
use super::cie::{SRGB_TO_XYZ, delta_e_linear_srgb};
use crate::error::{Error, Result};
use crate::io::Image;
use crate::linalg::{Mat3, least_squares, mat_vec, mul3};
use rayon::prelude::*;

/// Sign-preserving power sign(a)·|a|^p, colour-science's `spow` (its default, enabled).
pub fn spow(a: f64, p: f64) -> f64 {
    let r = a.signum() * a.abs().powf(p);
    if a == 0.0 || r.is_nan() { 0.0 } else { r }
}

/// Root-polynomial degree-2 terms of Finlayson et al. 2015: R, G, B, √RG, √GB, √RB, the square
/// roots taken with [`spow`] (sign-preserving) as colour-science's
/// `polynomial_expansion_Finlayson2015(RGB, 2)` does, so negative inputs give finite terms.
pub fn root_polynomial_terms(rgb: [f64; 3]) -> [f64; 6] {
    let [r, g, b] = rgb;
    [
        r,
        g,
        b,
        spow(r * g, 0.5),
        spow(g * b, 0.5),
        spow(r * b, 0.5),
    ]
}

/// Which colour correction to fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// 3×3 T, real = T · synthetic (the paper's Eq. 1).
    Matrix,
    /// 3×6 root-polynomial degree 2, real = M · terms(synthetic).
    RootPolynomial,
}

impl Model {
    pub fn terms(self) -> usize {
        match self {
            Model::Matrix => 3,
            Model::RootPolynomial => 6,
        }
    }
    fn expand(self, rgb: [f64; 3]) -> Vec<f64> {
        match self {
            Model::Matrix => rgb.to_vec(),
            Model::RootPolynomial => root_polynomial_terms(rgb).to_vec(),
        }
    }
}

/// A fitted correction.
#[derive(Clone, Debug, PartialEq)]
pub enum Fitted {
    Matrix(Mat3),
    RootPolynomial([[f64; 6]; 3]),
}

impl Fitted {
    pub fn apply(&self, rgb: [f64; 3]) -> [f64; 3] {
        match self {
            Fitted::Matrix(t) => mat_vec(t, rgb),
            Fitted::RootPolynomial(m) => apply_root_polynomial(m, rgb),
        }
    }
    pub fn model(&self) -> Model {
        match self {
            Fitted::Matrix(_) => Model::Matrix,
            Fitted::RootPolynomial(_) => Model::RootPolynomial,
        }
    }
}

pub fn apply_matrix(t: &Mat3, rgb: [f64; 3]) -> [f64; 3] {
    mat_vec(t, rgb)
}

pub fn apply_root_polynomial(m: &[[f64; 6]; 3], rgb: [f64; 3]) -> [f64; 3] {
    let e = root_polynomial_terms(rgb);
    std::array::from_fn(|i| (0..6).map(|k| m[i][k] * e[k]).sum())
}

/// Fit `model` so that real ≈ correction(synthetic), least squares over the patches.
pub fn fit(model: Model, synthetic: &[[f64; 3]], real: &[[f64; 3]]) -> Result<Fitted> {
    let a: Vec<Vec<f64>> = synthetic.iter().map(|&s| model.expand(s)).collect();
    let x = least_squares("colour fit (patches → terms)", &a, real)?;
    Ok(match model {
        Model::Matrix => Fitted::Matrix(std::array::from_fn(|i| std::array::from_fn(|k| x[k][i]))),
        Model::RootPolynomial => {
            Fitted::RootPolynomial(std::array::from_fn(|i| std::array::from_fn(|k| x[k][i])))
        }
    })
}

/// T (3×3), real = T · synthetic, least squares (colour-science `matrix_colour_correction`,
/// method 'Finlayson 2015', degree 1).
pub fn fit_matrix(synthetic: &[[f64; 3]], real: &[[f64; 3]]) -> Result<Mat3> {
    match fit(Model::Matrix, synthetic, real)? {
        Fitted::Matrix(t) => Ok(t),
        Fitted::RootPolynomial(_) => unreachable!("matrix model fits a matrix"),
    }
}

/// Root-polynomial degree-2 matrix (3×6), colour-science 'Finlayson 2015', degree 2.
pub fn fit_root_polynomial(synthetic: &[[f64; 3]], real: &[[f64; 3]]) -> Result<[[f64; 6]; 3]> {
    match fit(Model::RootPolynomial, synthetic, real)? {
        Fitted::RootPolynomial(m) => Ok(m),
        Fitted::Matrix(_) => unreachable!("root-polynomial model fits a 3×6 matrix"),
    }
}

/// Per-patch ΔE00 with mean and max.
#[derive(Clone, Debug, PartialEq)]
pub struct DeltaE {
    pub per_patch: Vec<f64>,
    pub mean: f64,
    pub max: f64,
}

impl DeltaE {
    pub fn from_values(per_patch: Vec<f64>) -> DeltaE {
        let n = per_patch.len().max(1) as f64;
        let mean = per_patch.iter().sum::<f64>() / n;
        let max = per_patch.iter().fold(0.0f64, |m, &v| m.max(v));
        DeltaE {
            per_patch,
            mean,
            max,
        }
    }
}

/// ΔE00 per pair, both colours treated as linear sRGB (D65).
pub fn delta_e_sets(a: &[[f64; 3]], b: &[[f64; 3]]) -> DeltaE {
    DeltaE::from_values(
        a.iter()
            .zip(b)
            .map(|(&x, &y)| delta_e_linear_srgb(x, y))
            .collect(),
    )
}

/// Leave-one-patch-out: for each patch, fit on the others and measure ΔE00 of the held-out one.
pub fn leave_one_out(model: Model, synthetic: &[[f64; 3]], real: &[[f64; 3]]) -> Result<DeltaE> {
    let n = synthetic.len();
    let mut out = Vec::with_capacity(n);
    for held in 0..n {
        let s: Vec<[f64; 3]> = (0..n)
            .filter(|&i| i != held)
            .map(|i| synthetic[i])
            .collect();
        let r: Vec<[f64; 3]> = (0..n).filter(|&i| i != held).map(|i| real[i]).collect();
        let f = fit(model, &s, &r)?;
        out.push(delta_e_linear_srgb(f.apply(synthetic[held]), real[held]));
    }
    Ok(DeltaE::from_values(out))
}

/// A fit with its ΔE00 before (identity), after (in-sample) and leave-one-out.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    pub fitted: Fitted,
    pub before: DeltaE,
    pub after: DeltaE,
    pub loo: DeltaE,
}

pub fn fit_and_evaluate(
    model: Model,
    synthetic: &[[f64; 3]],
    real: &[[f64; 3]],
) -> Result<Evaluation> {
    let fitted = fit(model, synthetic, real)?;
    let corrected: Vec<[f64; 3]> = synthetic.iter().map(|&s| fitted.apply(s)).collect();
    Ok(Evaluation {
        before: delta_e_sets(synthetic, real),
        after: delta_e_sets(&corrected, real),
        loo: leave_one_out(model, synthetic, real)?,
        fitted,
    })
}

/// White balance of the real patches before a chart fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum WhiteBalance {
    /// Scale the real channels so the mean of neutral patches 20–23 is neutral.
    Neutral,
    /// Use the real colours as they are.
    None,
}

/// A chart fit: the patch colours as fitted and the corrections fitted to them.
#[derive(Clone, Debug)]
pub struct ChartFit {
    /// Synthetic and real patch colours as fitted (after white balance and scaling).
    pub synthetic: Vec<[f64; 3]>,
    pub real: Vec<[f64; 3]>,
    pub white_balance_gains: [f64; 3],
    /// Scale applied to the white-balanced real patches to match the synthetic exposure.
    pub exposure_scale: f64,
    /// Scale applied to both sets so the synthetic neutrals match their reference reflectance.
    pub chart_scale: f64,
    /// T (3×3).
    pub matrix: Evaluation,
    /// The root-polynomial, when asked for.
    pub root_polynomial: Option<Evaluation>,
}

impl ChartFit {
    /// T (real = T · synthetic).
    pub fn t(&self) -> Mat3 {
        match &self.matrix.fitted {
            Fitted::Matrix(t) => *t,
            Fitted::RootPolynomial(_) => unreachable!("matrix evaluation holds a matrix"),
        }
    }
}

/// Why a chart fit failed; the caller says which capture it was.
#[derive(Debug, thiserror::Error)]
pub enum ChartFitError {
    /// `chart::neutral_gains` refused the real patches.
    #[error("white balance: {0}")]
    WhiteBalance(Error),
    #[error(
        "the neutral patches 20–23 average {real:.5} (real) and {synthetic:.5} (synthetic); \
         both must be > 0 (chart located correctly? black level right?)"
    )]
    NeutralMean { real: f64, synthetic: f64 },
    #[error(transparent)]
    Fit(#[from] Error),
}

/// Fit T (and the root-polynomial if asked) from the 24 patch means of a real chart and of the
/// synthetic one it should match. The real patches are white-balanced (`white_balance`), then
/// scaled by one factor so the mean of patches 20–23 (all channels) equals the synthetic one;
/// then both sets are scaled by one common factor so the synthetic neutrals match their
/// reference reflectance (ΔE00 is then on the chart's scale; T does not depend on it).
pub fn fit_chart(
    real: &[[f64; 3]],
    synthetic: &[[f64; 3]],
    white_balance: WhiteBalance,
    root_polynomial: bool,
) -> Result<ChartFit, ChartFitError> {
    let gains = match white_balance {
        WhiteBalance::Neutral => chart::neutral_gains(real).map_err(ChartFitError::WhiteBalance)?,
        WhiteBalance::None => [1.0; 3],
    };
    let balanced: Vec<[f64; 3]> = real
        .iter()
        .map(|p| std::array::from_fn(|c| p[c] * gains[c]))
        .collect();
    let (nr, ns) = (
        chart::neutral_mean(&balanced),
        chart::neutral_mean(synthetic),
    );
    if !(nr > 0.0 && ns > 0.0) {
        return Err(ChartFitError::NeutralMean {
            real: nr,
            synthetic: ns,
        });
    }
    let k = ns / nr;
    let s = chart::neutral_mean(&chart::reference_linear_srgb()) / ns;
    let scale = |v: &[f64; 3], f: f64| -> [f64; 3] { std::array::from_fn(|c| v[c] * f) };
    let real_fit: Vec<[f64; 3]> = balanced.iter().map(|p| scale(p, k * s)).collect();
    let syn_fit: Vec<[f64; 3]> = synthetic.iter().map(|p| scale(p, s)).collect();
    let matrix = fit_and_evaluate(Model::Matrix, &syn_fit, &real_fit)?;
    let root_polynomial = if root_polynomial {
        Some(fit_and_evaluate(
            Model::RootPolynomial,
            &syn_fit,
            &real_fit,
        )?)
    } else {
        None
    };
    Ok(ChartFit {
        synthetic: syn_fit,
        real: real_fit,
        white_balance_gains: gains,
        exposure_scale: k,
        chart_scale: s,
        matrix,
        root_polynomial,
    })
}

/// Apply a 3×3 matrix to every pixel.
pub fn apply_matrix_image(t: &Mat3, img: &Image) -> Image {
    map_pixels(img, |p| apply_matrix(t, p))
}

/// Apply a root-polynomial matrix to every pixel.
pub fn apply_root_polynomial_image(m: &[[f64; 6]; 3], img: &Image) -> Image {
    map_pixels(img, |p| apply_root_polynomial(m, p))
}

fn map_pixels(img: &Image, f: impl Fn([f64; 3]) -> [f64; 3] + Sync) -> Image {
    let mut out = img.clone();
    out.data.par_chunks_mut(3).for_each(|p| {
        let v = f([p[0] as f64, p[1] as f64, p[2] as f64]);
        for c in 0..3 {
            p[c] = v[c] as f32;
        }
    });
    out
}

/// T from a published XYZ→camera colour matrix (Adobe DNG `ColorMatrix`, the dcraw/LibRaw
/// `adobe_coeff` table): camera = M · XYZ, so camera = M · SRGB_TO_XYZ · linear sRGB; rows are
/// then scaled to sum to 1 so that a neutral stays neutral (white-balanced camera RGB, the
/// profile's convention), exactly as dcraw normalises its `cam_rgb`.
pub fn t_from_camera_xyz(cam_xyz: &Mat3) -> Result<Mat3> {
    let m = mul3(cam_xyz, &SRGB_TO_XYZ);
    let mut t = m;
    for row in &mut t {
        let s: f64 = row.iter().sum();
        if s.abs() < 1e-9 {
            return Err(Error::key(
                "colour matrix",
                "a row sums to 0: cannot white-balance",
            ));
        }
        for v in row.iter_mut() {
            *v /= s;
        }
    }
    Ok(t)
}
