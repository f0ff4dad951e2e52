//! What realism buys against how good the network is: the plot of a quality-against-compute
//! sweep's table (`sweep.csv`, written by tools/sweep.py; docs/experiments.md, "the sweep").
//!
//! Per sweep point and test set, x is Net_S − the triangle merge of its inputs (how close the
//! network is to, or how far past, the classical merge) and y is Net_S − Net_R (what the
//! device's colour and noise add to the same training), with its 95 % interval as a bar.

use crate::error::{Error, Result};
use crate::io::{BitDepth, Image, write_ldr};
use crate::plot::{Scatter, ScatterPoint};
use serde::Deserialize;
use std::path::Path;

/// One line of `sweep.csv` (the columns the plot reads; the others are ignored).
#[derive(Debug, Clone, Deserialize)]
pub struct SweepRow {
    pub width: usize,
    pub steps_factor: usize,
    pub static_fraction: f64,
    pub moving_training: String,
    pub head: String,
    #[serde(default = "triangle")]
    pub prior: String,
    #[serde(default = "pixels")]
    pub loss: String,
    pub testset: String,
    pub metric: String,
    #[serde(rename = "net_s-triangle")]
    pub net_s_triangle: f64,
    #[serde(rename = "net_s-net_r")]
    pub net_s_net_r: f64,
    /// "[lo, hi]", as tools/sweep.py writes it.
    #[serde(rename = "net_s-net_r_ci")]
    pub net_s_net_r_ci: String,
}

fn triangle() -> String {
    "triangle".to_string()
}

fn pixels() -> String {
    "pixels".to_string()
}

impl SweepRow {
    /// The point's name as tools/sweep.py spells it: `8x4h` (width 8, 4× the steps, half the
    /// samples still), suffixes m/h/q (moving training; half, three quarters still), k (kernel
    /// head), r (Robertson's prior), p (the PSNR-averaged loss).
    pub fn point(&self) -> String {
        let share = if self.static_fraction >= 0.7 {
            "q"
        } else if self.static_fraction > 0.0 {
            "h"
        } else if self.moving_training.eq_ignore_ascii_case("true") {
            "m"
        } else {
            ""
        };
        let head = if self.head == "kernel" { "k" } else { "" };
        let prior = if self.prior == "robertson" { "r" } else { "" };
        let loss = if self.loss == "psnr" { "p" } else { "" };
        format!(
            "{}x{}{share}{head}{prior}{loss}",
            self.width, self.steps_factor
        )
    }
}

/// Read `sweep.csv`; a missing column or a malformed interval names the file and the line.
pub fn read_sweep(path: &Path) -> Result<Vec<SweepRow>> {
    let mut reader = csv::Reader::from_path(path).map_err(|e| Error::decode(path, e))?;
    let mut rows = Vec::new();
    for (k, rec) in reader.deserialize::<SweepRow>().enumerate() {
        let row = rec.map_err(|e| Error::decode(path, format!("line {}: {e}", k + 2)))?;
        interval(&row.net_s_net_r_ci).ok_or_else(|| {
            Error::decode(
                path,
                format!(
                    "line {}: net_s-net_r_ci {:?} is not \"[lo, hi]\"",
                    k + 2,
                    row.net_s_net_r_ci
                ),
            )
        })?;
        rows.push(row);
    }
    if rows.is_empty() {
        return Err(Error::decode(path, "no rows"));
    }
    Ok(rows)
}

/// "[-0.05, +0.09]" → (−0.05, 0.09).
fn interval(s: &str) -> Option<(f64, f64)> {
    let inner = s.trim().strip_prefix('[')?.strip_suffix(']')?;
    let (lo, hi) = inner.split_once(',')?;
    Some((lo.trim().parse().ok()?, hi.trim().parse().ok()?))
}

/// The test sets drawn, in the legend's order: the validation sets (which choose between
/// points), then the main job's test sets.
pub const PLOTTED_SETS: [&str; 4] = ["val_static", "val_dynamic", "primary", "dynamic"];

/// The realism-against-quality plot of `rows` (PSNR-T rows of [`PLOTTED_SETS`]).
pub fn realism_plot(rows: &[SweepRow]) -> Image {
    let mut points = Vec::new();
    for (series, set) in PLOTTED_SETS.iter().enumerate() {
        for r in rows
            .iter()
            .filter(|r| r.metric == "psnr_t" && r.testset == *set)
        {
            let (lo, hi) = interval(&r.net_s_net_r_ci).unwrap_or((r.net_s_net_r, r.net_s_net_r));
            points.push(ScatterPoint {
                x: r.net_s_triangle,
                y: r.net_s_net_r,
                y_range: (lo, hi),
                series,
                label: r.point(),
            });
        }
    }
    Scatter {
        title: "Net_S - Net_R (realism's gain) vs Net_S - triangle merge [dB PSNR-T]; bars 95 % t",
        x_label: "Net_S - triangle merge [dB]",
        series: &PLOTTED_SETS,
    }
    .render(&points)
}

/// Read `sweep` and write its [`realism_plot`] to `out` (PNG, atomically).
pub fn write_realism_plot(sweep: &Path, out: &Path) -> Result<()> {
    write_ldr(out, &realism_plot(&read_sweep(sweep)?), BitDepth::Eight)
}
