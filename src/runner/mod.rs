//! Which engine runs a trained network on whole images. A checkpoint runs in Burn on the
//! run's device, or — `Engine::Auto` for Network-1 on a CPU device, in a build with the `onnx`
//! feature and ONNX Runtime's library present — in ONNX Runtime on the same network exported
//! in memory: it agrees with flex within 1e-4 (tests/onnx.rs); BENCHMARKS.md has the two
//! engines' times (ONNX Runtime a few per cent faster for Network-1, flex 12–19 % faster for
//! Network-2). An exported file (`infer --onnx`) always runs in ONNX
//! Runtime. The tiling is the same for every engine, so only kernel rounding differs.

use crate::device::is_cpu;
use crate::error::{Error, Result};
use crate::eval::blend::BlendWeight;
use crate::eval::infer::Engine;
use crate::eval::infer::{
    NetworkOptions, network1_tiling, network1_weight, network2_hdr_with, network2_tiling,
};
use crate::eval::tiling::Tiling;
use crate::io::Image;
use crate::models::wu::Linearise;
use crate::models::{BlendUNet, ModelConfig, WuNet};
use crate::sensor::profile::Response;
use crate::train::checkpoint;
use burn::module::Module;
use burn::tensor::Device;
use std::path::{Path, PathBuf};

pub mod method;

/// Which of the two networks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Network {
    Network1,
    Network2,
}

enum Runner {
    Network1(BlendUNet, Device),
    Network2(WuNet, Device),
    #[cfg(feature = "onnx")]
    Onnx(std::cell::RefCell<crate::onnx::runtime::OnnxModel>),
}

/// A trained network ready to run on whole images.
pub struct LoadedNetwork {
    pub network: Network,
    /// The checkpoint folder or ONNX file it came from.
    pub source: PathBuf,
    pub tiling: Tiling,
    /// Network-2: the model's `hdr_input_scale` (its outputs are already divided by it).
    pub hdr_input_scale: Option<f32>,
    runner: Runner,
}

impl LoadedNetwork {
    /// The network of a checkpoint (or a run folder's latest), on `engine` (module docs).
    pub fn from_checkpoint(path: &Path, opts: &NetworkOptions, device: &Device) -> Result<Self> {
        let dir = checkpoint::resolve(path)?;
        let state = checkpoint::read_state(&dir)?;
        let (network, tiling, hdr_input_scale, runner) = match &state.model {
            ModelConfig::BlendUnet(cfg) => {
                let model = checkpoint::load_model(cfg.init(device)?, &dir)?.valid();
                let runner = if use_onnx(opts.engine, device, Network::Network1)? {
                    in_onnx(&model, &dir)?
                } else {
                    Runner::Network1(model, device.clone())
                };
                (Network::Network1, network1_tiling(cfg), None, runner)
            }
            ModelConfig::Wu(cfg) => {
                let model = checkpoint::load_model(cfg.init(device)?, &dir)?.valid();
                let runner = if use_onnx(opts.engine, device, Network::Network2)? {
                    in_onnx(&model, &dir)?
                } else {
                    Runner::Network2(model, device.clone())
                };
                let scale = Some(cfg.hdr_input_scale as f32);
                (Network::Network2, network2_tiling(cfg), scale, runner)
            }
        };
        Ok(LoadedNetwork {
            network,
            source: dir,
            tiling: opts.tiling(tiling),
            hdr_input_scale,
            runner,
        })
    }

    /// A model exported by `hdrsynth export onnx`, in ONNX Runtime.
    #[cfg(feature = "onnx")]
    pub fn from_onnx_file(path: &Path, opts: &NetworkOptions) -> Result<Self> {
        use crate::onnx::runtime::{Network as OnnxNetwork, OnnxModel};
        let model = OnnxModel::load(path, None)?;
        let tiling = opts.tiling(crate::onnx::infer::default_tiling(&model)?);
        let network = match model.network {
            OnnxNetwork::Network1 => Network::Network1,
            OnnxNetwork::Network2 => Network::Network2,
        };
        Ok(LoadedNetwork {
            network,
            source: path.to_path_buf(),
            tiling,
            hdr_input_scale: model.hdr_input_scale,
            runner: Runner::Onnx(std::cell::RefCell::new(model)),
        })
    }

    #[cfg(not(feature = "onnx"))]
    pub fn from_onnx_file(path: &Path, _: &NetworkOptions) -> Result<Self> {
        Err(Error::flag(
            "--onnx",
            format!(
                "{}: this hdrsynth was built without ONNX support: rebuild with \
                 `cargo build --release --features onnx` (docs/onnx.md)",
                path.display()
            ),
        ))
    }

    /// Which engine runs it.
    pub fn engine(&self) -> &'static str {
        match self.runner {
            Runner::Network1(..) | Runner::Network2(..) => "Burn",
            #[cfg(feature = "onnx")]
            Runner::Onnx(_) => "ONNX Runtime",
        }
    }

    /// "Network-1 (blend-map U-Net) from SOURCE, tile T overlap O, ENGINE".
    pub fn describe(&self) -> String {
        let what = match self.network {
            Network::Network1 => "Network-1 (blend-map U-Net)",
            Network::Network2 => "Network-2 (Wu et al.)",
        };
        format!(
            "{what} from {}, tile {} overlap {}, {}",
            self.source.display(),
            self.tiling.tile,
            self.tiling.overlap,
            self.engine()
        )
    }

    fn wrong(&self, want: Network) -> Error {
        Error::config(
            &self.source,
            format!("holds {:?}, not {want:?}", self.network),
        )
    }

    /// Network-1's long-exposure weight per pixel of a (low, high) pair.
    pub fn network1_weight(
        &self,
        low: &Image,
        high: &Image,
        mode: BlendWeight,
    ) -> Result<Vec<f32>> {
        match &self.runner {
            Runner::Network1(model, device) => {
                network1_weight(model, low, high, self.tiling, mode, device)
            }
            #[cfg(feature = "onnx")]
            Runner::Onnx(m) if self.network == Network::Network1 => {
                crate::onnx::infer::network1_weight(
                    &mut m.borrow_mut(),
                    low,
                    high,
                    self.tiling,
                    mode,
                )
            }
            _ => Err(self.wrong(Network::Network1)),
        }
    }

    /// Network-2's linear HDR (1 = the reference exposure's white) of three frames.
    pub fn network2_hdr(&self, frames: [&Image; 3], times: [f32; 3]) -> Result<Image> {
        self.network2_hdr_on(frames, times, None)
    }

    /// [`network2_hdr`](Self::network2_hdr) of frames whose curve is known (`frame_curve`, a
    /// test set's record): a network with `linearise = "data"` was trained to merge its inputs
    /// through the curve they were encoded with, so it takes that curve; any other network
    /// keeps its own.
    pub fn network2_hdr_on(
        &self,
        frames: [&Image; 3],
        times: [f32; 3],
        frame_curve: Option<&Response>,
    ) -> Result<Image> {
        match &self.runner {
            Runner::Network2(model, device) => {
                let curve = match frame_curve {
                    Some(c) if model.config().linearise == Linearise::Data => c,
                    _ => &model.config().input_response,
                };
                network2_hdr_with(model, frames, times, curve, self.tiling, device)
            }
            #[cfg(feature = "onnx")]
            Runner::Onnx(m) if self.network == Network::Network2 => {
                crate::onnx::infer::network2_hdr(&mut m.borrow_mut(), frames, times, self.tiling)
            }
            _ => Err(self.wrong(Network::Network2)),
        }
    }
}

/// Whether `engine` on `device` means ONNX Runtime for `network`. `Auto` takes the faster
/// engine on the CPU as BENCHMARKS.md measured it: ONNX Runtime for Network-1 (flex
/// 1.01–1.03× its time), flex for Network-2 (0.81–0.88×).
fn use_onnx(engine: Engine, device: &Device, network: Network) -> Result<bool> {
    match engine {
        Engine::Burn => Ok(false),
        Engine::Onnx => onnx_available().map(|_| true),
        Engine::Auto => {
            Ok(network == Network::Network1 && is_cpu(device) && onnx_available().is_ok())
        }
    }
}

#[cfg(feature = "onnx")]
fn onnx_available() -> Result<()> {
    crate::onnx::runtime::environment().map(|_| ())
}

#[cfg(not(feature = "onnx"))]
fn onnx_available() -> Result<()> {
    Err(not_built())
}

#[cfg(not(feature = "onnx"))]
fn not_built() -> Error {
    Error::flag(
        "--engine",
        "onnx: this hdrsynth was built without ONNX support: rebuild with \
         `cargo build --release --features onnx` (docs/onnx.md)",
    )
}

/// A network exported in memory and loaded in ONNX Runtime.
#[cfg(feature = "onnx")]
fn in_onnx<M: Exportable>(model: &M, dir: &Path) -> Result<Runner> {
    use crate::onnx::export::{ExportOptions, to_bytes};
    let bytes = to_bytes(&model.export(&ExportOptions::default())?);
    let m = crate::onnx::runtime::OnnxModel::from_bytes(&bytes, dir, None)?;
    Ok(Runner::Onnx(std::cell::RefCell::new(m)))
}

#[cfg(not(feature = "onnx"))]
fn in_onnx<M>(_: &M, _: &Path) -> Result<Runner> {
    Err(not_built())
}

#[cfg(feature = "onnx")]
trait Exportable {
    fn export(
        &self,
        opts: &crate::onnx::export::ExportOptions,
    ) -> Result<crate::onnx::proto::ModelProto>;
}

#[cfg(feature = "onnx")]
impl Exportable for BlendUNet {
    fn export(
        &self,
        opts: &crate::onnx::export::ExportOptions,
    ) -> Result<crate::onnx::proto::ModelProto> {
        crate::onnx::export::network1(self, opts)
    }
}

#[cfg(feature = "onnx")]
impl Exportable for WuNet {
    fn export(
        &self,
        opts: &crate::onnx::export::ExportOptions,
    ) -> Result<crate::onnx::proto::ModelProto> {
        crate::onnx::export::network2(self, opts)
    }
}
