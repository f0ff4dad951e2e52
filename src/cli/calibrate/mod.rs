//! `hdrsynth calibrate colour|noise|dng|brackets`: fit a SensorProfile's colour transform or
//! noise model, read them from DNG tags, or measure the device's output from brackets.
pub mod brackets;
pub mod colour;
pub mod dng;
pub mod noise;
