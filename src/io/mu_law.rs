//! The μ-law tone curve of the field's PSNR-T / SSIM-T, Wu et al.'s Network-2 loss and the
//! dataset previews: T(x) = log(1 + μx) / log(1 + μ), μ = 5000.

/// μ of the μ-law tone curve (`MU = 5000.` in Wu et al.'s `model.py`).
pub const MU: f64 = 5000.0;

/// The float types the curve is evaluated in: f64 for the metrics, f32 for previews (each in
/// its own precision, so results stay those of the spelled-out formula).
pub trait MuLawFloat: Copy + std::ops::Add<Output = Self> + std::ops::Mul<Output = Self> {
    const ONE: Self;
    const MU: Self;
    fn ln(self) -> Self;
    fn div(self, rhs: Self) -> Self;
}

impl MuLawFloat for f64 {
    const ONE: f64 = 1.0;
    const MU: f64 = MU;
    fn ln(self) -> f64 {
        f64::ln(self)
    }
    fn div(self, rhs: f64) -> f64 {
        self / rhs
    }
}

impl MuLawFloat for f32 {
    const ONE: f32 = 1.0;
    const MU: f32 = MU as f32;
    fn ln(self) -> f32 {
        f32::ln(self)
    }
    fn div(self, rhs: f32) -> f32 {
        self / rhs
    }
}

/// μ-law tone curve `log(1 + μx) / log(1 + μ)`: maps [0, 1] to [0, 1].
///
/// Negative values: not clamped here. T is negative on (−1/μ, 0) and NaN at and below −1/μ.
/// Callers that treat negative radiance as 0 (evaluated predictions, previews, the training
/// loss's tensor form `train::loss::mu_law`) clamp before; the metrics take the values as given
/// and refuse images with values at or below −1/μ.
#[inline]
pub fn mu_law(x: f64) -> f64 {
    curve(x)
}

/// [`mu_law`] evaluated in `F`'s own precision (f32 for previews).
#[inline]
pub fn curve<F: MuLawFloat>(x: F) -> F {
    // Spelled as numpy spells it (not ln_1p) so results agree to the last bit.
    (F::ONE + F::MU * x).ln().div((F::ONE + F::MU).ln())
}
