//! Lowering both networks to ONNX graphs (opset 17), layer by layer from the modules' structure
//! and weights. Inputs, outputs and their shapes are documented in docs/onnx.md.

use super::graph::{Dim, GraphBuilder, int, ints, module_weights};
use super::proto::{ModelProto, OperatorSetIdProto, StringStringEntryProto};
use crate::error::{Error, Result};
use crate::io::atomic::write_atomic;
use crate::models::wu::{self, DeconvAlignment, WuOutput, WuVariant};
use crate::models::{BlendUNet, WuNet};
use crate::sensor::profile::Response;
use burn::nn::BatchNormConfig;
use prost::Message;
use std::path::Path;

/// ONNX operator set written (every op used has had its current form since opset 13–15).
pub const OPSET: i64 = 17;
/// ONNX IR version matching [`OPSET`].
pub const IR_VERSION: i64 = 8;

/// Input names of Network-1: the EV−3 frame, the EV0 frame.
pub const N1_INPUTS: [&str; 2] = ["low", "high"];
/// Output names of Network-1.
pub const N1_PROBABILITIES: &str = "probabilities";
pub const N1_WEIGHT: &str = "blend_weight";
/// Input names of Network-2: the three frames (EV −2, 0, +2) and their exposure times.
pub const N2_FRAMES: [&str; 3] = ["frame_short", "frame_reference", "frame_long"];
pub const N2_TIMES: &str = "exposure_times";
/// Output name of Network-2.
pub const N2_OUTPUT: &str = "hdr";

/// Metadata keys hdrsynth writes into `metadata_props` (read back by `onnx::runtime`).
pub const META_NETWORK: &str = "hdrsynth.network";
pub const META_SIZE_MULTIPLE: &str = "hdrsynth.size_multiple";
pub const META_MIN_SIZE: &str = "hdrsynth.min_size";
pub const META_RADIUS: &str = "hdrsynth.receptive_radius";
/// Network-2's `hdr_input_scale` (the `hdr` output is already divided by it; previews use it).
pub const META_HDR_SCALE: &str = "hdrsynth.hdr_input_scale";

/// Height and width of the exported graph's inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputSize {
    /// Batch 1, this height and width.
    Static { height: usize, width: usize },
    /// Symbolic batch `N`, height `H` and width `W`.
    Dynamic,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExportOptions {
    pub size: InputSize,
    /// Network-1 only: also output the expected blend weight (`blend_weight`).
    pub blend_weight: bool,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            size: InputSize::Dynamic,
            blend_weight: true,
        }
    }
}

/// The (batch, height, width) axes of the graph's image inputs and outputs.
fn axes(size: InputSize) -> [Dim; 3] {
    match size {
        InputSize::Static { height, width } => {
            [Dim::Fixed(1), Dim::Fixed(height), Dim::Fixed(width)]
        }
        InputSize::Dynamic => [Dim::Symbol("N"), Dim::Symbol("H"), Dim::Symbol("W")],
    }
}

fn image_dims(size: InputSize, channels: usize) -> Vec<Dim> {
    let [n, h, w] = axes(size);
    vec![n, Dim::Fixed(channels), h, w]
}

/// Checks a static size: positive multiples of `multiple`, at least `min`.
fn check_size(size: InputSize, multiple: usize, min: usize, what: &str) -> Result<()> {
    if let InputSize::Static { height, width } = size {
        for (name, v) in [("height", height), ("width", width)] {
            if v < min || !v.is_multiple_of(multiple) {
                return Err(Error::flag(
                    format!("--{name}"),
                    format!(
                        "{v} must be a multiple of {multiple} and at least {min} (ONNX export of \
                         {what})"
                    ),
                ));
            }
        }
    }
    Ok(())
}

fn model_proto(graph: super::proto::GraphProto, meta: Vec<(&str, String)>) -> ModelProto {
    ModelProto {
        ir_version: Some(IR_VERSION),
        opset_import: vec![OperatorSetIdProto {
            domain: Some(String::new()),
            version: Some(OPSET),
        }],
        producer_name: Some("hdrsynth".into()),
        producer_version: Some(env!("CARGO_PKG_VERSION").into()),
        domain: None,
        model_version: Some(1),
        doc_string: None,
        graph: Some(graph),
        metadata_props: meta
            .into_iter()
            .map(|(k, v)| StringStringEntryProto {
                key: Some(k.into()),
                value: Some(v),
            })
            .collect(),
    }
}

/// Smallest height/width Network-1 accepts: one 2^depth cell.
pub fn network1_min_size(model: &BlendUNet) -> usize {
    1 << model.depth()
}

/// Network-1 as ONNX. Inputs `low`, `high`: `[N, 3, H, W]` frames in [0, 1] (EV−3, EV0).
/// Outputs `probabilities` `[N, 256, H, W]` (softmax over the classes) and, with
/// `blend_weight`, `blend_weight` `[N, 1, H, W]` = Σ_c p_c · c / (C − 1) (the long exposure's
/// weight, `eval::blend::BlendWeight::Expected`).
pub fn network1(model: &BlendUNet, opts: &ExportOptions) -> Result<ModelProto> {
    let depth = model.depth();
    let classes = model.classes();
    check_size(opts.size, 1 << depth, network1_min_size(model), "Network-1")?;
    let mut g = GraphBuilder::new(module_weights(model)?);
    let eps = BatchNormConfig::new(1).epsilon; // blend_unet.rs uses Burn's default
    let low = g.input(N1_INPUTS[0], &image_dims(opts.size, 3));
    let high = g.input(N1_INPUTS[1], &image_dims(opts.size, 3));
    let x = g.concat("input", &[&low, &high], 1);

    let block = |g: &mut GraphBuilder, p: &str, x: &str| -> Result<String> {
        let mut x = x.to_string();
        for k in 1..=2 {
            x = g.conv(&format!("{p}.conv{k}"), &x, 1, [1; 4])?;
            let norm = format!("{p}.norm{k}");
            if g.has(&format!("{norm}.weight")) {
                x = g.batch_norm(&norm, &x, eps)?;
            }
            x = g.relu(&format!("{p}.relu{k}"), &x);
        }
        Ok(x)
    };
    let mut cur = block(&mut g, "encoder.0", &x)?;
    let mut skips = Vec::new();
    for l in 1..=depth {
        skips.push(cur.clone());
        let p = g.node(
            "MaxPool",
            &format!("encoder.{l}.pool"),
            &[&cur],
            vec![
                ints("kernel_shape", &[2, 2]),
                ints("strides", &[2, 2]),
                ints("pads", &[0; 4]),
            ],
        );
        cur = block(&mut g, &format!("encoder.{l}"), &p)?;
    }
    for l in (0..depth).rev() {
        let up = g.conv_transpose(&format!("decoder.{l}.up"), &cur, 2, [0; 4], 0)?;
        let skip = skips.pop().expect("one skip per level");
        let cat = g.concat(&format!("decoder.{l}.cat"), &[&skip, &up], 1);
        cur = block(&mut g, &format!("decoder.{l}.block"), &cat)?;
    }
    let logits = g.conv("head", &cur, 1, [2; 4])?;
    // Softmax over the class axis spelled out (max, exp, sum, divide): ONNX Runtime's Softmax
    // over a non-last axis took 44 % of a 768² window's time in its profiler; these ops stream
    // over NCHW as they are. The blend weight reuses the exponentials and their
    // sum.
    let max = g.node(
        "ReduceMax",
        "softmax.max",
        &[&logits],
        vec![ints("axes", &[1]), int("keepdims", 1)],
    );
    let shifted = g.node("Sub", "softmax.shifted", &[&logits, &max], vec![]);
    let e = g.node("Exp", "softmax.exp", &[&shifted], vec![]);
    let axis = g.const_i64("softmax.axes", &[1], vec![1]);
    let sum = g.node(
        "ReduceSum",
        "softmax.sum",
        &[&e, &axis],
        vec![int("keepdims", 1)],
    );
    let probs = g.node("Div", "softmax", &[&e, &sum], vec![]);
    let [n, h, w] = axes(opts.size);
    g.output(
        &probs,
        N1_PROBABILITIES,
        &[n.clone(), Dim::Fixed(classes), h.clone(), w.clone()],
    )?;
    if opts.blend_weight {
        // Expected class / (C − 1): Σ_c e_c · c/(C − 1) as a 1×1 convolution, over Σ_c e_c.
        let top = (classes - 1) as f32;
        let k = g.const_f32(
            "blend_weight.classes",
            &[1, classes, 1, 1],
            (0..classes).map(|c| c as f32 / top).collect(),
        );
        let num = g.node(
            "Conv",
            "blend_weight.weighted",
            &[&e, &k],
            vec![ints("kernel_shape", &[1, 1])],
        );
        let wgt = g.node("Div", "blend_weight.expected", &[&num, &sum], vec![]);
        g.output(&wgt, N1_WEIGHT, &[n, Dim::Fixed(1), h, w])?;
    }
    let graph = g.finish("hdrsynth_network1")?;
    Ok(model_proto(
        graph,
        vec![
            (META_NETWORK, "network1".into()),
            (META_SIZE_MULTIPLE, (1usize << depth).to_string()),
            (META_MIN_SIZE, network1_min_size(model).to_string()),
            (
                META_RADIUS,
                crate::models::BlendUNetConfig {
                    depth,
                    ..Default::default()
                }
                .receptive_radius()
                .to_string(),
            ),
        ],
    ))
}

/// Smallest height/width (a multiple of `size_multiple`) at which every reflection pad of
/// Network-2 is shorter than its axis, as ONNX's `Pad(mode = reflect)` requires (16 for the
/// ResNet, 64 for the default U-Net).
pub fn network2_min_size(cfg: &wu::WuConfig) -> usize {
    let m = cfg.size_multiple();
    let downs = 2 + cfg.merger_widths().len();
    let ok = |s: usize| {
        // Stride-2 5×5 convolutions pad (1, 2) at sizes s, s/2, …; the residual blocks pad 1 at
        // the bottom; the output convolution pads 2 at s.
        (0..downs).all(|k| (s >> k) > 2) && (cfg.variant != WuVariant::Resnet || (s >> downs) > 1)
    };
    (1..)
        .map(|k| k * m)
        .find(|&s| ok(s))
        .expect("some multiple works")
}

/// The γ of the network's input curve, where the network has Wu's form: the graph forms his
/// inputs (LDR^γ) and his image head only.
fn wu_form_gamma(cfg: &wu::WuConfig) -> Result<f32> {
    match (&cfg.input_response, cfg.output) {
        (Response::Gamma { gamma }, WuOutput::Image) => Ok(*gamma as f32),
        _ => Err(Error::Invalid(format!(
            "ONNX export of Network-2 supports Wu's form only (model.output = \"image\", a \
             gamma input_response); this network has output = {:?}, input_response = {}",
            cfg.output,
            cfg.input_response.label()
        ))),
    }
}

/// Network-2 as ONNX. Inputs `frame_short`, `frame_reference`, `frame_long`: `[N, 3, H, W]`
/// LDR frames in [0, 1] (EV −2, 0, +2); `exposure_times` `[N, 3]`: their exposure times
/// relative to the reference (2^(EV − EV_ref), e.g. 0.25, 1, 4). The graph forms the model's
/// input as the loader does (per frame LDR, LDR^2.2 / t) and maps it as `WuNet::forward`.
/// Output `hdr` `[N, 3, H, W]`: linear HDR, 1 = the reference exposure's white (the network's
/// [0, 1] output divided by `hdr_input_scale`, as `eval::infer::network2_hdr`).
pub fn network2(model: &WuNet, opts: &ExportOptions) -> Result<ModelProto> {
    let cfg = model.config().clone();
    let gamma = wu_form_gamma(&cfg)?;
    let m = cfg.size_multiple();
    check_size(opts.size, m, network2_min_size(&cfg), "Network-2")?;
    let mut g = GraphBuilder::new(module_weights(model)?);
    let eps = wu::BN_EPSILON;
    let frames: Vec<String> = N2_FRAMES
        .iter()
        .map(|n| g.input(n, &image_dims(opts.size, 3)))
        .collect();
    let [n, h, w] = axes(opts.size);
    let times = g.input(N2_TIMES, &[n.clone(), Dim::Fixed(wu::FRAMES)]);
    let hdr_scale = (2.0 * cfg.hdr_input_scale) as f32;
    // TensorFlow-'SAME' reflection pads depend on the size only through its parity under a
    // stride 2, and every stride-2 convolution sees an even size (H and W are multiples of
    // 2^(stride-2 steps) = m): so they are fixed, stride-2 5×5 (1, 2), 3×3 (1, 1), 5×5 (2, 2),
    // and the same graph serves every H×W.
    let conv_same = |g: &mut GraphBuilder, p: &str, x: &str, k: usize, stride: usize| {
        let pad = wu::same_padding(2 * m, k, stride);
        let x = g.pad_reflect(&format!("{p}.pad"), x, pad, pad);
        g.conv(p, &x, stride, [0; 4])
    };

    let mut e1 = Vec::new();
    let mut e2 = Vec::new();
    for (i, ldr) in frames.iter().enumerate() {
        let p = format!("encoders.{i}");
        let idx = g.const_i64(&format!("{p}.t_index"), &[], vec![i as i64]);
        let t = g.node(
            "Gather",
            &format!("{p}.t"),
            &[&times, &idx],
            vec![int("axis", 1)],
        );
        let shape = g.const_i64(&format!("{p}.t_shape"), &[4], vec![-1, 1, 1, 1]);
        let t = g.node("Reshape", &format!("{p}.t4"), &[&t, &shape], vec![]);
        let lin = g.with_scalar("Pow", &format!("{p}.linear"), ldr, gamma);
        let hdr = g.node("Div", &format!("{p}.hdr"), &[&lin, &t], vec![]);
        let ldr_m = g.with_scalar("Mul", &format!("{p}.ldr_x2"), ldr, 2.0);
        let ldr_m = g.with_scalar("Sub", &format!("{p}.ldr_in"), &ldr_m, 1.0);
        let hdr_m = g.with_scalar("Mul", &format!("{p}.hdr_x2s"), &hdr, hdr_scale);
        let hdr_m = g.with_scalar("Sub", &format!("{p}.hdr_in"), &hdr_m, 1.0);
        let xi = g.concat(&format!("{p}.input"), &[&ldr_m, &hdr_m], 1);
        let a = conv_same(&mut g, &format!("{p}.conv1"), &xi, 5, 2)?;
        let l = g.leaky_relu(&format!("{p}.lrelu"), &a, wu::LEAK);
        let c = conv_same(&mut g, &format!("{p}.conv2"), &l, 5, 2)?;
        e2.push(g.batch_norm(&format!("{p}.bn2"), &c, eps)?);
        e1.push(a);
    }
    let e1: Vec<&str> = e1.iter().map(String::as_str).collect();
    let e2: Vec<&str> = e2.iter().map(String::as_str).collect();
    let e1 = g.concat("E1", &e1, 1);
    let e2 = g.concat("E2", &e2, 1);
    let mut levels = Vec::new();
    let mut cur = e2.clone();
    for k in 0..cfg.merger_widths().len() {
        let p = format!("merger.down.{k}");
        let l = g.leaky_relu(&format!("{p}.lrelu"), &cur, wu::LEAK);
        let c = conv_same(&mut g, &format!("{p}.conv"), &l, 5, 2)?;
        cur = g.batch_norm(&format!("{p}.bn"), &c, eps)?;
        levels.push(cur.clone());
    }
    let deepest = levels.pop().expect("at least one merger level");
    let mut cur = match cfg.variant {
        WuVariant::Resnet => {
            let mut r = deepest.clone();
            for b in 0..cfg.res_blocks {
                let p = format!("merger.res.{b}");
                // As released: each block gets relu of the running tensor and adds to it.
                let rr = g.relu(&format!("{p}.in"), &r);
                let c = conv_same(&mut g, &format!("{p}.conv1"), &rr, 3, 1)?;
                let y = g.batch_norm(&format!("{p}.bn1"), &c, eps)?;
                let y = g.relu(&format!("{p}.relu"), &y);
                let c = conv_same(&mut g, &format!("{p}.conv2"), &y, 3, 1)?;
                let y = g.batch_norm(&format!("{p}.bn2"), &c, eps)?;
                r = g.node("Add", &format!("{p}.add"), &[&rr, &y], vec![]);
            }
            g.concat("merger.out", &[&r, &deepest], 1)
        }
        WuVariant::Unet => deepest,
    };
    let mut skips: Vec<String> = levels.into_iter().rev().collect();
    skips.extend([e2, e1]);
    let mut skips = skips.into_iter();
    // TensorFlow 'SAME' alignment = Burn padding 1 with the last row/column cropped: ONNX pads
    // 1 at the start and 2 at the end. The PyTorch port's: padding 2, output_padding 1.
    let (pads, out_pad) = match cfg.deconv_alignment {
        DeconvAlignment::Tensorflow => ([1, 1, 2, 2], 0),
        DeconvAlignment::Pytorch => ([2; 4], 1),
    };
    for j in 0..cfg.merger_widths().len() + 2 {
        let p = format!("decoder.up.{j}");
        let x = g.relu(&format!("{p}.relu"), &cur);
        let y = g.conv_transpose(&format!("{p}.deconv"), &x, 2, pads, out_pad)?;
        let y = g.batch_norm(&format!("{p}.bn"), &y, eps)?;
        cur = match skips.next() {
            Some(s) => g.concat(&format!("{p}.cat"), &[&y, &s], 1),
            None => y,
        };
    }
    let x = g.relu("decoder.out.relu", &cur);
    let out = conv_same(&mut g, "decoder.out", &x, 5, 1)?;
    let out = g.node("Tanh", "decoder.tanh", &[&out], vec![]);
    let out = g.with_scalar("Add", "decoder.plus1", &out, 1.0);
    let out = g.with_scalar("Mul", "decoder.half", &out, 0.5);
    let out = g.with_scalar("Mul", "hdr_unit", &out, (1.0 / cfg.hdr_input_scale) as f32);
    g.output(&out, N2_OUTPUT, &[n, Dim::Fixed(wu::OUTPUT_CHANNELS), h, w])?;
    let graph = g.finish("hdrsynth_network2")?;
    Ok(model_proto(
        graph,
        vec![
            (META_NETWORK, "network2".into()),
            (META_SIZE_MULTIPLE, m.to_string()),
            (META_MIN_SIZE, network2_min_size(&cfg).to_string()),
            (META_RADIUS, cfg.receptive_radius().to_string()),
            (META_HDR_SCALE, cfg.hdr_input_scale.to_string()),
        ],
    ))
}

/// The model's protobuf bytes.
pub fn to_bytes(model: &ModelProto) -> Vec<u8> {
    model.encode_to_vec()
}

/// A model back from its protobuf bytes (to inspect an exported file).
pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<ModelProto> {
    ModelProto::decode(bytes).map_err(|e| Error::decode(path, e))
}

/// Writes the model atomically.
pub fn save(model: &ModelProto, path: &Path) -> Result<()> {
    write_atomic(path, &to_bytes(model))
}
