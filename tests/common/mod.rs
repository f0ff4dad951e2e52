//! Helpers shared by the integration tests (each test binary includes this module; not every
//! binary uses every helper).
#![allow(dead_code)]

use hdrsynth::config::{GenerateConfig, parse_toml};
use std::path::Path;

/// Generate a small pure synthetic dataset into `dir` with the scene engine.
pub fn generate(dir: &Path, seed: u64, count: usize, (width, height): (usize, usize), evs: &str) {
    let text = format!(
        "seed = {seed}\ncount = {count}\nwidth = {width}\nheight = {height}\nevs = {evs}\n\
         [camera]\ncandidates = 4\n"
    );
    let mut c: GenerateConfig = parse_toml(&text, Path::new("gen.toml")).expect("config");
    c.source = None;
    hdrsynth::cli::generate::generate(&c, dir, false).expect("generate");
}

/// The validation score `key` the trainer logged at `step` in `RUN/log.jsonl` (step 0 is logged
/// before training).
pub fn validation_at(run: &Path, step: u64, key: &str) -> f64 {
    let log = std::fs::read_to_string(run.join("log.jsonl")).expect("log");
    let line = log
        .lines()
        .find(|l| l.starts_with(&format!("{{\"step\":{step},\"validation\"")))
        .unwrap_or_else(|| panic!("no validation at step {step}:\n{log}"));
    let rest = &line[line.find(&format!("\"{key}\":")).expect(key) + key.len() + 3..];
    rest.split([',', '}'])
        .next()
        .unwrap()
        .parse()
        .expect("number")
}
