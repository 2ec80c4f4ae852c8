//! `ogm-corners merge A B C ... | DIR`: every map placed at once (see [`ogm_corners::merge::many`]): each
//! group's merged map and picture, each map's pose (`--poses`), the multirobot_map_merge parameters
//! (`--init-poses`), and the HTML page (`--html`). All outputs are staged and renamed into place together.

use std::path::{Path, PathBuf};

use ogm_corners::map::{merged_yaml_text, save_names, write_merged_pgm_to};
use ogm_corners::merge::footprint;
use ogm_corners::merge::many::previous::Previous;
use ogm_corners::merge::many::{merge_maps_cached, page, poses, Cache, GlobalOptions, ManyMerge};
use ogm_corners::support::files;
use ogm_corners::support::memory::Budget;
use ogm_corners::support::report::Report;
use ogm_corners::{Error, OccupancyMap, Result};

use super::merge::MergeArgs;
use super::write_stdout;

/// `NAME.ext` for group 0, `NAME-k.ext` for group k.
fn group_path(base: &Path, g: usize) -> PathBuf {
    if g == 0 {
        return base.to_path_buf();
    }
    let stem = base
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match base.extension() {
        Some(e) => format!("{stem}-{g}.{}", e.to_string_lossy()),
        None => format!("{stem}-{g}"),
    };
    base.with_file_name(name)
}

/// The earlier merge of `--from FILE`: its record, read within the budget. Only a regular file is read
/// (a fifo would block, a device never end), and what is read is bounded as it is read (its size as
/// the file system gives it may be wrong): reading it and its parse take about four times its bytes.
fn previous(file: &Path, budget: &Budget) -> Result<Previous> {
    let text = files::read_small_text(
        file,
        budget.limit() / 4,
        "a --poses file within a quarter of the memory budget (raise it with --max-memory)",
    )
    .map_err(|e| Error::invalid(format!("--from {e}")))?;
    Previous::parse(&text, &format!("--from {}", file.display()))
}

pub(super) fn run(a: MergeArgs, budget: &Budget) -> Result<()> {
    super::check_stdout()?;
    let previous = a.from.as_deref().map(|f| previous(f, budget)).transpose()?;
    let (paths, mut inputs) = map_paths(&a, previous.as_ref(), budget)?;
    // Every map is held at once: the images now; their preparations once their explored parts are known.
    let mut total: u64 = 0;
    for p in &paths {
        let (w, h, _) = OccupancyMap::probe(p)?;
        total = total.saturating_add(u64::from(w) * u64::from(h));
    }
    budget.check(format_args!("{} maps", paths.len()), total)?;
    let outputs = Outputs::named(&a)?;
    outputs.claim(&a, paths.len(), &mut inputs)?;
    let html = a.html.as_deref().map(page::create).transpose()?;
    let names: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    let maps = paths
        .iter()
        .map(|p| OccupancyMap::load_within(p, budget, &|_, _| total))
        .collect::<Result<Vec<_>>>()?;
    for w in maps.iter().flat_map(|m| &m.warnings) {
        ogm_corners::say!(
            "ogm-corners: warning: {}",
            ogm_corners::support::error::one_line(w)
        );
    }
    // Each map at the first georeferenced map's cells, and its preparation over its explored part.
    let held = footprint::many_bytes(&maps)?;
    budget.check(
        format_args!("{} maps and their preparation", maps.len()),
        held,
    )?;
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:30} {pos}/{len} pairs, {elapsed} (eta {eta})",
        )
        .expect("valid template"),
    );
    let mut backend = super::backend_on(a.backend)?;
    let options = GlobalOptions::with_partners(a.partners as usize);
    let mut cache = cache_of(previous, &options);
    let many = merge_maps_cached(
        maps,
        &names,
        &options,
        backend.as_mut(),
        &|k, n| {
            bar.set_length(n as u64);
            bar.set_position(k as u64);
        },
        &mut cache,
    )?;
    if a.from.is_some() {
        say_reuse(&cache, &names);
    }
    bar.finish_and_clear();
    // Each group's merged map and picture are made one at a time, once the maps are placed: the
    // largest group's, beside what the set holds.
    let per_px =
        u64::from(outputs.pgm.is_some()) + 6 * u64::from(a.overlay.is_some() || html.is_some());
    let largest = many
        .frames
        .iter()
        .map(|f| u64::from(f.width) * u64::from(f.height))
        .max()
        .unwrap_or(0);
    budget.check(
        format_args!("the merged maps and pictures (the largest {largest} pixels)"),
        held.saturating_add(largest.saturating_mul(per_px)),
    )?;
    let mut doc = write_outputs(&a, &outputs, &many, html)?;
    // The alignments are the --poses file's: a later `--from` reads them there.
    doc.alignments.clear();
    write_stdout(|out| match a.format {
        super::TextOrJson::Json => {
            serde_json::to_writer_pretty(&mut *out, &doc)?;
            writeln!(out)
        }
        super::TextOrJson::Text => poses::write_text(out, &doc),
    })?;
    if many.groups() == 0 {
        return Err(Error::Declined(
            "no two maps could be placed together with confidence".to_string(),
        ));
    }
    Ok(())
}

/// The maps to merge: the earlier merge's first, in its order (so its pairs are found the same way
/// round), then the maps given that it does not list; and the input set no output may overwrite.
fn map_paths(
    a: &MergeArgs,
    previous: Option<&Previous>,
    budget: &Budget,
) -> Result<(Vec<PathBuf>, files::Inputs)> {
    let mut args: Vec<PathBuf> = previous
        .iter()
        .flat_map(|p| p.maps.iter().map(PathBuf::from))
        .collect();
    if let Some(p) = previous {
        for m in &p.maps {
            if !Path::new(m).exists() {
                return Err(Error::invalid(format!(
                    "--from {}: a map it lists, {m:?}, is not there (its paths are as given to that \
                     merge: run this one from the same folder)",
                    a.from.as_deref().unwrap_or(Path::new("")).display()
                )));
            }
        }
    }
    let listed = args.len();
    args.extend(a.maps.iter().cloned());
    let (mut paths, inputs) = super::map_inputs(&args, budget, &|_, _| 0)?;
    // A map given again that the earlier merge lists is taken once (a map given twice otherwise is
    // placed with its first copy, as always).
    if previous.is_some() {
        let id = |p: &PathBuf| std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        let old: std::collections::HashSet<PathBuf> = paths[..listed].iter().map(id).collect();
        let mut k = 0;
        paths.retain(|p| {
            k += 1;
            k <= listed || !old.contains(&id(p))
        });
    }
    if paths.len() < 2 {
        return Err(Error::invalid(format!(
            "merge needs at least two maps; found {}",
            paths.len()
        )));
    }
    Ok((paths, inputs))
}

/// The merged maps' files `-o` names (its yaml and image).
struct Outputs {
    yaml: Option<PathBuf>,
    pgm: Option<PathBuf>,
}

impl Outputs {
    fn named(a: &MergeArgs) -> Result<Self> {
        let (yaml, pgm) = save_names(a.output.as_deref())?;
        Ok(Outputs { yaml, pgm })
    }

    /// Every file the run may write, checked against the inputs before any work (at most one group
    /// per two of `maps`), and every output folder for being there and writable.
    fn claim(&self, a: &MergeArgs, maps: usize, inputs: &mut files::Inputs) -> Result<()> {
        for g in 0..maps / 2 {
            for (p, what) in [
                (&self.yaml, "-o"),
                (&self.pgm, "-o"),
                (&a.overlay, "--overlay"),
            ] {
                if let Some(p) = p {
                    inputs.claim_output(&group_path(p, g), what)?;
                }
            }
        }
        for (p, what) in [(&a.poses, "--poses"), (&a.init_poses, "--init-poses")] {
            if let Some(p) = p {
                inputs.claim_output(p, what)?;
            }
        }
        if let Some(dir) = &a.html {
            inputs.claim_output(&dir.join(ogm_corners::support::report::INDEX), "--html")?;
            for file in page::picture_files(maps) {
                inputs.claim_output(&dir.join(file), "--html")?;
            }
        }
        // A missing output folder is found now, not after the work.
        for p in [&self.yaml, &self.pgm, &a.overlay, &a.poses, &a.init_poses]
            .into_iter()
            .flatten()
        {
            files::check_writable(p)?;
        }
        Ok(())
    }
}

/// The alignments an earlier merge recorded, where they were made as these options make them.
fn cache_of(previous: Option<Previous>, options: &GlobalOptions) -> Cache {
    match previous {
        Some(p) if !p.fits(options) => {
            ogm_corners::say!(
                "ogm-corners: note: --from: its alignments were made by another version or with other \
                 options ({}); every pair is aligned again",
                p.options
            );
            Cache::new()
        }
        Some(p) => p.cache(options),
        None => Cache::new(),
    }
}

/// Says how much of `--from`'s alignments the merge took up, and why the first refused one was.
fn say_reuse(cache: &Cache, names: &[String]) {
    let used = cache.last_use();
    if let Some((i, j, why)) = cache.refused().first() {
        ogm_corners::say!(
            "ogm-corners: note: --from: {} of its pairs' alignments do not hold on the maps and were \
             not taken up (the first, {} onto {}: {})",
            used.pairs_refused,
            ogm_corners::support::error::one_line(&names[*j]),
            ogm_corners::support::error::one_line(&names[*i]),
            why
        );
    }
    ogm_corners::say!(
        "ogm-corners: --from: {} pairs taken up, {} aligned",
        used.pairs_reused,
        used.pairs_aligned
    );
}

/// Every output staged, then all renamed into place together (a failure leaves none of them): each
/// group's merged map and picture, the poses, the init poses and the report; the poses document.
fn write_outputs(
    a: &MergeArgs,
    outputs: &Outputs,
    many: &ManyMerge,
    html: Option<Report>,
) -> Result<poses::Poses> {
    let mut doc = many.report.clone();
    let mut staged = files::Staged::default();
    for g in 0..many.groups() {
        if let Some(pgm) = &outputs.pgm {
            let pgm = group_path(pgm, g);
            let merged = many.merged(g)?;
            staged.write(&pgm, |out| write_merged_pgm_to(&merged, out))?;
            doc.groups[g].merged = Some(pgm.display().to_string());
            if let Some(yaml) = &outputs.yaml {
                let yaml = group_path(yaml, g);
                let text = merged_yaml_text(&pgm, &merged, "the group's first map");
                staged.write(&yaml, |out| out.write_all(text.as_bytes()))?;
                doc.groups[g].merged = Some(yaml.display().to_string());
            }
        }
        if let Some(png) = &a.overlay {
            let png = group_path(png, g);
            let picture = many.overlay_with_legend(g)?;
            staged.write(&png, |out| files::encode_png(out, &picture))?;
            doc.groups[g].overlay = Some(png.display().to_string());
        }
    }
    if let Some(p) = &a.poses {
        staged.write(p, |out| {
            serde_json::to_writer_pretty(&mut *out, &doc)?;
            writeln!(out)
        })?;
    }
    if let Some(p) = &a.init_poses {
        let text = poses::init_poses_yaml(&doc)?;
        if doc.maps.iter().all(|m| m.world.is_none()) {
            ogm_corners::say!(
                "ogm-corners: note: {}: no placed map has a world frame (a yaml), so it lists none",
                p.display()
            );
        }
        staged.write(p, |out| out.write_all(text.as_bytes()))?;
    }
    // The report is written before anything is committed (a failure in it leaves no output), and moved
    // into its folder after the rest.
    let html = html.map(|h| page::write(h, many)).transpose()?;
    staged.commit()?;
    if let Some(html) = html {
        let index = html.commit()?;
        ogm_corners::say!(
            "ogm-corners: wrote {}",
            ogm_corners::support::error::one_line(&index.display().to_string())
        );
    }
    Ok(doc)
}
