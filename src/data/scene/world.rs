//! The static part of a scene: a procedural street/interior world or a real radiance map,
//! as a pure function radiance(x, y) of world position.
//!
//! Units: scene-linear relative radiance; a white diffuse surface in full sun is ~0.9. The
//! world spans [0, WORLD_W] × [0, WORLD_H], y pointing down. Light levels are drawn in stops
//! so one world spans > 16 stops: sun disc 2^15–2^17, lamps 2^8–2^11, sunlit surfaces ~2^0,
//! shade 2^-3–2^-5, interiors 2^-5–2^-7, doorways and dark windows 2^-9–2^-11 (× albedo).

use super::material::Material;
use super::noise::fbm;
use crate::io::Image;
use crate::rng::Rng;
use std::sync::Arc;

pub const WORLD_W: f32 = 1.6;
pub const WORLD_H: f32 = 1.2;

#[derive(Clone, Debug)]
pub struct Rect {
    pub x0: f32,
    pub y0: f32,
    pub x1: f32,
    pub y1: f32,
}

impl Rect {
    /// Signed distance (negative inside), exact for axis-aligned boxes.
    #[inline]
    pub fn sdf(&self, x: f32, y: f32) -> f32 {
        let cx = 0.5 * (self.x0 + self.x1);
        let cy = 0.5 * (self.y0 + self.y1);
        let dx = (x - cx).abs() - 0.5 * (self.x1 - self.x0);
        let dy = (y - cy).abs() - 0.5 * (self.y1 - self.y0);
        let out = (dx.max(0.0).powi(2) + dy.max(0.0).powi(2)).sqrt();
        out + dx.max(dy).min(0.0)
    }
}

/// Anti-aliased coverage of a shape with signed distance `d` at pixel size `px`; exactly 0
/// half a pixel outside the edge, so shapes never touch pixels beyond that.
#[inline]
pub fn coverage(d: f32, px: f32) -> f32 {
    (0.5 - d / px).clamp(0.0, 1.0)
}

/// A cast shadow: the half-plane n·p > c, with a penumbra of width `soft`.
#[derive(Clone, Debug)]
struct Shadow {
    nx: f32,
    ny: f32,
    c: f32,
    soft: f32,
}

#[derive(Clone, Debug)]
enum WindowKind {
    /// Unlit room behind: deep shadow with faint texture.
    Dark,
    /// Lit room behind: emissive, warm.
    Lit([f32; 3]),
    /// Glass reflecting the sky.
    Reflect,
}

#[derive(Clone, Debug)]
struct Facade {
    rect: Rect,
    material: Material,
    /// Window grid: columns, rows, window size as a fraction of the cell.
    cols: usize,
    rows: usize,
    fill: f32,
    door: Option<Rect>,
    seed: u32,
}

#[derive(Clone, Debug)]
pub struct Lamp {
    pub x: f32,
    pub y: f32,
    pub r: f32,
    pub radiance: [f32; 3],
}

#[derive(Clone, Debug)]
struct Interior {
    material: Material,
    /// Ambient irradiance of the room.
    e: f32,
    openings: Vec<Rect>,
    /// Window bars (mullions) across the openings: half-width.
    bar: f32,
}

/// A real HDR radiance map covering the world ("cover" fit, centred).
#[derive(Clone, Debug)]
pub struct RealBackground {
    pub image: Arc<Image>,
    /// Radiance multiplier (normalises the map's median).
    pub gain: f32,
    /// World units per source pixel, and the world position of the source's (0,0).
    unit: f32,
    ox: f32,
    oy: f32,
}

#[derive(Clone, Debug)]
pub struct World {
    seed: u32,
    ground_y: f32,
    horizon: f32,
    sky_zenith: [f32; 3],
    sky_horizon: [f32; 3],
    sun: Option<Lamp>,
    shade_e: f32,
    deep_e: f32,
    shadows: Vec<Shadow>,
    facades: Vec<Facade>,
    ground: Material,
    lamps: Vec<Lamp>,
    interior: Option<Interior>,
    real: Option<RealBackground>,
}

#[inline]
fn add(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline]
fn mul(a: [f32; 3], s: f32) -> [f32; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline]
fn lerp(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

fn warm_light(rng: &mut Rng, level: f32) -> [f32; 3] {
    // Tungsten-to-neutral tints.
    let t = rng.f32();
    let c = [1.0, 0.75 + 0.2 * t, 0.45 + 0.45 * t];
    let lum = crate::io::luminance(c);
    mul(c, level / lum)
}

impl World {
    /// A procedural world, deterministic in `rng`.
    pub fn procedural(rng: &mut Rng) -> World {
        let seed = rng.next_u64() as u32;
        let horizon = rng.range(0.35, 0.6);
        let ground_y = horizon + rng.range(0.15, 0.35);
        let sky_level = rng.stops(-1.5, 0.5);
        let sky_zenith = mul([0.35, 0.55, 1.0], sky_level);
        let sky_horizon = mul([0.85, 0.9, 1.0], sky_level * 1.8);
        let sun = rng.chance(0.75).then(|| Lamp {
            x: rng.range(0.1, WORLD_W - 0.1),
            y: rng.range(0.05, horizon * 0.8),
            r: rng.range(0.006, 0.014),
            radiance: mul([1.0, 0.97, 0.9], rng.stops(15.0, 17.0)),
        });
        let shade_e = rng.stops(-7.0, -4.0);
        let deep_e = rng.stops(-11.0, -9.0);
        let shadows = (0..rng.int(1, 3))
            .map(|_| {
                let a = rng.range(0.3, 1.3);
                let (nx, ny) = (a.cos(), a.sin());
                // Through a point in the lower half so every world has shade on the ground.
                let px = rng.range(0.2, WORLD_W - 0.2);
                let py = rng.range(horizon, WORLD_H - 0.1);
                Shadow {
                    nx,
                    ny,
                    c: nx * px + ny * py,
                    soft: rng.range(0.002, 0.02),
                }
            })
            .collect();
        let mut facades = Vec::new();
        let n = rng.int(4, 8);
        for _ in 0..n {
            let w = rng.range(0.2, 0.6);
            let x0 = rng.range(-0.1, WORLD_W - w + 0.1);
            let top = rng.range(0.02, horizon + 0.05);
            let rect = Rect {
                x0,
                y0: top,
                x1: x0 + w,
                y1: ground_y + 0.01,
            };
            let door = rng.chance(0.9).then(|| {
                let dw = rng.range(0.05, 0.12);
                let dx = rng.range(x0 + 0.02, x0 + w - dw - 0.02);
                Rect {
                    x0: dx,
                    y0: ground_y - rng.range(0.1, 0.2),
                    x1: dx + dw,
                    y1: ground_y + 0.01,
                }
            });
            facades.push(Facade {
                rect,
                material: Material::random(rng),
                cols: rng.int(2, 6),
                rows: rng.int(2, 7),
                fill: rng.range(0.35, 0.7),
                door,
                seed: rng.next_u64() as u32,
            });
        }
        let interior = rng.chance(0.5).then(|| {
            let mut openings = Vec::new();
            for _ in 0..rng.int(1, 2) {
                let w = rng.range(0.25, 0.6);
                let h = rng.range(0.25, 0.55);
                let x0 = rng.range(0.05, WORLD_W - w - 0.05);
                let y0 = rng.range(0.1, WORLD_H - h - 0.2);
                openings.push(Rect {
                    x0,
                    y0,
                    x1: x0 + w,
                    y1: y0 + h,
                });
            }
            Interior {
                material: Material::random(rng),
                e: rng.stops(-7.0, -5.0),
                openings,
                bar: rng.range(0.003, 0.008),
            }
        });
        let mut lamps = Vec::new();
        for _ in 0..rng.int(3, 8) {
            let (lo, hi) = if interior.is_some() {
                (6.0, 9.0)
            } else {
                (8.0, 11.0)
            };
            let level = rng.stops(lo, hi);
            lamps.push(Lamp {
                x: rng.range(0.05, WORLD_W - 0.05),
                y: rng.range(0.1, ground_y - 0.05),
                r: rng.range(0.008, 0.022),
                radiance: warm_light(rng, level),
            });
        }
        World {
            seed,
            ground_y,
            horizon,
            sky_zenith,
            sky_horizon,
            sun,
            shade_e,
            deep_e,
            shadows,
            facades,
            ground: Material::random(rng),
            lamps,
            interior,
            real: None,
        }
    }

    /// A world whose background is a real radiance map, with the median luminance scaled to
    /// 2^U(−3.5, −1.5) (mid grey ≈ 0.18 ≈ 2^−2.5) and the same sunlight model for subjects.
    pub fn real(rng: &mut Rng, image: Arc<Image>) -> World {
        let mut world = World::procedural(rng);
        let mut lum: Vec<f32> = image.luminance().into_iter().filter(|v| *v > 0.0).collect();
        let median = if lum.is_empty() {
            1.0
        } else {
            let mid = lum.len() / 2;
            *lum.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1
        };
        let gain = rng.stops(-3.5, -1.5) / median.max(1e-12);
        // Cover fit: the map fills the world, cropped on one axis, centred.
        let unit = (WORLD_W / image.width as f32).min(WORLD_H / image.height as f32);
        let ox = 0.5 * (WORLD_W - image.width as f32 * unit);
        let oy = 0.5 * (WORLD_H - image.height as f32 * unit);
        world.real = Some(RealBackground {
            image,
            gain,
            unit,
            ox,
            oy,
        });
        world.interior = None;
        world.lamps.clear();
        world
    }

    /// Outdoor irradiance at a point: sun unless inside a cast shadow (soft edge), plus shade.
    #[inline]
    fn outdoor_e(&self, x: f32, y: f32) -> f32 {
        let mut shadow = 0.0f32;
        for s in &self.shadows {
            let d = (s.nx * x + s.ny * y - s.c) / s.soft;
            shadow = shadow.max((d + 0.5).clamp(0.0, 1.0));
        }
        (1.0 - shadow) + self.shade_e
    }

    /// Irradiance inside the room: ambient plus inverse-square-ish light from the lamps.
    #[inline]
    fn interior_e(&self, room: &Interior, x: f32, y: f32) -> f32 {
        let mut e = room.e;
        for l in &self.lamps {
            let d2 = (x - l.x).powi(2) + (y - l.y).powi(2);
            let lum = crate::io::luminance(l.radiance);
            e += lum * l.r * l.r * 0.02 / (d2 + 0.01);
        }
        e
    }

    /// Irradiance for a foreground subject at (x, y).
    #[inline]
    pub fn subject_irradiance(&self, x: f32, y: f32) -> f32 {
        match &self.interior {
            Some(room) => self.interior_e(room, x, y),
            None => self.outdoor_e(x, y),
        }
    }

    fn sky(&self, x: f32, y: f32, px: f32) -> [f32; 3] {
        let t = (y / self.horizon.max(1e-3)).clamp(0.0, 1.0);
        let mut c = lerp(self.sky_zenith, self.sky_horizon, t * t);
        let cloud = (fbm(self.seed ^ 0xc10d, x, y * 2.5, 2.0, 0.5, px) - 0.1).max(0.0);
        c = lerp(
            c,
            mul([1.0, 1.0, 1.0], 2.5 * self.sky_horizon[1]),
            (cloud * 1.6).min(1.0),
        );
        if let Some(sun) = &self.sun {
            let d = ((x - sun.x).powi(2) + (y - sun.y).powi(2)).sqrt();
            let cov = coverage(d - sun.r, px);
            // Aureole: scattered sunlight falling off with the square of angular distance.
            let halo = (sun.r / d.max(sun.r)).powi(2) * (2.0f32).powi(-10);
            c = add(
                lerp(c, sun.radiance, cov),
                mul(sun.radiance, halo * (1.0 - cov)),
            );
        }
        c
    }

    fn facade(&self, f: &Facade, x: f32, y: f32, px: f32) -> [f32; 3] {
        let e = self.outdoor_e(x, y);
        let u = x - f.rect.x0;
        let v = y - f.rect.y0;
        let wall = mul(f.material.albedo(u, v, px), e);
        if let Some(door) = &f.door {
            let cov = coverage(door.sdf(x, y), px);
            if cov > 0.0 {
                let inside = self.deep(f.seed, x, y, px);
                return lerp(wall, inside, cov);
            }
        }
        // Window grid in the upper part of the facade (above the door zone).
        let h = (self.ground_y - 0.22 - f.rect.y0).max(0.0);
        if h <= 0.0 || v > h {
            return wall;
        }
        let cw = (f.rect.x1 - f.rect.x0) / f.cols as f32;
        let ch = h / f.rows as f32;
        let (ci, cj) = ((u / cw).floor(), (v / ch).floor());
        let cx = (ci + 0.5) * cw;
        let cy = (cj + 0.5) * ch;
        let win = Rect {
            x0: cx - 0.5 * cw * f.fill,
            y0: cy - 0.5 * ch * f.fill,
            x1: cx + 0.5 * cw * f.fill,
            y1: cy + 0.5 * ch * f.fill,
        };
        let cov = coverage(win.sdf(u, v), px);
        if cov <= 0.0 {
            return wall;
        }
        let r = super::noise::cell_random(f.seed, ci as i32, cj as i32);
        let kind = if r < 0.55 {
            WindowKind::Dark
        } else if r < 0.7 {
            let t = super::noise::cell_random(f.seed ^ 1, ci as i32, cj as i32);
            WindowKind::Lit(mul([1.0, 0.8, 0.55], (1.0 + 3.0 * t).exp2()))
        } else {
            WindowKind::Reflect
        };
        let glass = match kind {
            WindowKind::Dark => self.deep(f.seed ^ 7, x, y, px),
            WindowKind::Lit(c) => mul(c, 0.8 + 0.2 * fbm(f.seed ^ 3, u, v, 30.0, 0.5, px)),
            WindowKind::Reflect => mul(self.sky(x, self.horizon - (y - f.rect.y0) * 0.5, px), 0.6),
        };
        lerp(wall, glass, cov)
    }

    /// The deep-shadow interior of a doorway or dark window: textured, at 2^-9..2^-11.
    #[inline]
    fn deep(&self, seed: u32, x: f32, y: f32, px: f32) -> [f32; 3] {
        let t = 0.5 + 0.5 * fbm(seed ^ 0xdee9, x, y, 20.0, 0.6, px);
        mul(
            [0.6, 0.5, 0.4],
            self.deep_e * (0.15 + 0.85 * t.clamp(0.0, 1.0)),
        )
    }

    fn outdoor(&self, x: f32, y: f32, px: f32) -> [f32; 3] {
        // Front to back: ground, facades (last drawn is frontmost), sky.
        let mut acc = [0.0; 3];
        let mut alpha = 0.0f32;
        let g = coverage(self.ground_y - y, px);
        if g > 0.0 {
            let c = mul(self.ground.albedo(x, y * 3.0, px), self.outdoor_e(x, y));
            acc = add(acc, mul(c, g));
            alpha += g;
        }
        for f in self.facades.iter().rev() {
            if alpha >= 1.0 {
                break;
            }
            let cov = coverage(f.rect.sdf(x, y), px);
            if cov > 0.0 {
                let c = self.facade(f, x, y, px);
                let w = cov * (1.0 - alpha);
                acc = add(acc, mul(c, w));
                alpha += w;
            }
        }
        if alpha < 1.0 {
            acc = add(acc, mul(self.sky(x, y, px), 1.0 - alpha));
        }
        acc
    }

    fn real_sample(&self, bg: &RealBackground, x: f32, y: f32) -> [f32; 3] {
        let img = &bg.image;
        let sx = ((x - bg.ox) / bg.unit - 0.5).clamp(0.0, (img.width - 1) as f32);
        let sy = ((y - bg.oy) / bg.unit - 0.5).clamp(0.0, (img.height - 1) as f32);
        let (x0, y0) = (sx.floor() as usize, sy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(img.width - 1), (y0 + 1).min(img.height - 1));
        let (fx, fy) = (sx - x0 as f32, sy - y0 as f32);
        let a = lerp(img.get(x0, y0), img.get(x1, y0), fx);
        let b = lerp(img.get(x0, y1), img.get(x1, y1), fx);
        mul(lerp(a, b, fy), bg.gain)
    }

    /// Scene radiance at world position (x, y) seen through a pixel of size `px`.
    pub fn radiance(&self, x: f32, y: f32, px: f32) -> [f32; 3] {
        if let Some(bg) = &self.real {
            return self.real_sample(bg, x, y);
        }
        // Lamps are frontmost (fixtures on walls/poles), then the room wall, then outdoors.
        let mut acc = [0.0; 3];
        let mut alpha = 0.0f32;
        for l in &self.lamps {
            let d = ((x - l.x).powi(2) + (y - l.y).powi(2)).sqrt();
            let cov = coverage(d - l.r, px);
            if cov > 0.0 {
                // Slight falloff across the lamp's face, like a diffuser.
                let fall = 1.0 - 0.5 * (d / l.r).min(1.0).powi(2);
                let w = cov * (1.0 - alpha);
                acc = add(acc, mul(l.radiance, fall * w));
                alpha += w;
            }
        }
        if alpha < 1.0 {
            let behind = match &self.interior {
                Some(room) => {
                    let open = room
                        .openings
                        .iter()
                        .map(|o| o.sdf(x, y))
                        .fold(f32::INFINITY, f32::min);
                    let open_cov = coverage(open, px);
                    let wall_cov = 1.0 - open_cov;
                    let mut c = [0.0; 3];
                    if wall_cov > 0.0 {
                        let a = room.material.albedo(x, y, px);
                        c = mul(a, self.interior_e(room, x, y) * wall_cov);
                    }
                    if open_cov > 0.0 {
                        // Mullions: a cross of dark bars through each opening's centre.
                        let bar = room
                            .openings
                            .iter()
                            .map(|o| {
                                let cx = 0.5 * (o.x0 + o.x1);
                                let cy = 0.5 * (o.y0 + o.y1);
                                ((x - cx).abs() - room.bar).min((y - cy).abs() - room.bar)
                            })
                            .fold(f32::INFINITY, f32::min);
                        let bar_cov = coverage(bar, px);
                        let out = self.outdoor(x, y, px);
                        let frame = mul([0.08, 0.07, 0.06], self.interior_e(room, x, y));
                        c = add(c, mul(lerp(out, frame, bar_cov), open_cov));
                    }
                    c
                }
                None => self.outdoor(x, y, px),
            };
            acc = add(acc, mul(behind, 1.0 - alpha));
        }
        acc
    }

    /// The world's lamps (for tests and metadata).
    pub fn lamps(&self) -> &[Lamp] {
        &self.lamps
    }
}
