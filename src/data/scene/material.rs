//! Surface materials: procedural albedo textures with fine detail, evaluated in the surface's
//! own coordinates (so a moving subject carries its texture with it).

use super::noise::{band_weight, cell_random, fbm};
use crate::rng::Rng;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pattern {
    /// Mottled stone/plaster: two colours mixed by fractal noise.
    Noise,
    /// Running-bond bricks with mortar, per-brick tint and surface grain.
    Bricks,
    /// Square tiles in two colours with grout lines.
    Tiles,
    /// Fine parallel stripes (fabric, blinds, siding): detail near the pixel scale.
    Stripes,
    /// Wood-like rings distorted by noise.
    Wood,
}

#[derive(Clone, Debug)]
pub struct Material {
    pub pattern: Pattern,
    pub c1: [f32; 3],
    pub c2: [f32; 3],
    /// Pattern frequency in cycles per world unit.
    pub freq: f32,
    pub seed: u32,
}

#[inline]
fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

#[inline]
fn scale(a: [f32; 3], s: f32) -> [f32; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Coverage in [0,1] of a line of half-width `hw` at signed distance `d` (same units as `px`).
#[inline]
fn line_cov(d: f32, hw: f32, px: f32) -> f32 {
    (0.5 + (hw - d.abs()) / px.max(1e-9)).clamp(0.0, 1.0)
}

impl Material {
    /// A random material with albedos in [0.03, 0.85].
    pub fn random(rng: &mut Rng) -> Material {
        let pattern = *rng.pick(&[
            Pattern::Noise,
            Pattern::Bricks,
            Pattern::Tiles,
            Pattern::Stripes,
            Pattern::Wood,
        ]);
        let base = random_albedo(rng);
        let other = random_albedo(rng);
        let freq = match pattern {
            Pattern::Noise => rng.stops(2.0, 4.0),
            Pattern::Bricks => rng.stops(3.0, 4.5),
            Pattern::Tiles => rng.stops(2.5, 4.0),
            Pattern::Stripes => rng.stops(5.0, 8.0),
            Pattern::Wood => rng.stops(2.5, 4.0),
        };
        Material {
            pattern,
            c1: base,
            c2: other,
            freq,
            seed: rng.next_u64() as u32,
        }
    }

    /// Albedo at texture coordinates (u, v) for a pixel of size `px` (same units).
    #[inline]
    pub fn albedo(&self, u: f32, v: f32, px: f32) -> [f32; 3] {
        let f = self.freq;
        // Surface grain: fine fractal detail everywhere, starting 8× above the pattern scale.
        let grain = 1.0 + 0.18 * fbm(self.seed ^ 0x51ed, u, v, f * 8.0, 0.6, px);
        let c = match self.pattern {
            Pattern::Noise => {
                let t = 0.5 + 0.5 * fbm(self.seed, u, v, f, 0.55, px);
                mix(self.c1, self.c2, t.clamp(0.0, 1.0))
            }
            Pattern::Bricks => {
                let bw = 1.0 / f; // brick width
                let bh = bw / 3.0;
                let row = (v / bh).floor();
                let uu = u / bw + 0.5 * (row.rem_euclid(2.0));
                let col = uu.floor();
                let tint = cell_random(self.seed, col as i32, row as i32);
                let brick = mix(self.c1, scale(self.c1, 0.6), tint);
                let fu = (uu - col - 0.5) * bw; // distance from brick centre, world units
                let fv = (v / bh - row - 0.5) * bh;
                let mortar_hw = bh * 0.07;
                let cov = line_cov(bw * 0.5 - fu.abs(), mortar_hw, px).max(line_cov(
                    bh * 0.5 - fv.abs(),
                    mortar_hw,
                    px,
                ));
                mix(brick, self.c2, cov * band_weight(f * 3.0, px))
            }
            Pattern::Tiles => {
                let s = 1.0 / f;
                let (iu, iv) = ((u / s).floor(), (v / s).floor());
                let check = (iu + iv).rem_euclid(2.0);
                let tile = mix(self.c1, self.c2, check);
                let fu = (u / s - iu - 0.5) * s;
                let fv = (v / s - iv - 0.5) * s;
                let cov = line_cov(s * 0.5 - fu.abs(), s * 0.03, px).max(line_cov(
                    s * 0.5 - fv.abs(),
                    s * 0.03,
                    px,
                ));
                mix(tile, [0.05, 0.05, 0.05], cov * band_weight(f * 8.0, px))
            }
            Pattern::Stripes => {
                // Sinusoidal stripes fade to their mean where they would alias.
                let w = band_weight(f, px);
                let t = 0.5 + 0.5 * w * (u * f * std::f32::consts::TAU).sin();
                mix(self.c1, self.c2, t)
            }
            Pattern::Wood => {
                // Rings 1/(4f) apart, warped by at most ~a third of a ring so the grain stays
                // wood-like instead of turning into zebra stripes.
                let ring = 1.0 / (4.0 * f);
                let r = (u * u + 0.05 * v * v).sqrt()
                    + 0.35 * ring * fbm(self.seed, u, v, f * 0.5, 0.5, px);
                let w = band_weight(f * 4.0, px);
                let t = 0.5 + 0.35 * w * (r / ring * std::f32::consts::TAU).sin();
                mix(self.c1, self.c2, t)
            }
        };
        [
            (c[0] * grain).clamp(0.02, 0.95),
            (c[1] * grain).clamp(0.02, 0.95),
            (c[2] * grain).clamp(0.02, 0.95),
        ]
    }
}

/// A plausible diffuse albedo: log-uniform brightness in [0.03, 0.8], moderate saturation.
pub fn random_albedo(rng: &mut Rng) -> [f32; 3] {
    let l = rng.stops(-5.0, -0.35);
    let hue = rng.f32() * std::f32::consts::TAU;
    let sat = rng.range(0.0, 0.6);
    let c = [
        1.0 + sat * hue.cos(),
        1.0 + sat * (hue - 2.094).cos(),
        1.0 + sat * (hue + 2.094).cos(),
    ];
    let lum = crate::io::luminance(c);
    [c[0] / lum * l, c[1] / lum * l, c[2] / lum * l].map(|x| x.clamp(0.02, 0.95))
}
