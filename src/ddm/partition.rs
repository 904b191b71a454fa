//! Primal partitioning (seed 000 §2.2): a grain belongs to the subdomain whose box holds
//! its mass centre; a contact belongs to subdomain E when every moving body it touches
//! is in E, and to the interface Γ otherwise.
//!
//! Bodies that the contacts do not move (floor, walls, driven tools and sleepers) belong
//! to no subdomain: their velocities are read, never written, by the NLGS, so a contact
//! between a grain of E and a wall is a contact of E.

use std::ops::Range;

use nalgebra::Vector3;

/// How the space is cut into subdomain boxes.
#[derive(Debug, Clone, PartialEq)]
pub enum Partitioning {
    /// Slabs along one axis (0 = x, 1 = y, 2 = z), cut at increasing coordinates:
    /// `cuts.len() + 1` subdomains. One slab per sleeper, cut midway between
    /// neighbouring sleepers, is the seed's "areas under each sleeper".
    Slabs {
        /// The axis normal to the cuts.
        axis: usize,
        /// The cut coordinates (m), increasing.
        cuts: Vec<f64>,
    },
    /// A regular `nx × ny` grid over `[min, max]` in (x, y); bodies outside fall in the
    /// nearest box. Numbered x fastest.
    Grid {
        /// Boxes along x.
        nx: usize,
        /// Boxes along y.
        ny: usize,
        /// Lower (x, y) corner (m).
        min: [f64; 2],
        /// Upper (x, y) corner (m).
        max: [f64; 2],
    },
}

impl Partitioning {
    /// `n` slabs of equal width along `axis` over `[lo, hi]`.
    pub fn even_slabs(axis: usize, lo: f64, hi: f64, n: usize) -> Self {
        let n = n.max(1);
        let cuts = (1..n)
            .map(|k| lo + (hi - lo) * k as f64 / n as f64)
            .collect();
        Partitioning::Slabs { axis, cuts }
    }

    /// `n` slabs along `axis` holding equal shares of `positions` (the contacts'
    /// coordinates along it), cut midway between the neighbouring positions at each
    /// share: the seed's §5 suggestion of subdomains balanced by contact count, so
    /// that more subdomains than threads keep every thread busy. Fewer positions than
    /// slabs give fewer slabs.
    pub fn balanced_slabs(axis: usize, positions: &[f64], n: usize) -> Self {
        let mut sorted: Vec<f64> = positions
            .iter()
            .copied()
            .filter(|p| p.is_finite())
            .collect();
        sorted.sort_by(f64::total_cmp);
        let n = n.max(1);
        let mut cuts: Vec<f64> = (1..n)
            .filter_map(|k| {
                let i = k * sorted.len() / n;
                (i > 0 && i < sorted.len()).then(|| 0.5 * (sorted[i - 1] + sorted[i]))
            })
            .collect();
        cuts.dedup();
        Partitioning::Slabs { axis, cuts }
    }

    /// The number of subdomains.
    pub fn subdomains(&self) -> usize {
        match self {
            Partitioning::Slabs { cuts, .. } => cuts.len() + 1,
            Partitioning::Grid { nx, ny, .. } => nx.max(&1) * ny.max(&1),
        }
    }

    /// The subdomain whose box holds `centre`.
    pub fn subdomain_of(&self, centre: &Vector3<f64>) -> u32 {
        match self {
            Partitioning::Slabs { axis, cuts } => {
                cuts.partition_point(|&c| c <= centre[*axis]) as u32
            }
            Partitioning::Grid { nx, ny, min, max } => {
                let cell = |k: usize, n: usize| {
                    let n = n.max(1);
                    let span = max[k] - min[k];
                    let f = if span > 0.0 {
                        (centre[k] - min[k]) / span
                    } else {
                        0.0
                    };
                    ((f * n as f64).floor().max(0.0) as usize).min(n - 1)
                };
                (cell(1, *ny) * nx.max(&1) + cell(0, *nx)) as u32
            }
        }
    }

    /// Each body's subdomain: `None` for bodies the contacts do not move
    /// (`movable[b]` false).
    pub fn assign(&self, centres: &[Vector3<f64>], movable: &[bool]) -> Vec<Option<u32>> {
        centres
            .iter()
            .zip(movable)
            .map(|(c, &m)| m.then(|| self.subdomain_of(c)))
            .collect()
    }
}

/// The contacts of one problem numbered subdomain by subdomain, then the interface:
/// contact ranges in that order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Decomposition {
    /// Contact range of each subdomain (in the renumbered order).
    pub subdomains: Vec<Range<usize>>,
    /// Contact range of the interface Γ (the last contacts).
    pub interface: Range<usize>,
}

impl Decomposition {
    /// The number of contacts.
    pub fn contacts(&self) -> usize {
        self.interface.end
    }
}

/// The block of a contact between bodies `a` and `b`: the subdomain of its moving
/// bodies when they share one, `subdomains` (the interface) otherwise.
pub fn block_of(owner: &[Option<u32>], a: usize, b: usize, subdomains: usize) -> usize {
    match (owner[a], owner[b]) {
        (Some(x), Some(y)) if x == y => x as usize,
        (Some(x), None) | (None, Some(x)) => x as usize,
        _ => subdomains,
    }
}

/// Renumbers contacts subdomain by subdomain, then the interface, keeping their order
/// within each block (a stable sort): returns the permutation (new position → old
/// index) and the ranges. `bodies[c]` are contact c's two bodies.
pub fn decompose(
    bodies: &[[usize; 2]],
    owner: &[Option<u32>],
    subdomains: usize,
) -> (Vec<usize>, Decomposition) {
    let blocks: Vec<usize> = bodies
        .iter()
        .map(|&[a, b]| block_of(owner, a, b, subdomains))
        .collect();
    let mut order: Vec<usize> = (0..bodies.len()).collect();
    order.sort_by_key(|&c| blocks[c]);
    let mut counts = vec![0usize; subdomains + 1];
    for &b in &blocks {
        counts[b] += 1;
    }
    let mut ranges = Vec::with_capacity(subdomains + 1);
    let mut start = 0;
    for n in counts {
        ranges.push(start..start + n);
        start += n;
    }
    let interface = ranges.pop().expect("the interface range");
    (
        order,
        Decomposition {
            subdomains: ranges,
            interface,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balanced_slabs_share_the_positions_evenly() {
        // Dense on the left: 60 positions in [0, 1), 20 in [1, 3).
        let mut xs: Vec<f64> = (0..60).map(|k| k as f64 / 60.0).collect();
        xs.extend((0..20).map(|k| 1.0 + 2.0 * k as f64 / 20.0));
        let slabs = Partitioning::balanced_slabs(0, &xs, 4);
        assert_eq!(slabs.subdomains(), 4);
        let mut counts = [0usize; 4];
        for &x in &xs {
            counts[slabs.subdomain_of(&Vector3::new(x, 0.0, 0.0)) as usize] += 1;
        }
        assert_eq!(counts, [20, 20, 20, 20]);
        // Even slabs over the extent would put 60 of 80 in the first two.
        let even = Partitioning::even_slabs(0, 0.0, 3.0, 4);
        let first = xs
            .iter()
            .filter(|&&x| even.subdomain_of(&Vector3::new(x, 0.0, 0.0)) == 0)
            .count();
        assert_eq!(first, 45);
        assert_eq!(Partitioning::balanced_slabs(0, &[1.0], 3).subdomains(), 1);
    }

    #[test]
    fn slabs_and_grids_hold_their_centres() {
        let slabs = Partitioning::even_slabs(0, 0.0, 3.0, 3);
        assert_eq!(slabs.subdomains(), 3);
        for (x, s) in [(-1.0, 0), (0.5, 0), (1.0, 1), (2.9, 2), (7.0, 2)] {
            assert_eq!(slabs.subdomain_of(&Vector3::new(x, 0.0, 0.0)), s, "x = {x}");
        }
        let grid = Partitioning::Grid {
            nx: 2,
            ny: 3,
            min: [0.0, 0.0],
            max: [2.0, 3.0],
        };
        assert_eq!(grid.subdomains(), 6);
        assert_eq!(grid.subdomain_of(&Vector3::new(1.5, 2.5, 9.0)), 5);
        assert_eq!(grid.subdomain_of(&Vector3::new(-5.0, 1.5, 0.0)), 2);
        assert_eq!(grid.subdomain_of(&Vector3::new(5.0, -1.0, 0.0)), 1);
    }

    #[test]
    fn contacts_go_to_their_subdomain_or_the_interface() {
        // Bodies: 0 wall (no subdomain), 1 and 2 in subdomain 0, 3 in subdomain 1.
        let owner = [None, Some(0), Some(0), Some(1)];
        let bodies = [[1, 3], [0, 3], [1, 2], [0, 1], [2, 3], [3, 0]];
        let (order, d) = decompose(&bodies, &owner, 2);
        assert_eq!(d.subdomains, vec![0..2, 2..4]);
        assert_eq!(d.interface, 4..6);
        // Stable within blocks.
        assert_eq!(order, vec![2, 3, 1, 5, 0, 4]);
        assert_eq!(d.contacts(), 6);
    }
}
