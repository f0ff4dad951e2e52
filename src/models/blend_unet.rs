//! Network-1: the blend-map U-Net (Hu et al., §4.1).
//!
//! Input: 6×H×W, the two 8-bit frames (EV−3, EV0) in [0, 1], channel-major (RGB of EV−3, then RGB
//! of EV0), exactly as `data::loader` produces them. Output: logits over the blend-map classes
//! (class = round(255 · w_high), see `data::ground_truth`), [B, classes, H, W].
//!
//! Shape, with widths wₗ = base_width · 2^l for l = 0..=depth:
//! - encoder level 0: block(6 → w₀); level l ≥ 1: 2×2 max-pool, block(wₗ₋₁ → wₗ); level `depth`
//!   is the bottleneck;
//! - decoder level l = depth−1..0: 2×2 stride-2 transposed conv (wₗ₊₁ → wₗ), concatenation with
//!   the encoder's level-l output (skip first, then the up-sampled features: 2wₗ channels),
//!   block(2wₗ → wₗ);
//! - head: 5×5 conv (padding 2), w₀ → classes.
//!
//! A block is two × [3×3 conv (padding 1) → BatchNorm (optional) → ReLU]. With BatchNorm the
//! 3×3 convolutions carry no bias (BatchNorm's β replaces it); without it they do. The
//! transposed convolutions and the head always have a bias.
//!
//! H and W must be multiples of 2^depth: [`BlendUNet::forward`] panics otherwise (check first
//! with [`BlendUNet::check_input`]); [`BlendUNet::forward_padded`] accepts any size by padding
//! with edge replication and cropping the output back.
//!
//! BatchNorm uses batch statistics (and updates its running statistics) when the input lives
//! on an autodiff device, and the running statistics otherwise; call `model.valid()` for
//! inference on an autodiff device.

use crate::config::{KeyError, Range, in_range};
use crate::error::{Error, Result};
use crate::kernels::batch_norm::batch_norm_relu;
use crate::kernels::conv::{conv_transpose2d, conv2d};
use crate::kernels::pool::max_pool2d;
use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig, ConvTranspose2d, ConvTranspose2dConfig};
use burn::nn::pool::{MaxPool2d, MaxPool2dConfig};
use burn::nn::{BatchNorm, BatchNormConfig, PaddingConfig2d, Relu};
use burn::tensor::activation::softmax;
use burn::tensor::ops::PadMode;
use burn::tensor::{Device, Tensor};
use serde::{Deserialize, Serialize};

/// Input channels: RGB of EV−3 then RGB of EV0.
pub const INPUT_CHANNELS: usize = 6;

/// Network-1 hyper-parameters (a `[model]` table in a training config).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BlendUNetConfig {
    /// Width of level 0; level l has base_width · 2^l channels.
    pub base_width: usize,
    /// Number of 2×2 down-sampling steps (H and W must be multiples of 2^depth).
    pub depth: usize,
    /// BatchNorm after every 3×3 convolution.
    pub batch_norm: bool,
    /// Output classes (256 blend-map classes).
    pub classes: usize,
}

impl Default for BlendUNetConfig {
    fn default() -> Self {
        BlendUNetConfig {
            base_width: 32,
            depth: 4,
            batch_norm: true,
            classes: crate::data::ground_truth::CLASSES,
        }
    }
}

impl BlendUNetConfig {
    /// base_width ≥ 1, depth in [0, 10] down-sampling steps, classes in [2, 256] (the class
    /// maps are 8-bit); keys relative to `[model]`.
    pub fn validate(&self) -> std::result::Result<(), KeyError> {
        in_range("base_width", self.base_width, Range::at_least(1.0))?;
        in_range("depth", self.depth, Range::closed(0.0, 10.0))?;
        in_range("classes", self.classes, Range::closed(2.0, 256.0))
    }

    /// Channel widths of levels 0..=depth.
    pub fn widths(&self) -> Vec<usize> {
        (0..=self.depth).map(|l| self.base_width << l).collect()
    }

    /// H and W must be multiples of this (2^depth).
    pub fn size_multiple(&self) -> usize {
        1 << self.depth
    }

    /// Receptive-field radius in input pixels: how far from a pixel the inputs that can change
    /// its output lie (a bound: 2×2 pooling and the 2×2 transposed convolutions count one
    /// step of their stride). Tiled inference with at least this overlap equals untiled
    /// inference. Default (depth 4): 124 px.
    pub fn receptive_radius(&self) -> usize {
        let (mut r, mut s) = (2, 1); // level-0 block: two 3×3 convolutions
        for _ in 1..=self.depth {
            r += s; // 2×2 max-pool
            s *= 2;
            r += 2 * s; // block
        }
        for _ in 0..self.depth {
            r += s / 2; // 2×2 stride-2 transposed convolution
            s /= 2;
            r += 2 * s; // block
        }
        r + 2 // 5×5 head
    }

    /// Trainable parameters, counted from the architecture (weights, biases, BatchNorm γ and
    /// β; not BatchNorm's running mean and variance).
    pub fn trainable_parameters(&self) -> usize {
        let bn = self.batch_norm;
        let conv = |cin: usize, cout: usize, k: usize, bias: bool| {
            k * k * cin * cout + if bias { cout } else { 0 }
        };
        let block = |cin: usize, cout: usize| {
            conv(cin, cout, 3, !bn) + conv(cout, cout, 3, !bn) + if bn { 4 * cout } else { 0 }
        };
        let w = self.widths();
        let mut n = block(INPUT_CHANNELS, w[0]);
        for l in 1..=self.depth {
            n += block(w[l - 1], w[l]);
        }
        for l in 0..self.depth {
            n += conv(w[l + 1], w[l], 2, true) + block(2 * w[l], w[l]);
        }
        n + conv(w[0], self.classes, 5, true)
    }

    /// A freshly initialised network on `device` (Burn's default initialisers: Kaiming-uniform
    /// convolutions, BatchNorm γ = 1, β = 0); every parameter drawn now
    /// ([`super::seeded_init`] for a reproducible one).
    pub fn init(&self, device: &Device) -> Result<BlendUNet> {
        super::init::drawing(|| self.build(device))
    }

    fn build(&self, device: &Device) -> Result<BlendUNet> {
        self.validate()?;
        let w = self.widths();
        let mut encoder = vec![ConvBlock::new(
            INPUT_CHANNELS,
            w[0],
            self.batch_norm,
            device,
        )];
        for l in 1..=self.depth {
            encoder.push(ConvBlock::new(w[l - 1], w[l], self.batch_norm, device));
        }
        let decoder = (0..self.depth)
            .map(|l| UpBlock {
                up: ConvTranspose2dConfig::new([w[l + 1], w[l]], [2, 2])
                    .with_stride([2, 2])
                    .init(device),
                block: ConvBlock::new(2 * w[l], w[l], self.batch_norm, device),
            })
            .collect();
        Ok(BlendUNet {
            encoder,
            pool: MaxPool2dConfig::new([2, 2]).init(),
            decoder,
            head: Conv2dConfig::new([w[0], self.classes], [5, 5])
                .with_padding(PaddingConfig2d::Explicit(2, 2, 2, 2))
                .init(device),
            depth: self.depth,
            classes: self.classes,
        })
    }
}

/// Two × [3×3 conv → BatchNorm (optional) → ReLU].
#[derive(Module, Debug)]
pub struct ConvBlock {
    conv1: Conv2d,
    norm1: Option<BatchNorm>,
    conv2: Conv2d,
    norm2: Option<BatchNorm>,
    relu: Relu,
}

impl ConvBlock {
    fn new(cin: usize, cout: usize, batch_norm: bool, device: &Device) -> ConvBlock {
        let conv = |cin: usize| {
            Conv2dConfig::new([cin, cout], [3, 3])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .with_bias(!batch_norm)
                .init(device)
        };
        let norm = || batch_norm.then(|| BatchNormConfig::new(cout).init(device));
        ConvBlock {
            conv1: conv(cin),
            norm1: norm(),
            conv2: conv(cout),
            norm2: norm(),
            relu: Relu::new(),
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let x = self.norm_relu(&self.norm1, conv2d(&self.conv1, x));
        self.norm_relu(&self.norm2, conv2d(&self.conv2, x))
    }

    /// relu(BN(x)), or relu(x) without BatchNorm.
    fn norm_relu(&self, norm: &Option<BatchNorm>, x: Tensor<4>) -> Tensor<4> {
        match norm {
            Some(n) => batch_norm_relu(n, x),
            None => self.relu.forward(x),
        }
    }
}

/// Transposed-conv up-sampling, concatenation with the skip, then a block.
#[derive(Module, Debug)]
pub struct UpBlock {
    up: ConvTranspose2d,
    block: ConvBlock,
}

impl UpBlock {
    fn forward(&self, x: Tensor<4>, skip: Tensor<4>) -> Tensor<4> {
        let x = conv_transpose2d(&self.up, x);
        self.block.forward(Tensor::cat(vec![skip, x], 1))
    }
}

/// Network-1. Build with [`BlendUNetConfig::init`].
#[derive(Module, Debug)]
pub struct BlendUNet {
    /// Levels 0..=depth (the last is the bottleneck).
    encoder: Vec<ConvBlock>,
    pool: MaxPool2d,
    /// `decoder[l]` goes from level l+1 to level l; applied from l = depth−1 down to 0.
    decoder: Vec<UpBlock>,
    head: Conv2d,
    depth: usize,
    classes: usize,
}

impl BlendUNet {
    pub fn depth(&self) -> usize {
        self.depth
    }

    pub fn classes(&self) -> usize {
        self.classes
    }

    /// Whether an input of `channels`×`height`×`width` is accepted by [`forward`](Self::forward).
    pub fn check_input(&self, channels: usize, height: usize, width: usize) -> Result<()> {
        let m = 1usize << self.depth;
        if channels != INPUT_CHANNELS {
            return Err(Error::Invalid(format!(
                "blend U-Net: input has {channels} channels, expected {INPUT_CHANNELS} \
                 (RGB of EV−3, then RGB of EV0)"
            )));
        }
        if height == 0 || width == 0 || !height.is_multiple_of(m) || !width.is_multiple_of(m) {
            return Err(Error::Invalid(format!(
                "blend U-Net: input {height}×{width} is not a multiple of 2^depth = {m} \
                 (depth {}); crop to a multiple or use forward_padded",
                self.depth
            )));
        }
        Ok(())
    }

    /// Logits [B, classes, H, W] of input [B, 6, H, W].
    ///
    /// # Panics
    /// If the input is rejected by [`check_input`](Self::check_input).
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let [_, c, h, w] = x.dims();
        if let Err(e) = self.check_input(c, h, w) {
            panic!("{e}");
        }
        let mut skips = Vec::with_capacity(self.depth);
        let mut x = self.encoder[0].forward(x);
        for block in &self.encoder[1..] {
            skips.push(x.clone());
            x = block.forward(max_pool2d(&self.pool, x));
        }
        for up in self.decoder.iter().rev() {
            let skip = skips.pop().expect("one skip per decoder level");
            x = up.forward(x, skip);
        }
        conv2d(&self.head, x)
    }

    /// Class probabilities [B, classes, H, W] (softmax of the logits over dim 1).
    pub fn probabilities(&self, x: Tensor<4>) -> Tensor<4> {
        softmax(self.forward(x), 1)
    }

    /// Logits for any H×W ≥ 1: pads bottom and right to the next multiple of 2^depth by edge
    /// replication, runs [`forward`](Self::forward), and crops back to H×W. Pixels near the
    /// padded border then see replicated context instead of the zero padding of the convolutions.
    pub fn forward_padded(&self, x: Tensor<4>) -> Tensor<4> {
        let [b, _, h, w] = x.dims();
        let m = 1usize << self.depth;
        let (ph, pw) = (h.div_ceil(m) * m - h, w.div_ceil(m) * m - w);
        if ph == 0 && pw == 0 {
            return self.forward(x);
        }
        let x = x.pad([(0, ph), (0, pw)], PadMode::Edge);
        self.forward(x).slice([0..b, 0..self.classes, 0..h, 0..w])
    }
}
