//! What `merge A B C ...` reports: each map's pose in its group's merged map (the `--poses` JSON and the
//! text verdict), and the multirobot_map_merge parameters (`--init-poses`).

use std::io::{self, Write};

use serde::Serialize;

use crate::map::OccupancyMap;
use crate::merge::many::graph::Placement;
use crate::merge::many::mosaic::Frame;
use crate::merge::many::Pairwise;
use crate::merge::transform::{to_world, Rigid, WorldRigid};

/// One map's entry.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MapEntry {
    /// Its path as given.
    pub map: String,
    /// Whether it is placed.
    pub placed: bool,
    /// Its group (maps placed together); `null` when not placed.
    pub group: Option<usize>,
    /// Its pixels to its group's merged-map pixels (at the group's resolution: see `scale`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub transform: Option<Rigid>,
    /// Its map frame's pose in the merged map's frame (metres, radians), when both have a yaml.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub world: Option<WorldRigid>,
    /// Its resolution over the first georeferenced input map's (that map's pixels a pixel of its own),
    /// when they differ: every map is resampled to that resolution before aligning, and `transform`
    /// applies to the resampled pixels (its own pixel coordinates times about this).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<f64>,
    /// Why it is not placed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// The map given earlier that it is a copy of (the same pixels): aligned once, placed with it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub copy_of: Option<String>,
    /// Its content id (32 hex digits, [`crate::merge::many::content_id`] of the map as aligned): what the
    /// alignments below name it by when a later run takes them up (`merge --from`).
    pub content: String,
}

/// One aligned pair's record, as a later run takes it up ([`crate::merge::many::Cache::carry`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AlignmentEntry {
    /// The reference map.
    pub a: String,
    /// The moved map.
    pub b: String,
    /// Its alignment.
    pub alignment: crate::merge::many::PairRecord,
}

/// One group's entry.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GroupEntry {
    /// Its id.
    pub id: usize,
    /// Its maps (paths as given), its frame's map first.
    pub maps: Vec<String>,
    /// The merged map's size, pixels.
    pub width: u32,
    /// See `width`.
    pub height: u32,
    /// Where its merged map was written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub merged: Option<String>,
    /// Where its picture was written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub overlay: Option<String>,
}

/// An accepted pairwise merge the placement did not use.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DroppedEntry {
    /// The reference map.
    pub a: String,
    /// The moved map.
    pub b: String,
    /// Why.
    pub reason: String,
}

/// The whole report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Poses {
    /// One entry per input map, in the order given.
    pub maps: Vec<MapEntry>,
    /// The groups.
    pub groups: Vec<GroupEntry>,
    /// Accepted pairwise merges the placement dropped.
    pub dropped: Vec<DroppedEntry>,
    /// Pairs aligned.
    pub pairs_aligned: usize,
    /// Of them, accepted by the pair test.
    pub pairs_accepted: usize,
    /// Pairs the pre-screen left out (a large set: each map aligned with its most similar maps, then
    /// the pairs that close cycles).
    pub pairs_screened_out: usize,
    /// Seconds, end to end (reading the maps aside).
    pub seconds: f64,
    /// The options the alignments were made with ([`options_id`]): a later run takes them up only
    /// under the same.
    pub alignments_of: String,
    /// Every aligned pair's record, in the pairs' order (the `--poses` file's; left out of the report
    /// on standard output).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub alignments: Vec<AlignmentEntry>,
}

/// What the pair alignments depend on besides the maps: this build's version and the alignment's
/// options (which pairs a pre-screen chooses aside), as a short id.
pub fn options_id(options: &crate::merge::many::GlobalOptions) -> String {
    let options = crate::merge::many::GlobalOptions {
        prescreen: None,
        ..*options
    };
    let text = format!("{} {options:?}", env!("CARGO_PKG_VERSION"));
    format!(
        "{} {:016x}",
        env!("CARGO_PKG_VERSION"),
        xxhash_rust::xxh3::xxh3_64(text.as_bytes())
    )
}

/// The report of `run` of `maps` (named `names`; `scales` as [`MapEntry::scale`]), each group's
/// canvas in `frames`.
pub fn poses(
    names: &[String],
    maps: &[OccupancyMap],
    scales: &[Option<f64>],
    run: &crate::merge::many::Run,
    frames: &[Frame],
    seconds: f64,
    options: &crate::merge::many::GlobalOptions,
) -> Poses {
    let (pairwise, placement): (&Pairwise, &Placement) = (&run.pairwise, &run.placement);
    let copy_of = |m: usize| run.duplicate_of[m].map(|d| names[d].clone());
    let entries = placement
        .maps
        .iter()
        .enumerate()
        .map(|(m, p)| {
            let Some(g) = p.group else {
                return MapEntry {
                    map: names[m].clone(),
                    placed: false,
                    group: None,
                    transform: None,
                    world: None,
                    scale: scales[m],
                    reason: p.reason.clone(),
                    copy_of: copy_of(m),
                    content: format!("{:032x}", crate::merge::many::content_id(&maps[m])),
                };
            };
            let first = placement.groups[g][0];
            let world = match (maps[first].georef, maps[m].georef) {
                (Some(ga), Some(gm)) => Some(to_world(
                    &p.pose,
                    &ga,
                    maps[first].image.height(),
                    &gm,
                    maps[m].image.height(),
                )),
                _ => None,
            };
            MapEntry {
                map: names[m].clone(),
                placed: true,
                group: Some(g),
                transform: Some(frames[g].to_canvas(&p.pose)),
                world,
                scale: scales[m],
                reason: None,
                copy_of: copy_of(m),
                content: format!("{:032x}", crate::merge::many::content_id(&maps[m])),
            }
        })
        .collect();
    let groups = placement
        .groups
        .iter()
        .enumerate()
        .map(|(g, members)| GroupEntry {
            id: g,
            maps: members.iter().map(|&m| names[m].clone()).collect(),
            width: frames[g].width,
            height: frames[g].height,
            merged: None,
            overlay: None,
        })
        .collect();
    Poses {
        maps: entries,
        groups,
        dropped: placement
            .dropped
            .iter()
            .map(|d| DroppedEntry {
                a: names[d.edge.a].clone(),
                b: names[d.edge.b].clone(),
                reason: d.reason.clone(),
            })
            .collect(),
        pairs_aligned: pairwise.pairs.len(),
        pairs_accepted: pairwise.pairs.iter().filter(|p| p.accepted).count(),
        pairs_screened_out: pairwise.screened_out,
        seconds,
        alignments_of: options_id(options),
        alignments: run
            .records
            .iter()
            .map(|(a, b, r)| AlignmentEntry {
                a: names[*a].clone(),
                b: names[*b].clone(),
                alignment: r.clone(),
            })
            .collect(),
    }
}

/// The text verdict: a line per map, then the groups and the totals.
pub fn write_text(out: &mut dyn Write, doc: &Poses) -> io::Result<()> {
    use crate::support::error::one_line;
    for m in &doc.maps {
        // Names escaped, as errors are: a newline in a file name must not split a record, an escape
        // sequence must not reach the terminal.
        let (name, copy_of) = (one_line(&m.map), m.copy_of.as_deref().map(one_line));
        match (&m.group, &m.transform) {
            (Some(g), Some(t)) => {
                write!(
                    out,
                    "{}: group {g}, {:.2} deg, ({:.1}, {:.1}) px",
                    name, t.theta_deg, t.tx, t.ty
                )?;
                if let Some(w) = m.world {
                    write!(out, " = {w}")?;
                }
                if let Some(k) = m.scale {
                    write!(
                        out,
                        " (resampled: {k} merged-map pixels a pixel of its own)"
                    )?;
                }
                if let Some(c) = &copy_of {
                    write!(out, " (a copy of {c})")?;
                }
                writeln!(out)?;
            }
            _ => writeln!(
                out,
                "{}: not placed: {}",
                name,
                one_line(m.reason.as_deref().unwrap_or("not confident"))
            )?,
        }
    }
    let placed = doc.maps.iter().filter(|m| m.placed).count();
    let screened = match doc.pairs_screened_out {
        0 => String::new(),
        k => format!(" ({k} more left out by the pre-screen)"),
    };
    writeln!(
        out,
        "{placed} of {} maps placed in {} group(s); {} pairs aligned{screened}, {} accepted, {} of those \
         dropped as inconsistent; {:.1} s",
        doc.maps.len(),
        doc.groups.len(),
        doc.pairs_aligned,
        doc.pairs_accepted,
        doc.dropped.len(),
        doc.seconds
    )
}

/// The multirobot_map_merge parameters of the placed maps (`rosparam load` format): per robot (the map's
/// file stem; a repeated stem gets its map's number), `map_merge/init_pose_{x,y,z,yaw}`: the pose of
/// its map frame in its group's merged frame, after a comment naming the map. Maps without a yaml or not
/// placed are listed as comments. A robot name that is not a plain identifier is written quoted (a
/// newline or a colon in a file name stays inside its key); a pose that is not finite (an origin so
/// large that it overflows) is refused, naming the map: a YAML reader would take `inf` for a string.
pub fn init_poses_yaml(doc: &Poses) -> crate::support::error::Result<String> {
    use crate::support::error::one_line;
    let mut s = String::from(
        "# multirobot_map_merge with known_init_poses: each robot's map frame in the merged frame of its\n\
         # group (the frame of the group's first map), as found by ogm-corners merge.\n",
    );
    let mut seen = std::collections::BTreeSet::new();
    for (k, m) in doc.maps.iter().enumerate() {
        let stem = std::path::Path::new(&m.map)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| m.map.clone());
        // Two maps of one name (in two folders) get the second its number: keys must differ.
        let mut robot = stem.clone();
        let mut extra = k;
        while !seen.insert(robot.clone()) {
            robot = format!("{stem}_{extra}");
            extra += 1;
        }
        s.push_str(&format!("# {}\n", one_line(&m.map)));
        let robot = yaml_key(&robot);
        match (m.world, m.group) {
            (Some(w), Some(g)) => {
                if ![w.x, w.y, w.yaw].iter().all(|v| v.is_finite()) {
                    return Err(crate::support::error::Error::invalid(format!(
                        "{}: its pose in the merged frame is not finite (x {}, y {}, yaw {}): its yaml's \
                         origin or resolution is out of range; no --init-poses written",
                        one_line(&m.map),
                        w.x,
                        w.y,
                        w.yaw
                    )));
                }
                s.push_str(&format!(
                    // `{:?}` keeps a decimal point: YAML reads `0` as an integer, `0.0` as a float.
                    "{robot}:  # group {g}\n  map_merge:\n    init_pose_x: {:?}\n    init_pose_y: {:?}\n    \
                     init_pose_z: 0.0\n    init_pose_yaw: {:?}\n",
                    w.x, w.y, w.yaw
                ))
            }
            (None, Some(g)) => s.push_str(&format!(
                "# {}: group {g}, but it or its group's first map has no yaml (no world frame)\n",
                one_line(&robot)
            )),
            _ => s.push_str(&format!(
                "# {}: not placed: {}\n",
                one_line(&robot),
                one_line(m.reason.as_deref().unwrap_or("not confident"))
            )),
        }
    }
    Ok(s)
}

/// `name` as a YAML mapping key: as it is when it is a plain identifier (what ROS names are) that YAML
/// reads as a string, else double-quoted with JSON's escapes (which YAML's double quotes read alike).
fn yaml_key(name: &str) -> String {
    let plain = name
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '/'))
        && !matches!(
            name.to_ascii_lowercase().as_str(),
            "true" | "false" | "yes" | "no" | "on" | "off" | "y" | "n" | "null" | "nan" | "inf"
        );
    if plain {
        name.to_string()
    } else {
        serde_json::to_string(name).unwrap_or_else(|_| "\"robot\"".to_string())
    }
}
