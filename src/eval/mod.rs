//! Evaluation-side machinery: full-resolution inference by overlapping tiles, and Network-1's
//! blend-map fusion (blend map → Laplacian blend → tone curve).
pub mod blend;
pub mod infer;
pub mod tiling;
