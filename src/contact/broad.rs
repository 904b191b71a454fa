//! Broad phase: sort-and-sweep on axis-aligned boxes inflated by the alert distance.
//!
//! Bounded bodies are sorted by the lower x bound of their inflated box and swept once;
//! a pair whose boxes overlap on all three axes is a candidate. Half-spaces have no box:
//! each is paired with the bounded bodies whose box comes within the alert distance of
//! its plane. Pairs of two bodies that cannot move are skipped. The result is sorted, so
//! the contact order (and the NLGS order) does not depend on the sweep. Along a periodic
//! axis, boxes that cross an end of the cell are swept again as their images.

use nalgebra::{Isometry3, Point3, Unit, Vector3};

use crate::geometry::Period;

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Point3<f64>,
    /// Upper corner.
    pub max: Point3<f64>,
}

/// What the broad phase needs of a body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BroadShape {
    /// A bounded body with its box (world).
    Bounded(Aabb),
    /// A half-space: a point of its plane and its outward unit normal (world).
    HalfSpace(Point3<f64>, Unit<Vector3<f64>>),
}

/// The box of `points` (local) placed at `pose`.
pub fn aabb_of(points: &[Point3<f64>], pose: &Isometry3<f64>) -> Aabb {
    let mut min = Point3::from(Vector3::repeat(f64::INFINITY));
    let mut max = Point3::from(Vector3::repeat(f64::NEG_INFINITY));
    for p in points {
        let q = pose * p;
        min = min.inf(&q);
        max = max.sup(&q);
    }
    Aabb { min, max }
}

impl Aabb {
    /// Whether `p` lies in the box (faces included).
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        (0..3).all(|d| p[d] >= self.min[d] && p[d] <= self.max[d])
    }

    /// The box grown by `margin` (m) on every side.
    pub fn grown(self, margin: f64) -> Aabb {
        let m = Vector3::repeat(margin);
        Aabb {
            min: self.min - m,
            max: self.max + m,
        }
    }
}

/// A candidate pair `(i, j, k)`, `i < j`: body i against body j translated by `k`
/// periods (`k` = 0 without periodicity or within the cell; ±1 across an end).
pub type Candidate = (u32, u32, i8);

/// Candidate pairs `(i, j, k)` (see [`Candidate`]), sorted, of bodies within `alert` of
/// each other, or within `reach[i] + reach[j]` (each body's own reach, e.g. how far it
/// can move in a step; an empty slice for none), at least one of them `movable`. Each
/// box is inflated by `max(alert / 2, reach)`, so every pair within `max(alert, reach_i
/// + reach_j)` is found.
///
/// With a `period`, a box that crosses an end of the cell also enters the sweep as its
/// image one length the other way (a ghost), and a ghost pairs with the real boxes it
/// overlaps: body j's image k periods away touching body i gives `(i, j, k)`, found
/// once whichever of the two boxes crossed. Half-spaces are not repeated (a plane
/// across the periodic axis would be a wall, which a periodic side replaces). The cell
/// must be longer than any two inflated boxes together along its axis, so that a pair
/// meets through one image at most (a body never meets its own).
pub fn candidate_pairs(
    shapes: &[BroadShape],
    movable: &[bool],
    alert: f64,
    reach: &[f64],
    period: Option<&Period>,
) -> Vec<Candidate> {
    let half = 0.5 * alert;
    let reach_of = |i: usize| reach.get(i).copied().unwrap_or(0.0);
    let inflation = |i: usize| half.max(reach_of(i));
    let mut bounded: Vec<(u32, Aabb, i8)> = Vec::with_capacity(shapes.len());
    for (i, s) in shapes.iter().enumerate() {
        let BroadShape::Bounded(b) = s else {
            continue;
        };
        let inflated = Aabb {
            min: b.min - Vector3::repeat(inflation(i)),
            max: b.max + Vector3::repeat(inflation(i)),
        };
        bounded.push((i as u32, inflated, 0));
        if let Some(p) = period {
            let (k, length) = (p.axis, p.length);
            let ghost = |sign: f64| {
                let mut t = Vector3::zeros();
                t[k] = sign * length;
                Aabb {
                    min: inflated.min + t,
                    max: inflated.max + t,
                }
            };
            if inflated.min[k] < p.low {
                bounded.push((i as u32, ghost(1.0), 1));
            }
            if inflated.max[k] > p.low + length {
                bounded.push((i as u32, ghost(-1.0), -1));
            }
        }
    }
    bounded.sort_by(|a, b| {
        a.1.min
            .x
            .total_cmp(&b.1.min.x)
            .then(a.0.cmp(&b.0))
            .then(a.2.cmp(&b.2))
    });
    let mut pairs = Vec::new();
    for (k, (i, a, image_i)) in bounded.iter().enumerate() {
        for (j, b, image_j) in &bounded[k + 1..] {
            if b.min.x > a.max.x {
                break;
            }
            // A ghost meets real boxes only (two ghosts repeat a real pair), and no
            // body meets itself.
            if i == j || (*image_i != 0 && *image_j != 0) {
                continue;
            }
            let overlap = b.min.y <= a.max.y
                && a.min.y <= b.max.y
                && b.min.z <= a.max.z
                && a.min.z <= b.max.z;
            if overlap && (movable[*i as usize] || movable[*j as usize]) {
                // j's image relative to i.
                let image = image_j - image_i;
                pairs.push(if i < j {
                    (*i, *j, image)
                } else {
                    (*j, *i, -image)
                });
            }
        }
    }
    for (h, shape) in shapes.iter().enumerate() {
        let BroadShape::HalfSpace(origin, normal) = shape else {
            continue;
        };
        for (i, b, image) in &bounded {
            if *image != 0 || !(movable[h] || movable[*i as usize]) {
                continue;
            }
            // The box's lowest point along the normal, relative to the plane.
            let centre = Point3::from(0.5 * (b.min.coords + b.max.coords));
            let half_size = 0.5 * (b.max - b.min);
            let extent = normal.x.abs() * half_size.x
                + normal.y.abs() * half_size.y
                + normal.z.abs() * half_size.z;
            // The body's own distance from the plane (its box without the inflation).
            let gap = normal.dot(&(centre - origin)) - extent + inflation(*i as usize);
            if gap <= alert.max(reach_of(*i as usize) + reach_of(h)) {
                let h = h as u32;
                pairs.push((h.min(*i), h.max(*i), 0));
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube_at(x: f64, y: f64, z: f64) -> BroadShape {
        BroadShape::Bounded(Aabb {
            min: Point3::new(x, y, z),
            max: Point3::new(x + 1.0, y + 1.0, z + 1.0),
        })
    }

    #[test]
    fn sweep_finds_overlaps_within_the_alert_distance() {
        let shapes = [
            cube_at(0.0, 0.0, 0.0),
            cube_at(1.05, 0.0, 0.0), // 0.05 from the first
            cube_at(3.0, 0.0, 0.0),  // far
            cube_at(0.0, 1.0, 0.5),  // touching the first
            BroadShape::HalfSpace(Point3::origin(), Vector3::z_axis()),
        ];
        let movable = [true, true, true, true, false];
        assert_eq!(
            candidate_pairs(&shapes, &movable, 0.1, &[], None),
            vec![
                (0, 1, 0),
                (0, 3, 0),
                (0, 4, 0),
                (1, 3, 0),
                (1, 4, 0),
                (2, 4, 0)
            ]
        );
        assert_eq!(
            candidate_pairs(&shapes, &movable, 0.01, &[], None),
            vec![(0, 3, 0), (0, 4, 0), (1, 4, 0), (2, 4, 0)]
        );
        // Two fixed bodies never pair.
        assert_eq!(
            candidate_pairs(
                &shapes,
                &[false, false, false, false, false],
                0.1,
                &[],
                None
            ),
            vec![]
        );
    }

    #[test]
    fn periodic_images_pair_across_the_ends_once() {
        // Cell [0, 5) along x: body 0 crosses the low end, body 1 the high end, body 2
        // sits in the middle; bodies 0 and 1 meet across the ends.
        let shapes = [
            cube_at(-0.2, 0.0, 0.0),
            cube_at(3.75, 0.0, 0.0),
            cube_at(2.0, 0.0, 0.0),
            BroadShape::HalfSpace(Point3::origin(), Vector3::z_axis()),
        ];
        let movable = [true, true, true, false];
        let period = Period {
            axis: 0,
            low: 0.0,
            length: 5.0,
        };
        // 1's image one period down, at [-1.25, -0.25], is 0.05 from 0's box.
        assert_eq!(
            candidate_pairs(&shapes, &movable, 0.1, &[], Some(&period)),
            vec![(0, 1, -1), (0, 3, 0), (1, 3, 0), (2, 3, 0)]
        );
        assert_eq!(
            candidate_pairs(&shapes, &movable, 0.01, &[], Some(&period)),
            vec![(0, 3, 0), (1, 3, 0), (2, 3, 0)]
        );
        // Along y instead: the same boxes do not cross its ends.
        let across = Period { axis: 1, ..period };
        assert_eq!(
            candidate_pairs(&shapes, &movable, 0.1, &[], Some(&across)),
            vec![(0, 3, 0), (1, 3, 0), (2, 3, 0)]
        );
    }
}
