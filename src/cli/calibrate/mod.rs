//! `hdrsynth calibrate colour|noise|dng`: fit a SensorProfile's colour transform or noise model,
//! or read them from DNG tags.
pub mod colour;
pub mod dng;
pub mod noise;
