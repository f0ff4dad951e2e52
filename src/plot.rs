//! A white RGB canvas that embedded-graphics draws on (its bitmap fonts need no system fonts),
//! converted to an `Image` for writing, and the log-axis ticks the plots share (the noise PTC
//! plot, the class-weight plot, the diagnosis plots).

use crate::io::Image;
use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::mono_font::iso_8859_1::FONT_6X10;
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::*;
use embedded_graphics::primitives::{Line, PrimitiveStyle, Rectangle};
use embedded_graphics::text::{Alignment, Text};

pub struct Canvas {
    w: usize,
    h: usize,
    px: Vec<[u8; 3]>,
}

impl Canvas {
    pub fn new(w: usize, h: usize) -> Canvas {
        Canvas {
            w,
            h,
            px: vec![[255, 255, 255]; w * h],
        }
    }

    pub fn into_image(self) -> Image {
        let data = self
            .px
            .iter()
            .flat_map(|p| p.map(|v| v as f32 / 255.0))
            .collect();
        Image::from_vec(self.w, self.h, data)
    }
}

impl OriginDimensions for Canvas {
    fn size(&self) -> Size {
        Size::new(self.w as u32, self.h as u32)
    }
}

impl DrawTarget for Canvas {
    type Color = Rgb888;
    type Error = core::convert::Infallible;
    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Self::Error>
    where
        I: IntoIterator<Item = Pixel<Self::Color>>,
    {
        for Pixel(p, c) in pixels {
            if p.x >= 0 && p.y >= 0 && (p.x as usize) < self.w && (p.y as usize) < self.h {
                self.px[p.y as usize * self.w + p.x as usize] = [c.r(), c.g(), c.b()];
            }
        }
        Ok(())
    }
}

/// The label of the decade 10^k on a log axis: "1" to "10000", "0.1", "0.01", else "1e{k}".
pub fn decade_label(k: i32) -> String {
    match k {
        0..=4 => format!("{}", 10i64.pow(k as u32)),
        -2..=-1 => format!("{}", 10f64.powi(k)),
        _ => format!("1e{k}"),
    }
}

/// A horizontal grid line at row `y` from `x0` to `x1`, its label right-aligned left of `x0`.
pub fn y_tick(
    cv: &mut Canvas,
    (x0, x1): (i32, i32),
    y: i32,
    label: &str,
    grid: Rgb888,
    text: MonoTextStyle<'_, Rgb888>,
) {
    let _ = Line::new(Point::new(x0, y), Point::new(x1, y))
        .into_styled(PrimitiveStyle::with_stroke(grid, 1))
        .draw(cv);
    let _ = Text::with_alignment(label, Point::new(x0 - 4, y + 3), text, Alignment::Right).draw(cv);
}

/// A vertical grid line at column `x` from `y0` to `y1`, its label centred below `y1`.
pub fn x_tick(
    cv: &mut Canvas,
    (y0, y1): (i32, i32),
    x: i32,
    label: &str,
    grid: Rgb888,
    text: MonoTextStyle<'_, Rgb888>,
) {
    let _ = Line::new(Point::new(x, y0), Point::new(x, y1))
        .into_styled(PrimitiveStyle::with_stroke(grid, 1))
        .draw(cv);
    let _ = Text::with_alignment(label, Point::new(x, y1 + 13), text, Alignment::Center).draw(cv);
}

/// The size and margins (left, top, right, bottom) of the report plots drawn in a [`frame`].
pub const W: i32 = 520;
pub const H: i32 = 340;
pub const L: i32 = 60;
pub const T: i32 = 30;
pub const R: i32 = 20;
pub const B: i32 = 60;

/// The plot area's box and the title above it.
pub fn frame(c: &mut Canvas, title: &str) {
    let black = MonoTextStyle::new(&FONT_6X10, Rgb888::BLACK);
    let _ = Rectangle::new(
        Point::new(L, T),
        Size::new((W - L - R) as u32, (H - T - B) as u32),
    )
    .into_styled(PrimitiveStyle::with_stroke(Rgb888::BLACK, 1))
    .draw(c);
    let _ = Text::new(title, Point::new(L, 18), black).draw(c);
}

/// One bar per value on a log axis (0.1 up), each labelled with its value and (shortened) its
/// label, and a red line at `threshold`.
pub fn log_bars(values: &[f64], labels: &[String], threshold: f64, title: &str) -> Image {
    let mut c = Canvas::new(W as usize, H as usize);
    frame(&mut c, title);
    let text = MonoTextStyle::new(&FONT_6X10, Rgb888::BLACK);
    let top = values.iter().copied().fold(threshold, f64::max).max(1.0) * 1.2;
    let ly = |v: f64| {
        let f = (v.max(0.1).log10() + 1.0) / (top.log10() + 1.0);
        H - B - (f * (H - T - B) as f64) as i32
    };
    let n = values.len().max(1) as i32;
    let bw = (W - L - R) / n;
    for (i, (g, l)) in values.iter().zip(labels).enumerate() {
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
    let mut v = 0.1;
    while v <= top {
        let _ = Text::new(&format!("{v}"), Point::new(8, ly(v) + 3), text).draw(&mut c);
        v *= 10.0;
    }
    c.into_image()
}

/// One point of a [`Scatter`]: its position, a vertical interval drawn as a bar, the series it
/// belongs to (its colour and legend entry) and a short label drawn beside it.
pub struct ScatterPoint {
    pub x: f64,
    pub y: f64,
    pub y_range: (f64, f64),
    pub series: usize,
    pub label: String,
}

/// A scatter plot on linear axes with both zero lines drawn: each axis spans whole units,
/// from ⌊min − ¼⌋ to ⌈max + ¼⌉ of its values (the bars' ends included) and 0 (so no point sits
/// on the frame), and which side of zero a point lies on is read at a glance.
pub struct Scatter<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    /// Legend names, indexed by [`ScatterPoint::series`].
    pub series: &'a [&'a str],
}

/// Size of a [`Scatter`] and its plot area's margins (left, top, right, bottom).
pub const SCATTER_SIZE: (i32, i32) = (720, 480);
pub const SCATTER_MARGINS: (i32, i32, i32, i32) = (60, 40, 20, 50);
/// Series colours, in order (cycled).
pub const SERIES_COLOURS: [Rgb888; 4] = [
    Rgb888::new(40, 80, 220),
    Rgb888::new(210, 40, 40),
    Rgb888::new(30, 150, 50),
    Rgb888::new(200, 130, 0),
];

/// The whole-unit span [⌊min − ¼⌋, ⌈max + ¼⌉] of `values` and 0, at least one unit wide.
fn unit_span(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((0.0f64, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (lo, hi) = ((lo - 0.25).floor(), (hi + 0.25).ceil());
    (lo, if hi > lo { hi } else { lo + 1.0 })
}

impl Scatter<'_> {
    /// The axes' spans ((x0, x1), (y0, y1)) for `points`.
    pub fn spans(points: &[ScatterPoint]) -> ((f64, f64), (f64, f64)) {
        let xs = unit_span(points.iter().map(|p| p.x));
        let ys = unit_span(points.iter().flat_map(|p| [p.y, p.y_range.0, p.y_range.1]));
        (xs, ys)
    }

    pub fn render(&self, points: &[ScatterPoint]) -> Image {
        let (w, h) = SCATTER_SIZE;
        let (l, t, r, b) = SCATTER_MARGINS;
        let mut c = Canvas::new(w as usize, h as usize);
        let text = MonoTextStyle::new(&FONT_6X10, Rgb888::BLACK);
        let grid = Rgb888::new(222, 222, 222);
        let ((x0, x1), (y0, y1)) = Self::spans(points);
        let px = |x: f64| l + ((x - x0) / (x1 - x0) * (w - l - r) as f64).round() as i32;
        let py = |y: f64| h - b - ((y - y0) / (y1 - y0) * (h - t - b) as f64).round() as i32;
        let _ = Text::new(self.title, Point::new(l, 18), text).draw(&mut c);
        // Ticks every whole unit (every second one past 12 units).
        let step = |span: f64| if span > 12.0 { 2.0 } else { 1.0 };
        let mut v = x0;
        while v <= x1 {
            x_tick(&mut c, (t, h - b), px(v), &format!("{v:+.0}"), grid, text);
            v += step(x1 - x0);
        }
        let mut v = y0;
        while v <= y1 {
            y_tick(&mut c, (l, w - r), py(v), &format!("{v:+.0}"), grid, text);
            v += step(y1 - y0);
        }
        let zero = PrimitiveStyle::with_stroke(Rgb888::new(90, 90, 90), 1);
        let _ = Line::new(Point::new(px(0.0), t), Point::new(px(0.0), h - b))
            .into_styled(zero)
            .draw(&mut c);
        let _ = Line::new(Point::new(l, py(0.0)), Point::new(w - r, py(0.0)))
            .into_styled(zero)
            .draw(&mut c);
        let _ = Rectangle::new(
            Point::new(l, t),
            Size::new((w - l - r) as u32, (h - t - b) as u32),
        )
        .into_styled(PrimitiveStyle::with_stroke(Rgb888::BLACK, 1))
        .draw(&mut c);
        let _ = Text::with_alignment(
            self.x_label,
            Point::new((l + w - r) / 2, h - 12),
            text,
            Alignment::Center,
        )
        .draw(&mut c);
        for p in points {
            let colour = SERIES_COLOURS[p.series % SERIES_COLOURS.len()];
            let (x, y) = (px(p.x), py(p.y));
            let _ = Line::new(
                Point::new(x, py(p.y_range.0)),
                Point::new(x, py(p.y_range.1)),
            )
            .into_styled(PrimitiveStyle::with_stroke(colour, 1))
            .draw(&mut c);
            let _ = embedded_graphics::primitives::Circle::with_center(Point::new(x, y), 7)
                .into_styled(PrimitiveStyle::with_fill(colour))
                .draw(&mut c);
            let ink = MonoTextStyle::new(&FONT_6X10, colour);
            let _ = Text::new(&p.label, Point::new(x + 6, y - 4), ink).draw(&mut c);
        }
        for (k, name) in self.series.iter().enumerate() {
            let colour = SERIES_COLOURS[k % SERIES_COLOURS.len()];
            let y = t + 14 + 13 * k as i32;
            let _ = Rectangle::new(Point::new(l + 8, y - 7), Size::new(8, 8))
                .into_styled(PrimitiveStyle::with_fill(colour))
                .draw(&mut c);
            let _ = Text::new(name, Point::new(l + 20, y), text).draw(&mut c);
        }
        c.into_image()
    }
}
