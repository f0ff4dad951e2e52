//! Bracket folders off a device and what is made of them: scanning (EXIF, sidecars, grouping,
//! orientation), the Kalantari-layout test set and its ground truth, the inputs' choice and
//! encoding, the response and alignment, the diagnosis on brackets, profiles from brackets, their
//! noise correlation, the device-output check and the device loop. One module per topic; the
//! fixture builders they share are in `helpers`.

#[path = "../common/mod.rs"]
mod common;
mod helpers;

mod alignment;
mod device_loop;
mod diagnose;
mod encoding;
mod folders;
mod ground_truth;
mod inputs;
mod noise_correlation;
mod orientation;
mod output_check;
mod profile;
mod real_data;
mod response;
mod testset;
