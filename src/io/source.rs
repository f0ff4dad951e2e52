//! What identifies a capture: a profile records the captures it was calibrated on, a test set
//! the captures it was built from, and evaluation refuses to score a network on a capture that
//! calibrated the profile it was fine-tuned with.

use serde::{Deserialize, Serialize};

/// One capture a profile was calibrated on or a test set was built from: the file's SHA-256
/// (what identifies the capture wherever it is copied), the SHA-256 of its decoded pixels (what
/// identifies it after a lossless re-save under another name or format) and the pixels read,
/// [x0, y0, x1, y1) in the upright frame. Two sources overlap when they are the same file or
/// hold the same pixels, and share a pixel of the frame.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Source {
    /// The file's name when it was read (for messages; the hashes identify it).
    pub file: String,
    pub sha256: String,
    /// Absent in records written before it was kept: those compare by file only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixels_sha256: Option<String>,
    pub pixels: [usize; 4],
}

impl Source {
    /// Whether the two are the same capture (file or decoded pixels).
    pub fn same_capture(&self, other: &Source) -> bool {
        self.sha256 == other.sha256
            || matches!(
                (&self.pixels_sha256, &other.pixels_sha256),
                (Some(a), Some(b)) if a == b
            )
    }

    pub fn overlaps(&self, other: &Source) -> bool {
        let (p, q) = (self.pixels, other.pixels);
        self.same_capture(other) && p[0] < q[2] && q[0] < p[2] && p[1] < q[3] && q[1] < p[3]
    }
}

/// Every pair of `a` and `b` that overlaps.
pub fn overlapping<'a>(a: &'a [Source], b: &'a [Source]) -> Vec<(&'a Source, &'a Source)> {
    a.iter()
        .flat_map(|x| b.iter().filter(|y| x.overlaps(y)).map(move |y| (x, y)))
        .collect()
}
