//! The sensor model: device profiles, response curves, colour and noise calibration, and the
//! realism operator that turns pure synthetic frames into sensor-realistic ones.
pub mod captures;
pub mod colour;
pub mod crf;
pub mod darktable;
pub mod diagnose;
pub mod dng;
pub mod effects;
pub mod metering;
pub mod noise;
pub mod profile;
pub mod realism;
pub mod response;
