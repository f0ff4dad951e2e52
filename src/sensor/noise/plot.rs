//! The photon-transfer-curve plot of a calibration.

use super::{CHANNELS, IsoFit, NoiseCalibration};
use crate::error::Result;
use crate::io::Image;
use crate::plot::{Canvas, decade_label, x_tick, y_tick};
use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::mono_font::iso_8859_1::{FONT_6X10, FONT_7X13_BOLD};
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::*;
use embedded_graphics::primitives::{Circle, Line, PrimitiveStyle, Rectangle};
use embedded_graphics::text::{Alignment, Text};
use std::path::Path;

/// Panel size of the PTC plot, one panel per ISO.
pub const PTC_PANEL: (usize, usize) = (420, 320);
/// Height of the title strip above the panels.
pub const PTC_HEADER: usize = 30;
/// Panels per row.
pub const PTC_COLUMNS: usize = 3;

/// Size (width, height) of the PTC plot for `n_isos` panels: columns = min(n, 3), rows =
/// ceil(n / 3); width = 420·columns, height = 30 + 320·rows.
pub fn ptc_plot_size(n_isos: usize) -> (usize, usize) {
    let n = n_isos.max(1);
    let cols = n.min(PTC_COLUMNS);
    let rows = n.div_ceil(PTC_COLUMNS);
    (PTC_PANEL.0 * cols, PTC_HEADER + PTC_PANEL.1 * rows)
}

impl NoiseCalibration {
    /// Render the photon-transfer curves: per ISO a log–log panel of bin variance (DN²)
    /// against bin signal (DN above black), points with ±1 SE bars and the fitted lines, one
    /// colour per channel. Bins at or below the axis' left edge (dark bursts) are drawn on the
    /// edge as hollow squares. Returns display code values in [0, 1].
    pub fn render_ptc(&self) -> Image {
        render(self)
    }

    /// Write [`Self::render_ptc`] as an 8-bit PNG, atomically.
    pub fn write_ptc_plot(&self, path: &Path) -> Result<()> {
        crate::io::write_ldr(path, &self.render_ptc(), crate::io::BitDepth::Eight)
    }
}

const COLOURS: [Rgb888; 3] = [
    Rgb888::new(210, 40, 40),
    Rgb888::new(30, 150, 50),
    Rgb888::new(40, 80, 220),
];
const INK: Rgb888 = Rgb888::new(20, 20, 20);
const GRID: Rgb888 = Rgb888::new(222, 222, 222);

// Plot area inside a panel.
const LEFT: i32 = 56;
const RIGHT: i32 = 14;
const TOP: i32 = 30;
const BOTTOM: i32 = 40;

fn render(cal: &NoiseCalibration) -> Image {
    let (w, h) = ptc_plot_size(cal.isos.len());
    let mut cv = Canvas::new(w, h);
    let ink = MonoTextStyle::new(&FONT_6X10, INK);
    let _ = Text::new(
        "Photon transfer: temporal variance [DN²] vs signal above black [DN], log-log; \
         points = bins ±1 SE, lines = WLS fits",
        Point::new(8, 19),
        ink,
    )
    .draw(&mut cv);
    let decades = Decades::of(cal);
    for (k, fit) in cal.isos.iter().enumerate() {
        let p = Panel::new(k, decades);
        p.draw_axes(&mut cv, fit);
        p.draw_fits(&mut cv, fit);
        p.draw_bins(&mut cv, fit);
        // Legend.
        for (c, ch) in fit.channels.iter().enumerate() {
            let txt = format!("{} a={:.4} b={:.3}", CHANNELS[c], ch.a, ch.b);
            let _ = Text::new(
                &txt,
                Point::new(p.ax0 + 6, p.ay0 + 12 + 11 * c as i32),
                MonoTextStyle::new(&FONT_6X10, COLOURS[c]),
            )
            .draw(&mut cv);
        }
    }
    cv.into_image()
}

/// The axis ranges in decades, shared by the panels so that they compare at a glance.
#[derive(Clone, Copy)]
struct Decades {
    x_lo: i32,
    x_hi: i32,
    y_lo: i32,
    y_hi: i32,
}

impl Decades {
    fn of(cal: &NoiseCalibration) -> Decades {
        let bins = || {
            cal.isos
                .iter()
                .flat_map(|f| f.channels.iter().flat_map(|c| &c.bins))
        };
        let min_x = bins()
            .map(|b| b.signal)
            .filter(|&x| x >= 1.0)
            .fold(f64::INFINITY, f64::min);
        let max_x = bins().map(|b| b.signal).fold(1.0, f64::max);
        let x_lo = if min_x.is_finite() {
            min_x.log10().floor().min(0.0) as i32
        } else {
            0
        };
        let x_hi = (max_x.log10().ceil() as i32).max(x_lo + 1);
        let min_y = bins()
            .map(|b| b.variance - b.stderr)
            .filter(|&y| y > 0.0)
            .fold(f64::INFINITY, f64::min);
        let max_y = bins()
            .map(|b| b.variance + b.stderr)
            .fold(f64::NEG_INFINITY, f64::max);
        let y_lo = if min_y.is_finite() {
            min_y.log10().floor() as i32
        } else {
            -1
        };
        let y_hi = if max_y.is_finite() && max_y > 0.0 {
            (max_y.log10().ceil() as i32).max(y_lo + 1)
        } else {
            y_lo + 1
        };
        Decades {
            x_lo,
            x_hi,
            y_lo,
            y_hi,
        }
    }
}

/// One ISO's panel: its origin and plot area, and the data-to-pixel maps.
struct Panel {
    oy: i32,
    ax0: i32,
    ax1: i32,
    ay0: i32,
    ay1: i32,
    d: Decades,
}

impl Panel {
    fn new(k: usize, d: Decades) -> Panel {
        let ox = (k % PTC_COLUMNS * PTC_PANEL.0) as i32;
        let oy = (PTC_HEADER + k / PTC_COLUMNS * PTC_PANEL.1) as i32;
        let (pw, ph) = (PTC_PANEL.0 as i32, PTC_PANEL.1 as i32);
        Panel {
            oy,
            ax0: ox + LEFT,
            ax1: ox + pw - RIGHT,
            ay0: oy + TOP,
            ay1: oy + ph - BOTTOM,
            d,
        }
    }

    fn map_x(&self, x: f64) -> f64 {
        let (x_lo, x_hi) = (self.d.x_lo, self.d.x_hi);
        let t = (x.max(10f64.powi(x_lo)).log10() - x_lo as f64) / (x_hi - x_lo) as f64;
        self.ax0 as f64 + t * (self.ax1 - self.ax0) as f64
    }

    fn map_y(&self, y: f64) -> f64 {
        let (y_lo, y_hi) = (self.d.y_lo, self.d.y_hi);
        let t = (y.log10() - y_lo as f64) / (y_hi - y_lo) as f64;
        self.ay1 as f64 - t * (self.ay1 - self.ay0) as f64
    }

    fn clip_y(&self, y: f64) -> f64 {
        y.clamp(self.ay0 as f64, self.ay1 as f64)
    }

    /// Grid, ticks, frame and the panel's labels.
    fn draw_axes(&self, cv: &mut Canvas, fit: &IsoFit) {
        let ink = MonoTextStyle::new(&FONT_6X10, INK);
        let bold = MonoTextStyle::new(&FONT_7X13_BOLD, INK);
        let (ax0, ax1, ay0, ay1, oy) = (self.ax0, self.ax1, self.ay0, self.ay1, self.oy);
        for d in self.d.x_lo..=self.d.x_hi {
            let x = self.map_x(10f64.powi(d)).round() as i32;
            x_tick(cv, (ay0, ay1), x, &decade_label(d), GRID, ink);
        }
        for d in self.d.y_lo..=self.d.y_hi {
            let y = self.map_y(10f64.powi(d)).round() as i32;
            y_tick(cv, (ax0, ax1), y, &decade_label(d), GRID, ink);
        }
        let _ = Rectangle::new(
            Point::new(ax0, ay0),
            Size::new((ax1 - ax0 + 1) as u32, (ay1 - ay0 + 1) as u32),
        )
        .into_styled(PrimitiveStyle::with_stroke(INK, 1))
        .draw(cv);
        let _ = Text::new(&format!("ISO {}", fit.iso), Point::new(ax0, oy + 14), bold).draw(cv);
        let _ = Text::with_alignment(
            "variance [DN²]",
            Point::new(ax1, oy + 14),
            ink,
            Alignment::Right,
        )
        .draw(cv);
        let _ = Text::with_alignment(
            "signal above black [DN]",
            Point::new((ax0 + ax1) / 2, ay1 + 28),
            ink,
            Alignment::Center,
        )
        .draw(cv);
    }

    /// The fitted lines a·x + b, clipped to the plot area.
    fn draw_fits(&self, cv: &mut Canvas, fit: &IsoFit) {
        let (x_lo, x_hi) = (self.d.x_lo, self.d.x_hi);
        for (c, ch) in fit.channels.iter().enumerate() {
            let style = PrimitiveStyle::with_stroke(COLOURS[c], 1);
            let n = 120;
            let mut prev: Option<Point> = None;
            for i in 0..=n {
                let lx = x_lo as f64 + (x_hi - x_lo) as f64 * i as f64 / n as f64;
                let x = 10f64.powf(lx);
                let y = ch.a * x + ch.b;
                let pt = if y > 0.0 {
                    let py = self.map_y(y);
                    (py >= self.ay0 as f64 && py <= self.ay1 as f64)
                        .then(|| Point::new(self.map_x(x).round() as i32, py.round() as i32))
                } else {
                    None
                };
                if let (Some(p0), Some(p1)) = (prev, pt) {
                    let _ = Line::new(p0, p1).into_styled(style).draw(cv);
                }
                prev = pt;
            }
        }
    }

    /// The bins with ±1 SE bars; bins left of the axis as hollow squares on its edge.
    fn draw_bins(&self, cv: &mut Canvas, fit: &IsoFit) {
        for (c, ch) in fit.channels.iter().enumerate() {
            let colour = COLOURS[c];
            for b in &ch.bins {
                if b.variance <= 0.0 {
                    continue;
                }
                let x = self.map_x(b.signal).round() as i32;
                let y = self.clip_y(self.map_y(b.variance)).round() as i32;
                let hi = self.clip_y(self.map_y(b.variance + b.stderr)).round() as i32;
                let lo_v = b.variance - b.stderr;
                let lo = if lo_v > 0.0 {
                    self.clip_y(self.map_y(lo_v)).round() as i32
                } else {
                    self.ay1
                };
                let bar = PrimitiveStyle::with_stroke(colour, 1);
                let _ = Line::new(Point::new(x, lo), Point::new(x, hi))
                    .into_styled(bar)
                    .draw(cv);
                for e in [lo, hi] {
                    let _ = Line::new(Point::new(x - 2, e), Point::new(x + 2, e))
                        .into_styled(bar)
                        .draw(cv);
                }
                if b.signal < 10f64.powi(self.d.x_lo) {
                    let _ = Rectangle::new(Point::new(x - 3, y - 3), Size::new(7, 7))
                        .into_styled(PrimitiveStyle::with_stroke(colour, 1))
                        .draw(cv);
                } else {
                    let _ = Circle::new(Point::new(x - 2, y - 2), 5)
                        .into_styled(PrimitiveStyle::with_fill(colour))
                        .draw(cv);
                }
            }
        }
    }
}
