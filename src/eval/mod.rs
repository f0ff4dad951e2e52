//! Evaluation-side machinery: full-resolution inference by overlapping tiles, Network-1's
//! blend-map fusion (blend map → Laplacian blend → tone curve), and the field's metrics.
pub mod blend;
pub mod evaluate;
pub mod infer;
pub mod metrics;
pub mod report;
pub mod tiling;
