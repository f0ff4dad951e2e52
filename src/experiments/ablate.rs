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
use crate::engine::method::from_checkpoint;
use crate::error::{Error, Result};
use crate::eval::evaluate::{self, EvalOptions, NetworkOptions};
use crate::eval::report::{self, SUMMARY_METRICS};
use crate::io::atomic::write_atomic;
use crate::sensor::profile::SensorProfile;
use crate::stats::{self, bootstrap_crossed};
use crate::train::config::TrainConfig;
use crate::train::{self, TrainOptions, checkpoint};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

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
}

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
    /// Evaluate this checkpoint instead of training (implies `train = false`).
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
}

/// A method scored without a network (a cell whose row or column has a baseline kind).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Baseline {
    Constant,
    Mertens,
}

/// The constant baseline's blend weight: no preference between the two frames, chosen a
/// priori (a constant fitted on the test scenes would be tuned on them).
pub const CONSTANT_BLEND_WEIGHT: f32 = 0.5;

impl AxisKind {
    fn baseline(self) -> Option<Baseline> {
        match self {
            AxisKind::Constant => Some(Baseline::Constant),
            AxisKind::Mertens => Some(Baseline::Mertens),
            AxisKind::Finetune | AxisKind::Control => None,
        }
    }
}

impl Baseline {
    /// The method: Network-1's own fusion (Laplacian blend, tone curve) with these weights.
    fn method(self) -> Box<dyn evaluate::Method> {
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
        };
        Box::new(evaluate::Network1 {
            description,
            weights,
            tone_k,
        })
    }
}

fn yes() -> bool {
    true
}

impl Axis {
    fn label(&self) -> &str {
        self.label.as_deref().unwrap_or(&self.name)
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
        cfg.validate().map_err(|m| Error::config(path, m))?;
        Ok(cfg)
    }

    fn validate(&self) -> std::result::Result<(), String> {
        if self.rows.is_empty() {
            return Err("[[rows]]: at least one row is needed".into());
        }
        for (axis, list) in [("rows", &self.rows), ("columns", &self.columns)] {
            let mut seen = std::collections::BTreeSet::new();
            for a in list {
                if a.name.is_empty()
                    || !a
                        .name
                        .chars()
                        .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
                {
                    return Err(format!(
                        "[[{axis}]] name '{}': use letters, digits, '-' and '_' only",
                        a.name
                    ));
                }
                if !seen.insert(&a.name) {
                    return Err(format!("[[{axis}]] name '{}' appears twice", a.name));
                }
                if a.kind.baseline().is_some() && a.checkpoint.is_some() {
                    return Err(format!(
                        "[[{axis}]] '{}': a baseline kind has no network; it cannot name a \
                         checkpoint",
                        a.name
                    ));
                }
                if a.kind == AxisKind::Control && (!a.train || a.checkpoint.is_some()) {
                    return Err(format!(
                        "[[{axis}]] '{}': kind = \"control\" trains; it cannot also have \
                         train = false or a checkpoint",
                        a.name
                    ));
                }
                let sets_seed = a
                    .set
                    .get("run")
                    .and_then(|r| r.as_table())
                    .is_some_and(|r| r.contains_key("seed"));
                if sets_seed && !self.seeds.is_empty() {
                    return Err(format!(
                        "[[{axis}]] '{}' sets run.seed, but the grid's `seeds` set every \
                         trained cell's seed",
                        a.name
                    ));
                }
            }
        }
        let mut seeds = self.seeds.clone();
        seeds.sort_unstable();
        seeds.dedup();
        if seeds.len() != self.seeds.len() {
            return Err(format!("seeds {:?}: a seed appears twice", self.seeds));
        }
        if !(self.eval.level > 0.0 && self.eval.level < 1.0) {
            return Err(format!("eval.level {} must be in (0, 1)", self.eval.level));
        }
        for (key, m) in [
            ("margin_psnr", self.eval.margin_psnr),
            ("margin_ssim", self.eval.margin_ssim),
            ("margin_delta_e", self.eval.margin_delta_e),
        ] {
            if !(m > 0.0 && m.is_finite()) {
                return Err(format!("eval.{key} {m} must be a positive number"));
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
                return Err(format!("{what} '{r}' is not a cell of the grid"));
            }
        }
        if let Some(p) = &self.pretrained_per_seed
            && (self.seeds.is_empty() || !p.contains("{seed}"))
        {
            return Err(format!(
                "pretrained_per_seed '{p}' needs `seeds` and '{{seed}}' in the path"
            ));
        }
        let mut names = std::collections::BTreeSet::new();
        for (i, t) in std::iter::once(&self.testset).chain(&self.also).enumerate() {
            let what = match (i, &t.name) {
                (0, _) => "testset".to_string(),
                (_, Some(n)) => format!("also '{n}'"),
                (_, None) => return Err("every [[also]] test set needs a `name`".into()),
            };
            if i == 0 && t.name.is_some() {
                return Err("testset: the primary test set has no `name`".into());
            }
            if let Some(n) = &t.name
                && (n.is_empty()
                    || !n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                    || !names.insert(n))
            {
                return Err(format!(
                    "{what}: names are letters, digits and '_', each used once"
                ));
            }
            if t.radiance.is_some() != t.profile.is_some() {
                return Err(format!(
                    "{what}: give both `radiance` and `profile` (to build it) or neither"
                ));
            }
            if t.noise_per_seed && (self.seeds.is_empty() || t.radiance.is_none()) {
                return Err(format!(
                    "{what}: noise_per_seed needs `seeds` and a test set built from `radiance`"
                ));
            }
            t.options
                .validate()
                .map_err(|e| format!("{what}: {}", e.within("options")))?;
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
        let seeded = match self.cell_baseline(r, c) {
            Some(_) => self.testsets().any(|t| t.noise_per_seed),
            None => self.cell_trains(r, c) || self.seeded_eval(),
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
}

/// What a cell does, resolved: written as `cell.toml` (a changed cell is refused on rerun).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CellPlan {
    testset: PathBuf,
    /// The `also` test sets, in order. Not part of the cell's identity: an extra test set
    /// added later is scored without retraining (each has its own `eval_<name>/`).
    #[serde(skip)]
    also: Vec<PathBuf>,
    /// The checkpoint evaluated (the cell's own run folder when it trains); none for a
    /// baseline.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    checkpoint: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    baseline: Option<Baseline>,
    /// The training config, when the cell fine-tunes.
    #[serde(default)]
    train: Option<TrainConfig>,
    /// The base config's device (not part of the cell's identity).
    #[serde(skip)]
    backend: String,
}

/// What happened to a cell in this invocation.
#[derive(Clone, Debug, PartialEq)]
pub enum CellStatus {
    /// Finished before; skipped.
    Kept,
    /// Trained (from scratch or resumed at `resumed_at`) and/or evaluated now.
    Ran { resumed_at: Option<u64> },
}

#[derive(Clone, Debug)]
pub struct CellResult {
    pub id: String,
    pub status: CellStatus,
    pub seconds: f64,
}

#[derive(Clone, Debug)]
pub struct AblateSummary {
    pub cells: Vec<CellResult>,
    /// The Markdown table (also in `OUT/table.md`).
    pub table: String,
    pub seconds: f64,
}

pub const TABLE_MD: &str = "table.md";
pub const TABLE_CSV: &str = "table.csv";
/// Per-seed values (written when the grid has `seeds`).
pub const TABLE_SEEDS_CSV: &str = "table_seeds.csv";
const CELL_PLAN: &str = "cell.toml";
const EVAL_DIR: &str = "eval";

/// Run every unfinished cell of `cfg`, then write the table. `config_path` names the config in
/// errors.
pub fn run(cfg: &AblateConfig, config_path: &Path, progress: bool) -> Result<AblateSummary> {
    let began = Instant::now();
    let base = load_base(cfg)?;
    for t in cfg.testsets() {
        t.build(&cfg.seeds, progress)?;
        if !t.dir.is_dir() {
            return Err(Error::config(
                config_path,
                format!(
                    "test set {} does not exist (give `radiance` and `profile` to build it)",
                    t.dir.display()
                ),
            ));
        }
    }
    // One ablation per output folder: two would train and evaluate the same cells at once.
    let _lock = crate::io::guard::OutputLock::acquire(&cfg.out, "ablate")?;
    std::fs::create_dir_all(&cfg.out).map_err(|e| Error::io(&cfg.out, e))?;
    crate::io::atomic::remove_stale_temps(&cfg.out)?;
    let cells = cfg.cells();
    let mut results = Vec::new();
    for (k, &(r, c)) in cells.iter().enumerate() {
        for seed in cfg.cell_seeds(r, c) {
            let id = match seed {
                None => cfg.cell_id(r, c),
                Some(s) => format!("{}/seed{s}", cfg.cell_id(r, c)),
            };
            let t0 = Instant::now();
            let plan = plan_cell(cfg, config_path, &base, r, c, seed)?;
            if progress {
                eprintln!("cell {}/{} {id}", k + 1, cells.len());
            }
            let status = run_cell(cfg, &cfg.unit_dir(r, c, seed), &id, &plan, progress)?;
            results.push(CellResult {
                id,
                status,
                seconds: t0.elapsed().as_secs_f64(),
            });
            // The table so far, after every run: an interrupted grid shows what it has.
            write_table(cfg)?;
        }
    }
    let table = write_table(cfg)?;
    Ok(AblateSummary {
        cells: results,
        table,
        seconds: began.elapsed().as_secs_f64(),
    })
}

/// The training configs of the cells that fine-tune (for the caller to prepare their data).
pub fn train_configs(cfg: &AblateConfig, config_path: &Path) -> Result<Vec<TrainConfig>> {
    let base = load_base(cfg)?;
    let mut out = Vec::new();
    for (r, c) in cfg.cells() {
        for seed in cfg.cell_seeds(r, c) {
            out.extend(plan_cell(cfg, config_path, &base, r, c, seed)?.train);
        }
    }
    Ok(out)
}

fn load_base(cfg: &AblateConfig) -> Result<toml::Table> {
    let text = crate::io::guard::read_text(&cfg.base)?;
    crate::config::parse_toml(&text, &cfg.base)
}

fn plan_cell(
    cfg: &AblateConfig,
    config_path: &Path,
    base: &toml::Table,
    r: usize,
    c: Option<usize>,
    seed: Option<u64>,
) -> Result<CellPlan> {
    let axes: Vec<&Axis> = std::iter::once(&cfg.rows[r])
        .chain(c.map(|c| &cfg.columns[c]))
        .collect();
    let id = cfg.cell_id(r, c);
    let cell_err = |m: String| Error::config(config_path, format!("cell '{id}': {m}"));
    let mut base = base.clone();
    if let (Some(path), Some(k)) = (&cfg.pretrained_per_seed, seed)
        && let Some(t) = section(&mut base, "init")
    {
        t.insert(
            "checkpoint".into(),
            toml::Value::String(path.replace("{seed}", &k.to_string())),
        );
    }
    let mut merged = if axes.iter().any(|a| a.kind == AxisKind::Control) {
        control_config(&cfg.base, &base).map_err(|e| cell_err(format!("control: {e}")))?
    } else {
        base
    };
    for a in &axes {
        merge_tables(&mut merged, &a.set);
    }
    let run_dir = cfg.unit_dir(r, c, seed).join("run");
    if let Some(t) = section(&mut merged, "run") {
        t.insert(
            "out".into(),
            toml::Value::String(run_dir.to_string_lossy().into_owned()),
        );
        if let Some(s) = seed {
            // toml integers are i64: a seed above i64::MAX cannot be written into a config.
            let s = i64::try_from(s)
                .map_err(|_| cell_err(format!("seed {s} is larger than TOML's integers")))?;
            t.insert("seed".into(), toml::Value::Integer(s));
        }
    }
    let train_cfg: TrainConfig = toml::Value::Table(merged).try_into().map_err(|e| {
        cell_err(format!(
            "base {} with the cell's settings: {e}",
            cfg.base.display()
        ))
    })?;
    train_cfg.validate().map_err(|e| cell_err(e.to_string()))?;
    let explicit: Vec<&PathBuf> = axes.iter().filter_map(|a| a.checkpoint.as_ref()).collect();
    if explicit.len() > 1 {
        return Err(cell_err(
            "both its row and its column name a checkpoint".into(),
        ));
    }
    let trains = cfg.cell_trains(r, c);
    let baseline = cfg.cell_baseline(r, c);
    let checkpoint = match (explicit.first(), trains) {
        _ if baseline.is_some() => None,
        (Some(p), _) => Some((*p).clone()),
        (None, true) => Some(run_dir),
        (None, false) => Some(
            train_cfg
                .init
                .as_ref()
                .and_then(|i| i.checkpoint.clone())
                .ok_or_else(|| {
                    cell_err(
                        "train = false evaluates the config's [init] checkpoint, and it has none; \
                     give `checkpoint = ...`"
                            .into(),
                    )
                })?,
        ),
    };
    Ok(CellPlan {
        testset: cfg.testset.dir_for(seed),
        also: cfg.also.iter().map(|t| t.dir_for(seed)).collect(),
        checkpoint,
        baseline,
        backend: train_cfg.run.backend.clone(),
        train: trains.then_some(train_cfg),
    })
}

/// The table `[name]` of a config, created when missing (`None` when the key holds a value
/// that is not a table: the config's own validation reports it).
fn section<'a>(cfg: &'a mut toml::Table, name: &str) -> Option<&'a mut toml::Table> {
    cfg.entry(name)
        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
        .as_table_mut()
}

/// The training config of a control cell (`kind = "control"`): the config the pretrained
/// network was trained with (`config.toml` of the run that the base's `[init] checkpoint`
/// names), with the base's `[run]` (steps, seed, backend, checkpointing), `[optim]` (learning
/// rate, Adam), `[schedule]` and `[init]` (start from the pretrained weights, fresh Adam). Model,
/// data, loss and validation stay the pretraining run's: the same network trained on for as
/// many steps, with the same learning-rate restart as a fine-tune, on its own data.
fn control_config(base_path: &Path, base: &toml::Table) -> Result<toml::Table> {
    let init = base
        .get("init")
        .and_then(|i| i.get("checkpoint"))
        .and_then(|c| c.as_str())
        .ok_or_else(|| {
            Error::config(
                base_path,
                "a control cell needs the base config's [init] checkpoint (the pretrained run)",
            )
        })?;
    let init = PathBuf::from(init);
    // `[init] checkpoint` names a run folder or one of its checkpoints (RUN/checkpoints/step-N).
    let run = if init.join(checkpoint::STATE_FILE).is_file() {
        init.parent()
            .and_then(Path::parent)
            .map(Path::to_path_buf)
            .unwrap_or_default()
    } else {
        init.clone()
    };
    let path = run.join(train::RUN_CONFIG);
    let text = crate::io::guard::read_text(&path)?;
    let mut merged: toml::Table = crate::config::parse_toml(&text, &path)?;
    for key in ["run", "optim", "schedule", "init"] {
        match base.get(key) {
            Some(v) => merged.insert(key.into(), v.clone()),
            None => merged.remove(key),
        };
    }
    Ok(merged)
}

fn run_cell(
    cfg: &AblateConfig,
    dir: &Path,
    id: &str,
    plan: &CellPlan,
    progress: bool,
) -> Result<CellStatus> {
    let plan_path = dir.join(CELL_PLAN);
    let plan_text = toml::to_string(plan).map_err(|e| Error::encode(&plan_path, e))?;
    match std::fs::read_to_string(&plan_path) {
        Ok(saved) if saved != plan_text => {
            return Err(Error::config(
                &plan_path,
                format!(
                    "cell '{id}' was run with different settings (or test set); delete {} to \
                     run it again",
                    dir.display()
                ),
            ));
        }
        Ok(_) => {}
        Err(_) => {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            write_atomic(&plan_path, plan_text.as_bytes())?;
        }
    }
    // (test set folder, eval folder) pairs not scored yet.
    let pending: Vec<(&Path, String)> = std::iter::once(&plan.testset)
        .chain(&plan.also)
        .zip(cfg.testsets().map(TestsetSpec::eval_dir))
        .filter(|(_, e)| !dir.join(e).join(evaluate::SUMMARY_CSV).is_file())
        .map(|(t, e)| (t.as_path(), e))
        .collect();
    if pending.is_empty() {
        if progress {
            eprintln!("  finished before: kept");
        }
        return Ok(CellStatus::Kept);
    }
    let mut resumed_at = None;
    if let Some(tc) = &plan.train {
        let latest = checkpoint::latest(&tc.run.out)?;
        let done_step = match &latest {
            Some(d) => Some(checkpoint::read_state(d)?.step),
            None => None,
        };
        if done_step.is_none_or(|s| s < tc.run.steps) {
            if progress {
                match done_step {
                    Some(s) => eprintln!("  fine-tuning: resuming at step {s} of {}", tc.run.steps),
                    None => eprintln!("  fine-tuning: {} steps", tc.run.steps),
                }
            }
            resumed_at = done_step;
            train::run(
                tc,
                &TrainOptions {
                    resume: done_step.is_some(),
                    progress,
                },
            )?;
        }
    }
    let method = match (&plan.checkpoint, plan.baseline) {
        (_, Some(b)) => b.method(),
        (Some(ckpt), None) => {
            if progress {
                eprintln!("  evaluating {}", ckpt.display());
            }
            let backend = cfg.eval.backend.as_ref().unwrap_or(&plan.backend);
            let device = device_from_name(backend)?;
            let net = NetworkOptions {
                tile: cfg.eval.tile,
                ..NetworkOptions::default()
            };
            from_checkpoint(ckpt, &net, &device)?
        }
        (None, None) => {
            return Err(Error::Invalid(format!(
                "cell '{id}' has neither a checkpoint nor a baseline"
            )));
        }
    };
    let opts = EvalOptions {
        resamples: cfg.eval.resamples,
        seed: cfg.eval.seed,
        level: cfg.eval.level,
        progress,
        ..EvalOptions::default()
    };
    for (testset, eval_dir) in pending {
        // Scored into a partial folder, renamed when complete: a killed evaluation reruns.
        let partial = dir.join(format!("{eval_dir}.partial"));
        if partial.exists() {
            std::fs::remove_dir_all(&partial).map_err(|e| Error::io(&partial, e))?;
        }
        evaluate::evaluate(testset, method.as_ref(), &partial, &opts)?;
        let done = dir.join(&eval_dir);
        std::fs::rename(&partial, &done).map_err(|e| Error::io(&done, e))?;
    }
    Ok(CellStatus::Ran { resumed_at })
}

// ---------------------------------------------------------------------------------------------
// The table

/// Per-set values of [`SUMMARY_METRICS`] of a finished cell (`eval/per_image.csv`), by set
/// name. An appended metric is NaN where the file lacks its column or leaves it empty (PSNR-T
/// dark for a set with too few under-exposed pixels); NaN values are left out of the statistics.
fn read_per_image(path: &Path) -> Result<SetScores> {
    Ok(report::read_per_image(path)?
        .into_iter()
        .map(|row| {
            (
                row.set.clone(),
                row.summary_values().map(|v| v.unwrap_or(f64::NAN)),
            )
        })
        .collect())
}

/// The metrics of the tables, in their order: the paper's four, then ΔE2000 of the tone-mapped
/// output (lower is better) and PSNR-T over the reference frame's under-exposed pixels, where
/// colour and noise can matter (docs/protocol.md).
const TABLE_METRICS: [(&str, &str); 6] = [
    ("psnr_t", "PSNR-T"),
    ("psnr_l", "PSNR-L"),
    ("ssim_t", "SSIM-T"),
    ("ssim_l", "SSIM-L"),
    ("delta_e2000", "ΔE2000"),
    ("psnr_t_dark", "PSNR-T dark"),
];

fn metric_index(m: &str) -> usize {
    SUMMARY_METRICS
        .iter()
        .position(|x| *x == m)
        .expect("known metric")
}

fn fmt(metric: &str, v: f64) -> String {
    if !v.is_finite() {
        format!("{v}")
    } else if metric.starts_with("ssim") {
        format!("{v:.4}")
    } else {
        format!("{v:.2}")
    }
}

/// Per-set values of [`SUMMARY_METRICS`] (NaN where absent), by set name.
type SetScores = BTreeMap<String, [f64; SUMMARY_METRICS.len()]>;

/// A finished cell's scores: one per-set table per finished run, in the grid's seed order.
/// Seed `None`: a run that serves every seed (no `seeds`, or a cell that does not train).
struct CellScores {
    r: usize,
    c: Option<usize>,
    runs: Vec<(Option<u64>, SetScores)>,
}

/// One quantity (a cell's metric, or its difference to the reference) over seeds and scenes.
struct Stat {
    /// Sets behind one seed's value (finite values in the scenes used).
    n_sets: usize,
    n_seeds: usize,
    n_scenes: usize,
    mean: f64,
    lo: f64,
    hi: f64,
    /// Each seed's value: the mean over the scenes.
    per_seed: Vec<(Option<u64>, f64)>,
    /// Each scene's value: the mean over the seeds (the unit of the paired tests).
    per_scene: Vec<f64>,
}

/// Fewest scenes for an interval or a test: below it a table shows means only.
pub const MIN_SCENES_FOR_TESTS: usize = 10;

/// The paired tests of a difference over scenes (docs/protocol.md, "Statistics").
struct Tests {
    t: stats::PairedT,
    wilcoxon: Option<stats::Wilcoxon>,
    margin: f64,
    tost: Option<stats::Tost>,
}

impl Stat {
    fn tests(&self, level: f64, margin: f64) -> Option<Tests> {
        if self.n_scenes < MIN_SCENES_FOR_TESTS {
            return None;
        }
        Some(Tests {
            t: stats::paired_t(&self.per_scene, level)?,
            wilcoxon: stats::wilcoxon_signed_rank(&self.per_scene),
            margin,
            tost: stats::tost_paired(&self.per_scene, margin, 1.0 - level),
        })
    }
}

impl Stat {
    fn seeds_positive(&self) -> usize {
        self.per_seed.iter().filter(|(_, v)| *v > 0.0).count()
    }

    /// Seeds whose value has the sign of the mean (0 counts as its own sign).
    fn sign_holds(&self) -> usize {
        let sign = |v: f64| (v > 0.0) as i8 - (v < 0.0) as i8;
        self.per_seed
            .iter()
            .filter(|(_, v)| sign(*v) == sign(self.mean))
            .count()
    }
}

/// The statistic of per-set values, one table per seed: a set's value counts toward its scene's
/// mean (non-finite values are left out), a seed's value is the mean over the scenes, and the
/// interval is the two-level bootstrap (seeds, then scenes) of the mean over seeds. Only scenes
/// with a value in every seed are used, so every seed is scored on the same scenes.
fn crossed_stat(
    cfg: &AblateConfig,
    rows: &[(Option<u64>, BTreeMap<&str, f64>)],
    scenes: &BTreeMap<String, String>,
) -> Stat {
    let per_row: Vec<BTreeMap<&str, (f64, usize)>> = rows
        .iter()
        .map(|(_, sets)| {
            let mut by_scene: BTreeMap<&str, (f64, usize)> = BTreeMap::new();
            for (&set, &v) in sets.iter().filter(|(_, v)| v.is_finite()) {
                let scene = scenes.get(set).map_or(set, String::as_str);
                let e = by_scene.entry(scene).or_default();
                e.0 += v;
                e.1 += 1;
            }
            by_scene
        })
        .collect();
    let common: Vec<&str> = per_row.first().map_or_else(Vec::new, |first| {
        first
            .keys()
            .copied()
            .filter(|k| per_row.iter().all(|r| r.contains_key(k)))
            .collect()
    });
    let matrix: Vec<Vec<f64>> = per_row
        .iter()
        .map(|r| common.iter().map(|k| r[k].0 / r[k].1 as f64).collect())
        .collect();
    let n_sets = per_row
        .first()
        .map_or(0, |r| common.iter().map(|k| r[k].1).sum());
    let (mean, lo, hi) =
        bootstrap_crossed(&matrix, cfg.eval.resamples, cfg.eval.seed, cfg.eval.level);
    Stat {
        n_sets,
        n_seeds: matrix.len(),
        n_scenes: common.len(),
        mean,
        lo,
        hi,
        per_seed: rows
            .iter()
            .zip(&matrix)
            .map(|((s, _), m)| (*s, m.iter().sum::<f64>() / m.len() as f64))
            .collect(),
        per_scene: (0..common.len())
            .map(|j| matrix.iter().map(|m| m[j]).sum::<f64>() / matrix.len() as f64)
            .collect(),
    }
}

/// The runs of a cell paired with the reference's: by seed, and a run that serves every seed
/// (a cell that does not train) pairs with each of the other's seeds.
fn pair_runs<'a>(
    d: &'a CellScores,
    rs: &'a CellScores,
) -> Vec<(Option<u64>, &'a SetScores, &'a SetScores)> {
    let single = |x: &CellScores| x.runs.len() == 1 && x.runs[0].0.is_none();
    match (single(d), single(rs)) {
        (true, true) => vec![(None, &d.runs[0].1, &rs.runs[0].1)],
        (true, false) => rs.runs.iter().map(|(s, w)| (*s, &d.runs[0].1, w)).collect(),
        (false, true) => d.runs.iter().map(|(s, v)| (*s, v, &rs.runs[0].1)).collect(),
        (false, false) => d
            .runs
            .iter()
            .filter_map(|(s, v)| {
                rs.runs
                    .iter()
                    .find(|(t, _)| t == s)
                    .map(|(_, w)| (*s, v, w))
            })
            .collect(),
    }
}

/// Write every test set's tables from the finished runs: `table.md` and `table.csv` (and, with
/// `seeds`, `table_seeds.csv`) for the primary test set, `table_<name>.*` for each of `also`;
/// returns the Markdown of all, the primary first.
pub fn write_table(cfg: &AblateConfig) -> Result<String> {
    let tables = write_tables(cfg)?;
    Ok(tables
        .iter()
        .map(|t| t.markdown.as_str())
        .collect::<Vec<_>>()
        .join("\n\n"))
}

/// [`write_table`], returning every test set's table with its values (the primary first).
pub fn write_tables(cfg: &AblateConfig) -> Result<Vec<Table>> {
    cfg.testsets().map(|t| write_table_for(cfg, t)).collect()
}

/// One test set's table: its Markdown and the values behind it.
#[derive(Clone, Debug)]
pub struct Table {
    /// `None` for the primary test set, else the `also` test set's name.
    pub testset: Option<String>,
    pub markdown: String,
    pub entries: Vec<TableEntry>,
}

impl Table {
    pub fn entry(&self, row: &str, metric: &str) -> Option<&TableEntry> {
        self.entries
            .iter()
            .find(|e| e.row == row && e.column.is_none() && e.metric == metric)
    }
}

/// One cell's value of one metric: mean over seeds of the mean over scenes, and its paired
/// difference to the reference cell.
#[derive(Clone, Debug)]
pub struct TableEntry {
    pub row: String,
    pub column: Option<String>,
    pub metric: &'static str,
    pub mean: f64,
    pub n_scenes: usize,
    pub n_seeds: usize,
    pub diff: Option<DiffEntry>,
}

/// A paired difference to the reference cell (docs/protocol.md, "Statistics").
#[derive(Clone, Debug)]
pub struct DiffEntry {
    pub mean: f64,
    /// Seeds whose mean over scenes has the sign of `mean`, of `n_seeds`.
    pub sign_holds: usize,
    pub n_seeds: usize,
    /// The tests over scenes; `None` with fewer than [`MIN_SCENES_FOR_TESTS`] scenes.
    pub t: Option<stats::PairedT>,
    pub wilcoxon_p: Option<f64>,
    pub margin: f64,
    pub tost_p: Option<f64>,
}

fn write_table_for(cfg: &AblateConfig, t: &TestsetSpec) -> Result<Table> {
    let mut entries = Vec::new();
    let mut done = Vec::new();
    let (mut runs_done, mut runs_total) = (0, 0);
    for (r, c) in cfg.cells() {
        let mut runs = Vec::new();
        for seed in cfg.cell_seeds(r, c) {
            runs_total += 1;
            let path = cfg
                .unit_dir(r, c, seed)
                .join(t.eval_dir())
                .join(evaluate::PER_IMAGE);
            if path.is_file() {
                runs.push((seed, read_per_image(&path)?));
            }
        }
        runs_done += runs.len();
        if !runs.is_empty() {
            done.push(CellScores { r, c, runs });
        }
    }
    let set_names: std::collections::BTreeSet<&str> = done
        .iter()
        .flat_map(|d| d.runs.iter().flat_map(|(_, sets)| sets.keys()))
        .map(String::as_str)
        .collect();
    let testset_dir = t.dir_for(cfg.seeds.first().copied());
    let scenes = testset::scenes_of_sets(&testset_dir, set_names.iter().copied())?;
    let n_scenes = scenes
        .values()
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    let find = |r: usize, c: Option<usize>| done.iter().find(|d| d.r == r && d.c == c);
    let wanted = t.reference.as_ref().or(cfg.eval.reference.as_ref());
    let reference = cfg
        .cells()
        .into_iter()
        .find(|&(r, c)| wanted == Some(&cfg.cell_id(r, c)))
        .unwrap_or(cfg.cells()[0]);
    let ref_scores = find(reference.0, reference.1);
    let ref_label = cell_label(cfg, reference.0, reference.1);
    let pct = cfg.eval.level * 100.0;
    let seeded = !cfg.seeds.is_empty();

    let mut csv = String::from(
        "row,column,metric,n,mean,ci_lo,ci_hi,diff_vs_reference,diff_ci_lo,diff_ci_hi,\
         n_seeds,n_scenes,seeds_positive,diff_n_seeds,diff_t_lo,diff_t_hi,diff_t_p,\
         diff_wilcoxon_p,diff_tost_margin,diff_tost_p,n_pretrain_seeds\n",
    );
    let mut seeds_csv = String::from("row,column,seed,metric,n_scenes,mean,diff_vs_reference\n");
    // (metric, r, c) → "mean [lo, hi]" and paired difference.
    let mut cell_text: BTreeMap<(usize, usize, Option<usize>), (String, String)> = BTreeMap::new();
    for d in &done {
        let row_name = report::csv_field(&cfg.rows[d.r].name);
        let col_name = report::csv_field(d.c.map(|c| cfg.columns[c].name.as_str()).unwrap_or(""));
        for (mi, (metric, _)) in TABLE_METRICS.iter().enumerate() {
            let k = metric_index(metric);
            let rows: Vec<(Option<u64>, BTreeMap<&str, f64>)> = d
                .runs
                .iter()
                .map(|(s, sets)| (*s, sets.iter().map(|(n, v)| (n.as_str(), v[k])).collect()))
                .collect();
            let st = crossed_stat(cfg, &rows, &scenes);
            if st.n_scenes == 0 {
                // A metric no set of this cell has (PSNR-T dark without under-exposed pixels,
                // or a per_image.csv older than the metric): no row, "–" in the Markdown.
                cell_text.insert((mi, d.r, d.c), ("–".into(), "–".into()));
                continue;
            }
            // Paired within seed, scene and set: the same scenes and the same seed's data
            // stream, so scene difficulty and seed luck cancel and the interval is much tighter
            // than the two means' intervals.
            let diff = ref_scores
                .filter(|rs| !(rs.r == d.r && rs.c == d.c))
                .map(|rs| {
                    let rows: Vec<(Option<u64>, BTreeMap<&str, f64>)> = pair_runs(d, rs)
                        .into_iter()
                        .map(|(s, v, w)| {
                            let diffs = v
                                .iter()
                                .filter_map(|(n, a)| w.get(n).map(|b| (n.as_str(), a[k] - b[k])))
                                .collect();
                            (s, diffs)
                        })
                        .collect();
                    crossed_stat(cfg, &rows, &scenes)
                });
            let margin = cfg.eval.margin(metric);
            let tests = diff.as_ref().and_then(|x| x.tests(cfg.eval.level, margin));
            let opt = |f: &dyn Fn(&Stat) -> String| diff.as_ref().map(f).unwrap_or_default();
            entries.push(TableEntry {
                row: cfg.rows[d.r].name.clone(),
                column: d.c.map(|c| cfg.columns[c].name.clone()),
                metric,
                mean: st.mean,
                n_scenes: st.n_scenes,
                n_seeds: st.n_seeds,
                diff: diff.as_ref().map(|x| DiffEntry {
                    mean: x.mean,
                    sign_holds: x.sign_holds(),
                    n_seeds: x.n_seeds,
                    t: tests.as_ref().map(|ts| ts.t),
                    wilcoxon_p: tests
                        .as_ref()
                        .and_then(|ts| ts.wilcoxon.as_ref().map(|w| w.p)),
                    margin,
                    tost_p: tests.as_ref().and_then(|ts| ts.tost.as_ref().map(|w| w.p)),
                }),
            });
            let test = |f: &dyn Fn(&Tests) -> Option<f64>| {
                tests
                    .as_ref()
                    .and_then(f)
                    .map(|v| v.to_string())
                    .unwrap_or_default()
            };
            let _ = writeln!(
                csv,
                "{row_name},{col_name},{metric},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                st.n_sets,
                st.mean,
                st.lo,
                st.hi,
                opt(&|x| x.mean.to_string()),
                opt(&|x| x.lo.to_string()),
                opt(&|x| x.hi.to_string()),
                st.n_seeds,
                st.n_scenes,
                opt(&|x| x.seeds_positive().to_string()),
                opt(&|x| x.n_seeds.to_string()),
                test(&|x| Some(x.t.ci_lower)),
                test(&|x| Some(x.t.ci_upper)),
                test(&|x| Some(x.t.p)),
                test(&|x| x.wilcoxon.as_ref().map(|w| w.p)),
                test(&|x| Some(x.margin)),
                test(&|x| x.tost.as_ref().map(|w| w.p)),
                // Independent pretrainings behind the cell's numbers (0: no network).
                match (cfg.cell_baseline(d.r, d.c), &cfg.pretrained_per_seed) {
                    (Some(_), _) => 0,
                    (None, Some(_)) => st.n_seeds,
                    (None, None) => 1,
                },
            );
            if seeded {
                // Every seed's number; a run that serves every seed is repeated for each.
                for &seed in &cfg.seeds {
                    let at = |x: &Stat| {
                        x.per_seed
                            .iter()
                            .find(|(s, _)| s.is_none() || *s == Some(seed))
                            .map(|(_, v)| *v)
                    };
                    let Some(v) = at(&st) else { continue };
                    let dv = diff.as_ref().and_then(at);
                    let _ = writeln!(
                        seeds_csv,
                        "{row_name},{col_name},{seed},{metric},{},{v},{}",
                        st.n_scenes,
                        dv.map(|x| x.to_string()).unwrap_or_default()
                    );
                }
            }
            // With too few scenes for a test, means only: an interval over three scenes is
            // about their [min, max] and would suggest a certainty it does not have.
            let mean_text = if st.n_scenes >= MIN_SCENES_FOR_TESTS {
                format!(
                    "{} [{}, {}]",
                    fmt(metric, st.mean),
                    fmt(metric, st.lo),
                    fmt(metric, st.hi)
                )
            } else {
                fmt(metric, st.mean)
            };
            let seeds_text = |x: &Stat| {
                if seeded {
                    format!(" ({}/{})", x.sign_holds(), x.n_seeds)
                } else {
                    String::new()
                }
            };
            let diff_text = match (&diff, &tests) {
                (Some(x), Some(ts)) => format!(
                    "{:+} [{:+}, {:+}]{} p {}{}{}",
                    Signed(metric, x.mean),
                    Signed(metric, ts.t.ci_lower),
                    Signed(metric, ts.t.ci_upper),
                    if ts.t.ci_lower > 0.0 || ts.t.ci_upper < 0.0 {
                        " *"
                    } else {
                        ""
                    },
                    ts.wilcoxon
                        .as_ref()
                        .map_or("–".to_string(), |w| format_p(w.p)),
                    if ts.tost.as_ref().is_some_and(|t| t.p < 1.0 - cfg.eval.level) {
                        " ≈"
                    } else {
                        ""
                    },
                    seeds_text(x),
                ),
                (Some(x), None) => format!("{:+}{}", Signed(metric, x.mean), seeds_text(x)),
                (None, _) => "(reference)".into(),
            };
            cell_text.insert((mi, d.r, d.c), (mean_text, diff_text));
        }
    }

    let mut md = format!(
        "# {}{}\n\nTest set: `{}` ({} sets of {n_scenes} scenes; the sets of one scene are one \
         cluster{}).",
        cfg.title,
        t.label
            .as_ref()
            .or(t.name.as_ref())
            .map(|l| format!(" — {l}"))
            .unwrap_or_default(),
        t.dir.display(),
        set_names.len(),
        if t.noise_per_seed {
            "; test noise redrawn per seed"
        } else {
            ""
        },
    );
    let tests_text = if n_scenes >= MIN_SCENES_FOR_TESTS {
        format!(
            " Δ [{pct:.0} % paired t interval over scenes, each scene's Δ the mean over seeds] \
             p = Wilcoxon signed-rank p (two-sided); * = the t interval excludes 0; ≈ = \
             equivalent within ±{} dB PSNR / ±{} SSIM / ±{} ΔE2000 (TOST, α = {:.2}). ΔE2000: \
             lower is better. PSNR-T dark: over the pixels the reference frame under-exposes, \
             sets with at least 1 % of them.",
            cfg.eval.margin_psnr,
            cfg.eval.margin_ssim,
            cfg.eval.margin_delta_e,
            1.0 - cfg.eval.level
        )
    } else {
        format!(
            " With {n_scenes} scene(s) (fewer than {MIN_SCENES_FOR_TESTS}) the table shows \
             means only: no interval and no test."
        )
    };
    // The means' intervals, only where there are scenes enough for one.
    let ci_text = |what: &str| {
        if n_scenes >= MIN_SCENES_FOR_TESTS {
            format!(" [{pct:.0} % {what}; {} resamples]", cfg.eval.resamples)
        } else {
            String::new()
        }
    };
    if seeded {
        let list: Vec<String> = cfg.seeds.iter().map(u64::to_string).collect();
        let _ = write!(
            md,
            " Seeds: {} ({}). Each value: mean over the seeds of the mean over the scenes{}. Δ: \
             difference to **{ref_label}** paired within seed, scene and set; (k/n) = the seeds \
             in which Δ has the sign of its mean.{tests_text} {runs_done} of {runs_total} runs \
             finished.\n\n",
            list.join(", "),
            if cfg.pretrained_per_seed.is_some() {
                "each seed has its own pretrained network and its own fine-tuning data stream"
            } else {
                "every trained cell once per seed; a cell that does not train is evaluated once \
                 and serves every seed"
            },
            ci_text("CI of a two-level bootstrap: seeds, then scenes"),
        );
    } else {
        let _ = write!(
            md,
            " Each value: mean over the scenes{}. Δ: paired difference to **{ref_label}** over \
             the same sets.{tests_text} {runs_done} of {runs_total} cells finished.\n\n",
            ci_text("bootstrap CI resampling scenes"),
        );
    }
    let missing = "(not run yet)".to_string();
    if cfg.columns.is_empty() {
        // Paper Tables 1–2: one row per method, the four metrics across.
        let _ = write!(md, "| method |");
        for (_, name) in TABLE_METRICS {
            let _ = write!(md, " {name} |");
        }
        let _ = write!(md, "\n|---|");
        for _ in TABLE_METRICS {
            let _ = write!(md, "---|");
        }
        md.push('\n');
        for (r, row) in cfg.rows.iter().enumerate() {
            let _ = write!(md, "| {} |", row.label());
            for mi in 0..TABLE_METRICS.len() {
                let t = cell_text.get(&(mi, r, None));
                let _ = write!(md, " {} |", t.map(|t| &t.0).unwrap_or(&missing));
            }
            md.push('\n');
        }
        let _ = write!(md, "\n| Δ to {ref_label} |");
        for (_, name) in TABLE_METRICS {
            let _ = write!(md, " Δ {name} |");
        }
        let _ = write!(md, "\n|---|");
        for _ in TABLE_METRICS {
            let _ = write!(md, "---|");
        }
        md.push('\n');
        for (r, row) in cfg
            .rows
            .iter()
            .enumerate()
            .filter(|(r, _)| *r != reference.0)
        {
            let _ = write!(md, "| {} |", row.label());
            for mi in 0..TABLE_METRICS.len() {
                let t = cell_text.get(&(mi, r, None));
                let _ = write!(md, " {} |", t.map(|t| &t.1).unwrap_or(&missing));
            }
            md.push('\n');
        }
    } else {
        // Paper Tables 3–4: one table per metric, rows × columns.
        for (mi, (_, name)) in TABLE_METRICS.iter().enumerate() {
            let _ = write!(md, "## {name}\n\n| |");
            for col in &cfg.columns {
                let _ = write!(md, " {} |", col.label());
            }
            let _ = write!(md, "\n|---|");
            for _ in &cfg.columns {
                let _ = write!(md, "---|");
            }
            md.push('\n');
            for (r, row) in cfg.rows.iter().enumerate() {
                let _ = write!(md, "| {} |", row.label());
                for c in 0..cfg.columns.len() {
                    let t = cell_text.get(&(mi, r, Some(c)));
                    let _ = write!(
                        md,
                        " {} |",
                        t.map(|t| format!("{}<br>Δ {}", t.0, t.1))
                            .unwrap_or_else(|| missing.clone())
                    );
                }
                md.push('\n');
            }
            md.push('\n');
        }
    }
    write_atomic(&cfg.out.join(t.table_file(TABLE_MD)), md.as_bytes())?;
    write_atomic(&cfg.out.join(t.table_file(TABLE_CSV)), csv.as_bytes())?;
    if seeded {
        write_atomic(
            &cfg.out.join(t.table_file(TABLE_SEEDS_CSV)),
            seeds_csv.as_bytes(),
        )?;
    }
    Ok(Table {
        testset: t.name.clone(),
        markdown: md,
        entries,
    })
}

/// A p value as tables print it: two decimals, three below 0.01, "< 0.001" below that.
pub fn format_p(p: f64) -> String {
    if p < 0.001 {
        "< 0.001".into()
    } else if p < 0.01 {
        format!("{p:.3}")
    } else {
        format!("{p:.2}")
    }
}

fn cell_label(cfg: &AblateConfig, r: usize, c: Option<usize>) -> String {
    match c {
        None => cfg.rows[r].label().to_string(),
        Some(c) => format!("{} / {}", cfg.rows[r].label(), cfg.columns[c].label()),
    }
}

/// A signed value with the metric's precision.
struct Signed<'a>(&'a str, f64);

impl std::fmt::Display for Signed<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = fmt(self.0, self.1.abs());
        let sign = if self.1 < 0.0 { "−" } else { "+" };
        if f.sign_plus() || self.1 < 0.0 {
            write!(f, "{sign}{s}")
        } else {
            write!(f, "{s}")
        }
    }
}

/// The command's report: the table, then what each cell did and where the results are.
pub fn report(cfg: &AblateConfig, s: &AblateSummary) -> String {
    let mut out = s.table.clone();
    out.push('\n');
    for c in &s.cells {
        let what = match c.status {
            CellStatus::Kept => "kept (finished before)".to_string(),
            CellStatus::Ran {
                resumed_at: Some(step),
            } => format!("resumed at step {step}"),
            CellStatus::Ran { resumed_at: None } => "ran".to_string(),
        };
        let _ = writeln!(out, "cell {:<32} {what:<24} {:.1} s", c.id, c.seconds);
    }
    let _ = write!(
        out,
        "{:.1} s; wrote {}/{{{}, {}{}}} and cells/<cell>/{}{{run, eval}}",
        s.seconds,
        cfg.out.display(),
        TABLE_MD,
        TABLE_CSV,
        if cfg.seeds.is_empty() {
            String::new()
        } else {
            format!(", {}", TABLE_SEEDS_CSV)
        },
        if cfg.seeds.is_empty() {
            ""
        } else {
            "[seed<k>/]"
        },
    );
    out
}
