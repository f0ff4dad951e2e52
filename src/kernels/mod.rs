//! The networks' operations: each is Burn's op on any backend, and on flex (f32) a
//! hand-written kernel with its own gradient. The architectures in [`crate::models`] call these
//! functions and never see which one runs.
//!
//! - [`conv`]: 2D convolutions and transposed convolutions, im2col + GEMM on flex.
//! - [`pad`]: reflection padding (Network-2's convolutions), one fused op on flex.
//! - [`activation`]: leaky ReLU (Network-2's encoders), one fused op on flex.
//! - [`pool`]: Network-1's 2×2 max-pool, one fused op on flex.
//! - `winograd` (flex): Winograd F(m×m, r×r) for the stride-1 3×3 and 5×5 convolutions.
//! - `direct` (flex): direct convolution for thin stride-1 layers (≤ 4 channels on one side).
//! - [`batch_norm`]: BatchNorm, fused and parallel on flex in training mode.
//! - [`fused_loss`]: Network-1's class loss fused into one operation on flex.

pub mod activation;
pub mod batch_norm;
pub mod conv;
#[cfg(feature = "flex")]
pub mod direct;
pub mod fused_loss;
pub mod pad;
#[cfg(feature = "flex")]
pub(crate) mod par;
pub mod pool;
#[cfg(feature = "flex")]
pub mod winograd;
