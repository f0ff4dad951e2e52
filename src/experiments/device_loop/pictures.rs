//! Per test scene, one strip of aligned crops a user can judge by eye: the reference frame as
//! the device wrote it, the triangle merge, Net_O, every step's network (the first seed) and
//! the ground truth, the HDR ones tone-mapped alike (μ-law, the metric's T). The crop is the
//! window of the ground truth with the widest range.

use crate::data::layout;
use crate::error::{Error, Result};
use crate::eval::evaluate::Scoring;
use crate::eval::report::{Cell, grid};
use crate::experiments::ablate::AblateConfig;
use crate::io::{BitDepth, Image, read_image, write_ldr};
use std::path::{Path, PathBuf};

/// Side of the crop (pixels; smaller frames give their shorter side).
pub(super) const CROP: usize = 192;
/// Cells per row of a strip.
const PER_ROW: usize = 5;

/// The top-left corner of the `side`×`side` window of `gt` whose luminance spans the most
/// stops between its 2nd and 98th percentiles (every 4th pixel, windows every side/4).
pub fn widest_range_window(gt: &Image, side: usize) -> (usize, usize) {
    let lum = |x: usize, y: usize| {
        let p = gt.get(x, y);
        (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
            .max(1e-6)
            .log2()
    };
    let step = (side / 4).max(1);
    let positions = |n: usize| (0..=n - side).step_by(step).chain([n - side]);
    let mut best = (f32::NEG_INFINITY, (0, 0));
    for y0 in positions(gt.height) {
        for x0 in positions(gt.width) {
            let mut v: Vec<f32> = (y0..y0 + side)
                .step_by(4)
                .flat_map(|y| (x0..x0 + side).step_by(4).map(move |x| (x, y)))
                .map(|(x, y)| lum(x, y))
                .collect();
            v.sort_by(f32::total_cmp);
            let q = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
            let span = q(0.98) - q(0.02);
            if span > best.0 {
                best = (span, (x0, y0));
            }
        }
    }
    best.1
}

fn crop(img: &Image, (x0, y0): (usize, usize), side: usize) -> Image {
    let mut out = Image::new(side, side);
    for y in 0..side {
        for x in 0..side {
            out.set(x, y, img.get(x0 + x, y0 + y));
        }
    }
    out
}

/// Write `out/<set>.png` for every set of `testset` from the rows `rows` (label, row name) of
/// `cfg`'s grid; returns (set, file) per picture written. A row not finished for a set is
/// left out of its strip.
pub fn write(
    cfg: &AblateConfig,
    testset: &Path,
    rows: &[(String, &str)],
    out: &Path,
) -> Result<Vec<(String, PathBuf)>> {
    let info = layout::detect(testset)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let display = |img: &Image| img.map(|v| Scoring::Hdr.display(v));
    let mut written = Vec::new();
    for set in &info.sets {
        let gt = layout::read_linear_ground_truth(set)?;
        let side = CROP.min(gt.width).min(gt.height);
        let at = widest_range_window(&gt, side);
        let mut cells = Vec::new();
        if let Some(path) = set.reference_frame() {
            cells.push(Cell {
                label: "reference frame".into(),
                image: crop(&layout::read_set_image(set, path)?, at, side),
            });
        }
        for (label, name) in rows {
            let Some(r) = cfg.rows.iter().position(|row| row.name == *name) else {
                continue;
            };
            let seed = cfg.cell_seeds(r, None).first().copied().flatten();
            let exr = cfg
                .eval_dir(r, None, seed)
                .join(format!("{}.exr", set.name));
            if !exr.is_file() {
                continue;
            }
            let img = read_image(&exr)?;
            layout::check_size(&exr, img.width, img.height, set.width, set.height)?;
            cells.push(Cell {
                label: label.clone(),
                image: crop(&display(&img), at, side),
            });
        }
        cells.push(Cell {
            label: "ground truth".into(),
            image: crop(&display(&gt), at, side),
        });
        let mut rows_of_cells = Vec::new();
        let mut it = cells.into_iter().peekable();
        while it.peek().is_some() {
            rows_of_cells.push(it.by_ref().take(PER_ROW).collect::<Vec<_>>());
        }
        let path = out.join(format!("{}.png", set.name));
        write_ldr(&path, &grid(&rows_of_cells)?, BitDepth::Eight)?;
        written.push((set.name.clone(), path));
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_window_of_widest_range_holds_the_darkest_and_brightest_patches() {
        // Flat grey everywhere but a 16×16 patch at (70, 40): its left half 1e-3, right half 10.
        let mut gt = Image::new(128, 96);
        let patch = |x: usize, y: usize| (70..86).contains(&x) && (40..56).contains(&y);
        for y in 0..96 {
            for x in 0..128 {
                let v = match (patch(x, y), x < 78) {
                    (true, true) => 1e-3,
                    (true, false) => 10.0,
                    _ => 0.18,
                };
                gt.set(x, y, [v; 3]);
            }
        }
        let (x0, y0) = widest_range_window(&gt, 32);
        let inside = |dark: bool| {
            (y0..y0 + 32)
                .flat_map(|y| (x0..x0 + 32).map(move |x| (x, y)))
                .filter(|&(x, y)| patch(x, y) && (x < 78) == dark)
                .count()
        };
        // Both halves, each more than 2 % of the window (the percentiles' reach).
        assert!(inside(true) > 32 && inside(false) > 32, "({x0}, {y0})");
        // A window of grey alone, or of one half, would have a smaller range.
        assert_ne!((x0, y0), (0, 0));
    }
}
