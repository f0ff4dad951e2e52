//! Test-set evaluation (`hdrsynth eval`, docs/evaluation.md): per set, an output from a
//! [`Method`] (predictions made elsewhere, or a checkpoint's network run here at full
//! resolution), its reference, the field's metrics, and the files of [`evaluate`].
//!
//! Scoring:
//! - HDR outputs (`--predictions`, Network-2) against the set's linear ground truth with
//!   [`metrics::score`] (T = μ-law inside), in one unit for every layout ([`ScoreUnit`]):
//!   μ-law and PSNR with data range 1 are not scale invariant, so the same scene written with
//!   other exposure stops must be scored in the same unit.
//! - Network-1 outputs a display-referred fusion of the static (EV−3, EV0) pair, not radiance.
//!   Its reference ([`Network1Reference`]) is the same Laplacian blend of the same noisy pair
//!   with Mertens weights (OpenCV defaults) computed on the noise-free frames, or (option, and
//!   for sets without them) the Mertens fusion of the noisy pair itself; L = before the tone
//!   curve, T = after it (the same curve for both), scored with [`metrics::score_pair`].
//! - PSNR-T dark's mask ([`dark_mask`]) comes from the set's reference input frame as read,
//!   the same for every method scored on the set, as is PSNR-T moving's ([`moving_mask`], the
//!   union of the set's motion masks); ΔE2000 reads each path's T images (μ-law,
//!   or Network-1's tone curve) as sRGB display values.
//!
//! Memory: one set at a time; per set at most about four full-size images live at once (output,
//! reference and, for Network-1, their tone-mapped copies), plus the tiled inference's own.

use crate::data::encoding::{self, FrameEncoding};
use crate::data::ground_truth::{self, MertensWeights};
use crate::data::layout::{self, SetInfo};
use crate::data::scene::ev_tag;
use crate::error::{Error, Result};
use crate::eval::blend::{blend_pair, tone_curve};
use crate::eval::infer;
pub use crate::eval::infer::NetworkOptions;
use crate::eval::metrics::{self, MetricOptions, PixelMask, Pu21Scale, Scores};
use crate::eval::report::{self, Cell, MetricSummary, SetScore};
use crate::io::source::Source;
use crate::io::{BitDepth, Image, read_image, resize, write_exr_uncompressed, write_ldr};
use crate::sensor::profile::Response;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod methods;
pub use methods::*;

/// How an output and its reference are turned into scores and display images.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scoring {
    /// Linear HDR against linear ground truth; display = μ-law.
    Hdr,
    /// Network-1: L = before the curve, T = `tone_curve(L, k)` for output and reference.
    Network1 { tone_k: f32 },
}

impl Scoring {
    /// The display (T) value of a linear (L) value.
    pub fn display(self, v: f32) -> f32 {
        match self {
            Scoring::Hdr => metrics::mu_law(v.max(0.0) as f64) as f32,
            Scoring::Network1 { tone_k } => tone_curve(v, tone_k),
        }
    }

    /// `[dark, moving]`: the set's under-exposed pixels (from its reference input frame) and
    /// its moving ones (its motion masks), for PSNR-T dark and PSNR-T moving.
    pub fn score(
        self,
        reference: &Image,
        output: &Image,
        [dark, moving]: [Option<&PixelMask>; 2],
        opts: &MetricOptions,
    ) -> Result<Scores> {
        let mut scores = match self {
            Scoring::Hdr => metrics::score(reference, output, dark, opts)?,
            Scoring::Network1 { .. } => {
                let (rt, ot) = rayon::join(
                    || reference.map(|v| self.display(v)),
                    || output.map(|v| self.display(v)),
                );
                metrics::score_pair(reference, output, &rt, &ot, dark, opts)?
            }
        };
        if let Some(m) = moving {
            scores.psnr_t_moving = self.psnr_t_masked(reference, output, m)?;
            scores.moving_fraction = Some(m.fraction());
        }
        Ok(scores)
    }

    /// PSNR-T over the pixels of `mask`: μ-law for HDR, the tone curve for Network-1.
    pub fn psnr_t_masked(
        self,
        reference: &Image,
        output: &Image,
        mask: &PixelMask,
    ) -> Result<Option<f64>> {
        match self {
            Scoring::Hdr => metrics::psnr_mu_masked(reference, output, mask),
            Scoring::Network1 { .. } => metrics::psnr_masked(
                &reference.map(|v| self.display(v)),
                &output.map(|v| self.display(v)),
                mask,
            ),
        }
    }
}

/// A set's output and what it is scored against.
pub struct Outcome {
    /// Linear output (written as `<set>.exr`); HDR outputs in hdrsynth's unit (1 = the
    /// reference exposure's white), whatever the set's files use.
    pub output: Image,
    /// Reference, same size and space (and unit) as `output`.
    pub reference: Image,
    pub scoring: Scoring,
    /// The input frames to show in the grid.
    pub inputs: Vec<(String, Frame)>,
    /// Remarks for the summary (e.g. values clamped).
    pub notes: Vec<String>,
}

/// An input frame for the grid: read when its thumbnail is made, or already in memory (made
/// into a thumbnail before the scoring, so it does not stay alive with the full-size images).
pub enum Frame {
    File(PathBuf),
    Loaded(Image),
}

/// Where a set's output comes from.
pub trait Method {
    /// One line for the report.
    fn describe(&self, opts: &EvalOptions) -> String;
    /// `Some(what was looked for)` when the set's output does not exist (checked for every set
    /// before any work starts).
    fn missing(&self, _set: &SetInfo) -> Option<String> {
        None
    }
    fn run(&self, set: &SetInfo, opts: &EvalOptions) -> Result<Outcome>;
    /// The curve of the frames the method was trained on, where known (a checkpoint's run):
    /// compared with the test set's ([`crate::data::encoding`]).
    fn trained_encoding(&self) -> Option<&FrameEncoding> {
        None
    }
    /// The profile the method was fine-tuned with and the captures it was calibrated on, where
    /// known: no set built from any of them is scored ([`split_check`]).
    fn calibrated_on(&self) -> Option<(&Path, &[Source])> {
        None
    }
}

/// Display frames of a set for the grid: the dynamic frames (what a network sees), else the
/// static ones.
fn set_inputs(set: &SetInfo) -> Vec<(String, Frame)> {
    let frames = if set.dynamic_frames.is_empty() {
        &set.static_frames
    } else {
        &set.dynamic_frames
    };
    frames
        .iter()
        .zip(&set.evs)
        .map(|(p, &ev)| (format!("input {}", ev_tag(ev)), Frame::File(p.clone())))
        .collect()
}

// ---------------------------------------------------------------------------------------------
// The evaluation loop

/// The unit HDR outputs and ground truth are scored in. μ-law (μ = 5000) and PSNR with data
/// range 1 are not scale invariant, so the choice changes the scores; it never changes which
/// of two methods scored on the same sets is better by more or less than that.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum ScoreUnit {
    /// hdrsynth's unit, 1 = the reference exposure's white, for every layout: the same scene
    /// scores the same whatever stops its exposure file writes.
    #[default]
    Reference,
    /// The unit of each set's ground-truth file (Kalantari: a frame at stop 0 as written, i.e.
    /// the shortest frame for the dataset's "0 2 4"; Wu: the shortest frame), as the field's
    /// code scores: for comparison with published numbers.
    File,
}

#[derive(Clone, Debug)]
pub struct EvalOptions {
    pub metrics: MetricOptions,
    /// Unit of HDR scoring (`--predictions`, Network-2).
    pub unit: ScoreUnit,
    /// Network-1's reference.
    pub network1_reference: Network1Reference,
    /// Bootstrap resamples and seed of the confidence intervals.
    pub resamples: usize,
    pub seed: u64,
    /// Confidence level, e.g. 0.95.
    pub level: f64,
    /// Skip sets without an output (listed in the summary) instead of failing.
    pub allow_missing: bool,
    /// Largest side of a grid thumbnail.
    pub thumb: usize,
    pub progress: bool,
    /// The curve the test set records for its frames: set by [`evaluate`] from the set (a
    /// network with `linearise = "data"` linearises its inputs with it, as the classical rows
    /// do); what a caller puts here is replaced.
    pub frame_curve: Option<Response>,
    /// The test set is a validation set: sets built from the captures that calibrated the
    /// method's profile are scored (for choosing among networks, as the loop does; such a
    /// score is never a test of the network). Default: refused ([`split_check`]).
    pub validation: bool,
}

impl Default for EvalOptions {
    fn default() -> Self {
        EvalOptions {
            metrics: MetricOptions::default(),
            unit: ScoreUnit::default(),
            network1_reference: Network1Reference::default(),
            resamples: 2000,
            seed: 0,
            level: 0.95,
            allow_missing: false,
            thumb: 512,
            progress: false,
            frame_curve: None,
            validation: false,
        }
    }
}

#[derive(Clone, Debug)]
pub struct EvalSummary {
    pub out: PathBuf,
    pub method: String,
    pub rows: Vec<SetScore>,
    pub summary: Vec<MetricSummary>,
    /// (set, what was looked for) of sets skipped with `allow_missing`.
    pub missing: Vec<(String, String)>,
    pub notes: Vec<String>,
    /// Why the scores may not mean what they seem: a network scored on frames encoded with a
    /// curve other than its training frames'.
    pub warnings: Vec<String>,
    pub seconds: f64,
}

pub const PER_IMAGE: &str = "per_image.csv";
pub const SUMMARY_CSV: &str = "summary.csv";
pub const SUMMARY_MD: &str = "summary.md";
pub const REPORT: &str = "report.md";
pub const GRIDS: &str = "grids";

/// Evaluate `method` on every set of `testset` (any known layout), writing into `out`:
/// `per_image.csv`, `summary.csv`, `summary.md`, `report.md`, per set `<set>.exr` (linear
/// output), `<set>.png` (its display image) and `grids/<set>.png`.
pub fn evaluate(
    testset: &Path,
    method: &dyn Method,
    out: &Path,
    opts: &EvalOptions,
) -> Result<EvalSummary> {
    if !(opts.level > 0.0 && opts.level < 1.0) {
        return Err(Error::flag(
            "--level",
            format!("{} must be in (0, 1)", opts.level),
        ));
    }
    let began = Instant::now();
    let info = layout::detect(testset)?;
    if !opts.validation {
        split_check(method, &info.sets)?;
    }
    let (warnings, mut notes) = encoding_check(method, testset)?;
    if opts.validation && method.calibrated_on().is_some() {
        notes.push(
            "a validation set: its sets may hold captures that calibrated this network's \
             profile, so these scores choose among networks and test none"
                .into(),
        );
    }
    let opts = &EvalOptions {
        frame_curve: encoding::of_testset(testset)?.map(|e| e.response),
        ..opts.clone()
    };
    let mut missing = Vec::new();
    let mut sets = Vec::new();
    for set in &info.sets {
        match method.missing(set) {
            Some(looked) => missing.push((set.name.clone(), looked)),
            None => sets.push(set),
        }
    }
    if !missing.is_empty() && !opts.allow_missing {
        let list: Vec<String> = missing
            .iter()
            .take(10)
            .map(|(s, f)| format!("set '{s}' (looked for {f})"))
            .collect();
        return Err(Error::layout(
            testset,
            format!(
                "no output for {} of {} set(s): {}{}; pass --allow-missing to score the others",
                missing.len(),
                info.sets.len(),
                list.join(", "),
                if missing.len() > 10 { ", …" } else { "" }
            ),
        ));
    }
    // One writer per output folder; everything is written into a hidden staging sibling and
    // moved into `out` only when every set has been scored, so an error leaves no partial
    // output where readers look (docs/reliability.md).
    let lock = crate::io::guard::OutputLock::acquire(out, "eval")?;
    let staged = lock.stage(false)?;
    let final_out = out;
    let out = staged.path();
    let bar = if opts.progress {
        let b = ProgressBar::new(sets.len() as u64);
        if let Ok(style) =
            ProgressStyle::with_template("{bar:40} {pos}/{len} sets {elapsed_precise} {msg}")
        {
            b.set_style(style);
        }
        b
    } else {
        ProgressBar::hidden()
    };
    let mut rows = Vec::new();
    for set in sets {
        bar.set_message(set.name.clone());
        let row = evaluate_set(set, method, out, opts, &mut notes)?;
        rows.push(row);
        // Rewritten after every set: an interrupted run's scores stay readable in the
        // staging folder until the next run of this output clears it.
        report::write_text(&out.join(PER_IMAGE), &report::per_image_csv(&rows))?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let scenes =
        crate::data::testset::scenes_of_sets(testset, rows.iter().map(|r| r.set.as_str()))?;
    let summary = report::summarise(&rows, &scenes, opts.resamples, opts.seed, opts.level);
    let result = EvalSummary {
        out: final_out.to_path_buf(),
        method: method.describe(opts),
        rows,
        summary,
        missing,
        notes,
        warnings,
        seconds: began.elapsed().as_secs_f64(),
    };
    report::write_text(&out.join(PER_IMAGE), &report::per_image_csv(&result.rows))?;
    report::write_text(
        &out.join(SUMMARY_CSV),
        &report::summary_csv(&result.summary),
    )?;
    report::write_text(&out.join(SUMMARY_MD), &summary_md(&result, testset, opts))?;
    report::write_text(&out.join(REPORT), &report_md(&result, testset, opts))?;
    staged.commit()?;
    Ok(result)
}

/// Refuse a method whose profile was calibrated on a capture that some set was built from: a
/// scene never calibrates the model scored on it. Sets record their captures in
/// `brackets.toml` (`testset --brackets`); sets without a record are not checked.
fn split_check(method: &dyn Method, sets: &[SetInfo]) -> Result<()> {
    let Some((profile, calibrated)) = method.calibrated_on() else {
        return Ok(());
    };
    if calibrated.is_empty() {
        return Ok(());
    }
    for set in sets {
        let Some(sources) = crate::capture::testset::set_sources(&set.dir)? else {
            continue;
        };
        if let Some((c, t)) = crate::io::source::overlapping(calibrated, &sources).first() {
            return Err(Error::layout(
                &set.dir,
                format!(
                    "set '{}' was built from {} (pixels {:?}), which{} made {} (pixels {:?}), \
                     the profile or training set this network was fine-tuned with: a scene \
                     never trains or calibrates the model scored on it; use other scenes (or \
                     other regions, `--region`) than the test set's",
                    set.name,
                    t.file,
                    t.pixels,
                    if c.sha256 == t.sha256 {
                        String::new()
                    } else {
                        format!(" (the same pixels as {})", c.file)
                    },
                    profile.display(),
                    c.pixels
                ),
            ));
        }
    }
    Ok(())
}

/// The method's training encoding against the test set's: (warnings, notes).
fn encoding_check(method: &dyn Method, testset: &Path) -> Result<(Vec<String>, Vec<String>)> {
    let Some(trained) = method.trained_encoding() else {
        return Ok((Vec::new(), Vec::new()));
    };
    Ok(match encoding::of_testset(testset)? {
        Some(test) => (
            encoding::mismatch(trained, &test).into_iter().collect(),
            Vec::new(),
        ),
        None => (
            Vec::new(),
            vec![format!(
                "the test set does not record its frames' encoding (camera JPEGs of Kalantari's \
                 or Wu's layout); the network was trained on frames encoded with {}",
                trained.describe()
            )],
        ),
    })
}

/// The pixels where a subject moved in any frame of the set (the union of its motion masks);
/// None for a set without motion masks or where nothing moved (a static scene).
pub fn moving_mask(set: &SetInfo) -> Result<Option<PixelMask>> {
    let mut union: Option<Vec<bool>> = None;
    for path in set.masks.iter().filter(|p| p.is_file()) {
        let m = layout::read_set_image(set, path)?;
        let u = union.get_or_insert_with(|| vec![false; m.pixel_count()]);
        for (a, p) in u.iter_mut().zip(m.data.chunks_exact(3)) {
            *a |= p[0].max(p[1]).max(p[2]) > 0.5;
        }
    }
    match union {
        Some(u) if u.iter().any(|&m| m) => PixelMask::from_flags(set.width, set.height, u)
            .map(Some)
            .map_err(Error::within(set.dir.display().to_string())),
        _ => Ok(None),
    }
}

/// The set's under-exposed pixels ([`PixelMask`]) from its reference input frame as read (the
/// same mask for every method scored on the set); None for a set without one.
pub fn dark_mask(set: &SetInfo) -> Result<Option<PixelMask>> {
    let Some(path) = set.reference_frame() else {
        return Ok(None);
    };
    let frame = layout::read_set_image(set, path)?;
    PixelMask::from_frame(&frame)
        .map(Some)
        .map_err(Error::within(path.display().to_string()))
}

fn evaluate_set(
    set: &SetInfo,
    method: &dyn Method,
    out: &Path,
    opts: &EvalOptions,
    notes: &mut Vec<String>,
) -> Result<SetScore> {
    let t0 = Instant::now();
    // Before the method runs: only the masks (a byte per pixel) stay alive, not the frames.
    let (dark, moving) = (dark_mask(set)?, moving_mask(set)?);
    let outcome = method.run(set, opts)?;
    let Outcome {
        mut output,
        mut reference,
        scoring,
        inputs,
        notes: set_notes,
    } = outcome;
    // Outcomes are in hdrsynth's unit; the file's unit is 1 / file_to_reference of it.
    let k = set.file_to_reference();
    if scoring == Scoring::Hdr && opts.unit == ScoreUnit::File && k != 1.0 {
        let to_file = |img: &mut Image| img.data.par_iter_mut().for_each(|v| *v /= k);
        to_file(&mut output);
        to_file(&mut reference);
    }
    let (tw, th) = report::thumb_size(output.width, output.height, opts.thumb);
    // Frames already in memory become thumbnails before the full-size work below.
    let inputs: Vec<(String, Frame)> = inputs
        .into_iter()
        .map(|(label, f)| match f {
            Frame::Loaded(img) => (label, Frame::Loaded(resize(&img, tw, th))),
            file => (label, file),
        })
        .collect();
    let masks = [dark.as_ref(), moving.as_ref()];
    let scores = (scoring.score(&reference, &output, masks, &opts.metrics))
        .map_err(Error::within(format!("set '{}'", set.name)))?;
    let seconds = t0.elapsed().as_secs_f64();
    notes.extend(set_notes);

    write_exr_uncompressed(&out.join(format!("{}.exr", set.name)), &output)?;
    // Each display image is mapped once and its linear image dropped: the full-size preview
    // is written, the error map made from the two, then only thumbnails are kept.
    let shown = output.map(|v| scoring.display(v));
    drop(output);
    write_ldr(
        &out.join(format!("{}.png", set.name)),
        &shown,
        BitDepth::Eight,
    )?;
    let truth = reference.map(|v| scoring.display(v));
    drop(reference);
    let (out_thumb, ref_thumb) = (resize(&shown, tw, th), resize(&truth, tw, th));
    let err_thumb = {
        let mut e = Image::new(shown.width, shown.height);
        e.data
            .par_chunks_exact_mut(3)
            .zip(shown.data.par_chunks_exact(3))
            .zip(truth.data.par_chunks_exact(3))
            .for_each(|((e, o), r)| {
                let m = (0..3).map(|c| (o[c] - r[c]).abs()).sum::<f32>() / 3.0;
                e.fill(m);
            });
        drop((shown, truth));
        let t = resize(&e, tw, th);
        Image::from_vec(
            tw,
            th,
            t.data
                .chunks_exact(3)
                .flat_map(|p| report::hot(p[0]))
                .collect(),
        )
    };
    let mut input_cells = Vec::new();
    for (label, frame) in inputs {
        let image = match frame {
            Frame::File(path) => resize(&read_image(&path)?, tw, th),
            Frame::Loaded(thumb) => thumb,
        };
        input_cells.push(Cell { label, image });
    }
    let (out_label, ref_label) = match scoring {
        Scoring::Hdr => ("output (mu-law)", "ground truth (mu-law)"),
        Scoring::Network1 { .. } => ("output T", "reference T"),
    };
    let grid = report::grid(&[
        input_cells,
        vec![
            Cell {
                label: out_label.into(),
                image: out_thumb,
            },
            Cell {
                label: ref_label.into(),
                image: ref_thumb,
            },
            Cell {
                label: format!("|error| (white >= {})", report::ERROR_FULL_SCALE),
                image: err_thumb,
            },
        ],
    ])?;
    write_ldr(
        &out.join(GRIDS).join(format!("{}.png", set.name)),
        &grid,
        BitDepth::Eight,
    )?;
    Ok(SetScore {
        set: set.name.clone(),
        scores,
        width: set.width,
        height: set.height,
        seconds,
    })
}

fn setup_lines(r: &EvalSummary, testset: &Path, opts: &EvalOptions) -> String {
    let pu21 = match opts.metrics.pu21_scale {
        Pu21Scale::ReferenceMax => format!(
            "reference maximum → {} cd/m² (prediction scaled by the same factor)",
            opts.metrics.peak_luminance
        ),
        Pu21Scale::UnitValue => format!("value 1.0 → {} cd/m²", opts.metrics.peak_luminance),
    };
    let unit = match opts.unit {
        ScoreUnit::Reference => {
            "reference (1 = the reference exposure's white; Kalantari/Wu ground truth and \
             predictions × 2^(s_ref − s_unit) of their exposure file)"
        }
        ScoreUnit::File => {
            "file (each set's ground-truth file as written; network outputs × 2^(s_unit − s_ref))"
        }
    };
    format!(
        "- test set: {}\n- method: {}\n- sets scored: {}{}\n- HDR unit: {unit}\n\
         - PU21 scaling: {pu21}\n\
         - delta_e2000: mean CIEDE2000 of the T images read as sRGB display values (lower is \
         better); psnr_t_dark: PSNR-T over the pixels whose reference input frame has its \
         largest channel below {} (a code in [0, 1]), absent (no value) where under {} % of \
         the pixels are such; psnr_t_moving: PSNR-T over the pixels a subject covers in any \
         frame (the union of the set's motion masks), for sets with moving subjects\n\
         - mean and confidence intervals over scenes (a scene's sets at several ISOs are one \
         cluster: its mean counts once): percentile bootstrap resampling scenes, {} resamples, \
         seed {}, level {}; +inf values (identical images) are left out of mean and CI and \
         counted\n\
         - total time: {:.1} s\n",
        testset.display(),
        r.method,
        r.rows.len(),
        if r.missing.is_empty() {
            String::new()
        } else {
            format!(" ({} skipped: no output)", r.missing.len())
        },
        metrics::DARK_CODE,
        metrics::MASK_MIN_FRACTION * 100.0,
        opts.resamples,
        opts.seed,
        opts.level,
        r.seconds
    )
}

fn missing_and_notes(r: &EvalSummary) -> String {
    let mut s = String::new();
    if !r.warnings.is_empty() {
        s.push_str("\n## Warnings\n\n");
        for w in &r.warnings {
            let _ = writeln!(s, "- {w}");
        }
    }
    if !r.missing.is_empty() {
        s.push_str("\n## Sets without output (skipped)\n\n");
        for (set, looked) in &r.missing {
            let _ = writeln!(s, "- {set}: looked for {looked}");
        }
    }
    if !r.notes.is_empty() {
        s.push_str("\n## Notes\n\n");
        for n in &r.notes {
            let _ = writeln!(s, "- {n}");
        }
    }
    s
}

fn summary_md(r: &EvalSummary, testset: &Path, opts: &EvalOptions) -> String {
    format!(
        "# Evaluation summary\n\n{}\n{}{}",
        setup_lines(r, testset, opts),
        report::summary_table(&r.summary, opts.level),
        missing_and_notes(r)
    )
}

fn report_md(r: &EvalSummary, testset: &Path, opts: &EvalOptions) -> String {
    let mut s = format!(
        "# Evaluation report\n\n{}\n## Summary\n\n{}{}\n## Sets\n\n\
         Grid per set: input frames; output, reference and the error map (mean absolute \
         difference of the display images over RGB, black 0 … white ≥ {}).\n",
        setup_lines(r, testset, opts),
        report::summary_table(&r.summary, opts.level),
        missing_and_notes(r),
        report::ERROR_FULL_SCALE
    );
    for row in &r.rows {
        let _ = write!(
            s,
            "\n### {}\n\n{}×{}, {:.2} s\n\n{}{}\n\n![{}](<{}/{}.png>)\n",
            row.set,
            row.width,
            row.height,
            row.seconds,
            report::scores_header(),
            report::scores_row(&row.scores),
            row.set,
            GRIDS,
            row.set
        );
    }
    s
}
