//! Subcommands, one file each. The binary (src/main.rs) only parses and dispatches.
pub mod dataset;
pub mod generate;
