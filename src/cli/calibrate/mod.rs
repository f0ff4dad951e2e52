//! `hdrsynth calibrate colour|noise`: fit a SensorProfile's colour transform or noise model.
pub mod colour;
pub mod noise;
