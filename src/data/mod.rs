//! Synthetic sources and datasets: the procedural scene engine and dataset layouts.
pub mod class_maps;
pub mod encoding;
pub mod generate;
pub mod ground_truth;
pub mod layout;
pub mod loader;
pub mod preview;
pub mod pyramid;
pub mod scene;
pub mod testset;
