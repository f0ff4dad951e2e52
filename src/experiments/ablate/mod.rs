//! The ablation grid (`hdrsynth ablate --config F`, docs/experiments.md): every cell fine-tunes
//! from the same base training config with its own settings laid over it (a sensor profile, a
//! colour switch, an ISO range, ...), is evaluated on the same test set, and the cells become one
//! table shaped like the paper's Tables 1–4, with bootstrap confidence intervals and paired
//! differences against a reference cell (default: the first).
//!
//! Statistics (docs/experiments.md): the unit of test-set variation is the scene (the sets of one
//! scene at several ISOs are one cluster, `testset::scenes_of_sets`), and with `seeds = [...]`
//! every trained cell is trained once per seed; intervals come from a two-level bootstrap
//! (seeds, then scenes; `stats::bootstrap_crossed`), differences are paired within seed, scene
//! and set.
//!
//! Resumable at every level: a cell whose `eval/` folder exists is finished and skipped; a cell
//! killed while training resumes from its latest checkpoint (the trainer's bit-identical resume);
//! a cell killed while evaluating evaluates again (into `eval.partial/`, renamed when complete).
//! A cell that ran under a different config is refused, not silently reused.

use crate::config::merge_tables;
use crate::data::testset::{self, TestsetOptions};
use crate::device::device_from_name;
use crate::error::{Error, Result};
use crate::eval::evaluate::{self, EvalOptions, NetworkOptions};
use crate::eval::report::{self, SUMMARY_METRICS};
use crate::io::atomic::write_atomic;
use crate::runner::method::from_checkpoint;
use crate::sensor::profile::SensorProfile;
use crate::stats::{self, bootstrap_crossed};
use crate::train::config::TrainConfig;
use crate::train::{self, TrainOptions, checkpoint};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod cells;
mod table;

pub use cells::*;
pub use table::*;

/// Stands for the seed in a per-seed path (`pretrained_per_seed`, an axis's `checkpoint`).
pub const SEED_FIELD: &str = "{seed}";

/// The `ablate` config (TOML). Paths are relative to the working directory.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AblateConfig {
    /// Title of the table.
    pub title: String,
    /// Output folder: `cells/<cell>/{cell.toml, run/, eval/}` (with `seeds`, a trained cell has
    /// one such folder per seed: `cells/<cell>/seed<k>/`), `table.md`, `table.csv`.
    pub out: PathBuf,
    /// The training config every cell starts from (typically a fine-tune config whose `[init]`
    /// names the pretrained checkpoint).
    pub base: PathBuf,
    /// Training seeds: every trained cell is trained once per seed (the seed becomes the cell's
    /// `run.seed`, which seeds the initialisation and the whole data stream). Empty: once, with
    /// the base config's seed.
    #[serde(default)]
    pub seeds: Vec<u64>,
    /// Per-seed pretrained networks: the path of seed k's pretrained checkpoint (a run folder
    /// or one of its checkpoints) with `{seed}` standing for k. It replaces the base config's
    /// `[init] checkpoint` in seed k's cells, so the seeds vary pretraining as well as
    /// fine-tuning; cells that do not train are then evaluated once per seed.
    #[serde(default)]
    pub pretrained_per_seed: Option<String>,
    pub testset: TestsetSpec,
    /// More test sets every cell is also scored on, each with its own table
    /// (`table_<name>.md`/`.csv`); each needs a `name`.
    #[serde(default)]
    pub also: Vec<TestsetSpec>,
    #[serde(default)]
    pub eval: EvalSpec,
    /// First axis of the grid (table rows).
    pub rows: Vec<Axis>,
    /// Optional second axis (table columns); without it the grid is one column.
    #[serde(default)]
    pub columns: Vec<Axis>,
    /// Cells trained and scored at once (default 1), each in a thread pool of its own. One
    /// small network's training step keeps about 1.4 of 2 cores busy: its own thread works
    /// alone between the parallel operations. Results do not depend on it.
    #[serde(default = "one")]
    pub jobs: usize,
}

fn one() -> usize {
    1
}

/// Cells at once in the grids the product writes itself (the main job, the protocol, the
/// loop): one per seed; on two cores two already keep both busy (BENCHMARKS.md, "Main job").
pub const GRID_JOBS: usize = 3;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TestsetSpec {
    /// Folder-safe id of an extra test set (`also`): its eval folder is `eval_<name>/` and its
    /// table `table_<name>.md`. The primary test set has none.
    #[serde(default)]
    pub name: Option<String>,
    /// Shown above its table; default: the folder.
    #[serde(default)]
    pub label: Option<String>,
    /// The test set folder (any known layout).
    pub dir: PathBuf,
    /// Build `dir` from real radiance through `profile` first (`hdrsynth testset`); sets
    /// already built are kept.
    #[serde(default)]
    pub radiance: Option<PathBuf>,
    #[serde(default)]
    pub profile: Option<PathBuf>,
    #[serde(default)]
    pub options: TestsetOptions,
    /// Redraw the test noise per seed: seed k's test set is `dir/seed<k>`, built from
    /// `radiance` through `profile` with noise seed k, and every cell is scored per seed on its
    /// seed's test set (needs `seeds`, `radiance` and `profile`).
    #[serde(default)]
    pub noise_per_seed: bool,
    /// The reference cell of this test set's table, when it is not `eval.reference` (e.g. the
    /// ISO-matched cell of a table scored at one ISO).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<String>,
    /// A validation set (`also` only): scenes that calibrated a fine-tuned row's profile may be
    /// in it, so its scores choose among rows and are never a test (`EvalOptions::validation`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub validation: bool,
}

impl TestsetSpec {
    /// The folder of the test set seed `seed`'s runs are scored on.
    pub fn dir_for(&self, seed: Option<u64>) -> PathBuf {
        match seed {
            Some(k) if self.noise_per_seed => self.dir.join(format!("seed{k}")),
            _ => self.dir.clone(),
        }
    }

    /// The cell's eval folder for this test set.
    fn eval_dir(&self) -> String {
        match &self.name {
            None => EVAL_DIR.to_string(),
            Some(n) => format!("{EVAL_DIR}_{n}"),
        }
    }

    /// The table's file name with this test set's suffix (`table.md` → `table_<name>.md`).
    fn table_file(&self, file: &str) -> String {
        match &self.name {
            None => file.to_string(),
            Some(n) => match file.rsplit_once('.') {
                Some((stem, ext)) => format!("{stem}_{n}.{ext}"),
                None => format!("{file}_{n}"),
            },
        }
    }

    /// Build the test set (once, or per seed) when it is made from radiance.
    fn build(&self, seeds: &[u64], progress: bool) -> Result<()> {
        let (Some(radiance), Some(profile)) = (&self.radiance, &self.profile) else {
            return Ok(());
        };
        let p = SensorProfile::load(profile)?;
        let runs: Vec<Option<u64>> = if self.noise_per_seed {
            seeds.iter().map(|&k| Some(k)).collect()
        } else {
            vec![None]
        };
        for seed in runs {
            let dir = self.dir_for(seed);
            let mut options = self.options.clone();
            if let Some(k) = seed {
                options.seed = k;
            }
            if progress {
                eprintln!(
                    "test set: {} from {} through {}",
                    dir.display(),
                    radiance.display(),
                    profile.display()
                );
            }
            testset::build(radiance, &p, &options, &dir)?;
        }
        Ok(())
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EvalSpec {
    /// Bootstrap resamples, seed and confidence level of the intervals.
    pub resamples: usize,
    pub seed: u64,
    pub level: f64,
    /// Device for evaluation; default: the base config's `run.backend`.
    pub backend: Option<String>,
    /// Core tile side for full-resolution inference (default: the network's default).
    pub tile: Option<usize>,
    /// The cell the paired differences are taken against (`row` or `row__column`); default:
    /// the first cell.
    pub reference: Option<String>,
    /// Equivalence margins of the TOST on paired differences: ± this many dB for PSNR, ± this
    /// much for SSIM (docs/protocol.md).
    pub margin_psnr: f64,
    pub margin_ssim: f64,
    /// ± this much ΔE2000 (half a just-noticeable difference of about 1).
    pub margin_delta_e: f64,
}

impl EvalSpec {
    /// The TOST margin of a table metric.
    fn margin(&self, metric: &str) -> f64 {
        if metric.starts_with("ssim") {
            self.margin_ssim
        } else if metric == "delta_e2000" {
            self.margin_delta_e
        } else {
            self.margin_psnr
        }
    }
}

impl Default for EvalSpec {
    fn default() -> Self {
        EvalSpec {
            resamples: 2000,
            seed: 0,
            level: 0.95,
            backend: None,
            tile: None,
            reference: None,
            margin_psnr: 0.2,
            margin_ssim: 0.005,
            margin_delta_e: 0.5,
        }
    }
}

/// One value of an axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Axis {
    /// Folder-safe id (letters, digits, `-`, `_`).
    pub name: String,
    /// Shown in the table; default: `name`.
    #[serde(default)]
    pub label: Option<String>,
    /// Laid over the base training config (tables merge key by key), e.g.
    /// `set = { data = { profile = "pure" } }`.
    #[serde(default)]
    pub set: toml::Table,
    /// `false`: no fine-tuning; evaluate the checkpoint the config starts from (`[init]`), i.e.
    /// the pretrained network (the paper's Net_O).
    #[serde(default = "yes")]
    pub train: bool,
    /// Evaluate this checkpoint instead of training (implies `train = false`); `{seed}` in it
    /// stands for the cell's seed (a network trained per seed elsewhere, e.g. the main job's
    /// Net_S), and such a cell runs per seed.
    #[serde(default)]
    pub checkpoint: Option<PathBuf>,
    /// `"finetune"` (default): the base config with `set` laid over it. `"control"`: the
    /// pretrained network trained on for the same number of steps on its OWN pretraining data
    /// (see `control_config`), separating "more steps and a learning-rate restart" from "a new
    /// training domain". `"constant"` and `"mertens"`: Network-1's classical baselines, no
    /// network at all (`Baseline`).
    #[serde(default)]
    pub kind: AxisKind,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AxisKind {
    #[default]
    Finetune,
    Control,
    /// Network-1's pair fused with one blend weight, 0.5, everywhere.
    Constant,
    /// Network-1's pair fused with the Mertens weights of the noisy pair itself (OpenCV's
    /// defaults): what the network's targets would be without a noise-free render.
    Mertens,
    /// Network-2's classical rows, with the curve each test set records for its frames
    /// (`evaluate::Classical`): the reference frame linearised, what a network that copies
    /// its input scores;
    Copy,
    /// the triangle merge of the three inputs;
    Triangle,
    /// OpenCV's MergeDebevec of the three inputs;
    Debevec,
    /// OpenCV's MergeRobertson of the three inputs.
    Robertson,
}

/// A method scored without a network (a cell whose row or column has a baseline kind).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Baseline {
    Constant,
    Mertens,
    Copy,
    Triangle,
    Debevec,
    Robertson,
}

/// The constant baseline's blend weight: no preference between the two frames, chosen a
/// priori (a constant fitted on the test scenes would be tuned on them).
pub const CONSTANT_BLEND_WEIGHT: f32 = 0.5;

impl AxisKind {
    fn baseline(self) -> Option<Baseline> {
        match self {
            AxisKind::Constant => Some(Baseline::Constant),
            AxisKind::Mertens => Some(Baseline::Mertens),
            AxisKind::Copy => Some(Baseline::Copy),
            AxisKind::Triangle => Some(Baseline::Triangle),
            AxisKind::Debevec => Some(Baseline::Debevec),
            AxisKind::Robertson => Some(Baseline::Robertson),
            AxisKind::Finetune | AxisKind::Control => None,
        }
    }
}

impl Baseline {
    /// The method on the test set in `testset`: Network-1's own fusion (Laplacian blend, tone
    /// curve) with these weights, or a classical merge with the set's recorded curve.
    fn method(self, testset: &Path) -> Result<Box<dyn evaluate::Method>> {
        let classical = match self {
            Baseline::Copy => Some(evaluate::Classical::Copy),
            Baseline::Triangle => Some(evaluate::Classical::Triangle),
            Baseline::Debevec => Some(evaluate::Classical::Debevec),
            Baseline::Robertson => Some(evaluate::Classical::Robertson),
            Baseline::Constant | Baseline::Mertens => None,
        };
        if let Some(kind) = classical {
            return Ok(Box::new(evaluate::ClassicalMerge::for_testset(
                kind, testset,
            )?));
        }
        let tone_k = NetworkOptions::default().tone_k;
        let (description, weights): (String, evaluate::BlendInference) = match self {
            Baseline::Constant => (
                format!("constant blend weight {CONSTANT_BLEND_WEIGHT} (no network)"),
                Box::new(|low, _high| Ok(vec![CONSTANT_BLEND_WEIGHT; low.pixel_count()])),
            ),
            Baseline::Mertens => (
                "Mertens weights of the noisy pair (no network)".into(),
                Box::new(crate::data::ground_truth::blend_weights_high),
            ),
            Baseline::Copy | Baseline::Triangle | Baseline::Debevec | Baseline::Robertson => {
                unreachable!("the classical merges returned above")
            }
        };
        Ok(Box::new(evaluate::Network1 {
            description,
            weights,
            tone_k,
        }))
    }
}

fn yes() -> bool {
    true
}

impl Axis {
    fn label(&self) -> &str {
        self.label.as_deref().unwrap_or(&self.name)
    }

    /// Network-2's classical rows (no network): the copied reference, the triangle merge and
    /// OpenCV's Debevec and Robertson merges of each test set's inputs, through the curve the
    /// set records.
    pub fn classical_rows() -> Vec<Axis> {
        [
            (
                "copy",
                "copy: the reference frame, linearised (no network)",
                AxisKind::Copy,
            ),
            (
                "triangle",
                "triangle merge of the inputs (no network)",
                AxisKind::Triangle,
            ),
            (
                "debevec",
                "Debevec merge of the inputs, OpenCV's recipe (no network)",
                AxisKind::Debevec,
            ),
            (
                "robertson",
                "Robertson merge of the inputs, OpenCV's recipe (no network)",
                AxisKind::Robertson,
            ),
        ]
        .into_iter()
        .map(|(name, label, kind)| Axis {
            name: name.into(),
            label: Some(label.into()),
            set: toml::Table::new(),
            train: false,
            checkpoint: None,
            kind,
        })
        .collect()
    }
}

impl AblateConfig {
    pub fn load(path: &Path) -> Result<AblateConfig> {
        let text = crate::io::guard::read_text(path)?;
        Self::parse(&text, path)
    }

    /// The config's text, checked as [`AblateConfig::load`] checks the file `path` (named in
    /// errors); in memory for the fuzzer.
    pub fn parse(text: &str, path: &Path) -> Result<AblateConfig> {
        let cfg: AblateConfig = crate::config::parse_toml(text, path)?;
        cfg.validate(path)?;
        Ok(cfg)
    }

    fn validate(&self, path: &Path) -> Result<()> {
        if self.rows.is_empty() {
            return Err(Error::config(path, "[[rows]]: at least one row is needed"));
        }
        for (axis, list) in [("rows", &self.rows), ("columns", &self.columns)] {
            let mut seen = std::collections::BTreeSet::new();
            for a in list {
                self.check_axis(axis, a, &mut seen, path)?;
            }
        }
        let mut seeds = self.seeds.clone();
        seeds.sort_unstable();
        seeds.dedup();
        if seeds.len() != self.seeds.len() {
            return Err(Error::config(
                path,
                format!("seeds {:?}: a seed appears twice", self.seeds),
            ));
        }
        self.check_eval(path)?;
        if self.jobs == 0 {
            return Err(Error::config(
                path,
                "jobs = 0: at least one cell must run at a time",
            ));
        }
        if let Some(p) = &self.pretrained_per_seed
            && (self.seeds.is_empty() || !p.contains("{seed}"))
        {
            return Err(Error::config(
                path,
                format!("pretrained_per_seed '{p}' needs `seeds` and '{{seed}}' in the path"),
            ));
        }
        self.check_testsets(path)
    }

    /// One row or column of `axis` ("rows" or "columns"): its name (unique among `seen`), its
    /// kind against its checkpoint and training, and its seed against the grid's `seeds`.
    fn check_axis<'a>(
        &self,
        axis: &str,
        a: &'a Axis,
        seen: &mut std::collections::BTreeSet<&'a String>,
        path: &Path,
    ) -> Result<()> {
        if a.name.is_empty()
            || !a
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(Error::config(
                path,
                format!(
                    "[[{axis}]] name '{}': use letters, digits, '-' and '_' only",
                    a.name
                ),
            ));
        }
        if !seen.insert(&a.name) {
            return Err(Error::config(
                path,
                format!("[[{axis}]] name '{}' appears twice", a.name),
            ));
        }
        if a.kind.baseline().is_some() && a.checkpoint.is_some() {
            return Err(Error::config(
                path,
                format!(
                    "[[{axis}]] '{}': a baseline kind has no network; it cannot name a \
                 checkpoint",
                    a.name
                ),
            ));
        }
        if a.kind == AxisKind::Control && (!a.train || a.checkpoint.is_some()) {
            return Err(Error::config(
                path,
                format!(
                    "[[{axis}]] '{}': kind = \"control\" trains; it cannot also have \
                 train = false or a checkpoint",
                    a.name
                ),
            ));
        }
        let sets_seed = a
            .set
            .get("run")
            .and_then(|r| r.as_table())
            .is_some_and(|r| r.contains_key("seed"));
        if sets_seed && !self.seeds.is_empty() {
            return Err(Error::config(
                path,
                format!(
                    "[[{axis}]] '{}' sets run.seed, but the grid's `seeds` set every \
                 trained cell's seed",
                    a.name
                ),
            ));
        }
        Ok(())
    }

    /// `[eval]`: the confidence level, the equivalence margins, and references that are cells.
    fn check_eval(&self, path: &Path) -> Result<()> {
        if !(self.eval.level > 0.0 && self.eval.level < 1.0) {
            return Err(Error::config(
                path,
                format!("eval.level {} must be in (0, 1)", self.eval.level),
            ));
        }
        for (key, m) in [
            ("margin_psnr", self.eval.margin_psnr),
            ("margin_ssim", self.eval.margin_ssim),
            ("margin_delta_e", self.eval.margin_delta_e),
        ] {
            if !(m > 0.0 && m.is_finite()) {
                return Err(Error::config(
                    path,
                    format!("eval.{key} {m} must be a positive number"),
                ));
            }
        }
        let references = std::iter::once(("eval.reference", &self.eval.reference)).chain(
            self.testsets()
                .map(|t| ("a test set's reference", &t.reference)),
        );
        for (what, r) in references {
            if let Some(r) = r
                && !self
                    .cells()
                    .iter()
                    .any(|&(row, col)| self.cell_id(row, col) == *r)
            {
                return Err(Error::config(
                    path,
                    format!("{what} '{r}' is not a cell of the grid"),
                ));
            }
        }
        Ok(())
    }

    /// The primary test set and each `[[also]]`: names, how each is built, its options.
    fn check_testsets(&self, path: &Path) -> Result<()> {
        let mut names = std::collections::BTreeSet::new();
        for (i, t) in std::iter::once(&self.testset).chain(&self.also).enumerate() {
            let what = match (i, &t.name) {
                (0, _) => "testset".to_string(),
                (_, Some(n)) => format!("also '{n}'"),
                (_, None) => {
                    return Err(Error::config(
                        path,
                        "every [[also]] test set needs a `name`",
                    ));
                }
            };
            if i == 0 && t.name.is_some() {
                return Err(Error::config(
                    path,
                    "testset: the primary test set has no `name`",
                ));
            }
            if i == 0 && t.validation {
                return Err(Error::config(
                    path,
                    "testset: the primary test set is a test; a validation set is an [[also]]",
                ));
            }
            if let Some(n) = &t.name
                && (n.is_empty()
                    || !n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                    || !names.insert(n))
            {
                return Err(Error::config(
                    path,
                    format!("{what}: names are letters, digits and '_', each used once"),
                ));
            }
            if t.radiance.is_some() != t.profile.is_some() {
                return Err(Error::config(
                    path,
                    format!("{what}: give both `radiance` and `profile` (to build it) or neither"),
                ));
            }
            if t.noise_per_seed && (self.seeds.is_empty() || t.radiance.is_none()) {
                return Err(Error::config(
                    path,
                    format!(
                        "{what}: noise_per_seed needs `seeds` and a test set built from `radiance`"
                    ),
                ));
            }
            t.options
                .validate()
                .map_err(|e| Error::config(path, format!("{what}: {}", e.within("options"))))?;
        }
        Ok(())
    }

    /// Every test set: the primary, then `also`.
    pub fn testsets(&self) -> impl Iterator<Item = &TestsetSpec> {
        std::iter::once(&self.testset).chain(&self.also)
    }

    /// Whether a cell that does not train still runs per seed: its checkpoint (per-seed
    /// pretraining) or its test set (per-seed noise) depends on the seed.
    fn seeded_eval(&self) -> bool {
        self.pretrained_per_seed.is_some() || self.testsets().any(|t| t.noise_per_seed)
    }

    /// The cells, row-major.
    pub fn cells(&self) -> Vec<(usize, Option<usize>)> {
        let cols: Vec<Option<usize>> = if self.columns.is_empty() {
            vec![None]
        } else {
            (0..self.columns.len()).map(Some).collect()
        };
        (0..self.rows.len())
            .flat_map(|r| cols.iter().map(move |&c| (r, c)))
            .collect()
    }

    fn cell_id(&self, r: usize, c: Option<usize>) -> String {
        match c {
            None => self.rows[r].name.clone(),
            Some(c) => format!("{}__{}", self.rows[r].name, self.columns[c].name),
        }
    }

    pub fn cell_dir(&self, r: usize, c: Option<usize>) -> PathBuf {
        self.out.join("cells").join(self.cell_id(r, c))
    }

    /// Whether a cell trains (else it evaluates a checkpoint as it is): a function of the
    /// config alone, so the table can find a cell's folders without planning it.
    pub fn cell_trains(&self, r: usize, c: Option<usize>) -> bool {
        std::iter::once(&self.rows[r])
            .chain(c.map(|c| &self.columns[c]))
            .all(|a| a.train && a.checkpoint.is_none() && a.kind.baseline().is_none())
    }

    /// The baseline a cell scores instead of a network, if any.
    fn cell_baseline(&self, r: usize, c: Option<usize>) -> Option<Baseline> {
        std::iter::once(&self.rows[r])
            .chain(c.map(|c| &self.columns[c]))
            .find_map(|a| a.kind.baseline())
    }

    /// The seeds a cell runs at: `None` = once (no `seeds`, or a cell that does not train and
    /// therefore does not depend on the seed: it is evaluated once and serves every seed).
    pub fn cell_seeds(&self, r: usize, c: Option<usize>) -> Vec<Option<u64>> {
        let per_seed_checkpoint = std::iter::once(&self.rows[r])
            .chain(c.map(|c| &self.columns[c]))
            .any(|a| {
                a.checkpoint
                    .as_ref()
                    .is_some_and(|p| p.to_string_lossy().contains(SEED_FIELD))
            });
        let seeded = match self.cell_baseline(r, c) {
            Some(_) => self.testsets().any(|t| t.noise_per_seed),
            None => self.cell_trains(r, c) || self.seeded_eval() || per_seed_checkpoint,
        };
        if self.seeds.is_empty() || !seeded {
            vec![None]
        } else {
            self.seeds.iter().map(|&s| Some(s)).collect()
        }
    }

    /// The folder of one run of a cell: `cells/<cell>/` or, per seed, `cells/<cell>/seed<k>/`.
    pub fn unit_dir(&self, r: usize, c: Option<usize>, seed: Option<u64>) -> PathBuf {
        match seed {
            None => self.cell_dir(r, c),
            Some(k) => self.cell_dir(r, c).join(format!("seed{k}")),
        }
    }

    /// Where one run of a cell wrote its evaluation on the config's test set (`<set>.exr`,
    /// `per_image.csv`, ...).
    pub fn eval_dir(&self, r: usize, c: Option<usize>, seed: Option<u64>) -> PathBuf {
        self.unit_dir(r, c, seed).join(self.testset.eval_dir())
    }
}
