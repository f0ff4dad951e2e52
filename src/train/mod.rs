//! The one trainer. A [`task::Task`] says how to build a network and score a batch; [`run`]
//! does the rest for either network: data stream, Adam with a step-pure LR schedule,
//! validation, JSONL log, atomic checkpoints, resume, NaN stop. docs/training.md documents the
//! config and the run folder.
//!
//! Burn 0.22: train on an autodiff device (`device.clone().autodiff()`); `loss.backward()`
//! gives `Gradients`, `GradientsParams::from_grads` ties them to the module's parameters, and
//! `ModuleOptimizer::step` returns the updated module. Validation uses `model.valid()` (no
//! autodiff; BatchNorm on running statistics) with inputs on the plain device.

pub mod budget;
pub mod checkpoint;
pub mod config;
mod log;
#[cfg(feature = "flex")]
pub mod loss;
pub mod task;

use crate::data::ground_truth::{CLASSES, ClassWeights, MertensWeights, class_histogram};
use crate::data::loader::{Loader, LoaderConfig, Sample, Target};
use crate::device::device_from_name;
use crate::error::{Error, Result};
use crate::io::atomic::write_atomic;
use crate::models::{BlendUNet, ModelConfig, seeded_init};
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsAccumulator, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Int, Tensor};
use checkpoint::CheckpointState;
use config::TrainConfig;
use log::{Log, LogLine, Number, Scores};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;
use task::{CHECKPOINT_ALPHA_FILE, Network1, Network2, Task};

/// One bare Network-1 optimisation step: forward, softmax, paper Eq. 4 as written
/// ([`loss::network1_loss`], literal reading), backward, optimiser update. `input`, `target`
/// and `alpha` must be on the model's (autodiff) device. Returns the updated model and the step's loss (detached, before the
/// update). For use outside the trainer (docs/network1.md); the trainer and the step benchmark
/// run [`train_step`], which reads the loss as `[loss] reading` says ([`Task::loss`]) and skips
/// the update on a non-finite loss.
pub fn network1_step(
    model: BlendUNet,
    optim: &mut ModuleOptimizer,
    lr: f64,
    input: Tensor<4>,
    target: Tensor<3, Int>,
    alpha: Tensor<1>,
) -> (BlendUNet, Tensor<1>) {
    let loss = loss::network1_loss(
        loss::Network1Reading::Literal,
        model.forward(input),
        target,
        alpha,
        0.0,
    );
    let grads = GradientsParams::from_grads(loss.backward(), &model);
    let model = optim.step(lr, model, grads);
    (model, loss.detach())
}

/// One optimisation step of any task: loss of `batch`, then — only if the loss is finite —
/// backward and the optimizer update. Returns the model (unchanged when the loss is not
/// finite) and the loss.
pub fn train_step<T: Task>(
    task: &T,
    model: T::Model,
    optim: &mut ModuleOptimizer,
    lr: f64,
    batch: &[Sample],
    device: &Device,
) -> Result<(T::Model, f64)> {
    let loss = task.loss(&model, batch, device)?;
    let value = loss.clone().into_scalar::<f32>() as f64;
    if !value.is_finite() {
        return Ok((model, value));
    }
    let grads = GradientsParams::from_grads(loss.backward(), &model);
    Ok((optim.step(lr, model, grads), value))
}

/// One data-parallel optimisation step over `devices` (autodiff devices; the model lives on the
/// first): [`parallel_gradients`], then one optimiser step on the first device. Equals
/// [`train_step`] on the combined batch for a network without batch statistics; BatchNorm
/// normalises per shard (as PyTorch's DDP without SyncBatchNorm) and its running statistics
/// come from the first device's shard. One device: exactly [`train_step`].
pub fn train_step_parallel<T: Task + Sync>(
    task: &T,
    model: T::Model,
    optim: &mut ModuleOptimizer,
    lr: f64,
    batch: &[Sample],
    devices: &[Device],
) -> Result<(T::Model, f64)> {
    if let [device] = devices {
        return train_step(task, model, optim, lr, batch, device);
    }
    let (grads, value) = parallel_gradients(task, &model, batch, devices)?;
    if !value.is_finite() {
        return Ok((model, value));
    }
    Ok((optim.step(lr, model, grads), value))
}

/// The gradients of the batch's mean loss, computed data-parallel: the batch is split into one
/// contiguous shard per device, each device computes its shard's loss weighted by the shard's
/// share of the batch on its own replica (Burn's `Module::fork`), concurrently; the gradients
/// are moved to the first device and summed in device order (Burn's `GradientsAccumulator`),
/// so the result is deterministic. Burn 0.22's collective all-reduce
/// (`burn::tensor::distributed`) exists only for CUDA devices (flex and ndarray are not
/// collective backends), so this gathers instead; docs/training.md. Returns the gradients
/// and the batch's loss.
pub fn parallel_gradients<T: Task + Sync>(
    task: &T,
    model: &T::Model,
    batch: &[Sample],
    devices: &[Device],
) -> Result<(GradientsParams, f64)> {
    let n = devices.len();
    let Some(main) = devices.first() else {
        return Err(Error::Invalid("data-parallel training: no device".into()));
    };
    if batch.len() < n {
        return Err(Error::Invalid(format!(
            "a batch of {} cannot be split over {n} devices: batch_size must be ≥ the number of \
             devices",
            batch.len()
        )));
    }
    // Contiguous shards, the first `batch.len() % n` one sample larger.
    let (q, r) = (batch.len() / n, batch.len() % n);
    let mut shards = Vec::with_capacity(n);
    let mut at = 0;
    for i in 0..n {
        let len = q + usize::from(i < r);
        shards.push(&batch[at..at + len]);
        at += len;
    }
    let total = batch.len() as f64;
    let results: Vec<Result<(GradientsParams, f64)>> = std::thread::scope(|scope| {
        let handles: Vec<_> = devices
            .iter()
            .zip(&shards)
            .map(|(device, shard)| {
                let replica = model.clone().fork(device);
                scope.spawn(move || -> Result<(GradientsParams, f64)> {
                    let share = shard.len() as f64 / total;
                    let loss = task.loss(&replica, shard, device)?.mul_scalar(share);
                    let value = loss.clone().into_scalar::<f32>() as f64;
                    let grads = GradientsParams::from_grads(loss.backward(), &replica);
                    Ok((grads, value))
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect()
    });
    let mut accumulator = GradientsAccumulator::<T::Model>::new();
    let mut value = 0.0;
    for result in results {
        let (grads, v) = result?;
        value += v;
        accumulator.accumulate(model, grads.to_device(main, model));
    }
    Ok((accumulator.grads(), value))
}

#[derive(Clone, Debug, Default)]
pub struct TrainOptions {
    /// Continue the run in `run.out` from its latest checkpoint.
    pub resume: bool,
    /// Draw a progress bar on stderr.
    pub progress: bool,
}

#[derive(Clone, Debug)]
pub struct TrainSummary {
    pub run: PathBuf,
    /// Step the run started from (0, or the resumed checkpoint's).
    pub start_step: u64,
    pub steps: u64,
    /// Mean loss of the first and the last logged intervals of this invocation.
    pub first_loss: f64,
    pub last_loss: f64,
    pub checkpoint: PathBuf,
    pub samples_per_s: f64,
    /// The last validation scores, if validation ran.
    pub validation: Vec<(String, f64)>,
    /// `--resume` found the run already at `run.steps`: nothing was trained.
    pub already_finished: bool,
}

/// The resolved config of a run, written as `RUN/config.toml`.
pub const RUN_CONFIG: &str = "config.toml";
/// The metrics log, one JSON object per line.
pub const LOG_FILE: &str = "log.jsonl";
/// One line: what the training frames were made from (`Loader::describe_source`).
pub const DATA_SOURCE_FILE: &str = "data_source.txt";

/// Train as configured. Errors name what is wrong; a non-finite loss stops the run with the
/// last good checkpoint in place.
pub fn run(cfg: &TrainConfig, opts: &TrainOptions) -> Result<TrainSummary> {
    cfg.validate()?;
    budget::check_config(cfg)?;
    let kind = cfg.model.sample_kind();
    // The loader resolves the exposure rule itself, so `data_source.txt` says where it came
    // from; the run's recorded config holds the rule's values.
    let cfg = &cfg.with_resolved_model()?;
    let mut loader = Loader::new(&cfg.loader(kind)?)?;
    if let Some((lc, fraction)) = cfg.mix_loader(kind)? {
        loader = loader.mixed(Loader::new(&lc)?, fraction);
    }
    let loader = Arc::new(loader);
    let cfg = &cfg.with_resolved_metering()?;
    match &cfg.model {
        ModelConfig::BlendUnet(m) => {
            let alpha = network1_alpha(cfg, opts, &loader)?;
            let task = Network1 {
                config: m.clone(),
                alpha,
                reading: cfg.loss.reading,
                label_sigma: cfg.loss.label_sigma,
            };
            train(&task, cfg, opts, loader)
        }
        ModelConfig::Wu(m) => {
            let task = Network2::new(m.clone(), &cfg.loss);
            train(&task, cfg, opts, loader)
        }
    }
}

/// Network-1's α as `loss.alpha` asks (see `config::LossConfig`); on resume, the checkpoint's.
fn network1_alpha(cfg: &TrainConfig, opts: &TrainOptions, loader: &Loader) -> Result<ClassWeights> {
    let from_checkpoint = |dir: &Path| {
        let text = checkpoint::read_verified_text(dir, CHECKPOINT_ALPHA_FILE)?;
        ClassWeights::parse(&text, &dir.join(CHECKPOINT_ALPHA_FILE))
    };
    // The checkpoint `train` resumes from: the newest complete one (it reports the choice).
    if opts.resume
        && let (Some(dir), _) = checkpoint::newest_complete(&cfg.run.out)?
    {
        return from_checkpoint(&dir);
    }
    match cfg.loss.alpha.as_str() {
        "stream" => {
            let n = cfg.loss.alpha_samples.max(1);
            let samples: Vec<Sample> = (0..n)
                .map(|g| loader.stream_sample(g))
                .collect::<Result<_>>()?;
            let hist = class_histogram(samples.iter().map(|s| match &s.target {
                Target::Classes(c) => c.as_slice(),
                Target::Hdr(_) => &[],
            }));
            Ok(ClassWeights::new(
                &hist,
                MertensWeights::OPENCV_DEFAULT,
                loader.len(),
            ))
        }
        "uniform" => Ok(ClassWeights::new(
            &[1; CLASSES],
            MertensWeights::OPENCV_DEFAULT,
            0,
        )),
        "checkpoint" => {
            let init = cfg
                .init
                .as_ref()
                .and_then(|i| i.checkpoint.as_ref())
                .ok_or_else(|| {
                    Error::key("loss.alpha", "\"checkpoint\" needs an [init] checkpoint")
                })?;
            from_checkpoint(&checkpoint::resolve(init)?)
        }
        path => ClassWeights::load(Path::new(path)),
    }
}

/// The resolved config as TOML with `run.steps` blanked: what must not change on resume.
fn identity_of(cfg: &TrainConfig) -> Result<String> {
    let mut c = cfg.clone();
    c.run.steps = 0;
    toml::to_string(&c).map_err(|e| Error::encode(RUN_CONFIG, e))
}

/// The identity of the config a run folder records (a whole config, which `hdrsynth train
/// --config` takes again; folders written with `run.steps` blanked read the same).
fn recorded_identity(run: &Path) -> Result<String> {
    let path = run.join(RUN_CONFIG);
    let saved: TrainConfig = crate::config::load_toml(&path)?;
    identity_of(&saved)
}

/// The trainer shared by both networks: the run folder, then `start_or_resume`, the
/// `validation_set`, and `train_loop`.
pub fn train<T: Task + Sync>(
    task: &T,
    cfg: &TrainConfig,
    opts: &TrainOptions,
    loader: Arc<Loader>,
) -> Result<TrainSummary> {
    let run = &cfg.run.out;
    // One trainer per run folder: a second would interleave checkpoints with this one's.
    let _lock = crate::io::guard::OutputLock::acquire(run, "train")?;
    std::fs::create_dir_all(run).map_err(|e| Error::io(run, e))?;
    // Under the lock, anything half-written in the run folder is a killed run's.
    let cleaned = checkpoint::clean_leftovers(run)?;
    if cleaned > 0 && opts.progress {
        eprintln!(
            "removed {cleaned} leftover(s) of an interrupted run in {}",
            run.display()
        );
    }
    // Everything that can refuse the run comes before the first write into the run folder, so
    // a refused run leaves the folder as it was (a folder the lock created is removed again).
    let devices: Vec<Device> = if cfg.run.devices.is_empty() {
        vec![device_from_name(&cfg.run.backend)?.autodiff()]
    } else {
        cfg.run
            .devices
            .iter()
            .map(|d| Ok(device_from_name(d)?.autodiff()))
            .collect::<Result<_>>()?
    };
    if opts.progress
        && let Some(adapter) = crate::device::wgpu_adapter()
    {
        eprintln!("wgpu adapter: {adapter}");
    }
    let existing = checkpoint::resume_point(run, opts.resume)?;
    let (model, optim, start) =
        start_or_resume(task, cfg, opts.resume, &devices[0], existing.as_deref())?;
    if start >= cfg.run.steps {
        // Only a resumed run gets here (a new one starts at 0 < steps): it is finished, which
        // is success, not an error; raising run.steps continues it.
        return Ok(TrainSummary {
            run: run.clone(),
            start_step: start,
            steps: start,
            first_loss: f64::NAN,
            last_loss: f64::NAN,
            checkpoint: existing.unwrap_or_default(),
            samples_per_s: 0.0,
            validation: Vec::new(),
            already_finished: true,
        });
    }
    let validation = validation_set(task, cfg, &loader)?;
    if !opts.resume {
        let text = toml::to_string(cfg).map_err(|e| Error::encode(RUN_CONFIG, e))?;
        write_atomic(&run.join(RUN_CONFIG), text.as_bytes())?;
    }
    // Which frames the run trains on (pure, linear EXRs, display frames) for whoever reads it.
    let source = loader.describe_source();
    write_atomic(
        &run.join(DATA_SOURCE_FILE),
        format!("{source}\n").as_bytes(),
    )?;
    if opts.progress {
        eprintln!("training data: {source}");
    }
    let log = Log::open(run, opts.resume.then_some(start))?;
    let session = Session {
        task,
        cfg,
        loader: &loader,
        devices,
        log,
        validation,
        progress: opts.progress,
    };
    train_loop(session, model, optim, start, existing)
}

/// The model, the optimizer and the first step: from the latest checkpoint on `resume`, else
/// freshly initialised (seeded, then `[init]` weights; the caller writes the run's config).
fn start_or_resume<T: Task>(
    task: &T,
    cfg: &TrainConfig,
    resume: bool,
    device: &Device,
    existing: Option<&Path>,
) -> Result<(T::Model, ModuleOptimizer, u64)> {
    let run = &cfg.run.out;
    let identity = identity_of(cfg)?;
    let optim = optimizer(&cfg.optim);
    match (existing, resume) {
        (Some(dir), true) => {
            let saved = recorded_identity(run)?;
            if saved != identity {
                let keys = crate::config::differing_keys(&saved, &identity).join("; ");
                let msg = format!(
                    "the run was started with a different config ({keys}; only run.steps may \
                     change on resume); start a new run folder instead"
                );
                return Err(Error::config(run.join(RUN_CONFIG), msg));
            }
            let state = checkpoint::read_state(dir)?;
            if state.model != task.model_config() {
                return Err(Error::config(
                    dir.join(checkpoint::STATE_FILE),
                    "checkpoint holds a different model",
                ));
            }
            let model = checkpoint::load_model(task.init(device)?, dir)?;
            let optim = checkpoint::load_optimizer(optim, dir)?;
            Ok((model, optim, state.step))
        }
        (None, true) => Err(Error::layout(
            run,
            "--resume: the run has no checkpoint yet",
        )),
        (Some(dir), false) => Err(Error::layout(
            run,
            format!(
                "the run folder already holds checkpoints ({}{}): pass --resume to continue \
                 it, or set run.out to a new folder",
                dir.display(),
                checkpoint::incomplete(dir)
                    .map(|why| format!(", incomplete: {why}"))
                    .unwrap_or_default()
            ),
        )),
        (None, false) => Ok((initial_model(task, cfg, device)?, optim, 0)),
    }
}

/// Adam as `[optim]` configures it (the trainer's optimiser, fresh).
pub fn optimizer(cfg: &config::OptimConfig) -> ModuleOptimizer {
    AdamConfig::new()
        .with_beta_1(cfg.beta1)
        .with_beta_2(cfg.beta2)
        .with_epsilon(cfg.epsilon)
        .with_weight_decay(
            (cfg.weight_decay > 0.0)
                .then(|| burn::optim::decay::WeightDecayConfig::new(cfg.weight_decay)),
        )
        .init()
}

/// A new run's model: seeded initialisation, then `[init]`'s SafeTensors weights and/or
/// checkpoint (another run's, holding the same model).
pub fn initial_model<T: Task>(task: &T, cfg: &TrainConfig, device: &Device) -> Result<T::Model> {
    let run = &cfg.run.out;
    let mut model = seeded_init(device, cfg.run.seed, || task.init(device))?;
    if let Some(path) = cfg.init.as_ref().and_then(|i| i.safetensors.as_ref()) {
        model = crate::models::import::import_weights(model, path)?;
    }
    if let Some(init) = cfg.init.as_ref().and_then(|i| i.checkpoint.as_ref()) {
        let own = crate::io::guard::resolve(run)?;
        if crate::io::guard::resolve(init)?.starts_with(&own) {
            return Err(Error::key(
                "init.checkpoint",
                format!(
                    "{} lies in this run's own output folder (run.out = {}): fine-tuning \
                     starts from another run's checkpoint",
                    init.display(),
                    run.display()
                ),
            ));
        }
        let dir = checkpoint::resolve(init)?;
        let state = checkpoint::read_state(&dir)?;
        if !state.model.same_layers(&task.model_config()) {
            return Err(Error::config(
                dir.join(checkpoint::STATE_FILE),
                format!(
                    "init checkpoint holds {:?}, the config asks for {:?}",
                    state.model,
                    task.model_config()
                ),
            ));
        }
        model = checkpoint::load_model(model, &dir)?;
    }
    Ok(model)
}

/// The fixed held-out samples scored every `every` steps, and the task's baseline scores on
/// them (logged beside the model's).
struct ValidationSet {
    every: u64,
    samples: Vec<Sample>,
    baseline: Vec<(String, f64)>,
}

/// The `[validation]` samples: the training data's loader config on the validation dataset,
/// without augmentation, at the validation patch and target smoothing, seeded by `run.seed`
/// (not the stream's seed), so a pretraining and its fine-tuning score the same samples.
fn validation_set<T: Task>(
    task: &T,
    cfg: &TrainConfig,
    loader: &Loader,
) -> Result<Option<ValidationSet>> {
    let Some(v) = &cfg.validation else {
        return Ok(None);
    };
    let mut lc: LoaderConfig = cfg.loader(loader.config().kind)?;
    lc.seed = cfg.run.seed;
    lc.dataset = v.dataset.clone();
    lc.augment = false;
    lc.patch = v.patch.unwrap_or(cfg.data.patch);
    // The configured targets (default: per-pixel maps), not the training smoothing.
    lc.target_sigma = v.target_sigma;
    // Network-1 is always scored against the noise-free render's weights: what it should
    // predict, whichever frames its training targets came from.
    lc.target_frames = crate::data::loader::TargetFrames::Clean;
    let l = Loader::new(&lc)?;
    let n = v.samples.min(l.len()) as u64;
    let samples: Vec<Sample> = (0..n).map(|g| l.stream_sample(g)).collect::<Result<_>>()?;
    let baseline = task
        .validation_baseline(&samples)?
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
    Ok(Some(ValidationSet {
        every: v.every,
        samples,
        baseline,
    }))
}

/// What the loop runs with besides the model and the optimizer.
struct Session<'a, T> {
    task: &'a T,
    cfg: &'a TrainConfig,
    loader: &'a Arc<Loader>,
    /// Autodiff devices; the model lives on the first.
    devices: Vec<Device>,
    log: Log,
    validation: Option<ValidationSet>,
    progress: bool,
}

/// Steps `start..run.steps`: train, log every `log_every`, validate, checkpoint; stop at a
/// non-finite loss with the last good checkpoint in place.
fn train_loop<T: Task + Sync>(
    s: Session<T>,
    mut model: T::Model,
    mut optim: ModuleOptimizer,
    start: u64,
    existing: Option<PathBuf>,
) -> Result<TrainSummary> {
    let Session {
        task,
        cfg,
        loader,
        devices,
        mut log,
        validation,
        progress,
    } = s;
    let run = &cfg.run.out;
    let device = devices[0].clone().without_autodiff();
    let bs = cfg.data.batch_size as u64;
    let total = cfg.run.steps;
    let bar = progress_bar(progress, start, total);
    let mut batches = loader.range(start * bs, total * bs);
    let mut interval = Interval::new(bs);
    let mut last_checkpoint = existing;
    let mut last_validation = Vec::new();
    let began = Instant::now();
    let state_at = |step: u64, loss: Option<f64>| CheckpointState {
        format: checkpoint::FORMAT.into(),
        step,
        samples: step * bs,
        epoch: step * bs / loader.len() as u64,
        rng_seed: cfg.run.seed,
        loss,
        model: task.model_config(),
    };

    let validate_and_log =
        |log: &mut Log, model: &T::Model, done: u64| -> Result<Vec<(String, f64)>> {
            let Some(v) = &validation else {
                return Ok(Vec::new());
            };
            let mut scores = validate(task, model, &v.samples, bs as usize, &device)?;
            scores.extend(v.baseline.iter().cloned());
            log.write(&LogLine::Validation {
                step: done,
                validation: Scores(&scores),
            })?;
            Ok(scores)
        };
    // The untrained (or freshly initialised-from) model's scores: the baseline of the run.
    if start == 0 {
        validate_and_log(&mut log, &model, 0)?;
    }

    for step in start..total {
        let batch = batches
            .next()
            .ok_or_else(|| Error::Invalid("data stream ended early".into()))??;
        let lr = cfg.schedule.lr(cfg.optim.lr, step, total);
        let (next, value) = train_step_parallel(task, model, &mut optim, lr, &batch, &devices)?;
        model = next;
        if !value.is_finite() {
            let last = last_checkpoint.as_deref();
            return Err(stop_non_finite(&mut log, &bar, step, value, None, lr, last));
        }
        interval.add(value);
        let done = step + 1;
        bar.set_position(done);

        if done % cfg.run.log_every == 0 || done == total {
            let epoch = (done * bs) as f64 / loader.len() as f64;
            interval.close(&mut log, &bar, done, epoch, lr, began)?;
        }
        if let Some(v) = &validation
            && (done % v.every == 0 || done == total)
        {
            last_validation = validate_and_log(&mut log, &model, done)?;
        }
        if done % cfg.run.checkpoint_every == 0 || done == total {
            // A step can leave NaN weights behind a finite loss (the loss is taken before the
            // update): such a checkpoint is never written, so the one named below is usable.
            if let Some(name) = checkpoint::non_finite_parameter(&model) {
                let last = last_checkpoint.as_deref();
                let what = Some(name.as_str());
                return Err(stop_non_finite(&mut log, &bar, step, value, what, lr, last));
            }
            let dir = checkpoint::save(
                run,
                &state_at(done, Some(interval.last_mean).filter(|l| l.is_finite())),
                &model,
                Some(&optim),
                cfg.run.keep_checkpoints,
                |d| task.save_extra(d),
            )?;
            last_checkpoint = Some(dir);
        }
    }
    bar.finish();
    let secs = began.elapsed().as_secs_f64();
    Ok(TrainSummary {
        run: run.clone(),
        start_step: start,
        steps: total,
        first_loss: interval.first_mean.unwrap_or(f64::NAN),
        last_loss: interval.last_mean,
        checkpoint: last_checkpoint.unwrap_or_default(),
        samples_per_s: ((total - start) * bs) as f64 / secs.max(1e-9),
        validation: last_validation,
        already_finished: false,
    })
}

/// The training loss since the last log line, and the mean of the first and of the last line.
struct Interval {
    loss: f64,
    steps: u64,
    start: Instant,
    batch_size: u64,
    first_mean: Option<f64>,
    last_mean: f64,
}

impl Interval {
    fn new(batch_size: u64) -> Interval {
        Interval {
            loss: 0.0,
            steps: 0,
            start: Instant::now(),
            batch_size,
            first_mean: None,
            last_mean: f64::NAN,
        }
    }

    fn add(&mut self, loss: f64) {
        self.loss += loss;
        self.steps += 1;
    }

    /// End the interval at step `done`: its mean loss and throughput go to the progress bar
    /// and the log (with `epoch`, `lr` and the time since `began`); the next one starts.
    fn close(
        &mut self,
        log: &mut Log,
        bar: &indicatif::ProgressBar,
        done: u64,
        epoch: f64,
        lr: f64,
        began: Instant,
    ) -> Result<()> {
        let mean = self.loss / self.steps as f64;
        let secs = self.start.elapsed().as_secs_f64();
        let sps = (self.steps * self.batch_size) as f64 / secs.max(1e-9);
        self.first_mean.get_or_insert(mean);
        self.last_mean = mean;
        bar.set_message(format!("loss {mean:.4} · {sps:.1} samples/s"));
        log.write(&LogLine::Interval {
            step: done,
            epoch: Number(epoch),
            loss: Number(mean),
            lr: Number(lr),
            samples_per_s: Number(sps),
            elapsed_s: Number(began.elapsed().as_secs_f64()),
        })?;
        (self.loss, self.steps) = (0.0, 0);
        self.start = Instant::now();
        Ok(())
    }
}

/// A non-finite loss `value` at `step`, or (`weight`) a parameter of the updated model
/// holding a NaN or an infinity: logged, the bar abandoned, and the error that stops the run
/// naming the last good checkpoint (nothing after it is saved).
fn stop_non_finite(
    log: &mut Log,
    bar: &indicatif::ProgressBar,
    step: u64,
    value: f64,
    weight: Option<&str>,
    lr: f64,
    last_checkpoint: Option<&Path>,
) -> Error {
    let logged = log.write(&LogLine::Stopped {
        step,
        loss: Number(value),
        error: weight.map_or("non-finite loss", |_| "non-finite weights"),
    });
    if let Err(e) = logged {
        return e;
    }
    bar.abandon();
    let kept = match last_checkpoint {
        Some(d) => format!("the last good checkpoint is {}", d.display()),
        None => "no checkpoint was written yet".into(),
    };
    let what = match weight {
        Some(name) => format!("parameter '{name}' of the updated model holds a NaN or an infinity"),
        None => format!("the training loss is {value}"),
    };
    Error::Invalid(format!(
        "step {step}: {what} (non-finite; lr {lr:e}); training stopped and nothing after the \
         last checkpoint was saved: {kept}. Lower optim.lr or check the data"
    ))
}

/// Mean validation scores over `samples`, in batches, on the inference model.
fn validate<T: Task>(
    task: &T,
    model: &T::Model,
    samples: &[Sample],
    batch: usize,
    device: &Device,
) -> Result<Vec<(String, f64)>> {
    let m = model.valid();
    let mut sums: Vec<(String, f64)> = Vec::new();
    for chunk in samples.chunks(batch.max(1)) {
        for (i, (k, v)) in task.validate(&m, chunk, device)?.into_iter().enumerate() {
            match sums.get_mut(i) {
                Some(s) => s.1 += v,
                None => sums.push((k.to_string(), v)),
            }
        }
    }
    let n = samples.len().max(1) as f64;
    Ok(sums.into_iter().map(|(k, v)| (k, v / n)).collect())
}

fn progress_bar(show: bool, start: u64, total: u64) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(total);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] step {pos}/{len} · {msg} · ETA {eta}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar.set_position(start);
    bar
}
