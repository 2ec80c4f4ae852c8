//! What a many-map placement keeps of one pair's alignment: the pair test's verdict and the candidates
//! it may use as edges ([`PairRecord`]). It is all the placement reads of a pair, small (a few hundred
//! bytes), and written to a `--poses` file exactly (every float to the bit), so that a later run given
//! that file places new maps without aligning the old pairs again, and a distributed run hands it back
//! from a worker unchanged.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::merge::many::{Edge, GlobalOptions, PairVerdict};
use crate::merge::pair::align::{not_contradicted, overlap_centre, Alignment, Prepared};
use crate::merge::transform::Rigid;

/// One usable candidate of a pair ([`Edge`] without the maps' indices).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EdgeRecord {
    /// Its rank among the pair's candidates (0: the pair's choice).
    pub rank: usize,
    /// B's pixels to A's.
    pub transform: Rigid,
    /// The pair rule's value for it.
    #[serde(with = "any_f64")]
    pub score: f64,
    /// Where it makes the maps overlap, in B's pixels ([`Edge::at`]).
    pub at: (f64, f64),
    /// [`Edge::residual`].
    #[serde(with = "any_f64")]
    pub residual: f64,
}

/// One pair's alignment as a placement uses it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairRecord {
    /// Whether the pair test accepted its choice.
    pub accepted: bool,
    /// Its choice (B's pixels to A's).
    pub transform: Rigid,
    /// Its rule value.
    #[serde(with = "any_f64")]
    pub score: f64,
    /// Why not, when not.
    pub reason: Option<String>,
    /// Its usable candidates, best first.
    pub edges: Vec<EdgeRecord>,
}

impl PairRecord {
    /// The record of `al`, B (`pb`) aligned onto A (`pa`): its usable candidates are the accepted
    /// choice and every candidate from the weak rule value on that no contradiction veto declines (the
    /// self-symmetry aside: cycles are what settle a symmetric map's placement).
    pub fn of(pa: &Prepared, pb: &Prepared, al: &Alignment, options: &GlobalOptions) -> PairRecord {
        let edges = al
            .candidates
            .iter()
            .enumerate()
            .filter(|(rank, c)| {
                (*rank == 0 && al.accepted)
                    || (c.score >= options.weak_from && not_contradicted(&c.features))
            })
            .map(|(rank, c)| EdgeRecord {
                rank,
                transform: c.transform,
                score: c.score,
                at: overlap_centre(pa, pb, &c.transform),
                residual: c.features.residual,
            })
            .collect();
        PairRecord {
            accepted: al.accepted,
            transform: al.transform,
            score: al.score,
            reason: al.reason.clone(),
            edges,
        }
    }

    /// Its verdict as the pair of maps `a` and `b`.
    pub fn verdict(&self, a: usize, b: usize) -> PairVerdict {
        PairVerdict {
            a,
            b,
            accepted: self.accepted,
            transform: self.transform,
            score: self.score,
            reason: self.reason.clone(),
        }
    }

    /// Its candidates as edges between maps `a` and `b`.
    pub fn edges(&self, a: usize, b: usize) -> impl Iterator<Item = Edge> + '_ {
        self.edges.iter().map(move |e| Edge {
            a,
            b,
            rank: e.rank,
            transform: e.transform,
            score: e.score,
            accepted: e.rank == 0 && self.accepted,
            at: e.at,
            residual: e.residual,
        })
    }

    /// The record as JSON (every float to the bit).
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a record serialises")
    }

    /// A record written by [`PairRecord::to_json`].
    pub fn from_json(text: &str) -> crate::Result<PairRecord> {
        serde_json::from_str(text)
            .map_err(|e| crate::Error::invalid(format!("not a pair's alignment record: {e}")))
    }
}

/// An `f64` in JSON also when it is not finite (a pair with no candidate scores minus infinity):
/// a number when finite, else the string `"inf"`, `"-inf"` or `"nan"`.
mod any_f64 {
    use super::*;

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else if v.is_nan() {
            s.serialize_str("nan")
        } else if *v > 0.0 {
            s.serialize_str("inf")
        } else {
            s.serialize_str("-inf")
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Num {
            N(f64),
            S(String),
        }
        match Num::deserialize(d)? {
            Num::N(v) => Ok(v),
            Num::S(s) => match s.as_str() {
                "inf" => Ok(f64::INFINITY),
                "-inf" => Ok(f64::NEG_INFINITY),
                "nan" => Ok(f64::NAN),
                other => Err(serde::de::Error::custom(format!(
                    "expected a number, \"inf\", \"-inf\" or \"nan\"; found \"{other}\""
                ))),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_keeps_every_float_and_the_infinities() {
        let r = PairRecord {
            accepted: false,
            transform: Rigid {
                theta_deg: 0.1 + 0.2,
                tx: -1.0 / 3.0,
                ty: 1e-300,
            },
            score: f64::NEG_INFINITY,
            reason: Some("no \"candidate\"".into()),
            edges: vec![EdgeRecord {
                rank: 2,
                transform: Rigid {
                    theta_deg: 179.99999999999997,
                    tx: 123.456_789_012_345_68,
                    ty: -0.0,
                },
                score: std::f64::consts::PI,
                at: (5e-324, 1.7976931348623157e308),
                residual: f64::INFINITY,
            }],
        };
        let back = PairRecord::from_json(&r.to_json()).unwrap();
        assert_eq!(back, r);
        assert_eq!(back.edges[0].transform.ty.to_bits(), (-0.0f64).to_bits());
        let nan = PairRecord {
            score: f64::NAN,
            ..r.clone()
        };
        assert!(PairRecord::from_json(&nan.to_json())
            .unwrap()
            .score
            .is_nan());
        let e = PairRecord::from_json(r#"{"accepted":true}"#).unwrap_err();
        assert!(
            e.to_string().contains("not a pair's alignment record"),
            "{e}"
        );
    }
}
