//! The methods `hdrsynth eval` scores: predictions made elsewhere, Network-1 and Network-2
//! (any network behind a closure), and the classical merge that knows the device.

use super::*;

// ---------------------------------------------------------------------------------------------
// Predictions made elsewhere

/// Linear HDR predictions `DIR/<set name>.exr` (or `.hdr`), scored against each set's linear
/// ground truth. Predictions are taken in the unit of the set's files (the ground truth's, as
/// the field's tools write them). Negative values are clamped to 0 (μ-law is undefined below
/// −1/5000).
pub struct Predictions {
    pub dir: PathBuf,
}

impl Predictions {
    /// The candidates for a set, in order of preference.
    pub fn candidates(&self, set: &SetInfo) -> [PathBuf; 2] {
        [
            self.dir.join(format!("{}.exr", set.name)),
            self.dir.join(format!("{}.hdr", set.name)),
        ]
    }

    pub fn find(&self, set: &SetInfo) -> Option<PathBuf> {
        self.candidates(set).into_iter().find(|p| p.is_file())
    }
}

impl Method for Predictions {
    fn describe(&self, _opts: &EvalOptions) -> String {
        format!(
            "predictions from {} (linear HDR in the unit of each set's ground truth file, scored \
             against it; T = μ-law, μ = 5000)",
            self.dir.display()
        )
    }

    fn missing(&self, set: &SetInfo) -> Option<String> {
        if self.find(set).is_some() {
            return None;
        }
        let [a, b] = self.candidates(set);
        Some(format!("{} or {}", a.display(), b.display()))
    }

    fn run(&self, set: &SetInfo, _opts: &EvalOptions) -> Result<Outcome> {
        let path = self.find(set).ok_or_else(|| {
            let [a, b] = self.candidates(set);
            Error::layout(
                &self.dir,
                format!(
                    "no prediction for set '{}': looked for {} and {}",
                    set.name,
                    a.display(),
                    b.display()
                ),
            )
        })?;
        // One after the other: a file's bytes and decoded planes are transient copies of the
        // image, so parallel reads would double the peak memory for little gain (each decode
        // is parallel already).
        let reference = layout::read_linear_ground_truth(set)?;
        let mut output = read_image(&path)?;
        if (output.width, output.height) != (reference.width, reference.height) {
            return Err(Error::layout(
                &path,
                format!(
                    "prediction is {}×{}, the ground truth of set '{}' is {}×{}",
                    output.width, output.height, set.name, reference.width, reference.height
                ),
            ));
        }
        // The file's unit → hdrsynth's, as the ground truth was.
        let k = set.file_to_reference();
        let negative = output
            .data
            .par_iter_mut()
            .map(|v| {
                let neg = *v < 0.0;
                *v = v.max(0.0) * k;
                neg as usize
            })
            .sum::<usize>();
        let mut notes = Vec::new();
        if negative > 0 {
            notes.push(format!(
                "{}: {negative} negative values clamped to 0",
                path.display()
            ));
        }
        Ok(Outcome {
            output,
            reference,
            scoring: Scoring::Hdr,
            inputs: set_inputs(set),
            notes,
        })
    }
}

/// A network's long-exposure blend weight per pixel for a static (low, high) pair (code values
/// in [0, 1]), at the frames' size.
pub type BlendInference = Box<dyn Fn(&Image, &Image) -> Result<Vec<f32>>>;

/// What Network-1's output is scored against (docs/evaluation.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Network1Reference {
    /// The Laplacian blend (Network-1's own output stage) of the noisy pair with Mertens
    /// weights computed on the noise-free pair: what a network that sees through the noise
    /// would produce. Sets without noise-free frames fall back to `noisy-mertens` (noted).
    #[default]
    CleanWeights,
    /// The Mertens fusion of the noisy pair: rewards imitating noise-driven weights (Mertens'
    /// contrast term is |Laplacian|, which noise inflates).
    NoisyMertens,
}

impl Network1Reference {
    fn describe(self) -> &'static str {
        match self {
            Network1Reference::CleanWeights => {
                "reference = Laplacian blend of the noisy static pair with Mertens weights \
                 (OpenCV defaults: contrast 1, saturation 1, exposure 0) of its noise-free \
                 frames (sets without them: the Mertens fusion of the noisy pair, noted)"
            }
            Network1Reference::NoisyMertens => {
                "reference = Mertens fusion (OpenCV defaults: contrast 1, saturation 1, \
                 exposure 0) of the same noisy static pair"
            }
        }
    }
}

/// Network-1's reference L for the static frames (`low`, `high`) at indices `pair` of `set`
/// (docs/evaluation.md), and a note when `kind` could not be followed (no noise-free frames).
pub fn network1_reference(
    set: &SetInfo,
    pair: (usize, usize),
    low: &Image,
    high: &Image,
    kind: Network1Reference,
) -> Result<(Image, Option<String>)> {
    let noisy_mertens = || {
        let w = MertensWeights::OPENCV_DEFAULT;
        ground_truth::mertens(
            &[low.clone(), high.clone()],
            w.contrast,
            w.saturation,
            w.exposure,
        )
    };
    match kind {
        Network1Reference::NoisyMertens => Ok((noisy_mertens()?, None)),
        Network1Reference::CleanWeights if set.clean_frames.len() != set.evs.len() => Ok((
            noisy_mertens()?,
            Some(format!(
                "set '{}' has no noise-free frames: Network-1 scored against the Mertens fusion \
                 of the noisy pair",
                set.name
            )),
        )),
        Network1Reference::CleanWeights => {
            let read = |i: usize| -> Result<Image> {
                let p = &set.clean_frames[i];
                layout::read_set_image(set, p)
            };
            let (cl, ch) = rayon::join(|| read(pair.0), || read(pair.1));
            let w = ground_truth::blend_weights_high(&cl?, &ch?)?;
            Ok((blend_pair(low, high, &w)?, None))
        }
    }
}

/// Network-1 on the static pair, scored against [`network1_reference`].
pub struct Network1 {
    /// For the report: the network and its checkpoint.
    pub description: String,
    pub weights: BlendInference,
    /// Tone curve k of the T images (output and reference alike).
    pub tone_k: f32,
}

impl Method for Network1 {
    fn describe(&self, opts: &EvalOptions) -> String {
        format!(
            "{}, tone k {}; {}; L before the tone curve, T after it",
            self.description,
            self.tone_k,
            opts.network1_reference.describe()
        )
    }

    fn run(&self, set: &SetInfo, opts: &EvalOptions) -> Result<Outcome> {
        if set.static_frames.len() != set.evs.len() {
            return Err(Error::layout(
                &set.dir,
                format!(
                    "set '{}' has no static (motion-free) frames: Network-1's reference is a \
                     fusion of aligned frames",
                    set.name
                ),
            ));
        }
        let (lo, hi) = set.network1_pair()?;
        let read = |i: usize| -> Result<Image> {
            let p = &set.static_frames[i];
            layout::read_set_image(set, p)
        };
        let (low, high) = rayon::join(|| read(lo), || read(hi));
        let (low, high) = (low?, high?);
        let w = (self.weights)(&low, &high)?;
        if w.len() != low.pixel_count() {
            return Err(Error::Invalid(format!(
                "set '{}': the network returned {} blend weights for {}×{} frames",
                set.name,
                w.len(),
                low.width,
                low.height
            )));
        }
        let output = blend_pair(&low, &high, &w)?;
        let (reference, note) =
            network1_reference(set, (lo, hi), &low, &high, opts.network1_reference)?;
        Ok(Outcome {
            output,
            reference,
            scoring: Scoring::Network1 {
                tone_k: self.tone_k,
            },
            inputs: [lo, hi]
                .iter()
                .map(|&i| {
                    (
                        format!("input {}", ev_tag(set.evs[i])),
                        Frame::File(set.static_frames[i].clone()),
                    )
                })
                .collect(),
            notes: note.into_iter().collect(),
        })
    }
}

/// The three frames [`infer::network2_frames`] picked, for the grid, labelled by their EVs.
fn three_shown(set: &SetInfo, frames: [Image; 3]) -> Vec<(String, Frame)> {
    let evs = [0, set.reference, set.evs.len() - 1].map(|i| set.evs[i]);
    (frames.into_iter().zip(evs))
        .map(|(f, ev)| (format!("input {}", ev_tag(ev)), Frame::Loaded(f)))
        .collect()
}

/// A network's full-resolution inference on three frames (shortest, reference, longest; LDR
/// code values in [0, 1]) with exposure times relative to the reference (how the networks are
/// trained), and the curve the test set records for its frames where it records one → linear
/// HDR of the frames' size in hdrsynth's unit, 1 = the reference exposure's white.
pub type HdrInference = Box<dyn Fn([&Image; 3], [f32; 3], Option<&Response>) -> Result<Image>>;

/// Network-2 (or any three-frame HDR network) on each set's frames as
/// [`infer::network2_frames`] picks them (the frames `hdrsynth infer --set` uses), scored
/// against the set's linear ground truth.
pub struct Network2 {
    /// For the report: the network and its checkpoint.
    pub description: String,
    pub infer: HdrInference,
}

impl Method for Network2 {
    fn describe(&self, _opts: &EvalOptions) -> String {
        format!(
            "{}; scored against each set's linear ground truth (T = μ-law, μ = 5000)",
            self.description
        )
    }

    fn run(&self, set: &SetInfo, opts: &EvalOptions) -> Result<Outcome> {
        let (frames, times) = infer::network2_frames(set)?;
        let evs = [0, set.reference, set.evs.len() - 1].map(|i| set.evs[i]);
        for (f, ev) in frames.iter().zip(evs) {
            if (f.width, f.height) != (set.width, set.height) {
                return Err(Error::layout(
                    &set.dir,
                    format!(
                        "set '{}': frame {} is {}×{}, the set is {}×{}",
                        set.name,
                        ev_tag(ev),
                        f.width,
                        f.height,
                        set.width,
                        set.height
                    ),
                ));
            }
        }
        let [a, b, c] = &frames;
        let mut output = (self.infer)([a, b, c], times, opts.frame_curve.as_ref())?;
        let reference = layout::read_linear_ground_truth(set)?;
        if (output.width, output.height) != (reference.width, reference.height) {
            return Err(Error::Invalid(format!(
                "set '{}': the network returned {}×{} for {}×{} frames",
                set.name, output.width, output.height, reference.width, reference.height
            )));
        }
        // As for predictions: μ-law needs values above −1/5000.
        output.data.par_iter_mut().for_each(|v| *v = v.max(0.0));
        Ok(Outcome {
            output,
            reference,
            scoring: Scoring::Hdr,
            inputs: three_shown(set, frames),
            notes: Vec::new(),
        })
    }
}

// ---------------------------------------------------------------------------------------------
// A classical merge that knows the device

/// A classical way to get HDR from a set's three inputs (shortest, reference, longest), each
/// linearised through the curve the frames were made with: what a user has without a network.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Classical {
    /// The reference frame alone, linearised: what a network that copies its input scores.
    Copy,
    /// Kalantari's triangle merge (`ground_truth::triangle_merge_with`).
    Triangle,
    /// OpenCV's `MergeDebevec` with the known response ([`debevec_merge`]).
    Debevec,
    /// OpenCV's `MergeRobertson` with the known response ([`robertson_merge`]).
    Robertson,
}

impl Classical {
    pub const ALL: [Classical; 4] = [
        Classical::Copy,
        Classical::Triangle,
        Classical::Debevec,
        Classical::Robertson,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Classical::Copy => "copy",
            Classical::Triangle => "triangle",
            Classical::Debevec => "debevec",
            Classical::Robertson => "robertson",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Classical::Copy => "reference frame, linearised (copy)",
            Classical::Triangle => "triangle merge of the inputs",
            Classical::Debevec => "Debevec merge of the inputs (OpenCV MergeDebevec)",
            Classical::Robertson => "Robertson merge of the inputs (OpenCV MergeRobertson)",
        }
    }

    /// Linear HDR, 1 = the reference frame's white, of three frames (values in [0, 1]) with
    /// exposure times relative to the reference, linearised by `response`.
    pub fn merge(self, frames: &[Image; 3], times: [f32; 3], response: &Response) -> Result<Image> {
        let mut out = match self {
            Classical::Copy => frames[1].map(|v| response.invert(v as f64) as f32 / times[1]),
            Classical::Triangle => {
                ground_truth::triangle_merge_with(frames, times, |v| response.invert(v))?
            }
            Classical::Debevec => debevec_merge(frames, &times, response)?,
            Classical::Robertson => robertson_merge(frames, &times, response)?,
        };
        out.data.par_iter_mut().for_each(|v| *v = v.max(0.0));
        Ok(out)
    }
}

impl std::str::FromStr for Classical {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Classical, String> {
        Classical::ALL
            .into_iter()
            .find(|c| c.name() == s.trim())
            .ok_or_else(|| format!("'{s}': expected copy, triangle, debevec or robertson"))
    }
}

/// The frames' common size, after checking that they agree and that `times` holds one
/// finite, positive exposure time per frame.
fn check_merge_inputs(what: &str, frames: &[Image], times: &[f32]) -> Result<(usize, usize)> {
    let refs: Vec<&Image> = frames.iter().collect();
    let size = crate::data::ground_truth::check_frames(what, &refs)?;
    if times.len() != frames.len() || times.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(Error::Invalid(format!(
            "{what}: exposure times {times:?} must be finite, positive and one per frame"
        )));
    }
    Ok(size)
}

/// OpenCV's `MergeDebevec::process` (photo/src/merge.cpp; OpenCV 5.0, and 4.x since
/// opencv/opencv#27270) with a given response: frames as 8-bit codes z = round(255·v); per
/// pixel and frame the weight w = mean over channels of OpenCV's `triangleWeights`
/// (photo/src/hdr_common.cpp: z for 1 ≤ z ≤ 127, 255 − z for 128 ≤ z ≤ 254, and 1e-6 at the
/// clipped codes 0 and 255; z + 1 below 128, else 256 − z, before that change); per channel
/// H = exp(Σ w·(ln R(z) − ln t) / Σ w), the weighted mean in the log domain, R(z) = the
/// response's inverse at z/255 (OpenCV takes `log` of the response table it is given; code 0
/// is read as the value at half a code, since OpenCV's calibrated responses are positive and a
/// known curve's is 0 there). 1 = the reference's white when the times are relative to the
/// reference. Computed in f64 (OpenCV in f32: they agree to ~1e-6 relative).
pub fn debevec_merge(frames: &[Image], times: &[f32], response: &Response) -> Result<Image> {
    let (w, h) = check_merge_inputs("Debevec merge", frames, times)?;
    let floor = response.invert(0.5 / 255.0).max(f64::MIN_POSITIVE);
    let log_r: Vec<f64> = (0..256)
        .map(|z| response.invert(z as f64 / 255.0).max(floor).ln())
        .collect();
    // OpenCV's triangleWeights: a hat 1..127, 127..1, with 1e-6 (f32) at the clipped codes.
    let weight = |z: usize| match z {
        0 | 255 => 1e-6f32 as f64,
        1..=127 => z as f64,
        _ => 255.0 - z as f64,
    };
    let log_t: Vec<f64> = times.iter().map(|&t| (t as f64).ln()).collect();
    let code = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as usize;
    let mut out = Image::new(w, h);
    out.data
        .par_chunks_exact_mut(3)
        .enumerate()
        .for_each(|(px, o)| {
            let mut acc = [0.0f64; 3];
            let mut sum = 0.0;
            for (f, lt) in frames.iter().zip(&log_t) {
                let z = [0, 1, 2].map(|c| code(f.data[px * 3 + c]));
                let wt = z.iter().map(|&z| weight(z)).sum::<f64>() / 3.0;
                for c in 0..3 {
                    acc[c] += wt * (log_r[z[c]] - lt);
                }
                sum += wt;
            }
            for c in 0..3 {
                o[c] = (acc[c] / sum).exp() as f32;
            }
        });
    Ok(out)
}

/// OpenCV's `RobertsonWeights` (photo/src/hdr_common.cpp), in f32 as OpenCV computes it: a
/// Gaussian in the code, w(z) = s·exp(−(z/q − 2)²) + c with q = 255/4, s = e⁴/(e⁴ − 1) and
/// c = 1/(1 − e⁴), so that w is exactly 0 at the clipped codes 0 and 255 and ~1 at mid-grey.
pub fn robertson_weight(z: u8) -> f32 {
    let q = 255.0f32 / 4.0;
    let e4 = 4.0f32.exp();
    let v = z as f32 / q - 2.0;
    (e4 / (e4 - 1.0)) * (-v * v).exp() + 1.0 / (1.0 - e4)
}

/// OpenCV's `MergeRobertson::process` (photo/src/merge.cpp) with a given response: frames as
/// 8-bit codes z = round(255·v); per pixel, channel and frame the weight w = [`robertson_weight`]
/// of that channel's code; H = Σ tᵢ·w(zᵢ)·R(zᵢ) / (Σ tᵢ²·w(zᵢ) + DBL_EPSILON), R(z) = the
/// response's inverse at z/255 — the maximum-likelihood radiance under noise of equal variance
/// in every frame, which gives the longer exposure the larger share. A pixel clipped (code 0 or
/// 255) in every frame has no weight and merges to 0, as in OpenCV: a highlight clipped even in
/// the shortest frame comes out black. 1 = the reference's white when the times are relative
/// to the reference. Weights in f32 as OpenCV's, sums in f64 (OpenCV's in f32: they agree to
/// ~1e-6 relative).
pub fn robertson_merge(frames: &[Image], times: &[f32], response: &Response) -> Result<Image> {
    let (w, h) = check_merge_inputs("Robertson merge", frames, times)?;
    let lut: Vec<(f64, f64)> = (0..=255u8)
        .map(|z| {
            (
                robertson_weight(z) as f64,
                response.invert(z as f64 / 255.0),
            )
        })
        .collect();
    let code = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as usize;
    let mut out = Image::new(w, h);
    out.data.par_iter_mut().enumerate().for_each(|(i, o)| {
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for (f, &t) in frames.iter().zip(times) {
            let (wz, r) = lut[code(f.data[i])];
            let t = t as f64;
            num += t * wz * r;
            den += t * t * wz;
        }
        *o = (num / (den + f64::EPSILON)) as f32;
    });
    Ok(out)
}

/// A [`Classical`] method on a test set whose frames' curve is known (the true device
/// response of a rendered set, a bracket set's recorded encoding); `clean` merges the
/// noise-free frames of a rendered set instead of the noisy inputs.
pub struct ClassicalMerge {
    pub kind: Classical,
    /// The curve the frames were made with: code = response(signal), signal 1 at the white.
    pub response: Response,
    pub clean: bool,
}

impl ClassicalMerge {
    /// `kind` on the test set in `dir`, with the curve its frames record; refused, naming the
    /// set, where no curve is recorded.
    pub fn for_testset(kind: Classical, dir: &Path) -> Result<ClassicalMerge> {
        let enc = encoding::of_testset(dir)?.ok_or_else(|| {
            Error::layout(
                dir,
                format!(
                    "the {} baseline needs the curve the frames were made with, and this test \
                     set records none (Kalantari's and Wu's camera JPEGs do not; build the \
                     set with hdrsynth testset, which records it)",
                    kind.name()
                ),
            )
        })?;
        Ok(ClassicalMerge {
            kind,
            response: enc.response,
            clean: false,
        })
    }
}

impl Method for ClassicalMerge {
    fn describe(&self, _opts: &EvalOptions) -> String {
        format!(
            "{} of the {} frames, linearised with the frames' own curve ({}); scored against \
             each set's linear ground truth (T = μ-law, μ = 5000)",
            self.kind.label(),
            if self.clean { "noise-free" } else { "noisy" },
            self.response.label()
        )
    }

    fn missing(&self, set: &SetInfo) -> Option<String> {
        (self.clean && set.clean_frames.len() != set.evs.len()).then(|| {
            format!(
                "{}/static/clean_<ev>.png (noise-free frames)",
                set.dir.display()
            )
        })
    }

    fn run(&self, set: &SetInfo, _opts: &EvalOptions) -> Result<Outcome> {
        let (mut frames, times) = infer::network2_frames(set)?;
        if self.clean {
            let picks = [0, set.reference, set.evs.len() - 1];
            for (f, i) in frames.iter_mut().zip(picks) {
                *f = layout::read_set_image(set, &set.clean_frames[i])?;
            }
        }
        let output = self.kind.merge(&frames, times, &self.response)?;
        let reference = layout::read_linear_ground_truth(set)?;
        // The frames merged, as a network's are shown; the noise-free ones stay unshown.
        let inputs = if self.clean {
            set_inputs(set)
        } else {
            three_shown(set, frames)
        };
        Ok(Outcome {
            output,
            reference,
            scoring: Scoring::Hdr,
            inputs,
            notes: Vec::new(),
        })
    }
}
