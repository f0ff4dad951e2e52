//! Frames of one folder into sets, and each set's frames in ascending exposure.

use super::{BracketFrame, Frames, SAME_STOP, ScanOptions};
use crate::error::{Error, Result};

/// Split into sets in capture order: a new set where an exposure repeats (unless
/// `opts.repeats`: then repeats stay in the set as repeated captures) or the declared EVs are
/// used up, or, with capture times, where they are more than `max_gap_s` apart. Returns the
/// sets and how many boundaries came from time gaps alone.
pub(super) fn group_sets(
    frames: &Frames,
    order: &[usize],
    stops: &[f64],
    timed: bool,
    opts: &ScanOptions,
) -> (Vec<Vec<usize>>, usize) {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut gaps = 0;
    for &i in order {
        let start_new = match groups.last() {
            None => true,
            Some(g) => {
                let repeat = match &opts.evs {
                    Some(evs) => g.len() == evs.len(),
                    None => {
                        !opts.repeats && g.iter().any(|&j| (stops[j] - stops[i]).abs() < SAME_STOP)
                    }
                };
                let gap = timed && {
                    let prev = frames[*g.last().unwrap_or(&i)].1.captured_s.unwrap_or(0.0);
                    frames[i].1.captured_s.unwrap_or(0.0) - prev > opts.max_gap_s
                };
                if gap && !repeat {
                    gaps += 1;
                }
                repeat || gap
            }
        };
        if start_new {
            groups.push(vec![i]);
        } else if let Some(g) = groups.last_mut() {
            g.push(i);
        }
    }
    (groups, gaps)
}

/// How the folder was grouped, in words (the sets' `grouping`).
pub(super) fn grouping_text(
    n_groups: usize,
    prefix: &str,
    timed: bool,
    opts: &ScanOptions,
) -> String {
    let order_what = if timed {
        "EXIF capture time"
    } else {
        "file name"
    };
    let repeats = if opts.repeats {
        "; frames of one exposure kept as repeated captures"
    } else {
        ""
    };
    if n_groups == 1 {
        if prefix.is_empty() {
            format!("all frames of the folder ({order_what} order){repeats}")
        } else {
            format!("sub-folder {prefix}{repeats}")
        }
    } else {
        let split = match (opts.repeats, timed) {
            (false, true) => format!(
                "where an exposure repeats or capture times are > {} s apart",
                opts.max_gap_s
            ),
            (false, false) => "where an exposure repeats".to_string(),
            (true, _) => format!("where capture times are > {} s apart", opts.max_gap_s),
        };
        format!(
            "{}: in {order_what} order, a new set {split}{repeats}",
            if prefix.is_empty() {
                "the folder".to_string()
            } else {
                format!("sub-folder {prefix}")
            },
        )
    }
}

/// The frames `g` of set `name` (grouped `how`) in ascending stop, and its repeated captures
/// (with `repeats`: later frames of an exposure and ISO already in the set, in capture order);
/// an error for a set of one frame, of mixed EXIF orientations or with a repeated exposure
/// (without `repeats`, or at another ISO).
pub(super) fn set_frames(
    name: &str,
    how: &str,
    g: &[usize],
    frames: &Frames,
    stops: &[f64],
    repeats: bool,
) -> Result<(Vec<BracketFrame>, Vec<BracketFrame>)> {
    if g.len() < 2 {
        return Err(Error::layout(
            &frames[g[0]].0,
            format!(
                "set '{name}' ({how}) holds only this frame; a bracket needs at least two \
                 exposures{}",
                if repeats {
                    " or two captures of one"
                } else {
                    ""
                }
            ),
        ));
    }
    let frame = |i: usize| BracketFrame {
        path: frames[i].0.clone(),
        kind: frames[i].2,
        exif: frames[i].1.clone(),
        stop: stops[i],
        region: None,
    };
    let (mut set_frames, mut repeated): (Vec<BracketFrame>, Vec<BracketFrame>) =
        (Vec::new(), Vec::new());
    for &i in g {
        let f = frame(i);
        let same = set_frames
            .iter()
            .find(|s| (s.stop - f.stop).abs() < SAME_STOP);
        match same {
            None => set_frames.push(f),
            Some(s) if repeats && s.exif.iso == f.exif.iso => repeated.push(f),
            Some(s) => {
                let why = if repeats {
                    format!(
                        "ISO {:?} against {:?}; repeated captures must share their ISO",
                        f.exif.iso, s.exif.iso
                    )
                } else {
                    "a bracket needs distinct exposures (--repeats keeps repeated captures \
                     of one exposure)"
                        .to_string()
                };
                return Err(Error::layout(
                    &f.path,
                    format!(
                        "set '{name}': same exposure as {} (stop {:.3}): {why}",
                        s.path.display(),
                        s.stop
                    ),
                ));
            }
        }
    }
    set_frames.sort_by(|a, b| a.stop.total_cmp(&b.stop));
    let orient_of = |f: &BracketFrame| f.exif.orientation.unwrap_or(1);
    if set_frames
        .iter()
        .chain(&repeated)
        .any(|f| orient_of(f) != orient_of(&set_frames[0]))
    {
        return Err(Error::layout(
            &set_frames[0].path,
            format!(
                "set '{name}': its frames have different EXIF orientations ({}); the frames \
                 of one bracket must be captured in one orientation",
                set_frames
                    .iter()
                    .chain(&repeated)
                    .map(|f| format!("{} {}", f.path.display(), orient_of(f)))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    Ok((set_frames, repeated))
}
