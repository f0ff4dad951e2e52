//! The device-output check's blockiness statistic and the catalogue's `jpeg` effect read from
//! a bracket folder's own files.
//!
//! Blockiness: on each unit's noise plane (a frame against the merge of its set's others, or a
//! repeated pair's difference: no scene), per channel, the mean absolute difference of
//! horizontal neighbours in each of the 8 column phases (x mod 8) and of vertical neighbours in
//! each row phase, where both values are recorded between codes 3 and 250. JPEG's 8×8 blocks
//! quantise each block on its own, so the differences across a block edge exceed those inside;
//! per axis the largest phase's mean over the other phases' (whatever the grid's phase in the
//! window read), and the statistic is their average less 1, in per cent. The same code reads
//! the real and every simulated replicate.

use super::effects::with_effect;
use super::{OutputCheck, OutputCheckOptions, Prepared, RECORDED, check_prepared};
use crate::capture::noise::Planes;
use crate::capture::scan::{self, FrameKind};
use crate::error::Result;
use crate::sensor::effects::jpeg::{self as effect, ID};
use crate::sensor::effects::not_fitted;
use crate::sensor::profile::SensorProfile;

/// Per phase (x mod 8, y mod 8) the sums of |neighbour differences| and their counts.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct BlockMoments {
    h: [f64; 8],
    hn: [f64; 8],
    v: [f64; 8],
    vn: [f64; 8],
}

impl BlockMoments {
    pub fn add(&mut self, o: &BlockMoments) {
        for p in 0..8 {
            self.h[p] += o.h[p];
            self.hn[p] += o.hn[p];
            self.v[p] += o.v[p];
            self.vn[p] += o.vn[p];
        }
    }

    /// The blockiness in per cent (NaN without values in every phase).
    pub fn value(&self) -> f64 {
        let axis = |s: &[f64; 8], n: &[f64; 8]| {
            if n.iter().any(|&k| k < 1.0) {
                return f64::NAN;
            }
            let m: Vec<f64> = (0..8).map(|p| s[p] / n[p]).collect();
            let top = (0..8).max_by(|&a, &b| m[a].total_cmp(&m[b])).unwrap_or(0);
            let rest = (0..8).filter(|&p| p != top).map(|p| m[p]).sum::<f64>() / 7.0;
            if rest > 0.0 { m[top] / rest } else { f64::NAN }
        };
        100.0 * ((axis(&self.h, &self.hn) + axis(&self.v, &self.vn)) / 2.0 - 1.0)
    }
}

/// The moments of one unit.
pub(super) fn moments(p: Planes) -> BlockMoments {
    let (w, h) = (p.signal.width, p.signal.height);
    let mut m = BlockMoments::default();
    let rec = |i: usize| (RECORDED.0..=RECORDED.1).contains(&p.signal.data[i]);
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let i = (y * w + x) * 3 + c;
                if !rec(i) {
                    continue;
                }
                if x + 1 < w && rec(i + 3) {
                    m.h[x % 8] += f64::from((p.noise.data[i + 3] - p.noise.data[i]).abs());
                    m.hn[x % 8] += 1.0;
                }
                let below = i + 3 * w;
                if y + 1 < h && rec(below) {
                    m.v[y % 8] += f64::from((p.noise.data[below] - p.noise.data[i]).abs());
                    m.vn[y % 8] += 1.0;
                }
            }
        }
    }
    m
}

/// The IJG quality the folder's JPEG frames store (the median over them) and the largest mean
/// difference of a frame's tables from libjpeg's at its quality (0: every frame holds
/// libjpeg's own tables). None where no frame is a JPEG.
pub fn folder_quality(scan: &scan::BracketScan) -> Result<Option<(u32, f64)>> {
    let mut found = Vec::new();
    for f in scan.sets.iter().flat_map(|s| &s.frames) {
        if f.kind != FrameKind::Ldr {
            continue;
        }
        let bytes = std::fs::read(&f.path).map_err(|e| crate::error::Error::io(&f.path, e))?;
        if !bytes.starts_with(&[0xFF, 0xD8]) {
            continue;
        }
        let tables = crate::io::jpeg::quant_tables(&bytes, &f.path)?;
        if let Some(q) = crate::io::jpeg::ijg_quality(&tables) {
            found.push(q);
        }
    }
    if found.is_empty() {
        return Ok(None);
    }
    let mismatch = found.iter().map(|q| q.1).fold(0.0, f64::max);
    let mut q: Vec<u32> = found.into_iter().map(|q| q.0).collect();
    q.sort_unstable();
    Ok(Some((q[q.len() / 2], mismatch)))
}

/// `profile` storing its frames as JPEG at `quality` (any `jpeg` it held replaced).
pub fn with_jpeg(profile: &SensorProfile, quality: u32, mismatch: f64) -> SensorProfile {
    let note = format!(
        "JPEG storage at IJG quality {quality}, read from the frames' quantisation tables (mean \
         difference from libjpeg's {mismatch:.2})"
    );
    with_effect(profile, ID, effect::params(quality), &note)
}

/// What [`fit_jpeg`] found.
#[derive(Clone, Debug)]
pub struct JpegFit {
    pub quality: u32,
    /// The mean difference of the frames' tables from libjpeg's at that quality.
    pub mismatch: f64,
    pub profile: SensorProfile,
    /// The check of `profile`.
    pub check: OutputCheck,
}

/// `profile` with the frames' own JPEG quality, and its check. A key error on `jpeg` where no
/// frame is a JPEG.
pub fn fit_jpeg(
    scan: &scan::BracketScan,
    profile: &SensorProfile,
    opts: &OutputCheckOptions,
) -> Result<JpegFit> {
    let Some((quality, mismatch)) = folder_quality(scan)? else {
        return Err(not_fitted(ID, "no frame of these sets is a JPEG"));
    };
    let prep = Prepared::new(scan.clone(), profile)?;
    let profile = with_jpeg(profile, quality, mismatch);
    let check = check_prepared(&prep, &profile, opts)?;
    Ok(JpegFit {
        quality,
        mismatch,
        profile,
        check,
    })
}
