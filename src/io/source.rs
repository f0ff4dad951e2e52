//! What identifies a capture: a profile records the captures it was calibrated on, a test set
//! the captures it was built from, and evaluation refuses to score a network on a capture that
//! calibrated the profile it was fine-tuned with.

use serde::{Deserialize, Serialize};

/// One capture a profile was calibrated on or a test set was built from: the file's SHA-256
/// (what identifies the capture wherever it is copied) and the pixels read, [x0, y0, x1, y1)
/// in the upright frame. Two sources overlap when they are the same file and share a pixel.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Source {
    /// The file's name when it was read (for messages; the hash identifies it).
    pub file: String,
    pub sha256: String,
    pub pixels: [usize; 4],
}

impl Source {
    pub fn overlaps(&self, other: &Source) -> bool {
        let (p, q) = (self.pixels, other.pixels);
        self.sha256 == other.sha256 && p[0] < q[2] && q[0] < p[2] && p[1] < q[3] && q[1] < p[3]
    }
}

/// Every pair of `a` and `b` that overlaps.
pub fn overlapping<'a>(a: &'a [Source], b: &'a [Source]) -> Vec<(&'a Source, &'a Source)> {
    a.iter()
        .flat_map(|x| b.iter().filter(|y| x.overlaps(y)).map(move |y| (x, y)))
        .collect()
}
