//! The grid's tables from the finished runs' `per_image.csv`: means, paired differences to
//! the reference cell and their tests, as Markdown and CSV.

use super::*;

mod markdown;
use markdown::{table_body, table_intro};

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
/// colour and noise can matter (docs/protocol.md), and PSNR-T over the pixels where subjects
/// moved (test sets with moving subjects only: a metric no cell has gets no column).
const TABLE_METRICS: [(&str, &str); 7] = [
    ("psnr_t", "PSNR-T"),
    ("psnr_l", "PSNR-L"),
    ("ssim_t", "SSIM-T"),
    ("ssim_l", "SSIM-L"),
    ("delta_e2000", "ΔE2000"),
    ("psnr_t_dark", "PSNR-T dark"),
    ("psnr_t_moving", "PSNR-T moving"),
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
    /// Each seed's difference (the mean over scenes).
    pub per_seed: Vec<(Option<u64>, f64)>,
    /// Seeds whose mean over scenes has the sign of `mean`, of `n_seeds`.
    pub sign_holds: usize,
    pub n_seeds: usize,
    /// The tests over scenes; `None` with fewer than [`MIN_SCENES_FOR_TESTS`] scenes.
    pub t: Option<stats::PairedT>,
    /// The t interval over the per-seed differences: the training run as the unit, so it says
    /// whether a newly trained network would differ, not only these runs (None under 2 seeds).
    pub seed_t: Option<stats::PairedT>,
    pub wilcoxon_p: Option<f64>,
    pub margin: f64,
    pub tost_p: Option<f64>,
}

/// The Markdown texts of one (metric, row, column) of the table: the mean and the difference.
type CellTexts = BTreeMap<(usize, usize, Option<usize>), (String, String)>;

fn write_table_for(cfg: &AblateConfig, t: &TestsetSpec) -> Result<Table> {
    let (done, runs_done, runs_total) = load_cells(cfg, t)?;
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
    let seeded = !cfg.seeds.is_empty();

    let mut csv = String::from(
        "row,column,metric,n,mean,ci_lo,ci_hi,diff_vs_reference,diff_ci_lo,diff_ci_hi,\
         n_seeds,n_scenes,seeds_positive,diff_n_seeds,diff_t_lo,diff_t_hi,diff_t_p,\
         diff_wilcoxon_p,diff_tost_margin,diff_tost_p,n_pretrain_seeds\n",
    );
    let mut seeds_csv = String::from("row,column,seed,metric,n_scenes,mean,diff_vs_reference\n");
    let mut entries = Vec::new();
    let mut cell_text = CellTexts::new();
    for d in &done {
        for (mi, (metric, _)) in TABLE_METRICS.iter().enumerate() {
            let Some(m) = metric_stats(cfg, d, metric, ref_scores, &scenes) else {
                // A metric no set of this cell has (PSNR-T dark without under-exposed pixels,
                // or a per_image.csv older than the metric): no row, "–" in the Markdown.
                cell_text.insert((mi, d.r, d.c), ("–".into(), "–".into()));
                continue;
            };
            entries.push(m.entry(cfg, d));
            m.write_csv(cfg, d, &mut csv, &mut seeds_csv);
            cell_text.insert((mi, d.r, d.c), m.texts(cfg));
        }
    }

    let mut md = table_intro(
        cfg,
        t,
        set_names.len(),
        n_scenes,
        &ref_label,
        runs_done,
        runs_total,
    );
    table_body(&mut md, cfg, &cell_text, reference.0, &ref_label);
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

/// Row `row` of the grid (one column) against row `versus` on test set `t` (the primary or one
/// of `also`): each metric's [`TableEntry`], its `diff` the paired difference row − versus
/// (within seed, scene and set), as the table computes its differences to the reference.
/// Empty until both rows have finished runs.
/// Row `row` against `versus` in PSNR-T on test set `t`, paired as [`paired_rows`] pairs; None
/// where either row has no scores.
pub fn paired_psnr_t(
    cfg: &AblateConfig,
    t: &TestsetSpec,
    row: &str,
    versus: &str,
) -> Result<Option<DiffEntry>> {
    Ok(paired_rows(cfg, t, row, versus)?
        .into_iter()
        .find(|e| e.metric == "psnr_t")
        .and_then(|e| e.diff))
}

pub fn paired_rows(
    cfg: &AblateConfig,
    t: &TestsetSpec,
    row: &str,
    versus: &str,
) -> Result<Vec<TableEntry>> {
    let (done, _, _) = load_cells(cfg, t)?;
    let find = |name: &str| {
        done.iter()
            .find(|d| d.c.is_none() && cfg.rows[d.r].name == name)
    };
    let (Some(d), Some(v)) = (find(row), find(versus)) else {
        return Ok(Vec::new());
    };
    let set_names: std::collections::BTreeSet<&str> = done
        .iter()
        .flat_map(|d| d.runs.iter().flat_map(|(_, sets)| sets.keys()))
        .map(String::as_str)
        .collect();
    let scenes = testset::scenes_of_sets(&t.dir_for(cfg.seeds.first().copied()), set_names)?;
    Ok(TABLE_METRICS
        .iter()
        .filter_map(|(metric, _)| metric_stats(cfg, d, metric, Some(v), &scenes))
        .map(|m| m.entry(cfg, d))
        .collect())
}

/// A row's runs: each run's seed (`None`: a run that serves every seed) and one metric per set.
pub type RunScores = Vec<(Option<u64>, BTreeMap<String, f64>)>;

/// Each finished run of row `row` (no column) on test set `t`: its seed (`None`: a run that
/// serves every seed) and `metric` per set. Empty where the row has no finished run.
pub fn run_scores(
    cfg: &AblateConfig,
    t: &TestsetSpec,
    row: &str,
    metric: &str,
) -> Result<RunScores> {
    let k = metric_index(metric);
    let (done, _, _) = load_cells(cfg, t)?;
    Ok(done
        .into_iter()
        .find(|d| d.c.is_none() && cfg.rows[d.r].name == row)
        .map(|d| {
            d.runs
                .into_iter()
                .map(|(seed, sets)| (seed, sets.into_iter().map(|(n, v)| (n, v[k])).collect()))
                .collect()
        })
        .unwrap_or_default())
}

/// The finished runs of every cell on test set `t` (their `per_image.csv`), and how many of
/// the grid's runs are finished out of how many.
fn load_cells(cfg: &AblateConfig, t: &TestsetSpec) -> Result<(Vec<CellScores>, usize, usize)> {
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
    Ok((done, runs_done, runs_total))
}

/// One metric of one cell: its statistic, its paired difference to the reference cell (none
/// for the reference itself or without a finished reference) and that difference's tests.
struct MetricStats {
    metric: &'static str,
    st: Stat,
    diff: Option<Stat>,
    tests: Option<Tests>,
    margin: f64,
}

/// [`MetricStats`] of `metric` in cell `d`; None where no set of the cell has the metric.
fn metric_stats(
    cfg: &AblateConfig,
    d: &CellScores,
    metric: &'static str,
    ref_scores: Option<&CellScores>,
    scenes: &BTreeMap<String, String>,
) -> Option<MetricStats> {
    let k = metric_index(metric);
    let rows: Vec<(Option<u64>, BTreeMap<&str, f64>)> = d
        .runs
        .iter()
        .map(|(s, sets)| (*s, sets.iter().map(|(n, v)| (n.as_str(), v[k])).collect()))
        .collect();
    let st = crossed_stat(cfg, &rows, scenes);
    if st.n_scenes == 0 {
        return None;
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
            crossed_stat(cfg, &rows, scenes)
        });
    let margin = cfg.eval.margin(metric);
    let tests = diff.as_ref().and_then(|x| x.tests(cfg.eval.level, margin));
    Some(MetricStats {
        metric,
        st,
        diff,
        tests,
        margin,
    })
}

impl MetricStats {
    /// The typed entry of [`Table::entries`].
    fn entry(&self, cfg: &AblateConfig, d: &CellScores) -> TableEntry {
        let (st, tests) = (&self.st, &self.tests);
        TableEntry {
            row: cfg.rows[d.r].name.clone(),
            column: d.c.map(|c| cfg.columns[c].name.clone()),
            metric: self.metric,
            mean: st.mean,
            n_scenes: st.n_scenes,
            n_seeds: st.n_seeds,
            diff: self.diff.as_ref().map(|x| DiffEntry {
                mean: x.mean,
                per_seed: x.per_seed.clone(),
                sign_holds: x.sign_holds(),
                n_seeds: x.n_seeds,
                t: tests.as_ref().map(|ts| ts.t),
                seed_t: {
                    let v: Vec<f64> = x.per_seed.iter().map(|(_, v)| *v).collect();
                    stats::paired_t(&v, cfg.eval.level)
                },
                wilcoxon_p: tests
                    .as_ref()
                    .and_then(|ts| ts.wilcoxon.as_ref().map(|w| w.p)),
                margin: self.margin,
                tost_p: tests.as_ref().and_then(|ts| ts.tost.as_ref().map(|w| w.p)),
            }),
        }
    }

    /// Its `table.csv` row, and with `seeds` its `table_seeds.csv` rows.
    fn write_csv(
        &self,
        cfg: &AblateConfig,
        d: &CellScores,
        csv: &mut String,
        seeds_csv: &mut String,
    ) {
        let (metric, st, diff, tests) = (self.metric, &self.st, &self.diff, &self.tests);
        let row_name = report::csv_field(&cfg.rows[d.r].name);
        let col_name = report::csv_field(d.c.map(|c| cfg.columns[c].name.as_str()).unwrap_or(""));
        let opt = |f: &dyn Fn(&Stat) -> String| diff.as_ref().map(f).unwrap_or_default();
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
        // Every seed's number; a run that serves every seed is repeated for each.
        for &seed in &cfg.seeds {
            let at = |x: &Stat| {
                x.per_seed
                    .iter()
                    .find(|(s, _)| s.is_none() || *s == Some(seed))
                    .map(|(_, v)| *v)
            };
            let Some(v) = at(st) else { continue };
            let dv = diff.as_ref().and_then(at);
            let _ = writeln!(
                seeds_csv,
                "{row_name},{col_name},{seed},{metric},{},{v},{}",
                st.n_scenes,
                dv.map(|x| x.to_string()).unwrap_or_default()
            );
        }
    }

    /// The Markdown texts: "mean [lo, hi]" and the paired difference with its tests.
    fn texts(&self, cfg: &AblateConfig) -> (String, String) {
        let (metric, st) = (self.metric, &self.st);
        let seeded = !cfg.seeds.is_empty();
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
        let diff_text = match (&self.diff, &self.tests) {
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
        (mean_text, diff_text)
    }
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
