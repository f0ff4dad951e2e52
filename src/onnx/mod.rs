//! ONNX export of both networks and ONNX Runtime inference (cargo feature `onnx`; docs/onnx.md).
//!
//! - [`export`]: each network lowered to an ONNX graph (opset 17) from its modules' structure
//!   and weights; [`proto`] holds the protobuf messages (encoded by `prost`), [`graph`] a small
//!   builder.
//! - [`runtime`]: an exported file run in ONNX Runtime, loaded at run time from
//!   `ORT_DYLIB_PATH` (`tools/setup_ort.sh`).
//! - [`infer`]: whole-image inference of an exported model through the exact tiling.
//! - [`verify`]: the parity check of `hdrsynth export onnx --verify` (ONNX Runtime vs Burn).

pub mod export;
pub mod graph;
pub mod infer;
pub mod proto;
pub mod runtime;
pub mod verify;
