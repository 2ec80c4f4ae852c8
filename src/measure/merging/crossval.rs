//! Leave-one-building-out cross-validation of the acceptance rule (`merge-eval --cross-validate`): the
//! rule's weights and threshold fitted on every building but one, the merger's verdicts on the one left
//! out judged with that rule, for each building in turn. The held-out figures are what a user can expect
//! on a building the rule has never seen; the in-sample ones (fitted on all) only show the gap.
//!
//! The fit is the rule's own recipe ([`Acceptance`]): a logistic regression of "accurate" on the three
//! inputs (standardised, a unit ridge on the weights, Newton's method), the threshold 0.3 standard
//! deviations of the rule's values above the highest value of any wrong estimate or negative among the
//! training pairs, vetoed or not. The vetoes keep their limits (they are stated with the data they were
//! set on, in the acceptance module); as the threshold does not lean on them, the held-out figures with
//! the rule alone are reported too (`rule alone` rows): what the vetoes' hand-set limits add.

use std::collections::{BTreeMap, HashMap};
use std::io::{self, Write};

use serde::Serialize;

use crate::measure::merging::PairRecord;
use crate::merge::pair::align::{decline, Acceptance, Decline, Features};

/// Inputs of the rule.
const K: usize = 3;

/// The rule's inputs for a candidate's features, as [`Acceptance::margin`] weighs them.
fn inputs(f: &Features) -> [f64; K] {
    [
        f.coarse_ratio.max(1e-3).ln(),
        f.free_inside,
        (1.01 - f.free_agree).max(1e-3).ln(),
    ]
}

/// The rule fitted on `train` (features, accurate): weights by a ridge logistic regression, threshold
/// above the highest wrong one (vetoed or not: a wrong estimate a veto happens to catch here may pass
/// it on another building).
// The gradient and Hessian indexed as the formulas are written.
#[allow(clippy::needless_range_loop)]
pub fn fit(train: &[(Features, bool)]) -> Acceptance {
    const D: usize = K + 1;
    let n = train.len().max(1) as f64;
    let xs: Vec<[f64; K]> = train.iter().map(|(f, _)| inputs(f)).collect();
    let mut mean = [0.0; K];
    let mut sd = [0.0; K];
    for x in &xs {
        for k in 0..K {
            mean[k] += x[k] / n;
        }
    }
    for x in &xs {
        for k in 0..K {
            sd[k] += (x[k] - mean[k]).powi(2) / n;
        }
    }
    for v in &mut sd {
        *v = v.sqrt().max(1e-9);
    }
    // The intercept first, then the standardised inputs.
    let z = |x: &[f64; K]| -> [f64; D] {
        let mut z = [1.0; D];
        for k in 0..K {
            z[k + 1] = (x[k] - mean[k]) / sd[k];
        }
        z
    };
    // Newton's method on the penalised log-likelihood (a unit ridge on the weights, not the
    // intercept): the classes are often separable, and the ridge keeps the weights finite.
    let mut b = [0.0f64; D];
    for _ in 0..50 {
        let mut g = [0.0f64; D];
        let mut h = [[0.0f64; D]; D];
        for (x, (_, y)) in xs.iter().zip(train) {
            let zx = z(x);
            let eta: f64 = (0..D).map(|k| b[k] * zx[k]).sum();
            let p = 1.0 / (1.0 + (-eta).exp());
            let r = f64::from(u8::from(*y)) - p;
            let w = (p * (1.0 - p)).max(1e-12);
            for i in 0..D {
                g[i] += r * zx[i];
                for j in 0..D {
                    h[i][j] += w * zx[i] * zx[j];
                }
            }
        }
        for i in 1..D {
            g[i] -= b[i];
            h[i][i] += 1.0;
        }
        let Some(step) = solve(h, g) else { break };
        let mut moved = 0.0f64;
        for i in 0..D {
            b[i] += step[i];
            moved = moved.max(step[i].abs());
        }
        if moved < 1e-9 {
            break;
        }
    }
    // Back to the raw inputs: w_k = b_k / sd_k (the intercept folds into the threshold).
    let mut w = [0.0; K];
    for k in 0..K {
        w[k] = b[k + 1] / sd[k];
    }
    let value = |f: &Features| {
        let x = inputs(f);
        (0..K).map(|k| w[k] * x[k]).sum::<f64>()
    };
    let values: Vec<f64> = train.iter().map(|(f, _)| value(f)).collect();
    let m = values.iter().sum::<f64>() / n;
    let spread = (values.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n).sqrt();
    // The highest wrong one, vetoed or not: the rule must not lean on a veto's hand-set limit.
    let highest_wrong = train
        .iter()
        .zip(&values)
        .filter(|((_, ok), _)| !ok)
        .map(|(_, &v)| v)
        .fold(f64::NEG_INFINITY, f64::max);
    // With no wrong example (or no right one, or all values alike) there is nothing to set a threshold
    // on: the rule accepts nothing rather than everything.
    let has_right = train.iter().any(|(_, ok)| *ok);
    let threshold = if highest_wrong.is_finite() && has_right && spread > 1e-9 {
        highest_wrong + 0.3 * spread
    } else {
        f64::INFINITY
    };
    // In units of a tenth of the training values' spread: the many-map placement weighs candidates by
    // their rule values on that scale ([`crate::merge::many`]), whatever the fit's own scale.
    let unit = if spread > 1e-9 { 10.0 / spread } else { 1.0 };
    Acceptance {
        w_coarse: w[0] * unit,
        w_free_inside: w[1] * unit,
        w_free_disagree: w[2] * unit,
        threshold: threshold * unit,
    }
}

/// Solves `h x = g` (Gaussian elimination with partial pivoting); `None` when singular.
// Row and column indices read as the textbook's elimination does.
#[allow(clippy::needless_range_loop)]
fn solve<const D: usize>(mut h: [[f64; D]; D], mut g: [f64; D]) -> Option<[f64; D]> {
    for c in 0..D {
        let p = (c..D).max_by(|&i, &j| h[i][c].abs().total_cmp(&h[j][c].abs()))?;
        if h[p][c].abs() < 1e-12 {
            return None;
        }
        h.swap(c, p);
        g.swap(c, p);
        for r in c + 1..D {
            let f = h[r][c] / h[c][c];
            for k in c..D {
                h[r][k] -= f * h[c][k];
            }
            g[r] -= f * g[c];
        }
    }
    let mut x = [0.0; D];
    for r in (0..D).rev() {
        let s: f64 = (r + 1..D).map(|k| h[r][k] * x[k]).sum();
        x[r] = (g[r] - s) / h[r][r];
    }
    Some(x)
}

/// One building's held-out figures (or the pooled ones, or the in-sample ones).
#[derive(Clone, Debug, Serialize)]
pub struct FoldRow {
    /// The building left out ("pooled held-out", "in-sample, all buildings").
    pub building: String,
    /// Its pairs.
    pub pairs: usize,
    /// Accepted and accurate.
    pub accepted_accurate: usize,
    /// Accepted and not accurate.
    pub wrong: usize,
    /// Negatives involving it.
    pub negatives: usize,
    /// Of those, accepted.
    pub negatives_accepted: usize,
    /// Wrong accepts and negatives accepted by the rule alone, no veto applied: whether the held-out
    /// safety rests on the vetoes' hand-set limits.
    pub rule_alone_wrong: usize,
    /// Its pairs declined.
    pub declined: usize,
    /// Declines whose best candidate was the right pose: found, and turned down.
    pub found_turned_down: usize,
    /// Its pairs whose right pose was among the refined candidates at all (the candidate recall).
    pub right_among_candidates: usize,
    /// Why its pairs were declined ([`Decline`], as their `why:` lines open), counted.
    pub reasons: BTreeMap<Decline, usize>,
    /// The shipped rule on the same pairs: accepted and accurate.
    pub shipped_accepted_accurate: usize,
    /// The shipped rule on the same pairs: accepted and not accurate, and negatives accepted.
    pub shipped_wrong: usize,
    /// The rule fitted without it (none for the pooled row: each fold has its own).
    pub rule: Option<Acceptance>,
}

/// Each record's maps' buildings: from the pairs' own buildings, by map name.
fn buildings(rows: &[PairRecord]) -> HashMap<String, String> {
    let mut of = HashMap::new();
    for r in rows.iter().filter(|r| !r.negative) {
        of.insert(r.src.clone(), r.building.clone());
        of.insert(r.dst.clone(), r.building.clone());
    }
    of
}

/// Leave-one-building-out over the merger's records of a pair set (run with
/// [`crate::merge::pair::align::MergeOptions::always_verify`], so every veto was measured): one row per
/// building, then the pooled held-out row and the in-sample row.
pub fn cross_validate(rows: &[PairRecord]) -> Vec<FoldRow> {
    let of = buildings(rows);
    let touches = |r: &PairRecord, b: &str| {
        if r.negative {
            of.get(&r.src).is_some_and(|x| x == b) || of.get(&r.dst).is_some_and(|x| x == b)
        } else {
            r.building == b
        }
    };
    let sample = |r: &PairRecord| (r.alignment.features, !r.negative && r.accurate);
    let mut names: Vec<String> = rows
        .iter()
        .filter(|r| !r.negative)
        .map(|r| r.building.clone())
        .collect();
    names.sort();
    names.dedup();
    let judge = |rule: &Acceptance, sel: &[&PairRecord], label: String| {
        let why = |rule: &Acceptance, r: &PairRecord| {
            decline(&r.alignment.features, rule.margin(&r.alignment.features))
        };
        let alone = |r: &&&PairRecord| rule.margin(&r.alignment.features) >= 0.0;
        let pos: Vec<&PairRecord> = sel.iter().copied().filter(|r| !r.negative).collect();
        let neg: Vec<&PairRecord> = sel.iter().copied().filter(|r| r.negative).collect();
        let shipped = Acceptance::default();
        let count = |rule: &Acceptance, accurate: bool| {
            pos.iter()
                .filter(|r| why(rule, r).is_none() && r.accurate == accurate)
                .count()
        };
        let mut reasons = BTreeMap::new();
        for d in pos.iter().filter_map(|r| why(rule, r)) {
            *reasons.entry(d).or_insert(0) += 1;
        }
        FoldRow {
            building: label,
            pairs: pos.len(),
            accepted_accurate: count(rule, true),
            wrong: count(rule, false),
            negatives: neg.len(),
            negatives_accepted: neg.iter().filter(|r| why(rule, r).is_none()).count(),
            rule_alone_wrong: pos.iter().filter(|r| !r.accurate).filter(alone).count()
                + neg.iter().filter(alone).count(),
            declined: pos.iter().filter(|r| why(rule, r).is_some()).count(),
            found_turned_down: pos
                .iter()
                .filter(|r| r.accurate && why(rule, r).is_some())
                .count(),
            right_among_candidates: pos
                .iter()
                .filter(|r| r.accurate_candidates.iter().any(|&a| a))
                .count(),
            reasons,
            shipped_accepted_accurate: count(&shipped, true),
            shipped_wrong: count(&shipped, false)
                + neg.iter().filter(|r| why(&shipped, r).is_none()).count(),
            rule: Some(*rule),
        }
    };
    let mut out = Vec::new();
    for b in &names {
        let train: Vec<(Features, bool)> =
            rows.iter().filter(|r| !touches(r, b)).map(sample).collect();
        let rule = fit(&train);
        let test: Vec<&PairRecord> = rows.iter().filter(|r| touches(r, b)).collect();
        out.push(judge(&rule, &test, b.clone()));
    }
    let sum = |f: fn(&FoldRow) -> usize, v: &[FoldRow]| v.iter().map(f).sum::<usize>();
    let mut reasons = BTreeMap::new();
    for (&d, &n) in out.iter().flat_map(|r| &r.reasons) {
        *reasons.entry(d).or_insert(0) += n;
    }
    let pooled = FoldRow {
        building: "pooled held-out".to_string(),
        pairs: sum(|r| r.pairs, &out),
        accepted_accurate: sum(|r| r.accepted_accurate, &out),
        wrong: sum(|r| r.wrong, &out),
        // A negative touches two buildings: counted in both folds, judged by each fold's rule.
        negatives: sum(|r| r.negatives, &out),
        negatives_accepted: sum(|r| r.negatives_accepted, &out),
        rule_alone_wrong: sum(|r| r.rule_alone_wrong, &out),
        declined: sum(|r| r.declined, &out),
        found_turned_down: sum(|r| r.found_turned_down, &out),
        right_among_candidates: sum(|r| r.right_among_candidates, &out),
        reasons,
        shipped_accepted_accurate: sum(|r| r.shipped_accepted_accurate, &out),
        shipped_wrong: sum(|r| r.shipped_wrong, &out),
        rule: None,
    };
    let all: Vec<(Features, bool)> = rows.iter().map(sample).collect();
    let every: Vec<&PairRecord> = rows.iter().collect();
    let in_sample = judge(&fit(&all), &every, "in-sample (fitted on all)".to_string());
    let shipped = judge(
        &Acceptance::default(),
        &every,
        "shipped rule, all".to_string(),
    );
    out.push(pooled);
    out.push(in_sample);
    out.push(shipped);
    out
}

/// A row's decline reasons, most frequent first: `not confident 5, ambiguous (self-match) 2`.
fn reasons_cell(r: &FoldRow) -> String {
    let mut v: Vec<(&Decline, &usize)> = r.reasons.iter().collect();
    v.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
    let s: Vec<String> = v.iter().map(|(d, n)| format!("{} {n}", d.name())).collect();
    if s.is_empty() {
        "-".to_string()
    } else {
        s.join(", ")
    }
}

/// The folds as a markdown table.
pub fn write_folds(out: &mut dyn Write, rows: &[FoldRow]) -> io::Result<()> {
    writeln!(
        out,
        "| building left out | pairs | accepted and accurate | wrong accepts | declined | found and turned down | right pose among the candidates | why declined | negatives accepted | rule alone, no veto: wrong or negative accepts | shipped rule: accurate, wrong or negative accepts | rule fitted without it (coarse, free inside, free disagree; threshold) |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|---|")?;
    for r in rows {
        let rule = match &r.rule {
            Some(a) if a.threshold.is_infinite() => {
                "none: no wrong and right examples to fit on (accepts nothing)".to_string()
            }
            Some(a) => format!(
                "{:.3}, {:.3}, {:.3}; {:.3}",
                a.w_coarse, a.w_free_inside, a.w_free_disagree, a.threshold
            ),
            None => "each fold's own".to_string(),
        };
        let pct = |n: usize| 100.0 * n as f64 / r.pairs.max(1) as f64;
        writeln!(
            out,
            "| {} | {} | {} ({:.1}%) | {} | {} | {} | {} ({:.1}%) | {} | {} of {} | {} | {}, {} | {rule} |",
            crate::detect::output::md_cell(&r.building),
            r.pairs,
            r.accepted_accurate,
            pct(r.accepted_accurate),
            r.wrong,
            r.declined,
            r.found_turned_down,
            r.right_among_candidates,
            pct(r.right_among_candidates),
            reasons_cell(r),
            r.negatives_accepted,
            r.negatives,
            r.rule_alone_wrong,
            r.shipped_accepted_accurate,
            r.shipped_wrong,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On separable data the fitted rule accepts the right ones and no wrong one, and moves the
    /// threshold above the highest wrong value.
    #[test]
    fn the_fit_separates_what_it_can() {
        let mk = |free_inside: f64, choice: f64, ok: bool| {
            (
                Features {
                    choice_ratio: choice,
                    coarse_ratio: choice,
                    free_inside,
                    free_agree: 0.97,
                    support: 5000.0,
                    ..Features::default()
                },
                ok,
            )
        };
        let mut train = Vec::new();
        for k in 0..20 {
            let t = k as f64 / 20.0;
            train.push(mk(0.5 + 0.4 * t, 2.0 + 3.0 * t, true));
            train.push(mk(0.05 + 0.2 * t, 1.0 + 0.3 * t, false));
        }
        let rule = fit(&train);
        assert!(rule.w_free_inside > 0.0 && rule.w_coarse > 0.0, "{rule:?}");
        for (f, ok) in &train {
            assert_eq!(rule.margin(f) >= 0.0, *ok, "{f:?} {rule:?}");
        }
        // A wrong one that looks right but that a veto declines (walls deep in free space) still sets
        // the threshold: the rule alone declines it.
        let (f, _) = mk(0.7, 3.5, false);
        let vetoed = Features {
            conflict_fine: 0.9,
            ..f
        };
        assert!(!crate::merge::pair::align::accepts(&vetoed, f64::INFINITY));
        train.push((vetoed, false));
        let strict = fit(&train);
        assert!(strict.margin(&vetoed) < 0.0, "{strict:?}");
        assert!(strict.threshold > rule.threshold, "{strict:?} {rule:?}");
    }
}
