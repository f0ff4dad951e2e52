//! The ColorChecker24: reference colours, white balance on its neutral patches, the rendered
//! synthetic chart, and locating and sampling the chart in an image (full frame or four corners
//! through a homography). Geometry and coordinate conventions: the module docs of `colour`.
#![allow(clippy::needless_range_loop)]

use super::cie::{A_XY, D50_XY, D65_XY, SRGB_TO_XYZ, bradford, xy_to_xyz};
use super::{expected_floats, floats, parse_floats};
use crate::error::{Error, Result};
use crate::io::Image;
use crate::linalg::{Mat3, inverse3, mat_vec, mul3};
use std::fmt;
use std::str::FromStr;

/// One ColorChecker24 patch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    /// 1-based number in reading order.
    pub number: u8,
    pub name: &'static str,
    /// Linear sRGB (D65), reflectance scale (a perfect white diffuser is Y = 1).
    pub linear_srgb: [f64; 3],
    /// CIE L*a*b* under D50.
    pub lab_d50: [f64; 3],
}

/// ColorChecker24 "After November 2014", colour-science colour-checker dataset, BSD-3
/// (`colour.CCS_COLOURCHECKERS['ColorChecker24 - After November 2014']`; linear sRGB derived
/// from its xyY (D50) with the Bradford transform to D65, rounded to 6 decimals). Reading order.
pub const COLORCHECKER24: [Patch; 24] = [
    Patch {
        number: 1,
        name: "dark skin",
        linear_srgb: [0.173683, 0.078793, 0.052856],
        lab_d50: [37.54, 14.37, 14.92],
    },
    Patch {
        number: 2,
        name: "light skin",
        linear_srgb: [0.559784, 0.277447, 0.210892],
        lab_d50: [64.66, 19.27, 17.5],
    },
    Patch {
        number: 3,
        name: "blue sky",
        linear_srgb: [0.104201, 0.188915, 0.32893],
        lab_d50: [49.32, -3.82, -22.54],
    },
    Patch {
        number: 4,
        name: "foliage",
        linear_srgb: [0.105744, 0.150754, 0.050837],
        lab_d50: [43.46, -12.74, 22.72],
    },
    Patch {
        number: 5,
        name: "blue flower",
        linear_srgb: [0.227439, 0.212408, 0.426446],
        lab_d50: [54.94, 9.61, -24.79],
    },
    Patch {
        number: 6,
        name: "bluish green",
        linear_srgb: [0.115293, 0.507441, 0.411129],
        lab_d50: [70.48, -32.26, -0.37],
    },
    Patch {
        number: 7,
        name: "orange",
        linear_srgb: [0.745903, 0.202143, 0.029868],
        lab_d50: [62.73, 35.83, 56.5],
    },
    Patch {
        number: 8,
        name: "purplish blue",
        linear_srgb: [0.058742, 0.101182, 0.387748],
        lab_d50: [39.43, 10.75, -45.17],
    },
    Patch {
        number: 9,
        name: "moderate red",
        linear_srgb: [0.56013, 0.080153, 0.114586],
        lab_d50: [50.57, 48.64, 16.67],
    },
    Patch {
        number: 10,
        name: "purple",
        linear_srgb: [0.109167, 0.042, 0.138137],
        lab_d50: [30.1, 22.54, -20.87],
    },
    Patch {
        number: 11,
        name: "yellow green",
        linear_srgb: [0.33275, 0.497386, 0.042596],
        lab_d50: [71.77, -24.13, 58.19],
    },
    Patch {
        number: 12,
        name: "orange yellow",
        linear_srgb: [0.771037, 0.357918, 0.020449],
        lab_d50: [71.51, 18.24, 67.37],
    },
    Patch {
        number: 13,
        name: "blue",
        linear_srgb: [0.020956, 0.047534, 0.284129],
        lab_d50: [28.37, 15.42, -49.8],
    },
    Patch {
        number: 14,
        name: "green",
        linear_srgb: [0.046062, 0.292048, 0.061479],
        lab_d50: [54.38, -39.72, 32.27],
    },
    Patch {
        number: 15,
        name: "red",
        linear_srgb: [0.446171, 0.036406, 0.040551],
        lab_d50: [42.43, 51.05, 28.62],
    },
    Patch {
        number: 16,
        name: "yellow",
        linear_srgb: [0.841684, 0.574408, 0.004662],
        lab_d50: [81.8, 2.67, 80.41],
    },
    Patch {
        number: 17,
        name: "magenta",
        linear_srgb: [0.522342, 0.077817, 0.289313],
        lab_d50: [50.63, 51.28, -14.12],
    },
    Patch {
        number: 18,
        name: "cyan",
        linear_srgb: [-0.043918, 0.233662, 0.37719],
        lab_d50: [49.57, -29.71, -28.32],
    },
    Patch {
        number: 19,
        name: "white 9.5 (.05 D)",
        linear_srgb: [0.879529, 0.885028, 0.834247],
        lab_d50: [95.19, -1.03, 2.93],
    },
    Patch {
        number: 20,
        name: "neutral 8 (.23 D)",
        linear_srgb: [0.584493, 0.592168, 0.584478],
        lab_d50: [81.29, -0.57, 0.44],
    },
    Patch {
        number: 21,
        name: "neutral 6.5 (.44 D)",
        linear_srgb: [0.357694, 0.367077, 0.365266],
        lab_d50: [66.89, -0.75, -0.06],
    },
    Patch {
        number: 22,
        name: "neutral 5 (.70 D)",
        linear_srgb: [0.190094, 0.190866, 0.189814],
        lab_d50: [50.76, -0.13, 0.14],
    },
    Patch {
        number: 23,
        name: "neutral 3.5 (1.05 D)",
        linear_srgb: [0.085929, 0.088735, 0.089804],
        lab_d50: [35.63, -0.46, -0.48],
    },
    Patch {
        number: 24,
        name: "black 2 (1.5 D)",
        linear_srgb: [0.031354, 0.031496, 0.032323],
        lab_d50: [20.64, 0.07, -0.46],
    },
];

/// Columns and rows of the chart grid.
pub const CHART_COLS: usize = 6;
pub const CHART_ROWS: usize = 4;

/// 0-based indices of the neutral patches 20–23 (neutral 8 … neutral 3.5) used for white balance
/// and exposure normalisation: patch 19 (white) is the first to clip and patch 24 (black) the
/// most sensitive to flare and black-level error, so both are left out.
pub const NEUTRAL_PATCHES: [usize; 4] = [19, 20, 21, 22];

/// Reference linear sRGB of the 24 patches, in reading order.
pub fn reference_linear_srgb() -> Vec<[f64; 3]> {
    COLORCHECKER24.iter().map(|p| p.linear_srgb).collect()
}

// ---------------------------------------------------------------------------------------------
// White balance
// ---------------------------------------------------------------------------------------------

/// Per-channel gains that make the mean of the neutral patches 20–23 neutral, green kept:
/// gain_c = mean_G / mean_c over those patches.
pub fn neutral_gains(patches: &[[f64; 3]]) -> Result<[f64; 3]> {
    if patches.len() != 24 {
        return Err(Error::Invalid(format!(
            "white balance needs the 24 chart patches, got {}",
            patches.len()
        )));
    }
    let m: [f64; 3] =
        std::array::from_fn(|c| NEUTRAL_PATCHES.iter().map(|&i| patches[i][c]).sum::<f64>() / 4.0);
    if m.iter().any(|v| v.is_nan() || *v <= 0.0) {
        return Err(Error::Invalid(format!(
            "white balance: the neutral patches 20–23 have a non-positive mean ({:.4}, {:.4}, \
             {:.4}); is the chart located correctly and the black level right?",
            m[0], m[1], m[2]
        )));
    }
    Ok([m[1] / m[0], 1.0, m[1] / m[2]])
}

/// Mean over the neutral patches 20–23 and the three channels.
pub fn neutral_mean(patches: &[[f64; 3]]) -> f64 {
    NEUTRAL_PATCHES
        .iter()
        .map(|&i| patches[i].iter().sum::<f64>())
        .sum::<f64>()
        / 12.0
}

// ---------------------------------------------------------------------------------------------
// Synthetic chart
// ---------------------------------------------------------------------------------------------

/// The light the synthetic chart is rendered under, as linear-sRGB white gains.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Illuminant {
    D65,
    D50,
    A,
    /// Explicit linear RGB gains.
    Gains([f64; 3]),
}

impl Illuminant {
    /// Linear-sRGB gains: the D65 white adapted to the illuminant's white by the Bradford
    /// transform, in linear sRGB (M = sRGB⁻¹ · Bradford(D65 → W) · sRGB, gains = M · (1, 1, 1)).
    /// The adapted white has luminance Y = 1, so the gains keep luminance. D65 gives (1, 1, 1).
    /// Multiplying the reference RGB by these gains is a von Kries-type RGB approximation of the
    /// chart under that light: only RGB reflectances are known, not spectra.
    pub fn gains(&self) -> [f64; 3] {
        let white = match self {
            Illuminant::D65 => return [1.0; 3],
            Illuminant::D50 => D50_XY,
            Illuminant::A => A_XY,
            Illuminant::Gains(g) => return *g,
        };
        let cat = bradford(xy_to_xyz(D65_XY), xy_to_xyz(white)).expect("D65 adapts");
        let inv = inverse3(&SRGB_TO_XYZ).expect("sRGB matrix is invertible");
        let m = mul3(&inv, &mul3(&cat, &SRGB_TO_XYZ));
        mat_vec(&m, [1.0; 3])
    }
}

impl FromStr for Illuminant {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_uppercase().as_str() {
            "D65" => Ok(Illuminant::D65),
            "D50" => Ok(Illuminant::D50),
            "A" => Ok(Illuminant::A),
            _ => {
                const KEY: &str = "illuminant gains";
                let v = floats(s, 3).ok_or_else(|| {
                    Error::key(
                        KEY,
                        format!("{} (or one of D65, D50, A)", expected_floats(s, 3)),
                    )
                })?;
                if v.iter().any(|g| *g <= 0.0) {
                    return Err(Error::key(KEY, format!("'{s}' must be > 0")));
                }
                Ok(Illuminant::Gains([v[0], v[1], v[2]]))
            }
        }
    }
}

impl fmt::Display for Illuminant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Illuminant::D65 => write!(f, "D65"),
            Illuminant::D50 => write!(f, "D50"),
            Illuminant::A => write!(f, "A"),
            Illuminant::Gains(g) => write!(f, "{},{},{}", g[0], g[1], g[2]),
        }
    }
}

/// The patch colours of the synthetic chart: reference linear sRGB × illuminant gains × exposure.
pub fn chart_colours(illuminant: &Illuminant, exposure: f64) -> Vec<[f64; 3]> {
    let g = illuminant.gains();
    COLORCHECKER24
        .iter()
        .map(|p| std::array::from_fn(|c| p.linear_srgb[c] * g[c] * exposure))
        .collect()
}

/// Render the chart: the 24 patches fill the frame as a 6 × 4 grid of equal cells in reading
/// order (patch 1 top-left); pixel (x, y) belongs to the cell holding its centre. Linear values
/// = reference linear sRGB × illuminant gains × exposure, not clipped. A frame smaller than
/// 6 × 4 cannot show every patch; sampling it fails.
pub fn render_chart(width: usize, height: usize, illuminant: &Illuminant, exposure: f64) -> Image {
    let colours = chart_colours(illuminant, exposure);
    Image::from_fn(width, height, |x, y| {
        let i =
            (((x as f64 + 0.5) / width as f64 * CHART_COLS as f64) as usize).min(CHART_COLS - 1);
        let j =
            (((y as f64 + 0.5) / height as f64 * CHART_ROWS as f64) as usize).min(CHART_ROWS - 1);
        colours[j * CHART_COLS + i].map(|v| v as f32)
    })
}

// ---------------------------------------------------------------------------------------------
// Locating and sampling the chart
// ---------------------------------------------------------------------------------------------

/// A projective map (3×3, h[2][2] = 1) from chart coordinates (u, v) ∈ [0, 6] × [0, 4] to image
/// pixel coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Homography(pub Mat3);

impl Homography {
    /// The homography taking the four `src` points to the four `dst` points.
    pub fn from_points(src: [[f64; 2]; 4], dst: [[f64; 2]; 4]) -> Result<Homography> {
        let mut a = [[0.0f64; 9]; 8];
        for k in 0..4 {
            let [x, y] = src[k];
            let [u, v] = dst[k];
            a[2 * k] = [x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, u];
            a[2 * k + 1] = [0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, v];
        }
        // Gaussian elimination with partial pivoting on the 8×8 system.
        for col in 0..8 {
            let piv = (col..8)
                .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
                .expect("non-empty");
            if a[piv][col].abs() < 1e-12 {
                return Err(Error::key(CORNERS, "degenerate (three of them on a line?)"));
            }
            a.swap(col, piv);
            for r in 0..8 {
                if r != col {
                    let f = a[r][col] / a[col][col];
                    for c in col..9 {
                        a[r][c] -= f * a[col][c];
                    }
                }
            }
        }
        let h: Vec<f64> = (0..8).map(|r| a[r][8] / a[r][r]).collect();
        Ok(Homography([
            [h[0], h[1], h[2]],
            [h[3], h[4], h[5]],
            [h[6], h[7], 1.0],
        ]))
    }

    /// Chart (6 × 4 cells) → image through the four image corners of the patch area: top-left,
    /// top-right, bottom-right, bottom-left.
    pub fn chart_to_image(corners: [[f64; 2]; 4]) -> Result<Homography> {
        let (w, h) = (CHART_COLS as f64, CHART_ROWS as f64);
        Homography::from_points([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]], corners)
    }

    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let q = mat_vec(&self.0, [p[0], p[1], 1.0]);
        [q[0] / q[2], q[1] / q[2]]
    }

    pub fn inverse(&self) -> Option<Homography> {
        inverse3(&self.0).map(Homography)
    }
}

/// Where the chart's 6 × 4 patch area lies in an image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChartRegion {
    /// The chart fills the frame (what [`render_chart`] makes).
    FullFrame,
    /// Image coordinates of the patch area's corners: top-left, top-right, bottom-right,
    /// bottom-left (the outer corners of patches 1, 6, 24 and 19).
    Corners([[f64; 2]; 4]),
}

impl ChartRegion {
    /// Parse `x0,y0,x1,y1,x2,y2,x3,y3` (top-left, top-right, bottom-right, bottom-left).
    pub fn parse_corners(s: &str) -> Result<ChartRegion> {
        let v = parse_floats(s, 8, "chart corners (x0,y0,x1,y1,x2,y2,x3,y3)")?;
        Ok(ChartRegion::Corners(std::array::from_fn(|k| {
            [v[2 * k], v[2 * k + 1]]
        })))
    }

    pub fn corners(&self, width: usize, height: usize) -> [[f64; 2]; 4] {
        match self {
            ChartRegion::FullFrame => {
                let (w, h) = (width as f64, height as f64);
                [[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]]
            }
            ChartRegion::Corners(c) => *c,
        }
    }
}

impl fmt::Display for ChartRegion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ChartRegion::FullFrame => write!(f, "full frame"),
            ChartRegion::Corners(c) => {
                let s: Vec<String> = c.iter().flatten().map(|v| format!("{v}")).collect();
                write!(f, "{}", s.join(","))
            }
        }
    }
}

/// One sampled patch: mean and sample standard deviation per channel over its pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchSample {
    pub mean: [f64; 3],
    pub std: [f64; 3],
    pub pixels: usize,
}

/// Fewest pixels a patch's sampling window may hold.
pub const MIN_PATCH_PIXELS: usize = 4;
/// A patch is clipped when any sampled pixel has a channel at or above this fraction of the
/// clip level.
pub const CLIP_FRACTION: f64 = 0.98;

/// Sample the 24 patches: each cell's central half (chart coordinates [i + ¼, i + ¾) ×
/// [j + ¼, j + ¾)), pixels taken by their centres mapped back through the homography, so gaps
/// between patches, edges and blur stay out of the means. With `clip_level` Some(c), a patch with
/// any channel of any sampled pixel ≥ 0.98 · c is an error naming the patch. A window outside the
/// image or with fewer than 4 pixels is an error too.
pub fn sample_chart(
    img: &Image,
    region: &ChartRegion,
    clip_level: Option<f64>,
) -> Result<Vec<PatchSample>> {
    let corners = region.corners(img.width, img.height);
    let h = Homography::chart_to_image(corners)?;
    let inv = h
        .inverse()
        .ok_or_else(|| Error::key(CORNERS, "a singular mapping"))?;
    check_convex(&corners, region)?;
    let mut out = Vec::with_capacity(24);
    for (p, patch) in COLORCHECKER24.iter().enumerate() {
        let vals = patch_pixels(img, &h, &inv, p, patch)?;
        if let Some(clip) = clip_level {
            check_unclipped(patch, &vals, clip)?;
        }
        out.push(PatchSample::of(&vals));
    }
    Ok(out)
}

/// What corner errors name: the patch area's corners, as a flag or the full frame gives them.
const CORNERS: &str = "chart corners";

/// The patch area must be a convex quadrilateral in the given order (no flips or bow-ties).
fn check_convex(corners: &[[f64; 2]; 4], region: &ChartRegion) -> Result<()> {
    let cross = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
    };
    let turns: Vec<f64> = (0..4)
        .map(|k| cross(corners[k], corners[(k + 1) % 4], corners[(k + 2) % 4]))
        .collect();
    if !(turns.iter().all(|&t| t > 0.0) || turns.iter().all(|&t| t < 0.0)) {
        return Err(Error::key(
            CORNERS,
            format!(
                "{region} do not form a convex quadrilateral in the order top-left, top-right, \
                 bottom-right, bottom-left"
            ),
        ));
    }
    Ok(())
}

/// The pixels of patch `p`'s sampling window (the cell's central half, mapped into the image
/// by `h`; `inv` maps pixel centres back), at least [`MIN_PATCH_PIXELS`] of them.
fn patch_pixels(
    img: &Image,
    h: &Homography,
    inv: &Homography,
    p: usize,
    patch: &Patch,
) -> Result<Vec<[f64; 3]>> {
    let (w, hgt) = (img.width as f64, img.height as f64);
    let (i, j) = ((p % CHART_COLS) as f64, (p / CHART_COLS) as f64);
    let (u0, u1, v0, v1) = (i + 0.25, i + 0.75, j + 0.25, j + 0.75);
    let quad = [[u0, v0], [u1, v0], [u1, v1], [u0, v1]].map(|q| h.apply(q));
    if quad
        .iter()
        .any(|q| !(q[0] >= 0.0 && q[0] <= w && q[1] >= 0.0 && q[1] <= hgt))
    {
        return Err(Error::Invalid(format!(
            "patch {} ({}): its sampling window lies outside the {}×{} image; check the \
             chart corners",
            patch.number, patch.name, img.width, img.height
        )));
    }
    let xmin = quad
        .iter()
        .map(|q| q[0])
        .fold(f64::INFINITY, f64::min)
        .floor()
        .max(0.0) as usize;
    let xmax = (quad
        .iter()
        .map(|q| q[0])
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil() as usize)
        .min(img.width);
    let ymin = quad
        .iter()
        .map(|q| q[1])
        .fold(f64::INFINITY, f64::min)
        .floor()
        .max(0.0) as usize;
    let ymax = (quad
        .iter()
        .map(|q| q[1])
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil() as usize)
        .min(img.height);
    let mut vals: Vec<[f64; 3]> = Vec::new();
    for y in ymin..ymax {
        for x in xmin..xmax {
            let [u, v] = inv.apply([x as f64 + 0.5, y as f64 + 0.5]);
            if u >= u0 && u < u1 && v >= v0 && v < v1 {
                let px = img.get(x, y);
                vals.push([px[0] as f64, px[1] as f64, px[2] as f64]);
            }
        }
    }
    if vals.len() < MIN_PATCH_PIXELS {
        return Err(Error::Invalid(format!(
            "patch {} ({}): only {} pixels in its sampling window (need {MIN_PATCH_PIXELS}); \
             the chart is too small in the image or the corners are wrong",
            patch.number,
            patch.name,
            vals.len()
        )));
    }
    Ok(vals)
}

/// A clipped patch is an error: any sampled value at or above [`CLIP_FRACTION`] × `clip`.
fn check_unclipped(patch: &Patch, vals: &[[f64; 3]], clip: f64) -> Result<()> {
    let limit = CLIP_FRACTION * clip;
    let mut worst: Option<(usize, f64)> = None;
    let mut count = 0usize;
    for v in vals {
        for c in 0..3 {
            if v[c] >= limit {
                count += 1;
                if worst.is_none_or(|(_, w)| v[c] > w) {
                    worst = Some((c, v[c]));
                }
            }
        }
    }
    if let Some((c, v)) = worst {
        return Err(Error::Invalid(format!(
            "patch {} ({}) is clipped: {count} sampled values at or above {:.4} \
             ({CLIP_FRACTION} × clip level {clip}), up to {v:.4} in channel {}; lower \
             the exposure or leave it out of the capture",
            patch.number,
            patch.name,
            limit,
            ["R", "G", "B"][c]
        )));
    }
    Ok(())
}

impl PatchSample {
    /// Mean and sample standard deviation (0 for one pixel) of a patch's pixels.
    fn of(vals: &[[f64; 3]]) -> PatchSample {
        let n = vals.len() as f64;
        let mean: [f64; 3] = std::array::from_fn(|c| vals.iter().map(|v| v[c]).sum::<f64>() / n);
        let std: [f64; 3] = std::array::from_fn(|c| {
            if vals.len() < 2 {
                0.0
            } else {
                (vals.iter().map(|v| (v[c] - mean[c]).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
            }
        });
        PatchSample {
            mean,
            std,
            pixels: vals.len(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn d65_gains_are_one_and_a_is_warm() {
        assert_eq!(Illuminant::D65.gains(), [1.0; 3]);
        let a = Illuminant::A.gains();
        assert!(a[0] > 1.5 && a[2] < 0.3, "{a:?}");
        let y = 0.2126 * a[0] + 0.7152 * a[1] + 0.0722 * a[2];
        assert!((y - 1.0).abs() < 1e-3, "{y}");
    }

    #[test]
    fn homography_round_trip() {
        let c = [[10.0, 20.0], [200.0, 5.0], [220.0, 150.0], [5.0, 160.0]];
        let h = Homography::chart_to_image(c).unwrap();
        for (k, p) in [[0.0, 0.0], [6.0, 0.0], [6.0, 4.0], [0.0, 4.0]]
            .iter()
            .enumerate()
        {
            let q = h.apply(*p);
            assert!((q[0] - c[k][0]).abs() < 1e-9 && (q[1] - c[k][1]).abs() < 1e-9);
        }
    }
}
