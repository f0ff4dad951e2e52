//! The run's metrics log (`log.jsonl`): one JSON object per line, `step` first; cut back to
//! the resumed checkpoint's step on resume.

use super::LOG_FILE;
use crate::error::{Error, Result};
use crate::io::atomic::write_atomic;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};

pub(super) struct Log {
    path: PathBuf,
    file: std::fs::File,
}

impl Log {
    /// Open the run's log; on resume keep only lines up to `step` (later ones were written
    /// after the checkpoint and will be written again).
    pub(super) fn open(run: &Path, resume_step: Option<u64>) -> Result<Log> {
        let path = run.join(LOG_FILE);
        match resume_step {
            Some(step) => {
                let text = crate::io::guard::read_input_text(&path).unwrap_or_default();
                let kept: String = text
                    .lines()
                    .filter(|l| line_step(l).is_some_and(|s| s <= step))
                    .map(|l| format!("{l}\n"))
                    .collect();
                write_atomic(&path, kept.as_bytes())?;
            }
            None => write_atomic(&path, b"")?,
        }
        let file = std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| Error::io(&path, e))?;
        Ok(Log { path, file })
    }

    pub(super) fn write(&mut self, line: &LogLine) -> Result<()> {
        let text = serde_json::to_string(line).map_err(|e| Error::encode(&self.path, e))?;
        writeln!(self.file, "{text}")
            .and_then(|_| self.file.flush())
            .map_err(|e| Error::io(&self.path, e))
    }
}

/// One line of the metrics log: a JSON object whose keys come in field order, `step` first.
#[derive(Serialize)]
#[serde(untagged)]
pub(super) enum LogLine<'a> {
    Interval {
        step: u64,
        epoch: Number,
        loss: Number,
        lr: Number,
        samples_per_s: Number,
        elapsed_s: Number,
    },
    Validation {
        step: u64,
        validation: Scores<'a>,
    },
    Stopped {
        step: u64,
        loss: Number,
        error: &'static str,
    },
}

/// A score as JSON: a number, or its name as a string when not finite (JSON has no NaN).
pub(super) struct Number(pub f64);

impl Serialize for Number {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        if self.0.is_finite() {
            s.serialize_f64(self.0)
        } else {
            s.serialize_str(&self.0.to_string())
        }
    }
}

/// Validation scores as one JSON object, in the task's order.
pub(super) struct Scores<'a>(pub &'a [(String, f64)]);

impl Serialize for Scores<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_map(self.0.iter().map(|(k, v)| (k, Number(*v))))
    }
}

fn line_step(line: &str) -> Option<u64> {
    #[derive(Deserialize)]
    struct Step {
        step: u64,
    }
    serde_json::from_str::<Step>(line).ok().map(|s| s.step)
}
