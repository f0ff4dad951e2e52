//! The blend-class ground truth of Network-1 for every set of a dataset, and the dataset's
//! class weights (`hdrsynth dataset weights`; the per-image steps are crate::data::ground_truth).
//!
//! Per set: the static (motion-free) display frames of the pair (EV−3, EV0) — or, where a set
//! has no EV−3 frame, its lowest EV and its reference — give the per-pixel Mertens weight of
//! the long exposure, quantised to 256 classes and written as `<set>/blend_classes.png`. Over
//! all sets: the class histogram and inverse-frequency weights α, written atomically to
//! `DIR/class_weights.toml`; optionally a bar chart of frequencies and α (log y) as PNG.

use crate::data::ground_truth::{
    self, CLASS_MAP_FILE, CLASS_WEIGHTS_FILE, CLASSES, ClassWeights, MertensWeights,
};
use crate::data::layout::{self, SetInfo};
use crate::error::{Error, Result};
use crate::io::{BitDepth, Image, write_ldr};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The short exposure the paper pairs with the reference (EV0).
pub const PAPER_LOW_EV: f32 = -3.0;

/// What `dataset weights` does: the dataset, the optional plot and Mertens' exponents.
#[derive(Clone, Debug)]
pub struct ClassMapOptions {
    pub dir: PathBuf,
    pub plot: Option<PathBuf>,
    pub mertens: MertensWeights,
}

impl ClassMapOptions {
    /// Options with the OpenCV default exponents.
    pub fn new(dir: impl Into<PathBuf>, plot: Option<PathBuf>) -> ClassMapOptions {
        ClassMapOptions {
            dir: dir.into(),
            plot,
            mertens: MertensWeights::OPENCV_DEFAULT,
        }
    }
}

struct SetResult {
    hist: [u64; CLASSES],
    pair: (f32, f32),
}

fn process_set(set: &SetInfo, w: MertensWeights) -> Result<SetResult> {
    if set.static_frames.is_empty() {
        return Err(Error::layout(
            &set.dir,
            format!(
                "set {}: no static (motion-free) frames; blend classes need aligned frames",
                set.name
            ),
        ));
    }
    let (lo, hi) = set.network1_pair()?;
    let frame = |i: usize| -> Result<Image> {
        let p = set.static_frames.get(i).ok_or_else(|| {
            Error::layout(
                &set.dir,
                format!(
                    "set {}: {} static frames for {} EVs",
                    set.name,
                    set.static_frames.len(),
                    set.evs.len()
                ),
            )
        })?;
        crate::data::layout::read_set_image(set, p)
    };
    let (low, high) = (frame(lo)?, frame(hi)?);
    let weights = ground_truth::blend_weights_high_with(&low, &high, w)?;
    let classes = ground_truth::classes_from_weights(&weights);
    ground_truth::write_class_map(
        &set.dir.join(CLASS_MAP_FILE),
        &classes,
        low.width,
        low.height,
    )?;
    Ok(SetResult {
        hist: ground_truth::class_histogram([&classes]),
        pair: (set.evs[lo], set.evs[hi]),
    })
}

/// Class maps for every set, `DIR/class_weights.toml`, the optional plot; returns the summary
/// to print.
pub fn write_class_maps(args: &ClassMapOptions) -> Result<String> {
    let dir = &args.dir;
    let info = layout::detect(dir).map_err(Error::within(format!(
        "dataset weights {}: detecting the layout",
        dir.display()
    )))?;
    let w = args.mertens;
    let bar = ProgressBar::new(info.sets.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} sets")
            .expect("static template"),
    );
    let results = info
        .sets
        .par_iter()
        .map(|s| {
            let r = process_set(s, w).map_err(Error::within(format!("set {}", s.name)));
            bar.inc(1);
            r
        })
        .collect::<Result<Vec<_>>>()
        .map_err(Error::within(format!("dataset weights {}", dir.display())))?;
    bar.finish_and_clear();

    let mut hist = [0u64; CLASSES];
    for r in &results {
        for (h, c) in hist.iter_mut().zip(&r.hist) {
            *h += c;
        }
    }
    let cw = ClassWeights::new(&hist, w, results.len());
    let weights_path = dir.join(CLASS_WEIGHTS_FILE);
    cw.save(&weights_path)
        .map_err(Error::within(format!("dataset weights {}", dir.display())))?;
    if let Some(p) = &args.plot {
        write_plot(p, &cw).map_err(Error::within(format!(
            "dataset weights: plot {}",
            p.display()
        )))?;
    }

    let mut pairs: Vec<(f32, f32, usize)> = Vec::new();
    for r in &results {
        match pairs.iter_mut().find(|p| (p.0, p.1) == r.pair) {
            Some(p) => p.2 += 1,
            None => pairs.push((r.pair.0, r.pair.1, 1)),
        }
    }
    Ok(summary(
        &info.root,
        &info.skipped,
        &cw,
        &pairs,
        &weights_path,
        args.plot.as_deref(),
    ))
}

/// "3, 10-12, 200-255" for sorted class indices.
fn ranges(v: &[usize]) -> String {
    let mut parts = Vec::new();
    let mut i = 0;
    while i < v.len() {
        let mut j = i;
        while j + 1 < v.len() && v[j + 1] == v[j] + 1 {
            j += 1;
        }
        parts.push(if i == j {
            v[i].to_string()
        } else {
            format!("{}-{}", v[i], v[j])
        });
        i = j + 1;
    }
    parts.join(", ")
}

fn summary(
    root: &Path,
    skipped: &[(PathBuf, String)],
    cw: &ClassWeights,
    pairs: &[(f32, f32, usize)],
    weights_path: &Path,
    plot: Option<&Path>,
) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "dataset:   {}", root.display());
    let _ = writeln!(
        out,
        "sets:      {} (class map {CLASS_MAP_FILE} in each){}",
        cw.sets,
        if skipped.is_empty() {
            String::new()
        } else {
            format!("; {} folder(s) skipped", skipped.len())
        }
    );
    for (p, why) in skipped {
        let _ = writeln!(out, "  skipped {}: {why}", p.display());
    }
    for (lo, hi, n) in pairs {
        let note = if *lo == PAPER_LOW_EV {
            ""
        } else {
            " (no EV-3 frame: lowest EV and the reference)"
        };
        let _ = writeln!(
            out,
            "pair:      EV{lo:+} (short) + EV{hi:+} (long, reference) in {n} set(s){note}"
        );
    }
    let m = &cw.mertens;
    let _ = writeln!(
        out,
        "Mertens:   exponents contrast {}, saturation {}, exposure {}{}",
        m.contrast,
        m.saturation,
        m.exposure,
        if *m == MertensWeights::OPENCV_DEFAULT {
            " (OpenCV MergeMertens defaults)"
        } else {
            ""
        }
    );
    let _ = writeln!(
        out,
        "classes:   round(255 * w_long): 0 = long exposure saturated, 255 = short underexposed"
    );
    let _ = writeln!(out, "pixels:    {}", cw.pixels);
    let empty = cw.empty_classes();
    let _ = writeln!(
        out,
        "observed:  {} of {CLASSES} classes; empty: {}",
        CLASSES - empty.len(),
        if empty.is_empty() {
            "none".to_string()
        } else {
            format!("{} ({})", empty.len(), ranges(&empty))
        }
    );
    if cw.pixels > 0 {
        let n = cw.pixels as f64;
        let pct = |i: usize| 100.0 * cw.counts[i] as f64 / n;
        let (imin, amin) = arg_by(&cw.alpha, |a, b| a < b);
        let (imax, amax) = arg_by(&cw.alpha, |a, b| a > b);
        let _ = writeln!(
            out,
            "alpha:     min {amin:.4} (class {imin}, {:.2}% of pixels), max {amax:.4} (class \
             {imax}, {:.2}%); sum_i alpha_i p_i = 1, {} count smoothing",
            pct(imin),
            pct(imax),
            cw.smoothing
        );
        let _ = writeln!(
            out,
            "ends:      class 0 {:.2}% (alpha {:.4}), class 128 {:.2}% (alpha {:.4}), class 255 \
             {:.2}% (alpha {:.4})",
            pct(0),
            cw.alpha[0],
            pct(128),
            cw.alpha[128],
            pct(255),
            cw.alpha[255]
        );
    } else {
        let _ = writeln!(out, "alpha:     1 for every class (no pixels)");
    }
    let _ = writeln!(out, "weights:   {}", weights_path.display());
    if let Some(p) = plot {
        let _ = writeln!(out, "plot:      {}", p.display());
    }
    out
}

/// First index whose value beats all others under `better`.
fn arg_by(v: &[f64], better: impl Fn(f64, f64) -> bool) -> (usize, f64) {
    let mut best = (0, v[0]);
    for (i, &a) in v.iter().enumerate().skip(1) {
        if better(a, best.1) {
            best = (i, a);
        }
    }
    best
}

// ---------------------------------------------------------------------------------------------
// Bar chart

/// Plot size (width, height) in pixels.
pub const PLOT_SIZE: (usize, usize) = (LEFT as usize + 3 * CLASSES + RIGHT as usize, 572);

const LEFT: i32 = 64;
const RIGHT: i32 = 20;
const HEADER: i32 = 34;
const PANEL_H: i32 = 263;

/// Write [`render_plot`] as an 8-bit PNG, atomically.
pub fn write_plot(path: &Path, cw: &ClassWeights) -> Result<()> {
    write_ldr(path, &render_plot(cw), BitDepth::Eight)
}

/// Two panels of 256 bars, log y: the class frequencies p_i = n_i / N (empty classes marked by
/// red ticks under the axis) and the class weights α_i. Display code values in [0, 1].
pub fn render_plot(cw: &ClassWeights) -> Image {
    plot::render(cw)
}

mod plot {
    use super::{CLASSES, ClassWeights, HEADER, LEFT, PANEL_H, PLOT_SIZE};
    use crate::io::Image;
    use embedded_graphics::mono_font::MonoTextStyle;
    use embedded_graphics::mono_font::iso_8859_1::{FONT_6X10, FONT_7X13_BOLD};
    use embedded_graphics::pixelcolor::Rgb888;
    use embedded_graphics::prelude::*;
    use embedded_graphics::primitives::{Line, PrimitiveStyle, Rectangle};
    use embedded_graphics::text::{Alignment, Text};

    use crate::plot::Canvas;

    const INK: Rgb888 = Rgb888::new(20, 20, 20);
    const GRID: Rgb888 = Rgb888::new(222, 222, 222);
    const FREQ: Rgb888 = Rgb888::new(40, 80, 220);
    const ALPHA: Rgb888 = Rgb888::new(230, 120, 20);
    const EMPTY: Rgb888 = Rgb888::new(210, 30, 30);

    fn decade_label(k: i32) -> String {
        match k {
            0..=4 => format!("{}", 10i64.pow(k as u32)),
            -2..=-1 => format!("{}", 10f64.powi(k)),
            _ => format!("1e{k}"),
        }
    }

    /// One log-y bar panel at vertical offset `oy`; `values[i] <= 0` draws no bar.
    fn panel(cv: &mut Canvas, oy: i32, title: &str, values: &[f64], colour: Rgb888) {
        let ink = MonoTextStyle::new(&FONT_6X10, INK);
        let (ax0, ax1) = (LEFT, LEFT + 3 * CLASSES as i32);
        let (ay0, ay1) = (oy + 22, oy + PANEL_H - 36);
        let pos = values.iter().copied().filter(|v| *v > 0.0 && v.is_finite());
        let lo = pos.clone().fold(f64::INFINITY, f64::min);
        let hi = pos.fold(0.0, f64::max);
        let (d_lo, d_hi) = if lo.is_finite() && hi > 0.0 {
            let a = lo.log10().floor() as i32;
            (a, (hi.log10().ceil() as i32).max(a + 1))
        } else {
            (0, 1)
        };
        let map_y = |v: f64| {
            let t = (v.log10() - d_lo as f64) / (d_hi - d_lo) as f64;
            ay1 as f64 - t * (ay1 - ay0) as f64
        };
        let _ = Text::new(title, Point::new(ax0, oy + 14), ink).draw(cv);
        for d in d_lo..=d_hi {
            let y = map_y(10f64.powi(d)).round() as i32;
            let _ = Line::new(Point::new(ax0, y), Point::new(ax1, y))
                .into_styled(PrimitiveStyle::with_stroke(GRID, 1))
                .draw(cv);
            let _ = Text::with_alignment(
                &decade_label(d),
                Point::new(ax0 - 4, y + 3),
                ink,
                Alignment::Right,
            )
            .draw(cv);
        }
        for (i, &v) in values.iter().enumerate() {
            let x = ax0 + 3 * i as i32;
            if v > 0.0 && v.is_finite() {
                let top = map_y(v).round().clamp(ay0 as f64, ay1 as f64) as i32;
                let _ = Rectangle::new(
                    Point::new(x, top),
                    Size::new(2, (ay1 - top + 1).max(1) as u32),
                )
                .into_styled(PrimitiveStyle::with_fill(colour))
                .draw(cv);
            }
        }
        for c in (0..=CLASSES).step_by(32) {
            let c = c.min(CLASSES - 1);
            let x = ax0 + 3 * c as i32 + 1;
            let _ = Line::new(Point::new(x, ay1), Point::new(x, ay1 + 3))
                .into_styled(PrimitiveStyle::with_stroke(INK, 1))
                .draw(cv);
            let _ = Text::with_alignment(
                &c.to_string(),
                Point::new(x, ay1 + 22),
                ink,
                Alignment::Center,
            )
            .draw(cv);
        }
        let _ = Rectangle::new(
            Point::new(ax0 - 1, ay0),
            Size::new((ax1 - ax0 + 2) as u32, (ay1 - ay0 + 1) as u32),
        )
        .into_styled(PrimitiveStyle::with_stroke(INK, 1))
        .draw(cv);
        let _ = Text::with_alignment(
            "class = round(255 * w_long)",
            Point::new((ax0 + ax1) / 2, ay1 + 33),
            ink,
            Alignment::Center,
        )
        .draw(cv);
    }

    pub(super) fn render(cw: &ClassWeights) -> Image {
        let (w, h) = PLOT_SIZE;
        let mut cv = Canvas::new(w, h);
        let bold = MonoTextStyle::new(&FONT_7X13_BOLD, INK);
        let _ = Text::new(
            &format!(
                "Blend classes: {} pixels in {} sets (0 = long exposure saturated, 255 = short \
                 underexposed)",
                cw.pixels, cw.sets
            ),
            Point::new(8, 20),
            bold,
        )
        .draw(&mut cv);

        let n = cw.pixels.max(1) as f64;
        let freq: Vec<f64> = cw.counts.iter().map(|&c| c as f64 / n).collect();
        let empty = cw.empty_classes();
        panel(
            &mut cv,
            HEADER,
            &format!(
                "class frequency p_i (log); red ticks: {} empty classes",
                empty.len()
            ),
            &freq,
            FREQ,
        );
        let ay1 = HEADER + PANEL_H - 36;
        for &i in &empty {
            let x = LEFT + 3 * i as i32;
            let _ = Rectangle::new(Point::new(x, ay1 + 4), Size::new(2, 6))
                .into_styled(PrimitiveStyle::with_fill(EMPTY))
                .draw(&mut cv);
        }
        panel(
            &mut cv,
            HEADER + PANEL_H,
            &format!(
                "class weight alpha_i = k / (n_i + {}), sum_i alpha_i p_i = 1 (log)",
                cw.smoothing
            ),
            &cw.alpha,
            ALPHA,
        );

        cv.into_image()
    }
}
