//! Training samples with online sensor realism.
//!
//! Every sample is a pure function of (seed, epoch, index): the set (a per-epoch permutation),
//! the crop, the flips/rot90, the ISO and the noise all derive from it. Workers only change how
//! fast samples arrive, never what they are; batches come out in index order.
//!
//! Per sample: read the pure synthetic set → random crop → realism (profile + ISO drawn from the
//! configured list; skipped in "pure" mode, the paper's Net_P baseline) → target → the same
//! flip/rot90 on inputs and target.
//! - Network-1: frames (EV−3, EV0) of the static set, 8-bit quantised → 6×H×W input; target
//!   the 256-class blend map of the same crop rendered without the noise draw (or, with
//!   `target_frames = "noisy"`, of the noisy frames themselves).
//! - Network-2: frames (EV−2, 0, +2), the reference (EV0) from the static set and the others
//!   from the dynamic set (paper §4.2); inputs as Wu et al.: per frame LDR in [0, 1] and
//!   LDR^2.2 / t (t = 2^EV) → 18×H×W; target the set's linear HDR ground truth (hdrsynth's
//!   `hdr_gt.exr`, Kalantari's `HDRImg.hdr`, Wu's `ref_hdr_aligned*.hdr`, brought into
//!   hdrsynth's unit, 1 = the reference's white: `layout::to_reference_unit`), else the triangle
//!   merge of the static frames; always in units of the reference frame's white (pure mode
//!   divides by the dataset's tone-curve white, 7.24 for filmic); with realism, the device's
//!   linear space T · HDR · exposure (1 = the sensor's white level). Realism starts from the
//!   frames' linear EXRs when present and meters each set with `sensor::metering`.

use crate::data::ground_truth::{blend_classes_smoothed, triangle_merge};
use crate::data::layout::{self, GroundTruthKind, SetInfo, read_set_image};
use crate::error::{Error, Result};
use crate::io::Image;
use crate::rng::{Rng, hash};
use crate::sensor::metering::{Metering, Resolved};
use crate::sensor::profile::{Response, SensorProfile};
use crate::sensor::realism::{NoiseModel, Realism, RealismOptions, TargetSpace};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, sync_channel};
use std::sync::{Arc, Mutex, OnceLock};

pub mod config;
pub use config::{
    LoaderConfig, MAX_EV_JITTER, PURE_PROFILE, RealismConfig, SampleKind, Source, TargetFrames,
};

#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// Network-1: blend-map class per pixel (H×W).
    Classes(Vec<u8>),
    /// Network-2: linear HDR, 3×H×W.
    Hdr(Vec<f32>),
}

#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// C×H×W, channel-major.
    pub input: Vec<f32>,
    pub channels: usize,
    pub size: usize,
    pub target: Target,
    /// Exposure time of each input frame relative to the reference (2^EV).
    pub exposure_times: Vec<f32>,
    pub set: String,
    pub iso: Option<f64>,
}

pub struct Loader {
    cfg: LoaderConfig,
    sets: Vec<SetInfo>,
    /// One prepared operator per configured ISO. Its source is linear: the loader hands it
    /// linear frames already scaled by the sample's exposure.
    realism: Vec<(f64, Realism)>,
    /// Per ISO, the same operator without noise: Network-1's clean targets (empty when the
    /// targets come from the noisy frames, or the stream has no noise).
    clean: Vec<Realism>,
    /// What realism starts from (Linear or Display once resolved; unused in pure mode).
    source: Source,
    /// Display code (16-bit index) → linear, 1 = the source response's clipping point.
    linearise: Option<Vec<f32>>,
    /// The linear ground truth's value of the reference frame's white (the target unit); one
    /// value per dataset, as every set of a layout shares its tone curve.
    white: f32,
    /// Per set: the metered EV0 key, computed once on first use.
    keys: Vec<OnceLock<std::result::Result<f32, String>>>,
    /// The exposure rule the keys are metered with and where it came from (pure mode: none).
    metering: Option<Resolved>,
    /// Decoded files, kept while they fit [`CACHE_BYTES`]: every sample crops a few pixels
    /// of whole files, and decoding a device's full-size frames costs more than the step.
    images: Mutex<HashMap<PathBuf, Arc<Image>>>,
    cached_bytes: AtomicUsize,
    /// A second stream and the share of the stream's samples drawn from it ([`Loader::mixed`]).
    mix: Option<(Box<Loader>, f64)>,
}

/// Tag of the draw that picks a mixed stream's samples ([`Loader::mixed`]).
const MIX_DRAW: u64 = 0x313c;

/// Most bytes of decoded files a loader keeps.
const CACHE_BYTES: usize = 2 << 30;

/// Network-2's three frames of `set` and their exposure times relative to the reference:
/// EV −2, 0, +2 where the set has them (times ¼, 1, 4); else a set of exactly three frames
/// around its reference, at the EVs it records (a device's own bracket, whose steps are what
/// its exposure times made them, e.g. 1.91 stops).
fn network2_frames(set: &SetInfo) -> Result<(Vec<usize>, [f32; 3])> {
    match frames_at(set, &[-2.0, 0.0, 2.0]) {
        Ok(idx) => Ok((idx, [0.25, 1.0, 4.0])),
        Err(_) if set.evs.len() == 3 && set.evs[0] < 0.0 && set.evs[2] > 0.0 => Ok((
            vec![0, 1, 2],
            [set.evs[0], set.evs[1], set.evs[2]].map(f32::exp2),
        )),
        Err(e) => Err(e),
    }
}

/// The frames of `set` a sample of `kind` reads: Network-1's EV −3 and 0, Network-2's
/// [`network2_frames`] (an error naming the set where it lacks them).
fn sample_frames(kind: SampleKind, set: &SetInfo) -> Result<Vec<usize>> {
    match kind {
        SampleKind::Network1 => frames_at(set, &NETWORK1_EVS),
        SampleKind::Network2 => network2_frames(set).map(|(idx, _)| idx),
    }
}

/// Network-1's frames: the short exposure and the reference.
const NETWORK1_EVS: [f32; 2] = [-3.0, 0.0];

/// Indices of the frames with the wanted EVs (error naming the set when one is missing).
fn frames_at(set: &SetInfo, evs: &[f32]) -> Result<Vec<usize>> {
    evs.iter()
        .map(|ev| {
            set.evs
                .iter()
                .position(|e| (e - ev).abs() < 1e-3)
                .ok_or_else(|| {
                    Error::layout(
                        &set.dir,
                        format!(
                            "set '{}' has EVs {:?}; this sample kind needs {:?}",
                            set.name, set.evs, evs
                        ),
                    )
                })
        })
        .collect()
}

/// The linear EXR written beside a display frame (hdrsynth's layout, `write_linear`).
fn linear_sibling(frame: &Path) -> PathBuf {
    frame.with_extension("exr")
}

/// The linear ground truth's value of the reference frame's white: the dataset's tone
/// curve's clipping point for hdrsynth's layout (filmic: 7.24, the engine's display white at
/// EV0), 1 elsewhere (linear ground truth in units of the reference exposure).
fn reference_white(info: &layout::DatasetInfo) -> Result<f32> {
    Ok(match info.layout {
        layout::LayoutKind::Hdrsynth => {
            let m = layout::hdrsynth::read_manifest(&info.root)?;
            m.tone_curve.invert(1.0)
        }
        _ => 1.0,
    })
}

/// Crop `size`×`size` at (x0, y0).
fn crop(img: &Image, x0: usize, y0: usize, size: usize) -> Image {
    let mut out = Image::new(size, size);
    for y in 0..size {
        let src = ((y0 + y) * img.width + x0) * 3;
        out.data[y * size * 3..(y + 1) * size * 3].copy_from_slice(&img.data[src..src + size * 3]);
    }
    out
}

/// The dihedral transform `t` (0..8: a horizontal flip if bit 2 is set, then `t & 3` quarter
/// turns) of a square plane of `c` interleaved channels. Inputs and targets get the same `t`.
pub fn dihedral<T: Copy>(data: &[T], size: usize, c: usize, t: u8) -> Vec<T> {
    let n = size - 1;
    // dest(x, y) = src(f(x, y)).
    let remap = |src: &[T], f: &dyn Fn(usize, usize) -> (usize, usize)| -> Vec<T> {
        let mut out = Vec::with_capacity(src.len());
        for y in 0..size {
            for x in 0..size {
                let (sx, sy) = f(x, y);
                let i = (sy * size + sx) * c;
                out.extend_from_slice(&src[i..i + c]);
            }
        }
        out
    };
    let mut cur = data.to_vec();
    if t & 4 != 0 {
        cur = remap(&cur, &|x, y| (n - x, y));
    }
    for _ in 0..(t & 3) {
        // (x, y) → (y, n − x) applied four times is the identity: a quarter turn.
        cur = remap(&cur, &|x, y| (y, n - x));
    }
    cur
}

/// One sample's random choices ([`Loader::draw`]) and the frame readers they fix.
struct Draw<'a> {
    loader: &'a Loader,
    set: &'a SetInfo,
    /// Crop origin.
    x0: usize,
    y0: usize,
    /// Dihedral transform (0 without augmentation).
    t: u8,
    /// The ISO and its operator (None in pure mode), and the same without noise.
    op: Option<&'a (f64, Realism)>,
    clean: Option<&'a Realism>,
    /// Factor on the linear frames: the sample's EV0 exposure.
    exposure: f32,
    /// Seed of the realism noise; frame k of the sample uses hash(noise_seed, [k]), so frames
    /// of a sample get independent noise.
    noise_seed: u64,
    /// Network-2: every frame from the static set (`static_fraction`), not only the reference.
    still: bool,
}

impl Draw<'_> {
    /// The crop of a frame as linear values times the sample's exposure.
    fn exposed(&self, frame: &Path) -> Result<Image> {
        let window = [self.x0, self.y0, self.loader.cfg.patch];
        Ok(self
            .loader
            .linear_frame(self.set, frame, Some(window))?
            .map(|v| v * self.exposure))
    }

    /// The crop of frame `k` of the sample as the network sees it: through the realism
    /// operator, or in pure mode the display frame quantised to 8 bits.
    fn realistic(&self, frame: &Path, k: u64) -> Result<Image> {
        let p = self.loader.cfg.patch;
        Ok(match self.op {
            Some((_, r)) => r.apply(&self.exposed(frame)?, hash(self.noise_seed, &[k])),
            // Pure mode still quantises to 8 bits, as the networks see 8-bit frames.
            None => crop(&*self.loader.image(self.set, frame)?, self.x0, self.y0, p)
                .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() / 255.0),
        })
    }
}

impl Loader {
    pub fn new(cfg: &LoaderConfig) -> Result<Loader> {
        cfg.validate()?;
        let info = layout::detect(&cfg.dataset)?;
        if info.sets.is_empty() {
            return Err(Error::layout(&cfg.dataset, "no sets"));
        }
        for s in &info.sets {
            sample_frames(cfg.kind, s)?;
            if s.width < cfg.patch || s.height < cfg.patch {
                return Err(Error::layout(
                    &s.dir,
                    format!(
                        "set '{}' is {}×{}, smaller than the {} px patch",
                        s.name, s.width, s.height, cfg.patch
                    ),
                ));
            }
        }
        let white = reference_white(&info)?;
        let mut realism = Vec::new();
        let mut clean = Vec::new();
        let mut source = Source::Display;
        let mut linearise = None;
        let mut metering = None;
        if let Some(r) = &cfg.realism {
            let mut profile = SensorProfile::load(&r.profile)?;
            metering = Some(Metering::resolve(r.metering, profile.metering));
            let missing = info.sets.iter().find_map(|s| {
                let idx = sample_frames(cfg.kind, s).ok()?;
                [&s.static_frames, &s.dynamic_frames]
                    .into_iter()
                    .flat_map(|fs| idx.iter().filter_map(|&i| fs.get(i)))
                    .map(|f| linear_sibling(f))
                    .find(|f| !f.is_file())
            });
            source = match (r.source, missing) {
                (Source::Display, _) | (Source::Auto, Some(_)) => Source::Display,
                (Source::Linear | Source::Auto, None) => Source::Linear,
                (Source::Linear, Some(f)) => {
                    return Err(Error::layout(
                        &f,
                        "missing: `source = \"linear\"` needs every frame's linear EXR \
                         (generate with write_linear = true, or use source = \"display\")",
                    ));
                }
            };
            if source == Source::Display {
                linearise = Some(profile.source_response.inverse_table_to_white());
            }
            // The operator always receives linear, exposed frames.
            profile.source_response = Response::Linear;
            for &iso in &r.isos {
                let opts = RealismOptions {
                    iso,
                    exposure: 1.0,
                    noise: r.noise,
                    colour: r.colour,
                    output_bits: 8,
                };
                if cfg.kind == SampleKind::Network1
                    && cfg.target_frames == TargetFrames::Clean
                    && r.noise != NoiseModel::None
                {
                    let quiet = RealismOptions {
                        noise: NoiseModel::None,
                        ..opts.clone()
                    };
                    clean.push(Realism::new(&profile, &quiet)?);
                }
                realism.push((iso, Realism::new(&profile, &opts)?));
            }
        }
        Ok(Loader {
            cfg: cfg.clone(),
            keys: info.sets.iter().map(|_| OnceLock::new()).collect(),
            images: Mutex::new(HashMap::new()),
            cached_bytes: AtomicUsize::new(0),
            mix: None,
            sets: info.sets,
            realism,
            clean,
            source,
            linearise,
            white,
            metering,
        })
    }

    /// The exposure rule the sets are metered with and where it came from; `None` in pure mode.
    pub fn metering(&self) -> Option<Resolved> {
        self.metering
    }

    /// Samples per epoch (one per set).
    pub fn len(&self) -> usize {
        self.sets.len()
    }

    pub fn is_empty(&self) -> bool {
        self.sets.is_empty()
    }

    pub fn config(&self) -> &LoaderConfig {
        &self.cfg
    }

    /// What the training frames are made from, for logs and reports.
    pub fn describe_source(&self) -> String {
        let own = self.describe_own();
        match &self.mix {
            Some((other, f)) => format!(
                "{own}; a share {f} of the samples from {}: {}",
                other.cfg.dataset.display(),
                other.describe_own()
            ),
            None => own,
        }
    }

    fn describe_own(&self) -> String {
        match (&self.cfg.realism, self.metering) {
            (Some(r), Some(m)) => format!(
                "sensor realism ({}) from {}; exposure metered per set ({m}) × {} ± {} EV",
                r.profile.display(),
                self.source,
                r.exposure,
                r.ev_jitter
            ),
            _ => {
                "the dataset's display frames as they are (no sensor realism), targets in units of \
                  the reference frame's white"
                    .into()
            }
        }
    }

    /// Set index of sample `index` in `epoch`: a seeded Fisher–Yates permutation per epoch.
    fn set_of(&self, epoch: u64, index: usize) -> usize {
        let mut order: Vec<usize> = (0..self.sets.len()).collect();
        let mut rng = Rng::from_parts(self.cfg.seed, &[0x5e75, epoch]);
        for i in (1..order.len()).rev() {
            order.swap(i, rng.int(0, i));
        }
        order[index % order.len()]
    }

    /// A file of `set`, decoded once while the cache has room.
    fn image(&self, set: &SetInfo, path: &Path) -> Result<Arc<Image>> {
        let lock = || self.images.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(img) = lock().get(path) {
            return Ok(Arc::clone(img));
        }
        let img = Arc::new(read_set_image(set, path)?);
        let bytes = img.data.len() * std::mem::size_of::<f32>();
        if self.cached_bytes.fetch_add(bytes, Ordering::Relaxed) + bytes <= CACHE_BYTES {
            lock().insert(path.to_path_buf(), Arc::clone(&img));
        } else {
            self.cached_bytes.fetch_sub(bytes, Ordering::Relaxed);
        }
        Ok(img)
    }

    /// A frame as linear values in realism's starting unit: the EXR sibling (Linear source),
    /// or the display frame through the source response (Display source, 1 = its white);
    /// cropped to `window` ([x0, y0, side]) where given, before the per-pixel curve.
    fn linear_frame(
        &self,
        set: &SetInfo,
        frame: &Path,
        window: Option<[usize; 3]>,
    ) -> Result<Image> {
        let path = match self.linearise {
            None => linear_sibling(frame),
            Some(_) => frame.to_path_buf(),
        };
        let img = self.image(set, &path)?;
        let img = match window {
            Some([x0, y0, side]) => crop(&img, x0, y0, side),
            None => Image::clone(&img),
        };
        Ok(match &self.linearise {
            None => img,
            Some(lut) => img.map(|v| lut[(v.clamp(0.0, 1.0) * 65535.0).round() as usize]),
        })
    }

    /// The metered EV0 key of set `k` in realism's starting unit (cached).
    fn key(&self, k: usize) -> Result<f32> {
        let set = &self.sets[k];
        let rule = self.metering.map(|m| m.rule).ok_or_else(|| {
            Error::Invalid("loader: exposure metering needs a realism config".into())
        })?;
        self.keys[k]
            .get_or_init(|| {
                let radiance = match (&set.ground_truth, self.source) {
                    (Some(gt), Source::Linear) if gt.kind == GroundTruthKind::Linear => {
                        self.image(set, &gt.path).map(|i| Image::clone(&i))
                    }
                    _ => {
                        let frames = if set.static_frames.is_empty() {
                            &set.dynamic_frames
                        } else {
                            &set.static_frames
                        };
                        self.linear_frame(set, &frames[set.reference], None)
                    }
                }
                .map_err(|e| e.to_string())?;
                rule.key(&radiance).map(|e| e.key)
            })
            .clone()
            .map_err(|m| Error::layout(&set.dir, format!("set '{}': {m}", set.name)))
    }

    /// Sample `index` of `epoch`: a pure function of (config, epoch, index).
    pub fn sample(&self, epoch: u64, index: usize) -> Result<Sample> {
        let k = self.set_of(epoch, index);
        let d = self.draw(k, epoch, index)?;
        let (channels, input_hwc, target, times) = match self.cfg.kind {
            SampleKind::Network1 => self.network1(&d)?,
            SampleKind::Network2 => self.network2(&d)?,
        };
        let p = self.cfg.patch;
        let input = to_chw(&dihedral(&input_hwc, p, channels, d.t), p, channels);
        Ok(Sample {
            input,
            channels,
            size: p,
            target,
            exposure_times: times,
            set: d.set.name.clone(),
            iso: d.op.map(|(iso, _)| *iso),
        })
    }

    /// Sample `index` of `epoch`'s random choices, from the sample's own generator in a fixed
    /// order (crop x, crop y, dihedral transform, ISO, exposure jitter, then — only with a
    /// `static_fraction` — whether the sample is still: drawing them in another order would
    /// change every sample), and its noise seed.
    fn draw(&self, k: usize, epoch: u64, index: usize) -> Result<Draw<'_>> {
        let set = &self.sets[k];
        let mut rng = Rng::from_parts(self.cfg.seed, &[epoch, index as u64]);
        let p = self.cfg.patch;
        let x0 = rng.int(0, set.width - p);
        let y0 = rng.int(0, set.height - p);
        let t = if self.cfg.augment {
            rng.int(0, 7) as u8
        } else {
            0
        };
        let pick = (!self.realism.is_empty()).then(|| rng.int(0, self.realism.len() - 1));
        // The sample's EV0 exposure: the metered key, the user's factor, a random jitter.
        let exposure = match &self.cfg.realism {
            Some(r) => {
                let jitter = r.ev_jitter * rng.range(-1.0, 1.0) as f64;
                self.key(k)? * (r.exposure * jitter.exp2()) as f32
            }
            None => 1.0,
        };
        let f = self.cfg.static_fraction;
        let still = f > 0.0 && rng.range(0.0, 1.0) < f as f32;
        Ok(Draw {
            loader: self,
            set,
            x0,
            y0,
            t,
            op: pick.map(|i| &self.realism[i]),
            clean: pick.and_then(|i| self.clean.get(i)),
            exposure,
            noise_seed: hash(self.cfg.seed, &[0x0153, epoch, index as u64]),
            still,
        })
    }

    /// Network-1's sample: the EV−3 and EV0 frames interleaved (6 channels) and the blend
    /// classes of the clean frames (noisy ones when there is no clean operator), transformed.
    fn network1(&self, d: &Draw) -> Result<(usize, Vec<f32>, Target, Vec<f32>)> {
        let (set, p) = (d.set, self.cfg.patch);
        let idx = frames_at(set, &NETWORK1_EVS)?;
        let frames = if set.static_frames.is_empty() {
            &set.dynamic_frames
        } else {
            &set.static_frames
        };
        let sigma = self.cfg.target_sigma;
        let (low, high, classes) = match (d.op, d.clean) {
            (Some((_, r)), Some(c)) => {
                let lin = [d.exposed(&frames[idx[0]])?, d.exposed(&frames[idx[1]])?];
                let classes =
                    blend_classes_smoothed(&c.apply(&lin[0], 0), &c.apply(&lin[1], 0), sigma)?;
                let low = r.apply(&lin[0], hash(d.noise_seed, &[0]));
                let high = r.apply(&lin[1], hash(d.noise_seed, &[1]));
                (low, high, classes)
            }
            _ => {
                let low = d.realistic(&frames[idx[0]], 0)?;
                let high = d.realistic(&frames[idx[1]], 1)?;
                let classes = blend_classes_smoothed(&low, &high, sigma)?;
                (low, high, classes)
            }
        };
        let mut hwc = Vec::with_capacity(p * p * 6);
        for (l, h) in low.data.chunks_exact(3).zip(high.data.chunks_exact(3)) {
            hwc.extend_from_slice(l);
            hwc.extend_from_slice(h);
        }
        let classes = dihedral(&classes, p, 1, d.t);
        Ok((6, hwc, Target::Classes(classes), vec![0.125, 1.0]))
    }

    /// Network-2's sample: per frame (EV−2, 0, +2, or a three-frame set's own EVs:
    /// [`network2_frames`]) LDR and response⁻¹(LDR) / t (18 channels;
    /// the network's input curve, LDR^2.2 by default) and the
    /// linear HDR target, transformed.
    fn network2(&self, d: &Draw) -> Result<(usize, Vec<f32>, Target, Vec<f32>)> {
        let (set, p) = (d.set, self.cfg.patch);
        let (idx, times) = network2_frames(set)?;
        let stat = !set.static_frames.is_empty();
        let pick = |i: usize| -> &Path {
            // The reference from the static set, the others from the dynamic set (a still
            // sample: all from the static set).
            if (i == 1 || d.still) && stat {
                &set.static_frames[idx[i]]
            } else {
                &set.dynamic_frames[idx[i]]
            }
        };
        let wu = Response::Gamma { gamma: 2.2 };
        // None: Wu et al.'s LDR^2.2.
        let curve = self.cfg.input_response.as_ref().unwrap_or(&wu);
        let mut frames = Vec::with_capacity(3);
        for i in 0..3 {
            frames.push(d.realistic(pick(i), i as u64)?);
        }
        let hdr = self.network2_target(d, &idx, times)?;
        let mut hwc = Vec::with_capacity(p * p * 18);
        for px in 0..p * p {
            for (f, &ti) in frames.iter().zip(&times) {
                let v = &f.data[px * 3..px * 3 + 3];
                hwc.extend_from_slice(v);
                hwc.extend(v.iter().map(|&x| curve.invert_f32(x) / ti));
            }
        }
        let hdr = dihedral(&hdr.data, p, 3, d.t);
        Ok((18, hwc, Target::Hdr(to_chw(&hdr, p, 3)), times.to_vec()))
    }

    /// Network-2's target crop: the set's linear ground truth, else the triangle merge of its
    /// static frames (`idx`: their indices, `times`: their exposure times), through the
    /// sample's realism into the device's (or the scene's) linear space.
    fn network2_target(&self, d: &Draw, idx: &[usize], times: [f32; 3]) -> Result<Image> {
        let (set, x0, y0, p) = (d.set, d.x0, d.y0, self.cfg.patch);
        // The target in units of the reference frame's white (`white`), whatever the mode:
        // 1 = EV0's clipping point, as the test ground truth. Kalantari/Wu files are first
        // brought from their own unit into the reference's.
        let (hdr, white) = match &set.ground_truth {
            Some(gt) if gt.kind == GroundTruthKind::Linear => (
                layout::to_reference_unit(set, gt, crop(&*self.image(set, &gt.path)?, x0, y0, p)),
                self.white,
            ),
            _ if !set.static_frames.is_empty() => {
                let s: Vec<Image> = idx
                    .iter()
                    .map(|&i| {
                        self.image(set, &set.static_frames[i])
                            .map(|f| crop(&f, x0, y0, p))
                    })
                    .collect::<Result<_>>()?;
                // LDR^2.2 / t: the reference frame's white is 1.
                let m = triangle_merge(&[s[0].clone(), s[1].clone(), s[2].clone()], times, 2.2)?;
                (m, 1.0)
            }
            _ => {
                return Err(Error::layout(
                    &set.dir,
                    format!(
                        "set '{}' has no linear ground truth and no static frames",
                        set.name
                    ),
                ));
            }
        };
        Ok(match d.op {
            // Linear source: frames and ground truth share the engine's unit; display
            // source: the frames are in units of the source's white, so is the target.
            Some((_, r)) => {
                let unit = match self.source {
                    Source::Linear => d.exposure,
                    _ => d.exposure / white,
                };
                let space = self
                    .cfg
                    .realism
                    .as_ref()
                    .map_or(TargetSpace::Device, |r| r.target_space);
                r.target_linear(&hdr.map(|v| v * unit), space)
            }
            None => hdr.map(|v| v / white),
        })
    }

    /// Batches of one epoch, computed on `workers` threads with bounded prefetch, in index
    /// order. The last batch may be smaller.
    pub fn epoch(self: &Arc<Self>, epoch: u64) -> Batches {
        let n = self.len() as u64;
        self.range(epoch * n, (epoch + 1) * n)
    }

    /// Sample number `g` of the endless stream the trainer reads: sample `g mod len` of epoch
    /// `g div len`. A training step s reads g = s·batch_size … (s+1)·batch_size − 1, so a
    /// resumed run reads exactly the samples an uninterrupted one would have.
    pub fn stream_sample(&self, g: u64) -> Result<Sample> {
        if let Some((other, f)) = &self.mix
            && Rng::from_parts(self.cfg.seed, &[MIX_DRAW, g]).range(0.0, 1.0) < *f as f32
        {
            return other.stream_sample(g);
        }
        let n = self.len() as u64;
        self.sample(g / n, (g % n) as usize)
    }

    /// This stream with `other`'s samples in a share `fraction` of its places: stream sample g
    /// is `other`'s sample g where a draw from (this stream's seed, g) falls under `fraction`,
    /// so a resumed run reads the same samples.
    pub fn mixed(mut self, other: Loader, fraction: f64) -> Loader {
        self.mix = Some((Box::new(other), fraction));
        self
    }

    /// Batches of the stream samples `start..end` (see [`stream_sample`](Self::stream_sample)),
    /// computed on `workers` threads with bounded prefetch and returned in order; batches never
    /// straddle `end`, so the last may be smaller.
    pub fn range(self: &Arc<Self>, start: u64, end: u64) -> Batches {
        let (tx, rx) = sync_channel(self.cfg.prefetch.max(1));
        let next = Arc::new(AtomicU64::new(start));
        for _ in 0..self.cfg.workers {
            let (me, tx, next) = (Arc::clone(self), tx.clone(), Arc::clone(&next));
            std::thread::spawn(move || {
                loop {
                    let g = next.fetch_add(1, Ordering::Relaxed);
                    if g >= end || tx.send((g, me.stream_sample(g))).is_err() {
                        break;
                    }
                }
            });
        }
        Batches {
            rx,
            pending: BTreeMap::new(),
            next: start,
            end,
            batch_size: self.cfg.batch_size as u64,
        }
    }
}

fn to_chw(hwc: &[f32], size: usize, c: usize) -> Vec<f32> {
    let mut out = vec![0.0; hwc.len()];
    for (px, v) in hwc.chunks_exact(c).enumerate() {
        for (k, &x) in v.iter().enumerate() {
            out[k * size * size + px] = x;
        }
    }
    out
}

/// Iterator over batches of stream samples; reorders worker output by index.
pub struct Batches {
    rx: Receiver<(u64, Result<Sample>)>,
    pending: BTreeMap<u64, Result<Sample>>,
    next: u64,
    end: u64,
    batch_size: u64,
}

impl Iterator for Batches {
    type Item = Result<Vec<Sample>>;
    fn next(&mut self) -> Option<Self::Item> {
        if self.next >= self.end {
            return None;
        }
        let end = (self.next + self.batch_size).min(self.end);
        let mut batch = Vec::with_capacity((end - self.next) as usize);
        while self.next < end {
            let item = match self.pending.remove(&self.next) {
                Some(s) => s,
                None => match self.rx.recv() {
                    Ok((i, s)) => {
                        self.pending.insert(i, s);
                        continue;
                    }
                    Err(_) => return Some(Err(Error::Invalid("loader workers stopped".into()))),
                },
            };
            match item {
                Ok(s) => batch.push(s),
                Err(e) => {
                    self.next = self.end;
                    return Some(Err(e));
                }
            }
            self.next += 1;
        }
        Some(Ok(batch))
    }
}
