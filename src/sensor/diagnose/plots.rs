//! The gap and radial-profile plots of a diagnosis.

use crate::io::Image;
use crate::plot::{B, Canvas, H, L, R, T, W, frame};
use crate::sensor::effects::{Protocol, Summary};
use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::mono_font::iso_8859_1::FONT_6X10;
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::*;
use embedded_graphics::primitives::{Circle, Line, PrimitiveStyle};
use embedded_graphics::text::Text;

/// Mean flat signal (relative to its centre) in 16 bins of r².
pub(super) fn radial_profile(s: &Summary, proto: &Protocol) -> Vec<(f64, f64)> {
    let (w, h) = (s.width, s.height);
    let mut bins = vec![(0.0, 0.0, 0usize); 16];
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) * 3;
            let (u, v) = s.xy(x, y);
            let r2 = u * u + v * v;
            let k = ((r2 * 16.0) as usize).min(15);
            bins[k].0 += r2;
            bins[k].1 += (s.mean[i] + s.mean[i + 1] + s.mean[i + 2]) / 3.0 - proto.black;
            bins[k].2 += 1;
        }
    }
    let pts: Vec<(f64, f64)> = bins
        .iter()
        .filter(|b| b.2 > 0)
        .map(|b| (b.0 / b.2 as f64, b.1 / b.2 as f64))
        .collect();
    let c = pts.first().map_or(1.0, |p| p.1);
    pts.iter().map(|p| (p.0, p.1 / c)).collect()
}

/// Gap after each step (log scale bars) with the threshold line.
pub fn gap(gaps: &[f64], labels: &[String], threshold: f64) -> Image {
    crate::plot::log_bars(
        gaps,
        labels,
        threshold,
        "gap (largest |z|) per step; red: threshold",
    )
}

/// Flat signal relative to the centre against r², per flat burst, with the model's
/// vignetting 1 − k·r² (red line).
pub fn radial(series: &[(String, Vec<(f64, f64)>)], k: f64) -> Image {
    let mut c = Canvas::new(W as usize, H as usize);
    frame(
        &mut c,
        &format!("flat mean / centre vs r^2; red: model 1 - {k:.3} r^2"),
    );
    let text = MonoTextStyle::new(&FONT_6X10, Rgb888::BLACK);
    let lo = series
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p.1))
        .fold(1.0 - k, f64::min)
        .min(0.95)
        - 0.02;
    let hi = 1.05;
    let px = |x: f64| L + (x * (W - L - R) as f64) as i32;
    let py = |y: f64| H - B - ((y - lo) / (hi - lo) * (H - T - B) as f64) as i32;
    let _ = Line::new(
        Point::new(px(0.0), py(1.0)),
        Point::new(px(1.0), py(1.0 - k)),
    )
    .into_styled(PrimitiveStyle::with_stroke(Rgb888::RED, 1))
    .draw(&mut c);
    let colours = [
        Rgb888::new(40, 40, 40),
        Rgb888::new(40, 120, 40),
        Rgb888::new(40, 40, 160),
        Rgb888::new(150, 90, 20),
    ];
    for (i, (name, pts)) in series.iter().enumerate() {
        let col = colours[i % colours.len()];
        for p in pts {
            let _ = Circle::with_center(Point::new(px(p.0), py(p.1)), 5)
                .into_styled(PrimitiveStyle::with_stroke(col, 1))
                .draw(&mut c);
        }
        let _ = Text::new(
            name,
            Point::new(L + 8, T + 14 + 12 * i as i32),
            MonoTextStyle::new(&FONT_6X10, col),
        )
        .draw(&mut c);
    }
    for v in [lo, 1.0] {
        let _ = Text::new(&format!("{v:.2}"), Point::new(8, py(v) + 3), text).draw(&mut c);
    }
    let _ = Text::new("r^2: 0", Point::new(L, H - B + 14), text).draw(&mut c);
    let _ = Text::new("1", Point::new(W - R - 6, H - B + 14), text).draw(&mut c);
    c.into_image()
}
