//! A "truth" sensor for hidden-effect tests, written independently of the library's realism
//! operator and effect catalogue (plain loops, its own random streams, and for correlated
//! noise a different filter with the same lag-1 vertical correlation), so the workflow is tested
//! against planted truth rather than against its own simulator. It writes capture sets in the
//! `hdrsynth-captures/1` format with the library's `write_capture_set`.
//!
//! Conventions (the physical meaning of each catalogue parameter):
//! signal S = level × (1 − k·r²) × (1 + σ_prnu·z), then S → R·(S/R)^p, then the toe
//! u → √(u² + t²) − t and the shoulder u → u / (1 + (u/s)⁴)^¼ on u = S/R; noise with variance
//! a_c·S + b_c (read part Student-t of variance b_c when `heavy_dof`); offsets: declared black +
//! black offset + row offset (per frame) + column offset + DSNU + hot offset; clip to
//! [0, white], round.
#![allow(dead_code)]

use hdrsynth::io::Image;
use hdrsynth::sensor::captures::{Burst, BurstKind, CaptureManifest, write_capture_set};
use rand::SeedableRng;
use rand_distr::{Distribution, Open01, StandardNormal, StudentT};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::path::Path;

#[derive(Clone, Debug)]
pub struct Truth {
    pub width: usize,
    pub height: usize,
    pub frames: usize,
    pub isos: Vec<f64>,
    pub white: f64,
    pub black: f64,
    /// Shot-noise gain and read variance at ISO 100 (DN, DN²); a ∝ ISO, b ∝ ISO.
    pub a100: f64,
    pub b100: f64,
    pub black_offset: f64,
    pub row_sigma: f64,
    pub column_sigma: f64,
    pub dsnu_sigma: f64,
    pub prnu_sigma: f64,
    /// (fraction, offset DN)
    pub hot: Option<(f64, f64)>,
    pub heavy_dof: Option<f64>,
    /// Per-channel multipliers on a and b.
    pub channel: Option<([f64; 3], [f64; 3])>,
    pub vignetting: f64,
    pub corr_rho: f64,
    /// Noise filtered by a 2-D Gaussian kernel of this σ (pixels; 0 = off), applied directly
    /// (not separated) to draws padded beyond the frame, normalised to Σk² = 1 (variance kept).
    pub corr_gauss: f64,
    /// Correlation of a pixel's three channels' noise: z_c' = √(1 − ρ)·z_c + √ρ·z_s with a
    /// fresh shared draw z_s per pixel.
    pub channel_rho: f64,
    pub exponent: f64,
    /// Response toe t (fraction of the range; 0 = none) and shoulder s (0 = none).
    pub toe: f64,
    pub shoulder: f64,
    /// Flat levels per ISO (fractions of the range at exposure level / 20 s).
    pub flat_levels: Vec<f64>,
    /// Write the three-exposure scene (false: darks, flats and the chart only).
    pub scenes: bool,
    /// Camera RGB of the chart burst = M · reference linear sRGB (identity unless set).
    pub chart_matrix: [[f64; 3]; 3],
    pub seed: u64,
}

impl Truth {
    pub fn new(width: usize, height: usize, frames: usize, seed: u64) -> Truth {
        Truth {
            width,
            height,
            frames,
            isos: vec![100.0],
            white: 4095.0,
            black: 64.0,
            a100: 0.6,
            b100: 9.0,
            black_offset: 0.0,
            row_sigma: 0.0,
            column_sigma: 0.0,
            dsnu_sigma: 0.0,
            prnu_sigma: 0.0,
            hot: None,
            heavy_dof: None,
            channel: None,
            vignetting: 0.0,
            corr_rho: 0.0,
            corr_gauss: 0.0,
            channel_rho: 0.0,
            exponent: 1.0,
            toe: 0.0,
            shoulder: 0.0,
            flat_levels: vec![0.2, 0.55],
            scenes: true,
            chart_matrix: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            seed,
        }
    }

    fn range(&self) -> f64 {
        self.white - self.black
    }

    /// Fixed patterns: (gain per value, offset per value), and the number of hot values.
    #[allow(clippy::needless_range_loop)] // (x, y, c) index arithmetic reads clearer
    fn patterns(&self) -> (Vec<f64>, Vec<f64>, usize) {
        let (w, h) = (self.width, self.height);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(self.seed ^ 0xf1d0);
        let mut n = || -> f64 { StandardNormal.sample(&mut rng) };
        let cols: Vec<f64> = (0..w).map(|_| self.column_sigma * n()).collect();
        let hd = 0.5 * ((w * w + h * h) as f64).sqrt();
        let mut gain = vec![0.0; w * h * 3];
        let mut off = vec![0.0; w * h * 3];
        let mut rng2 = Xoshiro256PlusPlus::seed_from_u64(self.seed ^ 0x407);
        let mut hot = 0;
        for y in 0..h {
            for x in 0..w {
                let (u, v) = (
                    (x as f64 + 0.5 - w as f64 / 2.0) / hd,
                    (y as f64 + 0.5 - h as f64 / 2.0) / hd,
                );
                let vig = 1.0 - self.vignetting * (u * u + v * v);
                for c in 0..3 {
                    let i = (y * w + x) * 3 + c;
                    gain[i] = vig * (1.0 + self.prnu_sigma * n());
                    off[i] = cols[x] + self.dsnu_sigma * n();
                    let u: f64 = Open01.sample(&mut rng2);
                    if let Some((f, o)) = self.hot
                        && u < f
                    {
                        off[i] += o;
                        hot += 1;
                    }
                }
            }
        }
        (gain, off, hot)
    }

    /// Number of hot values planted.
    pub fn hot_count(&self) -> usize {
        self.patterns().2
    }

    /// One frame of a target (signal above black per value, before gain), burst `b`, frame `f`.
    fn frame(
        &self,
        target: &[f64],
        iso: f64,
        pat: &(Vec<f64>, Vec<f64>, usize),
        b: u64,
        f: u64,
    ) -> Image {
        let (w, h) = (self.width, self.height);
        let r = self.range();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(
            self.seed.wrapping_mul(0x9e37_79b9) ^ (b << 32) ^ (f << 16) ^ 0xabc,
        );
        let n3 = w * h * 3;
        // Unit normals, filtered vertically for correlated noise: e' = (e(y) + β e(y+1)) /
        // √(1 + β²) has lag-1 vertical correlation β / (1 + β²) = ρ.
        let e: Vec<f64> = (0..n3 + w * 3)
            .map(|_| StandardNormal.sample(&mut rng))
            .collect();
        let beta = if self.corr_rho > 0.0 {
            (1.0 - (1.0 - 4.0 * self.corr_rho * self.corr_rho).sqrt()) / (2.0 * self.corr_rho)
        } else {
            0.0
        };
        let norm = (1.0 + beta * beta).sqrt();
        let gauss = (self.corr_gauss > 0.0).then(|| self.gauss_field(&mut rng));
        let t = self.heavy_dof.map(|d| StudentT::new(d).unwrap());
        let (a0, b0) = (self.a100 * iso / 100.0, self.b100 * iso / 100.0);
        let mut out = vec![0.0f32; n3];
        for y in 0..h {
            let z: f64 = StandardNormal.sample(&mut rng);
            let row_off = self.row_sigma * z;
            for x in 0..w {
                let shared: f64 = if self.channel_rho > 0.0 {
                    StandardNormal.sample(&mut rng)
                } else {
                    0.0
                };
                for c in 0..3 {
                    let i = (y * w + x) * 3 + c;
                    let (ac, bc) = match self.channel {
                        Some((sa, sb)) => (a0 * sa[c], b0 * sb[c]),
                        None => (a0, b0),
                    };
                    let mut s = (target[i] * pat.0[i]).max(0.0);
                    s = r * (s / r).powf(self.exponent);
                    if self.toe > 0.0 {
                        let u = s / r;
                        s = r * ((u * u + self.toe * self.toe).sqrt() - self.toe);
                    }
                    if self.shoulder > 0.0 {
                        let q = (s / r / self.shoulder).powi(4);
                        s /= (1.0 + q).powf(0.25);
                    }
                    let z = match &gauss {
                        Some(g) => g[i],
                        None => (e[i] + beta * e[i + w * 3]) / norm,
                    };
                    let z = if self.channel_rho > 0.0 {
                        (1.0 - self.channel_rho).sqrt() * z + self.channel_rho.sqrt() * shared
                    } else {
                        z
                    };
                    let noise = match &t {
                        None => (ac * s + bc).sqrt() * z,
                        Some(t) => {
                            let d = self.heavy_dof.unwrap();
                            (ac * s).sqrt() * z
                                + bc.sqrt() * ((d - 2.0) / d).sqrt() * t.sample(&mut rng)
                        }
                    };
                    let v = s + noise + self.black + self.black_offset + row_off + pat.1[i];
                    out[i] = v.clamp(0.0, self.white).round() as f32;
                }
            }
        }
        Image::from_vec(w, h, out)
    }

    /// Unit-variance noise field (w × h × 3) filtered by the 2-D Gaussian kernel of σ
    /// `corr_gauss`, radius ⌈4σ⌉, over draws padded by the radius on every side.
    fn gauss_field(&self, rng: &mut Xoshiro256PlusPlus) -> Vec<f64> {
        let (w, h, s) = (self.width, self.height, self.corr_gauss);
        let r = (4.0 * s).ceil() as usize;
        let (pw, ph) = (w + 2 * r, h + 2 * r);
        let e: Vec<f64> = (0..pw * ph * 3)
            .map(|_| StandardNormal.sample(rng))
            .collect();
        let n = 2 * r + 1;
        let mut k = vec![0.0; n * n];
        for j in 0..n {
            for i in 0..n {
                let (dx, dy) = (i as f64 - r as f64, j as f64 - r as f64);
                k[j * n + i] = (-(dx * dx + dy * dy) / (2.0 * s * s)).exp();
            }
        }
        let norm = k.iter().map(|v| v * v).sum::<f64>().sqrt();
        let mut out = vec![0.0; w * h * 3];
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let mut acc = 0.0;
                    for j in 0..n {
                        for i in 0..n {
                            acc += k[j * n + i] * e[((y + j) * pw + x + i) * 3 + c];
                        }
                    }
                    out[(y * w + x) * 3 + c] = acc / norm;
                }
            }
        }
        out
    }

    /// Lag-1 correlation of `corr_gauss` noise along an axis, by hand from the kernel:
    /// Σ k(i, j)·k(i + 1, j) / Σ k² (the 2-D Gaussian factorises, so the sums over j cancel).
    pub fn gauss_lag1(&self) -> f64 {
        let s = self.corr_gauss;
        let r = (4.0 * s).ceil() as i64;
        let g = |i: i64| {
            if i.abs() > r {
                0.0
            } else {
                (-((i * i) as f64) / (2.0 * s * s)).exp()
            }
        };
        let num: f64 = (-r..=r).map(|i| g(i) * g(i + 1)).sum();
        let den: f64 = (-r..=r).map(|i| g(i) * g(i)).sum();
        num / den
    }

    /// Write the capture set: per ISO a dark burst and flats at `flat_levels` (20 % and 55 % of
    /// the range unless set);
    /// a chart burst (`chart_matrix` · ColorChecker reference × 0.5 of the range); one scene at
    /// exposures 16, 4 and 1 ms (2 frames each). Returns the number of hot values planted.
    pub fn write(&self, dir: &Path) -> usize {
        let (w, h) = (self.width, self.height);
        let r = self.range();
        let pat = self.patterns();
        let mut m = CaptureManifest::new();
        m.sensor.name = Some("truth".into());
        m.sensor.white_level = Some(self.white);
        m.sensor.black_level = Some(self.black);
        let mut frames = Vec::new();
        let mut add = |name: String, kind, iso, exposure_s, target: Vec<f64>, n: usize| {
            let b = m.bursts.len() as u64;
            let imgs: Vec<Image> = (0..n)
                .map(|f| self.frame(&target, iso, &pat, b, f as u64))
                .collect();
            m.bursts.push(Burst {
                name: name.clone(),
                kind,
                iso,
                exposure_s,
                frames: (0..n).map(|f| format!("{name}/{f:03}.png")).collect(),
                scene: None,
            });
            frames.push(imgs);
        };
        for &iso in &self.isos {
            add(
                format!("dark_{iso}"),
                BurstKind::Dark,
                iso,
                0.0,
                vec![0.0; w * h * 3],
                self.frames,
            );
            for (k, level) in self.flat_levels.iter().enumerate() {
                add(
                    format!("flat_{iso}_{k}"),
                    BurstKind::Flat,
                    iso,
                    level / 20.0,
                    vec![level * r; w * h * 3],
                    self.frames,
                );
            }
        }
        let reference = hdrsynth::sensor::colour::chart::reference_linear_srgb();
        let mut chart = vec![0.0; w * h * 3];
        for y in 0..h {
            for x in 0..w {
                // Nearest cell of the 6×4 grid.
                let i = ((y * 4 / h) * 6 + x * 6 / w).min(23);
                for c in 0..3 {
                    let v: f64 = (0..3)
                        .map(|k| self.chart_matrix[c][k] * reference[i][k])
                        .sum();
                    chart[(y * w + x) * 3 + c] = v * 0.5 * r;
                }
            }
        }
        add(
            "chart".into(),
            BurstKind::Chart,
            self.isos[0],
            0.01,
            chart,
            2,
        );
        let iso = self.isos[0];
        let scene: Vec<f64> = (0..w * h * 3)
            .map(|i| {
                let (x, y, c) = ((i / 3) % w, i / 3 / w, i % 3);
                let u = ((x * 7 + y * 3 + c * 5) % 97) as f64 / 96.0;
                (0.05 + 0.85 * u) * r
            })
            .collect();
        let exposures: &[f64] = if self.scenes { &[16.0, 4.0, 1.0] } else { &[] };
        for (k, e) in exposures.iter().enumerate() {
            let t: Vec<f64> = scene.iter().map(|v| v * e / 16.0).collect();
            add(
                format!("scene_{k}"),
                BurstKind::Scene,
                iso,
                e / 1000.0,
                t,
                2,
            );
        }
        write_capture_set(dir, &m, &frames).expect("write capture set");
        pat.2
    }
}

/// A scene-only capture set like the paper's public samples: per scene an EV0 and an EV−3
/// burst of one frame each (8 and 1 ms), 8-bit range (white 255, black 0), all scenes of one
/// frame size. Scene k has its own radiance pattern and response exponent `exponents[k]`
/// (I → R·(I/R)^p before noise of variance a·I + b). `keys`: declare `scene = "scene<k>"`.
pub fn write_scene_pairs(dir: &Path, w: usize, h: usize, exponents: &[f64], keys: bool, seed: u64) {
    let (white, a, b) = (255.0f64, 0.05, 0.3);
    let mut m = CaptureManifest::new();
    m.sensor.name = Some("scene pairs".into());
    m.sensor.white_level = Some(white);
    m.sensor.black_level = Some(0.0);
    let mut frames = Vec::new();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x5ce4e);
    for (k, &p) in exponents.iter().enumerate() {
        // Scene k: a pattern of its own (different period and phase per scene).
        let radiance: Vec<f64> = (0..w * h * 3)
            .map(|i| {
                let (x, y, c) = ((i / 3) % w, i / 3 / w, i % 3);
                let u = ((x * (5 + 2 * k) + y * (3 + k) + c * 7 + 13 * k) % 89) as f64 / 88.0;
                (0.05 + 0.9 * u) * white
            })
            .collect();
        for (name, e) in [("ev0", 1.0), ("ev-3", 0.125)] {
            let data: Vec<f32> = radiance
                .iter()
                .map(|&r| {
                    let s = white * (r * e / white).powf(p);
                    let z: f64 = StandardNormal.sample(&mut rng);
                    (s + (a * s + b).sqrt() * z).clamp(0.0, white).round() as f32
                })
                .collect();
            let bname = format!("scene{k}_{name}");
            m.bursts.push(Burst {
                name: bname.clone(),
                kind: BurstKind::Scene,
                iso: 100.0,
                exposure_s: 0.008 * e,
                frames: vec![format!("{bname}/000.png")],
                scene: keys.then(|| format!("scene{k}")),
            });
            frames.push(vec![Image::from_vec(w, h, data)]);
        }
    }
    write_capture_set(dir, &m, &frames).expect("write capture set");
}
