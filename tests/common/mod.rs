//! Helpers shared by the integration tests (each test binary includes this module; not every
//! binary uses every helper).
#![allow(dead_code)]

use burn::tensor::{Device, Tensor, TensorData};
use hdrsynth::config::parse_toml;
use hdrsynth::data::generate::GenerateConfig;
use std::path::{Path, PathBuf};

/// `../shared/data/REL` beside the repository. Tests that call it are
/// `#[ignore = "needs ../shared/data"]` (run with `--ignored` where the folder exists); a missing
/// file fails the test, naming it, rather than letting it pass without checking anything.
pub fn shared_data(rel: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(rel);
    assert!(
        p.exists(),
        "{} is missing: this test needs ../shared/data",
        p.display()
    );
    p
}

/// `tests/data/oracle_crops/REL`: oracle outputs on small crops of real HDR scenes, committed
/// (tools/oracle_crops.py writes them; PROVENANCE.md beside them), so the oracle tests run in
/// any clone.
pub fn oracle_crops(rel: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/oracle_crops")
        .join(rel);
    assert!(p.exists(), "{} is missing", p.display());
    p
}

/// Generate a small pure synthetic dataset into `dir` with the scene engine.
pub fn generate(dir: &Path, seed: u64, count: usize, (width, height): (usize, usize), evs: &str) {
    let text = format!(
        "seed = {seed}\ncount = {count}\nwidth = {width}\nheight = {height}\nevs = {evs}\n\
         [camera]\ncandidates = 4\n"
    );
    let mut c: GenerateConfig = parse_toml(&text, Path::new("gen.toml")).expect("config");
    c.source = None;
    hdrsynth::data::generate::generate(&c, dir, false).expect("generate");
}

/// The validation score `key` the trainer logged at `step` in `RUN/log.jsonl` (step 0 is logged
/// before training).
pub fn validation_at(run: &Path, step: u64, key: &str) -> f64 {
    let log = std::fs::read_to_string(run.join("log.jsonl")).expect("log");
    let line = log
        .lines()
        .find(|l| l.starts_with(&format!("{{\"step\":{step},\"validation\"")))
        .unwrap_or_else(|| panic!("no validation at step {step}:\n{log}"));
    let rest = &line[line.find(&format!("\"{key}\":")).expect(key) + key.len() + 3..];
    rest.split([',', '}'])
        .next()
        .unwrap()
        .parse()
        .expect("number")
}

/// Deterministic pseudo-random values in [0, 1) (splitmix64), independent of the crate's RNG.
pub fn values(n: usize, seed: u64) -> Vec<f32> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
        })
        .collect()
}

/// `n` synthetic training samples of `channels` × `size`² inputs (values from `values`), with
/// an HDR target (Network-2) or 256-class blend targets (Network-1).
pub fn samples(
    n: usize,
    channels: usize,
    size: usize,
    hdr: bool,
) -> Vec<hdrsynth::data::loader::Sample> {
    use hdrsynth::data::loader::{Sample, Target};
    (0..n as u64)
        .map(|i| Sample {
            input: values(channels * size * size, 10 + i),
            channels,
            size,
            target: if hdr {
                Target::Hdr(values(3 * size * size, 20 + i))
            } else {
                Target::Classes(
                    values(size * size, 20 + i)
                        .iter()
                        .map(|v| (v * 256.0) as u8)
                        .collect(),
                )
            },
            exposure_times: vec![],
            set: format!("s{i}"),
            iso: None,
        })
        .collect()
}

/// The first set folder (one with `static/`) of a generated dataset.
pub fn first_set(dataset: &Path) -> std::path::PathBuf {
    std::fs::read_dir(dataset)
        .expect("dataset")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.join("static").is_dir())
        .expect("a set")
}

/// Largest absolute difference of two equally long slices.
pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len(), "max_abs_diff: lengths differ");
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// CRC-32 (ISO-HDLC, as PNG uses), bitwise: the reference definition, independent of any crate.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// Flex with autodiff: where the flex kernels' tests compare against Burn's own ops.
pub fn flex_autodiff() -> Device {
    hdrsynth::device::device_from_name("flex")
        .expect("flex")
        .autodiff()
}

/// A tensor of `shape` on [`flex_autodiff`] with values in [−0.5, 0.5) from [`values`].
pub fn centred_tensor(shape: [usize; 4], seed: u64) -> Tensor<4> {
    let v = values(shape.iter().product(), seed)
        .into_iter()
        .map(|v| v - 0.5)
        .collect::<Vec<_>>();
    Tensor::from_data(TensorData::new(v, shape), &flex_autodiff())
}

/// A float tensor's values.
pub fn to_vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().try_to_vec::<f32>().expect("f32")
}

/// (f(x), dL/dx) of L = Σ f(x) ⊙ r, r a fixed [`centred_tensor`] of f(x)'s shape from `r_seed`:
/// an op's output and gradient, to compare with another implementation's.
pub fn value_and_grad(
    x: &Tensor<4>,
    r_seed: u64,
    f: impl Fn(Tensor<4>) -> Tensor<4>,
) -> (Vec<f32>, Vec<f32>) {
    let x = x.clone().require_grad();
    let y = f(x.clone());
    let r = centred_tensor(y.dims(), r_seed);
    let g = (y.clone() * r).sum().backward();
    (to_vec(y), to_vec(x.grad(&g).expect("dx")))
}

/// Gaussian draws from a fixed LCG (Box–Muller): the test's own noise, independent of the
/// library's generator.
pub struct TestNoise(pub u64);

impl TestNoise {
    pub fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    pub fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// IEC 61966-2-1 encoding by hand.
pub fn srgb(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}
