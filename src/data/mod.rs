//! Synthetic sources and datasets: the procedural scene engine and dataset layouts.
pub mod layout;
pub mod scene;
