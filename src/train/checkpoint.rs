//! Checkpoints: one folder per saved step, written whole or not at all.
//!
//! ```text
//! RUN/checkpoints/step-00000200/
//!     model.bpk          weights and BatchNorm statistics (Burn burnpack; parameter ids kept)
//!     optimizer.bpk      Adam moments and step counts (absent in an inference-only export)
//!     state.toml         step, stream position, seed, model config (CheckpointState)
//!     class_weights.toml Network-1's α
//!     checksums.sha256   SHA-256 of every other file (`sha256sum -c` reads it)
//! RUN/checkpoints/latest   the name of the newest complete checkpoint
//! ```
//!
//! A checkpoint is written into `.tmp-step-…`, synced, then renamed; `latest` is replaced
//! atomically afterwards. A run killed at any moment leaves the previous checkpoint intact.
//! Every read of a checkpoint file ([`read_verified`]) checks it against `checksums.sha256`,
//! so a damaged file is an error naming it, never weights used silently; a checkpoint without
//! the file (written before checksums existed) loads with a warning.
//!
//! A checkpoint is complete or it is not used ([`incomplete`]: a required file missing or
//! failing its checksum). A run folder's readers ([`latest`], [`resolve`]) pass over
//! incomplete ones to the newest complete one and say so on stderr; a step folder named
//! explicitly is refused if incomplete. `train --resume` moves incomplete checkpoints aside
//! into `RUN/checkpoints/incomplete/` ([`set_aside_incomplete`]); nothing is deleted.
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
pub const CHECKSUMS_FILE: &str = "checksums.sha256";
const LATEST: &str = "latest";
/// The folder of a run's checkpoints folder that incomplete checkpoints are moved into.
pub const INCOMPLETE_DIR: &str = "incomplete";

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
        let bytes = optimizer_to_bytes(optim, &path)?;
        write_file(&path, &bytes)?;
    }
    let path = tmp.join(STATE_FILE);
    let text = toml::to_string(state).map_err(|e| Error::encode(&path, e))?;
    write_file(&path, text.as_bytes())?;
    extra(&tmp)?;
    write_checksums(&tmp)?;
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

/// The step of a checkpoint folder name `step-N`.
fn step_of(name: &str) -> Option<u64> {
    name.strip_prefix("step-")?.parse().ok()
}

/// Every `step-N` folder of a checkpoints root, complete or not, oldest first.
fn step_folders(root: &Path) -> Result<Vec<(u64, PathBuf)>> {
    let mut out = Vec::new();
    let entries = match std::fs::read_dir(root) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(out),
        Err(e) => return Err(Error::io(root, e)),
    };
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(root, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if let Some(step) = step_of(&name)
            && entry.path().is_dir()
        {
            out.push((step, entry.path()));
        }
    }
    out.sort();
    Ok(out)
}

/// Every checkpoint folder (`step-N`) of a run, complete or not, oldest first.
pub fn all_steps(run: &Path) -> Result<Vec<PathBuf>> {
    Ok(step_folders(&dir_of(run))?
        .into_iter()
        .map(|(_, d)| d)
        .collect())
}

/// Checkpoint folders with a state file, oldest first: what [`prune`] may remove (the trainer
/// sets incomplete ones aside before it writes any).
fn list(root: &Path) -> Result<Vec<(u64, PathBuf)>> {
    let mut all = step_folders(root)?;
    all.retain(|(_, d)| d.join(STATE_FILE).is_file());
    Ok(all)
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
/// `.prune-…` (a prune cut short) and `write_atomic` temp files in the run folder, all the
/// trainer's own temporaries. A `step-…` folder is never removed here, complete or not
/// ([`set_aside_incomplete`] moves incomplete ones aside). Returns how many entries were
/// removed. The caller holds the run's writer lock.
pub fn clean_leftovers(run: &Path) -> Result<usize> {
    let root = dir_of(run);
    let mut n = 0;
    if let Ok(entries) = std::fs::read_dir(&root) {
        for entry in entries {
            let entry = entry.map_err(|e| Error::io(&root, e))?;
            let path = entry.path();
            let name = entry.file_name().to_string_lossy().into_owned();
            let leftover = name.starts_with(".tmp-step-") || name.starts_with(".prune-");
            if leftover && path.is_dir() {
                std::fs::remove_dir_all(&path).map_err(|e| Error::io(&path, e))?;
                n += 1;
            }
        }
    }
    Ok(n + crate::io::atomic::remove_stale_temps(run)?)
}

/// Why the checkpoint folder `dir` is incomplete, or None when it is complete: `state.toml`
/// and `model.bpk` present, and every file `checksums.sha256` lists present with the recorded
/// SHA-256 (so a missing `optimizer.bpk` or `class_weights.toml` counts). A checkpoint
/// written before checksums needs only the first two.
pub fn incomplete(dir: &Path) -> Option<String> {
    let mut why = Vec::new();
    for name in [STATE_FILE, MODEL_FILE] {
        if !dir.join(name).exists() {
            why.push(format!("{name} is missing"));
        }
    }
    match recorded_checksums(dir) {
        Err(e) => why.push(format!("{CHECKSUMS_FILE} is unreadable ({e})")),
        Ok(None) => {}
        Ok(Some(sums)) => {
            for (name, want) in sums {
                let path = dir.join(&name);
                if !path.exists() {
                    if !why.iter().any(|w| w.starts_with(&format!("{name} "))) {
                        why.push(format!("{name} is missing"));
                    }
                    continue;
                }
                match crate::io::guard::read_file(&path) {
                    Err(e) => why.push(format!("{name} is unreadable ({e})")),
                    Ok(bytes) if crate::io::sha256_hex(&bytes) != want => {
                        why.push(format!("{name} fails its checksum in {CHECKSUMS_FILE}"))
                    }
                    Ok(_) => {}
                }
            }
        }
    }
    (!why.is_empty()).then(|| why.join(", "))
}

/// A checkpoint passed over because it is [`incomplete`], and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Skipped {
    pub dir: PathBuf,
    pub why: String,
}

/// The newest complete checkpoint of a run (the one `latest` names, else the highest step),
/// and the incomplete ones passed over to reach it, newest first. Prints nothing.
pub fn newest_complete(run: &Path) -> Result<(Option<PathBuf>, Vec<Skipped>)> {
    let root = dir_of(run);
    let mut candidates: Vec<PathBuf> = step_folders(&root)?
        .into_iter()
        .rev()
        .map(|(_, d)| d)
        .collect();
    if let Ok(name) = crate::io::guard::read_text(&root.join(LATEST))
        && let Some(at) = candidates
            .iter()
            .position(|d| d.file_name().is_some_and(|n| n == name.trim()))
    {
        let named = candidates.remove(at);
        candidates.insert(0, named);
    }
    let mut skipped = Vec::new();
    for dir in candidates {
        match incomplete(&dir) {
            None => return Ok((Some(dir), skipped)),
            Some(why) => skipped.push(Skipped { dir, why }),
        }
    }
    Ok((None, skipped))
}

/// What a reader of `run` says on stderr about a checkpoint it passed over (once per folder
/// and process): which one it uses instead, and why.
fn warn_skipped(run: &Path, s: &Skipped, used: Option<&Path>) {
    static WARNED: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    let mut warned = WARNED.lock().unwrap_or_else(|e| e.into_inner());
    if warned.iter().any(|d| d == &s.dir) {
        return;
    }
    warned.push(s.dir.clone());
    let instead = match used {
        Some(d) => format!(
            "using {} instead, the newest complete checkpoint of {}",
            d.display(),
            run.display()
        ),
        None => format!("{} has no complete checkpoint", run.display()),
    };
    eprintln!(
        "warning: checkpoint {} is incomplete ({}) and is not used; {instead}",
        s.dir.display(),
        s.why
    );
}

/// The newest complete checkpoint of a run, if any ([`newest_complete`]); each incomplete
/// one passed over is named on stderr with the one used instead.
pub fn latest(run: &Path) -> Result<Option<PathBuf>> {
    let (dir, skipped) = newest_complete(run)?;
    for s in &skipped {
        warn_skipped(run, s, dir.as_deref());
    }
    Ok(dir)
}

/// An incomplete checkpoint moved aside by [`set_aside_incomplete`]: from, to, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct SetAside {
    pub from: PathBuf,
    pub to: PathBuf,
    pub why: String,
}

/// Move every [`incomplete`] checkpoint of `run` into `RUN/checkpoints/incomplete/` (as
/// `step-N`, or `step-N.2`, … when that name is taken), byte for byte; nothing is deleted.
/// `latest` is then rewritten to name the newest complete checkpoint if it named a moved one.
/// The caller (the trainer, on resume) holds the run's writer lock and reports the moves.
pub fn set_aside_incomplete(run: &Path) -> Result<Vec<SetAside>> {
    let root = dir_of(run);
    let aside = root.join(INCOMPLETE_DIR);
    let mut moved = Vec::new();
    for (_, dir) in step_folders(&root)?.into_iter().rev() {
        let Some(why) = incomplete(&dir) else {
            continue;
        };
        std::fs::create_dir_all(&aside).map_err(|e| Error::io(&aside, e))?;
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut to = aside.join(&name);
        let mut k = 2;
        while to.exists() {
            to = aside.join(format!("{name}.{k}"));
            k += 1;
        }
        std::fs::rename(&dir, &to).map_err(|e| Error::io(&dir, e))?;
        moved.push(SetAside { from: dir, to, why });
    }
    if moved.is_empty() {
        return Ok(moved);
    }
    sync_dir(&aside);
    sync_dir(&root);
    let named = crate::io::guard::read_text(&root.join(LATEST)).unwrap_or_default();
    let stale = moved
        .iter()
        .any(|m| m.from.file_name().is_some_and(|n| n == named.trim()));
    if stale && let Some((_, dir)) = list(&root)?.pop() {
        let name = dir.file_name().map(|n| n.to_string_lossy().into_owned());
        write_atomic(&root.join(LATEST), name.unwrap_or_default().as_bytes())?;
    }
    Ok(moved)
}

/// The checkpoint a run continues from (the trainer calls it under the run's writer lock).
/// On `resume`, every incomplete checkpoint is first moved aside into
/// `RUN/checkpoints/incomplete/` ([`set_aside_incomplete`]; never deleted), each named on
/// stderr, and the run continues from the newest complete one, named on stderr with why. A
/// new run gets the newest checkpoint folder, complete or not, so that the trainer refuses a
/// folder holding any.
pub fn resume_point(run: &Path, resume: bool) -> Result<Option<PathBuf>> {
    if !resume {
        return Ok(all_steps(run)?.pop());
    }
    let moved = set_aside_incomplete(run)?;
    for m in &moved {
        eprintln!(
            "warning: checkpoint {} is incomplete ({}): moved aside to {} (nothing deleted)",
            m.from.display(),
            m.why,
            m.to.display()
        );
    }
    let (existing, _) = newest_complete(run)?;
    if moved.is_empty() {
        return Ok(existing);
    }
    let names = moved
        .iter()
        .filter_map(|m| m.from.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect::<Vec<_>>()
        .join(", ");
    match &existing {
        Some(dir) => eprintln!(
            "resuming from {}, the newest complete checkpoint ({names} set aside as \
             incomplete)",
            dir.display()
        ),
        None => {
            return Err(Error::layout(
                run,
                format!(
                    "--resume: the run has no complete checkpoint ({names} set aside as \
                     incomplete, in {}); start a new run folder",
                    dir_of(run).join(INCOMPLETE_DIR).display()
                ),
            ));
        }
    }
    Ok(existing)
}

/// Whether `path` is meant as one checkpoint folder rather than a run folder: no
/// `checkpoints` folder in it, and a checkpoint file in it or a `step-N` name.
fn names_a_checkpoint(path: &Path) -> bool {
    if dir_of(path).is_dir() {
        return false;
    }
    [STATE_FILE, MODEL_FILE, CHECKSUMS_FILE]
        .iter()
        .any(|f| path.join(f).is_file())
        || path
            .file_name()
            .and_then(|n| step_of(&n.to_string_lossy()))
            .is_some()
}

/// A checkpoint folder from a path naming either a checkpoint or a run folder. A checkpoint
/// folder named explicitly must be complete ([`incomplete`]), else it is an error naming it
/// and what is wrong; a run folder gives its newest complete checkpoint ([`latest`]: each
/// incomplete one passed over is named on stderr with the one used instead).
pub fn resolve(path: &Path) -> Result<PathBuf> {
    if !path.exists() {
        return Err(Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such checkpoint or run"),
        ));
    }
    if names_a_checkpoint(path) {
        return match incomplete(path) {
            None => Ok(path.to_path_buf()),
            Some(why) => Err(Error::layout(
                path,
                format!(
                    "incomplete checkpoint ({why}); it is not used: give an earlier step \
                     folder, or the run folder to use its newest complete checkpoint"
                ),
            )),
        };
    }
    let (dir, skipped) = newest_complete(path)?;
    for s in &skipped {
        warn_skipped(path, s, dir.as_deref());
    }
    dir.ok_or_else(|| match skipped.first() {
        Some(s) => Error::layout(
            path,
            format!(
                "the run has no complete checkpoint: {} is incomplete ({})",
                s.dir.display(),
                s.why
            ),
        ),
        None => Error::layout(
            path,
            format!("neither a checkpoint (no {STATE_FILE}) nor a run with checkpoints"),
        ),
    })
}

pub fn read_state(dir: &Path) -> Result<CheckpointState> {
    let path = dir.join(STATE_FILE);
    let text = read_verified_text(dir, STATE_FILE)?;
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

/// Load the checkpoint's weights into `model` (built from the checkpoint's model config).
pub fn load_model<M: Module>(model: M, dir: &Path) -> Result<M> {
    let bytes = read_verified(dir, MODEL_FILE)?;
    model_from_bytes(model, bytes, &dir.join(MODEL_FILE))
}

/// [`load_model`] of a `model.bpk` held in memory (`path` names it in errors): the same path.
pub fn model_from_bytes<M: Module>(model: M, bytes: Vec<u8>, path: &Path) -> Result<M> {
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes))
        .map_err(|e| Error::decode(path, e))?;
    // Burn 0.22 panics instead of erring when a record tensor has a non-float dtype where a
    // float parameter is (found by tests/fuzz.rs: one byte "F32" → "U32" in the header), and
    // the record's dtypes are not public to check first; a crafted checkpoint must give an
    // error naming the file, not take the process down.
    let model = without_panic(path, "the record does not fit the model", || {
        model.try_load_record(record)
    })?
    .map_err(|e| Error::decode(path, e))?;
    // A diverged run's or a damaged file's NaN would be written as images and scored as zeros.
    match non_finite_parameter(&model) {
        Some(name) => Err(Error::decode(
            path,
            format!(
                "parameter '{name}' holds a NaN or an infinity: the weights are not usable \
                 (a diverged run or a damaged file; use an earlier checkpoint)"
            ),
        )),
        None => Ok(model),
    }
}

/// The module path of the first float parameter of `model` holding a NaN or an infinity.
pub fn non_finite_parameter<M: Module>(model: &M) -> Option<String> {
    use burn::module::{ModuleVisitor, Param};
    use burn::tensor::Tensor;
    struct Finder {
        path: Vec<String>,
        found: Option<String>,
    }
    impl ModuleVisitor for Finder {
        fn enter_module(&mut self, name: &str, _: &str) {
            self.path.push(name.to_string());
        }
        fn exit_module(&mut self, _: &str, _: &str) {
            self.path.pop();
        }
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            if self.found.is_none() && p.val().into_data().iter::<f32>().any(|v| !v.is_finite()) {
                self.found = Some(self.path.join("."));
            }
        }
    }
    let mut finder = Finder {
        path: Vec::new(),
        found: None,
    };
    model.visit(&mut finder);
    finder.found
}

/// `f()`, a Burn record load, with a panic inside it turned into an error naming `path`.
fn without_panic<T>(path: &Path, what: &str, f: impl FnOnce() -> T) -> Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|panic| {
        let why = panic
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| panic.downcast_ref::<&str>().copied())
            .unwrap_or("unknown");
        Error::decode(path, format!("corrupt checkpoint: {what} ({why})"))
    })
}

/// The bytes [`save`] writes to `model.bpk` (`path` names it in errors): the same weights
/// always give the same bytes ([`canonical_model`]).
pub fn model_to_bytes<M: Module>(model: &M, path: &Path) -> Result<Vec<u8>> {
    // `valid()` first: BatchNorm's running statistics (Burn's RunningState) hold their newest
    // update in a per-thread buffer that recording does not read; valid() folds it in.
    let bytes = model
        .valid()
        .into_record()
        .into_bytes()
        .map_err(|e| Error::encode(path, e))?;
    canonical_model(bytes, path)
}

/// The bytes [`save`] writes to `optimizer.bpk` (`path` names it in errors): the same state
/// always gives the same bytes ([`canonical_optimizer`]).
pub fn optimizer_to_bytes(optim: &ModuleOptimizer, path: &Path) -> Result<Vec<u8>> {
    let bytes = optim.into_bytes().map_err(|e| Error::encode(path, e))?;
    canonical_optimizer(bytes, path)
}

/// The parameter id a checkpoint gives the parameter at module path `path` (FNV-1a, 64 bits).
/// Burn draws parameter ids at random when a module is built, and both record files store
/// them, so without this two identical runs write different bytes.
pub fn param_id_of(path: &str) -> u64 {
    path.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

fn rewrite(
    bytes: burn::tensor::Bytes,
    path: &Path,
    edit: impl FnOnce(
        &mut Vec<burn_pack::Tensor>,
        &mut std::collections::BTreeMap<String, burn_pack::Scalar>,
        &mut std::collections::BTreeMap<String, String>,
    ),
) -> Result<Vec<u8>> {
    let reader = burn_pack::Reader::from_bytes(bytes).map_err(|e| Error::encode(path, e))?;
    let mut scalars = reader.scalars().clone();
    let mut metadata = reader.metadata().clone();
    let mut tensors = reader.into_tensors().map_err(|e| Error::encode(path, e))?;
    edit(&mut tensors, &mut scalars, &mut metadata);
    let mut writer = burn_pack::Writer::new(tensors);
    for (k, v) in &scalars {
        writer = writer.with_scalar(k, *v);
    }
    for (k, v) in &metadata {
        writer = writer.with_metadata(k, v);
    }
    writer
        .into_bytes()
        .map(|b| b.to_vec())
        .map_err(|e| Error::encode(path, e))
}

/// A module record (burnpack) with every parameter id replaced by [`param_id_of`] its module
/// path. Loading restores these ids, and [`canonical_optimizer`] keys the optimizer state by
/// the same ones, so a resumed run finds its state.
pub fn canonical_model(bytes: burn::tensor::Bytes, path: &Path) -> Result<Vec<u8>> {
    rewrite(bytes, path, |tensors, _, _| {
        for t in tensors {
            t.param_id = Some(param_id_of(&t.name));
        }
    })
}

/// An optimizer record (burnpack) keyed by [`param_id_of`] each parameter's module path (which
/// the record holds) instead of the run's random ids, its tensors in name order (Burn writes
/// them in hash-map order).
pub fn canonical_optimizer(bytes: burn::tensor::Bytes, path: &Path) -> Result<Vec<u8>> {
    rewrite(bytes, path, |tensors, scalars, paths| {
        // Old id (decimal) → new id, from the record's own id → module path entries.
        let ids: std::collections::BTreeMap<String, String> = paths
            .iter()
            .map(|(id, p)| (id.clone(), param_id_of(p).to_string()))
            .collect();
        let rename = |name: &str| match name.split_once('.') {
            Some((id, rest)) => match ids.get(id) {
                Some(new) => format!("{new}.{rest}"),
                None => name.to_string(),
            },
            None => name.to_string(),
        };
        for t in tensors.iter_mut() {
            t.name = rename(&t.name);
            t.param_id = t.param_id.map(|id| {
                ids.get(&id.to_string())
                    .and_then(|n| n.parse().ok())
                    .unwrap_or(id)
            });
        }
        tensors.sort_by(|a, b| a.name.cmp(&b.name));
        *scalars = std::mem::take(scalars)
            .into_iter()
            .map(|(k, v)| (rename(&k), v))
            .collect();
        *paths = std::mem::take(paths)
            .into_iter()
            .map(|(id, p)| (ids.get(&id).cloned().unwrap_or(id), p))
            .collect();
    })
}

/// Restore the optimizer state saved with the checkpoint.
pub fn load_optimizer(optim: ModuleOptimizer, dir: &Path) -> Result<ModuleOptimizer> {
    let bytes = read_verified(dir, OPTIMIZER_FILE)?;
    optimizer_from_bytes(optim, bytes, &dir.join(OPTIMIZER_FILE))
}

/// [`load_optimizer`] of an `optimizer.bpk` held in memory (`path` names it in errors).
pub fn optimizer_from_bytes(
    optim: ModuleOptimizer,
    bytes: Vec<u8>,
    path: &Path,
) -> Result<ModuleOptimizer> {
    // Burn 0.22's `load_record` panics on a state tensor without a parameter id.
    without_panic(path, "not an optimizer state", || {
        optim.from_bytes(Bytes::from_bytes_vec(bytes))
    })?
    .map_err(|e| Error::decode(path, e))
}

/// Write `checksums.sha256` into the checkpoint folder `dir`: one `HEX  NAME` line per file
/// (every file but itself and dot-files, by name), the format `sha256sum -c` checks.
fn write_checksums(dir: &Path) -> Result<()> {
    let mut names = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name != CHECKSUMS_FILE && !name.starts_with('.') && entry.path().is_file() {
            names.push(name);
        }
    }
    names.sort();
    let mut text = String::new();
    for name in names {
        let path = dir.join(&name);
        let bytes = crate::io::guard::read_file(&path)?;
        text.push_str(&format!("{}  {name}\n", crate::io::sha256_hex(&bytes)));
    }
    write_file(&dir.join(CHECKSUMS_FILE), text.as_bytes())
}

/// The recorded checksums of a checkpoint folder, by file name; None when it has no
/// `checksums.sha256` (a checkpoint written before checksums existed).
fn recorded_checksums(dir: &Path) -> Result<Option<Vec<(String, String)>>> {
    let path = dir.join(CHECKSUMS_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let text = crate::io::guard::read_text(&path)?;
    parse_checksums(&text, &path).map(Some)
}

/// `checksums.sha256` text: lines `HEX  NAME` (64 hex digits, two spaces, a plain file name).
pub fn parse_checksums(text: &str, path: &Path) -> Result<Vec<(String, String)>> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, line)| {
            let bad = || {
                Error::decode(
                    path,
                    format!(
                        "line {}: expected 64 hex digits, two spaces and a file name (the file \
                         is damaged)",
                        i + 1
                    ),
                )
            };
            let (hex, name) = line.split_once("  ").ok_or_else(bad)?;
            let name = name.trim_end_matches('\r');
            if hex.len() != 64
                || !hex.bytes().all(|b| b.is_ascii_hexdigit())
                || name.is_empty()
                || name.contains(['/', '\\'])
            {
                return Err(bad());
            }
            Ok((name.to_string(), hex.to_ascii_lowercase()))
        })
        .collect()
}

/// Warn once per checkpoint folder and process that its files cannot be verified.
fn warn_unverified(dir: &Path) {
    static WARNED: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    let mut warned = WARNED.lock().unwrap_or_else(|e| e.into_inner());
    if !warned.iter().any(|d| d == dir) {
        warned.push(dir.to_path_buf());
        eprintln!(
            "warning: {}: no {CHECKSUMS_FILE} (a checkpoint written before checksums): its \
             files are loaded unverified",
            dir.display()
        );
    }
}

/// Error unless `bytes`, the content of the file `name` of the checkpoint `dir`, match the
/// checksum recorded for it; a checkpoint without checksums passes with a warning.
pub fn verify(dir: &Path, name: &str, bytes: &[u8]) -> Result<()> {
    let path = dir.join(name);
    let Some(sums) = recorded_checksums(dir)? else {
        warn_unverified(dir);
        return Ok(());
    };
    let Some((_, want)) = sums.iter().find(|(n, _)| n == name) else {
        return Err(Error::decode(
            &path,
            format!("not listed in {CHECKSUMS_FILE}: the checkpoint is incomplete or was altered"),
        ));
    };
    let got = crate::io::sha256_hex(bytes);
    if &got != want {
        return Err(Error::decode(
            &path,
            format!(
                "checksum mismatch: the file's SHA-256 is {got} but {CHECKSUMS_FILE} records \
                 {want}; the file is damaged (copy the checkpoint again, or use an earlier one)"
            ),
        ));
    }
    Ok(())
}

/// The bytes of the file `name` of the checkpoint `dir`, verified ([`verify`]).
pub fn read_verified(dir: &Path, name: &str) -> Result<Vec<u8>> {
    let bytes = crate::io::guard::read_file(&dir.join(name))?;
    verify(dir, name, &bytes)?;
    Ok(bytes)
}

/// [`read_verified`] of a text file.
pub fn read_verified_text(dir: &Path, name: &str) -> Result<String> {
    let path = dir.join(name);
    String::from_utf8(read_verified(dir, name)?).map_err(|_| Error::decode(&path, "not UTF-8 text"))
}
