//! Checkpoints: one folder per saved step, written whole or not at all.
//!
//! ```text
//! RUN/checkpoints/step-00000200/
//!     model.bpk          weights and BatchNorm statistics (Burn burnpack; parameter ids kept)
//!     optimizer.bpk      Adam moments and step counts (absent in an inference-only export)
//!     state.toml         step, stream position, seed, model config (CheckpointState)
//!     class_weights.toml Network-1's α
//! RUN/checkpoints/latest   the name of the newest complete checkpoint
//! ```
//!
//! A checkpoint is written into `.tmp-step-…`, synced, then renamed; `latest` is replaced
//! atomically afterwards. A run killed at any moment leaves the previous checkpoint intact.
//! The data stream and the learning-rate schedule are pure functions of (seed, step), so the
//! step is the whole random state: `rng_seed` and `samples` record it.

use crate::error::{Error, Result};
use crate::io::atomic::write_atomic;
use crate::models::ModelConfig;
use burn::module::Module;
use burn::optim::ModuleOptimizer;
use burn::store::ModuleRecord;
use burn::tensor::Bytes;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const FORMAT: &str = "hdrsynth-checkpoint/1";
pub const MODEL_FILE: &str = "model.bpk";
pub const OPTIMIZER_FILE: &str = "optimizer.bpk";
pub const STATE_FILE: &str = "state.toml";
const LATEST: &str = "latest";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckpointState {
    pub format: String,
    /// Optimisation steps completed.
    pub step: u64,
    /// Stream samples consumed (step · batch size): the next sample to read.
    pub samples: u64,
    /// Epoch of the next sample (samples div training sets).
    pub epoch: u64,
    /// The data/initialisation seed; with `samples` the complete random state.
    pub rng_seed: u64,
    /// Mean training loss of the last logged interval.
    #[serde(default)]
    pub loss: Option<f64>,
    pub model: ModelConfig,
}

/// The checkpoints folder of a run.
pub fn dir_of(run: &Path) -> PathBuf {
    run.join("checkpoints")
}

fn name_of(step: u64) -> String {
    format!("step-{step:08}")
}

fn sync_dir(dir: &Path) {
    // Directory fsync makes the rename durable; not all platforms allow opening a directory.
    if let Ok(f) = std::fs::File::open(dir) {
        let _ = f.sync_all();
    }
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let mut f = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    f.write_all(bytes).map_err(|e| Error::io(path, e))?;
    f.sync_all().map_err(|e| Error::io(path, e))
}

/// Save a checkpoint of `run` at `state.step`; `extra` writes task files into the new folder.
/// Prunes all but the newest `keep` checkpoints. Returns the checkpoint folder.
pub fn save<M: Module>(
    run: &Path,
    state: &CheckpointState,
    model: &M,
    optim: Option<&ModuleOptimizer>,
    keep: usize,
    extra: impl FnOnce(&Path) -> Result<()>,
) -> Result<PathBuf> {
    let root = dir_of(run);
    let name = name_of(state.step);
    let tmp = root.join(format!(".tmp-{name}"));
    let fin = root.join(&name);
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
    }
    std::fs::create_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
    let model_path = tmp.join(MODEL_FILE);
    let bytes = model_to_bytes(model, &model_path)?;
    write_file(&model_path, &bytes)?;
    if let Some(optim) = optim {
        let path = tmp.join(OPTIMIZER_FILE);
        let bytes = optim.into_bytes().map_err(|e| Error::encode(&path, e))?;
        write_file(&path, &bytes)?;
    }
    let path = tmp.join(STATE_FILE);
    let text = toml::to_string(state).map_err(|e| Error::encode(&path, e))?;
    write_file(&path, text.as_bytes())?;
    extra(&tmp)?;
    sync_dir(&tmp);
    if fin.exists() {
        std::fs::remove_dir_all(&fin).map_err(|e| Error::io(&fin, e))?;
    }
    std::fs::rename(&tmp, &fin).map_err(|e| Error::io(&fin, e))?;
    sync_dir(&root);
    write_atomic(&root.join(LATEST), name.as_bytes())?;
    prune(&root, keep.max(1))?;
    Ok(fin)
}

/// Complete checkpoint folders of a checkpoints root, oldest first.
fn list(root: &Path) -> Result<Vec<(u64, PathBuf)>> {
    let mut out = Vec::new();
    let entries = match std::fs::read_dir(root) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(out),
        Err(e) => return Err(Error::io(root, e)),
    };
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(root, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if let Some(step) = name
            .strip_prefix("step-")
            .and_then(|s| s.parse::<u64>().ok())
            && entry.path().join(STATE_FILE).is_file()
        {
            out.push((step, entry.path()));
        }
    }
    out.sort();
    Ok(out)
}

fn prune(root: &Path, keep: usize) -> Result<()> {
    let all = list(root)?;
    for (_, dir) in all.iter().take(all.len().saturating_sub(keep)) {
        // Renamed out of the `step-` namespace first (atomic), so a kill during the removal
        // leaves a `.prune-` folder that `clean_leftovers` removes, never a half-deleted
        // `step-` folder.
        let name = dir.file_name().map(|n| n.to_string_lossy().into_owned());
        let doomed = root.join(format!(".prune-{}", name.unwrap_or_default()));
        std::fs::rename(dir, &doomed).map_err(|e| Error::io(dir, e))?;
        std::fs::remove_dir_all(&doomed).map_err(|e| Error::io(&doomed, e))?;
    }
    Ok(())
}

/// Remove what a killed run left in its checkpoints folder: `.tmp-step-…` (a save cut short),
/// `.prune-…` (a prune cut short), `step-…` folders without a state file (a prune cut short
/// by an older version, which deleted in place) and `write_atomic` temp files in the run
/// folder. Returns how many entries were removed. The caller holds the run's writer lock.
pub fn clean_leftovers(run: &Path) -> Result<usize> {
    let root = dir_of(run);
    let mut n = 0;
    if let Ok(entries) = std::fs::read_dir(&root) {
        for entry in entries {
            let entry = entry.map_err(|e| Error::io(&root, e))?;
            let path = entry.path();
            let name = entry.file_name().to_string_lossy().into_owned();
            let leftover = name.starts_with(".tmp-step-")
                || name.starts_with(".prune-")
                || (name.starts_with("step-") && !path.join(STATE_FILE).is_file());
            if leftover && path.is_dir() {
                std::fs::remove_dir_all(&path).map_err(|e| Error::io(&path, e))?;
                n += 1;
            }
        }
    }
    Ok(n + crate::io::atomic::remove_stale_temps(run)?)
}

/// The newest complete checkpoint of a run, if any (`latest`, else the highest step folder).
pub fn latest(run: &Path) -> Result<Option<PathBuf>> {
    let root = dir_of(run);
    if let Ok(name) = std::fs::read_to_string(root.join(LATEST)) {
        let dir = root.join(name.trim());
        if dir.join(STATE_FILE).is_file() {
            return Ok(Some(dir));
        }
    }
    Ok(list(&root)?.pop().map(|(_, d)| d))
}

/// A checkpoint folder from a path naming either a checkpoint or a run folder (its latest).
pub fn resolve(path: &Path) -> Result<PathBuf> {
    if path.join(STATE_FILE).is_file() {
        return Ok(path.to_path_buf());
    }
    if !path.exists() {
        return Err(Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such checkpoint or run"),
        ));
    }
    latest(path)?.ok_or_else(|| {
        Error::layout(
            path,
            format!("neither a checkpoint (no {STATE_FILE}) nor a run with checkpoints"),
        )
    })
}

pub fn read_state(dir: &Path) -> Result<CheckpointState> {
    let path = dir.join(STATE_FILE);
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    parse_state(&text, &path)
}

/// A `state.toml`'s text, checked as [`read_state`] checks the file `path` (named in errors).
pub fn parse_state(text: &str, path: &Path) -> Result<CheckpointState> {
    let state: CheckpointState = crate::config::parse_toml(text, path)?;
    if state.format != FORMAT {
        return Err(Error::config(
            path,
            format!("format '{}' is not '{FORMAT}'", state.format),
        ));
    }
    Ok(state)
}

fn read_bytes(path: &Path) -> Result<Bytes> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    Ok(Bytes::from_bytes_vec(bytes))
}

/// Load the checkpoint's weights into `model` (built from the checkpoint's model config).
pub fn load_model<M: Module>(model: M, dir: &Path) -> Result<M> {
    let path = dir.join(MODEL_FILE);
    let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
    model_from_bytes(model, bytes, &path)
}

/// [`load_model`] of a `model.bpk` held in memory (`path` names it in errors): the same path.
pub fn model_from_bytes<M: Module>(model: M, bytes: Vec<u8>, path: &Path) -> Result<M> {
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes))
        .map_err(|e| Error::decode(path, e))?;
    // Burn 0.22 panics instead of erring when a record tensor has a non-float dtype where a
    // float parameter is (found by tests/fuzz.rs: one byte "F32" → "U32" in the header), and
    // the record's dtypes are not public to check first; a crafted checkpoint must give an
    // error naming the file, not take the process down.
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        model.try_load_record(record)
    })) {
        Ok(loaded) => loaded.map_err(|e| Error::decode(path, e)),
        Err(panic) => {
            let why = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("unknown");
            Err(Error::decode(
                path,
                format!("corrupt checkpoint: the record does not fit the model ({why})"),
            ))
        }
    }
}

/// The bytes [`save`] writes to `model.bpk` (`path` names it in errors).
pub fn model_to_bytes<M: Module>(model: &M, path: &Path) -> Result<Vec<u8>> {
    // `valid()` first: BatchNorm's running statistics (Burn's RunningState) hold their newest
    // update in a per-thread buffer that recording does not read; valid() folds it in.
    model
        .valid()
        .into_record()
        .into_bytes()
        .map(|b| b.to_vec())
        .map_err(|e| Error::encode(path, e))
}

/// Restore the optimizer state saved with the checkpoint.
pub fn load_optimizer(optim: ModuleOptimizer, dir: &Path) -> Result<ModuleOptimizer> {
    let path = dir.join(OPTIMIZER_FILE);
    optim
        .from_bytes(read_bytes(&path)?)
        .map_err(|e| Error::decode(&path, e))
}
