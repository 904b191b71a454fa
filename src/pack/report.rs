//! What a packing is worth: compactness in control boxes (exact polyhedron clipping),
//! coordination number, interpenetration, stones outside the container.

use crate::contact::ContactPoint;
use crate::geometry::{convex_volume_in_box, ControlBox, Period};
use crate::nscd::body::Body;
use crate::nscd::step::SolvedContact;
use nalgebra::{Isometry3, Point3, Translation3, Vector3};

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
/// boxes (min and max corners, world, in order along x): under each sleeper (its
/// footprint, from `margin` above the floor to its underside, `margin` in from the side
/// walls), in each crib (between two sleepers, from `margin` to `margin` below
/// `crib_top`: the struck-off surface is as loose as a wall), and the whole bed below
/// the lowest underside (or `depth` without sleepers), `margin` in from every wall.
/// `margin` (one d50) keeps the walls' layering out of the measure. A bed `periodic`
/// along x has no end walls: the bed box takes the whole length, and the crib across
/// the ends (last sleeper to the first one's image) is `crib_N_1`, reaching past
/// `length` (measure it with [`solid_fraction`] and the period).
pub fn control_boxes(
    length: f64,
    width: f64,
    depth: f64,
    sleepers: &[(Point3<f64>, Point3<f64>)],
    crib_top: f64,
    margin: f64,
    periodic: bool,
) -> Vec<(String, ControlBox)> {
    let (y_lo, y_hi) = (-0.5 * width + margin, 0.5 * width - margin);
    let mut boxes = Vec::new();
    let underside = sleepers.iter().map(|s| s.0.z).fold(depth, f64::min);
    let end = if periodic { 0.0 } else { margin };
    boxes.push((
        "bed".to_string(),
        ControlBox {
            min: Point3::new(end, y_lo, margin),
            max: Point3::new(length - end, y_hi, underside - margin),
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
    let crib = |left: &(Point3<f64>, Point3<f64>), right_x: f64| ControlBox {
        min: Point3::new(left.1.x, left.0.y.max(y_lo), margin),
        max: Point3::new(right_x, left.1.y.min(y_hi), crib_top - margin),
    };
    for (k, pair) in sleepers.windows(2).enumerate() {
        let name = format!("crib_{}_{}", k + 1, k + 2);
        boxes.push((name, crib(&pair[0], pair[1].0.x)));
    }
    if let (true, Some(first), Some(last)) = (periodic, sleepers.first(), sleepers.last()) {
        let name = format!("crib_{}_1", sleepers.len());
        boxes.push((name, crib(last, first.0.x + length)));
    }
    boxes
}

/// The stones among `bodies` (by their `roles`).
pub fn stone_bodies<'a>(bodies: &'a [Body], roles: &[Role]) -> Vec<&'a Body> {
    bodies
        .iter()
        .zip(roles)
        .filter(|(_, r)| matches!(r, Role::Stone(_)))
        .map(|(b, _)| b)
        .collect()
}

/// The solid fraction of the stones in each box, exactly (each stone's hull clipped by
/// the box, [`convex_volume_in_box`]; with a `period`, its images too).
pub fn compactness(
    bodies: &[Body],
    roles: &[Role],
    boxes: &[(String, ControlBox)],
    period: Option<&Period>,
) -> Vec<Compactness> {
    let stones = stone_bodies(bodies, roles);
    boxes
        .iter()
        .map(|(name, bx)| Compactness {
            name: name.clone(),
            bx: *bx,
            value: solid_fraction(&stones, bx, period),
        })
        .collect()
}

/// Σ volume(stone ∩ `bx`) / volume(`bx`) over `stones`, exactly
/// ([`convex_volume_in_box`]). With a `period`, a stone also counts through its images
/// one length either way that reach the box: a stone across an end counts in a box at
/// the other end, and a box may reach past the ends (a crib across them). The stones'
/// shares are computed in parallel and summed in order, so the value does not depend
/// on the thread count.
pub fn solid_fraction(stones: &[&Body], bx: &ControlBox, period: Option<&Period>) -> f64 {
    use rayon::prelude::*;
    let shares: Vec<f64> = stones
        .par_iter()
        .map(|b| {
            let pose = b.pose();
            let share = |pose: &Isometry3<f64>| {
                convex_volume_in_box(&b.shape.vertices, &b.shape.triangles, pose, bx)
            };
            let mut volume = share(&pose);
            if let Some(p) = period {
                let (x, r) = (b.position[p.axis], b.shape.bounding_radius());
                for k in [1, -1] {
                    // The image's bounding sphere against the box along the axis.
                    let image = x + f64::from(k) * p.length;
                    if image + r > bx.min[p.axis] && image - r < bx.max[p.axis] {
                        let shift = Translation3::from(Vector3::from(p.shift(k)));
                        volume += share(&(shift * pose));
                    }
                }
            }
            volume
        })
        .collect();
    shares.iter().sum::<f64>() / bx.volume()
}

/// The slices of [`depth_profile`] under the sleepers, in d50: a quarter of a stone, fine
/// enough to resolve the loose band under a flat face, coarse enough to hold a few
/// stones' worth of volume per slice.
pub const PROFILE_SLICE_OVER_D50: f64 = 0.25;

/// One horizontal slice of a control box: how far below the box's top it lies (m) and
/// the solid fraction in it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Slice {
    /// Depth of the slice's top below the box's top (m).
    pub from_m: f64,
    /// Depth of the slice's bottom below the box's top (m).
    pub to_m: f64,
    /// Σ volume(stone ∩ slice) / volume(slice).
    pub value: f64,
}

/// A control box's [`depth_profile`], as `summary.json` and `ballast-post compactness`
/// write it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BoxProfile {
    /// The box's name (`under_sleeper_1` …).
    #[serde(rename = "box")]
    pub name: String,
    /// The solid fraction of the box less its top d50: under a sleeper, the bulk below
    /// the underside's loose band, the figure to set beside compactness measured in
    /// track away from faces (`None` for a box less than a d50 high).
    pub below_one_d50: Option<f64>,
    /// Its slices from the top down.
    pub slices: Vec<Slice>,
}

impl BoxProfile {
    /// Measures box `name`: its [`depth_profile`] in slices near `slice` high and its
    /// solid fraction below its top `d50`.
    pub fn measure(
        stones: &[&Body],
        name: &str,
        bx: &ControlBox,
        slice: f64,
        d50: f64,
        period: Option<&Period>,
    ) -> Self {
        let mut bulk = *bx;
        bulk.max.z -= d50;
        BoxProfile {
            name: name.to_string(),
            below_one_d50: (bulk.volume() > 0.0).then(|| solid_fraction(stones, &bulk, period)),
            slices: depth_profile(stones, bx, slice, period),
        }
    }

    /// One line: the box, the slices' height and their values from the top down.
    pub fn line(&self) -> String {
        let h = self.slices.first().map_or(0.0, |s| s.to_m - s.from_m);
        let values: Vec<String> = self
            .slices
            .iter()
            .map(|s| format!("{:.3}", s.value))
            .collect();
        let bulk = self
            .below_one_d50
            .map_or(String::new(), |v| format!("; below its top d50: {v:.4}"));
        format!(
            "{} by depth below its top ({:.1} mm slices): {}{bulk}",
            self.name,
            1e3 * h,
            values.join(" ")
        )
    }
}

/// The solid fraction of `bx` by depth below its top: the box cut into horizontal
/// slices of equal height, as near `thickness` as a whole number of them allows (at
/// least one), each measured as [`solid_fraction`]. Under a sleeper the top is its
/// underside, so the profile shows the loose band a flat face leaves in a granular
/// bed (the wall effect: about half a grain deep) apart from the bulk below it.
/// The slices' mean is the box's compactness (volumes add).
pub fn depth_profile(
    stones: &[&Body],
    bx: &ControlBox,
    thickness: f64,
    period: Option<&Period>,
) -> Vec<Slice> {
    let height = bx.max.z - bx.min.z;
    if !(height > 0.0 && thickness > 0.0) {
        return Vec::new();
    }
    let n = ((height / thickness).round() as usize).max(1);
    let h = height / n as f64;
    (0..n)
        .map(|k| {
            let (from_m, to_m) = (k as f64 * h, (k + 1) as f64 * h);
            let mut slice = *bx;
            slice.max.z = bx.max.z - from_m;
            slice.min.z = if k + 1 == n {
                bx.min.z
            } else {
                bx.max.z - to_m
            };
            Slice {
                from_m,
                to_m,
                value: solid_fraction(stones, &slice, period),
            }
        })
        .collect()
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
        let boxes = control_boxes(1.25, 1.2, 0.3, &sleepers, 0.4, 0.04, false);
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

    #[test]
    fn a_profile_cuts_a_box_into_slices_whose_mean_is_the_box() {
        use crate::nscd::body::BodyShape;
        use std::sync::Arc;
        // A 0.1 m cube whose top sits 0.02 m below the box's top (0.1 m high).
        let cube = Arc::new(BodyShape::cuboid(Vector3::repeat(0.1)).unwrap());
        let stone = Body::dynamic("s", cube, 1.0, 0, Isometry3::translation(0.0, 0.0, 0.03));
        let bx = ControlBox {
            min: Point3::new(-0.1, -0.1, 0.0),
            max: Point3::new(0.1, 0.1, 0.1),
        };
        let slices = depth_profile(&[&stone], &bx, 0.026, None);
        assert_eq!(
            slices.len(),
            4,
            "0.1 m in slices near 0.026 m: four of 0.025"
        );
        let quarter = 0.25; // the cube's 0.1 × 0.1 footprint in the 0.2 × 0.2 box
        let expected = [quarter * 0.005 / 0.025, quarter, quarter, quarter];
        for (s, e) in slices.iter().zip(expected) {
            assert!((s.value - e).abs() < 1e-12, "{s:?}, expected {e}");
        }
        assert!((slices[3].to_m - 0.1).abs() < 1e-15);
        let mean = slices.iter().map(|s| s.value).sum::<f64>() / 4.0;
        let whole = solid_fraction(&[&stone], &bx, None);
        assert!((mean - whole).abs() < 1e-12, "{mean} against {whole}");
    }

    #[test]
    fn periodic_solid_fraction_counts_images_in_boxes_past_and_at_the_ends() {
        use crate::nscd::body::BodyShape;
        use std::sync::Arc;
        let cube = Arc::new(BodyShape::cuboid(Vector3::repeat(0.1)).unwrap());
        let at = |x: f64| {
            Body::dynamic(
                "stone",
                cube.clone(),
                1.0,
                0,
                Isometry3::translation(x, 0.0, 0.0),
            )
        };
        let period = Period {
            axis: 0,
            low: 0.0,
            length: 1.0,
        };
        let bx = |x0: f64, x1: f64| ControlBox {
            min: Point3::new(x0, -0.05, -0.05),
            max: Point3::new(x1, 0.05, 0.05),
        };
        let near_low = at(0.03); // [-0.02, 0.08]; image +1 at [0.98, 1.08]
        let near_high = at(0.97); // [0.92, 1.02]; image −1 at [-0.08, 0.02]
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        // A crib box past the high end holds 0.07 of the first stone's image.
        let past = solid_fraction(&[&near_low], &bx(0.9, 1.05), Some(&period));
        assert!(close(past, 0.07 / 0.15), "{past}");
        assert_eq!(solid_fraction(&[&near_low], &bx(0.9, 1.05), None), 0.0);
        // A box at the low end: the first stone's own 0.08, the second's image 0.02.
        let low = solid_fraction(&[&near_low, &near_high], &bx(0.0, 0.1), Some(&period));
        assert!(close(low, 0.1 / 0.1), "{low}");
        // Across the whole cell every stone counts exactly once.
        let whole = solid_fraction(&[&near_low, &near_high], &bx(0.0, 1.0), Some(&period));
        assert!(close(whole, 0.2 / 1.0), "{whole}");
    }
}
