//! The sensor model. For now: the response curves shared by the scene engine (its display
//! tone curve) and, later, the device model. `response` depends on nothing else in the crate.
pub mod response;
