//! The realism operator: pure synthetic frame + (ISO, exposure, seed) → sensor-realistic frame.
//!
//! Per pixel, in physical order:
//! 1. linearise the synthetic code values with the profile's *source* response, normalised so
//!    the source's clipping point is 1 (for the engine's filmic curve, code 1.0 ↔ 7.24 → 1);
//!    a linear source (EXR renders) passes values through unclipped;
//! 2. colour: device = T · synthetic (or the root-polynomial), negative results clamped to 0;
//! 3. scale to DN: signal I = device · exposure · (white − black);
//! 4. noise: the paper's normal approximation I + N(0, a·I + b), or exact Poisson-Gaussian
//!    a·Poisson(I / a) + N(0, b) (a, b in DN, from the profile's normalised a, b at this ISO);
//! 5. add the black level; 6. extra effects of the profile (src/sensor/effects: signal-stage
//!    effects act before step 4, noise-stage ones change step 4, offsets come here);
//! 7. clip to [0, white]; 8. quantise to integer DN;
//! 9. device response of (DN − black)/(white − black) → code value, quantised to 8 or 16 bits
//!    (after the output floor, where the profile has one); 10. JPEG storage, where the profile
//!    has it (the whole frame encoded and decoded again).
//!
//! Random draws come from a generator seeded by (seed, row), so output bits do not depend on the
//! number of threads. The same operator simulates captures for the sim-to-real gap workflow
//! (`to_dn`), so training data and simulation cannot drift apart.

use crate::error::{Error, Result};
use crate::io::{BitDepth, Image};
use crate::rng::hash;
use crate::sensor::effects::Plan;
use crate::sensor::profile::{Response, SensorProfile};
use rand::SeedableRng;
use rand_distr::{Distribution, Poisson, StandardNormal, StudentT};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::{Arc, Mutex};

/// The space of Network-2's linear ground truth. `Device`: the device's linear RGB after its
/// colour transform T, the same space as the inputs, so a network never has to correct colour.
/// `Scene`: scene-linear Rec. 709 at the same exposure, with T on the inputs only, as a device's
/// ISP renders: the network must undo T, so the colour model can matter (docs/protocol.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum TargetSpace {
    #[default]
    Device,
    Scene,
}

impl TargetSpace {
    /// For `skip_serializing_if`: configs and recipes written before the key existed keep
    /// their text (a run's or test set's identity).
    pub fn is_device(&self) -> bool {
        *self == TargetSpace::Device
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseModel {
    /// The paper's N(0, a·I + b).
    #[default]
    Gaussian,
    /// Exact shot noise a·Poisson(I/a) plus Gaussian read noise N(0, b).
    PoissonGaussian,
    /// No noise (colour and quantisation only): for ablations and tests.
    None,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RealismOptions {
    pub iso: f64,
    /// Multiplier on the linearised signal (1 = the source's clipping point at white level).
    #[serde(default = "one")]
    pub exposure: f64,
    #[serde(default)]
    pub noise: NoiseModel,
    /// Apply the profile's colour transform (the colour ablation turns it off).
    #[serde(default = "yes")]
    pub colour: bool,
    /// Bits of the LDR output.
    #[serde(default = "eight")]
    pub output_bits: u32,
}

fn one() -> f64 {
    1.0
}
fn yes() -> bool {
    true
}
fn eight() -> u32 {
    8
}

impl RealismOptions {
    pub fn new(iso: f64) -> Self {
        RealismOptions {
            iso,
            exposure: 1.0,
            noise: NoiseModel::Gaussian,
            colour: true,
            output_bits: 8,
        }
    }
}

enum ColourOp {
    Identity,
    Matrix([[f32; 3]; 3]),
    RootPoly([[f32; 6]; 3]),
}

impl ColourOp {
    /// Plain loops, not `array::from_fn`: the closure form was not inlined in the hot path.
    #[inline(always)]
    fn apply(&self, lin: [f32; 3]) -> [f32; 3] {
        let mut dev = lin;
        match self {
            ColourOp::Identity => {}
            ColourOp::Matrix(m) => {
                for (d, row) in dev.iter_mut().zip(m) {
                    *d = row[0] * lin[0] + row[1] * lin[1] + row[2] * lin[2];
                }
            }
            ColourOp::RootPoly(m) => {
                let t = [
                    lin[0],
                    lin[1],
                    lin[2],
                    (lin[0] * lin[1]).max(0.0).sqrt(),
                    (lin[1] * lin[2]).max(0.0).sqrt(),
                    (lin[0] * lin[2]).max(0.0).sqrt(),
                ];
                for (d, row) in dev.iter_mut().zip(m) {
                    *d = row.iter().zip(&t).map(|(a, b)| a * b).sum();
                }
            }
        }
        dev
    }
}

/// A profile prepared for one ISO and option set: tables precomputed, ready for many frames.
pub struct Realism {
    /// Source linearisation: None for a linear source (values pass through, unclipped, so
    /// exposure < 1 can bring render highlights into range); else a table over the 65536
    /// 16-bit code values, exact for 8- and 16-bit inputs (k/255 = 257k/65535) and within half
    /// a 16-bit step for float inputs.
    source_lut: Option<Vec<f32>>,
    colour: ColourOp,
    /// Linear value of the source's clipping point (the normalisation of step 1).
    source_sat: f32,
    exposure: f32,
    scale: f32,
    a_dn: [f32; 3],
    b_dn: [f32; 3],
    noise: NoiseModel,
    black: f32,
    white: f32,
    /// Integer DN → final output code value (device response, quantised to the output bits).
    output_lut: Vec<f32>,
    /// The profile's extra effects (src/sensor/effects); `plain` when none touches the pixel
    /// loop, which then runs the original fast path.
    plan: Plan,
    plain: bool,
    range: f32,
    /// Fixed-pattern maps of the last frame size (built once per size, shared by frames).
    patterns: Mutex<Option<Arc<Patterns>>>,
}

/// Fixed patterns of one frame size: per-value gain (vignetting × PRNU) and offset (columns,
/// DSNU, hot pixels).
struct Patterns {
    size: (usize, usize),
    gain: Option<Vec<f32>>,
    offset: Option<Vec<f32>>,
}

/// Tags that separate the per-row draws of the effects from the noise draws.
const ROW_TAG: u64 = 0x524f_5721;
const HEAVY_TAG: u64 = 0x4845_4156;
/// Tag of a frame's local gain field in its seed.
const LOCAL_GAIN_TAG: u64 = 0x4c47_4149;

/// x limited to [0, hi], with NaN → 0 (f32::clamp would pass NaN through).
#[inline(always)]
#[allow(clippy::manual_clamp)]
fn bound(x: f32, hi: f32) -> f32 {
    x.max(0.0).min(hi)
}

/// Exact shot noise of a signal `i` DN with gain `a` DN per electron: a·Poisson(i/a).
#[inline(always)]
fn shot_noise(i: f32, a: f32, rng: &mut Xoshiro256PlusPlus) -> f32 {
    if a > 0.0 && i > 0.0 {
        let lambda = (i / a) as f64;
        let k: f64 = Poisson::new(lambda)
            .map(|p| p.sample(rng))
            .unwrap_or(lambda);
        k as f32 * a
    } else {
        i
    }
}

/// Truncating float → index for values already clamped to [0, 2^24): a plain conversion
/// instruction, without the saturation checks of `as` (a third of the per-pixel work here).
#[inline(always)]
fn index(x: f32) -> usize {
    debug_assert!((0.0..16_777_216.0).contains(&x));
    // SAFETY: every caller limits x with `bound` (NaN → 0, ±inf → the ends) to
    // [0, 65535.5] or [0, white + 0.5] with white < 2^16, so x is finite and fits in u32.
    unsafe { x.to_int_unchecked::<u32>() as usize }
}

/// Per-thread row buffers: normal draws, and a and b repeated per value of a row.
#[derive(Default)]
struct Scratch {
    z: Vec<f32>,
    a: Vec<f32>,
    b: Vec<f32>,
}

impl Scratch {
    fn prepare(&mut self, n: usize, a: &[f32; 3], b: &[f32; 3]) {
        if self.a.len() != n {
            self.a = (0..n).map(|k| a[k % 3]).collect();
            self.b = (0..n).map(|k| b[k % 3]).collect();
        }
    }
}

impl Realism {
    pub fn new(profile: &SensorProfile, opts: &RealismOptions) -> Result<Realism> {
        let out_depth = BitDepth::from_bits(opts.output_bits).ok_or_else(|| {
            Error::flag("--bits", format!("{} must be 8 or 16", opts.output_bits))
        })?;
        if !(opts.exposure > 0.0 && opts.exposure.is_finite()) {
            return Err(Error::flag(
                "--exposure",
                format!("{} must be > 0", opts.exposure),
            ));
        }
        let plan = Plan::from_effects(&profile.effects)
            .map_err(Error::within(format!("profile '{}'", profile.name)))?;
        if plan.jpeg.is_some() && out_depth != BitDepth::Eight {
            return Err(Error::profile(
                &profile.name,
                "its `jpeg` effect stores 8-bit frames: the output must be 8 bits",
            ));
        }
        let sat = profile.source_response.invert(1.0).max(1e-12);
        let source_lut = match &profile.source_response {
            Response::Linear => None,
            src => Some(src.inverse_table_to_white()),
        };
        let colour = if !opts.colour {
            ColourOp::Identity
        } else {
            let c = profile.colour.as_ref().ok_or_else(|| {
                Error::profile(
                    &profile.name,
                    "has no colour calibration (run `hdrsynth calibrate colour`, or turn colour \
                     off)",
                )
            })?;
            match (&c.root_polynomial, c.use_root_polynomial) {
                (Some(rp), true) => ColourOp::RootPoly(rp.map(|r| r.map(|v| v as f32))),
                _ => ColourOp::Matrix(c.matrix.map(|r| r.map(|v| v as f32))),
            }
        };
        let l = &profile.levels;
        let range = l.white_level - l.black_level;
        let (a_dn, b_dn) = match opts.noise {
            NoiseModel::None => ([0.0; 3], [0.0; 3]),
            _ => {
                let (a, b) = profile.noise_at(opts.iso)?;
                (
                    std::array::from_fn(|c| (a[c] * range) as f32 * plan.a_scale[c]),
                    std::array::from_fn(|c| (b[c] * range * range) as f32 * plan.b_scale[c]),
                )
            }
        };
        let white_dn = l.white_level.floor() as usize;
        let max_code = out_depth.max_code() as f64;
        let output_lut = (0..=white_dn)
            .map(|dn| {
                let x = crate::sensor::effects::floor::crush(
                    (dn as f64 - l.black_level) / range,
                    plan.floor,
                );
                ((profile.response.apply(x) * max_code).round() / max_code) as f32
            })
            .collect();
        Ok(Realism {
            source_lut,
            colour,
            source_sat: sat as f32,
            exposure: opts.exposure as f32,
            scale: (opts.exposure * range) as f32,
            a_dn,
            b_dn,
            noise: opts.noise,
            black: l.black_level as f32,
            white: l.white_level.floor() as f32,
            output_lut,
            plain: plan.per_pixel_neutral(),
            plan,
            range: range as f32,
            patterns: Mutex::new(None),
        })
    }

    /// The fixed patterns for a w×h frame (cached for the last size).
    fn patterns(&self, w: usize, h: usize) -> Arc<Patterns> {
        let mut slot = self.patterns.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = slot.as_ref().filter(|p| p.size == (w, h)) {
            return p.clone();
        }
        let p = Arc::new(Patterns {
            size: (w, h),
            gain: self.plan.gain_map(w, h),
            offset: self.plan.offset_map(w, h),
        });
        *slot = Some(p.clone());
        p
    }

    /// The first `n` standard normals of row `row`'s generator (the same draws as the plain
    /// path), or zeros outside the frame.
    fn row_normals(seed: u64, row: isize, height: usize, n: usize, z: &mut Vec<f32>) {
        z.clear();
        if row < 0 || row as usize >= height {
            z.resize(n, 0.0);
            return;
        }
        let mut rng = Self::row_rng(seed, row as usize);
        z.extend((0..n).map(|_| {
            let v: f64 = StandardNormal.sample(&mut rng);
            v as f32
        }));
    }

    /// Normal draws of row `row` filtered by the separable kernel (half kernels `kh`, `kv`,
    /// effects/correlated_noise.rs). Every row, inside the frame or not, has its own draws
    /// (the row's n in-frame draws first, so an unfiltered row is unchanged, then 3·R per side
    /// beyond the frame's left and right edges), so the filtered field is stationary up to
    /// the frame's border and keeps unit variance everywhere.
    fn filtered_normals(seed: u64, row: usize, n: usize, kh: &[f32], kv: &[f32], z: &mut Vec<f32>) {
        let (rx, ry) = (kh.len() - 1, kv.len() - 1);
        let pad = 3 * rx;
        let mut line = vec![0.0f32; n + 2 * pad];
        z.clear();
        z.resize(n, 0.0);
        for dy in -(ry as isize)..=ry as isize {
            let y = row as isize + dy;
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(hash(seed, &[y as u64]));
            let mut draw = || -> f32 {
                let v: f64 = StandardNormal.sample(&mut rng);
                v as f32
            };
            for v in &mut line[pad..pad + n] {
                *v = draw();
            }
            for i in (0..pad).chain(pad + n..n + 2 * pad) {
                line[i] = draw();
            }
            let wv = kv[dy.unsigned_abs()];
            for (k, o) in z.iter_mut().enumerate() {
                let c = pad + k;
                let mut h = kh[0] * line[c];
                for (d, w) in kh.iter().enumerate().skip(1) {
                    h += w * (line[c - 3 * d] + line[c + 3 * d]);
                }
                *o += wv * h;
            }
        }
    }

    /// `row_dn` with the profile's effects, in physical order (src/sensor/effects/mod.rs).
    #[allow(clippy::too_many_arguments)]
    fn row_dn_effects(
        &self,
        input: &[f32],
        out: &mut [f32],
        seed: u64,
        row: usize,
        height: usize,
        pat: &Patterns,
        s: &mut Scratch,
    ) {
        let n = out.len();
        let at = row * n;
        // Signal stage: optics and pixel gain, then the response nonlinearity.
        for (o, i) in out.chunks_exact_mut(3).zip(input.chunks_exact(3)) {
            o.copy_from_slice(&self.signal(i));
        }
        if let Some(g) = &pat.gain {
            for (o, g) in out.iter_mut().zip(&g[at..at + n]) {
                *o *= g;
            }
        }
        if let Some(c) = &self.plan.response {
            let r = self.range as f64;
            for o in out.iter_mut() {
                *o = (r * c.apply(*o as f64 / r)) as f32;
            }
        }
        // Noise stage.
        let heavy = self.plan.heavy_dof.map(|d| {
            let t = StudentT::new(d as f64).expect("dof > 4 checked at install");
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(hash(seed, &[row as u64, HEAVY_TAG]));
            let scale = ((d as f64 - 2.0) / d as f64).sqrt();
            (0..n)
                .map(|_| (t.sample(&mut rng) * scale) as f32)
                .collect::<Vec<f32>>()
        });
        match self.noise {
            NoiseModel::None => {}
            NoiseModel::Gaussian => {
                s.prepare(n, &self.a_dn, &self.b_dn);
                match &self.plan.corr_kernels {
                    Some((kh, kv)) => Self::filtered_normals(seed, row, n, kh, kv, &mut s.z),
                    None => Self::row_normals(seed, row as isize, height, n, &mut s.z),
                }
                // Channel correlation mixes a pixel's three draws (no new draws, so the draws
                // of every other effect stay as they are).
                if let Some((a, b)) = self.plan.channel_mix {
                    let k = b / 3f32.sqrt();
                    for z in s.z.chunks_exact_mut(3) {
                        let sum = z[0] + z[1] + z[2];
                        for v in z.iter_mut() {
                            *v = a * *v + k * sum;
                        }
                    }
                }
                match &heavy {
                    None => {
                        for (((o, z), a), b) in out.iter_mut().zip(&s.z).zip(&s.a).zip(&s.b) {
                            *o += (a * *o + b).max(0.0).sqrt() * z;
                        }
                    }
                    Some(t) => {
                        for ((((o, z), a), b), t) in
                            out.iter_mut().zip(&s.z).zip(&s.a).zip(&s.b).zip(t)
                        {
                            *o += (a * *o).max(0.0).sqrt() * z + b.max(0.0).sqrt() * t;
                        }
                    }
                }
            }
            NoiseModel::PoissonGaussian => {
                let mut rng = Self::row_rng(seed, row);
                for (k, v) in out.iter_mut().enumerate() {
                    let c = k % 3;
                    let i = *v;
                    let shot = shot_noise(i, self.a_dn[c], &mut rng);
                    let zv: f64 = StandardNormal.sample(&mut rng);
                    let read = heavy.as_ref().map_or(zv as f32, |t| t[k]);
                    *v = shot + self.b_dn[c].max(0.0).sqrt() * read;
                }
            }
        }
        // Offset stage: pedestal, per-frame row offset, fixed offsets; then clip and quantise.
        let mut add = self.black + self.plan.black_offset;
        if self.plan.row_sigma > 0.0 {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(hash(seed, &[row as u64, ROW_TAG]));
            let z: f64 = StandardNormal.sample(&mut rng);
            add += self.plan.row_sigma * z as f32;
        }
        match &pat.offset {
            None => {
                for v in out.iter_mut() {
                    *v = index(bound(*v + add, self.white) + 0.5) as f32;
                }
            }
            Some(off) => {
                for (v, o) in out.iter_mut().zip(&off[at..at + n]) {
                    *v = index(bound(*v + add + o, self.white) + 0.5) as f32;
                }
            }
        }
    }

    /// Signal above black in DN (noise-free) for one synthetic pixel.
    #[inline(always)]
    fn signal(&self, v: &[f32]) -> [f32; 3] {
        let lin = match &self.source_lut {
            None => [v[0].max(0.0), v[1].max(0.0), v[2].max(0.0)],
            Some(lut) => {
                let at = |x: f32| lut[index(bound(x, 1.0) * 65535.0 + 0.5)];
                [at(v[0]), at(v[1]), at(v[2])]
            }
        };
        let mut dev = self.colour.apply(lin);
        for d in &mut dev {
            *d = d.max(0.0) * self.scale;
        }
        dev
    }

    /// One row of quantised DN (`out`, interleaved RGB) from one row of synthetic code values.
    /// Staged so each pass is a simple loop the CPU can overlap or vectorise: signal, noise
    /// standard deviation, normal draws (the only sequential part), then combine.
    fn row_dn(&self, input: &[f32], out: &mut [f32], seed: u64, row: usize, s: &mut Scratch) {
        let mut rng = Self::row_rng(seed, row);
        for (o, i) in out.chunks_exact_mut(3).zip(input.chunks_exact(3)) {
            o.copy_from_slice(&self.signal(i));
        }
        match self.noise {
            NoiseModel::None => {}
            NoiseModel::Gaussian => {
                s.prepare(out.len(), &self.a_dn, &self.b_dn);
                s.z.clear();
                s.z.extend((0..out.len()).map(|_| {
                    let v: f64 = StandardNormal.sample(&mut rng);
                    v as f32
                }));
                // Flat loop over per-value parameters so it vectorises (sqrtps).
                for (((o, z), a), b) in out.iter_mut().zip(&s.z).zip(&s.a).zip(&s.b) {
                    *o += (a * *o + b).max(0.0).sqrt() * z;
                }
            }
            NoiseModel::PoissonGaussian => {
                for px in out.chunks_exact_mut(3) {
                    for (c, v) in px.iter_mut().enumerate() {
                        let i = *v;
                        let shot = shot_noise(i, self.a_dn[c], &mut rng);
                        let zv: f64 = StandardNormal.sample(&mut rng);
                        *v = shot + self.b_dn[c].max(0.0).sqrt() * zv as f32;
                    }
                }
            }
        }
        for v in out.iter_mut() {
            // Non-negative after the clamp, so +0.5 and truncation rounds half up; i32 keeps it
            // vectorisable and avoids the libm `roundf` call of baseline x86-64.
            *v = index(bound(*v + self.black, self.white) + 0.5) as f32;
        }
    }

    fn row_rng(seed: u64, row: usize) -> Xoshiro256PlusPlus {
        Xoshiro256PlusPlus::seed_from_u64(hash(seed, &[row as u64]))
    }

    /// The sensor frame in DN (integers stored as f32), before the device response.
    pub fn to_dn(&self, input: &Image, seed: u64) -> Image {
        let mut out = Image::new(0, 0);
        self.rows_into(input, seed, &mut out, false);
        out
    }

    /// `to_dn` into a caller's buffer (resized as needed): the gap workflow simulates
    /// thousands of frames, and a fresh frame each time cost page faults and memset.
    pub fn to_dn_into(&self, input: &Image, seed: u64, out: &mut Image) {
        self.rows_into(input, seed, out, false);
    }

    /// `to_dn_into` for some rows of a frame of `height` rows: `input` holds rows `rows`
    /// stacked, and each output row is bit-identical to that row of the whole frame's `to_dn`
    /// (its draws and patterns depend on the frame row), so the gap workflow can simulate a
    /// subset of a large frame exactly.
    pub fn to_dn_rows_into(
        &self,
        input: &Image,
        rows: &[usize],
        height: usize,
        seed: u64,
        out: &mut Image,
    ) {
        assert_eq!(input.height, rows.len(), "one input row per frame row");
        self.rows_of(input, Some((rows, height)), seed, out, false);
    }

    /// Device response of a DN frame: code values in [0, 1], quantised to the output bits.
    pub fn dn_to_ldr(&self, dn: &Image) -> Image {
        dn.map(|d| self.output_lut[index(bound(d, self.white))])
    }

    /// Synthetic frame → sensor-realistic LDR frame in one pass (same draws as `to_dn`).
    pub fn apply(&self, input: &Image, seed: u64) -> Image {
        let mut out = Image::new(0, 0);
        self.apply_into(input, seed, &mut out);
        out
    }

    /// `apply` into a caller's buffer (resized as needed), so loaders reuse their allocations.
    pub fn apply_into(&self, input: &Image, seed: u64, out: &mut Image) {
        match self.plan.local_gain {
            None => self.rows_into(input, seed, out, true),
            // The field spans the frame: applied to the whole DN frame, then the response.
            Some((sigma, scale)) => {
                self.rows_into(input, seed, out, false);
                let field_seed = hash(seed, &[LOCAL_GAIN_TAG]);
                crate::sensor::effects::local_gain::apply_dn(
                    out, self.black, sigma, scale, field_seed,
                );
                for d in &mut out.data {
                    *d = self.output_lut[index(bound(d.round(), self.white))];
                }
            }
        }
        if let Some(q) = self.plan.jpeg {
            crate::sensor::effects::jpeg::round_trip(out, q);
        }
    }

    /// Rows in parallel into `out`: DN, then (with `ldr`) the device response.
    fn rows_into(&self, input: &Image, seed: u64, out: &mut Image, ldr: bool) {
        self.rows_of(input, None, seed, out, ldr);
    }

    /// `rows_into` where input row r is frame row `rows[r]` of a frame of `height` rows
    /// (None: the input is the whole frame).
    fn rows_of(
        &self,
        input: &Image,
        frame: Option<(&[usize], usize)>,
        seed: u64,
        out: &mut Image,
        ldr: bool,
    ) {
        out.width = input.width;
        out.height = input.height;
        out.data.resize(input.data.len(), 0.0);
        let w3 = input.width * 3;
        let height = frame.map_or(input.height, |f| f.1);
        let pat = (!self.plain).then(|| self.patterns(input.width, height));
        out.data
            .par_chunks_mut(w3)
            .zip(input.data.par_chunks(w3))
            .enumerate()
            .for_each_init(Scratch::default, |sc, (r, (o, i))| {
                let row = frame.map_or(r, |f| f.0[r]);
                match &pat {
                    None => self.row_dn(i, o, seed, row, sc),
                    Some(p) => self.row_dn_effects(i, o, seed, row, height, p, sc),
                }
                if ldr {
                    for v in o.iter_mut() {
                        *v = self.output_lut[index(*v)];
                    }
                }
            });
    }

    /// A linear HDR image (e.g. ground truth, in the source's linear units) in this device's
    /// linear space: T · (v / source saturation) · exposure, so 1 = the sensor's white level.
    /// No noise, no clipping: the Network-2 target that matches realistic inputs.
    pub fn device_linear(&self, linear: &Image) -> Image {
        self.target_linear(linear, TargetSpace::Device)
    }

    /// The linear target of `linear` in `space`: [`Realism::device_linear`], or for
    /// [`TargetSpace::Scene`] the same exposure scaling without T (the inputs keep T).
    pub fn target_linear(&self, linear: &Image, space: TargetSpace) -> Image {
        let k = self.exposure / self.source_sat;
        let mut out = linear.clone();
        for p in out.data.chunks_exact_mut(3) {
            let v = [p[0].max(0.0) * k, p[1].max(0.0) * k, p[2].max(0.0) * k];
            let d = match space {
                TargetSpace::Device => self.colour.apply(v).map(|x| x.max(0.0)),
                TargetSpace::Scene => v,
            };
            p.copy_from_slice(&d);
        }
        out
    }

    /// Expected DN (noise-free, unclipped, unquantised) of a synthetic pixel: for tests/diagnosis.
    pub fn expected_dn(&self, v: [f32; 3]) -> [f32; 3] {
        self.signal(&v).map(|s| s + self.black)
    }

    /// Noise variance in DN² at a signal of `i` DN above black, per channel.
    pub fn variance_dn(&self, i: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|c| self.a_dn[c] * i[c] + self.b_dn[c])
    }
}
