//! `hdrsynth dataset info [--verify]`: the report of data::layout::info.

use std::path::Path;

/// The report and the number of bad files (`--verify`).
pub fn info_report_verified(dir: &Path, verify: bool) -> anyhow::Result<(String, usize)> {
    Ok(crate::data::layout::info::info_report_verified(
        dir, verify,
    )?)
}
