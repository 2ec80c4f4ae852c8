//! Exact Euclidean distance maps for the aligner: the distance from every pixel to the nearest seed, and
//! which seed it is.

/// Exact Euclidean distance transform (Felzenszwalb and Huttenlocher) to the nearest `true` pixel, with
/// the index of that pixel; `f32::MAX` and `u32::MAX` where there is none.
pub(in crate::merge) fn edt(mask: &[bool], w: usize, h: usize) -> (Vec<f32>, Vec<u32>) {
    edt_with(mask, w, h, true)
}

/// [`edt`]'s distances alone (no nearest pixel tracked: less memory traffic).
pub(in crate::merge) fn edt_distance(mask: &[bool], w: usize, h: usize) -> Vec<f32> {
    edt_with(mask, w, h, false).0
}

fn edt_with(mask: &[bool], w: usize, h: usize, with_nearest: bool) -> (Vec<f32>, Vec<u32>) {
    use rayon::prelude::*;
    const INF: f64 = 1e20;
    // Columns first: the nearest seed above and below each pixel in its column, by one sweep down and
    // one up over whole rows (the squared vertical distance is that distance squared: no parabolas
    // needed in 1-D with 0/INF input, and rows stay contiguous in memory).
    let mut g = vec![INF; w * h];
    let mut seed_row = vec![u32::MAX; if with_nearest { w * h } else { 0 }];
    let mut last = vec![u32::MAX; w];
    let down: Vec<usize> = (0..h).collect();
    let up: Vec<usize> = (0..h).rev().collect();
    for ys in [down, up] {
        last.fill(u32::MAX);
        for y in ys {
            let row = y * w..(y + 1) * w;
            let seeds = if with_nearest {
                &mut seed_row[row.clone()]
            } else {
                &mut []
            };
            for (x, (l, gv)) in last.iter_mut().zip(&mut g[row.clone()]).enumerate() {
                if mask[y * w + x] {
                    *l = y as u32;
                }
                if *l != u32::MAX {
                    // Strictly nearer: on the way up, ties keep the seed above.
                    let d = (y.abs_diff(*l as usize) as f64).powi(2);
                    if d < *gv {
                        *gv = d;
                        if let Some(s) = seeds.get_mut(x) {
                            *s = *l;
                        }
                    }
                }
            }
        }
    }
    let mut dist = vec![f32::MAX; w * h];
    let mut nearest = vec![u32::MAX; if with_nearest { w * h } else { 0 }];
    let row_len = w.max(1);
    let nearest_rows: Vec<&mut [u32]> = if with_nearest {
        nearest.chunks_mut(row_len).collect()
    } else {
        (0..h).map(|_| &mut [][..]).collect()
    };
    dist.par_chunks_mut(row_len)
        .zip(nearest_rows)
        .enumerate()
        .for_each(|(y, (drow, nrow))| {
            let f = &g[y * w..(y + 1) * w];
            let (mut out, mut arg) = (vec![0f64; w], vec![0usize; w]);
            envelope(f, &mut out, &mut arg);
            for x in 0..w {
                if out[x] < INF / 2.0 {
                    drow[x] = out[x].sqrt() as f32;
                    if let Some(n) = nrow.get_mut(x) {
                        let sx = arg[x];
                        *n = seed_row[y * w + sx] * w as u32 + sx as u32;
                    }
                }
            }
        });
    (dist, nearest)
}

/// The 1-D squared distance transform of `f`: `out[q] = min_p (q - p)^2 + f[p]`, `arg[q]` the minimising p.
fn envelope(f: &[f64], out: &mut [f64], arg: &mut [usize]) {
    let n = f.len();
    if n == 0 {
        return;
    }
    let mut v = vec![0usize; n];
    let mut z = vec![0f64; n + 1];
    let mut k = 0usize;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        loop {
            let p = v[k];
            let s =
                ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q as f64 - p as f64));
            if s <= z[k] && k > 0 {
                k -= 1;
                continue;
            }
            if s <= z[k] {
                // k == 0: q replaces the first parabola.
                v[0] = q;
                z[1] = f64::INFINITY;
                break;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
            break;
        }
    }
    let mut k = 0usize;
    for q in 0..n {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        out[q] = (q as f64 - p as f64).powi(2) + f[p];
        arg[q] = p;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_distance_transform_is_exact_and_names_the_nearest_pixel() {
        let (w, h) = (7, 5);
        let mut m = vec![false; w * h];
        m[2 * w + 1] = true;
        m[4 * w + 6] = true;
        let (d, near) = edt(&m, w, h);
        for y in 0..h {
            for x in 0..w {
                let want = [(1usize, 2usize), (6, 4)]
                    .iter()
                    .map(|&(sx, sy)| {
                        ((x as f64 - sx as f64).powi(2) + (y as f64 - sy as f64).powi(2)).sqrt()
                    })
                    .fold(f64::MAX, f64::min);
                assert!((f64::from(d[y * w + x]) - want).abs() < 1e-5, "({x}, {y})");
                let j = near[y * w + x] as usize;
                let got = ((x as f64 - (j % w) as f64).powi(2)
                    + (y as f64 - (j / w) as f64).powi(2))
                .sqrt();
                assert!((got - want).abs() < 1e-5);
            }
        }
        let (d, near) = edt(&[false; 6], 3, 2);
        assert!(d.iter().all(|&v| v == f32::MAX) && near.iter().all(|&v| v == u32::MAX));
    }

    #[test]
    fn random_masks_match_brute_force() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for case in 0..40 {
            let (w, h) = (1 + (next() % 23) as usize, 1 + (next() % 19) as usize);
            // Sparse to dense seeds, and some masks with none.
            let density = next() % 100;
            let m: Vec<bool> = (0..w * h)
                .map(|_| case % 10 != 0 && next() % 100 < density)
                .collect();
            let (d, near) = edt(&m, w, h);
            assert_eq!(edt_distance(&m, w, h), d, "case {case}");
            for i in 0..w * h {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                let want = (0..w * h)
                    .filter(|&j| m[j])
                    .map(|j| ((x - (j % w) as f64).powi(2) + (y - (j / w) as f64).powi(2)).sqrt())
                    .fold(f64::MAX, f64::min);
                if want == f64::MAX {
                    assert!(d[i] == f32::MAX && near[i] == u32::MAX, "case {case}");
                    continue;
                }
                assert!(
                    (f64::from(d[i]) - want).abs() < 1e-4,
                    "case {case}, pixel {i}"
                );
                let j = near[i] as usize;
                assert!(m[j], "case {case}: pixel {i} names a non-seed");
                let got = ((x - (j % w) as f64).powi(2) + (y - (j / w) as f64).powi(2)).sqrt();
                assert!((got - want).abs() < 1e-4, "case {case}, pixel {i}");
            }
        }
    }
}
