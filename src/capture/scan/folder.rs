//! A bracket folder read once for every stage of a run: [`scan`](super::scan) groups the
//! frames (EXIF read), [`select`] takes a stage's sets and region from the grouping.

use super::{BracketScan, ScanOptions, scan};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// The sets of `all` (a grouping of `root`) that `opts` names (every set where it names
/// none), each frame given `opts.region`.
pub(super) fn select(
    root: &Path,
    mut scan: BracketScan,
    opts: &ScanOptions,
) -> Result<BracketScan> {
    if !opts.sets.is_empty() {
        if let Some(n) = opts
            .sets
            .iter()
            .find(|n| !scan.sets.iter().any(|s| &&s.name == n))
        {
            return Err(Error::layout(
                root,
                format!(
                    "no set named '{n}' (sets: {})",
                    scan.sets
                        .iter()
                        .map(|s| s.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        scan.sets.retain(|s| opts.sets.contains(&s.name));
    }
    for s in scan.sets.iter_mut() {
        for f in s.frames.iter_mut().chain(s.repeats.iter_mut()) {
            f.region = opts.region;
        }
    }
    let sizes: Vec<usize> = scan.sets.iter().map(|s| s.frames.len()).collect();
    if sizes.iter().any(|&n| n != sizes[0]) {
        scan.notes.push(format!(
            "{DIFFERING} ({}); check the grouping",
            scan.sets
                .iter()
                .map(|s| format!("{} {}", s.name, s.frames.len()))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    Ok(scan)
}

/// A bracket folder scanned once (file listing, EXIF, grouping into sets); every stage of a
/// run that reads it takes its sets and region from here with [`FolderScan::select`], exactly
/// as [`scan`] with the stage's options would give them.
#[derive(Clone, Debug)]
pub struct FolderScan {
    root: PathBuf,
    /// The options the grouping was made with (every set, no region).
    grouping: ScanOptions,
    all: BracketScan,
}

impl FolderScan {
    /// Scan `root` with `opts`' grouping (its sets and region are left to [`Self::select`]).
    pub fn new(root: &Path, opts: &ScanOptions) -> Result<Self> {
        let grouping = ScanOptions {
            sets: Vec::new(),
            region: None,
            ..opts.clone()
        };
        Ok(FolderScan {
            root: root.to_path_buf(),
            all: scan(root, &grouping)?,
            grouping,
        })
    }

    /// What `scan(root, opts)` gives, without reading the folder again when `opts` groups as
    /// this scan did (the same declared EVs, gap and repeats; otherwise the folder is read).
    pub fn select(&self, opts: &ScanOptions) -> Result<BracketScan> {
        let g = &self.grouping;
        if (&g.evs, g.max_gap_s, g.repeats) != (&opts.evs, opts.max_gap_s, opts.repeats) {
            return scan(&self.root, opts);
        }
        // The grouping's own "differing numbers" note is the selection's to make.
        let mut all = self.all.clone();
        all.notes.retain(|n| !n.starts_with(DIFFERING));
        select(&self.root, all, opts)
    }
}

const DIFFERING: &str = "ambiguous: sets have differing numbers of frames";
