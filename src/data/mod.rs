//! Synthetic sources and datasets: the procedural scene engine and dataset layouts.
pub mod align;
pub mod bracket_captures;
pub mod bracket_output;
pub mod bracket_profile;
pub mod bracket_testset;
pub mod brackets;
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
