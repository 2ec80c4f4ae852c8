//! Exact Euclidean distance maps for the aligner: the distance from every pixel to the nearest seed, and
//! which seed it is.

/// Exact Euclidean distance transform (Felzenszwalb and Huttenlocher) to the nearest `true` pixel, with
/// the index of that pixel; `f32::MAX` and `u32::MAX` where there is none.
pub(super) fn edt(mask: &[bool], w: usize, h: usize) -> (Vec<f32>, Vec<u32>) {
    use rayon::prelude::*;
    const INF: f64 = 1e20;
    // Columns first (each on its own, every core): squared vertical distance and the row of the nearest
    // seed, stored column by column.
    let columns: Vec<(Vec<f64>, Vec<u32>)> = (0..w)
        .into_par_iter()
        .map(|x| {
            let f: Vec<f64> = (0..h)
                .map(|y| if mask[y * w + x] { 0.0 } else { INF })
                .collect();
            let (mut out, mut arg) = (vec![0f64; h], vec![0usize; h]);
            envelope(&f, &mut out, &mut arg);
            let rows = (0..h)
                .map(|y| {
                    if out[y] < INF / 2.0 {
                        arg[y] as u32
                    } else {
                        u32::MAX
                    }
                })
                .collect();
            (out, rows)
        })
        .collect();
    // The columns' results row by row (in 64 x 64 blocks, so both sides stay in cache), for the rows.
    let mut g = vec![0f64; w * h];
    let mut seed_row = vec![0u32; w * h];
    const B: usize = 64;
    for x0 in (0..w).step_by(B) {
        for y0 in (0..h).step_by(B) {
            for (x, (col, rows)) in columns.iter().enumerate().skip(x0).take(B) {
                for y in y0..(y0 + B).min(h) {
                    g[y * w + x] = col[y];
                    seed_row[y * w + x] = rows[y];
                }
            }
        }
    }
    drop(columns);
    let mut dist = vec![f32::MAX; w * h];
    let mut nearest = vec![u32::MAX; w * h];
    dist.par_chunks_mut(w.max(1))
        .zip(nearest.par_chunks_mut(w.max(1)))
        .enumerate()
        .for_each(|(y, (drow, nrow))| {
            let f = &g[y * w..(y + 1) * w];
            let (mut out, mut arg) = (vec![0f64; w], vec![0usize; w]);
            envelope(f, &mut out, &mut arg);
            for x in 0..w {
                if out[x] < INF / 2.0 {
                    let sx = arg[x];
                    let sy = seed_row[y * w + sx];
                    drow[x] = out[x].sqrt() as f32;
                    nrow[x] = sy * w as u32 + sx as u32;
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
}
