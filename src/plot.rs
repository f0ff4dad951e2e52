//! A white RGB canvas that embedded-graphics draws on (its bitmap fonts need no system fonts),
//! converted to an `Image` for writing. Shared by the PTC plot and the class-weight plot.

use crate::io::Image;
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::*;

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
