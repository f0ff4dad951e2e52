//! Network-2: Wu et al., "Deep High Dynamic Range Imaging with Large Foreground Motions" (ECCV
//! 2018), as released by the authors (TensorFlow `model.py` / `ops.py` of elliottwu/DeepHDR),
//! in its ResNet form and the paper's U-Net form. See docs/network2.md for the sources, the
//! differences between paper and code, and the weight naming scheme of [`import_weights`].
//!
//! Input: `[B, 18, H, W]` exactly as `data::loader` produces Network-2 samples: per frame
//! i = 0, 1, 2 (EV −2, 0, +2) three channels LDR in [0, 1], then three channels LDR^2.2 / tᵢ. The
//! forward maps every channel to x·2 − 1 (HDR channels first multiplied by
//! [`WuConfig::hdr_input_scale`]); values above 1 (HDR of the short frame, up to 1/t = 4) are not
//! clipped, as in the released code. Output: `[B, 3, H, W]` linear HDR in [0, 1] ((tanh + 1) / 2).
//!
//! Layers (b = `base_width`, 64 by default; every 5×5 convolution has stride 2 and TensorFlow
//! 'SAME'-sized reflection padding; every convolution has a bias, even before a BatchNorm):
//! - encoder i (weights not shared): e_i1 = conv(xᵢ, b); e_i2 = BN(conv(lrelu(e_i1), 2b));
//! - merger: E2 = cat(e_12, e_22, e_32) (6b);
//!   - ResNet: e3 = BN(conv(lrelu(E2), 4b)); r ← e3; 9 × r ← relu(r) + F(relu(r)) with
//!     F(x) = BN(conv3×3(pad(relu(BN(conv3×3(pad(x))))))) (stride 1, reflect padding 1);
//!     bottom = cat(r, e3);
//!   - U-Net: x₁ = BN(conv(lrelu(E2), m₁)), xₖ = BN(conv(lrelu(xₖ₋₁), mₖ)) for the
//!     `unet_merger_widths` mₖ (× b); bottom = x_K;
//! - decoder: cur ← bottom; per level: y = BN(deconv5×5 s2(relu(cur))), cur = cat(y, skip), with
//!   skips (deepest first) x_{K−1} … x₁ (U-Net only), E2, E1 = cat(e_11, e_21, e_31), none; the
//!   deconvolution widths mirror the skips (…, 2b, b) and the last one is b;
//!   out = tanh(conv5×5 stride 1(relu(cur), 3)).
//!
//! BatchNorm uses batch statistics (and updates its running statistics with TensorFlow's decay
//! 0.9, Burn momentum 0.1) when the input lives on an autodiff device, the running statistics
//! otherwise; call `model.valid()` for inference on an autodiff device.

use super::merge_head;
use crate::config::{KeyError, Range, each_in_range, in_range};
use crate::error::{Error, Result};
use crate::kernels::activation::leaky_relu;
use crate::kernels::batch_norm::{batch_norm, batch_norm_relu};
use crate::kernels::conv::{conv_transpose2d, conv2d};
use crate::kernels::pad::reflect_pad;
use crate::sensor::profile::Response;
use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig, ConvTranspose2d, ConvTranspose2dConfig};
use burn::nn::{BatchNorm, BatchNormConfig, Initializer, PaddingConfig2d};
use burn::tensor::activation::{relu, tanh};
use burn::tensor::{Device, Tensor, TensorData};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Input channels: 3 frames × (LDR RGB, HDR RGB).
pub const INPUT_CHANNELS: usize = 18;
/// Frames (EV −2, 0, +2), each with its own encoder.
pub const FRAMES: usize = 3;
/// Channels per frame: LDR RGB then LDR^2.2 / t.
pub const FRAME_CHANNELS: usize = 6;
/// Output channels (linear RGB).
pub const OUTPUT_CHANNELS: usize = 3;
/// Leaky ReLU slope of the encoders (`ops.lrelu`, leak 0.2).
pub const LEAK: f64 = 0.2;
/// BatchNorm ε (`ops.batch_norm`, epsilon 1e-5).
pub const BN_EPSILON: f64 = 1e-5;
/// TensorFlow's BatchNorm decay (`ops.batch_norm`, momentum 0.9): running = 0.9·running +
/// 0.1·batch. Burn's `momentum` weighs the batch instead, so Burn gets 1 − 0.9.
pub const TF_BN_DECAY: f64 = 0.9;
/// Standard deviation of the authors' weight initialisation (`ops.conv2d`, stddev 0.02).
pub const INIT_STD: f64 = 0.02;

/// What the last convolution predicts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WuOutput {
    /// The HDR image itself, (tanh + 1) / 2: Wu et al.'s network as released.
    #[default]
    Image,
    /// Per pixel and colour channel, corrections to the triangle weights of the three
    /// linearised input frames (Kalantari & Ramamoorthi's "weight estimator" reading of the
    /// merge): out = Σᵢ softmaxᵢ(ln(wᵢ + ε) + zᵢ)·HDRᵢ, wᵢ the triangle weights of the
    /// reference frame's code. The last convolution starts at zero, so an untrained network is
    /// the triangle merge of its inputs; training can only move it from there.
    Merge,
    /// As `Merge` over each frame's 3×3 neighbourhood (a kernel-predicting merge, after
    /// Mildenhall et al.'s burst denoising): 27 weights per pixel and colour channel, the
    /// centre taps' prior the triangle weights and the others' ε, so the untrained network is
    /// again the triangle merge; spatial averaging lets it denoise as well as weigh.
    Kernel,
}

/// The per-frame weights the merge heads start from and correct.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MergePrior {
    /// Kalantari & Ramamoorthi's triangle weights of the reference frame's code: the reference
    /// alone in its mid-tones, so the prior is ghost-free there and as noisy as that frame.
    #[default]
    Triangle,
    /// OpenCV `MergeRobertson`'s weights tᵢ²·w(zᵢ) of each frame's own code (w the Gaussian
    /// of `evaluate::robertson_weight`, 0 at the clipped codes), tᵢ² read off the frame as
    /// zᵢ^(2·2.2) (∝ tᵢ² wherever the scene is static, so no exposure time is needed);
    /// normalised over the frames, then + ε as the triangle's. Every unclipped frame
    /// contributes, the longer exposure most: the static merge with the least noise, which
    /// ghosts where subjects move until training learns to drop the frames that disagree.
    /// Where every frame is clipped the triangle weights decide.
    Robertson,
}

/// Where the curve of the HDR input channels (LDR → linear, then / t) comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Linearise {
    /// `input_response` as configured (γ 2.2 by default: Wu et al.'s LDR^2.2).
    #[default]
    Fixed,
    /// The training frames' own curve (the profile's device response, or a pure dataset's
    /// display curve), written into `input_response` by the trainer, so the checkpoint keeps it
    /// and inference linearises as training did.
    Data,
}

/// Taps of [`WuOutput::Kernel`]'s neighbourhood (3×3).
pub const TAPS: usize = 9;

/// ε of the triangle prior of [`WuOutput::Merge`]: a frame the triangle gives no weight keeps
/// a weight of about ε until training moves it.
pub const MERGE_PRIOR_EPS: f32 = 1e-3;

/// Which of the paper's two structures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WuVariant {
    /// Merger = one stride-2 convolution + residual blocks (the released model).
    #[default]
    Resnet,
    /// Merger = further stride-2 convolutions, mirrored decoder with skips.
    Unet,
}

/// How a 5×5 stride-2 transposed convolution is aligned on its 2× output grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DeconvAlignment {
    /// TensorFlow `conv2d_transpose(padding='SAME')`, as released: output o = 2i + k − 1
    /// (Burn/PyTorch padding 1, the extra last row and column cropped).
    #[default]
    Tensorflow,
    /// The usual PyTorch port, `ConvTranspose2d(5, stride=2, padding=2, output_padding=1)`:
    /// o = 2i + k − 2, i.e. one pixel further up-left. Use it for weights trained that way.
    Pytorch,
}

impl DeconvAlignment {
    /// (padding, padding_out) of Burn's `ConvTranspose2dConfig` for this alignment (the
    /// TensorFlow one also crops the extra last row and column, see [`deconv_same`]).
    pub fn paddings(self) -> (usize, usize) {
        match self {
            DeconvAlignment::Tensorflow => (1, 0),
            DeconvAlignment::Pytorch => (2, 1),
        }
    }
}

/// Network-2 hyper-parameters (a `[model]` table in a training config). Defaults are the
/// authors' (released ResNet model, `gf_dim` 64, 9 residual blocks).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WuConfig {
    pub variant: WuVariant,
    /// b: width of e_i1; e_i2 has 2b, the ResNet merger 4b.
    pub base_width: usize,
    /// Residual blocks of the ResNet merger (ignored by the U-Net).
    pub res_blocks: usize,
    /// Widths of the U-Net merger's stride-2 convolutions, in multiples of b (ignored by the
    /// ResNet). One entry per further down-sampling step.
    pub unet_merger_widths: Vec<usize>,
    pub deconv_alignment: DeconvAlignment,
    /// The HDR channels are multiplied by this before the x·2 − 1 mapping, and the output
    /// in [0, 1] is HDR × this (the trainer scales targets, inference divides it out). 0.25
    /// (default): Wu's convention, t relative to the shortest exposure of the EV −2/0/+2
    /// bracket, so HDR inputs are ≤ 1 and output 1 is the short frame's white (4× the
    /// reference's). 1: t relative to the reference; the output then cannot exceed the
    /// reference's white.
    pub hdr_input_scale: f64,
    /// What the last convolution predicts (`"image"`, Wu's; or `"merge"`). Defaults are not
    /// written, so configs and checkpoints of Wu's form read as they always have.
    #[serde(skip_serializing_if = "is_default")]
    pub output: WuOutput,
    /// The weights the merge heads correct (`"triangle"` or `"robertson"`; ignored by
    /// `output = "image"`).
    #[serde(skip_serializing_if = "is_default")]
    pub merge_prior: MergePrior,
    /// Where `input_response` comes from (`"fixed"`, or `"data"`: the training frames' curve).
    #[serde(skip_serializing_if = "is_default")]
    pub linearise: Linearise,
    /// The curve the HDR input channels invert: HDRᵢ = response⁻¹(LDRᵢ) / tᵢ. Default γ 2.2
    /// (Wu et al.'s LDR^2.2).
    #[serde(skip_serializing_if = "is_wu_curve")]
    pub input_response: Response,
}

fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

/// Wu et al.'s input curve, LDR^2.2.
pub fn wu_input_response() -> Response {
    Response::Gamma { gamma: 2.2 }
}

fn is_wu_curve(r: &Response) -> bool {
    *r == wu_input_response()
}

/// Most residual blocks of the ResNet merger.
pub const MAX_RES_BLOCKS: usize = 64;

impl Default for WuConfig {
    fn default() -> Self {
        WuConfig {
            variant: WuVariant::Resnet,
            base_width: 64,
            res_blocks: 9,
            unet_merger_widths: vec![4, 8, 8],
            deconv_alignment: DeconvAlignment::Tensorflow,
            hdr_input_scale: 0.25,
            output: WuOutput::Image,
            merge_prior: MergePrior::Triangle,
            linearise: Linearise::Fixed,
            input_response: wu_input_response(),
        }
    }
}

/// One decoder level's transposed convolution, `cin → cout`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct UpPlan {
    cin: usize,
    cout: usize,
}

impl WuConfig {
    /// The released ResNet model with base width `b` (tests use small ones).
    pub fn resnet(base_width: usize) -> WuConfig {
        WuConfig {
            base_width,
            ..WuConfig::default()
        }
    }

    /// The paper's U-Net with base width `b` and the default merger widths.
    pub fn unet(base_width: usize) -> WuConfig {
        WuConfig {
            variant: WuVariant::Unet,
            base_width,
            ..WuConfig::default()
        }
    }

    /// base_width ≥ 1; res_blocks ≤ 64 (the released model has 9); the U-Net's merger widths
    /// 1 to 8 entries, each ≥ 1; hdr_input_scale in (0, 1] (HDR inputs above 1 would leave the
    /// x·2 − 1 range); keys relative to `[model]`.
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        in_range("base_width", self.base_width, Range::at_least(1.0))?;
        in_range(
            "res_blocks",
            self.res_blocks,
            Range::closed(0.0, MAX_RES_BLOCKS as f64),
        )?;
        if self.variant == WuVariant::Unet {
            let n = self.unet_merger_widths.len();
            if !(1..=8).contains(&n) {
                return Err(KeyError::new(
                    "unet_merger_widths",
                    format!("has {n} entries, expected 1 to 8"),
                ));
            }
            each_in_range(
                "unet_merger_widths",
                &self.unet_merger_widths,
                Range::at_least(1.0),
            )?;
        }
        in_range(
            "hdr_input_scale",
            self.hdr_input_scale,
            Range::left_open(0.0, 1.0),
        )
    }

    /// Widths of the merger's stride-2 convolutions: [4b] (ResNet) or mₖ·b (U-Net).
    pub fn merger_widths(&self) -> Vec<usize> {
        match self.variant {
            WuVariant::Resnet => vec![4 * self.base_width],
            WuVariant::Unet => self
                .unet_merger_widths
                .iter()
                .map(|m| m * self.base_width)
                .collect(),
        }
    }

    /// H and W must be multiples of this: 8 (ResNet) or 2^(2 + merger steps) (U-Net; 32).
    /// Receptive-field radius in input pixels (a bound: each stride-s 5×5 convolution or
    /// transposed convolution counts 2·s, each 3×3 of a residual block s). Tiled inference with
    /// at least this overlap equals untiled inference. Default ResNet: 188 px.
    pub fn receptive_radius(&self) -> usize {
        let downs = 3 + match self.variant {
            WuVariant::Resnet => 0,
            WuVariant::Unet => self.unet_merger_widths.len(),
        };
        let (mut r, mut s) = (0, 1);
        for _ in 0..downs {
            r += 2 * s;
            s *= 2;
        }
        if self.variant == WuVariant::Resnet {
            r += self.res_blocks * 2 * s;
        }
        for _ in 0..downs {
            r += 2 * s;
            s /= 2;
        }
        r + 2
    }

    pub fn size_multiple(&self) -> usize {
        1 << (2 + self.merger_widths().len())
    }

    /// Channels of the last convolution: 3 (the image) or 9 (a weight correction per frame
    /// and colour channel).
    pub fn head_channels(&self) -> usize {
        match self.output {
            WuOutput::Image => OUTPUT_CHANNELS,
            WuOutput::Merge => FRAMES * OUTPUT_CHANNELS,
            WuOutput::Kernel => FRAMES * TAPS * OUTPUT_CHANNELS,
        }
    }

    /// An HDR input channel's value: the code `v` through the inverse input response, over the
    /// frame's exposure time `t` (relative to the reference).
    pub fn hdr_input(&self, v: f32, t: f32) -> f32 {
        self.input_response.invert_f32(v) / t
    }

    /// The decoder levels, deepest first.
    fn decoder_plan(&self) -> Vec<UpPlan> {
        let b = self.base_width;
        let m = self.merger_widths();
        let mut plan = Vec::new();
        let mut cin = match self.variant {
            // cat(residual output, e3)
            WuVariant::Resnet => 2 * m[0],
            WuVariant::Unet => m[m.len() - 1],
        };
        // Mirrored skips, deepest first, as (deconvolution width, skip width): the merger's own
        // levels below the bottom (U-Net), then E2 = 3 × 2b after a 2b deconvolution and
        // E1 = 3 × b after a b one.
        let mut levels: Vec<(usize, usize)> =
            m[..m.len() - 1].iter().rev().map(|&w| (w, w)).collect();
        levels.extend([(2 * b, FRAMES * 2 * b), (b, FRAMES * b)]);
        for (cout, skip) in levels {
            plan.push(UpPlan { cin, cout });
            cin = cout + skip;
        }
        plan.push(UpPlan { cin, cout: b });
        plan
    }

    /// Trainable parameters, counted from the architecture: convolution weights and biases,
    /// BatchNorm γ and β (not BatchNorm's running mean and variance).
    pub fn trainable_parameters(&self) -> usize {
        let b = self.base_width;
        let conv = |cin: usize, cout: usize, k: usize| k * k * cin * cout + cout;
        let bn = |c: usize| 2 * c;
        let mut n = FRAMES * (conv(FRAME_CHANNELS, b, 5) + conv(b, 2 * b, 5) + bn(2 * b));
        let mut cin = FRAMES * 2 * b;
        for m in self.merger_widths() {
            n += conv(cin, m, 5) + bn(m);
            cin = m;
        }
        if self.variant == WuVariant::Resnet {
            n += self.res_blocks * 2 * (conv(cin, cin, 3) + bn(cin));
        }
        for up in self.decoder_plan() {
            n += conv(up.cin, up.cout, 5) + bn(up.cout);
        }
        n + conv(b, self.head_channels(), 5)
    }

    /// A freshly initialised network on `device`, initialised as the authors do: weights
    /// N(0, 0.02) (TensorFlow draws the convolutions' from a truncated normal), biases 0,
    /// BatchNorm γ = 1, β = 0; every parameter drawn now ([`super::seeded_init`] for a
    /// reproducible one).
    pub fn init(&self, device: &Device) -> Result<WuNet> {
        super::init::drawing(|| self.build(device))
    }

    fn build(&self, device: &Device) -> Result<WuNet> {
        self.validate()?;
        let b = self.base_width;
        let encoders = (0..FRAMES)
            .map(|_| ExposureEncoder::init(b, device))
            .collect();
        let mut down = Vec::new();
        let mut cin = FRAMES * 2 * b;
        for m in self.merger_widths() {
            down.push(DownBlock::init(cin, m, device));
            cin = m;
        }
        let res = match self.variant {
            WuVariant::Resnet => (0..self.res_blocks)
                .map(|_| ResBlock::init(cin, device))
                .collect(),
            WuVariant::Unet => Vec::new(),
        };
        let up = self
            .decoder_plan()
            .into_iter()
            .map(|p| UpBlock::init(p, self.deconv_alignment, device))
            .collect();
        Ok(WuNet {
            encoders,
            merger: Merger { down, res },
            decoder: Decoder {
                up,
                out: match self.output {
                    WuOutput::Image => conv(b, OUTPUT_CHANNELS, 5, 1, device),
                    WuOutput::Merge | WuOutput::Kernel => {
                        zero_conv(conv(b, self.head_channels(), 5, 1, device))
                    }
                },
            },
            config: self.clone(),
        })
    }
}

/// The merge head's last convolution starts at zero (weights and bias): the untrained network
/// is the triangle merge.
fn zero_conv(mut c: Conv2d) -> Conv2d {
    c.weight = c.weight.map(zeros_keeping_grad);
    c
}

fn normal_init() -> Initializer {
    Initializer::Normal {
        mean: 0.0,
        std: INIT_STD,
    }
}

/// Burn's config initialises the bias with the weight's initialiser; TensorFlow's is 0.
fn zero_bias(mut c: Conv2d) -> Conv2d {
    c.bias = c.bias.map(|p| p.map(zeros_keeping_grad));
    c
}

fn zero_bias_t(mut c: ConvTranspose2d) -> ConvTranspose2d {
    c.bias = c.bias.map(|p| p.map(zeros_keeping_grad));
    c
}

/// Zeros of `t`'s shape that keep its gradient flag: `zeros_like` makes a tensor without one,
/// and a bias without it gets no gradient, so it would never train (until a checkpoint reload
/// set the flag, making a resumed run differ from an uninterrupted one).
fn zeros_keeping_grad<const D: usize>(t: Tensor<D>) -> Tensor<D> {
    let grad = t.is_require_grad();
    t.zeros_like().set_require_grad(grad)
}

/// k×k convolution with stride s and no padding of its own (see [`conv_same`]).
fn conv(cin: usize, cout: usize, k: usize, s: usize, device: &Device) -> Conv2d {
    zero_bias(
        Conv2dConfig::new([cin, cout], [k, k])
            .with_stride([s, s])
            .with_padding(PaddingConfig2d::Valid)
            .with_initializer(normal_init())
            .init(device),
    )
}

fn norm(c: usize, device: &Device) -> BatchNorm {
    BatchNormConfig::new(c)
        .with_epsilon(BN_EPSILON)
        .with_momentum(1.0 - TF_BN_DECAY)
        .init(device)
}

/// (before, after) padding of `ops.conv2d(padding='REFLECT')` for one axis: the total is
/// k − s when `size` is a multiple of s, else k − (size mod s) (never negative), the smaller
/// half before. Output size: ⌈size / s⌉.
pub fn same_padding(size: usize, kernel: usize, stride: usize) -> (usize, usize) {
    let total = if size.is_multiple_of(stride) {
        kernel.saturating_sub(stride)
    } else {
        kernel.saturating_sub(size % stride)
    };
    (total / 2, total - total / 2)
}

/// `ops.conv2d(padding='REFLECT')`: reflection padding sized as TensorFlow's 'SAME' (see
/// [`same_padding`]), then the convolution without padding.
pub fn conv_same(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    let [_, _, h, w] = x.dims();
    let pv = same_padding(h, conv.kernel_size[0], conv.stride[0]);
    let ph = same_padding(w, conv.kernel_size[1], conv.stride[1]);
    conv2d(conv, reflect_pad(x, pv, ph))
}

/// A 5×5 stride-2 transposed convolution to exactly twice the input size, built with
/// `alignment.paddings()`: TensorFlow's `conv2d_transpose(padding='SAME')` (padding 1 gives
/// 2h + 1 rows; 'SAME' keeps the first 2h) or the PyTorch port's (already 2h).
pub fn deconv_same(
    deconv: &ConvTranspose2d,
    x: Tensor<4>,
    alignment: DeconvAlignment,
) -> Tensor<4> {
    let [b, _, h, w] = x.dims();
    let y = conv_transpose2d(deconv, x);
    match alignment {
        DeconvAlignment::Tensorflow => {
            let c = y.dims()[1];
            y.slice([0..b, 0..c, 0..2 * h, 0..2 * w])
        }
        DeconvAlignment::Pytorch => y,
    }
}

/// The per-exposure encoder: e1 = conv(x, b), e2 = BN(conv(lrelu(e1), 2b)).
#[derive(Module, Debug)]
pub struct ExposureEncoder {
    conv1: Conv2d,
    conv2: Conv2d,
    bn2: BatchNorm,
}

impl ExposureEncoder {
    fn init(b: usize, device: &Device) -> Self {
        ExposureEncoder {
            conv1: conv(FRAME_CHANNELS, b, 5, 2, device),
            conv2: conv(b, 2 * b, 5, 2, device),
            bn2: norm(2 * b, device),
        }
    }

    /// (e1, e2) of one frame's 6 channels: e1 is the decoder's last skip, e2 the merger's input.
    fn forward(&self, x: Tensor<4>) -> (Tensor<4>, Tensor<4>) {
        let e1 = conv_same(&self.conv1, x);
        let e2 = batch_norm(
            &self.bn2,
            conv_same(&self.conv2, leaky_relu(e1.clone(), LEAK)),
        );
        (e1, e2)
    }
}

/// A stride-2 merger level: BN(conv(lrelu(x))).
#[derive(Module, Debug)]
pub struct DownBlock {
    conv: Conv2d,
    bn: BatchNorm,
}

impl DownBlock {
    fn init(cin: usize, cout: usize, device: &Device) -> Self {
        DownBlock {
            conv: conv(cin, cout, 5, 2, device),
            bn: norm(cout, device),
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        batch_norm(&self.bn, conv_same(&self.conv, leaky_relu(x, LEAK)))
    }
}

/// x + BN(conv3×3(relu(BN(conv3×3(x))))), reflect padding 1 (the released `residule_block`).
#[derive(Module, Debug)]
pub struct ResBlock {
    conv1: Conv2d,
    bn1: BatchNorm,
    conv2: Conv2d,
    bn2: BatchNorm,
}

impl ResBlock {
    fn init(c: usize, device: &Device) -> Self {
        ResBlock {
            conv1: conv(c, c, 3, 1, device),
            bn1: norm(c, device),
            conv2: conv(c, c, 3, 1, device),
            bn2: norm(c, device),
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let y = batch_norm_relu(&self.bn1, conv_same(&self.conv1, x.clone()));
        x + batch_norm(&self.bn2, conv_same(&self.conv2, y))
    }
}

/// A decoder level: BN(deconv(relu(x))).
#[derive(Module, Debug)]
pub struct UpBlock {
    deconv: ConvTranspose2d,
    bn: BatchNorm,
    #[module(skip)]
    alignment: DeconvAlignment,
}

impl UpBlock {
    fn init(plan: UpPlan, alignment: DeconvAlignment, device: &Device) -> Self {
        let (padding, padding_out) = alignment.paddings();
        UpBlock {
            deconv: zero_bias_t(
                ConvTranspose2dConfig::new([plan.cin, plan.cout], [5, 5])
                    .with_stride([2, 2])
                    .with_padding([padding, padding])
                    .with_padding_out([padding_out, padding_out])
                    .with_initializer(normal_init())
                    .init(device),
            ),
            bn: norm(plan.cout, device),
            alignment,
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        batch_norm(&self.bn, deconv_same(&self.deconv, relu(x), self.alignment))
    }
}

/// `down`: the stride-2 convolutions (one for the ResNet); `res`: the residual blocks (none
/// for the U-Net).
#[derive(Module, Debug)]
pub struct Merger {
    down: Vec<DownBlock>,
    res: Vec<ResBlock>,
}

#[derive(Module, Debug)]
pub struct Decoder {
    /// Deepest level first.
    up: Vec<UpBlock>,
    out: Conv2d,
}

/// Network-2. Build with [`WuConfig::init`].
#[derive(Module, Debug)]
pub struct WuNet {
    /// One per frame (EV −2, 0, +2).
    encoders: Vec<ExposureEncoder>,
    merger: Merger,
    decoder: Decoder,
    #[module(skip)]
    config: WuConfig,
}

impl WuNet {
    pub fn config(&self) -> &WuConfig {
        &self.config
    }

    /// H and W must be multiples of this (see [`WuConfig::size_multiple`]).
    pub fn size_multiple(&self) -> usize {
        self.config.size_multiple()
    }

    /// Whether an input of `channels`×`height`×`width` is accepted by [`forward`](Self::forward).
    pub fn check_input(&self, channels: usize, height: usize, width: usize) -> Result<()> {
        let m = self.size_multiple();
        if channels != INPUT_CHANNELS {
            return Err(Error::Invalid(format!(
                "Wu net: input has {channels} channels, expected {INPUT_CHANNELS} (per frame \
                 EV−2, 0, +2: LDR RGB, then LDR^2.2/t RGB)"
            )));
        }
        if height == 0 || width == 0 || !height.is_multiple_of(m) || !width.is_multiple_of(m) {
            return Err(Error::Invalid(format!(
                "Wu net: input {height}×{width} is not a positive multiple of {m}; crop to a \
                 multiple or use forward_padded"
            )));
        }
        Ok(())
    }

    /// The network's own input mapping: every channel x → x·2 − 1, the HDR channels scaled by
    /// `hdr_input_scale` first.
    fn map_input(&self, x: Tensor<4>) -> Tensor<4> {
        let s = self.config.hdr_input_scale;
        if s == 1.0 {
            return x.mul_scalar(2.0).sub_scalar(1.0);
        }
        let scale: Vec<f32> = (0..INPUT_CHANNELS)
            .map(|c| {
                if c % FRAME_CHANNELS < 3 {
                    2.0
                } else {
                    (2.0 * s) as f32
                }
            })
            .collect();
        let scale = Tensor::<1>::from_data(TensorData::new(scale, [INPUT_CHANNELS]), &x.device())
            .reshape([1, INPUT_CHANNELS, 1, 1]);
        (x * scale).sub_scalar(1.0)
    }

    /// Linear HDR `[B, 3, H, W]` in [0, 1] of input `[B, 18, H, W]` (see the module docs).
    ///
    /// # Panics
    /// If the input is rejected by [`check_input`](Self::check_input).
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let [_, c, h, w] = x.dims();
        if let Err(e) = self.check_input(c, h, w) {
            panic!("{e}");
        }
        let raw = x.clone();
        let x = self.map_input(x);
        let (e1, e2): (Vec<_>, Vec<_>) = self
            .encoders
            .iter()
            .enumerate()
            .map(|(i, enc)| enc.forward(x.clone().narrow(1, i * FRAME_CHANNELS, FRAME_CHANNELS)))
            .unzip();
        let e1 = Tensor::cat(e1, 1);
        let e2 = Tensor::cat(e2, 1);
        let mut levels = Vec::with_capacity(self.merger.down.len());
        let mut cur = e2.clone();
        for d in &self.merger.down {
            cur = d.forward(cur);
            levels.push(cur.clone());
        }
        let deepest = levels.pop().expect("at least one merger level");
        let mut cur = match self.config.variant {
            WuVariant::Resnet => {
                // As released: each block gets relu of the running tensor and adds to it.
                let mut r = deepest.clone();
                for block in &self.merger.res {
                    r = block.forward(relu(r));
                }
                Tensor::cat(vec![r, deepest], 1)
            }
            WuVariant::Unet => deepest,
        };
        let mut skips: Vec<Tensor<4>> = levels.into_iter().rev().collect();
        skips.extend([e2, e1]);
        let mut skips = skips.into_iter();
        for up in &self.decoder.up {
            let y = up.forward(cur);
            cur = match skips.next() {
                Some(s) => Tensor::cat(vec![y, s], 1),
                None => y,
            };
        }
        let head = conv_same(&self.decoder.out, relu(cur));
        match self.config.output {
            WuOutput::Image => tanh(head).add_scalar(1.0).mul_scalar(0.5),
            WuOutput::Merge | WuOutput::Kernel => merge_head::merge(raw, head, &self.config),
        }
    }

    /// [`forward`](Self::forward) for any H×W ≥ 1: pads bottom and right by reflection to the
    /// next multiple of [`size_multiple`](Self::size_multiple) and crops the output back.
    pub fn forward_padded(&self, x: Tensor<4>) -> Tensor<4> {
        let [b, _, h, w] = x.dims();
        let m = self.size_multiple();
        let (ph, pw) = (h.div_ceil(m) * m - h, w.div_ceil(m) * m - w);
        if ph == 0 && pw == 0 {
            return self.forward(x);
        }
        let x = reflect_pad(x, (0, ph), (0, pw));
        self.forward(x)
            .slice([0..b, 0..OUTPUT_CHANNELS, 0..h, 0..w])
    }
}

/// Loads pretrained weights stored under the documented PyTorch-style names (docs/network2.md)
/// from a `.safetensors` or PyTorch `.pt`/`.pth` state dict into `model` (built with the
/// matching config). See [`super::import::import_weights`].
pub fn import_weights(model: WuNet, path: impl AsRef<Path>) -> Result<WuNet> {
    super::import::import_weights(model, path.as_ref())
}

/// Writes `model`'s weights (BatchNorm running statistics included) to a `.safetensors` file
/// under the documented PyTorch-style names. See [`super::import::export_weights`].
pub fn export_weights(model: &WuNet, path: impl AsRef<Path>) -> Result<()> {
    super::import::export_weights(model, path.as_ref())
}
