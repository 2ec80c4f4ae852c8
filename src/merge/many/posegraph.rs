//! The pose graph of one group: every map's pose in the group's frame by weighted least squares over the
//! pairwise transforms kept, the group's first map fixed. Residuals are point residuals (each edge's
//! points in the moved map, through the edge and through the poses), so a turn and a shift are weighed
//! in the pixels they move walls by; Gauss-Newton from the agglomeration's poses, which are already
//! close.

use crate::merge::transform::Rigid;

/// One constraint: map `v`'s pixels to map `u`'s by `transform`, checked at `points` of `v`, with `weight`.
#[derive(Clone, Debug, PartialEq)]
pub struct Constraint {
    /// The reference map.
    pub u: usize,
    /// The moved map.
    pub v: usize,
    /// `v`'s pixels to `u`'s.
    pub transform: Rigid,
    /// Points of `v` (its pixels) where the residual is measured.
    pub points: Vec<(f64, f64)>,
    /// Weight.
    pub weight: f64,
}

/// One kept edge as the pose graph sees it: its two maps, whether the pair test accepted it, and its
/// weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kept {
    /// The reference map.
    pub u: usize,
    /// The moved map.
    pub v: usize,
    /// Accepted by the pair test (a measurement), or a weak candidate that cycles confirm (a vote).
    pub accepted: bool,
    /// Its vote.
    pub weight: f64,
}

/// Which of `kept` (over maps `0..n`) the pose graph rests on, by index: every accepted edge, and of the
/// others only those that join what the accepted ones leave apart, heaviest first. A weak candidate
/// agrees with the placement only within the loop tolerance; where accepted pairs already measure the
/// same two maps, it can add nothing but its error (in a set of alike rooms, a shift by one room that
/// passes the tolerance pulls every pose of the group towards it).
pub fn rests_on(n: usize, kept: &[Kept]) -> Vec<usize> {
    let mut root: Vec<usize> = (0..n).collect();
    fn find(root: &mut [usize], mut m: usize) -> usize {
        while root[m] != m {
            root[m] = root[root[m]];
            m = root[m];
        }
        m
    }
    // Whether `k` joins two components (and joins them).
    fn join(root: &mut [usize], k: &Kept) -> bool {
        let (a, b) = (find(root, k.u), find(root, k.v));
        root[a.max(b)] = a.min(b);
        a != b
    }
    let mut used = vec![false; kept.len()];
    for (i, k) in kept.iter().enumerate().filter(|(_, k)| k.accepted) {
        join(&mut root, k);
        used[i] = true;
    }
    let mut weak: Vec<usize> = (0..kept.len()).filter(|&i| !kept[i].accepted).collect();
    weak.sort_by(|&x, &y| kept[y].weight.total_cmp(&kept[x].weight).then(x.cmp(&y)));
    for i in weak {
        used[i] = join(&mut root, &kept[i]);
    }
    (0..kept.len()).filter(|&i| used[i]).collect()
}

/// Gauss-Newton iterations at most.
const ITERATIONS: usize = 20;

/// The poses (each map's pixels to the frame of `fixed`) that best satisfy `constraints`, from `start`;
/// maps in no constraint keep their start. `start` itself when the system is singular.
pub fn solve(start: &[Rigid], fixed: usize, constraints: &[Constraint]) -> Vec<Rigid> {
    let n = start.len();
    // Unknowns: (theta in radians, tx, ty) of every map but `fixed`.
    let slot = |m: usize| -> Option<usize> {
        match m.cmp(&fixed) {
            std::cmp::Ordering::Less => Some(3 * m),
            std::cmp::Ordering::Equal => None,
            std::cmp::Ordering::Greater => Some(3 * (m - 1)),
        }
    };
    let dim = 3 * n.saturating_sub(1);
    if dim == 0 || constraints.is_empty() {
        return start.to_vec();
    }
    let mut poses = start.to_vec();
    for _ in 0..ITERATIONS {
        let mut h = vec![0.0; dim * dim];
        let mut g = vec![0.0; dim];
        for c in constraints {
            let (pu, pv) = (&poses[c.u], &poses[c.v]);
            let (su, cu) = pu.theta_deg.to_radians().sin_cos();
            let (sv, cv) = pv.theta_deg.to_radians().sin_cos();
            for &p in &c.points {
                let q = c.transform.apply(p); // in u's pixels
                let a = pu.apply(q);
                let b = pv.apply(p);
                let r = (a.0 - b.0, a.1 - b.1);
                // d a / d theta_u = R'(theta_u) q; d b / d theta_v = R'(theta_v) p.
                let dau = (-su * q.0 - cu * q.1, cu * q.0 - su * q.1);
                let dbv = (-sv * p.0 - cv * p.1, cv * p.0 - sv * p.1);
                // Jacobian rows (x and y of r) over the unknowns of u (+) and v (-).
                let mut rows: [Vec<(usize, f64)>; 2] = [Vec::new(), Vec::new()];
                if let Some(s) = slot(c.u) {
                    rows[0].extend([(s, dau.0), (s + 1, 1.0)]);
                    rows[1].extend([(s, dau.1), (s + 2, 1.0)]);
                }
                if let Some(s) = slot(c.v) {
                    rows[0].extend([(s, -dbv.0), (s + 1, -1.0)]);
                    rows[1].extend([(s, -dbv.1), (s + 2, -1.0)]);
                }
                for (row, res) in rows.iter().zip([r.0, r.1]) {
                    for &(i, ji) in row {
                        g[i] += c.weight * ji * res;
                        for &(j, jj) in row {
                            h[i * dim + j] += c.weight * ji * jj;
                        }
                    }
                }
            }
        }
        // Maps in no constraint: keep them (a unit diagonal keeps the system regular).
        for i in 0..dim {
            if h[i * dim + i] == 0.0 {
                h[i * dim + i] = 1.0;
            }
        }
        let Some(step) = solve_linear(&mut h, &mut g, dim) else {
            return start.to_vec();
        };
        let mut largest: f64 = 0.0;
        for (m, pose) in poses.iter_mut().enumerate() {
            if let Some(s) = slot(m) {
                *pose = Rigid {
                    theta_deg: pose.theta_deg - step[s].to_degrees(),
                    tx: pose.tx - step[s + 1],
                    ty: pose.ty - step[s + 2],
                };
                largest = largest.max(step[s + 1].abs()).max(step[s + 2].abs());
            }
        }
        if largest < 1e-4 {
            break;
        }
    }
    poses.iter().map(Rigid::normalized).collect()
}

/// Solves `h x = g` (h symmetric, `dim` x `dim`) by Gaussian elimination with partial pivoting; `None`
/// when singular.
fn solve_linear(h: &mut [f64], g: &mut [f64], dim: usize) -> Option<Vec<f64>> {
    for col in 0..dim {
        let pivot = (col..dim).max_by(|&x, &y| {
            h[x * dim + col]
                .abs()
                .total_cmp(&h[y * dim + col].abs())
                .then(y.cmp(&x))
        })?;
        if h[pivot * dim + col].abs() < 1e-12 {
            return None;
        }
        if pivot != col {
            for k in 0..dim {
                h.swap(pivot * dim + k, col * dim + k);
            }
            g.swap(pivot, col);
        }
        let d = h[col * dim + col];
        for row in col + 1..dim {
            let f = h[row * dim + col] / d;
            if f != 0.0 {
                for k in col..dim {
                    h[row * dim + k] -= f * h[col * dim + k];
                }
                g[row] -= f * g[col];
            }
        }
    }
    let mut x = vec![0.0; dim];
    for row in (0..dim).rev() {
        let s: f64 = (row + 1..dim).map(|k| h[row * dim + k] * x[k]).sum();
        x[row] = (g[row] - s) / h[row * dim + row];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rigid(theta_deg: f64, tx: f64, ty: f64) -> Rigid {
        Rigid { theta_deg, tx, ty }
    }

    fn close(a: &Rigid, b: &Rigid) -> bool {
        (a.theta_deg - b.theta_deg).abs() < 1e-6
            && (a.tx - b.tx).abs() < 1e-6
            && (a.ty - b.ty).abs() < 1e-6
    }

    #[test]
    fn exact_constraints_are_met_from_a_perturbed_start() {
        let truth = [
            Rigid::IDENTITY,
            rigid(30.0, 100.0, -20.0),
            rigid(-75.0, -40.0, 250.0),
        ];
        let pts = vec![(0.0, 0.0), (200.0, 0.0), (0.0, 150.0), (120.0, 90.0)];
        let edge = |u: usize, v: usize| Constraint {
            u,
            v,
            transform: truth[u].inverse().after(&truth[v]),
            points: pts.clone(),
            weight: 1.0,
        };
        let start = [
            Rigid::IDENTITY,
            rigid(32.0, 95.0, -10.0),
            rigid(-72.0, -30.0, 240.0),
        ];
        let got = solve(&start, 0, &[edge(0, 1), edge(1, 2), edge(0, 2)]);
        for (g, t) in got.iter().zip(&truth) {
            assert!(close(g, t), "{g:?} vs {t:?}");
        }
    }

    #[test]
    fn a_weak_edge_is_used_only_where_accepted_ones_leave_maps_apart() {
        let k = |u, v, accepted, weight| Kept {
            u,
            v,
            accepted,
            weight,
        };
        // 0-1 and 1-2 accepted: the weak 0-2 is redundant; of the two weak edges to 3, the heavier.
        let kept = [
            k(0, 1, true, 1.0),
            k(0, 2, false, 9.0),
            k(1, 2, true, 0.5),
            k(2, 3, false, 1.0),
            k(3, 0, false, 2.0),
        ];
        assert_eq!(rests_on(4, &kept), vec![0, 2, 4]);
        // Weak edges alone: a spanning tree, heaviest first.
        let weak = [
            k(0, 1, false, 1.0),
            k(1, 2, false, 3.0),
            k(0, 2, false, 2.0),
        ];
        assert_eq!(rests_on(3, &weak), vec![1, 2]);
    }

    #[test]
    fn a_loop_error_is_shared_by_weight() {
        // 0 -> 1 and 1 -> 2 say map 2 is 10 px right of map 0; 0 -> 2 says 20 px. With equal weights the
        // solution sits between them; with the direct edge nine times heavier, near it.
        let pts = vec![(0.0, 0.0)];
        let c = |u, v, tx: f64, weight| Constraint {
            u,
            v,
            transform: rigid(0.0, tx, 0.0),
            points: pts.clone(),
            weight,
        };
        let start = [Rigid::IDENTITY; 3];
        let even = solve(
            &start,
            0,
            &[c(0, 1, 5.0, 1.0), c(1, 2, 5.0, 1.0), c(0, 2, 20.0, 1.0)],
        );
        assert!(even[2].tx > 12.0 && even[2].tx < 18.0, "{:?}", even[2]);
        let heavy = solve(
            &start,
            0,
            &[c(0, 1, 5.0, 1.0), c(1, 2, 5.0, 1.0), c(0, 2, 20.0, 9.0)],
        );
        assert!(heavy[2].tx > 18.0, "{:?}", heavy[2]);
        // The fixed map stays.
        assert!(close(&even[0], &Rigid::IDENTITY));
    }
}
