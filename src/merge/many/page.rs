//! The `merge A B C ... --html` page: every map's placement (maps left out first), every pair's verdict,
//! the merges the placement dropped, each group's picture with its maps' colours, and each map alone.

use std::path::Path;

use crate::merge::many::merged::ManyMerge;
use crate::support::error::Result;
use crate::support::report::{file_name, Cell, Report, Staged, Table};

/// Width of the box a group's picture is fitted into, pixels.
pub const GROUP_PICTURE: u32 = 1000;

/// Side of the box each map's own picture is fitted into, pixels.
pub const MAP_PICTURE: u32 = 300;

/// The maps' table (`id="maps"`): maps left out first, then by group.
pub fn maps_table(many: &ManyMerge) -> Table {
    let mut t = Table::new(
        "maps",
        "Every map: its group, and its pose in the group's merged map (pixels, degrees)",
        &[
            ("#", true),
            ("map", false),
            ("placed", false),
            ("group", true),
            ("θ °", true),
            ("x px", true),
            ("y px", true),
            ("resolution ratio", true),
            ("why not placed / copy of", false),
        ],
    );
    let doc = &many.report;
    let mut order: Vec<usize> = (0..doc.maps.len()).collect();
    order.sort_by_key(|&m| (doc.maps[m].placed, doc.maps[m].group, m));
    for m in order {
        let e = &doc.maps[m];
        let tf = e.transform;
        let note = e
            .reason
            .clone()
            .or_else(|| e.copy_of.as_ref().map(|c| format!("copy of {c}")))
            .unwrap_or_default();
        t.row_with(
            vec![
                Cell::int(m as i128),
                Cell::text(&e.map),
                Cell::text(if e.placed { "yes" } else { "no" }),
                Cell::opt(e.group.map(|g| g as f64), 0),
                Cell::opt(tf.map(|t| t.theta_deg), 1),
                Cell::opt(tf.map(|t| t.tx), 1),
                Cell::opt(tf.map(|t| t.ty), 1),
                Cell::opt(e.scale, 3),
                Cell::text(note),
            ],
            Some(if e.placed { "good" } else { "warn" }),
        );
    }
    t
}

/// The pairs' table (`id="pairs"`): every pair the pair test saw, accepted ones first.
pub fn pairs_table(many: &ManyMerge) -> Table {
    let mut t = Table::new(
        "pairs",
        "Every pair aligned (in a large set, those the pre-screen chose): B (moved) onto A (reference), the pair test's verdict and score (the rule's value minus its threshold)",
        &[
            ("A", false),
            ("B", false),
            ("accepted", false),
            ("score", true),
            ("θ °", true),
            ("x px", true),
            ("y px", true),
            ("why declined", false),
        ],
    );
    let name = |i: usize| many.report.maps[i].map.as_str();
    let mut pairs: Vec<_> = many.run.pairwise.pairs.iter().collect();
    pairs.sort_by_key(|p| !p.accepted);
    for p in pairs {
        t.row_with(
            vec![
                Cell::text(name(p.a)),
                Cell::text(name(p.b)),
                Cell::text(if p.accepted { "yes" } else { "no" }),
                Cell::num(p.score, 3),
                Cell::num(p.transform.theta_deg, 1),
                Cell::num(p.transform.tx, 1),
                Cell::num(p.transform.ty, 1),
                Cell::text(p.reason.as_deref().unwrap_or("")),
            ],
            p.accepted.then_some("good"),
        );
    }
    t
}

/// The dropped merges' table (`id="dropped"`).
pub fn dropped_table(many: &ManyMerge) -> Table {
    let mut t = Table::new(
        "dropped",
        "Pairs the pair test accepted but the placement did not use, and why",
        &[("A", false), ("B", false), ("why", false)],
    );
    for d in &many.report.dropped {
        t.row_with(
            vec![Cell::text(&d.a), Cell::text(&d.b), Cell::text(&d.reason)],
            Some("warn"),
        );
    }
    t
}

/// The page's pictures in its folder for `maps` maps: at most one group per two maps, and each map.
pub fn picture_files(maps: usize) -> Vec<String> {
    (0..maps / 2)
        .map(|g| file_name(g, "group", ""))
        .chain((0..maps).map(|m| file_name(m, "map", "")))
        .collect()
}

/// A page for `merge` in `dir` (made now, so that a bad folder is found before the work).
pub fn create(dir: &Path) -> Result<Report> {
    Report::create(dir, "ogm-corners merge")
}

/// Writes the whole page (made by [`create`]) into its staging folder; [`Staged::commit`] moves it into
/// place.
pub fn write(mut page: Report, many: &ManyMerge) -> Result<Staged> {
    let doc = &many.report;
    let placed = doc.maps.iter().filter(|m| m.placed).count();
    page.text(format!(
        "{} maps: {} placed in {} groups, {} left out. {} pairs aligned, {} accepted by the pair test, {} of \
         those dropped by the placement. {:.2} s. Click a column to sort.",
        doc.maps.len(),
        placed,
        doc.groups.len(),
        doc.maps.len() - placed,
        doc.pairs_aligned,
        doc.pairs_accepted,
        doc.dropped.len(),
        doc.seconds
    ));
    page.table(maps_table(many));
    for g in 0..many.groups() {
        let entry = &doc.groups[g];
        page.heading(format!(
            "Group {g}: {} maps, {}x{} pixels, in the frame of {}",
            entry.maps.len(),
            entry.width,
            entry.height,
            entry.maps.first().map_or("", String::as_str)
        ));
        let legend = many.legend(g);
        page.legend(&legend);
        let full = many.overlay(g)?;
        let full =
            crate::support::plot::crop_to_content(&full, crate::merge::compose::OVERLAY_UNKNOWN, 4);
        // Walls (any map's colour) survive a shrink before free space, free space before unknown.
        let picture =
            crate::support::plot::fit_image(&full, GROUP_PICTURE, GROUP_PICTURE, |p| match p {
                crate::merge::compose::OVERLAY_UNKNOWN => 0,
                image::Rgb([255, 255, 255]) => 1,
                _ => 2,
            });
        let caption = vec![
            format!("group {g}: each map's walls in its colour"),
            "free space white, unknown grey".to_string(),
        ];
        let figure = page.picture(&file_name(g, "group", ""), &picture, caption)?;
        page.figures_at(vec![figure], 700);
    }
    page.heading("The pairs aligned");
    page.table(pairs_table(many));
    if !doc.dropped.is_empty() {
        page.table(dropped_table(many));
    }
    page.heading("Each map as given (at the merge's resolution)");
    let mut figures = Vec::new();
    for (m, (map, e)) in many.maps.iter().zip(&doc.maps).enumerate() {
        let picture =
            crate::detect::overlay::render_overlay_fit(&map.image, &[], MAP_PICTURE, MAP_PICTURE);
        let status = match e.group {
            Some(g) => format!("group {g}"),
            None => "not placed".to_string(),
        };
        let mut figure = page.picture(
            &file_name(m, "map", ""),
            &picture,
            vec![format!("#{m} {}", e.map), status],
        )?;
        figure.class = Some(if e.placed { "good" } else { "warn" });
        figures.push(figure);
    }
    page.figures_at(figures, 240);
    page.stage()
}
