//! Foreground subjects with motion: rigid shapes (translation + rotation) and articulated
//! figures (a kinematic chain of limbs whose joint angles change over time). Time t is in
//! frame intervals relative to the reference frame (t = 0 is the static pose).

use super::material::Material;
use super::world::coverage;
use crate::rng::Rng;

#[derive(Clone, Debug)]
pub enum Shape {
    Ellipse {
        a: f32,
        b: f32,
    },
    /// Regular polygon with `n` sides and circumradius `r`.
    Polygon {
        n: usize,
        r: f32,
    },
    RoundRect {
        hw: f32,
        hh: f32,
        r: f32,
    },
    /// Stick figure: torso, head, two two-segment arms and legs (capsules).
    Figure(Figure),
}

#[derive(Clone, Debug)]
pub struct Figure {
    /// Torso length (hip to neck); limbs and head scale with it.
    pub size: f32,
    pub thickness: f32,
    /// Per joint: base angle, amplitude, angular frequency (rad per frame), phase.
    /// Joints: 0,1 shoulders; 2,3 elbows; 4,5 hips; 6,7 knees; 8 torso lean.
    pub joints: [[f32; 4]; 9],
}

#[derive(Clone, Debug)]
pub struct Subject {
    pub shape: Shape,
    pub material: Material,
    /// Self-luminous subjects (lanterns, screens) ignore scene lighting.
    pub emissive: Option<[f32; 3]>,
    pub x0: f32,
    pub y0: f32,
    pub vx: f32,
    pub vy: f32,
    pub theta0: f32,
    pub omega: f32,
}

/// A capsule (segment with radius) in world coordinates, with its texture frame.
#[derive(Clone, Copy, Debug)]
struct Capsule {
    ax: f32,
    ay: f32,
    bx: f32,
    by: f32,
    r: f32,
    /// Texture offset so each limb has its own texture region.
    tex: f32,
}

impl Capsule {
    /// Signed distance and texture coordinates (along, across) of point p.
    #[inline]
    fn eval(&self, x: f32, y: f32) -> (f32, f32, f32) {
        let (dx, dy) = (self.bx - self.ax, self.by - self.ay);
        let len2 = (dx * dx + dy * dy).max(1e-12);
        let (px, py) = (x - self.ax, y - self.ay);
        let h = ((px * dx + py * dy) / len2).clamp(0.0, 1.0);
        let (qx, qy) = (px - dx * h, py - dy * h);
        let d = (qx * qx + qy * qy).sqrt() - self.r;
        let len = len2.sqrt();
        let along = (px * dx + py * dy) / len;
        let across = (px * -dy + py * dx) / len;
        (d, along + self.tex, across)
    }
}

/// A subject posed at one instant: everything needed to shade pixels.
pub struct Posed<'a> {
    subject: &'a Subject,
    cx: f32,
    cy: f32,
    cos: f32,
    sin: f32,
    capsules: Vec<Capsule>,
    /// Bounding box in world units (already padded by the shape's extent).
    pub bbox: [f32; 4],
}

impl Subject {
    pub fn random(
        rng: &mut Rng,
        cx: f32,
        cy: f32,
        view_w: f32,
        motion: f32,
        articulated: bool,
    ) -> Subject {
        let size = view_w * rng.range(0.06, 0.16);
        let shape = if articulated {
            let mut joints = [[0.0f32; 4]; 9];
            let base = [0.5, -0.5, 0.4, -0.4, 0.15, -0.15, -0.3, 0.3, 0.0];
            for (j, b) in joints.iter_mut().zip(base) {
                *j = [
                    b + rng.range(-0.3, 0.3),
                    rng.range(0.2, 0.8) * motion.min(2.0),
                    rng.range(0.3, 1.0),
                    rng.range(0.0, std::f32::consts::TAU),
                ];
            }
            joints[8][1] *= 0.2;
            Shape::Figure(Figure {
                size: size * 1.2,
                thickness: size * rng.range(0.12, 0.2),
                joints,
            })
        } else {
            match rng.int(0, 2) {
                0 => Shape::Ellipse {
                    a: size,
                    b: size * rng.range(0.4, 1.0),
                },
                1 => Shape::Polygon {
                    n: rng.int(3, 8),
                    r: size,
                },
                _ => Shape::RoundRect {
                    hw: size,
                    hh: size * rng.range(0.4, 1.0),
                    r: size * rng.range(0.05, 0.3),
                },
            }
        };
        let speed = view_w * rng.range(0.01, 0.05) * motion;
        let dir = rng.range(0.0, std::f32::consts::TAU);
        let emissive = (!articulated && rng.chance(0.15)).then(|| {
            let level = rng.stops(4.0, 9.0);
            [
                level,
                level * rng.range(0.6, 1.0),
                level * rng.range(0.3, 1.0),
            ]
        });
        Subject {
            shape,
            material: Material::random(rng),
            emissive,
            x0: cx,
            y0: cy,
            vx: speed * dir.cos(),
            vy: speed * dir.sin(),
            theta0: rng.range(0.0, std::f32::consts::TAU),
            omega: rng.range(-0.15, 0.15) * motion,
        }
    }

    /// The subject at time t.
    pub fn pose(&self, t: f32) -> Posed<'_> {
        let cx = self.x0 + self.vx * t;
        let cy = self.y0 + self.vy * t;
        let theta = self.theta0 + self.omega * t;
        let mut capsules = Vec::new();
        let extent = match &self.shape {
            Shape::Ellipse { a, b } => a.max(*b),
            Shape::Polygon { r, .. } => *r,
            Shape::RoundRect { hw, hh, .. } => (hw * hw + hh * hh).sqrt(),
            Shape::Figure(fig) => {
                capsules = fig.capsules(cx, cy, t);
                let mut bb = [
                    f32::INFINITY,
                    f32::INFINITY,
                    f32::NEG_INFINITY,
                    f32::NEG_INFINITY,
                ];
                for c in &capsules {
                    bb[0] = bb[0].min(c.ax.min(c.bx) - c.r);
                    bb[1] = bb[1].min(c.ay.min(c.by) - c.r);
                    bb[2] = bb[2].max(c.ax.max(c.bx) + c.r);
                    bb[3] = bb[3].max(c.ay.max(c.by) + c.r);
                }
                return Posed {
                    subject: self,
                    cx,
                    cy,
                    cos: 1.0,
                    sin: 0.0,
                    capsules,
                    bbox: bb,
                };
            }
        };
        Posed {
            subject: self,
            cx,
            cy,
            cos: theta.cos(),
            sin: theta.sin(),
            capsules,
            bbox: [cx - extent, cy - extent, cx + extent, cy + extent],
        }
    }
}

impl Figure {
    fn capsules(&self, hx: f32, hy: f32, t: f32) -> Vec<Capsule> {
        let ang = |j: usize| {
            let [b, a, w, p] = self.joints[j];
            b + a * (w * t + p).sin()
        };
        let s = self.size;
        let r = self.thickness;
        // Torso from hip upwards, leaning by joint 8 (angle from vertical).
        let lean = ang(8);
        let (nx, ny) = (hx + s * lean.sin(), hy - s * lean.cos());
        let mut out = vec![Capsule {
            ax: hx,
            ay: hy,
            bx: nx,
            by: ny,
            r: r * 1.3,
            tex: 0.0,
        }];
        // Head: a zero-length capsule (a disc) above the neck.
        out.push(Capsule {
            ax: nx + 0.35 * s * lean.sin(),
            ay: ny - 0.35 * s * lean.cos(),
            bx: nx + 0.35 * s * lean.sin(),
            by: ny - 0.35 * s * lean.cos(),
            r: 0.22 * s,
            tex: 10.0,
        });
        // Limbs: (root, upper joint, lower joint, upper length, lower length).
        let limbs = [
            (nx, ny, 0usize, 2usize, 0.55, 0.5),
            (nx, ny, 1, 3, 0.55, 0.5),
            (hx, hy, 4, 6, 0.6, 0.6),
            (hx, hy, 5, 7, 0.6, 0.6),
        ];
        for (k, (rx, ry, j1, j2, l1, l2)) in limbs.into_iter().enumerate() {
            // Angles measured from straight down.
            let a1 = ang(j1);
            let (ex, ey) = (rx + s * l1 * a1.sin(), ry + s * l1 * a1.cos());
            let a2 = a1 + ang(j2);
            let (wx, wy) = (ex + s * l2 * a2.sin(), ey + s * l2 * a2.cos());
            out.push(Capsule {
                ax: rx,
                ay: ry,
                bx: ex,
                by: ey,
                r,
                tex: 20.0 + 10.0 * k as f32,
            });
            out.push(Capsule {
                ax: ex,
                ay: ey,
                bx: wx,
                by: wy,
                r: r * 0.85,
                tex: 25.0 + 10.0 * k as f32,
            });
        }
        out
    }
}

impl Posed<'_> {
    /// Signed distance (world units) and texture coordinates at world point (x, y).
    #[inline]
    fn eval(&self, x: f32, y: f32) -> (f32, f32, f32) {
        if !self.capsules.is_empty() {
            let mut best = (f32::INFINITY, 0.0, 0.0);
            for c in &self.capsules {
                let e = c.eval(x, y);
                if e.0 < best.0 {
                    best = e;
                }
            }
            return best;
        }
        // Local frame of a rigid shape: rotate the offset by −θ.
        let (dx, dy) = (x - self.cx, y - self.cy);
        let u = self.cos * dx + self.sin * dy;
        let v = -self.sin * dx + self.cos * dy;
        let d = match &self.subject.shape {
            Shape::Ellipse { a, b } => {
                // First-order distance to the ellipse: f / |∇f|, exact on the boundary.
                let f = (u / a).powi(2) + (v / b).powi(2) - 1.0;
                let g = 2.0 * ((u / (a * a)).powi(2) + (v / (b * b)).powi(2)).sqrt();
                f / g.max(1e-9)
            }
            Shape::Polygon { n, r } => {
                let k = *n as f32;
                let apothem = r * (std::f32::consts::PI / k).cos();
                (0..*n)
                    .map(|i| {
                        let a = std::f32::consts::TAU * (i as f32 + 0.5) / k;
                        u * a.cos() + v * a.sin() - apothem
                    })
                    .fold(f32::NEG_INFINITY, f32::max)
            }
            Shape::RoundRect { hw, hh, r } => {
                let qx = u.abs() - (hw - r);
                let qy = v.abs() - (hh - r);
                (qx.max(0.0).powi(2) + qy.max(0.0).powi(2)).sqrt() + qx.max(qy).min(0.0) - r
            }
            Shape::Figure(_) => unreachable!("figures are capsules"),
        };
        (d, u, v)
    }

    /// Coverage in [0, 1] of pixel (x, y) of size px; exactly 0 beyond half a pixel outside.
    #[inline]
    pub fn coverage(&self, x: f32, y: f32, px: f32) -> (f32, f32, f32) {
        let (d, u, v) = self.eval(x, y);
        (coverage(d, px), u, v)
    }

    /// Radiance of the subject's surface at texture coords (u, v) under irradiance `e`.
    #[inline]
    pub fn radiance(&self, u: f32, v: f32, px: f32, e: f32) -> [f32; 3] {
        let a = self.subject.material.albedo(u, v, px);
        match self.subject.emissive {
            Some(c) => [
                c[0] * (0.6 + 0.4 * a[0]),
                c[1] * (0.6 + 0.4 * a[1]),
                c[2] * (0.6 + 0.4 * a[2]),
            ],
            None => [a[0] * e, a[1] * e, a[2] * e],
        }
    }
}
