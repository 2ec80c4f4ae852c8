//! Merges two robots' maps with no initial pose: aligns B onto A, prints the verdict (and where B's map
//! frame lies in A's, in metres), and writes the merged map when the merge is confident.
//!
//! ```sh
//! cargo run --release --example merge_two -- A.yaml B.yaml [MERGED.yaml]
//! ```

use std::path::Path;

use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::merge::pair::{compose_pair, merge_pair};
use ogm_corners::merge::MergeOptions;
use ogm_corners::OccupancyMap;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [a, b, rest @ ..] = args.as_slice() else {
        return Err("usage: merge_two A.yaml B.yaml [MERGED.yaml]".into());
    };
    let (ma, mb) = (
        OccupancyMap::load(Path::new(a))?,
        OccupancyMap::load(Path::new(b))?,
    );
    // B is brought to A's resolution first when they differ; the scoring runs on the CPU here.
    let merged = merge_pair(&ma, &mb, &MergeOptions::default(), &mut ReferenceBackend)?;
    let v = merged.verdict();
    let t = v.transform;
    println!(
        "{}: B -> A {:.2} deg, ({:.1}, {:.1}) px; score {:.2}, overlap {:.0}%",
        if v.accepted { "merged" } else { "not merged" },
        t.theta_deg,
        t.tx,
        t.ty,
        v.score,
        100.0 * v.overlap
    );
    if let Some(w) = v.world {
        println!("B's map frame in A's: {w}");
    }
    if let Some(reason) = &v.reason {
        println!("why not: {reason}");
    }
    // A wrong merged map is worse than none: only a confident merge is written.
    if let (true, Some(out)) = (v.accepted, rest.first()) {
        compose_pair(&ma, &mb, &t)?.save(Path::new(out))?;
        println!("wrote {out}");
    }
    Ok(())
}
