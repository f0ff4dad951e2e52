//! Procedural HDR scene engine: linear radiance scenes, deterministic from (seed, sample
//! index), rendered as exposure brackets with a static set (motion stopped) and a dynamic set
//! (motion resumed), plus motion masks and the HDR ground truth.
//!
//! Pipeline per sample: build a world (procedural street/interior, or a real radiance map) →
//! choose a viewpoint and exposure key that hit the configured fractions of over- and
//! under-exposed pixels at EV0 and at least `min_dynamic_range` stops → place moving subjects
//! in view → render the background once → composite the subjects at each frame's time.
//! Frame i's linear value is radiance · key · 2^ev_i; display frames apply the tone curve.

pub mod config;
pub mod material;
pub mod noise;
pub mod subjects;
pub mod world;

use crate::config::{KeyError, Range, each_in_range, in_range, in_range_because};
use crate::error::{Error, Result};
use crate::io::{Image, dynamic_range_stops, read_image};
use crate::rng::Rng;
use crate::sensor::response::ToneCurve;
use config::GenerateConfig;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::Arc;
use subjects::{Posed, Subject};
use world::{WORLD_H, WORLD_W, World};

/// Largest frame the engine renders (a 12 MP phone sensor), in either orientation.
pub const MAX_LONG_SIDE: usize = 4032;
pub const MAX_SHORT_SIDE: usize = 3024;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneConfig {
    /// Number of moving subjects per sample, [min, max] inclusive.
    pub subjects: [usize; 2],
    /// Fraction of subjects that are articulated figures (the rest move rigidly).
    pub articulated_fraction: f32,
    /// Scales subject speed and joint amplitudes between consecutive frames.
    pub motion_scale: f32,
    /// Optional folder of real HDR radiance maps (.exr/.hdr) used as backgrounds.
    pub backgrounds_dir: Option<PathBuf>,
    /// Probability that a sample uses a real background when `backgrounds_dir` is set.
    pub real_background_probability: f32,
    /// Viewpoints are chosen to show at least this many stops (99.9th / 0.1th percentile).
    pub min_dynamic_range: f32,
}

impl Default for SceneConfig {
    fn default() -> Self {
        SceneConfig {
            subjects: [2, 4],
            articulated_fraction: 0.5,
            motion_scale: 1.0,
            backgrounds_dir: None,
            real_background_probability: 0.5,
            min_dynamic_range: 16.0,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// Wanted fraction of over-exposed pixels at EV0 (max channel ≥ `over_threshold`).
    pub target_over: f32,
    /// Wanted fraction of under-exposed pixels at EV0 (max channel ≤ `under_threshold`).
    pub target_under: f32,
    /// Display code value at or above which a pixel counts as over-exposed.
    pub over_threshold: f32,
    /// Display code value at or below which a pixel counts as under-exposed.
    pub under_threshold: f32,
    /// Viewpoints tried per sample.
    pub candidates: usize,
}

/// Largest `scene.min_dynamic_range` (stops); the engine's scenes span about 16–24.
pub const MAX_DYNAMIC_RANGE: f32 = 32.0;
/// Most moving subjects per sample.
pub const MAX_SUBJECTS: usize = 64;
/// Largest `scene.motion_scale`: beyond it subjects leave the frame between exposures.
pub const MAX_MOTION_SCALE: f32 = 10.0;

impl SceneConfig {
    /// `[scene]`'s rules, keys relative to it.
    pub fn validate(&self) -> Result<(), KeyError> {
        each_in_range(
            "subjects",
            &self.subjects,
            Range::closed(0.0, MAX_SUBJECTS as f64),
        )?;
        if self.subjects[0] > self.subjects[1] {
            return Err(KeyError::new(
                "subjects",
                format!("{:?}: min > max", self.subjects),
            ));
        }
        in_range(
            "articulated_fraction",
            self.articulated_fraction,
            Range::UNIT,
        )?;
        in_range(
            "motion_scale",
            self.motion_scale,
            Range::closed(0.0, MAX_MOTION_SCALE as f64),
        )?;
        in_range(
            "real_background_probability",
            self.real_background_probability,
            Range::UNIT,
        )?;
        // Below 1 the probability applies only "when backgrounds_dir is set" (the shipped
        // configs keep 0.5 with the folder commented out); 1 demands a real background for
        // every sample, which no folder cannot give.
        if self.real_background_probability == 1.0 && self.backgrounds_dir.is_none() {
            return Err(KeyError::new(
                "real_background_probability",
                "1 (every sample on a real background) needs scene.backgrounds_dir",
            ));
        }
        in_range_because(
            "min_dynamic_range",
            self.min_dynamic_range,
            Range::closed(0.0, MAX_DYNAMIC_RANGE as f64),
            "stops; the engine's scenes span about 16–24, a larger minimum is never met",
        )
    }
}

impl CameraConfig {
    /// `[camera]`'s rules, keys relative to it: target fractions in [0, 1) summing below 1,
    /// 0 < under_threshold < over_threshold < 1, at least one candidate viewpoint.
    pub fn validate(&self) -> Result<(), KeyError> {
        in_range("target_over", self.target_over, Range::half_open(0.0, 1.0))?;
        in_range(
            "target_under",
            self.target_under,
            Range::half_open(0.0, 1.0),
        )?;
        let rest = 1.0 - self.target_over;
        in_range_because(
            "target_under",
            self.target_under,
            Range::half_open(0.0, rest as f64),
            "target_over + target_under must stay below 1",
        )?;
        in_range("over_threshold", self.over_threshold, Range::open(0.0, 1.0))?;
        in_range_because(
            "under_threshold",
            self.under_threshold,
            Range::open(0.0, self.over_threshold as f64),
            "below over_threshold",
        )?;
        in_range("candidates", self.candidates, Range::at_least(1.0))
    }
}

impl Default for CameraConfig {
    fn default() -> Self {
        CameraConfig {
            target_over: 0.08,
            target_under: 0.15,
            over_threshold: 0.98,
            under_threshold: 0.02,
            candidates: 24,
        }
    }
}

/// A view of the world: centre, width in world units, and the output raster.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub cx: f32,
    pub cy: f32,
    pub view_w: f32,
    pub width: usize,
    pub height: usize,
}

impl Camera {
    /// World units per pixel.
    pub fn px(&self) -> f32 {
        self.view_w / self.width as f32
    }
    /// World position of pixel (col, row)'s centre.
    #[inline]
    pub fn world(&self, col: usize, row: usize) -> (f32, f32) {
        let px = self.px();
        (
            self.cx + (col as f32 + 0.5 - 0.5 * self.width as f32) * px,
            self.cy + (row as f32 + 0.5 - 0.5 * self.height as f32) * px,
        )
    }
    /// The same view at another resolution.
    pub fn with_size(&self, width: usize, height: usize) -> Camera {
        Camera {
            width,
            height,
            ..*self
        }
    }
}

/// Statistics of one rendered sample, written to its metadata.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleStats {
    pub exposure_key: f32,
    pub over_fraction: f32,
    pub under_fraction: f32,
    pub dynamic_range_stops: f32,
    pub camera: Camera,
    /// File name of the real radiance map used as background, if any.
    pub background: Option<String>,
    pub subjects: usize,
    pub articulated: usize,
}

/// One sample's radiance at each frame's time; frames are derived by exposure scaling.
pub struct RenderedSample {
    pub evs: Vec<f32>,
    pub reference: usize,
    /// Frame times in frame intervals (reference = 0); the static set is all at t = 0.
    pub times: Vec<f32>,
    /// Scene radiance with motion stopped (t = 0), before the exposure key.
    pub static_radiance: Image,
    /// Scene radiance at each frame's time (the reference entry equals `static_radiance`).
    pub dynamic_radiance: Vec<Image>,
    /// Per dynamic frame, 1 where a moving subject covers the pixel in the static or the
    /// dynamic pose (so every pixel outside is identical in both sets), else 0.
    pub masks: Vec<Vec<u8>>,
    pub stats: SampleStats,
}

impl RenderedSample {
    /// Gain from radiance to frame `i`'s linear value: key · 2^ev_i.
    pub fn frame_gain(&self, i: usize) -> f32 {
        self.stats.exposure_key * self.evs[i].exp2()
    }
    /// Linear value of frame `i` of a set: radiance · key · 2^ev_i.
    pub fn linear_frame(&self, radiance: &Image, i: usize) -> Image {
        let g = self.frame_gain(i);
        radiance.map(|v| v * g)
    }
    /// The HDR ground truth: static radiance at the reference exposure (EV0).
    pub fn ground_truth(&self) -> Image {
        self.linear_frame(&self.static_radiance, self.reference)
    }
}

pub struct Generator {
    cfg: GenerateConfig,
    backgrounds: Vec<(String, Arc<Image>)>,
}

impl Generator {
    pub fn new(cfg: &GenerateConfig) -> Result<Generator> {
        cfg.validate().map_err(|e| e.at(&cfg.origin(), None))?;
        let mut backgrounds = Vec::new();
        if let Some(dir) = &cfg.scene.backgrounds_dir {
            let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
            let mut files: Vec<PathBuf> = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    matches!(
                        p.extension()
                            .and_then(|e| e.to_str())
                            .map(str::to_ascii_lowercase)
                            .as_deref(),
                        Some("exr" | "hdr")
                    )
                })
                .collect();
            files.sort();
            if files.is_empty() {
                return Err(Error::config(
                    dir,
                    "backgrounds_dir holds no .exr or .hdr files",
                ));
            }
            for f in files {
                let img = read_image(&f)?;
                let name = f
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .into_owned();
                backgrounds.push((name, Arc::new(img)));
            }
        }
        Ok(Generator {
            cfg: cfg.clone(),
            backgrounds,
        })
    }

    pub fn config(&self) -> &GenerateConfig {
        &self.cfg
    }

    /// Render sample `index`; a pure function of (config, index).
    pub fn render(&self, index: u64) -> RenderedSample {
        let cfg = &self.cfg;
        let mut rng = Rng::from_parts(cfg.seed, &[index]);
        let (world, background) =
            if !self.backgrounds.is_empty() && rng.chance(cfg.scene.real_background_probability) {
                let (name, img) = rng.pick(&self.backgrounds).clone();
                (World::real(&mut rng, img), Some(name))
            } else {
                (World::procedural(&mut rng), None)
            };
        let (camera, key) = choose_viewpoint(&world, cfg, &mut rng);

        let n = rng.int(cfg.scene.subjects[0], cfg.scene.subjects[1]);
        let view_h = camera.view_w * cfg.height as f32 / cfg.width as f32;
        let mut subjects = Vec::with_capacity(n);
        let mut articulated = 0;
        for _ in 0..n {
            let art = rng.chance(cfg.scene.articulated_fraction);
            articulated += art as usize;
            let sx = camera.cx + rng.range(-0.4, 0.4) * camera.view_w;
            let sy = camera.cy + rng.range(-0.35, 0.35) * view_h;
            subjects.push(Subject::random(
                &mut rng,
                sx,
                sy,
                camera.view_w,
                cfg.scene.motion_scale,
                art,
            ));
        }

        let background_img = render_world(&world, &camera);
        let reference = cfg.reference_index();
        let times: Vec<f32> = (0..cfg.evs.len())
            .map(|i| i as f32 - reference as f32)
            .collect();
        let (static_radiance, _) =
            composite(&background_img, &world, &subjects, &camera, 0.0, None);
        let mut dynamic_radiance = Vec::with_capacity(times.len());
        let mut masks = Vec::with_capacity(times.len());
        for &t in &times {
            if t == 0.0 {
                dynamic_radiance.push(static_radiance.clone());
                masks.push(vec![0u8; camera.width * camera.height]);
            } else {
                let (img, mask) =
                    composite(&background_img, &world, &subjects, &camera, t, Some(0.0));
                dynamic_radiance.push(img);
                masks.push(mask);
            }
        }

        let (over, under) = exposure_fractions(&static_radiance, key, cfg);
        let dr = dynamic_range_stops(&static_radiance, 0.1, 99.9).unwrap_or(0.0) as f32;
        RenderedSample {
            evs: cfg.evs.clone(),
            reference,
            times,
            static_radiance,
            dynamic_radiance,
            masks,
            stats: SampleStats {
                exposure_key: key,
                over_fraction: over,
                under_fraction: under,
                dynamic_range_stops: dr,
                camera,
                background,
                subjects: n,
                articulated,
            },
        }
    }
}

/// Linear thresholds (on the exposed max channel) equivalent to the display thresholds.
fn linear_thresholds(cfg: &GenerateConfig) -> (f32, f32) {
    let c: ToneCurve = cfg.tone_curve;
    (
        c.invert(cfg.camera.over_threshold),
        c.invert(cfg.camera.under_threshold),
    )
}

/// Fractions of over- and under-exposed pixels at EV0 for radiance × key.
pub fn exposure_fractions(radiance: &Image, key: f32, cfg: &GenerateConfig) -> (f32, f32) {
    let (x_over, x_under) = linear_thresholds(cfg);
    let n = radiance.pixel_count().max(1) as f32;
    let (mut over, mut under) = (0usize, 0usize);
    for p in radiance.pixels() {
        let m = p[0].max(p[1]).max(p[2]) * key;
        over += (m >= x_over) as usize;
        under += (m <= x_under) as usize;
    }
    (over as f32 / n, under as f32 / n)
}

/// Try `candidates` random viewpoints on a low-resolution render; for each, the exposure key
/// minimising |over − target_over| + |under − target_under|; keep the viewpoint with the
/// smallest such error among those showing ≥ `min_dynamic_range` (+1 margin) stops.
fn choose_viewpoint(world: &World, cfg: &GenerateConfig, rng: &mut Rng) -> (Camera, f32) {
    let aspect = cfg.height as f32 / cfg.width as f32;
    let max_w = WORLD_W.min(WORLD_H / aspect);
    let (x_over, x_under) = linear_thresholds(cfg);
    let sw = 320usize;
    let sh = ((sw as f32 * aspect).round() as usize).max(8);
    let mut best: Option<(f32, Camera, f32)> = None;
    for _ in 0..cfg.camera.candidates.max(1) {
        let view_w = max_w * rng.range(0.3, 1.0);
        let view_h = view_w * aspect;
        let cam = Camera {
            cx: rng.range(0.5 * view_w, WORLD_W - 0.5 * view_w),
            cy: rng.range(0.5 * view_h, WORLD_H - 0.5 * view_h),
            view_w,
            width: cfg.width,
            height: cfg.height,
        };
        let small = render_world(world, &cam.with_size(sw, sh));
        let mut maxc: Vec<f32> = small.pixels().map(|p| p[0].max(p[1]).max(p[2])).collect();
        maxc.sort_by(|a, b| a.total_cmp(b));
        let q = |f: f32| maxc[((f * (maxc.len() - 1) as f32).round() as usize).min(maxc.len() - 1)];
        let n = maxc.len() as f32;
        let over_at = |k: f32| (maxc.len() - maxc.partition_point(|&m| m * k < x_over)) as f32 / n;
        let under_at = |k: f32| maxc.partition_point(|&m| m * k <= x_under) as f32 / n;
        // Start from the key that hits the over-exposure target exactly, then trade it
        // against the under-exposure target within ±3 stops (both fractions matter).
        let k0 = if cfg.camera.target_over > 0.0 {
            x_over / q(1.0 - cfg.camera.target_over).max(1e-12)
        } else {
            0.999 * x_over / q(1.0).max(1e-12)
        };
        let (mut key, mut err) = (k0, f32::INFINITY);
        for step in -24..=24 {
            let k = k0 * (step as f32 / 8.0).exp2();
            let e = (over_at(k) - cfg.camera.target_over).abs()
                + (under_at(k) - cfg.camera.target_under).abs();
            if e < err {
                (key, err) = (k, e);
            }
        }
        let dr = dynamic_range_stops(&small, 0.1, 99.9).unwrap_or(0.0) as f32;
        let mut score = err;
        // A margin: subjects placed later may cover some of the darkest or brightest pixels.
        if dr < cfg.scene.min_dynamic_range + 1.0 {
            score += 1.0 + (cfg.scene.min_dynamic_range + 1.0 - dr);
        }
        if best.as_ref().is_none_or(|b| score < b.0) {
            best = Some((score, cam, key));
        }
    }
    let (_, cam, key) = best.expect("at least one candidate");
    (cam, key)
}

/// Render the world's radiance through a camera, rows in parallel.
pub fn render_world(world: &World, cam: &Camera) -> Image {
    let mut img = Image::new(cam.width, cam.height);
    let px = cam.px();
    img.data
        .par_chunks_mut(cam.width * 3)
        .enumerate()
        .for_each(|(row, line)| {
            for col in 0..cam.width {
                let (x, y) = cam.world(col, row);
                line[col * 3..col * 3 + 3].copy_from_slice(&world.radiance(x, y, px));
            }
        });
    img
}

/// Composite the subjects (in order, back to front) posed at time `t` over `background`.
/// With `mask_against = Some(t0)`, also returns the mask of pixels covered at t or at t0.
fn composite(
    background: &Image,
    world: &World,
    subjects: &[Subject],
    cam: &Camera,
    t: f32,
    mask_against: Option<f32>,
) -> (Image, Vec<u8>) {
    let posed: Vec<Posed> = subjects.iter().map(|s| s.pose(t)).collect();
    let others: Vec<Posed> = match mask_against {
        Some(t0) => subjects.iter().map(|s| s.pose(t0)).collect(),
        None => Vec::new(),
    };
    let mut img = background.clone();
    let mut mask = vec![
        0u8;
        if mask_against.is_some() {
            cam.pixel_count()
        } else {
            0
        }
    ];
    let px = cam.px();
    let w = cam.width;
    // Pixel rectangle touched by a posed subject (its bbox plus one pixel).
    let span = |p: &Posed| -> (usize, usize, usize, usize) {
        let (x0, y0) = cam.world(0, 0);
        let c0 = ((p.bbox[0] - x0) / px - 1.0).floor().max(0.0) as usize;
        let r0 = ((p.bbox[1] - y0) / px - 1.0).floor().max(0.0) as usize;
        let c1 = (((p.bbox[2] - x0) / px + 2.0).ceil().max(0.0) as usize).min(w);
        let r1 = (((p.bbox[3] - y0) / px + 2.0).ceil().max(0.0) as usize).min(cam.height);
        (c0, r0, c1, r1)
    };
    let spans: Vec<_> = posed.iter().map(span).collect();
    let other_spans: Vec<_> = others.iter().map(span).collect();
    let mask_rows: Vec<&mut [u8]> = if mask.is_empty() {
        Vec::new()
    } else {
        mask.chunks_mut(w).collect()
    };
    let mut mask_rows: Vec<Option<&mut [u8]>> = mask_rows.into_iter().map(Some).collect();
    mask_rows.resize_with(cam.height, || None);
    img.data
        .par_chunks_mut(w * 3)
        .zip(mask_rows.par_iter_mut())
        .enumerate()
        .for_each(|(row, (line, mrow))| {
            for (p, &(c0, r0, c1, r1)) in posed.iter().zip(&spans) {
                if row < r0 || row >= r1 {
                    continue;
                }
                for col in c0..c1 {
                    let (x, y) = cam.world(col, row);
                    let (a, u, v) = p.coverage(x, y, px);
                    if a > 0.0 {
                        let e = world.subject_irradiance(x, y);
                        let c = p.radiance(u, v, px, e);
                        let o = &mut line[col * 3..col * 3 + 3];
                        for k in 0..3 {
                            o[k] += (c[k] - o[k]) * a;
                        }
                        if let Some(m) = mrow.as_deref_mut() {
                            m[col] = 1;
                        }
                    }
                }
            }
            if let Some(m) = mrow.as_deref_mut() {
                for (p, &(c0, r0, c1, r1)) in others.iter().zip(&other_spans) {
                    if row < r0 || row >= r1 {
                        continue;
                    }
                    for (col, mv) in m.iter_mut().enumerate().take(c1).skip(c0) {
                        let (x, y) = cam.world(col, row);
                        if p.coverage(x, y, px).0 > 0.0 {
                            *mv = 1;
                        }
                    }
                }
            }
        });
    (img, mask)
}

impl Camera {
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }
}

/// File-name tag of an EV: "ev-3", "ev+0", "ev+2", "ev-1.5".
pub fn ev_tag(ev: f32) -> String {
    if ev.fract() == 0.0 {
        format!("ev{:+}", ev as i32)
    } else {
        format!("ev{ev:+}")
    }
}

/// Check a requested frame size (the config keys `width` and `height`) against the engine's
/// limits.
pub fn check_size(width: usize, height: usize) -> Result<(), KeyError> {
    let range = Range::closed(16.0, MAX_LONG_SIDE as f64);
    in_range("width", width, range)?;
    in_range("height", height, range)?;
    let short = width.min(height);
    if short > MAX_SHORT_SIDE {
        let key = if width <= height { "width" } else { "height" };
        return Err(KeyError::new(
            key,
            format!(
                "{short} is out of range (the shorter side must be ≤ {MAX_SHORT_SIDE}: at most \
                 {MAX_LONG_SIDE}×{MAX_SHORT_SIDE} in either orientation)"
            ),
        ));
    }
    Ok(())
}
