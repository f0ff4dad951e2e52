//! A white RGB canvas that embedded-graphics draws on (its bitmap fonts need no system fonts),
//! converted to an `Image` for writing, and the log-axis ticks the plots share (the noise PTC
//! plot, the class-weight plot, the diagnosis plots).

use crate::io::Image;
use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::*;
use embedded_graphics::primitives::{Line, PrimitiveStyle};
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
