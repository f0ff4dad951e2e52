//! A device's own captures: a user's bracket folders read once and turned into what the rest
//! of hdrsynth uses — a test set in Kalantari's layout, a profile of the device's output, scene
//! bursts for the sim-to-real diagnosis, and the check of a profile against the device's own
//! frames.
//!
//! One public entry per job: [`scan::scan`] (folders → sets of frames with their exposures),
//! [`linearise`] (code values → linear), [`testset::build`], [`profile::calibrate_brackets`],
//! [`diagnose::diagnose_brackets`], [`output::check`]; [`align`] is the alignment of hand-held
//! frames, [`noise`] the output-domain noise measurements that the profile and the check share.
pub mod align;
pub mod diagnose;
pub mod linearise;
pub mod noise;
pub mod output;
pub mod profile;
pub mod scan;
pub mod testset;
