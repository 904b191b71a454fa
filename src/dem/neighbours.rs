//! Broad phase: pairs of spheres of different bodies closer than a cut-off, by a cell
//! list (cells at least one cut-off wide, each sphere checked against the 27 cells
//! around it), optionally periodic along one axis (seed 004 §4: periodic along the
//! track). The pairs come out sorted by (first, second) whatever the thread count.

use rayon::prelude::*;

pub use crate::geometry::Period;

/// Below this many spheres the search runs on the calling thread.
const PARALLEL_MIN: usize = 4096;

/// All pairs (i, j), i < j, with `owner[i] != owner[j]` and minimum-image distance
/// below `cutoff`, sorted by (i, j).
pub fn close_pairs(
    positions: &[[f64; 3]],
    owner: &[u32],
    cutoff: f64,
    period: Option<&Period>,
) -> Vec<(u32, u32)> {
    let n = positions.len();
    if n < 2 {
        return Vec::new();
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in positions {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let mut dims = [1usize; 3];
    let mut size = [cutoff; 3];
    for d in 0..3 {
        let extent = match period {
            Some(p) if p.axis == d => {
                lo[d] = p.low;
                p.length
            }
            _ => hi[d] - lo[d],
        };
        // At most ~2 cells per sphere overall keeps the cell table small.
        let cells = ((extent / cutoff).floor() as usize).clamp(1, 2 * n);
        dims[d] = cells;
        size[d] = (extent / cells as f64).max(cutoff);
    }
    let wrap_axis = period.map(|p| p.axis);
    // A periodic axis with fewer than 3 cells is searched as one cell (the minimum
    // image then finds every neighbour exactly once).
    if let Some(k) = wrap_axis {
        if dims[k] < 3 {
            dims[k] = 1;
            size[k] = period.map(|p| p.length).unwrap_or(cutoff);
        }
    }
    let cell_of = |p: &[f64; 3]| -> [usize; 3] {
        let mut c = [0usize; 3];
        for d in 0..3 {
            let mut x = p[d] - lo[d];
            if wrap_axis == Some(d) {
                x = x.rem_euclid(period.map(|p| p.length).unwrap_or(1.0));
            }
            c[d] = ((x / size[d]).floor().max(0.0) as usize).min(dims[d] - 1);
        }
        c
    };
    let index = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
    let cells: Vec<[usize; 3]> = positions.iter().map(cell_of).collect();
    let cell_count = dims[0] * dims[1] * dims[2];
    let mut start = vec![0u32; cell_count + 1];
    for c in &cells {
        start[index(*c) + 1] += 1;
    }
    for k in 0..cell_count {
        start[k + 1] += start[k];
    }
    let mut fill = start.clone();
    let mut sorted = vec![0u32; n];
    for (i, c) in cells.iter().enumerate() {
        let k = index(*c);
        sorted[fill[k] as usize] = i as u32;
        fill[k] += 1;
    }
    let cut2 = cutoff * cutoff;
    let neighbours_of = |i: usize| -> Vec<(u32, u32)> {
        let c = cells[i];
        let mut out = Vec::new();
        for dz in -1i64..=1 {
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let mut nc = [0usize; 3];
                    let mut inside = true;
                    for (d, o) in [dx, dy, dz].into_iter().enumerate() {
                        if dims[d] == 1 && o != 0 {
                            inside = false;
                            break;
                        }
                        let v = c[d] as i64 + o;
                        if wrap_axis == Some(d) {
                            nc[d] = v.rem_euclid(dims[d] as i64) as usize;
                        } else if v < 0 || v >= dims[d] as i64 {
                            inside = false;
                            break;
                        } else {
                            nc[d] = v as usize;
                        }
                    }
                    if !inside {
                        continue;
                    }
                    let k = index(nc);
                    for &j in &sorted[start[k] as usize..start[k + 1] as usize] {
                        let j = j as usize;
                        if j <= i || owner[j] == owner[i] {
                            continue;
                        }
                        let d = Period::difference(period, positions[i], positions[j]);
                        if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < cut2 {
                            out.push((i as u32, j as u32));
                        }
                    }
                }
            }
        }
        out.sort_unstable();
        out
    };
    let lists: Vec<Vec<(u32, u32)>> = if n >= PARALLEL_MIN {
        (0..n).into_par_iter().map(neighbours_of).collect()
    } else {
        (0..n).map(neighbours_of).collect()
    };
    lists.concat()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(p: &[[f64; 3]], owner: &[u32], cut: f64, period: Option<&Period>) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for i in 0..p.len() {
            for j in i + 1..p.len() {
                let d = Period::difference(period, p[i], p[j]);
                if owner[i] != owner[j] && (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) < cut * cut {
                    out.push((i as u32, j as u32));
                }
            }
        }
        out
    }

    #[test]
    fn the_cell_list_finds_what_the_brute_force_finds() {
        // A deterministic scatter (a low-discrepancy sequence) in a 1 × 0.5 × 0.3 box.
        let n = 600;
        let p: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let f = i as f64;
                [
                    (f * 0.618_033_988_7).fract(),
                    0.5 * (f * 0.754_877_666_2).fract(),
                    0.3 * (f * 0.569_840_290_9).fract(),
                ]
            })
            .collect();
        let owner: Vec<u32> = (0..n as u32).map(|i| i / 3).collect();
        for cut in [0.02, 0.07, 0.4] {
            assert_eq!(
                close_pairs(&p, &owner, cut, None),
                brute(&p, &owner, cut, None)
            );
            for (axis, length) in [(0, 1.0), (1, 0.5)] {
                let period = Period {
                    axis,
                    low: 0.0,
                    length,
                };
                assert_eq!(
                    close_pairs(&p, &owner, cut, Some(&period)),
                    brute(&p, &owner, cut, Some(&period)),
                    "cut {cut} axis {axis}"
                );
            }
        }
        // Across the periodic boundary: x = 0.01 and x = 0.99 are 0.02 apart.
        let q = [[0.01, 0.0, 0.0], [0.99, 0.0, 0.0]];
        let period = Period {
            axis: 0,
            low: 0.0,
            length: 1.0,
        };
        assert_eq!(close_pairs(&q, &[0, 1], 0.03, Some(&period)), vec![(0, 1)]);
        assert!(close_pairs(&q, &[0, 1], 0.03, None).is_empty());
    }
}
