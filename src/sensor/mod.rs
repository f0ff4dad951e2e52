//! The sensor model: device profiles, response curves, colour and noise calibration, and the
//! realism operator that turns pure synthetic frames into sensor-realistic ones.
pub mod effects;
pub mod profile;
pub mod response;
