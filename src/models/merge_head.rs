//! The merge heads of Network-2 (`output = "merge"` / `"kernel"`, docs/network2.md): the
//! network's last convolution corrects the triangle weights of its linearised inputs, so the
//! output is a convex combination of what the frames hold.

use super::wu::{FRAME_CHANNELS, MERGE_PRIOR_EPS, OUTPUT_CHANNELS, TAPS, WuOutput};
use crate::kernels::pad::reflect_pad;
use burn::tensor::Tensor;

/// [`WuOutput::Merge`] and [`WuOutput::Kernel`]: the triangle weights of the reference
/// frame's code (clamped to [0, 1]) corrected by `z` ([B, head_channels, H, W]; frame, then
/// tap, then colour) through one softmax over all frames and taps, applied to the HDR input
/// channels of `x` (the unmapped input), in the output unit (× `hdr_input_scale`).
pub(crate) fn merge(x: Tensor<4>, z: Tensor<4>, output: WuOutput, scale: f64) -> Tensor<4> {
    let [b, _, h, w] = x.dims();
    let mid = x.clone().narrow(1, FRAME_CHANNELS, 3).clamp(0.0, 1.0);
    let short = mid.clone().sub_scalar(0.5).clamp_min(0.0).mul_scalar(2.0);
    let long = mid.neg().add_scalar(0.5).clamp_min(0.0).mul_scalar(2.0);
    let middle = (short.clone() + long.clone()).neg().add_scalar(1.0);
    let prior = [short, middle, long].map(|w| w.add_scalar(MERGE_PRIOR_EPS).log());
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
    (num / den).mul_scalar(scale)
}
