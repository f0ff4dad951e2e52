//! What `hdrsynth eval` writes besides the images: per-image and summary tables (CSV and
//! Markdown), the Markdown report, and the per-set image grid (docs/evaluation.md).

use crate::error::{Error, Result};
use crate::eval::metrics::Scores;
use crate::io::Image;
use crate::io::atomic::write_atomic;
use crate::plot::Canvas;
use crate::stats::bootstrap_ci;
use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::mono_font::iso_8859_1::FONT_7X13;
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::*;
use embedded_graphics::text::Text;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// The six metrics every set has, in table order, as the CSV columns name them: the first
/// columns of `per_image.csv` after `set`.
pub const METRICS: [&str; 6] = [
    "psnr_l",
    "psnr_t",
    "ssim_l",
    "ssim_t",
    "pu21_psnr",
    "pu21_ssim",
];

pub fn metric_values(s: &Scores) -> [f64; 6] {
    [
        s.psnr_l,
        s.psnr_t,
        s.ssim_l,
        s.ssim_t,
        s.pu21_psnr,
        s.pu21_ssim,
    ]
}

/// Columns appended to `per_image.csv` after `seconds` (so the columns before them keep their
/// positions): ΔE2000 of T (lower is better), PSNR-T over the under-exposed pixels (empty when
/// absent) and the fraction of pixels in that mask (empty without a reference frame), PSNR-T
/// over the moving pixels and their fraction (empty for a set without motion masks).
pub const APPENDED: [&str; 5] = [
    "delta_e2000",
    "psnr_t_dark",
    "dark_fraction",
    "psnr_t_moving",
    "moving_fraction",
];

pub fn appended_values(s: &Scores) -> [Option<f64>; 5] {
    [
        Some(s.delta_e2000),
        s.psnr_t_dark,
        s.dark_fraction,
        s.psnr_t_moving,
        s.moving_fraction,
    ]
}

/// Metrics of the summary, in its order: [`METRICS`], then ΔE2000, PSNR-T dark and PSNR-T
/// moving.
pub const SUMMARY_METRICS: [&str; 9] = [
    "psnr_l",
    "psnr_t",
    "ssim_l",
    "ssim_t",
    "pu21_psnr",
    "pu21_ssim",
    "delta_e2000",
    "psnr_t_dark",
    "psnr_t_moving",
];

/// A set's values of [`SUMMARY_METRICS`]; None where the metric is absent for the set.
pub fn summary_values(s: &Scores) -> [Option<f64>; 9] {
    let m = metric_values(s).map(Some);
    [
        m[0],
        m[1],
        m[2],
        m[3],
        m[4],
        m[5],
        Some(s.delta_e2000),
        s.psnr_t_dark,
        s.psnr_t_moving,
    ]
}

/// One evaluated set (a row of `per_image.csv`).
#[derive(Clone, Debug, PartialEq)]
pub struct SetScore {
    pub set: String,
    pub scores: Scores,
    pub width: usize,
    pub height: usize,
    /// Producing the output (reading it, or running the network) and scoring it.
    pub seconds: f64,
}

/// Mean and bootstrap interval of one metric over the test set's scenes.
#[derive(Clone, Debug, PartialEq)]
pub struct MetricSummary {
    pub metric: &'static str,
    /// Sets with a value of the metric.
    pub n: usize,
    /// Sets scored without a value of the metric (PSNR-T dark where too few pixels are dark).
    pub n_absent: usize,
    /// Sets whose value is +inf (identical images: PSNR with MSE 0), left out of mean and CI.
    pub n_inf: usize,
    /// Scenes behind the mean and CI (the bootstrap's unit).
    pub n_scenes: usize,
    pub mean: f64,
    pub lo: f64,
    pub hi: f64,
}

/// Per metric: the mean over scenes of each scene's mean over its sets' finite values, and the
/// percentile bootstrap CI resampling scenes (a scene's sets at several ISOs share content and
/// difficulty: one cluster, as in `hdrsynth ablate`). `scenes` maps a set to its scene
/// (`testset::scenes_of_sets`); a set not in it is its own scene. +inf values are counted and
/// left out; sets without a value (None) are counted as absent and left out. All +inf gives
/// mean = lo = hi = +inf; no values gives NaNs.
pub fn summarise(
    rows: &[SetScore],
    scenes: &BTreeMap<String, String>,
    resamples: usize,
    seed: u64,
    level: f64,
) -> Vec<MetricSummary> {
    SUMMARY_METRICS
        .iter()
        .enumerate()
        .map(|(k, &metric)| {
            let all: Vec<(&SetScore, f64)> = rows
                .iter()
                .filter_map(|r| summary_values(&r.scores)[k].map(|v| (r, v)))
                .collect();
            let n_inf = all.iter().filter(|(_, v)| *v == f64::INFINITY).count();
            let mut by_scene: BTreeMap<&str, (f64, usize)> = BTreeMap::new();
            for &(r, v) in &all {
                if v.is_finite() {
                    let scene = scenes.get(&r.set).map_or(r.set.as_str(), String::as_str);
                    let e = by_scene.entry(scene).or_insert((0.0, 0));
                    e.0 += v;
                    e.1 += 1;
                }
            }
            let scene_means: Vec<f64> = by_scene.values().map(|(s, n)| s / *n as f64).collect();
            let (mean, lo, hi) = if scene_means.is_empty() && n_inf > 0 {
                (f64::INFINITY, f64::INFINITY, f64::INFINITY)
            } else {
                bootstrap_ci(&scene_means, resamples, seed, level)
            };
            MetricSummary {
                metric,
                n: all.len(),
                n_absent: rows.len() - all.len(),
                n_inf,
                n_scenes: scene_means.len(),
                mean,
                lo,
                hi,
            }
        })
        .collect()
}

/// A CSV field, quoted when it holds a comma, quote or line break.
pub fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// `per_image.csv`: set, the six [`METRICS`] (shortest round-trip decimals; `inf` for +inf),
/// width, height, seconds, then the [`APPENDED`] columns (empty where absent).
pub fn per_image_csv(rows: &[SetScore]) -> String {
    let mut w = csv::Writer::from_writer(Vec::new());
    let header = ["set"]
        .into_iter()
        .chain(METRICS)
        .chain(["width", "height", "seconds"])
        .chain(APPENDED);
    // Writing into a Vec cannot fail.
    let _ = w.write_record(header);
    for r in rows {
        let fields = [r.set.clone()]
            .into_iter()
            .chain(metric_values(&r.scores).map(|x| x.to_string()))
            .chain([
                r.width.to_string(),
                r.height.to_string(),
                format!("{:.3}", r.seconds),
            ])
            .chain(appended_values(&r.scores).map(|x| x.map_or(String::new(), |x| x.to_string())));
        let _ = w.write_record(fields);
    }
    String::from_utf8(w.into_inner().unwrap_or_default()).unwrap_or_default()
}

/// A row of `per_image.csv` read back (a finished evaluation on disk), columns by header name:
/// the appended metrics are `None` where the field is empty or the file lacks the column.
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub struct PerImageRow {
    pub set: String,
    pub psnr_l: f64,
    pub psnr_t: f64,
    pub ssim_l: f64,
    pub ssim_t: f64,
    pub pu21_psnr: f64,
    pub pu21_ssim: f64,
    #[serde(default)]
    pub delta_e2000: Option<f64>,
    #[serde(default)]
    pub psnr_t_dark: Option<f64>,
    #[serde(default)]
    pub psnr_t_moving: Option<f64>,
}

impl PerImageRow {
    /// The row's values of [`SUMMARY_METRICS`], as [`summary_values`] gives them for scores.
    pub fn summary_values(&self) -> [Option<f64>; 9] {
        [
            Some(self.psnr_l),
            Some(self.psnr_t),
            Some(self.ssim_l),
            Some(self.ssim_t),
            Some(self.pu21_psnr),
            Some(self.pu21_ssim),
            self.delta_e2000,
            self.psnr_t_dark,
            self.psnr_t_moving,
        ]
    }
}

/// The rows of a `per_image.csv`; an error names the file and the line.
pub fn read_per_image(path: &Path) -> Result<Vec<PerImageRow>> {
    read_rows(path)
}

/// (metric, mean) of each row of a `summary.csv`; an error names the file and the line.
pub fn read_summary_means(path: &Path) -> Result<Vec<(String, f64)>> {
    #[derive(serde::Deserialize)]
    struct Row {
        metric: String,
        mean: f64,
    }
    let rows: Vec<Row> = read_rows(path)?;
    Ok(rows.into_iter().map(|r| (r.metric, r.mean)).collect())
}

fn read_rows<T: serde::de::DeserializeOwned>(path: &Path) -> Result<Vec<T>> {
    let text = crate::io::guard::read_text(path)?;
    csv::Reader::from_reader(text.as_bytes())
        .deserialize()
        .map(|row| {
            row.map_err(|e| {
                let m = match e.position() {
                    Some(p) => format!("line {}: {e}", p.line()),
                    None => e.to_string(),
                };
                Error::layout(path, m)
            })
        })
        .collect()
}

/// `summary.csv`: metric, n, n_inf, mean, ci_lo, ci_hi, n_scenes, n_absent.
pub fn summary_csv(summary: &[MetricSummary]) -> String {
    let mut out = String::from("metric,n,n_inf,mean,ci_lo,ci_hi,n_scenes,n_absent\n");
    for m in summary {
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{}",
            m.metric, m.n, m.n_inf, m.mean, m.lo, m.hi, m.n_scenes, m.n_absent
        );
    }
    out
}

fn fmt_value(metric: &str, v: f64) -> String {
    if v.is_infinite() || v.is_nan() {
        format!("{v}")
    } else if metric.contains("ssim") || metric.ends_with("_fraction") {
        format!("{v:.4}")
    } else {
        format!("{v:.2}")
    }
}

/// How a metric is named in Markdown tables: ΔE2000 says that lower is better.
fn md_name(metric: &str) -> String {
    match metric {
        "delta_e2000" => "delta_e2000 (lower is better)".into(),
        m => m.into(),
    }
}

/// Markdown table of the summary.
pub fn summary_table(summary: &[MetricSummary], level: f64) -> String {
    let mut out = format!(
        "| metric | mean | {:.0} % CI | n | scenes | +inf (excluded) | no value |\n\
         |---|---|---|---|---|---|---|\n",
        level * 100.0
    );
    for m in summary {
        let _ = writeln!(
            out,
            "| {} | {} | [{}, {}] | {} | {} | {} | {} |",
            md_name(m.metric),
            fmt_value(m.metric, m.mean),
            fmt_value(m.metric, m.lo),
            fmt_value(m.metric, m.hi),
            m.n,
            m.n_scenes,
            m.n_inf,
            m.n_absent
        );
    }
    out
}

/// One row of a per-set Markdown table: [`METRICS`] then [`APPENDED`] ("–" where absent).
pub fn scores_row(s: &Scores) -> String {
    let metrics = METRICS
        .iter()
        .zip(metric_values(s))
        .map(|(m, x)| fmt_value(m, x));
    let appended = APPENDED
        .iter()
        .zip(appended_values(s))
        .map(|(m, x)| x.map_or("–".to_string(), |x| fmt_value(m, x)));
    let cells: Vec<String> = metrics.chain(appended).collect();
    format!("| {} |", cells.join(" | "))
}

pub fn scores_header() -> String {
    let names: Vec<String> = METRICS
        .iter()
        .chain(&APPENDED)
        .map(|m| md_name(m))
        .collect();
    format!(
        "| {} |\n|{}\n",
        names.join(" | "),
        "---|".repeat(names.len())
    )
}

pub fn write_text(path: &Path, text: &str) -> Result<()> {
    write_atomic(path, text.as_bytes())
}

// ---------------------------------------------------------------------------------------------
// Image grid

/// Full scale of the error map: mean |display(output) − display(reference)| over RGB at or
/// above this is white.
pub const ERROR_FULL_SCALE: f32 = 0.2;

/// "Hot" colour ramp of an error in [0, ERROR_FULL_SCALE]: black → red → yellow → white.
pub fn hot(e: f32) -> [f32; 3] {
    let t = (e / ERROR_FULL_SCALE).clamp(0.0, 1.0) * 3.0;
    [
        t.min(1.0),
        (t - 1.0).clamp(0.0, 1.0),
        (t - 2.0).clamp(0.0, 1.0),
    ]
}

/// Thumbnail size of a w×h image that fits in `max`×`max` (never enlarged).
pub fn thumb_size(w: usize, h: usize, max: usize) -> (usize, usize) {
    let s = (max as f64 / w as f64).min(max as f64 / h as f64).min(1.0);
    (
        ((w as f64 * s).round() as usize).max(1),
        ((h as f64 * s).round() as usize).max(1),
    )
}

/// A labelled picture of the grid.
pub struct Cell {
    pub label: String,
    pub image: Image,
}

const LABEL_H: usize = 18;
const GAP: usize = 6;

/// Rows of labelled thumbnails on white, each cell as wide as the widest thumbnail.
pub fn grid(rows: &[Vec<Cell>]) -> Result<Image> {
    let cols = rows.iter().map(Vec::len).max().unwrap_or(0);
    if cols == 0 {
        return Err(Error::Invalid("grid: no cells".into()));
    }
    let cw = rows
        .iter()
        .flatten()
        .map(|c| c.image.width)
        .max()
        .unwrap_or(1);
    let row_h: Vec<usize> = rows
        .iter()
        .map(|r| r.iter().map(|c| c.image.height).max().unwrap_or(0) + LABEL_H)
        .collect();
    let w = cols * (cw + GAP) + GAP;
    let h = row_h.iter().map(|r| r + GAP).sum::<usize>() + GAP;
    let mut canvas = Canvas::new(w, h);
    let ink = MonoTextStyle::new(&FONT_7X13, Rgb888::new(20, 20, 20));
    let mut y0 = GAP;
    for (r, row) in rows.iter().enumerate() {
        for (c, cell) in row.iter().enumerate() {
            let x0 = GAP + c * (cw + GAP);
            // Labels longer than the cell are cut, not wrapped: the report has the full names.
            let max_chars = cw / 7;
            let label: String = cell.label.chars().take(max_chars).collect();
            let _ = Text::new(
                &label,
                Point::new(x0 as i32, (y0 + LABEL_H - 6) as i32),
                ink,
            )
            .draw(&mut canvas);
        }
        y0 += row_h[r] + GAP;
    }
    let mut img = canvas.into_image();
    let mut y0 = GAP;
    for (r, row) in rows.iter().enumerate() {
        for (c, cell) in row.iter().enumerate() {
            let x0 = GAP + c * (cw + GAP);
            for y in 0..cell.image.height {
                for x in 0..cell.image.width {
                    let v = cell.image.get(x, y).map(|v| v.clamp(0.0, 1.0));
                    img.set(x0 + x, y0 + LABEL_H + y, v);
                }
            }
        }
        y0 += row_h[r] + GAP;
    }
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(set: &str, v: f64) -> SetScore {
        SetScore {
            set: set.into(),
            scores: Scores {
                psnr_l: v,
                psnr_t: v,
                ssim_l: v,
                ssim_t: v,
                pu21_psnr: v,
                pu21_ssim: v,
                delta_e2000: v,
                psnr_t_dark: Some(v),
                dark_fraction: Some(0.5),
                psnr_t_moving: None,
                moving_fraction: None,
            },
            width: 1,
            height: 1,
            seconds: 0.0,
        }
    }

    /// Two sets of scene A (10, 20) and one of scene B (40): the mean is over scenes,
    /// (15 + 40) / 2 = 27.5, not over sets (23.33), and every resample is a mean of {15, 40}.
    #[test]
    fn the_summary_averages_and_resamples_scenes_not_sets() {
        // Every metric present, PSNR-T over moving pixels included (a dynamic set's rows).
        let rows = [("A_iso100", 10.0), ("A_iso800", 20.0), ("B_iso100", 40.0)].map(|(s, v)| {
            let mut r = row(s, v);
            r.scores.psnr_t_moving = Some(v);
            r.scores.moving_fraction = Some(0.5);
            r
        });
        let scenes: BTreeMap<String, String> =
            [("A_iso100", "A"), ("A_iso800", "A"), ("B_iso100", "B")]
                .into_iter()
                .map(|(a, b)| (a.to_string(), b.to_string()))
                .collect();
        for m in summarise(&rows, &scenes, 500, 0, 0.95) {
            assert_eq!(
                (m.n, m.n_scenes, m.n_inf, m.n_absent),
                (3, 2, 0, 0),
                "{}",
                m.metric
            );
            assert!((m.mean - 27.5).abs() < 1e-12, "{}: {}", m.metric, m.mean);
            assert!(m.lo >= 15.0 && m.hi <= 40.0 && m.lo < m.hi, "{m:?}");
        }
        // summary.csv carries n_scenes, then n_absent, in its last columns.
        let csv = summary_csv(&summarise(&rows, &scenes, 500, 0, 0.95));
        let psnr_t = csv
            .lines()
            .find(|l| l.starts_with("psnr_t,"))
            .expect("psnr_t");
        assert_eq!(psnr_t.split(',').count(), 8, "{psnr_t}");
        assert!(psnr_t.ends_with(",2,0"), "{psnr_t}");
        // Without a scene map every set is its own scene: the plain mean over sets.
        let m = &summarise(&rows, &BTreeMap::new(), 500, 0, 0.95)[0];
        assert_eq!(m.n_scenes, 3);
        assert!((m.mean - 70.0 / 3.0).abs() < 1e-12);
    }

    /// A set without PSNR-T dark is absent from that metric's mean and counted, and its
    /// per_image.csv field is empty; the other metrics keep all three sets.
    #[test]
    fn absent_values_are_left_out_and_counted() {
        let mut rows = vec![
            row("A_iso100", 10.0),
            row("B_iso100", 20.0),
            row("C_iso100", 40.0),
        ];
        rows[2].scores.psnr_t_dark = None;
        rows[2].scores.dark_fraction = Some(0.004);
        let s = summarise(&rows, &BTreeMap::new(), 500, 0, 0.95);
        let dark = s.iter().find(|m| m.metric == "psnr_t_dark").expect("dark");
        assert_eq!((dark.n, dark.n_absent, dark.n_scenes), (2, 1, 2));
        assert!((dark.mean - 15.0).abs() < 1e-12, "{dark:?}");
        let de = s.iter().find(|m| m.metric == "delta_e2000").expect("de");
        assert_eq!((de.n, de.n_absent), (3, 0));
        assert!((de.mean - 70.0 / 3.0).abs() < 1e-12, "{de:?}");
        let csv = per_image_csv(&rows);
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().expect("header").split(',').collect();
        assert_eq!(
            header[7..],
            [
                "width",
                "height",
                "seconds",
                "delta_e2000",
                "psnr_t_dark",
                "dark_fraction",
                "psnr_t_moving",
                "moving_fraction"
            ]
        );
        let last: Vec<&str> = lines.next_back().expect("row").split(',').collect();
        assert_eq!(last[10..], ["40", "", "0.004", "", ""]);
        // All absent: NaN mean, every set counted as absent.
        for r in &mut rows {
            r.scores.psnr_t_dark = None;
        }
        let s = summarise(&rows, &BTreeMap::new(), 500, 0, 0.95);
        let dark = s.iter().find(|m| m.metric == "psnr_t_dark").expect("dark");
        assert_eq!((dark.n, dark.n_absent, dark.n_scenes), (0, 3, 0));
        assert!(dark.mean.is_nan());
    }
}
