//! What a dataset folder holds, as detected by [`crate::data::layout`] (`hdrsynth dataset info`).

use crate::data::layout::{self, DatasetInfo, GroundTruthKind, SetInfo};
use crate::error::{Error, Result};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::Path;

/// Sets listed one per line; beyond this only the summary describes the rest.
const MAX_LINES: usize = 50;

/// Dynamic range of a set's ground truth, in stops, or why there is none.
enum Dr {
    Stops(f64),
    NotApplicable(&'static str),
}

impl std::fmt::Display for Dr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Dr::Stops(s) => write!(f, "{s:.1} stops"),
            Dr::NotApplicable(why) => write!(f, "n/a ({why})"),
        }
    }
}

fn set_dr(set: &SetInfo) -> Result<Dr> {
    let Some(gt) = &set.ground_truth else {
        return Ok(Dr::NotApplicable("no GT"));
    };
    if gt.kind == GroundTruthKind::Display {
        return Ok(Dr::NotApplicable("display-referred GT"));
    }
    let img = crate::io::read_image(&gt.path).map_err(Error::within(format!(
        "set {}: reading the ground truth",
        set.name
    )))?;
    Ok(match crate::io::dynamic_range_stops(&img, 0.1, 99.9) {
        Some(s) => Dr::Stops(s),
        None => Dr::NotApplicable("GT has fewer than two positive pixels"),
    })
}

fn fmt_evs(evs: &[f32]) -> String {
    let parts: Vec<String> = evs
        .iter()
        .map(|&e| {
            if e == 0.0 {
                "0".to_string()
            } else if e.fract() == 0.0 {
                format!("{e:+}")
            } else {
                format!("{e:+.2}")
            }
        })
        .collect();
    format!("[{}]", parts.join(", "))
}

fn gt_kind(set: &SetInfo) -> &'static str {
    match set.ground_truth.as_ref().map(|g| g.kind) {
        Some(GroundTruthKind::Linear) => "linear",
        Some(GroundTruthKind::Display) => "display",
        None => "none",
    }
}

/// Human-readable report of the dataset at `dir`: root, layout, sets, skipped folders with
/// reasons, one line per set (at most 50, then a summary of all sets).
pub fn info_report(dir: &Path) -> Result<String> {
    Ok(info_report_verified(dir, false)?.0)
}

/// [`info_report`], and with `verify` every file decoded and checked against its set's size
/// ([`layout::verify`]): the bad files are listed in the report and counted in the second value.
pub fn info_report_verified(dir: &Path, verify: bool) -> Result<(String, usize)> {
    let info = layout::detect(dir).map_err(Error::within(format!(
        "dataset info {}: detecting the layout",
        dir.display()
    )))?;
    if verify {
        let bad = layout::verify(&info);
        let mut out = String::new();
        let files: usize = info.sets.iter().map(|s| layout::set_files(s).len()).sum();
        if bad.is_empty() {
            let _ = writeln!(out, "verify:  every file decodes and has its set's size");
        } else {
            let _ = writeln!(out, "verify:  {} bad file(s):", bad.len());
            for (_, e) in &bad {
                let _ = writeln!(out, "  {e}");
            }
        }
        let _ = writeln!(
            out,
            "         ({files} frame/mask/ground-truth files, plus linear .exr siblings)"
        );
        // The per-set table still needs readable ground truth; report the bad files instead
        // of failing on the first one.
        let drs: Vec<Dr> = info
            .sets
            .iter()
            .map(|s| set_dr(s).unwrap_or(Dr::NotApplicable("unreadable GT")))
            .collect();
        return Ok((format!("{}\n{out}", render(&info, &drs)), bad.len()));
    }
    let drs = info
        .sets
        .par_iter()
        .map(set_dr)
        .collect::<Result<Vec<_>>>()
        .map_err(Error::within(format!("dataset info {}", dir.display())))?;
    Ok((render(&info, &drs), 0))
}

fn render(info: &DatasetInfo, drs: &[Dr]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "root:    {}", info.root.display());
    let _ = writeln!(out, "layout:  {}", info.layout);
    let _ = writeln!(out, "sets:    {}", info.sets.len());
    if info.skipped.is_empty() {
        let _ = writeln!(out, "skipped: none");
    } else {
        let _ = writeln!(out, "skipped: {}", info.skipped.len());
        for (path, reason) in &info.skipped {
            let _ = writeln!(out, "  {}: {reason}", path.display());
        }
    }

    let shown = &info.sets[..info.sets.len().min(MAX_LINES)];
    let rows: Vec<[String; 6]> = shown
        .iter()
        .zip(drs)
        .map(|(s, dr)| {
            [
                s.name.clone(),
                format!("{}×{}", s.width, s.height),
                fmt_evs(&s.evs),
                format!("{}/{}", s.static_frames.len(), s.dynamic_frames.len()),
                gt_kind(s).to_string(),
                dr.to_string(),
            ]
        })
        .collect();
    let header = [
        "set",
        "size",
        "EVs",
        "static/dynamic",
        "GT",
        "GT dynamic range",
    ];
    let mut widths = header.map(|h| h.chars().count());
    for r in &rows {
        for (w, c) in widths.iter_mut().zip(r) {
            *w = (*w).max(c.chars().count());
        }
    }
    let line = |cells: &[String]| {
        let mut l = String::from(" ");
        for (i, (c, w)) in cells.iter().zip(&widths).enumerate() {
            l.push(' ');
            l.push_str(c);
            if i + 1 < cells.len() {
                l.push_str(&" ".repeat(w - c.chars().count() + 1));
            }
        }
        l
    };
    let _ = writeln!(out);
    let _ = writeln!(out, "{}", line(&header.map(String::from)));
    for r in &rows {
        let _ = writeln!(out, "{}", line(r));
    }
    if info.sets.len() > MAX_LINES {
        let _ = writeln!(
            out,
            "  … {} more set(s) not listed",
            info.sets.len() - MAX_LINES
        );
    }

    if info.sets.len() > 1 {
        let _ = writeln!(out);
        let _ = writeln!(out, "summary over all {} sets:", info.sets.len());
        let mut sizes: Vec<(usize, usize)> =
            info.sets.iter().map(|s| (s.width, s.height)).collect();
        sizes.sort_by_key(|&(w, h)| (w * h, w));
        let med = sizes[(sizes.len() - 1) / 2];
        let (lo, hi) = (sizes[0], sizes[sizes.len() - 1]);
        let _ = writeln!(
            out,
            "  size (by pixel count): min {}×{}, median {}×{}, max {}×{}",
            lo.0, lo.1, med.0, med.1, hi.0, hi.1
        );
        let mut stops: Vec<f64> = drs
            .iter()
            .filter_map(|d| match d {
                Dr::Stops(s) => Some(*s),
                Dr::NotApplicable(_) => None,
            })
            .collect();
        if stops.is_empty() {
            let _ = writeln!(out, "  GT dynamic range: n/a (no linear ground truth)");
        } else {
            stops.sort_by(|a, b| a.total_cmp(b));
            let n = stops.len();
            let median = if n.is_multiple_of(2) {
                0.5 * (stops[n / 2 - 1] + stops[n / 2])
            } else {
                stops[n / 2]
            };
            let _ = writeln!(
                out,
                "  GT dynamic range ({n} set(s) with linear GT): min {:.1}, median {median:.1}, max {:.1} stops",
                stops[0],
                stops[n - 1]
            );
        }
    }
    out
}
