//! Synthetic sources and datasets: the procedural scene engine and dataset layouts.
pub mod align;
pub mod bracket_captures;
pub mod bracket_testset;
pub mod brackets;
pub mod class_maps;
pub mod generate;
pub mod ground_truth;
pub mod layout;
pub mod loader;
pub mod preview;
pub mod pyramid;
pub mod scene;
pub mod testset;

/// `e` behind `what` ("what: e"): the context the CLI's messages carried before these passes
/// moved into the library.
pub(crate) fn within(what: String) -> impl FnOnce(crate::Error) -> crate::Error {
    move |e| crate::Error::Invalid(format!("{what}: {e}"))
}
