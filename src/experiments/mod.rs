//! Experiments: the ablation grid, the main job and the full protocol. They generate data, train
//! and evaluate through `data`, `train` and `eval`; `eval` itself only scores.
pub mod ablate;
pub mod protocol;
pub mod quickstart;
