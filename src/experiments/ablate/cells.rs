//! Running the grid: each cell's plan (its training config over the base), training and
//! evaluation, resumable; and the run's summary.

use super::*;

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
pub(super) const EVAL_DIR: &str = "eval";

/// Run every unfinished cell of `cfg`, then write the table. `config_path` names the config in
/// errors.
pub fn run(cfg: &AblateConfig, config_path: &Path, progress: bool) -> Result<AblateSummary> {
    run_with(cfg, config_path, progress, &|_| Ok(()))
}

/// [`run`], where `pretrain(seed)` makes `pretrained_per_seed`'s network of that seed: called
/// on the grid's workers before the first of that seed's cells that read it (once per seed;
/// its other cells wait for it), so that pretrainings share the cores with the cells of the
/// seeds already pretrained.
pub fn run_with(
    cfg: &AblateConfig,
    config_path: &Path,
    progress: bool,
    pretrain: &(dyn Fn(u64) -> Result<()> + Sync),
) -> Result<AblateSummary> {
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
    let mut units = Vec::new();
    for (k, &(r, c)) in cells.iter().enumerate() {
        for seed in cfg.cell_seeds(r, c) {
            let id = match seed {
                None => cfg.cell_id(r, c),
                Some(s) => format!("{}/seed{s}", cfg.cell_id(r, c)),
            };
            let label = format!("cell {}/{} {id}", k + 1, cells.len());
            units.push(Unit {
                label,
                id,
                dir: cfg.unit_dir(r, c, seed),
                at: (r, c, seed),
            });
        }
    }
    // Planned before any runs: a cell that cannot be planned stops the grid first. The table
    // is rewritten after each run, by one writer at a time: an interrupted grid shows what it
    // has.
    let plans = units
        .iter()
        .map(|u| plan_cell(cfg, config_path, &base, u.at.0, u.at.1, u.at.2))
        .collect::<Result<Vec<_>>>()?;
    let table = std::sync::Mutex::new(());
    // Per seed: whether its pretraining is done. A seed's lock is held while it pretrains.
    let pretrained: Vec<std::sync::Mutex<bool>> =
        cfg.seeds.iter().map(|_| Default::default()).collect();
    let results = crate::experiments::at_once(cfg.jobs, &units, |i, u| {
        if let (Some(k), Some(_), None) = (u.at.2, &cfg.pretrained_per_seed, plans[i].baseline)
            && let Some(at) = cfg.seeds.iter().position(|&s| s == k)
        {
            let mut done = pretrained[at].lock().unwrap_or_else(|e| e.into_inner());
            if !*done {
                pretrain(k)?;
                *done = true;
            }
        }
        let r = run_unit(cfg, u, &plans[i], progress, cfg.jobs > 1)?;
        let _one_writer = table.lock().unwrap_or_else(|e| e.into_inner());
        write_table(cfg)?;
        Ok(r)
    })?;
    let table = write_table(cfg)?;
    Ok(AblateSummary {
        cells: results,
        table,
        seconds: began.elapsed().as_secs_f64(),
    })
}

/// One run of a cell: its seed's folder, named for the progress lines.
struct Unit {
    label: String,
    id: String,
    dir: PathBuf,
    at: (usize, Option<usize>, Option<u64>),
}

/// Runs one unit; `quiet` leaves out its progress bars (several run at once) and says when it
/// is done instead.
fn run_unit(
    cfg: &AblateConfig,
    u: &Unit,
    plan: &CellPlan,
    progress: bool,
    quiet: bool,
) -> Result<CellResult> {
    let t0 = Instant::now();
    if progress {
        eprintln!("{}", u.label);
    }
    let status = run_cell(cfg, &u.dir, &u.id, plan, progress && !quiet)?;
    let seconds = t0.elapsed().as_secs_f64();
    if progress && quiet {
        eprintln!("{}: done in {seconds:.0} s", u.label);
    }
    Ok(CellResult {
        id: u.id.clone(),
        status,
        seconds,
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
            toml::Value::String(path.replace(SEED_FIELD, &k.to_string())),
        );
    }
    let mut merged = if axes.iter().any(|a| a.kind == AxisKind::Control) {
        control_config(&cfg.base, &base).map_err(Error::within(format!(
            "{}: cell '{id}': control",
            config_path.display()
        )))?
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
        (Some(p), _) => Some(match seed {
            Some(k) => PathBuf::from(p.to_string_lossy().replace(SEED_FIELD, &k.to_string())),
            None => (*p).clone(),
        }),
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

/// The network row `row`'s run of `seed` scores (its checkpoint folder; `None` for a classical
/// row).
pub fn run_checkpoint(
    cfg: &AblateConfig,
    config_path: &Path,
    row: &str,
    seed: Option<u64>,
) -> Result<Option<PathBuf>> {
    let r = cfg
        .rows
        .iter()
        .position(|a| a.name == row)
        .ok_or_else(|| Error::config(config_path, format!("no row '{row}'")))?;
    Ok(plan_cell(cfg, config_path, &load_base(cfg)?, r, None, seed)?.checkpoint)
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
    // Recorded with the exposure rule the cell trains with (as a run records its config): a
    // profile whose measured rule changed is another cell. Trained as written, so the run
    // says where its rule came from.
    let recorded = CellPlan {
        train: plan
            .train
            .as_ref()
            .map(TrainConfig::with_resolved_metering)
            .transpose()?,
        ..plan.clone()
    };
    let plan_text = toml::to_string(&recorded).map_err(|e| Error::encode(&plan_path, e))?;
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
    // (test set folder, eval folder, a validation set) of the sets not scored yet.
    let pending: Vec<(&Path, String, bool)> = std::iter::once(&plan.testset)
        .chain(&plan.also)
        .zip(cfg.testsets())
        .map(|(t, spec)| (t.as_path(), spec.eval_dir(), spec.validation))
        .filter(|(_, e, _)| !dir.join(e).join(evaluate::SUMMARY_CSV).is_file())
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
    let network = cell_network(cfg, id, plan, progress)?;
    let opts = EvalOptions {
        resamples: cfg.eval.resamples,
        seed: cfg.eval.seed,
        level: cfg.eval.level,
        progress,
        ..EvalOptions::default()
    };
    for (testset, eval_dir, validation) in pending {
        // Scored into a partial folder, renamed when complete: a killed evaluation reruns.
        let partial = dir.join(format!("{eval_dir}.partial"));
        if partial.exists() {
            std::fs::remove_dir_all(&partial).map_err(|e| Error::io(&partial, e))?;
        }
        let built;
        let method = match (&network, plan.baseline) {
            (Some(m), _) => m.as_ref(),
            (None, Some(b)) => {
                built = b.method(testset)?;
                built.as_ref()
            }
            (None, None) => {
                return Err(Error::Invalid(format!(
                    "cell '{id}' has neither a checkpoint nor a baseline"
                )));
            }
        };
        let opts = EvalOptions {
            validation,
            ..opts.clone()
        };
        evaluate::evaluate(testset, method, &partial, &opts)?;
        let done = dir.join(&eval_dir);
        std::fs::rename(&partial, &done).map_err(|e| Error::io(&done, e))?;
    }
    Ok(CellStatus::Ran { resumed_at })
}

/// The network a cell scores, loaded once (None for a baseline, which is built per test set: a
/// classical merge reads the set's curve).
fn cell_network(
    cfg: &AblateConfig,
    id: &str,
    plan: &CellPlan,
    progress: bool,
) -> Result<Option<Box<dyn evaluate::Method>>> {
    match (&plan.checkpoint, plan.baseline) {
        (_, Some(_)) => Ok(None),
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
            Ok(Some(from_checkpoint(ckpt, &net, &device)?))
        }
        (None, None) => Err(Error::Invalid(format!(
            "cell '{id}' has neither a checkpoint nor a baseline"
        ))),
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
