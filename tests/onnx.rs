//! ONNX export of both networks, checked in the real ONNX Runtime (cargo feature `onnx`;
//! ORT_DYLIB_PATH from tools/setup_ort.sh). ONNX Runtime is an independent implementation of
//! every operator; each export is compared with Burn's forward pass on inputs the export never
//! saw (other sizes, real frames) with fully random weights and BatchNorm statistics.
#![cfg(feature = "onnx")]

mod common;

use burn::module::Module;
use burn::tensor::Device;
use hdrsynth::io::read_image;
use hdrsynth::models::import::{expected_tensors, import_weights};
use hdrsynth::models::seeded_init;
use hdrsynth::models::{BlendUNet, BlendUNetConfig, ModelConfig, WuConfig, WuNet};
use hdrsynth::onnx::export::{self, ExportOptions, InputSize};
use hdrsynth::onnx::runtime::OnnxModel;
use hdrsynth::onnx::verify::{self, Check, Loaded};
use hdrsynth::train::checkpoint::{self, CheckpointState};
use std::path::{Path, PathBuf};
use std::process::Command;

const TOLERANCE: f32 = 1e-4;

/// ONNX Runtime must be there: with the feature on and no library these tests fail, loudly.
fn require_ort() {
    if let Err(e) = hdrsynth::onnx::runtime::dylib_path() {
        panic!("the onnx tests need ONNX Runtime: {e}");
    }
}

fn device() -> Device {
    hdrsynth::device::device_from_name("flex").expect("flex")
}

/// Replaces every weight and BatchNorm statistic of `model` by seeded random values (through
/// a SafeTensors file and the strict importer), so that no parameter keeps a neutral value
/// (γ = 1, β = 0, mean 0, variance 1) that a wrong export could get right by accident.
fn randomize<M: Module>(model: M, seed: u64, dir: &Path) -> M {
    let tensors = expected_tensors(&model);
    let mut bytes = Vec::new();
    for (k, (name, shape)) in tensors.iter().enumerate() {
        let n: usize = shape.iter().product();
        let u = common::values(n, seed * 1000 + k as u64);
        let fan_in: usize = shape.iter().skip(1).product::<usize>().max(1);
        let v: Vec<f32> = if name.ends_with("running_var") {
            u.iter().map(|x| 0.5 + x).collect()
        } else if name.ends_with("running_mean") || shape.len() == 1 {
            u.iter().map(|x| 0.4 * (x - 0.5)).collect()
        } else {
            let a = 1.7 / (fan_in as f32).sqrt();
            u.iter().map(|x| a * (2.0 * x - 1.0)).collect()
        };
        // BatchNorm γ around 1 (the 1-D `weight`s of norms).
        let v = if shape.len() == 1 && name.ends_with(".weight") {
            v.iter().map(|x| 1.0 + x).collect()
        } else {
            v
        };
        bytes.push(v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>());
    }
    let views: Vec<(String, safetensors::tensor::TensorView)> = tensors
        .iter()
        .zip(&bytes)
        .map(|((name, shape), b)| {
            let view =
                safetensors::tensor::TensorView::new(safetensors::Dtype::F32, shape.clone(), b)
                    .expect("view");
            (name.clone(), view)
        })
        .collect();
    let path = dir.join(format!("random-{seed}.safetensors"));
    safetensors::serialize_to_file(views, None, &path).expect("write safetensors");
    import_weights(model, &path).expect("import random weights")
}

fn network1(cfg: &BlendUNetConfig, seed: u64, dir: &Path) -> BlendUNet {
    let dev = device();
    let m = seeded_init(&dev, seed, || cfg.init(&dev)).expect("init");
    randomize(m, seed, dir)
}

fn network2(cfg: &WuConfig, seed: u64, dir: &Path) -> WuNet {
    let dev = device();
    let m = seeded_init(&dev, seed, || cfg.init(&dev)).expect("init");
    randomize(m, seed, dir)
}

fn export_and_load(loaded: &Loaded, opts: &ExportOptions, path: &Path) -> OnnxModel {
    export::save(&loaded.to_onnx(opts).expect("export"), path).expect("save");
    OnnxModel::load(path, Some(2)).expect("ONNX Runtime loads the export")
}

fn assert_close(checks: &[Check], what: &str) {
    assert!(!checks.is_empty());
    for c in checks {
        eprintln!("{what}: {c}");
        assert!(
            c.max_abs_diff <= TOLERANCE,
            "{what}: ONNX Runtime vs Burn: {c}"
        );
    }
}

/// Real frames: the committed 64×48 Desk crop's brackets (tests/data/oracle_crops), and a label.
fn images(names: &[&str]) -> (Vec<hdrsynth::io::Image>, String) {
    let frames = names
        .iter()
        .map(|n| read_image(&common::oracle_crops(n)).expect("image"))
        .collect();
    (frames, format!("real crop {}", names.join(" + ")))
}

#[test]
fn network1_exports_match_burn_in_onnx_runtime() {
    require_ort();
    let tmp = tempfile::tempdir().expect("tmp");
    let dev = device();
    let real = images(&["desk_ev-3.png", "desk_ev+0.png"]);
    let real_ref = Some((real.0.as_slice(), real.1.as_str()));
    for (k, batch_norm) in [true, false].into_iter().enumerate() {
        let cfg = BlendUNetConfig {
            base_width: 4,
            depth: 2,
            batch_norm,
            ..Default::default()
        };
        let loaded = Loaded::Network1(network1(&cfg, 3 + k as u64, tmp.path()));
        // Dynamic: checked at two non-square sizes (64×68, 72×64) and the 64×48 real crop.
        let path = tmp.path().join(format!("n1-dyn-{k}.onnx"));
        let mut onnx = export_and_load(&loaded, &ExportOptions::default(), &path);
        assert_eq!(onnx.static_size, None);
        let checks =
            verify::verify(&loaded, &mut onnx, InputSize::Dynamic, real_ref, &dev).expect("verify");
        assert_close(
            &checks,
            &format!("Network-1 dynamic, batch norm {batch_norm}"),
        );
        assert!(checks.iter().all(|c| c.weight_max_abs_diff.is_some()));
        assert!(checks.iter().any(|c| c.height != c.width));
        assert!(
            checks
                .iter()
                .any(|c| c.input == real.1 && (c.height, c.width) == (48, 64))
        );
        // Inputs off the 2^depth grid are refused before ONNX Runtime sees them.
        let e = onnx
            .network1(&[0.0; 3 * 30 * 32], &[0.0; 3 * 30 * 32], (1, 30, 32))
            .unwrap_err()
            .to_string();
        assert!(e.contains("multiples of 4"), "{e}");
    }

    // Static 32×48, probabilities only.
    let cfg = BlendUNetConfig {
        base_width: 4,
        depth: 2,
        ..Default::default()
    };
    let loaded = Loaded::Network1(network1(&cfg, 5, tmp.path()));
    let size = InputSize::Static {
        height: 32,
        width: 48,
    };
    let opts = ExportOptions {
        size,
        blend_weight: false,
    };
    let mut onnx = export_and_load(&loaded, &opts, &tmp.path().join("n1-static.onnx"));
    assert_eq!(onnx.static_size, Some((32, 48)));
    assert!(!onnx.has_weight);
    let checks = verify::verify(&loaded, &mut onnx, size, real_ref, &dev).expect("verify");
    assert_close(&checks, "Network-1 static 32×48");
    // A static size larger than the real frames (64×48): they continue by reflection.
    let big = InputSize::Static {
        height: 336,
        width: 384,
    };
    let big_opts = ExportOptions {
        size: big,
        blend_weight: true,
    };
    let mut big_onnx = export_and_load(&loaded, &big_opts, &tmp.path().join("n1-big.onnx"));
    let checks = verify::verify(&loaded, &mut big_onnx, big, real_ref, &dev).expect("verify");
    assert_close(&checks, "Network-1 static 336×384");
    let e = onnx
        .network1(&[0.0; 3 * 48 * 32], &[0.0; 3 * 48 * 32], (1, 48, 32))
        .unwrap_err()
        .to_string();
    assert!(e.contains("static 32×48"), "{e}");
    // A static size off the grid is refused at export.
    let bad = ExportOptions {
        size: InputSize::Static {
            height: 30,
            width: 48,
        },
        blend_weight: true,
    };
    let e = loaded.to_onnx(&bad).unwrap_err().to_string();
    assert!(e.contains("height 30 must be a multiple of 4"), "{e}");
}

#[test]
fn network2_exports_match_burn_in_onnx_runtime() {
    require_ort();
    let tmp = tempfile::tempdir().expect("tmp");
    let dev = device();
    // Generated frames (the scene engine, EV −2/0/+2) and the real desk triple.
    let gen_dir = tmp.path().join("gen");
    common::generate(&gen_dir, 17, 1, (96, 80), "[-2.0, 0.0, 2.0]");
    let set = common::first_set(&gen_dir);
    let generated: Vec<hdrsynth::io::Image> = ["ev-2", "ev+0", "ev+2"]
        .iter()
        .map(|e| read_image(&set.join(format!("static/{e}.png"))).expect("frame"))
        .collect();
    let (real_frames, real_label) = images(&["desk_ev-2.png", "desk_ev+0.png", "desk_ev+2.png"]);

    let mut resnet = WuConfig::resnet(2);
    resnet.res_blocks = 2;
    let mut resnet_unit = resnet.clone();
    resnet_unit.hdr_input_scale = 1.0;
    let mut unet = WuConfig::unet(2);
    unet.unet_merger_widths = vec![2, 3];
    unet.deconv_alignment = hdrsynth::models::wu::DeconvAlignment::Pytorch;
    for (k, cfg) in [resnet, resnet_unit, unet].iter().enumerate() {
        let loaded = Loaded::Network2(network2(cfg, 20 + k as u64, tmp.path()));
        let what = format!(
            "Network-2 {:?} {:?} scale {}",
            cfg.variant, cfg.deconv_alignment, cfg.hdr_input_scale
        );
        let path = tmp.path().join(format!("n2-dyn-{k}.onnx"));
        let mut onnx = export_and_load(&loaded, &ExportOptions::default(), &path);
        let gen_ref = Some((generated.as_slice(), "generated set (96×80 crop)"));
        let mut checks =
            verify::verify(&loaded, &mut onnx, InputSize::Dynamic, gen_ref, &dev).expect("verify");
        let m = loaded.size_multiple();
        let (h, w) = (
            (real_frames[0].height.min(256) / m) * m,
            (real_frames[0].width.min(256) / m) * m,
        );
        let frames = verify::crop_frames(&real_frames, h, w).expect("crop");
        checks.push(
            verify::compare(
                &loaded,
                &mut onnx,
                &frames,
                verify::CHECK_TIMES,
                &dev,
                &real_label,
            )
            .expect("compare"),
        );
        assert_close(&checks, &what);
        assert!(checks.iter().any(|c| c.height != c.width));
        // The output is linear HDR above the reference's white where the short frame says so:
        // not clipped to [0, 1] (scale 0.25: up to 4).
        if cfg.hdr_input_scale == 0.25 {
            assert_eq!(onnx.hdr_input_scale, Some(0.25));
        }
    }

    // A batch of two with different exposure times per item, against Burn on the same batch.
    {
        let mut cfg = WuConfig::resnet(2);
        cfg.res_blocks = 1;
        let model = network2(&cfg, 25, tmp.path());
        let unit = 1.0 / cfg.hdr_input_scale as f32;
        let (h, w) = (40, 24);
        let times = [[0.25f32, 1.0, 4.0], [0.5, 1.0, 2.0]];
        let items: Vec<Vec<hdrsynth::eval::tiling::Planar>> = (0..2)
            .map(|b| verify::random_frames(3, h, w, 70 + b))
            .collect();
        let mut x = Vec::new();
        for (b, frames) in items.iter().enumerate() {
            let mut ldr = hdrsynth::eval::tiling::Planar::new(9, w, h);
            for (k, f) in frames.iter().enumerate() {
                ldr.data[k * 3 * w * h..(k + 1) * 3 * w * h].copy_from_slice(&f.data);
            }
            x.extend(
                hdrsynth::eval::infer::network2_input(
                    &ldr,
                    times[b],
                    &hdrsynth::models::wu::wu_input_response(),
                )
                .data,
            );
        }
        let x = burn::tensor::Tensor::<4>::from_data(
            burn::tensor::TensorData::new(x, [2, 18, h, w]),
            &dev,
        );
        let expected: Vec<f32> = model
            .forward(x)
            .mul_scalar(unit)
            .into_data()
            .try_into_vec::<f32>()
            .expect("burn output");
        let path = tmp.path().join("n2-batch.onnx");
        let mut onnx = export_and_load(&Loaded::Network2(model), &ExportOptions::default(), &path);
        let frame =
            |k: usize| -> Vec<f32> { items.iter().flat_map(|f| f[k].data.clone()).collect() };
        let (f0, f1, f2) = (frame(0), frame(1), frame(2));
        let flat_times: Vec<f32> = times.iter().flatten().copied().collect();
        let got = onnx
            .network2([&f0, &f1, &f2], &flat_times, (2, h, w))
            .expect("batch of two");
        let d = common::max_abs_diff(&got, &expected);
        eprintln!("Network-2 batch of 2 (40×24): max |ONNX Runtime − Burn| = {d:.3e}");
        assert!(d <= TOLERANCE, "batch of two: {d}");
    }

    // Static export of the ResNet at 32×48, and the minimum size enforced (16 for the ResNet:
    // reflection pads must be shorter than their axis).
    let mut cfg = WuConfig::resnet(2);
    cfg.res_blocks = 1;
    let loaded = Loaded::Network2(network2(&cfg, 30, tmp.path()));
    assert_eq!(loaded.min_size(), 16);
    let size = InputSize::Static {
        height: 32,
        width: 48,
    };
    let opts = ExportOptions {
        size,
        blend_weight: true,
    };
    let mut onnx = export_and_load(&loaded, &opts, &tmp.path().join("n2-static.onnx"));
    let checks = verify::verify(&loaded, &mut onnx, size, None, &dev).expect("verify");
    assert_close(&checks, "Network-2 static 32×48");
    let small = ExportOptions {
        size: InputSize::Static {
            height: 8,
            width: 16,
        },
        blend_weight: true,
    };
    let e = loaded.to_onnx(&small).unwrap_err().to_string();
    assert!(e.contains("at least 16"), "{e}");
    // Hand-computed minimum of the default U-Net: 2^5 grid, and the fifth stride-2 convolution
    // needs an axis > 2 at 1/16 scale: 64.
    assert_eq!(export::network2_min_size(&WuConfig::unet(64)), 64);
}

/// The graph forms Wu's inputs and image head only: a merge head, or an input curve other
/// than a gamma, is refused with what the network has, not exported wrong.
#[test]
fn export_refuses_what_the_graph_cannot_form() {
    use hdrsynth::models::wu::WuOutput;
    use hdrsynth::sensor::profile::Response;
    let dev = Device::flex();
    for (cfg, names) in [
        (
            WuConfig {
                output: WuOutput::Merge,
                ..WuConfig::resnet(2)
            },
            "Merge",
        ),
        (
            WuConfig {
                input_response: Response::Srgb,
                ..WuConfig::resnet(2)
            },
            "srgb",
        ),
    ] {
        let net = seeded_init(&dev, 0, || cfg.init(&dev)).expect("init");
        let e = export::network2(&net, &ExportOptions::default())
            .expect_err("refused")
            .to_string();
        assert!(e.contains("Wu's form") && e.contains(names), "{e}");
    }
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
}

fn save_checkpoint<M: Module>(run: &Path, model: &M, cfg: ModelConfig) {
    let state = CheckpointState {
        format: checkpoint::FORMAT.into(),
        step: 7,
        samples: 7,
        epoch: 0,
        rng_seed: 1,
        loss: None,
        model: cfg,
    };
    checkpoint::save(run, &state, model, None, 1, |_| Ok(())).expect("checkpoint");
}

fn exr(path: &Path) -> Vec<f32> {
    read_image(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .data
}

#[test]
fn export_cli_verifies_and_infer_onnx_matches_the_checkpoint() {
    require_ort();
    let tmp = tempfile::tempdir().expect("tmp");
    let t = tmp.path();
    let n1_cfg = BlendUNetConfig {
        base_width: 4,
        depth: 2,
        ..Default::default()
    };
    save_checkpoint(
        &t.join("run1"),
        &network1(&n1_cfg, 40, t),
        ModelConfig::BlendUnet(n1_cfg.clone()),
    );
    let mut n2_cfg = WuConfig::resnet(2);
    n2_cfg.res_blocks = 2;
    save_checkpoint(
        &t.join("run2"),
        &network2(&n2_cfg, 41, t),
        ModelConfig::Wu(n2_cfg.clone()),
    );
    common::generate(&t.join("pairs"), 5, 1, (96, 80), "[-3.0, 0.0]");
    common::generate(&t.join("triples"), 6, 1, (96, 80), "[-2.0, 0.0, 2.0]");

    let run = |args: &[&str]| {
        let out = bin().args(args).output().expect("run hdrsynth");
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(out.status.success(), "hdrsynth {args:?} failed:\n{text}");
        eprintln!("{text}");
        text
    };
    let s = |p: PathBuf| p.to_string_lossy().into_owned();
    for (run_dir, set_root, name) in [("run1", "pairs", "n1"), ("run2", "triples", "n2")] {
        let ckpt = s(t.join(run_dir));
        let dyn_file = s(t.join(format!("{name}.onnx")));
        let text = run(&[
            "export",
            "onnx",
            "--checkpoint",
            &ckpt,
            "--out",
            &dyn_file,
            "--verify",
        ]);
        assert!(text.contains("verified in ONNX Runtime"), "{text}");
        let set = s(common::first_set(&t.join(set_root)));
        let reference = t.join(format!("{name}-burn"));
        run(&[
            "infer",
            "--checkpoint",
            &ckpt,
            "--set",
            &set,
            "--out",
            &s(reference.clone()),
            "--tile",
            "32",
            "--engine",
            "burn",
        ]);
        // The default engine (auto) runs Network-1 in ONNX Runtime on CPU when it is there and
        // Network-2 in flex (the faster of each, BENCHMARKS.md).
        let auto = t.join(format!("{name}-auto"));
        let text = run(&[
            "infer",
            "--checkpoint",
            &ckpt,
            "--set",
            &set,
            "--out",
            &s(auto.clone()),
            "--tile",
            "32",
        ]);
        let want = if name == "n1" { "ONNX Runtime" } else { "Burn" };
        assert!(text.contains(want), "{name}: {text}");
        let via_onnx = t.join(format!("{name}-onnx"));
        run(&[
            "infer",
            "--onnx",
            &dyn_file,
            "--set",
            &set,
            "--out",
            &s(via_onnx.clone()),
            "--tile",
            "32",
        ]);
        let file = if name == "n1" {
            "linear.exr"
        } else {
            "hdr.exr"
        };
        let d = common::max_abs_diff(&exr(&reference.join(file)), &exr(&via_onnx.join(file)));
        eprintln!("{name}: infer --onnx vs --checkpoint, {file}: max abs diff {d:.3e}");
        assert!(d <= TOLERANCE, "{name}: infer --onnx vs --checkpoint: {d}");
        let d = common::max_abs_diff(&exr(&reference.join(file)), &exr(&auto.join(file)));
        eprintln!("{name}: --engine auto vs burn, {file}: max abs diff {d:.3e}");
        assert!(d <= TOLERANCE, "{name}: --engine auto vs burn: {d}");
        // A static export runs through the same tiles (windows padded to its size).
        let static_file = s(t.join(format!("{name}-static.onnx")));
        run(&[
            "export",
            "onnx",
            "--checkpoint",
            &ckpt,
            "--out",
            &static_file,
            "--height",
            "256",
            "--width",
            "256",
        ]);
        let via_static = t.join(format!("{name}-onnx-static"));
        run(&[
            "infer",
            "--onnx",
            &static_file,
            "--set",
            &set,
            "--out",
            &s(via_static.clone()),
        ]);
        let d = common::max_abs_diff(&exr(&reference.join(file)), &exr(&via_static.join(file)));
        eprintln!(
            "{name}: infer with a static 256×256 export vs --checkpoint: max abs diff {d:.3e}"
        );
        assert!(d <= TOLERANCE, "{name}: static export vs --checkpoint: {d}");
    }

    // Without ORT_DYLIB_PATH, --verify fails and says what to do.
    let out = bin()
        .args([
            "export",
            "onnx",
            "--checkpoint",
            &s(t.join("run1")),
            "--out",
            &s(t.join("x.onnx")),
            "--verify",
        ])
        .env_remove("ORT_DYLIB_PATH")
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("ORT_DYLIB_PATH is not set") && err.contains("tools/setup_ort.sh"),
        "{err}"
    );
}

/// The graph, counted by hand from the architecture: opset 17, one
/// BatchNormalization per BatchNorm module, Pad(mode = reflect) before every Network-2
/// convolution, ConvTranspose with the pads/output_padding of each alignment.
#[test]
fn exported_graphs_have_the_promised_structure() {
    use hdrsynth::onnx::proto::{AttributeProto, NodeProto};
    let tmp = tempfile::tempdir().expect("tmp");
    let attr = |n: &NodeProto, name: &str| -> AttributeProto {
        n.attribute
            .iter()
            .find(|a| a.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("{:?} has no '{name}'", n.name))
            .clone()
    };
    let count = |nodes: &[NodeProto], op: &str| {
        nodes
            .iter()
            .filter(|n| n.op_type.as_deref() == Some(op))
            .count()
    };
    // Network-1, depth 2 with BatchNorm: 5 blocks (3 encoder levels, 2 decoder) × 2.
    let cfg = BlendUNetConfig {
        base_width: 4,
        depth: 2,
        ..Default::default()
    };
    let m = Loaded::Network1(network1(&cfg, 50, tmp.path()));
    let g = m.to_onnx(&ExportOptions::default()).expect("export");
    assert_eq!(g.opset_import[0].version, Some(17));
    let nodes = &g.graph.as_ref().expect("graph").node;
    assert_eq!(count(nodes, "BatchNormalization"), 10);
    assert_eq!(count(nodes, "ConvTranspose"), 2);
    assert_eq!(count(nodes, "MaxPool"), 2);
    assert_eq!(count(nodes, "Pad"), 0);
    for n in nodes
        .iter()
        .filter(|n| n.op_type.as_deref() == Some("ConvTranspose"))
    {
        assert_eq!(attr(n, "kernel_shape").ints, [2, 2]);
        assert_eq!(attr(n, "strides").ints, [2, 2]);
        assert_eq!(attr(n, "pads").ints, [0, 0, 0, 0]);
        assert_eq!(attr(n, "output_padding").ints, [0, 0]);
    }

    // Network-2 ResNet, 2 residual blocks: BatchNorms 3 (encoders) + 1 (merger) + 2·2
    // (residual) + 3 (decoder) = 11; reflection pads before 3·2 encoder + 1 merger + 2·2
    // residual convolutions + the output convolution = 12; 3 transposed convolutions.
    for (alignment, pads, out_pad) in [
        (
            hdrsynth::models::wu::DeconvAlignment::Tensorflow,
            [1, 1, 2, 2],
            0,
        ),
        (
            hdrsynth::models::wu::DeconvAlignment::Pytorch,
            [2, 2, 2, 2],
            1,
        ),
    ] {
        let mut cfg = WuConfig::resnet(2);
        cfg.res_blocks = 2;
        cfg.deconv_alignment = alignment;
        let m = Loaded::Network2(network2(&cfg, 51, tmp.path()));
        let bytes = export::to_bytes(&m.to_onnx(&ExportOptions::default()).expect("export"));
        let g = export::from_bytes(&bytes, Path::new("n2.onnx")).expect("decode");
        let nodes = &g.graph.as_ref().expect("graph").node;
        assert_eq!(count(nodes, "BatchNormalization"), 11);
        assert_eq!(count(nodes, "Pad"), 12);
        assert_eq!(count(nodes, "ConvTranspose"), 3);
        for n in nodes.iter().filter(|n| n.op_type.as_deref() == Some("Pad")) {
            assert_eq!(attr(n, "mode").s.as_deref(), Some(&b"reflect"[..]));
        }
        for n in nodes
            .iter()
            .filter(|n| n.op_type.as_deref() == Some("ConvTranspose"))
        {
            assert_eq!(attr(n, "kernel_shape").ints, [5, 5]);
            assert_eq!(attr(n, "pads").ints, pads);
            assert_eq!(attr(n, "output_padding").ints, [out_pad, out_pad]);
        }
        let inputs: Vec<_> = g
            .graph
            .as_ref()
            .unwrap()
            .input
            .iter()
            .map(|v| v.name.clone().unwrap())
            .collect();
        assert_eq!(
            inputs,
            [
                "frame_short",
                "frame_reference",
                "frame_long",
                "exposure_times"
            ]
        );
    }
}

/// `engine`: a checkpoint run through each engine. `auto` on the CPU
/// device picks ONNX Runtime when it is there (these tests require it), `burn` forces Burn, and
/// both agree within the parity tolerance on Network-1's blend weights and Network-2's HDR.
#[test]
fn engines_agree_and_auto_picks_the_faster_engine_on_cpu() {
    use hdrsynth::eval::infer::Engine;
    use hdrsynth::eval::infer::NetworkOptions;
    use hdrsynth::runner::LoadedNetwork;
    require_ort();
    let tmp = tempfile::tempdir().expect("tmp");
    let t = tmp.path();
    let n1_cfg = BlendUNetConfig {
        base_width: 4,
        depth: 2,
        ..Default::default()
    };
    save_checkpoint(
        &t.join("run1"),
        &network1(&n1_cfg, 50, t),
        ModelConfig::BlendUnet(n1_cfg.clone()),
    );
    let mut n2_cfg = WuConfig::resnet(2);
    n2_cfg.res_blocks = 2;
    save_checkpoint(
        &t.join("run2"),
        &network2(&n2_cfg, 51, t),
        ModelConfig::Wu(n2_cfg.clone()),
    );
    let (w, h) = (72, 56);
    let frame = |seed: u64, gain: f32| {
        let v = common::values(w * h * 3, seed);
        hdrsynth::io::Image::from_vec(w, h, v.iter().map(|x| (x * gain).min(1.0)).collect())
    };
    let (low, high, mid) = (frame(1, 0.3), frame(2, 1.0), frame(3, 0.7));
    let load = |run: &str, engine: Engine| {
        let opts = NetworkOptions {
            tile: Some(32),
            engine,
            ..NetworkOptions::default()
        };
        LoadedNetwork::from_checkpoint(&t.join(run), &opts, &device()).expect("load")
    };
    for run in ["run1", "run2"] {
        let auto = load(run, Engine::Auto);
        let burn = load(run, Engine::Burn);
        let onnx = load(run, Engine::Onnx);
        // Network-1 in ONNX Runtime, Network-2 in flex: the faster of each on the CPU
        // (BENCHMARKS.md).
        let want = if run == "run1" {
            "ONNX Runtime"
        } else {
            "Burn"
        };
        assert_eq!(auto.engine(), want, "{run}: {}", auto.describe());
        assert_eq!(burn.engine(), "Burn");
        assert_eq!(onnx.engine(), "ONNX Runtime");
        assert_eq!(
            burn.tiling, onnx.tiling,
            "{run}: one tiling for every engine"
        );
        let out = |n: &LoadedNetwork| -> Vec<f32> {
            if run == "run1" {
                n.network1_weight(&low, &high, Default::default())
                    .expect("weights")
            } else {
                n.network2_hdr([&low, &mid, &high], [0.25, 1.0, 4.0])
                    .expect("hdr")
                    .data
            }
        };
        let (b, o) = (out(&burn), out(&onnx));
        assert_eq!(b.len(), o.len());
        let d = common::max_abs_diff(&b, &o);
        eprintln!("{run}: ONNX Runtime vs Burn, max abs diff {d:.3e}");
        assert!(d <= TOLERANCE, "{run}: engines differ by {d}");
        assert!(
            b.iter().any(|&v| v != b[0]),
            "{run}: a constant output tests nothing"
        );
        // A wrong-network call is an error, not a panic.
        let wrong = if run == "run1" {
            onnx.network2_hdr([&low, &mid, &high], [0.25, 1.0, 4.0])
                .is_err()
        } else {
            onnx.network1_weight(&low, &high, Default::default())
                .is_err()
        };
        assert!(wrong, "{run}: the other network's call must fail");
    }
}
