//! The gap and radial-profile plots of a diagnosis.

use crate::io::Image;
use crate::plot::Canvas;
use crate::sensor::effects::{Protocol, Summary};
use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::mono_font::iso_8859_1::FONT_6X10;
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::*;
use embedded_graphics::primitives::{Circle, Line, PrimitiveStyle, Rectangle};
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

const W: i32 = 520;
const H: i32 = 340;
const L: i32 = 60;
const T: i32 = 30;
const R: i32 = 20;
const B: i32 = 60;

fn frame(c: &mut Canvas, title: &str) {
    let black = MonoTextStyle::new(&FONT_6X10, Rgb888::BLACK);
    let _ = Rectangle::new(
        Point::new(L, T),
        Size::new((W - L - R) as u32, (H - T - B) as u32),
    )
    .into_styled(PrimitiveStyle::with_stroke(Rgb888::BLACK, 1))
    .draw(c);
    let _ = Text::new(title, Point::new(L, 18), black).draw(c);
}

/// Gap after each step (log scale bars) with the threshold line.
pub fn gap(gaps: &[f64], labels: &[String], threshold: f64) -> Image {
    let mut c = Canvas::new(W as usize, H as usize);
    frame(&mut c, "gap (largest |z|) per step; red: threshold");
    let text = MonoTextStyle::new(&FONT_6X10, Rgb888::BLACK);
    let top = gaps.iter().copied().fold(threshold, f64::max).max(1.0) * 1.2;
    let ly = |v: f64| {
        let f = (v.max(0.1).log10() + 1.0) / (top.log10() + 1.0);
        H - B - (f * (H - T - B) as f64) as i32
    };
    let n = gaps.len().max(1) as i32;
    let bw = (W - L - R) / n;
    for (i, (g, l)) in gaps.iter().zip(labels).enumerate() {
        let x0 = L + i as i32 * bw + bw / 6;
        let y = ly(*g);
        let _ = Rectangle::new(
            Point::new(x0, y),
            Size::new((bw * 2 / 3) as u32, (H - B - y).max(1) as u32),
        )
        .into_styled(PrimitiveStyle::with_fill(Rgb888::new(70, 110, 200)))
        .draw(&mut c);
        let _ = Text::new(&format!("{g:.1}"), Point::new(x0, y - 3), text).draw(&mut c);
        let short: String = l.chars().take((bw / 6).max(4) as usize).collect();
        let _ = Text::new(&short, Point::new(x0, H - B + 14), text).draw(&mut c);
    }
    let yt = ly(threshold);
    let _ = Line::new(Point::new(L, yt), Point::new(W - R, yt))
        .into_styled(PrimitiveStyle::with_stroke(Rgb888::RED, 1))
        .draw(&mut c);
    for v in [0.1, 1.0, 10.0, 100.0, 1000.0] {
        if v <= top {
            let _ = Text::new(&format!("{v}"), Point::new(8, ly(v) + 3), text).draw(&mut c);
        }
    }
    c.into_image()
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
