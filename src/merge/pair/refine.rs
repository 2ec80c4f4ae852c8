//! Refining a candidate pose between two prepared maps: trimmed ICP, the polish to a fraction of a
//! pixel, and the verification's counts of each map's walls and free space on the other (the scoring
//! kernel, on any backend); and the change between a transform of the maps' crops and one of their
//! own pixels.

use crate::backend::Backend;
use crate::merge::pair::accept::Features;
use crate::merge::pair::coarse::cs;
use crate::merge::pair::prepare::Prepared;
use crate::merge::pair::score::{score_both, Probe};
use crate::merge::transform::{fit_rigid, Rigid};
use crate::support::error::Result;

/// `t` (src crop to dst crop) moved by up to `scale` half pixels and turned by up to `scale` tenths of
/// a degree about src's walls' centre to where most wall pixels of each map land on occupied pixels of
/// the other: 75 transforms scored by the kernel at once, the first best one kept (`t` itself first).
pub(in crate::merge) fn polish(
    src: &Prepared,
    dst: &Prepared,
    t: &Rigid,
    scale: f64,
    backend: &mut dyn Backend,
) -> Result<Rigid> {
    let c = src.reference[4];
    let mut grid = vec![*t];
    for d in [-0.1 * scale, 0.0, 0.1 * scale] {
        let (cd, sd) = cs(d);
        // p -> t(R_d (p - c) + c): the same turn about c.
        let shift = (c.0 - (cd * c.0 - sd * c.1), c.1 - (sd * c.0 + cd * c.1));
        let (ct, st) = cs(t.theta_deg);
        let base = Rigid {
            theta_deg: t.theta_deg + d,
            tx: t.tx + ct * shift.0 - st * shift.1,
            ty: t.ty + st * shift.0 + ct * shift.1,
        };
        for dy in [-0.5, -0.25, 0.0, 0.25, 0.5] {
            for dx in [-0.5, -0.25, 0.0, 0.25, 0.5] {
                if d != 0.0 || dx != 0.0 || dy != 0.0 {
                    grid.push(Rigid {
                        tx: base.tx + dx * scale,
                        ty: base.ty + dy * scale,
                        ..base
                    });
                }
            }
        }
    }
    // The coarser steps on a sample of the walls; the finest on all of them.
    let probe = if scale > 1.0 {
        Probe::FineSample
    } else {
        Probe::Fine
    };
    let (a, b) = score_both(src, dst, &grid, probe, backend)?;
    let mut best = (0u32, *t);
    for ((x, y), g) in a.iter().zip(&b).zip(&grid) {
        let hits = x[1] + y[1];
        if hits > best.0 {
            best = (hits, *g);
        }
    }
    Ok(best.1)
}

/// Trimmed ICP of src's wall pixels onto dst's nearest wall pixels: 20 iterations, the trimming
/// distance falling from 12 to 4 px, closed-form 2-D rotation and translation each time.
pub(in crate::merge) fn icp(src: &Prepared, dst: &Prepared, mut t: Rigid) -> Rigid {
    const ITERS: usize = 20;
    // At most about 6000 wall pixels: enough for a rigid fit.
    let step = src.walls.len().div_ceil(6000).max(1);
    let mut it = 0;
    while it < ITERS {
        let trim = 12.0 + (4.0 - 12.0) * it as f64 / (ITERS - 1) as f64;
        let (mut pairs_p, mut pairs_q) = (Vec::new(), Vec::new());
        // The nearest wall pixel to q itself, not only to q's pixel: in the last iterations, among the
        // nearest wall pixels of q's pixel and its four neighbours (sub-pixel convergence).
        let probes: &[(f64, f64)] = if it + 5 >= ITERS {
            &[(0.0, 0.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]
        } else {
            &[(0.0, 0.0)]
        };
        let apply = t.applier();
        for &p in src.walls.iter().step_by(step) {
            let q = apply.apply(p);
            let mut target: Option<(f64, f64)> = None;
            // Squared distances: no square root per probe.
            let mut best = f64::MAX;
            for &(dx, dy) in probes {
                let Some(i) = dst.index(q.0 + dx, q.1 + dy) else {
                    continue;
                };
                if dst.nearest[i] == u32::MAX {
                    continue;
                }
                // In u32 (a crop's index fits, as `nearest` holds it): a 32-bit division, the
                // fastest of this loop's steps to shorten.
                let (j, w) = (dst.nearest[i], dst.w as u32);
                let c = (f64::from(j % w), f64::from(j / w));
                let d = (c.0 - q.0).powi(2) + (c.1 - q.1).powi(2);
                if d < best {
                    (best, target) = (d, Some(c));
                }
            }
            if let Some(target) = target.filter(|_| best < trim * trim) {
                pairs_p.push(p);
                pairs_q.push(target);
            }
        }
        if pairs_p.len() < 20 {
            break;
        }
        let next = fit_rigid(&pairs_p, &pairs_q);
        let done = (next.theta_deg - t.theta_deg).abs() < 1e-4
            && (next.tx - t.tx).abs() < 1e-3
            && (next.ty - t.ty).abs() < 1e-3;
        t = next;
        // Converged: done after the sub-pixel iterations, else on to them.
        it = match (done, it + 5 >= ITERS) {
            (true, true) => break,
            (true, false) => ITERS - 5,
            _ => it + 1,
        };
    }
    t
}

/// The verification features of each candidate (src crop to dst crop): both maps' walls mapped into the
/// other by the scoring kernel on `backend`, one batch of transforms each way.
pub(in crate::merge) fn verify(
    src: &Prepared,
    dst: &Prepared,
    candidates: &[Rigid],
    backend: &mut dyn Backend,
) -> Result<Vec<Features>> {
    let (into_dst, into_src) = score_both(src, dst, candidates, Probe::Walls, backend)?;
    let (fine_dst, fine_src) = score_both(src, dst, candidates, Probe::Fine, backend)?;
    let (free_dst, free_src) = score_both(src, dst, candidates, Probe::Free, backend)?;
    let share = |n: u32, of: usize| f64::from(n) / of.max(1) as f64;
    Ok(into_dst
        .iter()
        .zip(&into_src)
        .zip(fine_dst.iter().zip(&fine_src))
        .zip(free_dst.iter().zip(&free_src))
        .map(
            |(
                ((&[ia, ma, da], &[ib, mb, db]), (&[_, fa, ga], &[_, fb, gb])),
                (&[ka, oa, _], &[kb, ob, _]),
            )| {
                let inside_total = f64::from((ia + ib).max(1));
                Features {
                    free_inside: share(ka, src.free_points.len())
                        .min(share(kb, dst.free_points.len())),
                    free_agree: f64::from(oa + ob) / f64::from((ka + kb).max(1)),
                    conflict: f64::from(da + db) / inside_total,
                    inside: (f64::from(ia) / src.walls.len().max(1) as f64)
                        .min(f64::from(ib) / dst.walls.len().max(1) as f64),
                    matched: f64::from(ma + mb) / inside_total,
                    support: f64::from(ma + mb),
                    matched_fine: f64::from(fa + fb) / inside_total,
                    conflict_fine: f64::from(ga + gb) / inside_total,
                    // The rest is the choice's, filled in by the caller.
                    ..Features::default()
                }
            },
        )
        .collect())
}

/// A transform between the crops of src and dst as one between the maps' own pixels:
/// p_dst = R (p_src - off_src) + t + off_dst.
pub(in crate::merge) fn crop_to_map(src: &Prepared, dst: &Prepared, t: &Rigid) -> Rigid {
    let (c, s) = cs(t.theta_deg);
    Rigid {
        theta_deg: t.theta_deg,
        tx: t.tx - (c * src.off.0 - s * src.off.1) + dst.off.0,
        ty: t.ty - (s * src.off.0 + c * src.off.1) + dst.off.1,
    }
    .normalized()
}

/// The inverse of [`crop_to_map`]: a transform between the maps' pixels as one between their crops.
pub(in crate::merge) fn map_to_crop(src: &Prepared, dst: &Prepared, t: &Rigid) -> Rigid {
    let (c, s) = cs(t.theta_deg);
    Rigid {
        theta_deg: t.theta_deg,
        tx: t.tx + (c * src.off.0 - s * src.off.1) - dst.off.0,
        ty: t.ty + (s * src.off.0 + c * src.off.1) - dst.off.1,
    }
}
