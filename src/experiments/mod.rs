//! Experiments: the ablation grid, the main job, the full protocol and the sim-to-real loop. They generate data, train
//! and evaluate through `data`, `train` and `eval`; `eval` itself only scores.
pub mod ablate;
pub mod device_loop;
pub mod protocol;
pub mod quickstart;
pub mod sweep;
