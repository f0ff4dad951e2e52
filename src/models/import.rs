//! Weight exchange with PyTorch-style state dicts stored as SafeTensors (burn-store).
//!
//! Names are the module's own field paths (`encoders.0.conv1.weight`, `decoder.up.2.bn.bias`,
//! …) with PyTorch's BatchNorm names: `weight`/`bias` for Burn's γ/β, plus `running_mean` and
//! `running_var`. Convolution weights are `[out, in, kh, kw]`, transposed convolutions
//! `[in, out, kh, kw]`: Burn's layouts are PyTorch's, so no tensor is permuted. The table for
//! Network-2 is in docs/network2.md; [`expected_tensors`] lists any module's.
//!
//! A PyTorch `.pt`/`.pth` state dict is converted once in Python (docs/network2.md); reading
//! pickles here would need burn's `pytorch` feature, whose zip dependency changes feature sets
//! shared with the rest of the build (a full rebuild of the Burn stack).

use crate::error::{Error, Result};
use burn::module::Module;
use burn::store::{
    BurnToPyTorchAdapter, FloatCastAdapter, ModuleAdapter, ModuleSnapshot, ModuleStore,
    PyTorchToBurnAdapter, SafetensorsStore,
};
use burn::tensor::DType;
use std::collections::BTreeMap;
use std::path::Path;

/// Keys in a state dict that carry no parameter of ours (PyTorch's BatchNorm step counter).
fn ignored(key: &str) -> bool {
    key.ends_with("num_batches_tracked")
}

/// The tensors `model` takes, as (PyTorch-style name, shape), in the module's order.
pub fn expected_tensors<M: Module>(model: &M) -> Vec<(String, Vec<usize>)> {
    model
        .collect(None, Some(Box::new(BurnToPyTorchAdapter)), true)
        .into_iter()
        .map(|t| (t.name.clone(), t.shape.to_vec()))
        .collect()
}

fn list(keys: &[String]) -> String {
    const SHOWN: usize = 5;
    let mut s = keys
        .iter()
        .take(SHOWN)
        .map(|k| format!("'{k}'"))
        .collect::<Vec<_>>()
        .join(", ");
    if keys.len() > SHOWN {
        s.push_str(&format!(" and {} more", keys.len() - SHOWN));
    }
    s
}

/// Loads every parameter and BatchNorm running statistic of `model` from the SafeTensors file
/// at `path` (names as in [`expected_tensors`]; a leading `module.` of every key, as
/// `nn.DataParallel` writes, is dropped; `*.num_batches_tracked` keys are ignored). Float
/// tensors of any precision are converted to f32.
///
/// Strict: a missing tensor, a tensor of another shape or a non-float dtype, or a tensor that
/// matches no parameter is an error naming the key and the file; `model` is then not modified.
pub fn import_weights<M: Module>(model: M, path: &Path) -> Result<M> {
    let mut file = crate::io::guard::open_input(path).map_err(|e| {
        let e = match e.kind() {
            std::io::ErrorKind::NotFound => {
                std::io::Error::new(std::io::ErrorKind::NotFound, "no such weights file")
            }
            _ => e,
        };
        Error::io(path, e)
    })?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("safetensors") => {}
        Some("pt" | "pth" | "bin") => {
            return Err(Error::unsupported(
                path,
                "PyTorch pickles are not read directly; convert the state dict to SafeTensors \
                 first (docs/network2.md: safetensors.torch.save_file)",
            ));
        }
        _ => {
            return Err(Error::unsupported(
                path,
                "expected a .safetensors file of PyTorch-style names (docs/network2.md)",
            ));
        }
    }
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(&mut file, &mut bytes).map_err(|e| Error::io(path, e))?;
    import_weights_bytes(model, bytes, path)
}

/// [`import_weights`] of a SafeTensors file held in memory (`path` names it in errors); the
/// file reader calls this, so both share every check.
pub fn import_weights_bytes<M: Module>(mut model: M, bytes: Vec<u8>, path: &Path) -> Result<M> {
    let mut store = SafetensorsStore::from_bytes(Some(bytes));
    let stored = store
        .get_all_tensors()
        .map_err(|e| Error::decode(path, e))?
        .clone();
    // A leading "module." only when every key has it (nn.DataParallel).
    let strip = !stored.is_empty() && stored.keys().all(|k| k.starts_with("module."));
    let mut file: BTreeMap<String, _> = BTreeMap::new();
    for (key, mut t) in stored {
        let key = if strip {
            key["module.".len()..].to_string()
        } else {
            key
        };
        if ignored(&key) {
            continue;
        }
        t.name = key.clone();
        file.insert(key, t);
    }

    let expected = expected_tensors(&model);
    let mut missing = Vec::new();
    for (key, shape) in &expected {
        match file.get(key) {
            None => missing.push(format!("{key} {shape:?}")),
            Some(t) => {
                let found = t.shape.to_vec();
                if &found != shape {
                    return Err(Error::decode(
                        path,
                        format!("tensor '{key}' has shape {found:?}, the model expects {shape:?}"),
                    ));
                }
                if !t.dtype.is_float() {
                    return Err(Error::unsupported(
                        path,
                        format!(
                            "tensor '{key}' has dtype {:?}, expected a float type",
                            t.dtype
                        ),
                    ));
                }
            }
        }
    }
    if !missing.is_empty() {
        return Err(Error::decode(
            path,
            format!(
                "{} of the model's {} tensors are missing: {}",
                missing.len(),
                expected.len(),
                list(&missing)
            ),
        ));
    }
    let known: std::collections::HashSet<&str> = expected.iter().map(|(k, _)| k.as_str()).collect();
    let unexpected: Vec<String> = file
        .keys()
        .filter(|k| !known.contains(k.as_str()))
        .cloned()
        .collect();
    if !unexpected.is_empty() {
        return Err(Error::decode(
            path,
            format!(
                "{} tensors match no parameter of the model (another naming scheme or \
                 architecture?): {}",
                unexpected.len(),
                list(&unexpected)
            ),
        ));
    }

    // PyTorch → Burn renames BatchNorm weight/bias to γ/β; the cast keeps every parameter f32
    // (burn-store would otherwise keep the file's dtype).
    let adapter: Box<dyn ModuleAdapter> =
        Box::new(PyTorchToBurnAdapter.chain(FloatCastAdapter::to(DType::F32)));
    let result = model.apply(file.into_values().collect(), None, Some(adapter), true);
    if !result.errors.is_empty() || !result.missing.is_empty() {
        let mut msgs: Vec<String> = result.errors.iter().map(|e| e.to_string()).collect();
        msgs.extend(result.missing.iter().map(|(k, _)| format!("missing '{k}'")));
        return Err(Error::decode(path, list(&msgs)));
    }
    Ok(model)
}

/// Writes every parameter and BatchNorm running statistic of `model` to a SafeTensors file
/// at `path` (replaced if present) under the names of [`expected_tensors`], as f32.
pub fn export_weights<M: Module>(model: &M, path: &Path) -> Result<()> {
    let mut store = SafetensorsStore::from_file(path)
        .with_to_adapter(BurnToPyTorchAdapter)
        .skip_enum_variants(true)
        .overwrite(true);
    model
        .save_into(&mut store)
        .map_err(|e| Error::encode(path, e))
}
