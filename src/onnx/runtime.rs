//! Running exported models in ONNX Runtime (the `ort` crate, library loaded at run time from
//! `ORT_DYLIB_PATH`; `tools/setup_ort.sh` fetches it from PyPI's `onnxruntime` wheel).

use super::export::{
    META_HDR_SCALE, META_MIN_SIZE, META_NETWORK, META_RADIUS, META_SIZE_MULTIPLE, N1_INPUTS,
    N1_PROBABILITIES, N1_WEIGHT, N2_FRAMES, N2_OUTPUT, N2_TIMES,
};
use crate::error::{Error, Result};
use ort::environment::Environment;
use ort::session::{OutputSelector, RunOptions, Session};
use ort::value::Tensor;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The environment variable naming the ONNX Runtime shared library.
pub const DYLIB_ENV: &str = "ORT_DYLIB_PATH";

/// The ONNX Runtime library named by `ORT_DYLIB_PATH`; an error that says how to get one when
/// the variable is unset or names no file.
pub fn dylib_path() -> Result<PathBuf> {
    let Some(path) = std::env::var_os(DYLIB_ENV) else {
        return Err(Error::flag(
            DYLIB_ENV,
            format!(
                "is not set: hdrsynth loads ONNX Runtime at run time. Run tools/setup_ort.sh \
                 (fetches PyPI's onnxruntime wheel into target/ort) and \
                 `export {DYLIB_ENV}=<the path it prints>`"
            ),
        ));
    };
    let path = PathBuf::from(path);
    if !path.is_file() {
        return Err(Error::io(
            &path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("{DYLIB_ENV} names no file; run tools/setup_ort.sh"),
            ),
        ));
    }
    Ok(path)
}

/// The process's ONNX Runtime environment (ONNX Runtime allows one), loaded on first use.
pub fn environment() -> Result<Environment> {
    // The failure is kept as (library, text): every later call reports the first one's cause.
    static ENV: OnceLock<std::result::Result<Environment, (PathBuf, String)>> = OnceLock::new();
    let path = dylib_path()?;
    ENV.get_or_init(|| {
        let failed = |what: &str, e: &dyn std::fmt::Display| (path.clone(), format!("{what}: {e}"));
        ort::init_from(&path)
            .map_err(|e| failed("loading ONNX Runtime", &e))?
            .with_name("hdrsynth")
            .with_telemetry(false)
            .build()
            .map_err(|e| failed("creating the ONNX Runtime environment", &e))
    })
    .clone()
    .map_err(|(path, msg)| Error::io(path, std::io::Error::other(msg)))
}

/// Which network an exported file holds (its `hdrsynth.network` metadata).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Network {
    Network1,
    Network2,
}

/// An exported model loaded in ONNX Runtime.
pub struct OnnxModel {
    session: Session,
    path: PathBuf,
    pub network: Network,
    /// H and W must be multiples of this.
    pub size_multiple: usize,
    /// … and at least this.
    pub min_size: usize,
    /// Receptive-field radius: the overlap of exact tiling.
    pub receptive_radius: usize,
    /// (height, width) of a static export; `None` when dynamic.
    pub static_size: Option<(usize, usize)>,
    /// Network-1: whether the file has the `blend_weight` output.
    pub has_weight: bool,
    /// Network-2: the model's `hdr_input_scale` (its output is already divided by it).
    pub hdr_input_scale: Option<f32>,
}

fn meta_usize(session: &Session, key: &str, path: &Path) -> Result<usize> {
    let meta = session
        .metadata()
        .map_err(|e| Error::decode(path, format!("reading metadata: {e}")))?;
    meta.custom(key)
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| {
            Error::unsupported(
                path,
                format!("no '{key}' metadata: not a model exported by `hdrsynth export onnx`"),
            )
        })
}

impl OnnxModel {
    /// Loads `path`; `threads` sets ONNX Runtime's intra-op threads (default: its own choice,
    /// one per physical core).
    pub fn load(path: &Path, threads: Option<usize>) -> Result<OnnxModel> {
        let bytes = crate::io::guard::read_input(path).map_err(|e| {
            let e = match e.kind() {
                std::io::ErrorKind::NotFound => {
                    std::io::Error::new(std::io::ErrorKind::NotFound, "no such ONNX model")
                }
                _ => e,
            };
            Error::io(path, e)
        })?;
        Self::from_bytes(&bytes, path, threads)
    }

    /// A model serialised in memory (a checkpoint exported on the fly: `engine`);
    /// `label` names it in messages.
    pub fn from_bytes(bytes: &[u8], label: &Path, threads: Option<usize>) -> Result<OnnxModel> {
        Self::build(label, threads, |b| b.commit_from_memory(bytes))
    }

    fn build(
        path: &Path,
        threads: Option<usize>,
        commit: impl FnOnce(&mut ort::session::builder::SessionBuilder) -> ort::Result<Session>,
    ) -> Result<OnnxModel> {
        let env = environment()?;
        let err = |e: &dyn std::fmt::Display| Error::decode(path, format!("ONNX Runtime: {e}"));
        let mut builder = Session::builder(&env).map_err(|e| err(&e))?;
        if let Some(n) = threads {
            builder = builder.with_intra_threads(n).map_err(|e| err(&e))?;
        }
        let session = commit(&mut builder).map_err(|e| err(&e))?;
        let network = {
            let meta = session.metadata().map_err(|e| err(&e))?;
            match meta.custom(META_NETWORK).as_deref() {
                Some("network1") => Network::Network1,
                Some("network2") => Network::Network2,
                other => {
                    return Err(Error::unsupported(
                        path,
                        format!(
                            "metadata '{META_NETWORK}' is {other:?}: not a model exported by \
                             `hdrsynth export onnx`"
                        ),
                    ));
                }
            }
        };
        let size_multiple = meta_usize(&session, META_SIZE_MULTIPLE, path)?;
        let min_size = meta_usize(&session, META_MIN_SIZE, path)?;
        let receptive_radius = meta_usize(&session, META_RADIUS, path)?;
        let first = session
            .inputs()
            .first()
            .ok_or_else(|| Error::unsupported(path, "the graph has no inputs"))?;
        let static_size = first.dtype().tensor_shape().and_then(|s| {
            let s: &[i64] = s;
            (s.len() == 4 && s[2] > 0 && s[3] > 0).then(|| (s[2] as usize, s[3] as usize))
        });
        let has_weight = session.outputs().iter().any(|o| o.name() == N1_WEIGHT);
        let hdr_input_scale = session
            .metadata()
            .ok()
            .and_then(|m| m.custom(META_HDR_SCALE))
            .and_then(|v| v.parse().ok());
        Ok(OnnxModel {
            session,
            path: path.to_path_buf(),
            network,
            size_multiple,
            min_size,
            receptive_radius,
            static_size,
            has_weight,
            hdr_input_scale,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether a `height`×`width` input is accepted.
    pub fn check_size(&self, height: usize, width: usize) -> Result<()> {
        if let Some((h, w)) = self.static_size {
            if (h, w) != (height, width) {
                return Err(Error::config(
                    &self.path,
                    format!("a static {h}×{w} model cannot take a {height}×{width} input"),
                ));
            }
            return Ok(());
        }
        let m = self.size_multiple;
        for v in [height, width] {
            if v < self.min_size || !v.is_multiple_of(m) {
                return Err(Error::config(
                    &self.path,
                    format!(
                        "input {height}×{width}: height and width must be multiples of {m} and \
                         at least {}",
                        self.min_size
                    ),
                ));
            }
        }
        Ok(())
    }

    fn expect(&self, network: Network) -> Result<()> {
        if self.network != network {
            return Err(Error::config(
                &self.path,
                format!("holds {:?}, not {network:?}", self.network),
            ));
        }
        Ok(())
    }

    /// Network-1 on `n` pairs of `[3, h, w]` planar frames (EV−3, EV0), stacked: the class
    /// probabilities `[n, C, h, w]` and, if the model has it, the blend weight `[n, 1, h, w]`.
    pub fn network1(
        &mut self,
        low: &[f32],
        high: &[f32],
        (n, h, w): (usize, usize, usize),
    ) -> Result<(Vec<f32>, Option<Vec<f32>>)> {
        self.expect(Network::Network1)?;
        self.check_size(h, w)?;
        let shape = [n, 3, h, w];
        let input = |v: &[f32]| Tensor::from_array((shape, v.to_vec()));
        let (a, b) = (
            input(low).map_err(|e| run_err(&self.path, e))?,
            input(high).map_err(|e| run_err(&self.path, e))?,
        );
        let has_weight = self.has_weight;
        let outputs = self
            .session
            .run(ort::inputs![N1_INPUTS[0] => a, N1_INPUTS[1] => b])
            .map_err(|e| run_err(&self.path, e))?;
        let path = &self.path;
        let take = |name: &str| -> Result<Vec<f32>> {
            let (_, data) = outputs[name]
                .try_extract_tensor::<f32>()
                .map_err(|e| run_err(path, e))?;
            Ok(data.to_vec())
        };
        let probs = take(N1_PROBABILITIES);
        let weight = has_weight.then(|| take(N1_WEIGHT)).transpose();
        drop(outputs);
        Ok((probs?, weight?))
    }

    /// Network-1's `blend_weight` output alone (`[n, 1, h, w]`): ONNX Runtime is asked for no
    /// other output, so the C×H×W probabilities are never copied out (at 256 classes they are
    /// 256× the weight).
    pub fn network1_blend_weight(
        &mut self,
        low: &[f32],
        high: &[f32],
        (n, h, w): (usize, usize, usize),
    ) -> Result<Vec<f32>> {
        self.expect(Network::Network1)?;
        self.check_size(h, w)?;
        if !self.has_weight {
            return Err(Error::config(
                &self.path,
                format!("exported without the '{N1_WEIGHT}' output"),
            ));
        }
        let shape = [n, 3, h, w];
        let a = Tensor::from_array((shape, low.to_vec())).map_err(|e| run_err(&self.path, e))?;
        let b = Tensor::from_array((shape, high.to_vec())).map_err(|e| run_err(&self.path, e))?;
        let options = RunOptions::new()
            .map_err(|e| run_err(&self.path, e))?
            .with_outputs(OutputSelector::no_default().with(N1_WEIGHT));
        let outputs = self
            .session
            .run_with_options(ort::inputs![N1_INPUTS[0] => a, N1_INPUTS[1] => b], &options)
            .map_err(|e| run_err(&self.path, e))?;
        let out = outputs[N1_WEIGHT]
            .try_extract_tensor::<f32>()
            .map(|(_, d)| d.to_vec())
            .map_err(|e| run_err(&self.path, e));
        drop(outputs);
        out
    }

    /// Network-2 on `n` triples of `[3, h, w]` planar frames (EV −2, 0, +2), each frame
    /// stacked over the batch, with exposure times `[n, 3]` relative to the reference: linear
    /// HDR `[n, 3, h, w]` (1 = the reference's white).
    pub fn network2(
        &mut self,
        frames: [&[f32]; 3],
        times: &[f32],
        (n, h, w): (usize, usize, usize),
    ) -> Result<Vec<f32>> {
        self.expect(Network::Network2)?;
        self.check_size(h, w)?;
        let mut values = Vec::new();
        for f in frames {
            values.push(
                Tensor::from_array(([n, 3, h, w], f.to_vec()))
                    .map_err(|e| run_err(&self.path, e))?,
            );
        }
        let t = Tensor::from_array(([n, 3], times.to_vec())).map_err(|e| run_err(&self.path, e))?;
        let [a, b, c]: [Tensor<f32>; 3] = values
            .try_into()
            .map_err(|_| run_err(&self.path, "inputs"))?;
        let outputs = self
            .session
            .run(ort::inputs![
                N2_FRAMES[0] => a,
                N2_FRAMES[1] => b,
                N2_FRAMES[2] => c,
                N2_TIMES => t
            ])
            .map_err(|e| run_err(&self.path, e))?;
        let out = outputs[N2_OUTPUT]
            .try_extract_tensor::<f32>()
            .map(|(_, d)| d.to_vec())
            .map_err(|e| run_err(&self.path, e));
        drop(outputs);
        out
    }
}

/// An error of ONNX Runtime while running the model at `path`.
fn run_err(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::config(path, format!("ONNX Runtime: {e}"))
}
