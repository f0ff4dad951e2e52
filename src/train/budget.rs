//! A lower bound on a training step's memory, checked against the host's available memory
//! before a run allocates anything: a config whose batch or network cannot fit is refused,
//! naming the key, instead of aborting in the allocator ("memory allocation of … failed").

use super::config::TrainConfig;
use crate::device::device_from_name;
use crate::error::{Error, Result};
use crate::models::ModelConfig;

/// What a training step holds at least, in bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepMemory {
    /// Trainable values of the network.
    pub parameters: u64,
    /// Weights, their gradients and Adam's two moments: 4 f32 per parameter.
    pub optimiser_bytes: f64,
    /// One batch of inputs at the network's input channels (f32): every activation is extra.
    pub input_bytes: f64,
    /// The batch of `patch`² crops it was computed for.
    pub batch: usize,
    pub patch: usize,
}

impl StepMemory {
    pub fn total(&self) -> f64 {
        self.optimiser_bytes + self.input_bytes
    }
}

/// The lower bound for `model` trained on batches of `batch` crops of `patch`², counted from
/// the architecture: a network too large to allocate can still be measured.
pub fn step_memory(model: &ModelConfig, batch: usize, patch: usize) -> StepMemory {
    let parameters = model.trainable_parameters() as u64;
    StepMemory {
        parameters,
        optimiser_bytes: 16.0 * parameters as f64,
        input_bytes: 4.0 * batch as f64 * (patch as f64).powi(2) * model.input_channels() as f64,
        batch,
        patch,
    }
}

/// The host's available memory (Linux `/proc/meminfo` MemAvailable), bytes; `None` elsewhere.
pub fn available_memory() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// Refuse a step whose lower bound `need` exceeds `available` bytes, naming the key that
/// dominates it (the network's width and depth, or the batch and crop size).
pub fn check(need: &StepMemory, available: f64, model_keys: &str) -> Result<()> {
    if need.total() <= available {
        return Ok(());
    }
    let gb = |b: f64| b / 1e9;
    // (keys, what they cost): the message reads "KEYS: COST; a training step needs …".
    let (keys, cost) = if need.optimiser_bytes >= need.input_bytes {
        (
            model_keys.to_string(),
            format!(
                "the network has {} parameters, {:.1} GB with their gradients and Adam's \
                 moments",
                need.parameters,
                gb(need.optimiser_bytes)
            ),
        )
    } else {
        (
            format!(
                "data.batch_size = {} crops of data.patch = {}²",
                need.batch, need.patch
            ),
            format!(
                "one batch of inputs alone is {:.1} GB",
                gb(need.input_bytes)
            ),
        )
    };
    Err(Error::key(
        keys,
        format!(
            "{cost}; a training step needs at least {:.1} GB and this machine has {:.1} GB \
             available: lower it (docs/training.md, \"Memory\")",
            gb(need.total()),
            gb(available)
        ),
    ))
}

/// On a CPU backend, refuse a config whose training step cannot fit in the host's available
/// memory, before anything is read or allocated.
pub fn check_config(cfg: &TrainConfig) -> Result<()> {
    let names = if cfg.run.devices.is_empty() {
        std::slice::from_ref(&cfg.run.backend)
    } else {
        cfg.run.devices.as_slice()
    };
    for name in names {
        if !crate::device::is_cpu(&device_from_name(name)?) {
            return Ok(());
        }
    }
    let Some(available) = available_memory() else {
        return Ok(());
    };
    let keys = match &cfg.model {
        ModelConfig::BlendUnet(_) => "model.base_width and model.depth",
        ModelConfig::Wu(_) => "model.base_width and model.res_blocks",
    };
    let need = step_memory(&cfg.model, cfg.data.batch_size, cfg.data.patch);
    check(&need, available, keys)
}
