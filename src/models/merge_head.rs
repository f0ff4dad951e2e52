//! The merge heads of Network-2 (`output = "merge"` / `"kernel"`, docs/network2.md): the
//! network's last convolution corrects prior weights of its linearised inputs (the triangle's
//! or Robertson's, [`MergePrior`]), so the output is a convex combination of what the frames
//! hold.

use super::wu::{
    FRAME_CHANNELS, FRAMES, MERGE_PRIOR_EPS, MergePrior, OUTPUT_CHANNELS, TAPS, WuConfig, WuOutput,
};
use crate::kernels::pad::reflect_pad;
use burn::tensor::Tensor;

/// The γ that turns a frame's code into a stand-in for its exposure: z^(2γ) ∝ t² where the
/// scene is static (Wu's input curve; an sRGB frame is close to it).
const ROBERTSON_GAMMA: f64 = 2.2;

/// The triangle weights' share of Robertson's prior: nothing, except where every frame is
/// clipped and Robertson's weights all vanish.
const ROBERTSON_FALLBACK: f64 = 1e-12;

/// [`WuOutput::Merge`] and [`WuOutput::Kernel`]: the prior weights ([`prior_weights`])
/// corrected by `z` ([B, head_channels, H, W]; frame, then tap, then colour) through one
/// softmax over all frames and taps, applied to the HDR input channels of `x` (the unmapped
/// input), in the output unit (× `hdr_input_scale`).
pub(crate) fn merge(x: Tensor<4>, z: Tensor<4>, cfg: &WuConfig) -> Tensor<4> {
    let [b, _, h, w] = x.dims();
    let prior = prior_weights(&x, cfg.merge_prior).map(|w| w.add_scalar(MERGE_PRIOR_EPS).log());
    let output = cfg.output;
    // (logit, HDR values) per frame and tap: the centre taps only for `Merge`; for
    // `Kernel` each frame's 3×3 neighbourhood (reflected at the border), the centre tap
    // first, the others with the prior ε.
    let taps: Vec<(usize, usize)> = match output {
        WuOutput::Kernel => std::iter::once((1, 1))
            .chain((0..TAPS).map(|k| (k / 3, k % 3)).filter(|&t| t != (1, 1)))
            .collect(),
        _ => vec![(1, 1)],
    };
    let (mut logits, mut values) = (Vec::new(), Vec::new());
    for (i, p) in prior.iter().enumerate() {
        let hdr = x.clone().narrow(1, i * FRAME_CHANNELS + 3, 3);
        let padded = (taps.len() > 1).then(|| reflect_pad(hdr.clone(), (1, 1), (1, 1)));
        for (k, &(dy, dx)) in taps.iter().enumerate() {
            let zi = z
                .clone()
                .narrow(1, (i * taps.len() + k) * OUTPUT_CHANNELS, 3);
            let (l, v) = match &padded {
                Some(pd) if (dy, dx) != (1, 1) => (
                    zi.add_scalar(MERGE_PRIOR_EPS.ln()),
                    pd.clone().slice([0..b, 0..3, dy..dy + h, dx..dx + w]),
                ),
                _ => (zi + p.clone(), hdr.clone()),
            };
            logits.push(l);
            values.push(v);
        }
    }
    let top = logits[1..]
        .iter()
        .fold(logits[0].clone(), |m, l| m.max_pair(l.clone()));
    let (mut num, mut den) = (None::<Tensor<4>>, None::<Tensor<4>>);
    for (l, v) in logits.into_iter().zip(values) {
        let e = (l - top.clone()).exp();
        let term = e.clone() * v;
        num = Some(num.map_or(term.clone(), |n| n + term));
        den = Some(den.map_or(e.clone(), |d| d + e));
    }
    let (num, den) = (num.expect("three frames"), den.expect("three frames"));
    (num / den).mul_scalar(cfg.hdr_input_scale)
}

/// Per frame (short, reference, long) and colour channel, weights that sum to 1 over the
/// frames. Triangle: of the reference's code m (clamped to [0, 1]) the short frame gets
/// max(0, 2m − 1), the long max(0, 1 − 2m), the reference the rest. Robertson: each frame's
/// code z gives w(z)·z^(2γ), w OpenCV's `RobertsonWeights` as a function of z·255 (a Gaussian,
/// 0 at z = 0 and 1), normalised over the frames, with the triangle's weights × 1e-12 added so
/// that a pixel clipped in every frame keeps them.
fn prior_weights(x: &Tensor<4>, prior: MergePrior) -> [Tensor<4>; FRAMES] {
    let code = |i: usize| x.clone().narrow(1, i * FRAME_CHANNELS, 3).clamp(0.0, 1.0);
    let mid = code(1);
    let short = mid.clone().sub_scalar(0.5).clamp_min(0.0).mul_scalar(2.0);
    let long = mid.neg().add_scalar(0.5).clamp_min(0.0).mul_scalar(2.0);
    let middle = (short.clone() + long.clone()).neg().add_scalar(1.0);
    let triangle = [short, middle, long];
    if prior == MergePrior::Triangle {
        return triangle;
    }
    let e4 = 4f64.exp();
    let (s, c) = (e4 / (e4 - 1.0), 1.0 / (1.0 - e4));
    let raw: Vec<Tensor<4>> = triangle
        .into_iter()
        .enumerate()
        .map(|(i, tri)| {
            let z = code(i);
            // z·255 / (255/4) − 2 = 4z − 2.
            let d = z.clone().mul_scalar(4.0).sub_scalar(2.0);
            let w = (d.clone() * d)
                .neg()
                .exp()
                .mul_scalar(s)
                .add_scalar(c)
                .clamp_min(0.0);
            w * z.powf_scalar(2.0 * ROBERTSON_GAMMA) + tri.mul_scalar(ROBERTSON_FALLBACK)
        })
        .collect();
    let sum = raw[1..].iter().fold(raw[0].clone(), |a, r| a + r.clone());
    let mut it = raw.into_iter().map(|r| r / sum.clone());
    [(); FRAMES].map(|_| it.next().expect("three frames"))
}
