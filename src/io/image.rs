//! The one image type: H×W×3 f32, interleaved RGB, row-major.
//! Values are linear unless the producer says otherwise (LDR files read as [0,1] code values).

#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    /// `height * width * 3` values, pixel (x, y) channel c at `(y * width + x) * 3 + c`.
    pub data: Vec<f32>,
}

impl Image {
    pub fn new(width: usize, height: usize) -> Self {
        Image {
            width,
            height,
            data: vec![0.0; width * height * 3],
        }
    }

    /// Panics if `data.len() != width * height * 3` (a programming error, not bad input).
    pub fn from_vec(width: usize, height: usize, data: Vec<f32>) -> Self {
        assert_eq!(
            data.len(),
            width * height * 3,
            "Image::from_vec: wrong length"
        );
        Image {
            width,
            height,
            data,
        }
    }

    pub fn from_fn(
        width: usize,
        height: usize,
        mut f: impl FnMut(usize, usize) -> [f32; 3],
    ) -> Self {
        let mut img = Image::new(width, height);
        for y in 0..height {
            for x in 0..width {
                img.set(x, y, f(x, y));
            }
        }
        img
    }

    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }

    #[inline]
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        let i = (y * self.width + x) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    #[inline]
    pub fn set(&mut self, x: usize, y: usize, v: [f32; 3]) {
        let i = (y * self.width + x) * 3;
        self.data[i..i + 3].copy_from_slice(&v);
    }

    pub fn pixels(&self) -> impl Iterator<Item = [f32; 3]> + '_ {
        self.data.chunks_exact(3).map(|p| [p[0], p[1], p[2]])
    }

    pub fn map(&self, f: impl Fn(f32) -> f32 + Sync) -> Image {
        Image {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(|&v| f(v)).collect(),
        }
    }

    /// The image as displayed under EXIF/TIFF `Orientation` `o` (1–8; TIFF 6.0 tag 274): the
    /// stored image mirrored and/or rotated so that row 0 is the visual top. None for values
    /// outside 1–8. 5–8 swap width and height.
    pub fn oriented(&self, o: u16) -> Option<Image> {
        let (w, h) = (self.width, self.height);
        // Display (x, y) → stored (x, y), read off the tag's definition of where stored row 0
        // and column 0 appear.
        let map: fn(usize, usize, usize, usize) -> (usize, usize) = match o {
            1 => |x, y, _, _| (x, y),
            2 => |x, y, w, _| (w - 1 - x, y),
            3 => |x, y, w, h| (w - 1 - x, h - 1 - y),
            4 => |x, y, _, h| (x, h - 1 - y),
            5 => |x, y, _, _| (y, x),
            6 => |x, y, _, h| (y, h - 1 - x),
            7 => |x, y, w, h| (w - 1 - y, h - 1 - x),
            8 => |x, y, w, _| (w - 1 - y, x),
            _ => return None,
        };
        let (dw, dh) = if o >= 5 { (h, w) } else { (w, h) };
        Some(Image::from_fn(dw, dh, |x, y| {
            let (sx, sy) = map(x, y, w, h);
            self.get(sx, sy)
        }))
    }

    /// Rec. 709 / sRGB-primaries relative luminance of each pixel.
    pub fn luminance(&self) -> Vec<f32> {
        self.pixels().map(luminance).collect()
    }

    /// Count of NaN/Inf values and the (x, y) of the first one.
    pub fn non_finite(&self) -> Option<(usize, usize, usize)> {
        let mut count = 0;
        let mut first = None;
        for (i, v) in self.data.iter().enumerate() {
            if !v.is_finite() {
                count += 1;
                if first.is_none() {
                    let p = i / 3;
                    first = Some((p % self.width, p / self.width));
                }
            }
        }
        first.map(|(x, y)| (count, x, y))
    }
}

#[inline]
pub fn luminance(p: [f32; 3]) -> f32 {
    0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]
}

/// Dynamic range in stops: log2 of the ratio of the `hi` and `lo` percentiles of luminance
/// (e.g. 99.9 and 0.1), ignoring pixels at or below zero so a black border does not make it infinite.
pub fn dynamic_range_stops(img: &Image, lo: f64, hi: f64) -> Option<f64> {
    let mut l: Vec<f32> = img.luminance().into_iter().filter(|&v| v > 0.0).collect();
    if l.len() < 2 {
        return None;
    }
    l.sort_by(|a, b| a.total_cmp(b));
    let pick = |p: f64| {
        let idx = ((p / 100.0) * (l.len() - 1) as f64).round() as usize;
        l[idx.min(l.len() - 1)] as f64
    };
    Some((pick(hi) / pick(lo)).log2())
}
