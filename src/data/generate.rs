//! The resumable dataset writer behind `hdrsynth generate` and its config: sets that are
//! complete (meta.toml present) are kept; a different config in the folder is refused.

use crate::data::layout::hdrsynth as layout;
use crate::data::scene::Generator;
pub use crate::data::scene::config::{GenerateConfig, MAX_EV};
use crate::error::{Error, Result};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::Path;
use std::time::Instant;

#[derive(Debug)]
pub struct Summary {
    pub generated: usize,
    pub resumed: usize,
    pub seconds: f64,
    pub frames_mpix: f64,
    pub over: Vec<f32>,
    pub under: Vec<f32>,
    pub dynamic_range: Vec<f32>,
}

pub fn generate(cfg: &GenerateConfig, out: &Path, progress: bool) -> Result<Summary> {
    let generator = Generator::new(cfg)?;
    let manifest = layout::manifest_for(cfg);
    // One generator per dataset folder: two with different configs would mix their sets.
    let _lock = crate::io::guard::OutputLock::acquire(out, "generate")?;
    // Under the lock, temp files in the folder are a killed run's.
    crate::io::atomic::remove_stale_temps(out)?;
    if layout::is_dataset(out) {
        let existing = layout::read_manifest(out)?;
        // Compare everything but where the config was read from.
        let same = match &existing.generator {
            Some(g) => {
                let mut g = g.clone();
                g.source = cfg.source.clone();
                g == *cfg
            }
            None => false,
        };
        if !same {
            return Err(Error::flag(
                "--out",
                format!(
                    "{} holds a dataset made with a different config; choose another --out \
                     (or delete it) rather than mixing sets",
                    out.display()
                ),
            ));
        }
    } else {
        std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
        layout::write_manifest(out, &manifest)?;
    }
    let bar = if progress {
        ProgressBar::new(cfg.count as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} sets {msg}",
        )
        .expect("static template"),
    );
    let start = Instant::now();
    let mut s = Summary {
        generated: 0,
        resumed: 0,
        seconds: 0.0,
        frames_mpix: 0.0,
        over: Vec::new(),
        under: Vec::new(),
        dynamic_range: Vec::new(),
    };
    for index in 0..cfg.count as u64 {
        if layout::set_done(out, index) {
            let meta = layout::read_set_meta(&out.join(layout::set_name(index)))?;
            s.over.push(meta.stats.over_fraction);
            s.under.push(meta.stats.under_fraction);
            s.dynamic_range.push(meta.stats.dynamic_range_stops);
            s.resumed += 1;
            bar.inc(1);
            continue;
        }
        let sample = generator.render(index);
        layout::write_set(out, index, &sample, cfg).map_err(Error::within(format!(
            "writing set {index} under {}",
            out.display()
        )))?;
        s.over.push(sample.stats.over_fraction);
        s.under.push(sample.stats.under_fraction);
        s.dynamic_range.push(sample.stats.dynamic_range_stops);
        s.generated += 1;
        // Output frames: static and dynamic display frames per EV.
        s.frames_mpix += (2 * cfg.evs.len() * cfg.width * cfg.height) as f64 / 1e6;
        bar.set_message(format!("DR {:.1} stops", sample.stats.dynamic_range_stops));
        bar.inc(1);
    }
    bar.finish_and_clear();
    s.seconds = start.elapsed().as_secs_f64();
    Ok(s)
}

fn stats(v: &[f32]) -> String {
    if v.is_empty() {
        return "-".into();
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    format!(
        "min {:.3} / median {:.3} / max {:.3}",
        s[0],
        s[s.len() / 2],
        s[s.len() - 1]
    )
}

impl Summary {
    pub fn report(&self, out: &Path) -> String {
        let rate = if self.seconds > 0.0 {
            self.frames_mpix / self.seconds
        } else {
            0.0
        };
        format!(
            "wrote {} sets to {} ({} already complete, kept) in {:.1} s — {:.2} Mpix/s of output frames\n\
             over-exposed at EV0:  {}\n\
             under-exposed at EV0: {}\n\
             dynamic range (stops, 99.9/0.1 percentile): {}",
            self.generated,
            out.display(),
            self.resumed,
            self.seconds,
            rate,
            stats(&self.over),
            stats(&self.under),
            stats(&self.dynamic_range)
        )
    }
}
