//! Evaluation methods that run a trained network here: a checkpoint's or an exported ONNX
//! file's network on the engine [`super::LoadedNetwork`] picks, as `eval::evaluate`'s
//! [`Method`]s.

use super::{LoadedNetwork, Network};
use crate::data::encoding::FrameEncoding;
use crate::error::{Error, Result};
use crate::eval::evaluate::{
    Classical, ClassicalMerge, Method, Network1, Network2, NetworkOptions, Predictions,
};
use crate::io::source::Source as Capture;
use crate::train::config::TrainedOn;
use burn::tensor::Device;
use std::path::{Path, PathBuf};

/// The method for a checkpoint (or run folder): the network its state names, weights loaded,
/// on the engine `opts.engine` chooses (`engine`).
pub fn from_checkpoint(
    path: &Path,
    opts: &NetworkOptions,
    device: &Device,
) -> Result<Box<dyn Method>> {
    let net = LoadedNetwork::from_checkpoint(path, opts, device)?;
    // The run folder holds the config that says what the training frames were encoded with.
    let run = net
        .source
        .parent()
        .and_then(Path::parent)
        .map(Path::to_path_buf);
    let trained = match run {
        Some(run) if run.join(crate::train::RUN_CONFIG).is_file() => {
            crate::train::config::run_trained_on(&run)
        }
        _ => Ok(TrainedOn::default()),
    };
    Ok(Box::new(Trained {
        method: from_network(net, opts),
        trained,
    }))
}

/// A checkpoint's method with what its run was trained on (or why it could not be read).
struct Trained {
    method: Box<dyn Method>,
    trained: Result<TrainedOn>,
}

impl Method for Trained {
    fn describe(&self, opts: &crate::eval::evaluate::EvalOptions) -> String {
        match &self.trained {
            Ok(_) => self.method.describe(opts),
            Err(e) => format!(
                "{}; its training frames' encoding could not be read: {e}",
                self.method.describe(opts)
            ),
        }
    }

    fn missing(&self, set: &crate::data::layout::SetInfo) -> Option<String> {
        self.method.missing(set)
    }

    fn run(
        &self,
        set: &crate::data::layout::SetInfo,
        opts: &crate::eval::evaluate::EvalOptions,
    ) -> Result<crate::eval::evaluate::Outcome> {
        self.method.run(set, opts)
    }

    fn trained_encoding(&self) -> Option<&FrameEncoding> {
        self.trained.as_ref().ok().and_then(|t| t.encoding.as_ref())
    }

    fn calibrated_on(&self) -> Option<(&Path, &[Capture])> {
        let t = self.trained.as_ref().ok()?;
        Some((t.profile.as_deref()?, &t.calibrated_on))
    }
}

/// What `hdrsynth eval` scores.
#[derive(Clone, Debug)]
pub enum Source {
    /// A folder of linear predictions made elsewhere, `<set>.exr` (or `.hdr`).
    Predictions(PathBuf),
    /// A checkpoint (or run folder: its latest checkpoint) run here on the device `backend`
    /// names (`device::device_from_name`).
    Checkpoint {
        path: PathBuf,
        backend: String,
        network: NetworkOptions,
    },
    /// A classical merge of the test set in the folder, with the curve it records.
    Baseline(Classical, PathBuf),
}

/// The method that scores `source`.
pub fn method_for(source: &Source) -> Result<Box<dyn Method>> {
    match source {
        Source::Predictions(dir) => {
            if !dir.is_dir() {
                return Err(Error::flag(
                    "--predictions",
                    format!("{}: not a folder", dir.display()),
                ));
            }
            Ok(Box::new(Predictions { dir: dir.clone() }))
        }
        Source::Checkpoint {
            path,
            backend,
            network,
        } => {
            let device = crate::device::device_from_name(backend)?;
            from_checkpoint(path, network, &device)
        }
        Source::Baseline(kind, testset) => {
            Ok(Box::new(ClassicalMerge::for_testset(*kind, testset)?))
        }
    }
}

/// The method for a loaded network (a checkpoint's, or an exported ONNX file's).
pub fn from_network(net: LoadedNetwork, opts: &NetworkOptions) -> Box<dyn Method> {
    match net.network {
        Network::Network1 => {
            let mode = opts.weight;
            Box::new(Network1 {
                description: format!("{}, weight {mode:?}", net.describe()),
                weights: Box::new(move |low, high| net.network1_weight(low, high, mode)),
                tone_k: opts.tone_k,
            })
        }
        Network::Network2 => Box::new(Network2 {
            description: net.describe(),
            infer: Box::new(move |frames, times, curve| net.network2_hdr_on(frames, times, curve)),
        }),
    }
}
