//! Every `hdrsynth` command the README and docs/ show parses as written: each command line in
//! their code blocks (`hdrsynth …`, or `cargo run --release [--features …] -- …`) goes through
//! the binary's own argument parser, so a renamed command or flag fails here, not in a user's
//! terminal. Whether the commands also run is what the README's main job and the tests of
//! each command check.

use clap::Parser;
use hdrsynth::cli::Cli;
use std::path::Path;

/// Command lines inside the fenced and indented code blocks of `markdown`, with `\`
/// continuations joined and trailing `# comments` dropped.
fn code_lines(markdown: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut fenced = false;
    let mut pending = String::new();
    for line in markdown.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        let code = if fenced {
            line
        } else if let Some(rest) = line.strip_prefix("    ") {
            rest
        } else {
            continue;
        };
        let code = code.trim();
        if let Some(head) = code.strip_suffix('\\') {
            pending.push_str(head.trim_end());
            pending.push(' ');
            continue;
        }
        pending.push_str(code);
        let full = std::mem::take(&mut pending);
        // A comment starts at " #" outside quotes; the docs' commands do not quote '#'.
        let full = full.split(" #").next().unwrap_or("").trim().to_string();
        if !full.is_empty() {
            out.push(full);
        }
    }
    out
}

/// A usage synopsis (`[--flag N]`, `(--a | --b)`, `[options]`) describes a command's form; the
/// reference pages list them beside runnable examples, which are what this test parses.
fn is_synopsis(line: &str) -> bool {
    ["[-", "(-", "[options]", " | ", "…"]
        .iter()
        .any(|t| line.contains(t))
}

/// The hdrsynth arguments of a command line, if it runs hdrsynth.
fn hdrsynth_args(line: &str) -> Option<Vec<String>> {
    if is_synopsis(line) {
        return None;
    }
    let words = shlex::split(line)?;
    let start = match words.first()?.as_str() {
        "hdrsynth" => 1,
        "cargo" if words.get(1).map(String::as_str) == Some("run") => {
            if words.iter().any(|w| w == "--example") {
                return None;
            }
            words.iter().position(|w| w == "--")? + 1
        }
        _ => return None,
    };
    let mut args = vec!["hdrsynth".to_string()];
    args.extend(words[start..].iter().cloned());
    Some(args)
}

fn pages() -> Vec<std::path::PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut pages = vec![root.join("README.md")];
    let mut docs: Vec<_> = std::fs::read_dir(root.join("docs"))
        .expect("docs/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    pages.extend(docs);
    pages
}

#[test]
fn every_documented_command_parses() {
    let mut checked = 0;
    let mut failures = Vec::new();
    for page in pages() {
        let text = std::fs::read_to_string(&page).expect("page");
        for line in code_lines(&text) {
            let Some(args) = hdrsynth_args(&line) else {
                continue;
            };
            checked += 1;
            if let Err(e) = Cli::try_parse_from(&args) {
                // `--help` and `--version` are "errors" that print and exit 0.
                if e.exit_code() != 0 {
                    let first = e.to_string().lines().next().unwrap_or("").to_string();
                    failures.push(format!("{}: `{line}`: {first}", page.display()));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {checked} documented commands do not parse:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // The README alone shows about ten; a parser that found none would prove nothing.
    assert!(checked >= 20, "only {checked} commands found in the docs");
}

#[test]
fn the_extractor_reads_fences_indents_continuations_and_comments() {
    let md = "text hdrsynth not code\n```bash\nhdrsynth eval --out a \\\n  --testset b   # note\n```\n\n    cargo run --release --features onnx -- quickstart --full\n    cargo run --release --example x\n";
    let lines = code_lines(md);
    assert_eq!(
        lines,
        [
            "hdrsynth eval --out a --testset b",
            "cargo run --release --features onnx -- quickstart --full",
            "cargo run --release --example x",
        ]
    );
    assert_eq!(
        hdrsynth_args(&lines[1]).unwrap(),
        ["hdrsynth", "quickstart", "--full"]
    );
    assert_eq!(hdrsynth_args(&lines[2]), None);
    assert_eq!(
        hdrsynth_args("hdrsynth train --config FILE [--resume]"),
        None
    );
    // A misspelt flag is caught by the parser the test uses.
    assert!(Cli::try_parse_from(["hdrsynth", "quickstart", "--ful"]).is_err());
    assert!(Cli::try_parse_from(["hdrsynth", "quickstart", "--full"]).is_ok());
}
