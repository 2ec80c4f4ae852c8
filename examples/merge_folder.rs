//! Merges every map in a folder (`*.yaml`) at once, as a fleet's maps with no initial poses: prints
//! each map's group and pose, and writes the largest group's merged map.
//!
//! ```sh
//! cargo run --release --example merge_folder -- DIR [MERGED.yaml]
//! ```

use std::path::{Path, PathBuf};

use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::merge::many::{merge_maps, GlobalOptions};
use ogm_corners::OccupancyMap;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = args.next().ok_or("usage: merge_folder DIR [MERGED.yaml]")?;
    let out = args.next();
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()?;
    paths.retain(|p| p.extension().is_some_and(|e| e == "yaml"));
    paths.sort();
    if paths.len() < 2 {
        return Err(format!("{dir}: fewer than two maps (*.yaml)").into());
    }
    let maps = paths
        .iter()
        .map(OccupancyMap::load)
        .collect::<Result<Vec<_>, _>>()?;
    let names: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    let many = merge_maps(
        maps,
        &names,
        &GlobalOptions::default(),
        &mut ReferenceBackend,
        &|_, _| {},
    )?;
    let placement = &many.run.placement;
    for (k, name) in names.iter().enumerate() {
        match placement.groups.iter().position(|g| g.contains(&k)) {
            Some(g) => {
                let p = placement.maps[k].pose;
                println!(
                    "{name}: group {g}, {:.2} deg, ({:.1}, {:.1}) px in {}'s frame",
                    p.theta_deg, p.tx, p.ty, names[placement.groups[g][0]]
                );
            }
            None => println!("{name}: not placed"),
        }
    }
    let largest = (0..many.groups()).max_by_key(|&g| placement.groups[g].len());
    match (largest, out) {
        (Some(g), Some(out)) => {
            many.merged(g)?.save(Path::new(&out))?;
            println!("wrote {out} ({} maps)", placement.groups[g].len());
        }
        (None, _) => println!("no two maps could be placed together with confidence"),
        _ => {}
    }
    Ok(())
}
