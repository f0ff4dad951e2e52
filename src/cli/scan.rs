//! The flags of the bracket scan, declared once for every command that reads a bracket folder
//! (`testset --brackets`, `calibrate brackets`, `diagnose --brackets`, `loop`).

use crate::capture::scan::{Region, ScanOptions};

#[derive(clap::Args, Clone, Debug)]
pub struct ScanArgs {
    /// Declared EV steps in capture order, for frames without EXIF or sidecar.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub declared_evs: Option<Vec<f64>>,
    /// Largest gap between capture times within one set, seconds.
    #[arg(long, default_value_t = ScanOptions::default().max_gap_s)]
    pub max_gap: f64,
    /// Frames of one exposure within a set are repeated captures of a static scene from a
    /// fixed camera (a burst): only capture-time gaps and sub-folders split sets; noise is
    /// measured on the differences of repeated frames, and a test set uses each exposure's
    /// first capture.
    #[arg(long)]
    pub repeats: bool,
}

/// `--region`: the part of every frame that is read.
#[derive(clap::Args, Clone, Debug)]
pub struct RegionArg {
    /// Read only this part of every frame: left, right, top, bottom (halves of the upright
    /// frame, split at ⌊w/2⌋ or ⌊h/2⌋) or x,y,w,h in pixels.
    #[arg(long)]
    pub region: Option<Region>,
}

impl ScanArgs {
    /// The library's scan options for these flags, reading `region` of every frame.
    pub fn options(&self, region: Option<Region>) -> ScanOptions {
        ScanOptions {
            evs: self.declared_evs.clone(),
            max_gap_s: self.max_gap,
            region,
            sets: Vec::new(),
            repeats: self.repeats,
        }
    }
}
