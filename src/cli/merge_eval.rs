//! `ogm-corners merge-eval`: the merger over a pair set with ground truth (see [`ogm_corners::merge::eval`]).

use std::path::PathBuf;

use clap::Args;

use ogm_corners::merge::eval;
use ogm_corners::merge::pairs::PairSet;
use ogm_corners::merge::MergeOptions;
use ogm_corners::Result;

use super::write_stdout;

#[derive(Args, Debug)]
pub(super) struct MergeEvalArgs {
    /// The pair file (the format of `pairs.json` in the shared merge-pairs data).
    pairs: PathBuf,
    /// Folder of the maps, `NAME.png|pgm|yaml` (default: `maps` beside the pair file).
    #[arg(long)]
    maps: Option<PathBuf>,
    /// Output: a summary table, or every pair's record as JSON.
    #[arg(long, value_enum, default_value = "md")]
    format: super::TextOrJsonMd,
}

pub(super) fn run(a: MergeEvalArgs) -> Result<()> {
    super::check_stdout()?;
    let set = PairSet::load(&a.pairs)?;
    let maps = a.maps.clone().unwrap_or_else(|| {
        a.pairs
            .parent()
            .unwrap_or(std::path::Path::new("."))
            .join("maps")
    });
    let (rows, prep_ms) = eval::run(&set, &maps, &MergeOptions::default())?;
    write_stdout(|out| match a.format {
        super::TextOrJsonMd::Md => eval::write_summary(out, &rows, prep_ms),
        super::TextOrJsonMd::Json => {
            serde_json::to_writer_pretty(&mut *out, &rows)?;
            writeln!(out)
        }
    })
}
