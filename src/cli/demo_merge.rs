//! `ogm-corners demo` (no arguments): the whole job on a synthetic building. Robots explore it, each
//! making a partial map in its own frame; each map's corners are found; the maps are merged with no
//! known poses; and the placement is checked against the truth the simulation knows. One line a step,
//! with its time.

use std::time::Instant;

use serde_json::json;

use ogm_corners::map::{merged_yaml_text, write_merged_pgm_to, yaml_text, GeoRef};
use ogm_corners::measure::synthetic::{explore, Exploration, SyntheticCrop};
use ogm_corners::merge::footprint;
use ogm_corners::merge::many::{merge_maps, GlobalOptions, ManyMerge};
use ogm_corners::merge::Rigid;
use ogm_corners::support::files;
use ogm_corners::support::memory::Budget;
use ogm_corners::support::plot;
use ogm_corners::{map::synthetic, Error, MapImage, OccupancyMap, Result};

use super::demo::DemoArgs;
use super::write_stdout;

/// The robots' cells, metres (the 5 cm of most ROS maps).
const RESOLUTION: f64 = 0.05;

/// The smallest building, pixels: a few rooms, so that the robots' maps can overlap (seeds 1-6 place
/// every robot at the default 1024x768; at 512x384 a robot's map may hold too little to place).
const MIN_SIDE: (u32, u32) = (512, 384);

/// Bytes a pixel of the building the exploration holds at its peak (measured 52-61 at 4096x3072 and
/// 8192x6144, with margin).
const BYTES_PER_PIXEL: u64 = 72;

pub(super) fn run(a: &DemoArgs, budget: &Budget) -> Result<()> {
    let (w, h) = a.size;
    let dir = &a.output;
    super::check_stdout()?;
    check_size(w, h, budget)?;
    files::create_dir(dir)?;
    let mut lines = Vec::new();
    let total = Instant::now();
    let building = make_building(a, &mut lines)?;
    let (robots, names, maps) = explore_building(a, &building, &mut lines)?;
    let corners = find_corners(a, &maps, &mut lines)?;
    budget.check(
        format_args!("merging {} robots' maps", maps.len()),
        footprint::many_bytes(&maps)?,
    )?;
    let t = Instant::now();
    let mut backend = super::backend_on(a.opts.backend)?;
    let many = merge_maps(
        maps,
        &names,
        &GlobalOptions::default(),
        backend.as_mut(),
        &|_, _| {},
    )?;
    let placed: usize = many
        .run
        .placement
        .groups
        .iter()
        .map(Vec::len)
        .max()
        .unwrap_or(0);
    lines.push(format!(
        "4. merged with no initial poses: {placed} of {} maps placed in one map: {}",
        many.maps.len(),
        ms(t)
    ));
    let report = placements_against_truth(&many, &robots, &names, &mut lines);
    let t = Instant::now();
    let wrote = write_outputs(dir, &many, &names, &corners, report, budget)?;
    lines.push(format!("5. outputs written: {}", ms(t)));
    lines.push(format!("all in {}", ms(total)));
    write_stdout(|out| {
        for l in &lines {
            writeln!(out, "{l}")?;
        }
        for p in &wrote {
            writeln!(
                out,
                "wrote {}",
                ogm_corners::support::error::one_line(&p.display().to_string())
            )?;
        }
        Ok(())
    })?;
    if many.groups() == 0 {
        return Err(Error::Declined(
            "the robots' maps could not be placed together with confidence".to_string(),
        ));
    }
    Ok(())
}

/// Refuses a building too small for robots to overlap in, over 2^32 pixels, or whose exploration the
/// memory budget cannot hold.
fn check_size(w: u32, h: u32, budget: &Budget) -> Result<()> {
    // The office is made at half the size and doubled, so that its rooms are as large in pixels as a
    // real 5 cm map's (at its own scale a window of it is a dense grid of small alike rooms).
    if w < MIN_SIDE.0 || h < MIN_SIDE.1 {
        return Err(Error::invalid(format!(
            "demo --size {w}x{h}: robots need a building of at least {}x{} to explore and to \
             overlap; demo --detect-only takes smaller maps",
            MIN_SIDE.0, MIN_SIDE.1
        )));
    }
    if u64::from(w) * u64::from(h) > u64::from(u32::MAX) {
        return Err(Error::invalid(format!(
            "demo --size {w}x{h}: over the {} pixels a building may have",
            u32::MAX
        )));
    }
    synthetic::check_office_size(w / 2, h / 2)?;
    // What the exploration holds at its peak, measured: about 50-60 bytes a pixel of the building (its
    // states, the drivable cells and their order of reach, the cells each pose sees, the robots' maps).
    budget.check(
        format_args!("demo --size {w}x{h}"),
        u64::from(w) * u64::from(h) * BYTES_PER_PIXEL,
    )
}

/// Step 1: the synthetic office, made at half the size and doubled.
fn make_building(a: &DemoArgs, lines: &mut Vec<String>) -> Result<OccupancyMap> {
    let (w, h) = a.size;
    let t = Instant::now();
    let half = synthetic::office_map(w / 2, h / 2, a.seed)?;
    let (bw, bh) = (half.width() * 2, half.height() * 2);
    let px = (0..bh)
        .flat_map(|y| (0..bw).map(move |x| (x, y)))
        .map(|(x, y)| half.get(x / 2, y / 2))
        .collect();
    let building = OccupancyMap::from_image(MapImage::new(bw, bh, px)?);
    lines.push(format!(
        "1. a {bw}x{bh} synthetic office building ({:.0} x {:.0} m at {RESOLUTION} m a cell, seed {}): {}",
        f64::from(bw) * RESOLUTION,
        f64::from(bh) * RESOLUTION,
        a.seed,
        ms(t)
    ));

    Ok(building)
}

/// Step 2: the robots explore the building, each map in its own frame; their names and maps.
fn explore_building(
    a: &DemoArgs,
    building: &OccupancyMap,
    lines: &mut Vec<String>,
) -> Result<(Vec<SyntheticCrop>, Vec<String>, Vec<OccupancyMap>)> {
    let t = Instant::now();
    let how = Exploration {
        robots: a.robots as usize,
        ..Exploration::default()
    };
    let robots = explore(building, &how, a.seed).ok_or_else(|| {
        Error::invalid(
            "the robots found no room to drive in, or a robot's map would be over 16384 px a side: \
             try another --seed or a smaller --size",
        )
    })?;
    let names: Vec<String> = (1..=robots.len()).map(|k| format!("robot-{k}")).collect();
    let maps: Vec<OccupancyMap> = robots
        .iter()
        .map(|r| OccupancyMap {
            georef: Some(GeoRef {
                resolution: RESOLUTION,
                origin: [0.0; 3],
            }),
            ..r.map.clone()
        })
        .collect();
    lines.push(format!(
        "2. {} robots explored it ({:.0} m sensor range), each map in its own frame, the poses kept from \
         the merger: {}",
        robots.len(),
        how.range * RESOLUTION,
        ms(t)
    ));

    Ok((robots, names, maps))
}

/// Step 3: each robot's map's corners.
fn find_corners(
    a: &DemoArgs,
    maps: &[OccupancyMap],
    lines: &mut Vec<String>,
) -> Result<Vec<Vec<ogm_corners::Keypoint>>> {
    let t = Instant::now();
    let mut detector = a.opts.detector()?;
    let mut corners = Vec::with_capacity(maps.len());
    for m in maps {
        corners.push(detector.detect(m)?.keypoints);
    }
    let counts: Vec<String> = corners.iter().map(|c| c.len().to_string()).collect();
    lines.push(format!(
        "3. corners ({}, {}): {} in the robots' maps: {}",
        detector.options().detector.name(),
        detector.backend_name(),
        counts.join(", "),
        ms(t)
    ));

    Ok(corners)
}

/// Each robot's placement against the truth, in the frame of its group's first map: a line for each
/// placed one (and for each not placed), and its entry for poses.json.
fn placements_against_truth(
    many: &ManyMerge,
    robots: &[SyntheticCrop],
    names: &[String],
    lines: &mut Vec<String>,
) -> Vec<serde_json::Value> {
    let mut report = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let group = many
            .run
            .placement
            .groups
            .iter()
            .position(|g| g.contains(&k));
        let entry = match group {
            Some(g) => {
                let first = many.run.placement.groups[g][0];
                let pose = many.run.placement.maps[k].pose;
                let truth = robots[k].true_pair(&robots[first], name, &names[first]);
                let (deg, px) = truth.errors(&pose);
                if k != first {
                    lines.push(format!(
                        "   {name}: placed {:.1} deg, ({:.0}, {:.0}) px from {}; the truth differs by \
                         {deg:.2} deg, {px:.2} px",
                        pose.theta_deg, pose.tx, pose.ty, names[first]
                    ));
                }
                let to_canvas = many.frames[g].to_canvas(&pose);
                json!({"name": name, "group": g, "frame_of": names[first],
                       "pose": rigid_json(&pose), "truth": json!({"theta_deg": truth.theta_deg, "tx": truth.tx, "ty": truth.ty}),
                       "error_deg": deg, "error_px": px,
                       "to_merged_px": rigid_json(&to_canvas)})
            }
            None => {
                lines.push(format!("   {name}: not placed"));
                json!({"name": name, "group": null})
            }
        };
        report.push(entry);
    }

    report
}

/// Step 5: every output staged, then renamed into place together; the files written.
fn write_outputs(
    dir: &std::path::Path,
    many: &ManyMerge,
    names: &[String],
    corners: &[Vec<ogm_corners::Keypoint>],
    report: Vec<serde_json::Value>,
    budget: &Budget,
) -> Result<Vec<std::path::PathBuf>> {
    let maps = &many.maps;
    let mut staged = files::Staged::default();
    let mut wrote = Vec::new();
    for (m, name) in maps.iter().zip(names) {
        let pgm = dir.join(format!("{name}.pgm"));
        let yaml = dir.join(format!("{name}.yaml"));
        staged.write(&pgm, |out| m.image.write_pgm_to(out))?;
        let text = yaml_text(&pgm, m, name);
        staged.write(&yaml, |out| out.write_all(text.as_bytes()))?;
        wrote.push(yaml);
    }
    let csv = dir.join("corners.csv");
    staged.write(&csv, |out| {
        writeln!(out, "robot,x,y,merged_x,merged_y")?;
        for (k, c) in corners.iter().enumerate() {
            let to_merged = placement_on_canvas(many, k);
            for p in c {
                write!(out, "{},{},{}", names[k], p.x, p.y)?;
                match to_merged {
                    Some(t) => {
                        let (x, y) = t.apply((f64::from(p.x), f64::from(p.y)));
                        writeln!(out, ",{x:.1},{y:.1}")?;
                    }
                    None => writeln!(out, ",,")?,
                }
            }
        }
        Ok(())
    })?;
    wrote.push(csv);
    if many.groups() > 0 {
        let g = 0;
        // The merged map (a byte a pixel) and the picture (three, and two for its owners), counted first.
        let f = &many.frames[g];
        budget.check(
            format_args!("the merged map and picture ({}x{})", f.width, f.height),
            u64::from(f.width) * u64::from(f.height) * 6,
        )?;
        let merged = many.merged(g)?;
        let pgm = dir.join("merged.pgm");
        let yaml = dir.join("merged.yaml");
        staged.write(&pgm, |out| write_merged_pgm_to(&merged, out))?;
        let text = merged_yaml_text(&pgm, &merged, &names[many.run.placement.groups[g][0]]);
        staged.write(&yaml, |out| out.write_all(text.as_bytes()))?;
        wrote.push(yaml);
        let picture = picture(many, g, corners)?;
        let png = dir.join("demo.png");
        staged.write(&png, |out| files::encode_png(out, &picture))?;
        wrote.push(png);
    }
    let poses = dir.join("poses.json");
    let doc = json!({"robots": report, "resolution_m": RESOLUTION,
                     "note": "pose: the robot's map pixels to its group's first map's pixels; truth: the simulation's; to_merged_px: to merged.pgm's pixels"});
    staged.write(&poses, |out| {
        serde_json::to_writer_pretty(&mut *out, &doc)?;
        writeln!(out)
    })?;
    wrote.push(poses);
    staged.commit()?;
    // A folder used before may hold outputs this run did not write (more robots then, or a merge this
    // run declined): said, so that nobody reads them as this run's. They are the user's files to keep.
    for p in earlier_outputs(dir, names.len(), many.groups() > 0) {
        ogm_corners::say!(
            "ogm-corners: note: {} is from an earlier run, not this one",
            ogm_corners::support::error::one_line(&p.display().to_string())
        );
    }
    Ok(wrote)
}

/// The demo's outputs in `dir` that a run of `robots` robots (`merged`: the merge written) did not write:
/// `robot-K.pgm`/`.yaml` for K past `robots`, and the merged map and picture of a declined merge.
fn earlier_outputs(dir: &std::path::Path, robots: usize, merged: bool) -> Vec<std::path::PathBuf> {
    let mut out: Vec<std::path::PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            let stem = name
                .strip_suffix(".pgm")
                .or_else(|| name.strip_suffix(".yaml"));
            stem.and_then(|s| s.strip_prefix("robot-"))
                .and_then(|k| k.parse::<usize>().ok())
                .is_some_and(|k| k > robots)
        })
        .collect();
    if !merged {
        out.extend(
            ["merged.pgm", "merged.yaml", "demo.png"]
                .iter()
                .map(|n| dir.join(n))
                .filter(|p| p.exists()),
        );
    }
    out.sort();
    out
}

/// Milliseconds since `t`, for people.
fn ms(t: Instant) -> String {
    format!("{:.0} ms", t.elapsed().as_secs_f64() * 1e3)
}

fn rigid_json(t: &Rigid) -> serde_json::Value {
    json!({"theta_deg": t.theta_deg, "tx": t.tx, "ty": t.ty})
}

/// Robot `k`'s pixels to its group's merged map's pixels, when it is placed in the first group (the
/// one written).
fn placement_on_canvas(many: &ogm_corners::merge::many::ManyMerge, k: usize) -> Option<Rigid> {
    let g = many.run.placement.groups.first()?;
    g.contains(&k)
        .then(|| many.frames[0].to_canvas(&many.run.placement.maps[k].pose))
}

/// Group `g`'s picture: each robot's walls in its colour, its corners as black crosses, a legend.
fn picture(
    many: &ogm_corners::merge::many::ManyMerge,
    g: usize,
    corners: &[Vec<ogm_corners::Keypoint>],
) -> Result<image::RgbImage> {
    let mut img = many.overlay(g)?;
    let black = image::Rgb([0, 0, 0]);
    for &k in &many.run.placement.groups[g] {
        let t = many.frames[g].to_canvas(&many.run.placement.maps[k].pose);
        for p in &corners[k] {
            let (x, y) = t.apply((f64::from(p.x), f64::from(p.y)));
            let (x, y) = (x.round() as i64, y.round() as i64);
            for d in -3i64..=3 {
                for (cx, cy) in [(x + d, y), (x, y + d)] {
                    if cx >= 0
                        && cy >= 0
                        && cx < i64::from(img.width())
                        && cy < i64::from(img.height())
                    {
                        img.put_pixel(cx as u32, cy as u32, black);
                    }
                }
            }
        }
    }
    let mut entries: Vec<(String, image::Rgb<u8>)> = many
        .legend(g)
        .into_iter()
        .map(|(m, c)| (m.to_string(), c))
        .collect();
    entries.push(("corners".to_string(), black));
    Ok(plot::with_legend(&img, &entries))
}
