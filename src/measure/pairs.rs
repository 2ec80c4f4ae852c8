//! Pair sets with ground truth, for `merge-eval`: the format of `pairs.json` in the shared merge-pairs data
//! (`{"pairs": [{"src", "dst", "building", "theta_deg", "tx", "ty", "gt_rms_px", "rms_limit_px",
//! "rot_limit_deg", "src_points", "dst_points"}], "negatives": [{"src", "dst"}]}`), and its success test.
//!
//! The truth maps src pixels to dst pixels, so a pair is merged as `merge dst src` (A = dst, the reference
//! frame; B = src).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::merge::transform::Rigid;
use crate::support::error::{Error, Result};

/// Largest pair file read.
pub const MAX_PAIRS_BYTES: u64 = 64 << 20;

/// A pair of maps of one place with the true transform.
#[derive(Clone, Debug, Deserialize, Serialize)]
pub struct TruePair {
    /// The map moved (B).
    pub src: String,
    /// The reference map (A).
    pub dst: String,
    /// Which building (for per-building reports).
    #[serde(default)]
    pub building: String,
    /// True rotation src -> dst, degrees.
    pub theta_deg: f64,
    /// True translation, pixels.
    pub tx: f64,
    /// True translation, pixels.
    pub ty: f64,
    /// Largest RMS error over the annotated points an estimate may have, pixels.
    pub rms_limit_px: f64,
    /// Largest rotation error, degrees.
    pub rot_limit_deg: f64,
    /// Annotated points in src.
    pub src_points: Vec<[f64; 2]>,
    /// The same points in dst.
    pub dst_points: Vec<[f64; 2]>,
}

/// Two maps of different places: any accepted merge of them is wrong.
#[derive(Clone, Debug, Deserialize)]
pub struct Negative {
    /// The map moved.
    pub src: String,
    /// The reference map.
    pub dst: String,
}

/// A pair file.
#[derive(Clone, Debug, Deserialize)]
pub struct PairSet {
    /// Pairs of one place.
    pub pairs: Vec<TruePair>,
    /// Pairs of different places.
    #[serde(default)]
    pub negatives: Vec<Negative>,
    /// The folder of the maps, relative to the pair file (a pair file the tool writes says `.`: its maps
    /// stand beside it); absent: `maps` beside the pair file, as in the shared merge-pairs data.
    #[serde(default)]
    pub maps: Option<String>,
}

impl PairSet {
    /// Reads and checks a pair file (bounded size; finite numbers; as many points in both maps).
    pub fn load(path: &Path) -> Result<Self> {
        let text = crate::support::files::read_small_text(path, MAX_PAIRS_BYTES, "a pair file")?;
        let set: PairSet = serde_json::from_str(&text)
            .map_err(|e| Error::input(path, format!("not a pair file: {e}")))?;
        // A file of no pairs would give a table of zeros that reads as a result.
        if set.pairs.is_empty() {
            return Err(Error::input(
                path,
                "has no pairs (a pair file lists maps of one place with their true transform)",
            ));
        }
        for p in &set.pairs {
            let finite = [p.theta_deg, p.tx, p.ty, p.rms_limit_px, p.rot_limit_deg]
                .iter()
                .chain(p.src_points.iter().chain(&p.dst_points).flatten())
                .all(|v| v.is_finite());
            if !finite || p.src_points.len() != p.dst_points.len() || p.src_points.is_empty() {
                return Err(Error::input(
                    path,
                    format!(
                        "pair {} -> {}: non-finite numbers or unmatched points",
                        p.src, p.dst
                    ),
                ));
            }
            // A limit of zero or less would make every estimate wrong, silently.
            if p.rms_limit_px <= 0.0 || p.rot_limit_deg <= 0.0 {
                return Err(Error::input(
                    path,
                    format!(
                        "pair {} -> {}: the success limits must be positive (rms_limit_px {}, \
                         rot_limit_deg {})",
                        p.src, p.dst, p.rms_limit_px, p.rot_limit_deg
                    ),
                ));
            }
        }
        Ok(set)
    }
}

impl PairSet {
    /// The folder of the maps of the pair file at `path`: its `maps` entry (relative to the file's
    /// folder), else `maps` beside it.
    pub fn maps_folder(&self, path: &Path) -> std::path::PathBuf {
        let dir = path.parent().unwrap_or(Path::new("."));
        dir.join(self.maps.as_deref().unwrap_or("maps"))
    }
}

impl TruePair {
    /// The true transform (src pixels to dst pixels).
    pub fn truth(&self) -> Rigid {
        Rigid {
            theta_deg: self.theta_deg,
            tx: self.tx,
            ty: self.ty,
        }
    }

    /// The estimate's rotation error (degrees, absolute, modulo 360) and RMS error over the annotated
    /// points (pixels).
    pub fn errors(&self, estimate: &Rigid) -> (f64, f64) {
        let d = (estimate.theta_deg - self.theta_deg).rem_euclid(360.0);
        let rot = d.min(360.0 - d);
        let sum: f64 = self
            .src_points
            .iter()
            .zip(&self.dst_points)
            .map(|(s, t)| {
                let (x, y) = estimate.apply((s[0], s[1]));
                (x - t[0]).powi(2) + (y - t[1]).powi(2)
            })
            .sum();
        (rot, (sum / self.src_points.len() as f64).sqrt())
    }

    /// Whether the estimate is accurate: rotation within the limit and RMS within the limit.
    pub fn accurate(&self, estimate: &Rigid) -> bool {
        let (rot, rms) = self.errors(estimate);
        rot <= self.rot_limit_deg && rms <= self.rms_limit_px
    }
}
