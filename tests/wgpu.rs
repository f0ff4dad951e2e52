//! Burn's wgpu backend (cargo feature `wgpu`) run, not only compiled, and checked against flex.
//! CI runs these on lavapipe (Mesa's Vulkan driver on the CPU; `.ci/run` installs
//! `mesa-vulkan-drivers`); on a machine with a GPU and its Vulkan/Metal/DX12 driver they run
//! there. `cargo test --release --features wgpu,onnx --test wgpu` (docs/gpu.md).
//!
//! Every other test runs flex, where the layers go through this crate's own kernels
//! (`kernels::conv`: im2col, Winograd, polyphase, direct; the fused BatchNorm+ReLU, pooling,
//! reflection padding and leaky ReLU; `kernels::fused_loss`). Each of them is taken only where
//! `device::is_flex` holds, so on wgpu the same model code runs Burn's own operations
//! ([`wgpu_runs_burns_ops_not_the_flex_kernels`]): these tests compare two implementations of
//! the networks, from the same weights on the same data. The sizes are chosen so that flex
//! takes its Winograd path (Network-1's 16-channel 3×3 layers and 5×5 head), its polyphase
//! path (Network-2's 5×5 stride-2 layers from 8 channels on) and its direct kernel (Network-2's
//! 3-channel output layer).
//!
//! Agreement is the largest element difference relative to the tensor's largest magnitude on
//! flex, max|wgpu − flex| / max|flex| (f32 summed in another order; an element-wise relative
//! error is meaningless where values pass through 0). Each figure is printed
//! (`-- --nocapture`).
#![cfg(feature = "wgpu")]

mod common;

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor};
use hdrsynth::config::parse_toml;
use hdrsynth::data::ground_truth::{ClassWeights, MertensWeights};
use hdrsynth::data::layout;
use hdrsynth::data::loader::Sample;
use hdrsynth::device::{device_from_name, is_cpu, is_flex};
use hdrsynth::eval::infer::Engine;
use hdrsynth::eval::infer::{NetworkOptions, network1_frames, network2_frames};
use hdrsynth::io::{Image, read_image};
use hdrsynth::models::seeded_init;
use hdrsynth::models::{BlendUNetConfig, ModelConfig, WuConfig};
use hdrsynth::runner::LoadedNetwork;
use hdrsynth::train::TrainOptions;
use hdrsynth::train::checkpoint;
use hdrsynth::train::config::{DEFAULT_LABEL_SIGMA, TrainConfig};
use hdrsynth::train::loss::{Network1Reading, network1_batch, network2_batch};
use hdrsynth::train::task::{Network1, Network2, Task};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Outputs and losses: f32 rounding in another summation order.
const OUTPUT_TOL: f64 = 1e-4;
/// Gradients: each is a sum over every pixel of the batch, and BatchNorm on batch statistics
/// divides by a per-channel standard deviation of the few values a small batch has.
const GRAD_TOL: f64 = 1e-3;
/// Below this share of the model's largest gradient a tensor's gradient is taken as 0.
const GRAD_FLOOR: f64 = 1e-3;
/// Adam's own f32 rounding of u(g) = m̂/(√v̂ + ε) (bias corrections, square root), in units of lr.
const ADAM_ROUNDING: f64 = 1e-6;
/// The step's learning rate and Adam's ε (the trainer's default).
const LR: f64 = 1e-3;
const ADAM_EPSILON: f64 = 1e-8;

fn wgpu() -> Device {
    device_from_name("wgpu").unwrap_or_else(|e| panic!("the wgpu tests need an adapter: {e}"))
}

fn flex() -> Device {
    device_from_name("flex").expect("flex")
}

/// max|a − b| / max|b| (0 when both are 0).
fn rel(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len(), "lengths differ");
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs() as f64));
    let diff = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((*x as f64 - *y as f64).abs()));
    assert!(diff.is_finite(), "non-finite values");
    if diff == 0.0 { 0.0 } else { diff / scale }
}

fn max_abs(a: &[f32], b: &[f32]) -> f64 {
    common::max_abs_diff(a, b) as f64
}

/// Every float tensor of a module (parameters and BatchNorm statistics), with its path.
fn tensors<M: Module>(m: &M) -> Vec<(String, Vec<f32>)> {
    #[derive(Default)]
    struct V {
        path: Vec<String>,
        out: Vec<(String, Vec<f32>)>,
    }
    impl ModuleVisitor for V {
        fn enter_module(&mut self, name: &str, _: &str) {
            self.path.push(name.to_string());
        }
        fn exit_module(&mut self, _: &str, _: &str) {
            self.path.pop();
        }
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            self.out
                .push((self.path.join("."), common::to_vec(p.val())));
        }
    }
    let mut v = V::default();
    m.visit(&mut v);
    v.out
}

/// The gradient of every trainable parameter, with its path, in visiting order.
fn gradients<M: Module>(m: &M, grads: &GradientsParams) -> Vec<(String, Vec<f32>)> {
    struct V<'a> {
        grads: &'a GradientsParams,
        path: Vec<String>,
        out: Vec<(String, Vec<f32>)>,
    }
    impl ModuleVisitor for V<'_> {
        fn enter_module(&mut self, name: &str, _: &str) {
            self.path.push(name.to_string());
        }
        fn exit_module(&mut self, _: &str, _: &str) {
            self.path.pop();
        }
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            if let Some(g) = self.grads.get::<D>(p.id) {
                self.out.push((self.path.join("."), common::to_vec(g)));
            }
        }
    }
    let mut v = V {
        grads,
        path: Vec::new(),
        out: Vec::new(),
    };
    m.visit(&mut v);
    v.out
}

#[test]
fn wgpu_runs_burns_ops_not_the_flex_kernels() {
    let dev = wgpu();
    eprintln!(
        "wgpu adapter: {}",
        hdrsynth::device::wgpu_adapter().expect("acquired")
    );
    // The one switch every fused flex path checks (kernels::conv, batch_norm, pool, pad,
    // activation; kernels::fused_loss): false on wgpu, so Burn's ops run there.
    assert!(!is_flex(&dev) && !is_flex(&dev.clone().autodiff()));
    assert!(is_flex(&flex().autodiff()));
    // `Engine::Auto` keeps a wgpu checkpoint in Burn (ONNX Runtime runs on the CPU).
    assert!(!is_cpu(&dev));
    // The fused Network-1 loss answers only for flex tensors.
    let inputs = |d: &Device| {
        let l = Tensor::<4>::zeros([1, 4, 2, 2], d);
        let t = Tensor::<3, burn::tensor::Int>::zeros([1, 2, 2], d);
        let a = Tensor::<1>::ones([4], d);
        (l, t, a)
    };
    let loss = hdrsynth::kernels::fused_loss::ClassLoss {
        reading: Network1Reading::Literal,
        sigma: 0.0,
    };
    let on = |d: &Device| {
        let (l, t, a) = inputs(d);
        hdrsynth::kernels::fused_loss::class_loss(&l, &t, &a, loss).is_some()
    };
    assert!(on(&flex()) && !on(&dev));
    // A device index means nothing for wgpu: refused, not ignored.
    let err = device_from_name("wgpu:1").expect_err("index").to_string();
    assert!(err.contains("only cuda takes an index"), "{err}");
    // Something computes, with the right answer: [[1,2],[3,4]]² sums to 54.
    let t = Tensor::<2>::from_floats([[1.0, 2.0], [3.0, 4.0]], &dev);
    assert_eq!(t.clone().matmul(t).sum().into_scalar::<f32>(), 54.0);
}

/// What one training step produces on one device, from the model in `bytes`.
struct Step {
    /// The training-mode forward output (BatchNorm on batch statistics).
    output: Vec<f32>,
    loss: f64,
    gradients: Vec<(String, Vec<f32>)>,
    /// Every float tensor after the Adam step (BatchNorm statistics included).
    updated: Vec<(String, Vec<f32>)>,
    /// Every float tensor as loaded, before the step.
    before: Vec<(String, Vec<f32>)>,
    seconds: f64,
}

fn step_on<T: Task>(
    task: &T,
    bytes: &[u8],
    batch: &[Sample],
    forward: impl Fn(&T::Model, &Device) -> Tensor<4>,
    device: &Device,
) -> Step {
    let dev = device.clone().autodiff();
    let fresh = || {
        checkpoint::model_from_bytes(
            task.init(&dev).expect("init"),
            bytes.to_vec(),
            Path::new("model.bpk"),
        )
        .expect("load")
    };
    // Two copies from the same bytes: one for the forward output, one for the step, so the
    // step's BatchNorm statistics are updated once, as in training.
    let output = common::to_vec(forward(&fresh(), &dev));
    let model = fresh();
    let before = tensors(&model);
    let began = Instant::now();
    let loss = task.loss(&model, batch, &dev).expect("loss");
    let value = loss.clone().into_scalar::<f32>() as f64;
    let grads = GradientsParams::from_grads(loss.backward(), &model);
    let gradients = gradients(&model, &grads);
    let mut optim: ModuleOptimizer = AdamConfig::new().with_epsilon(ADAM_EPSILON as f32).init();
    // `valid()` folds in BatchNorm's newest running statistics (held per thread until then).
    let updated = tensors(&optim.step(LR, model, grads).valid());
    Step {
        output,
        loss: value,
        gradients,
        updated,
        before,
        seconds: began.elapsed().as_secs_f64(),
    }
}

/// One step on flex and on wgpu from the same weights and batch; asserts and prints each
/// agreement figure.
fn compare_step<T: Task>(
    name: &str,
    task: &T,
    batch: &[Sample],
    forward: impl Fn(&T::Model, &Device) -> Tensor<4>,
) {
    let init = flex();
    let model = seeded_init(&init, 5, || task.init(&init)).expect("init");
    let bytes = checkpoint::model_to_bytes(&model, Path::new("model.bpk")).expect("bytes");
    let f = step_on(task, &bytes, batch, &forward, &flex());
    let g = step_on(task, &bytes, batch, &forward, &wgpu());
    assert_eq!(
        f.before, g.before,
        "{name}: the two start from other weights"
    );

    let out = rel(&g.output, &f.output);
    let loss = (g.loss - f.loss).abs() / f.loss.abs();
    eprintln!(
        "{name}: forward output rel {out:.2e}; loss {:.6} (flex) {:.6} (wgpu) rel {loss:.2e}; \
         step {:.3} s (flex) {:.3} s (wgpu)",
        f.loss, g.loss, f.seconds, g.seconds
    );
    assert!(out <= OUTPUT_TOL, "{name}: forward output rel {out:.2e}");
    assert!(loss <= OUTPUT_TOL, "{name}: loss rel {loss:.2e}");

    assert_eq!(f.gradients.len(), g.gradients.len());
    // A tensor's difference is taken relative to the larger of its own largest magnitude and
    // GRAD_FLOOR of the model's largest gradient: the bias of a convolution followed by
    // BatchNorm has an exact gradient of 0 (BatchNorm removes any constant per channel), so
    // both backends give f32 rounding noise there, and noise relative to noise means nothing.
    let model_scale = f
        .gradients
        .iter()
        .flat_map(|(_, g)| g.iter())
        .fold(0.0f64, |m, v| m.max(v.abs() as f64));
    let mut worst_grad = 0.0f64;
    for ((path, fg), (gp, gg)) in f.gradients.iter().zip(&g.gradients) {
        assert_eq!(path, gp);
        let own = fg.iter().fold(0.0f64, |m, v| m.max(v.abs() as f64));
        let r = max_abs(gg, fg) / own.max(GRAD_FLOOR * model_scale);
        let note = if own < GRAD_FLOOR * model_scale {
            " (below GRAD_FLOOR of the model's largest gradient: relative to that)"
        } else {
            ""
        };
        eprintln!("  {name}: gradient {path} rel {r:.2e}, max|g| {own:.2e}{note}");
        worst_grad = worst_grad.max(r);
    }
    assert!(
        worst_grad <= GRAD_TOL,
        "{name}: a gradient differs by {worst_grad:.2e} relative"
    );

    // Weights after the step: Adam's first update is lr·u(g), u(g) = g/(|g| + ε), increasing
    // in g. With δ the tensor's largest gradient difference, an element whose flex gradient is
    // g may move by at most lr·max(u(g + δ) − u(g), u(g) − u(g − δ)) (up to 2·lr where δ
    // reaches across 0), plus f32 rounding of u and of the weight.
    fn find<'a>(s: &'a Step, path: &str) -> Option<&'a Vec<f32>> {
        s.gradients.iter().find(|(p, _)| p == path).map(|(_, g)| g)
    }
    let gradient_of = |path: &str| find(&f, path).zip(find(&g, path));
    let u = |g: f64| g / (g.abs() + ADAM_EPSILON);
    let (mut worst_ratio, mut sensitive, mut worst_stat) = (0.0f64, 0usize, 0.0f64);
    for ((path, fw), (_, gw)) in f.updated.iter().zip(&g.updated) {
        let Some((gf, gg)) = gradient_of(path) else {
            // No gradient: a BatchNorm running statistic, set from the batch statistics.
            let r = rel(gw, fw);
            eprintln!("  {name}: updated {path} rel {r:.2e}");
            worst_stat = worst_stat.max(r);
            continue;
        };
        let delta = max_abs(gg, gf);
        let scale = fw.iter().fold(0.0f64, |m, v| m.max(v.abs() as f64));
        let mut ratio = 0.0f64;
        for ((a, b), grad) in gw.iter().zip(fw).zip(gf) {
            let g0 = *grad as f64;
            let slope = (u(g0 + delta) - u(g0)).max(u(g0) - u(g0 - delta));
            if slope > 1e-2 {
                sensitive += 1;
            }
            let bound = LR * (slope + ADAM_ROUNDING) + 2.0 * scale * f64::from(f32::EPSILON);
            ratio = ratio.max((*a as f64 - *b as f64).abs() / bound);
        }
        eprintln!(
            "  {name}: updated {path} rel {:.2e}, within {:.2} of its bound",
            rel(gw, fw),
            ratio
        );
        worst_ratio = worst_ratio.max(ratio);
    }
    eprintln!(
        "{name}: worst gradient rel {worst_grad:.2e}; updated weights within {worst_ratio:.2} \
         of Adam's bound ({sensitive} elements may move by over 0.01·lr); \
         BatchNorm statistics rel {worst_stat:.2e}"
    );
    assert!(
        worst_ratio <= 1.0,
        "{name}: an updated weight is {worst_ratio:.2}× its bound"
    );
    assert!(
        worst_stat <= OUTPUT_TOL,
        "{name}: BatchNorm statistics rel {worst_stat:.2e}"
    );
}

fn network1_task(config: BlendUNetConfig) -> Network1 {
    Network1 {
        config,
        alpha: ClassWeights::new(
            &std::array::from_fn(|i| 1 + (i as u64 * 7) % 13),
            MertensWeights::OPENCV_DEFAULT,
            1,
        ),
        reading: Network1Reading::default(),
        label_sigma: DEFAULT_LABEL_SIGMA,
    }
}

#[test]
fn network1_step_agrees_with_flex() {
    let task = network1_task(BlendUNetConfig {
        base_width: 16,
        depth: 2,
        ..BlendUNetConfig::default()
    });
    let batch = common::samples(2, 6, 64, false);
    compare_step("Network-1", &task, &batch, |m, d| {
        m.forward(network1_batch(&batch, d).expect("batch").0)
    });
}

fn network2_forward(batch: &[Sample]) -> impl Fn(&hdrsynth::models::WuNet, &Device) -> Tensor<4> {
    move |m, d| m.forward(network2_batch(batch, d).expect("batch").0)
}

#[test]
fn network2_resnet_step_agrees_with_flex() {
    let task = Network2::new(
        WuConfig {
            res_blocks: 2,
            ..WuConfig::resnet(8)
        },
        &Default::default(),
    );
    let batch = common::samples(2, 18, 64, true);
    compare_step("Network-2 ResNet", &task, &batch, network2_forward(&batch));
}

#[test]
fn network2_unet_step_agrees_with_flex() {
    let task = Network2::new(WuConfig::unet(4), &Default::default());
    let batch = common::samples(2, 18, 64, true);
    compare_step("Network-2 U-Net", &task, &batch, network2_forward(&batch));
}

// ─── Training runs, checkpoints and inference ──────────────────────────────────────────────

/// A small generated dataset with Network-1's pair (EV −3/0), frames 96×80.
fn dataset1() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().expect("tmp");
        common::generate(dir.path(), 31, 4, (96, 80), "[-3.0, 0.0]");
        dir
    })
    .path()
}

/// A small generated dataset with Network-2's bracket (EV −2/0/+2), frames 64×48.
fn dataset3() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().expect("tmp");
        common::generate(dir.path(), 32, 2, (64, 48), "[-2.0, 0.0, 2.0]");
        dir
    })
    .path()
}

fn scratch() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| tempfile::tempdir().expect("tmp")).path()
}

/// A Network-1 run config (base width 4, depth 2, patch 32, batch 2) on `backend`.
fn network1_config(out: &Path, backend: &str, steps: u64, init: Option<&Path>) -> String {
    let init = init
        .map(|p| format!("[init]\ncheckpoint = {p:?}\n"))
        .unwrap_or_default();
    format!(
        "[run]\nout = {out:?}\nseed = 9\nsteps = {steps}\nbackend = \"{backend}\"\n\
         checkpoint_every = 8\nlog_every = 4\nkeep_checkpoints = 1\n\
         [model]\nkind = \"blend_unet\"\nbase_width = 4\ndepth = 2\n\
         [data]\ndataset = {:?}\npatch = 32\nbatch_size = 2\nworkers = 2\nprofile = \"pure\"\n\
         [optim]\nlr = 3e-3\n{init}",
        dataset1()
    )
}

fn network2_config(out: &Path, backend: &str, steps: u64) -> String {
    format!(
        "[run]\nout = {out:?}\nseed = 4\nsteps = {steps}\nbackend = \"{backend}\"\n\
         checkpoint_every = {steps}\nlog_every = 1\n\
         [model]\nkind = \"wu\"\nbase_width = 4\nres_blocks = 1\n\
         [data]\ndataset = {:?}\npatch = 32\nbatch_size = 2\nworkers = 1\nprofile = \"pure\"\n\
         [optim]\nlr = 1e-3\n",
        dataset3()
    )
}

fn parse(text: &str) -> TrainConfig {
    let cfg: TrainConfig = parse_toml(text, Path::new("train.toml")).expect("config");
    cfg.validate().expect("valid");
    cfg
}

fn train(text: &str) -> PathBuf {
    let cfg = parse(text);
    let s = hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("train");
    s.checkpoint
}

/// Network-1 pretrained on flex (8 steps): the start of the wgpu fine-tuning.
fn pretrained_on_flex() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let run = scratch().join("net1-flex");
        train(&network1_config(&run, "flex", 8, None))
    })
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
}

/// The fine-tuning on wgpu: 24 steps from [`pretrained_on_flex`], through the binary.
const FINE_TUNE_STEPS: u64 = 24;

fn fine_tune_config(name: &str) -> (PathBuf, PathBuf) {
    let run = scratch().join(name);
    let cfg = scratch().join(format!("{name}.toml"));
    let text = network1_config(&run, "wgpu", FINE_TUNE_STEPS, Some(pretrained_on_flex()));
    std::fs::write(&cfg, text).expect("write");
    (run, cfg)
}

/// The uninterrupted wgpu fine-tuning run (its folder) and its wall time.
fn fine_tuned_on_wgpu() -> &'static (PathBuf, f64) {
    static RUN: OnceLock<(PathBuf, f64)> = OnceLock::new();
    RUN.get_or_init(|| {
        let (run, cfg) = fine_tune_config("net1-wgpu");
        let began = Instant::now();
        let out = bin()
            .args(["train", "--quiet", "--config"])
            .arg(&cfg)
            .output()
            .expect("train");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        (run, began.elapsed().as_secs_f64())
    })
}

/// (step, loss) of every interval line of a run's log.
fn logged_losses(run: &Path) -> Vec<(u64, f64)> {
    std::fs::read_to_string(run.join("log.jsonl"))
        .expect("log")
        .lines()
        .filter(|l| !l.contains("validation"))
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).expect("json");
            (
                v["step"].as_u64().expect("step"),
                v["loss"].as_f64().expect("loss"),
            )
        })
        .collect()
}

fn final_weights(run: &Path) -> Vec<(String, Vec<f32>)> {
    let dir = checkpoint::resolve(run).expect("checkpoint");
    let ModelConfig::BlendUnet(cfg) = checkpoint::read_state(&dir).expect("state").model else {
        panic!("a Network-1 checkpoint expected");
    };
    let dev = flex();
    tensors(&checkpoint::load_model(cfg.init(&dev).expect("init"), &dir).expect("load"))
}

#[test]
fn fine_tuning_on_wgpu_learns_and_a_killed_run_resumes_bit_identically() {
    let (run_a, secs) = fine_tuned_on_wgpu();
    let losses = logged_losses(run_a);
    eprintln!("wgpu fine-tuning, {FINE_TUNE_STEPS} steps in {secs:.1} s: {losses:?}");
    assert_eq!(losses.len() as u64, FINE_TUNE_STEPS / 4);
    let (first, last) = (losses[0].1, losses[losses.len() - 1].1);
    assert!(
        last < first,
        "the loss did not fall on wgpu: {first} → {last}"
    );

    // The same run killed (SIGKILL) once its first checkpoint is complete, then resumed.
    let (run_b, cfg_b) = fine_tune_config("net1-wgpu-killed");
    let mut child = bin()
        .args(["train", "--quiet", "--config"])
        .arg(&cfg_b)
        .spawn()
        .expect("spawn");
    let began = Instant::now();
    while checkpoint::latest(&run_b).expect("latest").is_none() {
        assert!(
            began.elapsed() < Duration::from_secs(600),
            "no checkpoint appeared"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().expect("SIGKILL");
    child.wait().expect("wait");
    let at_kill = checkpoint::read_state(&checkpoint::latest(&run_b).unwrap().unwrap())
        .expect("state")
        .step;
    assert!(at_kill < FINE_TUNE_STEPS, "finished before the kill");
    let st = bin()
        .args(["train", "--quiet", "--resume", "--config"])
        .arg(&cfg_b)
        .status()
        .expect("resume");
    assert!(st.success());
    let (a, b) = (final_weights(run_a), final_weights(&run_b));
    assert_eq!(a.len(), b.len());
    for ((path, x), (_, y)) in a.iter().zip(&b) {
        assert!(
            x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()),
            "{path} differs after a kill at step {at_kill} and resume"
        );
    }
    assert_eq!(losses, logged_losses(&run_b), "the logged losses differ");
}

/// Tiles of 32 px: every frame here is larger, so each output is stitched from several
/// windows.
fn tiled(engine: Engine) -> NetworkOptions {
    NetworkOptions {
        tile: Some(32),
        engine,
        ..NetworkOptions::default()
    }
}

/// The engines and devices a checkpoint is run on: Burn on flex (the reference), Burn on wgpu,
/// and ONNX Runtime where this build has it.
fn runners(dir: &Path) -> Vec<(&'static str, LoadedNetwork)> {
    let mut v = vec![
        (
            "flex",
            LoadedNetwork::from_checkpoint(dir, &tiled(Engine::Burn), &flex()).expect("flex"),
        ),
        (
            "wgpu",
            LoadedNetwork::from_checkpoint(dir, &tiled(Engine::Burn), &wgpu()).expect("wgpu"),
        ),
    ];
    if cfg!(feature = "onnx") {
        v.push((
            "ONNX Runtime",
            LoadedNetwork::from_checkpoint(dir, &tiled(Engine::Onnx), &flex())
                .unwrap_or_else(|e| panic!("ONNX Runtime (ORT_DYLIB_PATH): {e}")),
        ));
    }
    v
}

/// Network-1's blend weights of every set of `dataset1` by each runner, compared with flex's.
fn network1_agreement(what: &str, dir: &Path) {
    let sets = layout::detect(dataset1()).expect("detect").sets;
    let runners = runners(dir);
    for set in &sets {
        let (low, high) = network1_frames(set).expect("frames");
        assert!(low.width > 32 && low.height > 32);
        let outs: Vec<Vec<f32>> = runners
            .iter()
            .map(|(_, n)| {
                n.network1_weight(&low, &high, Default::default())
                    .expect("weights")
            })
            .collect();
        for ((name, _), out) in runners.iter().zip(&outs).skip(1) {
            let r = rel(out, &outs[0]);
            eprintln!(
                "{what}, set {}: {name} vs flex, blend weight rel {r:.2e}",
                set.name
            );
            assert!(
                r <= OUTPUT_TOL,
                "{what}: {name} differs from flex by {r:.2e}"
            );
        }
    }
}

fn network2_agreement(what: &str, dir: &Path) {
    let sets = layout::detect(dataset3()).expect("detect").sets;
    let runners = runners(dir);
    for set in &sets {
        let (frames, times) = network2_frames(set).expect("frames");
        let refs: [&Image; 3] = std::array::from_fn(|i| &frames[i]);
        let outs: Vec<Image> = runners
            .iter()
            .map(|(_, n)| n.network2_hdr(refs, times).expect("hdr"))
            .collect();
        for ((name, _), out) in runners.iter().zip(&outs).skip(1) {
            let r = rel(&out.data, &outs[0].data);
            eprintln!("{what}, set {}: {name} vs flex, HDR rel {r:.2e}", set.name);
            assert!(
                r <= OUTPUT_TOL,
                "{what}: {name} differs from flex by {r:.2e}"
            );
        }
    }
}

/// The model.bpk of a checkpoint loaded on `device` and written again: the same bytes, so the
/// file does not depend on the backend that wrote it.
fn rewritten_on(dir: &Path, device: &Device) -> Vec<u8> {
    let state = checkpoint::read_state(dir).expect("state");
    let path = dir.join(checkpoint::MODEL_FILE);
    match state.model {
        ModelConfig::BlendUnet(c) => {
            let m = checkpoint::load_model(c.init(device).expect("init"), dir).expect("load");
            checkpoint::model_to_bytes(&m, &path).expect("bytes")
        }
        ModelConfig::Wu(c) => {
            let m = checkpoint::load_model(c.init(device).expect("init"), dir).expect("load");
            checkpoint::model_to_bytes(&m, &path).expect("bytes")
        }
    }
}

fn check_checkpoint_moves(dir: &Path) {
    let written = std::fs::read(dir.join(checkpoint::MODEL_FILE)).expect("model.bpk");
    for device in [flex(), wgpu()] {
        assert!(
            rewritten_on(dir, &device) == written,
            "{}: loaded and written again on {device:?}, the bytes differ",
            dir.display()
        );
    }
}

#[test]
fn network1_checkpoints_move_between_wgpu_flex_and_onnx_with_the_same_tiled_outputs() {
    // Written on wgpu (the fine-tuning run), run tiled on flex, wgpu and ONNX Runtime.
    let (run, _) = fine_tuned_on_wgpu();
    let from_wgpu = checkpoint::resolve(run).expect("checkpoint");
    check_checkpoint_moves(&from_wgpu);
    network1_agreement("Network-1 written on wgpu", &from_wgpu);
    // And the reverse: written on flex.
    let from_flex = pretrained_on_flex();
    check_checkpoint_moves(from_flex);
    network1_agreement("Network-1 written on flex", from_flex);
}

#[test]
fn network2_checkpoints_move_between_wgpu_flex_and_onnx_with_the_same_tiled_outputs() {
    for backend in ["wgpu", "flex"] {
        let run = scratch().join(format!("net2-{backend}"));
        let dir = train(&network2_config(&run, backend, 2));
        check_checkpoint_moves(&dir);
        network2_agreement(&format!("Network-2 written on {backend}"), &dir);
    }
}

/// `infer` and `eval --engine burn` through the binary on wgpu write what they write on flex.
#[test]
fn infer_and_eval_on_wgpu_write_flexs_outputs() {
    let (run, _) = fine_tuned_on_wgpu();
    let set = &layout::detect(dataset1()).expect("detect").sets[0];
    let out = |what: &str, backend: &str| scratch().join(format!("{what}-{backend}"));
    for backend in ["flex", "wgpu"] {
        let st = bin()
            .args([
                "infer",
                "--engine",
                "burn",
                "--tile",
                "32",
                "--backend",
                backend,
            ])
            .arg("--checkpoint")
            .arg(run)
            .arg("--set")
            .arg(&set.dir)
            .arg("--out")
            .arg(out("infer", backend))
            .status()
            .expect("infer");
        assert!(st.success(), "infer on {backend}");
        let st = bin()
            .args(["eval", "--quiet", "--engine", "burn", "--tile", "32"])
            .args(["--backend", backend, "--checkpoint"])
            .arg(run)
            .arg("--testset")
            .arg(dataset1())
            .arg("--out")
            .arg(out("eval", backend))
            .status()
            .expect("eval");
        assert!(st.success(), "eval on {backend}");
    }
    let read = |p: PathBuf| read_image(&p).unwrap_or_else(|e| panic!("{e}"));
    let r = rel(
        &read(out("infer", "wgpu").join("linear.exr")).data,
        &read(out("infer", "flex").join("linear.exr")).data,
    );
    eprintln!("infer linear.exr: wgpu vs flex rel {r:.2e}");
    assert!(r <= OUTPUT_TOL, "infer: {r:.2e}");
    for s in layout::detect(dataset1()).expect("detect").sets {
        let name = format!("{}.exr", s.name);
        let r = rel(
            &read(out("eval", "wgpu").join(&name)).data,
            &read(out("eval", "flex").join(&name)).data,
        );
        eprintln!("eval {name}: wgpu vs flex rel {r:.2e}");
        assert!(r <= OUTPUT_TOL, "eval {name}: {r:.2e}");
    }
}

/// A wgpu run that cannot get its adapter stops with an error naming the cause before it
/// writes anything: here the adapter asked for (`CUBECL_WGPU_DEFAULT_DEVICE`) does not exist.
#[test]
fn a_missing_adapter_is_refused_before_training_starts() {
    let run = scratch().join("no-adapter");
    let cfg = scratch().join("no-adapter.toml");
    std::fs::write(&cfg, network1_config(&run, "wgpu", 2, None)).expect("write");
    let out = bin()
        .env("CUBECL_WGPU_DEFAULT_DEVICE", "DiscreteGpu(99)")
        .args(["train", "--quiet", "--config"])
        .arg(&cfg)
        .output()
        .expect("train");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("device 'wgpu': no usable adapter") && !err.contains("panicked"),
        "{err}"
    );
    assert!(!run.exists(), "the refused run left {}", run.display());
}

// ─── The `gpu` preset ─────────────────────────────────────────────────────────────────────

/// The `gpu` preset's pretraining config as the main job writes it (Wu's released width 64,
/// 9 residual blocks, its merge head, optimiser and schedule) starts on wgpu: two steps on
/// 32² crops of one sample, a finite loss each, a checkpoint of that network.
#[test]
fn the_gpu_presets_pretraining_config_starts_on_wgpu() {
    use hdrsynth::experiments::quickstart::{Preset, pretrain_config};
    let run = scratch().join("gpu-preset");
    let mut cfg = pretrain_config(Preset::Gpu, "wgpu", dataset3(), Path::new("pure"), &run, 1);
    let ModelConfig::Wu(wu) = &cfg.model else {
        panic!("the gpu preset trains Network-2");
    };
    assert_eq!((wu.base_width, wu.res_blocks), (64, 9));
    (cfg.data.patch, cfg.data.batch_size, cfg.data.workers) = (32, 1, 1);
    (cfg.run.steps, cfg.run.checkpoint_every, cfg.run.log_every) = (2, 2, 1);
    cfg.schedule.warmup_steps = 1;
    cfg.validate().expect("valid");
    hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("train");
    let losses = logged_losses(&run);
    assert_eq!(losses.iter().map(|l| l.0).collect::<Vec<_>>(), [1, 2]);
    assert!(
        losses.iter().all(|l| l.1.is_finite() && l.1 > 0.0),
        "{losses:?}"
    );
    let dir = checkpoint::resolve(&run).expect("checkpoint");
    let ModelConfig::Wu(saved) = checkpoint::read_state(&dir).expect("state").model else {
        panic!("a Network-2 checkpoint expected");
    };
    assert_eq!((saved.base_width, saved.res_blocks), (64, 9));
}
