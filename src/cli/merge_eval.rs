//! `ogm-corners merge-eval`: the merger over a pair set with ground truth, or over synthetic pairs cut from
//! any maps (see [`ogm_corners::measure::merging`]).

use std::path::PathBuf;

use clap::Args;

use ogm_corners::measure::merging;
use ogm_corners::measure::merging::many as global_eval;
use ogm_corners::measure::merging::page::PairsPage;
use ogm_corners::measure::pairs::PairSet;
use ogm_corners::merge::many::GlobalOptions;
use ogm_corners::merge::{MergeOptions, Ranking, Rigid};
use ogm_corners::support::memory::Budget;
use ogm_corners::{Error, OccupancyMap, Result};

use super::write_stdout;

#[derive(Args, Debug)]
pub(super) struct MergeEvalArgs {
    /// The pair file (the format of `pairs.json` in the shared merge-pairs data); not with --synthetic.
    /// With --cross-validate, several: their buildings judged together (`merge-pairs/pairs.json` and the
    /// sets `--save-pairs` wrote).
    #[arg(required_unless_present_any = ["synthetic", "global"], conflicts_with = "synthetic")]
    pairs: Vec<PathBuf>,
    /// Folder of the maps, `NAME.png|pgm|yaml` (default: the folder the pair file names, else `maps`
    /// beside it).
    #[arg(long)]
    maps: Option<PathBuf>,
    /// Instead of a pair file: synthetic pairs with exact truth cut from these maps or folders of maps
    /// (none: the built-in synthetic office generator, seeds 1-8, with negatives: one office's part
    /// against another's), at 50% and 30% overlap, one part turned by a random angle and shifted.
    #[arg(long, num_args = 0.., value_name = "MAP|DIR")]
    synthetic: Option<Vec<PathBuf>>,
    /// With --synthetic and no maps: the families to run, comma-separated: office (the office generator's
    /// offices cut in two, with negatives), grid-rooms, warehouse, doors (repetitive layouts at 50, 30 and
    /// 20% overlap), bent (offices with heading drift, speckle and unexplored rooms), crops (windows of 120,
    /// 250 and 400 px overlapping or apart), symmetric (a hall with 2 to 8 identical wings, mirrored or
    /// not, or one extra room, cut into two windows that both hold the hall; the extra-room halls also
    /// cut until both windows hold the room), or all (the default).
    #[arg(long, value_delimiter = ',', value_name = "FAMILY")]
    family: Vec<String>,
    /// With --synthetic MAPS: a map `NAME_furnished` given beside `NAME` is its furnished copy (the same
    /// place in the same frame with furniture drawn in, as in the maps-more data): not cut on its own,
    /// but --per-map plan-vs-furnished pairs, A a window of `NAME` and B one of the copy, each 36-64% of
    /// the known area, B turned by any angle, exact truth (`NAME+furnished/<k>`).
    #[arg(long)]
    furnished: bool,
    /// Synthetic pairs per map and overlap (per family and overlap for the generated families).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=1000))]
    per_map: u32,
    /// Synthetic speckle: the probability that a free pixel turns occupied.
    #[arg(long, default_value_t = 0.0)]
    noise: f64,
    /// Seed of the synthetic cuts.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also write every synthetic pair into DIR (`a_<map>-<overlap>-<k>.pgm` and `b_...`) with a
    /// `pairs.json` of their truths: `merge-eval DIR/pairs.json` runs them again, `merge` takes any of them.
    /// With `--global` and no pair file: the synthetic set's maps (`part-NN.pgm`), for `merge DIR`.
    #[arg(long, value_name = "DIR")]
    save_pairs: Option<PathBuf>,
    /// Instead of one run: the ablation of where hypotheses come from (dense correlation; corners of each
    /// detector alone; both), one row each (a pair file only; takes a few minutes).
    #[arg(long, conflicts_with = "synthetic")]
    ablation: bool,
    /// Leave-one-building-out: the acceptance rule fitted on every building but one and the one left out
    /// judged with it, for each building; then the pooled held-out figures, the in-sample ones and the
    /// shipped rule's (pair files only; several are judged together).
    #[arg(long, conflicts_with_all = ["synthetic", "ablation", "html"])]
    cross_validate: bool,
    /// With --cross-validate: only the pairs (and negatives) whose maps' names start with one of these
    /// comma-separated prefixes (a small subset for a quick check).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "PREFIX",
        requires = "cross_validate"
    )]
    only: Vec<String>,
    /// Instead of pairs: every building's maps placed at once (`merge A B C ...`), every two buildings'
    /// maps together (they must come out as separate groups), the cost as the number of maps grows, and a
    /// synthetic set of `--set-size` maps cut from one office (takes a few minutes). Without a pair
    /// file: the synthetic set alone.
    #[arg(long, conflicts_with_all = ["synthetic", "ablation"])]
    global: bool,
    /// Maps in the synthetic set of `--global`.
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u32).range(2..=1000))]
    set_size: u32,
    /// With --global: the synthetic set cut from this many synthetic offices (seeds `--seed` on), about
    /// as many maps from each, mixed: maps of different offices must stay in different groups.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100))]
    buildings: u32,
    /// With --global: in a set of more than 12 maps, align each map first with only its N most similar
    /// maps, then the pairs that close cycles and may join groups (0: every pair; as `merge`).
    #[arg(long, value_name = "N", default_value_t = 3, value_parser = clap::value_parser!(u32).range(0..=1000))]
    partners: u32,
    /// Also write an HTML report into DIR (pair runs: a pair file or --synthetic): `index.html` with every
    /// pair's verdict, score, overlap, errors against the truth and runner-up (sortable; wrong accepts and
    /// missed pairs first), and each pair's two maps overlaid at the estimate (and, when it is wrong, at
    /// the truth); opened from disk, no server.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["ablation", "global"])]
    html: Option<PathBuf>,
    /// Keep each pair's measured alignment in DIR, and read it back when the same maps are aligned again
    /// by the same build with the same options (a pair file's runs and --cross-validate): default
    /// `$OGM_CORNERS_CACHE`, else `$XDG_CACHE_HOME/ogm-corners/merge-eval`, else
    /// `~/.cache/ogm-corners/merge-eval`.
    #[arg(long, value_name = "DIR", conflicts_with = "no_cache")]
    cache: Option<PathBuf>,
    /// Measure every pair again and keep nothing.
    #[arg(long)]
    no_cache: bool,
    /// What orders each pair's candidates for the choice: the choice key (the default, as `merge`
    /// ranks them), or their consistent evidence (the wall pixels that agree after a few px of local
    /// shift, less those left in the other map's free space), measured beside it (pair files,
    /// --synthetic and --cross-validate).
    #[arg(long, value_enum, default_value = "choice", conflicts_with_all = ["ablation", "global"])]
    ranking: Ranking,
    /// Output: a summary table, or every pair's record as JSON.
    #[arg(long, value_enum, default_value = "md")]
    format: super::TextOrJsonMd,
}

impl MergeEvalArgs {
    /// The merge options of a run: the defaults with the chosen ranking.
    fn merge_options(&self) -> MergeOptions {
        MergeOptions {
            ranking: self.ranking,
            ..MergeOptions::default()
        }
    }
}

pub(super) fn run(a: MergeEvalArgs, budget: &Budget) -> Result<()> {
    if !(0.0..=0.5).contains(&a.noise) {
        return Err(Error::invalid(format!(
            "--noise must be a probability in [0, 0.5], got {}",
            a.noise
        )));
    }
    super::check_stdout()?;
    if a.global {
        return run_global(&a, budget);
    }
    let chosen = chosen_families(&a)?;
    let mut page = match &a.html {
        Some(dir) => Some(PairsPage::create(dir)?),
        None => None,
    };
    // Each pair drawn as it is run, when there is a page.
    let mut on_pair = |i: usize,
                       r: &merging::PairRecord,
                       ma: &OccupancyMap,
                       mb: &OccupancyMap,
                       truth: Option<Rigid>| match &mut page {
        Some(p) => p.add(i, r, ma, mb, truth),
        None => Ok(()),
    };
    if a.cross_validate {
        return cross_validate(&a, budget);
    }
    let (rows, costs) = match (a.pair_file()?, &a.synthetic) {
        (Some(pairs), _) => {
            let set = PairSet::load(pairs)?;
            let maps = maps_folder(&a, &set, pairs);
            if a.ablation {
                check_set_memory(&set, &maps, budget)?;
                let rows = merging::ablation(&set, &maps, &mut |h| {
                    ogm_corners::say!("ogm-corners: merge-eval: hypotheses {h}")
                })?;
                return write_table(a.format, &rows, |out| merging::write_ablation(out, &rows));
            }
            check_set_memory(&set, &maps, budget)?;
            let mut cache = a.record_cache();
            let done = merging::run_cached(
                &set,
                &maps,
                &a.merge_options(),
                &mut on_pair,
                cache.as_mut(),
            )?;
            say_cache_use(cache.as_ref());
            done
        }
        (None, sources) => {
            let given = sources.as_deref().unwrap_or(&[]);
            let (sources, mut inputs) = synthetic_sources(given, budget)?;
            let (sources, furnished) = furnished_of(&a, sources)?;
            let overlaps = vec![0.5, 0.3];
            if let Some(dir) = &a.save_pairs {
                let per_map = a.per_map as usize;
                claim_saved_pairs(dir, (&sources, &furnished), &overlaps, per_map, &mut inputs)?;
            }
            let (office, families) = chosen.unwrap_or_default();
            // Negatives only between the generator's offices: given maps may show one place twice.
            let run = merging::SyntheticRun {
                overlaps,
                per_map: a.per_map as usize,
                noise: a.noise,
                seed: a.seed,
                negatives: given.is_empty(),
                furnished,
                save: a.save_pairs.clone(),
            };
            let options = a.merge_options();
            let (mut rows, mut costs) = if office {
                merging::run_synthetic_with(&sources, &run, &options, &mut on_pair)?
            } else {
                (Vec::new(), merging::MapCosts::default())
            };
            if !given.is_empty() {
                say_uncut(&sources, &rows)?;
            }
            if !families.is_empty() {
                let first = rows.len();
                let mut shifted = |i: usize,
                                   r: &merging::PairRecord,
                                   ma: &OccupancyMap,
                                   mb: &OccupancyMap,
                                   truth: Option<Rigid>| {
                    on_pair(first + i, r, ma, mb, truth)
                };
                let (more, more_costs) = merging::families::run_families(
                    &families,
                    a.per_map as usize,
                    a.seed,
                    &options,
                    &mut shifted,
                )?;
                costs = costs.and(more_costs);
                rows.extend(more);
            }
            (rows, costs)
        }
    };
    if let Some(page) = page {
        let index = page.finish(&rows, costs.prepare_ms)?;
        ogm_corners::say!(
            "ogm-corners: wrote {}",
            ogm_corners::support::error::one_line(&index.display().to_string())
        );
    }
    write_table(a.format, &rows, |out| {
        merging::write_summary(out, &rows, &costs)
    })
}

/// How a run used the cache, on standard error.
fn say_cache_use(cache: Option<&merging::cache::RecordCache>) {
    if let Some(c) = cache {
        ogm_corners::say!(
            "ogm-corners: merge-eval: {} pairs read from the cache ({}), {} aligned",
            c.hits,
            ogm_corners::support::error::one_line(&c.dir().display().to_string()),
            c.misses
        );
        if let Some(why) = &c.unwritable {
            ogm_corners::say!(
                "ogm-corners: warning: merge-eval: the cache could not be written ({}); give another \
                 with --cache DIR, or --no-cache",
                ogm_corners::support::error::one_line(why)
            );
        }
    }
}

impl MergeEvalArgs {
    /// The cache of measured alignments the options ask for (none with --no-cache, or when no folder
    /// can be told).
    fn record_cache(&self) -> Option<merging::cache::RecordCache> {
        if self.no_cache {
            return None;
        }
        let dir = self.cache.clone().or_else(merging::cache::default_dir)?;
        Some(merging::cache::RecordCache::new(&dir))
    }

    /// The one pair file of a run that takes one (all but --cross-validate).
    fn pair_file(&self) -> Result<Option<&PathBuf>> {
        match self.pairs.as_slice() {
            [] => Ok(None),
            [one] => Ok(Some(one)),
            more => Err(Error::invalid(format!(
                "{} pair files: only --cross-validate takes several",
                more.len()
            ))),
        }
    }
}

/// `merge-eval --cross-validate PAIRS...`: the merger over every pair file's pairs (their `--only`
/// subset), every veto measured, then leave-one-building-out over all their buildings together.
fn cross_validate(a: &MergeEvalArgs, budget: &Budget) -> Result<()> {
    if a.maps.is_some() && a.pairs.len() > 1 {
        return Err(Error::invalid(
            "--maps names one pair file's maps: with several, each finds its own (its \"maps\" entry, \
             else maps beside it)",
        ));
    }
    let options = MergeOptions {
        always_verify: true,
        ..a.merge_options()
    };
    let keep = |n: &str| a.only.is_empty() || a.only.iter().any(|p| n.starts_with(p.as_str()));
    // Every file read and checked before the first pair is run.
    let mut sets = Vec::new();
    for pairs in &a.pairs {
        let mut set = PairSet::load(pairs)?;
        set.pairs.retain(|p| keep(&p.src) && keep(&p.dst));
        set.negatives.retain(|p| keep(&p.src) && keep(&p.dst));
        let maps = maps_folder(a, &set, pairs);
        check_set_memory(&set, &maps, budget)?;
        sets.push((set, maps));
    }
    if sets.iter().all(|(set, _)| set.pairs.is_empty()) {
        return Err(Error::invalid(format!(
            "--only {}: no pair of the pair file has both maps named so",
            a.only.join(",")
        )));
    }
    let mut rows = Vec::new();
    let mut cache = a.record_cache();
    for (set, maps) in sets.iter().filter(|(set, _)| !set.pairs.is_empty()) {
        let none = &mut |_: usize,
                         _: &merging::PairRecord,
                         _: &OccupancyMap,
                         _: &OccupancyMap,
                         _: Option<Rigid>| Ok(());
        rows.extend(merging::run_cached(set, maps, &options, none, cache.as_mut())?.0);
    }
    say_cache_use(cache.as_ref());
    let folds = merging::crossval::cross_validate(&rows);
    write_table(a.format, &folds, |out| {
        merging::crossval::write_folds(out, &folds)
    })
}

/// With `--furnished`: the given maps split into those cut on their own and the furnished copies
/// (`NAME_furnished` beside `NAME`); an error when there is none. Without it, every map on its own.
/// The synthetic families `--family` chooses, checked before any folder is made (clap drops a
/// requirement on --synthetic, which conflicts with the pair file, so it is checked here), with the
/// options that need `--synthetic`: whether the office pairs are cut, and the families.
fn chosen_families(a: &MergeEvalArgs) -> Result<Option<(bool, Vec<merging::families::Family>)>> {
    if a.furnished && a.synthetic.as_ref().is_none_or(|g| g.is_empty()) {
        return Err(Error::invalid(
            "--furnished pairs given maps with their furnished copies: use it with --synthetic MAPS",
        ));
    }
    if a.save_pairs.is_some() && a.synthetic.is_none() {
        return Err(Error::invalid(
            "--save-pairs writes synthetic pairs (--synthetic) or the synthetic set (--global without a pair file)",
        ));
    }
    match &a.synthetic {
        Some(given) => Ok(Some(families(&a.family, given.is_empty())?)),
        None if !a.family.is_empty() => Err(Error::invalid(
            "--family chooses synthetic families: use it with --synthetic",
        )),
        None => Ok(None),
    }
}

/// `--save-pairs DIR`: the folder made, and every file it may write claimed against the inputs before
/// the first pair (each pair cut from `sources` at `overlaps`, and each of `furnished`, `per_map` times).
fn claim_saved_pairs(
    dir: &std::path::Path,
    (sources, furnished): (&[merging::NamedMap], &[merging::NamedMap]),
    overlaps: &[f64],
    per_map: usize,
    inputs: &mut ogm_corners::support::files::Inputs,
) -> Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::input(dir, format!("cannot create the folder: {e}")))?;
    inputs.claim_output(&dir.join("pairs.json"), "--save-pairs")?;
    let labels = sources.iter().flat_map(|(name, _)| {
        overlaps
            .iter()
            .flat_map(move |&o| (0..per_map).map(move |k| merging::synthetic_label(name, o, k)))
    });
    let furnished_labels = furnished
        .iter()
        .flat_map(|(name, _)| (0..per_map).map(move |k| merging::furnished_label(name, k)));
    for label in labels.chain(furnished_labels) {
        let stem = merging::saved_stem(&label);
        for side in ["a", "b"] {
            inputs.claim_output(&dir.join(format!("{side}_{stem}.pgm")), "--save-pairs")?;
        }
    }
    Ok(())
}

/// A given map too small to cut at these overlaps gives no pair: said, and an error when none of them
/// gave one (a table of zeros would read as a result).
fn say_uncut(sources: &[merging::NamedMap], rows: &[merging::PairRecord]) -> Result<()> {
    let uncut: Vec<&str> = sources
        .iter()
        .map(|(name, _)| name.as_str())
        .filter(|name| !rows.iter().any(|r| r.src.starts_with(&format!("{name}/"))))
        .collect();
    if uncut.len() == sources.len() {
        return Err(Error::invalid(format!(
            "no synthetic pair could be cut from {}: too small (or too little of it known) \
             for two parts at 50% and 30% overlap",
            ogm_corners::support::error::one_line(&uncut.join(", "))
        )));
    }
    for name in uncut {
        ogm_corners::say!(
            "ogm-corners: note: {}: too small to cut synthetic pairs from; left out",
            ogm_corners::support::error::one_line(name)
        );
    }
    Ok(())
}

fn furnished_of(
    a: &MergeEvalArgs,
    sources: Vec<merging::NamedMap>,
) -> Result<(Vec<merging::NamedMap>, Vec<merging::NamedMap>)> {
    if !a.furnished {
        return Ok((sources, Vec::new()));
    }
    let (own, copies) = merging::furnished_copies(sources);
    if copies.is_empty() {
        return Err(Error::invalid(format!(
            "--furnished: no map NAME{} beside a map NAME among the maps given",
            merging::FURNISHED_SUFFIX
        )));
    }
    Ok((own, copies))
}

/// Whether to run the office family, and which generated families: all of them by default; given maps
/// are cut as the office family is, and take no generated family.
fn families(names: &[String], generated: bool) -> Result<(bool, Vec<merging::families::Family>)> {
    use merging::families::Family;
    let all = names.is_empty() || names.iter().any(|n| n == "all");
    if !generated {
        if names.iter().any(|n| n != "all") {
            return Err(Error::invalid(
                "--family chooses generated families: give no maps to --synthetic",
            ));
        }
        return Ok((true, Vec::new()));
    }
    if all {
        return Ok((true, Family::all()));
    }
    let mut out = Vec::new();
    let mut office = false;
    for n in names {
        if n == "office" {
            office = true;
        } else {
            let f = Family::parse(n)?;
            if !out.contains(&f) {
                out.push(f);
            }
        }
    }
    Ok((office, out))
}

/// The maps synthetic pairs are cut from: the given ones (checked against the memory budget with the
/// merger's buffers for both parts), or eight synthetic offices.
fn synthetic_sources(
    args: &[PathBuf],
    budget: &Budget,
) -> Result<(
    Vec<(String, OccupancyMap)>,
    ogm_corners::support::files::Inputs,
)> {
    if args.is_empty() {
        let maps = (1..=8)
            .map(|seed| {
                let img = ogm_corners::map::synthetic::office_map(1024, 768, seed)?;
                Ok((format!("office-{seed}"), OccupancyMap::from_image(img)))
            })
            .collect::<Result<_>>()?;
        return Ok((maps, ogm_corners::support::files::Inputs::new()));
    }
    // Each part's canvas holds at most the map's diagonal squared: twice the map, and the merger's
    // buffers for both.
    let extra = |w: u32, h: u32| {
        ogm_corners::merge::pair::align::prepared_bytes(w, h)
            .saturating_mul(4)
            .saturating_add(u64::from(w) * u64::from(h) * 4)
    };
    let (maps, inputs) = super::map_inputs(args, budget, &extra)?;
    let maps = maps
        .iter()
        .map(|p| Ok((ogm_corners::map::map_name(p), OccupancyMap::load(p)?)))
        .collect::<Result<_>>()?;
    Ok((maps, inputs))
}

/// Every map the pair set names, with its building (from its pairs), read from `maps`.
fn library(set: &PairSet, maps: &std::path::Path) -> Result<global_eval::Library> {
    let mut named: std::collections::BTreeMap<String, String> = Default::default();
    for p in &set.pairs {
        for m in [&p.src, &p.dst] {
            named.entry(m.clone()).or_insert_with(|| p.building.clone());
        }
    }
    let maps = named
        .into_iter()
        .map(|(name, building)| {
            let map = OccupancyMap::load(merging::map_path(maps, &name)?)?;
            Ok((name, building, map))
        })
        .collect::<Result<_>>()?;
    Ok(global_eval::Library { maps })
}

/// Refuses a pair file whose maps, each held with its preparation (every map is prepared once and kept
/// while its pairs run), would exceed the budget; read up to their image headers only.
fn check_set_memory(set: &PairSet, maps: &std::path::Path, budget: &Budget) -> Result<()> {
    let bytes = |name: &str| {
        let (w, h, _) = OccupancyMap::probe(&merging::map_path(maps, name)?)?;
        Ok(set_bytes(w, h))
    };
    let (peak, held) = merging::peak_held(set, &bytes)?;
    budget.check(
        format_args!("the pair file's maps held at once ({held}) and their preparation"),
        peak,
    )
}

/// `merge-eval --global`: the suite over a pair file's buildings, or the synthetic set alone.
fn run_global(a: &MergeEvalArgs, budget: &Budget) -> Result<()> {
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg}: {bar:30} {pos}/{len} pairs")
            .expect("valid template"),
    );
    let progress = |label: &str, k: usize, n: usize| {
        bar.set_message(label.to_string());
        bar.set_length(n as u64);
        bar.set_position(k as u64);
    };
    let options = GlobalOptions::with_partners(a.partners as usize);
    let size = a.set_size as usize;
    let buildings = a.buildings as usize;
    if buildings > size {
        return Err(Error::invalid(format!(
            "--buildings {buildings} is more than --set-size {size}: each office needs a map"
        )));
    }
    let rows = match a.pair_file()? {
        Some(pairs) => {
            if a.save_pairs.is_some() {
                return Err(Error::invalid(
                    "--save-pairs with --global writes the synthetic set: give no pair file",
                ));
            }
            let set = PairSet::load(pairs)?;
            let maps = maps_folder(a, &set, pairs);
            let lib = library(&set, &maps)?;
            // The largest set placed holds every map and its preparation at once, and the synthetic set.
            let all = ogm_corners::merge::footprint::set_bytes(
                lib.maps
                    .iter()
                    .map(|(_, _, m)| kept_working(m.image.width(), m.image.height())),
            );
            budget.check(
                format_args!("{} maps placed at once", lib.maps.len()),
                all.max(synthetic_bytes(size)),
            )?;
            global_eval::suite(
                &lib,
                &set.pairs,
                &options,
                (size, buildings),
                a.seed,
                &progress,
            )?
        }
        None => {
            budget.check(
                format_args!("a synthetic set of {size} maps"),
                synthetic_bytes(size),
            )?;
            let (names, maps, truths) = global_eval::synthetic_mixed(size, buildings, a.seed)?;
            if let Some(dir) = &a.save_pairs {
                save_set(dir, &names, &maps, &truths)?;
            }
            let label = global_eval::synthetic_label(size, buildings);
            vec![global_eval::score_maps(
                &label, names, &maps, &truths, &options, &progress,
            )?]
        }
    };
    bar.finish_and_clear();
    write_table(a.format, &rows, |out| global_eval::write_rows(out, &rows))
}

/// A map of `w` x `h` in a set placed at once: its pixels and its preparation.
fn set_bytes(w: u32, h: u32) -> u64 {
    (u64::from(w) * u64::from(h))
        .saturating_add(ogm_corners::merge::pair::align::prepared_bytes(w, h))
}

/// A `w` x `h` map in a set placed at once: (what it keeps while the others are prepared and aligned,
/// its working memory while it is), for [`footprint::set_bytes`](ogm_corners::merge::footprint::set_bytes).
fn kept_working(w: u32, h: u32) -> (u64, u64) {
    let kept = (u64::from(w) * u64::from(h))
        .saturating_add(ogm_corners::merge::pair::align::kept_bytes(w, h).min(prepared(w, h)));
    (kept, set_bytes(w, h) - kept)
}

fn prepared(w: u32, h: u32) -> u64 {
    ogm_corners::merge::pair::align::prepared_bytes(w, h)
}

/// A synthetic set of `n` maps: each a square canvas of about 1500 px a side (a 1044 px window turned),
/// and the office they are cut from (about 580 px a map).
fn synthetic_bytes(n: usize) -> u64 {
    let (kept, working) = kept_working(1500, 1500);
    ogm_corners::merge::footprint::set_bytes((0..n).map(|_| (kept + 580 * 580, working)))
}

/// Writes a synthetic set into `dir`: `NAME.pgm` per map and `pairs.json` with every ordered pair's truth.
fn save_set(
    dir: &std::path::Path,
    names: &[String],
    maps: &[OccupancyMap],
    truths: &[ogm_corners::measure::pairs::TruePair],
) -> Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::input(dir, format!("cannot create the folder: {e}")))?;
    // All or nothing: the maps and their truths renamed into place together.
    let mut staged = ogm_corners::support::files::Staged::default();
    for (n, m) in names.iter().zip(maps) {
        staged.write(&dir.join(format!("{n}.pgm")), |out| {
            m.image.write_pgm_to(out)
        })?;
    }
    // Its maps beside it, as it says: `merge-eval DIR/pairs.json` finds them.
    let doc = serde_json::json!({ "pairs": truths, "negatives": [], "maps": "." });
    staged.write(&dir.join("pairs.json"), |out| {
        serde_json::to_writer_pretty(&mut *out, &doc)?;
        writeln!(out)
    })?;
    staged.commit()
}

/// The maps of a pair file: `--maps`, else the folder the file names, else `maps` beside the file.
fn maps_folder(a: &MergeEvalArgs, set: &PairSet, pairs: &std::path::Path) -> PathBuf {
    a.maps.clone().unwrap_or_else(|| set.maps_folder(pairs))
}

/// Rows on standard output: the markdown table `md` writes, or the rows as JSON.
fn write_table<T: serde::Serialize>(
    format: super::TextOrJsonMd,
    rows: &T,
    md: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> Result<()> {
    write_stdout(|out| match format {
        super::TextOrJsonMd::Md => md(out),
        super::TextOrJsonMd::Json => {
            serde_json::to_writer_pretty(&mut *out, rows)?;
            writeln!(out)
        }
    })
}
