//! What a packing is worth: compactness in control boxes (exact polyhedron clipping),
//! coordination number, interpenetration, stones outside the container.

use crate::contact::ContactPoint;
use crate::geometry::{convex_volume_in_box, ControlBox};
use crate::nscd::body::Body;
use crate::nscd::step::SolvedContact;
use nalgebra::Point3;

use super::deposit::Role;

/// A named control box and the solid fraction measured in it.
#[derive(Debug, Clone, PartialEq)]
pub struct Compactness {
    /// `under_sleeper_1`, `crib_1_2`, `bed` ….
    pub name: String,
    /// The box.
    pub bx: ControlBox,
    /// Σ volume(stone ∩ box) / volume(box).
    pub value: f64,
}

/// The control boxes of a bed `[0, length] × [−width/2, width/2]` with its sleepers'
/// boxes (min and max corners, world): under each sleeper (its footprint, from `margin`
/// above the floor to its underside, `margin` in from the side walls), in each crib
/// (between two sleepers, from `margin` to `margin` below `crib_top`: the struck-off
/// surface is as loose as a wall), and the whole bed below the
/// lowest underside (or `depth` without sleepers), `margin` in from every wall.
/// `margin` (one d50) keeps the walls' layering out of the measure.
pub fn control_boxes(
    length: f64,
    width: f64,
    depth: f64,
    sleepers: &[(Point3<f64>, Point3<f64>)],
    crib_top: f64,
    margin: f64,
) -> Vec<(String, ControlBox)> {
    let (y_lo, y_hi) = (-0.5 * width + margin, 0.5 * width - margin);
    let mut boxes = Vec::new();
    let underside = sleepers.iter().map(|s| s.0.z).fold(depth, f64::min);
    boxes.push((
        "bed".to_string(),
        ControlBox {
            min: Point3::new(margin, y_lo, margin),
            max: Point3::new(length - margin, y_hi, underside - margin),
        },
    ));
    for (k, (lo, hi)) in sleepers.iter().enumerate() {
        boxes.push((
            format!("under_sleeper_{}", k + 1),
            ControlBox {
                min: Point3::new(lo.x, lo.y.max(y_lo), margin),
                max: Point3::new(hi.x, hi.y.min(y_hi), lo.z),
            },
        ));
    }
    for (k, pair) in sleepers.windows(2).enumerate() {
        let (left, right) = (&pair[0], &pair[1]);
        boxes.push((
            format!("crib_{}_{}", k + 1, k + 2),
            ControlBox {
                min: Point3::new(left.1.x, left.0.y.max(y_lo), margin),
                max: Point3::new(right.0.x, left.1.y.min(y_hi), crib_top - margin),
            },
        ));
    }
    boxes
}

/// The solid fraction of the stones in each box, exactly (each stone's hull clipped by
/// the box, [`convex_volume_in_box`]).
pub fn compactness(
    bodies: &[Body],
    roles: &[Role],
    boxes: &[(String, ControlBox)],
) -> Vec<Compactness> {
    let stones: Vec<&Body> = bodies
        .iter()
        .zip(roles)
        .filter(|(_, r)| matches!(r, Role::Stone(_)))
        .map(|(b, _)| b)
        .collect();
    boxes
        .iter()
        .map(|(name, bx)| Compactness {
            name: name.clone(),
            bx: *bx,
            value: solid_fraction(&stones, bx),
        })
        .collect()
}

/// Σ volume(stone ∩ `bx`) / volume(`bx`) over `stones`, exactly
/// ([`convex_volume_in_box`]). The stones' shares are computed in parallel and summed
/// in order, so the value does not depend on the thread count.
pub fn solid_fraction(stones: &[&Body], bx: &ControlBox) -> f64 {
    use rayon::prelude::*;
    let shares: Vec<f64> = stones
        .par_iter()
        .map(|b| convex_volume_in_box(&b.shape.vertices, &b.shape.triangles, &b.pose(), bx))
        .collect();
    shares.iter().sum::<f64>() / bx.volume()
}

/// Mean number of contacting neighbours per stone, 2 P / N with P the stone–stone
/// pairs that carry a normal impulse in `contacts` (several points of one pair count
/// once); and the same with walls, floor and sleepers counted as neighbours.
pub fn coordination_numbers(roles: &[Role], contacts: &[SolvedContact]) -> (f64, f64) {
    let mut pairs: Vec<(u32, u32)> = contacts
        .iter()
        .filter(|c| c.impulse[0] > 0.0)
        .map(|c| (c.contact.key.body_a, c.contact.key.body_b))
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let stone = |k: u32| matches!(roles[k as usize], Role::Stone(_));
    let stones = roles.iter().filter(|r| matches!(r, Role::Stone(_))).count();
    if stones == 0 {
        return (0.0, 0.0);
    }
    let (mut inner, mut ends) = (0usize, 0usize);
    for (a, b) in pairs {
        match (stone(a), stone(b)) {
            (true, true) => inner += 2,
            (true, false) | (false, true) => ends += 1,
            _ => {}
        }
    }
    (
        inner as f64 / stones as f64,
        (inner + ends) as f64 / stones as f64,
    )
}

/// Largest and mean interpenetration over the touching contact points of a detection
/// (m; zero when none interpenetrates).
pub fn interpenetration(contacts: &[ContactPoint]) -> (f64, f64) {
    let depths: Vec<f64> = contacts
        .iter()
        .filter(|c| c.gap < 0.0)
        .map(|c| -c.gap)
        .collect();
    if depths.is_empty() {
        return (0.0, 0.0);
    }
    let max = depths.iter().copied().fold(0.0, f64::max);
    (max, depths.iter().sum::<f64>() / depths.len() as f64)
}

/// Stones whose mass centre lies outside the container box.
pub fn stones_outside(bodies: &[Body], roles: &[Role], container: &ControlBox) -> usize {
    bodies
        .iter()
        .zip(roles)
        .filter(|(b, r)| {
            let p = b.position;
            matches!(r, Role::Stone(_))
                && !(p.x >= container.min.x
                    && p.x <= container.max.x
                    && p.y >= container.min.y
                    && p.y <= container.max.y
                    && p.z >= container.min.z
                    && p.z <= container.max.z)
        })
        .count()
}

/// The median of `values` (upper median for an even count; 0 for none).
pub fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_sit_under_the_sleepers_and_in_the_cribs() {
        let sleepers = [
            (Point3::new(0.2, -0.5, 0.3), Point3::new(0.45, 0.5, 0.5)),
            (Point3::new(0.8, -0.5, 0.3), Point3::new(1.05, 0.5, 0.5)),
        ];
        let boxes = control_boxes(1.25, 1.2, 0.3, &sleepers, 0.4, 0.04);
        let names: Vec<&str> = boxes.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(
            names,
            ["bed", "under_sleeper_1", "under_sleeper_2", "crib_1_2"]
        );
        let crib = boxes[3].1;
        assert_eq!((crib.min.x, crib.max.x), (0.45, 0.8));
        assert_eq!((crib.min.z, crib.max.z), (0.04, 0.4 - 0.04));
        let under = boxes[1].1;
        assert_eq!((under.min.y, under.max.y, under.max.z), (-0.5, 0.5, 0.3));
    }
}
