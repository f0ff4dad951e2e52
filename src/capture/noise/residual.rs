//! Each frame of a bracket set against the merge of the set's other frames: a residual that
//! holds the device's noise without the scene, where the noise's spatial and channel
//! correlation are read (`calibrate brackets`, the device-output check).

use super::{FLAT_FRACTION, Planes, window};
use crate::capture::testset::binned_means;
use crate::error::Result;
use crate::io::Image;
use crate::sensor::profile::Response;

/// The central [`window`] of `img`.
pub(super) fn crop_window(img: &Image) -> Image {
    let (x0, y0, w, h) = window(img);
    if (w, h) == (img.width, img.height) {
        return img.clone();
    }
    Image::from_fn(w, h, |x, y| img.get(x0 + x, y0 + y))
}

/// A frame's residual against the other frames of its set: the frame's codes less the codes it
/// is expected to record at the radiance the others merge to. The scene cancels (the frames of
/// a set are aligned), so what remains is the frame's noise and the others' noise carried to
/// its exposure — the device's noise in both, with its spatial and channel correlation. Scene
/// texture, which a single frame's flat regions keep (it raises the low-order residual over
/// Immerkær's as correlated noise does), does not enter it.
pub(crate) struct CrossResidual {
    /// The frame's codes; 0 (outside every bin) where the others do not record the value.
    signal: Image,
    noise: Image,
}

impl CrossResidual {
    pub fn planes(&self) -> Planes<'_> {
        Planes {
            signal: &self.signal,
            noise: &self.noise,
            flat_fraction: FLAT_FRACTION,
            // The residual is not on a code lattice.
            quantum: 1e-7,
        }
    }
}

/// A frame's mean stored code against the value the other frames give it, in [`Self::BINS`]
/// even bins over [0, 1], empty bins interpolated between their neighbours (held flat beyond
/// the first and last): the code the frame is expected to record there, read from the frame
/// itself, so it holds whatever the response, its estimation error, clipping or the bias that
/// noise gives a code through a curved response — each a smooth function of the value that
/// would otherwise follow the scene into the residual.
struct ConditionalMean(Vec<f64>);

impl ConditionalMean {
    const BINS: usize = 256;

    fn at(&self, v: f64) -> f64 {
        let x = v.clamp(0.0, 1.0) * (Self::BINS - 1) as f64;
        let lo = (x.floor() as usize).min(Self::BINS - 1);
        let hi = (lo + 1).min(Self::BINS - 1);
        let f = x - lo as f64;
        self.0[lo] * (1.0 - f) + self.0[hi] * f
    }
}

/// [`ConditionalMean`] per channel of `code` against `at` (per value), over the values `keep`.
fn conditional_means(
    code: &Image,
    at: &[f64],
    keep: &dyn Fn(usize) -> bool,
) -> [ConditionalMean; 3] {
    let samples = code.data.iter().enumerate().filter(|&(k, _)| keep(k));
    binned_means(
        samples.map(|(k, &z)| (k, at[k], f64::from(z))),
        ConditionalMean::BINS,
    )
    .map(ConditionalMean)
}

/// [`CrossResidual`] of each of `codes` (a set's frames as stored, of 1, aligned; relative
/// exposure times `times`): the others merged by [`testset::hat_merge_covered`] after
/// `response`, the frame's expected codes its [`ConditionalMean`] at merged · its time.
pub(crate) fn cross_residuals(
    codes: &[Image],
    times: &[f64],
    response: &Response,
) -> Result<Vec<CrossResidual>> {
    use crate::capture::testset::{FIELD_GAMMA, hat_merge_covered};
    let inv_g = 1.0 / FIELD_GAMMA;
    let written: Vec<Image> = codes
        .iter()
        .map(|c| c.map(|z| (response.invert(f64::from(z)).clamp(0.0, 1.0) as f32).powf(inv_g)))
        .collect();
    let mut out = Vec::with_capacity(codes.len());
    for (i, code) in codes.iter().enumerate() {
        let others = |v: &[Image]| -> Vec<Image> {
            v.iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, x)| x.clone())
                .collect()
        };
        let t: Vec<f64> = (0..times.len())
            .filter(|&j| j != i)
            .map(|j| times[j])
            .collect();
        let (merged, covered) =
            hat_merge_covered(&others(&written), &others(codes), &t, FIELD_GAMMA)?;
        // The others' value at this frame's exposure, as written (γ 2.2: even bins in codes).
        let at: Vec<f64> = merged
            .data
            .iter()
            .map(|&m| (f64::from(m) * times[i]).max(0.0).powf(f64::from(inv_g)))
            .collect();
        let use_value = |k: usize| covered[k] && at[k] < 1.0;
        let table = conditional_means(code, &at, &use_value);
        let mut signal = code.clone();
        let mut noise = code.clone();
        for (k, (s, n)) in signal
            .data
            .iter_mut()
            .zip(noise.data.iter_mut())
            .enumerate()
        {
            *n = (f64::from(code.data[k]) - table[k % 3].at(at[k])) as f32;
            if !use_value(k) {
                *s = 0.0;
            }
        }
        out.push(CrossResidual { signal, noise });
    }
    Ok(out)
}
