//! Exact volume of a convex polyhedron inside an axis-aligned box.
//!
//! The compactness (solid fraction) of a packing in a control box (under a sleeper, in a
//! crib) is Σ_stones volume(stone ∩ box) / volume(box); it has to be exact (up to
//! round-off), not sampled, so that it converges with the packing and not with a grid.
//!
//! The polyhedron is a list of planar, outward-oriented polygons (its faces). It is cut by
//! one half-space n·x ≤ d at a time: Sutherland–Hodgman clips every face, faces left with
//! nothing strictly inside are dropped, and the points that lie on the cutting plane
//! (edge crossings and vertices on the plane) make the cap polygon, ordered by angle
//! around their centroid so that its normal is n (outward). The volume follows from the
//! divergence theorem: the signed tetrahedra (reference, fan triangle) of all faces, with a
//! reference point on the clipped solid to limit round-off.

use nalgebra::{Isometry3, Point3, Vector3};

/// A planar polygon of a polyhedron, counter-clockwise seen from outside.
type Polygon = Vec<Point3<f64>>;

/// Tolerance, relative to the body's bounding-box diagonal, within which a vertex counts as
/// lying on a cutting plane (neither kept inside nor cut off).
const ON_PLANE_TOL: f64 = 1e-12;
/// Tolerance, relative to the body's bounding-box diagonal, within which two points of a
/// cap are merged.
const MERGE_TOL: f64 = 1e-10;

/// An axis-aligned box `[min, max]`: a control volume in which the compactness of the
/// packing is measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlBox {
    /// Lower corner (m); a component may be `-∞` for a side without bound.
    pub min: Point3<f64>,
    /// Upper corner (m); a component may be `+∞` for a side without bound.
    pub max: Point3<f64>,
}

impl ControlBox {
    /// The volume of the box (m³): 0 when it is empty (some `max < min`), `+∞` when it is
    /// unbounded and not empty.
    pub fn volume(&self) -> f64 {
        let extent = self.max - self.min;
        if extent.iter().any(|&e| e.is_nan() || e <= 0.0) {
            0.0
        } else {
            extent.iter().product()
        }
    }
}

/// Volume (m³) of the convex polyhedron (hull vertices `vertices` and outward triangles
/// `triangles`, 0-based indices, in the body frame, placed in the world by `pose`) that
/// lies inside `bx`: the stone's share of the solid volume of a control box.
///
/// A body whose world bounding box lies inside `bx` gets its full volume (the same value as
/// [`crate::geometry::mass_properties`]); one whose bounding box does not overlap `bx` (or
/// only touches it) gets 0; otherwise the polyhedron is clipped by the box sides that cut
/// its bounding box (see [`clipped_convex_volume`]).
pub fn convex_volume_in_box(
    vertices: &[Point3<f64>],
    triangles: &[[u32; 3]],
    pose: &Isometry3<f64>,
    bx: &ControlBox,
) -> f64 {
    if vertices.is_empty() || triangles.is_empty() {
        return 0.0;
    }
    let world: Vec<Point3<f64>> = vertices.iter().map(|v| pose * v).collect();
    let (lo, hi) = bounding_box(&world);
    // Strict comparisons: a box that only touches the body, is empty or NaN gives 0.
    let overlaps = (0..3).all(|i| hi[i] > bx.min[i] && lo[i] < bx.max[i] && bx.min[i] < bx.max[i]);
    if !overlaps {
        return 0.0;
    }
    if (0..3).all(|i| lo[i] >= bx.min[i] && hi[i] <= bx.max[i]) {
        return full_volume(vertices, triangles);
    }
    let mut planes = Vec::with_capacity(6);
    for i in 0..3 {
        let axis = Vector3::ith(i, 1.0);
        if hi[i] > bx.max[i] {
            planes.push((axis, bx.max[i]));
        }
        if lo[i] < bx.min[i] {
            planes.push((-axis, -bx.min[i]));
        }
    }
    let faces = triangles
        .iter()
        .map(|t| t.iter().map(|&k| world[k as usize]).collect())
        .collect();
    clipped_convex_volume(faces, &planes)
}

/// Volume of the convex polyhedron bounded by `faces` (planar polygons, counter-clockwise
/// seen from outside, so that the polyhedron is closed and outward oriented; triangles are
/// fine) intersected with the half-spaces n·x ≤ d of `planes` (`(n, d)`; n need not be a
/// unit vector). This is the general form behind [`convex_volume_in_box`].
///
/// A zero normal is the constraint 0 ≤ d: it keeps everything when d ≥ 0 and nothing
/// otherwise; d = +∞ keeps everything. Vertices within 10⁻¹² of the bounding-box diagonal
/// of a plane count as on it. Round-off can make a vanishing volume slightly negative; the
/// result is clamped at 0.
pub fn clipped_convex_volume(
    mut faces: Vec<Vec<Point3<f64>>>,
    planes: &[(Vector3<f64>, f64)],
) -> f64 {
    let Some(origin) = faces.iter().find_map(|f| f.first()).copied() else {
        return 0.0;
    };
    // Work relative to a vertex so that far-away stones do not lose digits.
    for p in faces.iter_mut().flatten() {
        *p = Point3::from(*p - origin);
    }
    let all: Vec<Point3<f64>> = faces.iter().flatten().copied().collect();
    let (lo, hi) = bounding_box(&all);
    let size = (hi - lo).norm();
    if !(size > 0.0 && size.is_finite()) {
        return 0.0;
    }
    let (on_tol, merge_tol) = (ON_PLANE_TOL * size, MERGE_TOL * size);
    for (n, d) in planes {
        let norm = n.norm();
        if norm == 0.0 || norm.is_nan() {
            if *d >= 0.0 {
                continue;
            }
            return 0.0;
        }
        let normal = n / norm;
        let offset = (d - n.dot(&origin.coords)) / norm;
        faces = clip_by_plane(faces, &normal, offset, on_tol, merge_tol);
        if faces.is_empty() {
            return 0.0;
        }
    }
    let reference = faces[0][0];
    enclosed_volume(&faces, &reference).max(0.0)
}

/// The faces of the part of the closed polyhedron `faces` in the half-space
/// `normal`·x ≤ `offset` (`normal` a unit vector), with the cap on the plane added.
fn clip_by_plane(
    faces: Vec<Polygon>,
    normal: &Vector3<f64>,
    offset: f64,
    on_tol: f64,
    merge_tol: f64,
) -> Vec<Polygon> {
    let distance = |p: &Point3<f64>| normal.dot(&p.coords) - offset;
    let (mut any_out, mut any_in) = (false, false);
    for p in faces.iter().flatten() {
        let s = distance(p);
        any_out |= s > on_tol;
        any_in |= s < -on_tol;
    }
    if !any_out {
        return faces;
    }
    if !any_in {
        return Vec::new();
    }
    let mut kept = Vec::with_capacity(faces.len() + 1);
    let mut cap = Vec::new();
    for face in faces {
        let s: Vec<f64> = face.iter().map(distance).collect();
        let on = |x: f64| x.abs() <= on_tol;
        if !s.iter().any(|&x| x < -on_tol) {
            // Nothing strictly inside: the face is cut off or lies in the plane, where the
            // cap replaces it.
            cap.extend(face.iter().zip(&s).filter(|(_, &x)| on(x)).map(|(p, _)| *p));
            continue;
        }
        if s.iter().all(|&x| x <= on_tol) {
            cap.extend(face.iter().zip(&s).filter(|(_, &x)| on(x)).map(|(p, _)| *p));
            kept.push(face);
            continue;
        }
        let mut polygon = Vec::with_capacity(face.len() + 2);
        for i in 0..face.len() {
            let j = (i + 1) % face.len();
            let (a, sa, b, sb) = (face[i], s[i], face[j], s[j]);
            if sa <= on_tol {
                polygon.push(a);
                if on(sa) {
                    cap.push(a);
                }
            }
            // The crossing is always computed from the inside end, so that the two faces
            // sharing an edge get the same point, bit for bit.
            let crossing = if sa < -on_tol && sb > on_tol {
                Some(crossing(&a, sa, &b, sb))
            } else if sa > on_tol && sb < -on_tol {
                Some(crossing(&b, sb, &a, sa))
            } else {
                None
            };
            if let Some(p) = crossing {
                polygon.push(p);
                cap.push(p);
            }
        }
        if polygon.len() >= 3 {
            kept.push(polygon);
        }
    }
    if let Some(polygon) = cap_polygon(cap, normal, merge_tol) {
        kept.push(polygon);
    }
    kept
}

/// The point where the segment from `inside` (signed distance `s_in` < 0) to `outside`
/// (`s_out` > 0) crosses the plane.
fn crossing(inside: &Point3<f64>, s_in: f64, outside: &Point3<f64>, s_out: f64) -> Point3<f64> {
    inside + (outside - inside) * (s_in / (s_in - s_out))
}

/// The convex polygon through `points` (on a plane of unit normal `normal`), merged within
/// `merge_tol` and ordered counter-clockwise around `normal`; `None` with fewer than three
/// distinct points.
fn cap_polygon(points: Vec<Point3<f64>>, normal: &Vector3<f64>, merge_tol: f64) -> Option<Polygon> {
    let mut unique: Vec<Point3<f64>> = Vec::with_capacity(points.len() / 2 + 1);
    for p in points {
        if !unique
            .iter()
            .any(|q| (q - p).norm_squared() <= merge_tol * merge_tol)
        {
            unique.push(p);
        }
    }
    if unique.len() < 3 {
        return None;
    }
    let centroid =
        Point3::from(unique.iter().map(|p| p.coords).sum::<Vector3<f64>>() / unique.len() as f64);
    // (u, v, normal) is right-handed, so increasing angle from u towards v turns
    // counter-clockwise seen from the side `normal` points to.
    let helper = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = normal.cross(&helper).normalize();
    let v = normal.cross(&u);
    let mut keyed: Vec<(f64, Point3<f64>)> = unique
        .into_iter()
        .map(|p| {
            let r = p - centroid;
            (r.dot(&v).atan2(r.dot(&u)), p)
        })
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
    Some(keyed.into_iter().map(|(_, p)| p).collect())
}

/// The volume enclosed by the closed, outward-oriented `faces`: the signed tetrahedra
/// (`reference`, fan triangle) summed over the faces (divergence theorem).
fn enclosed_volume(faces: &[Polygon], reference: &Point3<f64>) -> f64 {
    let mut six_volume = 0.0;
    for face in faces {
        let Some(first) = face.first() else { continue };
        let a = first - reference;
        for pair in face[1..].windows(2) {
            let (b, c) = (pair[0] - reference, pair[1] - reference);
            six_volume += a.dot(&b.cross(&c));
        }
    }
    six_volume / 6.0
}

/// The volume of the closed triangle surface, computed as
/// [`crate::geometry::mass_properties`] does (same reference, same order of sums).
fn full_volume(vertices: &[Point3<f64>], triangles: &[[u32; 3]]) -> f64 {
    let origin = vertices[0].coords;
    let mut volume = 0.0;
    for tri in triangles {
        let a = vertices[tri[0] as usize].coords - origin;
        let b = vertices[tri[1] as usize].coords - origin;
        let c = vertices[tri[2] as usize].coords - origin;
        volume += a.dot(&b.cross(&c)) / 6.0;
    }
    volume
}

/// The bounding box (lower, upper corner) of `points`.
fn bounding_box(points: &[Point3<f64>]) -> (Point3<f64>, Point3<f64>) {
    let mut lo = Point3::from(Vector3::repeat(f64::INFINITY));
    let mut hi = Point3::from(Vector3::repeat(f64::NEG_INFINITY));
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{convex_hull, convex_hull_volume, mass_properties};
    use nalgebra::Translation3;

    /// Relative tolerance of the checks: every result below is a sum of a few hundred
    /// tetrahedron determinants of O(1) numbers, each off by a few ulp (2.2e-16), so the
    /// relative error is ≲ 1e-13; 1e-12 leaves a margin and still catches any wrong face.
    const REL: f64 = 1e-12;

    fn close(actual: f64, expected: f64, scale: f64) -> bool {
        (actual - expected).abs() <= REL * scale
    }

    fn cube(lo: f64, hi: f64) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        let mut corners = Vec::new();
        for &x in &[lo, hi] {
            for &y in &[lo, hi] {
                for &z in &[lo, hi] {
                    corners.push(Point3::new(x, y, z));
                }
            }
        }
        convex_hull(&corners).unwrap()
    }

    fn boxed(min: [f64; 3], max: [f64; 3]) -> ControlBox {
        ControlBox {
            min: Point3::from(min),
            max: Point3::from(max),
        }
    }

    /// A fixed-seed uniform generator on [0, 1) (64-bit LCG, top 53 bits).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The hull of 30 random points of an ellipsoidal shell, like a stone (semi-axes 3, 2, 1.5).
    fn random_stone(seed: u64) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        let mut rng = Lcg(seed);
        let points: Vec<Point3<f64>> = (0..30)
            .map(|_| {
                let d = Vector3::new(rng.next(), rng.next(), rng.next()).map(|x| 2.0 * x - 1.0);
                let d = d.normalize() * (0.7 + 0.3 * rng.next());
                Point3::new(3.0 * d.x, 2.0 * d.y, 1.5 * d.z)
            })
            .collect();
        convex_hull(&points).unwrap()
    }

    fn faces_of(vertices: &[Point3<f64>], triangles: &[[u32; 3]]) -> Vec<Polygon> {
        triangles
            .iter()
            .map(|t| t.iter().map(|&k| vertices[k as usize]).collect())
            .collect()
    }

    #[test]
    fn control_box_volume() {
        assert_eq!(boxed([0.0, 1.0, 2.0], [2.0, 4.0, 6.0]).volume(), 24.0);
        assert_eq!(boxed([0.0; 3], [1.0, -1.0, f64::INFINITY]).volume(), 0.0);
        assert_eq!(
            boxed([0.0; 3], [1.0, 1.0, f64::INFINITY]).volume(),
            f64::INFINITY
        );
    }

    #[test]
    fn unit_cube_inside_outside_half_and_corner() {
        // Dyadic coordinates and cuts at 0.5: every step is exact, 1e-12 is only a margin.
        let (v, t) = cube(0.0, 1.0);
        let id = Isometry3::identity();
        let inf = f64::INFINITY;
        let vol = |b: ControlBox| convex_volume_in_box(&v, &t, &id, &b);
        assert!(close(vol(boxed([-1.0; 3], [2.0; 3])), 1.0, 1.0));
        assert_eq!(vol(boxed([2.0; 3], [3.0; 3])), 0.0);
        assert_eq!(vol(boxed([1.0, 0.0, 0.0], [2.0, 1.0, 1.0])), 0.0); // touches a face
        assert!(close(vol(boxed([-1.0; 3], [0.5, 2.0, 2.0])), 0.5, 1.0));
        assert!(close(vol(boxed([0.5; 3], [inf; 3])), 0.125, 1.0));
        // Box sides on the cube's faces (coplanar clipping) plus one cut at z = 0.5.
        assert!(close(
            vol(boxed([0.0, -1.0, -1.0], [1.0, 2.0, 0.5])),
            0.5,
            1.0
        ));
        assert!(close(vol(boxed([0.0; 3], [1.0; 3])), 1.0, 1.0));
        // A translated cube gives the same share.
        let moved = Isometry3::translation(100.25, -40.5, 7.0);
        let b = boxed([-inf; 3], [100.75, inf, inf]);
        assert!(close(convex_volume_in_box(&v, &t, &moved, &b), 0.5, 1.0));
    }

    #[test]
    fn rotated_cube_half_and_triangular_prism() {
        // Unit cube centred at the origin, turned 45° about z: its xy section is a square
        // with corners (±√2/2, 0), (0, ±√2/2). Rotation round-off is ~1e-16 relative.
        let (v, t) = cube(-0.5, 0.5);
        let pose = Isometry3::rotation(Vector3::z() * std::f64::consts::FRAC_PI_4);
        let big = 10.0;
        let half = convex_volume_in_box(&v, &t, &pose, &boxed([-big; 3], [big, 0.0, big]));
        assert!(close(half, 0.5, 1.0), "{half}");
        // x ≥ c cuts a triangle of height h = √2/2 − c and base 2h: a prism of volume h²·1.
        let c = 0.3;
        let h = std::f64::consts::FRAC_1_SQRT_2 - c;
        let prism = convex_volume_in_box(&v, &t, &pose, &boxed([c, -big, -big], [big; 3]));
        assert!(close(prism, h * h, 1.0), "{prism} vs {}", h * h);
    }

    #[test]
    fn tetrahedron_corner_is_a_similar_tetrahedron() {
        // The unit simplex x, y, z ≥ 0, x + y + z ≤ 1 has volume 1/6; its part with x ≥ c
        // is the simplex scaled by 1 − c (the cap is a cut across an oblique face).
        let v = vec![
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        let t = convex_hull(&v).unwrap();
        let c = 0.37;
        let inf = f64::INFINITY;
        let got = convex_volume_in_box(
            &t.0,
            &t.1,
            &Isometry3::identity(),
            &boxed([c, -inf, -inf], [inf; 3]),
        );
        let expected = (1.0 - c).powi(3) / 6.0;
        assert!(close(got, expected, 1.0 / 6.0), "{got} vs {expected}");
    }

    #[test]
    fn octants_of_random_stone_sum_to_its_volume() {
        for seed in [1, 7, 2024] {
            let (v, t) = random_stone(seed);
            let total = mass_properties(&v, &t).volume;
            let pose = Isometry3::new(Vector3::new(12.0, -3.5, 0.8), Vector3::new(0.3, -1.1, 0.7));
            // An interior point off the centre, so that the octants are unequal.
            let centre = pose * Point3::new(0.4, -0.3, 0.2);
            let inf = f64::INFINITY;
            let mut sum = 0.0;
            for octant in 0..8 {
                let mut b = boxed([-inf; 3], [inf; 3]);
                for i in 0..3 {
                    if octant >> i & 1 == 0 {
                        b.max[i] = centre[i];
                    } else {
                        b.min[i] = centre[i];
                    }
                }
                let part = convex_volume_in_box(&v, &t, &pose, &b);
                assert!(
                    part > 0.0 && part <= total,
                    "seed {seed} octant {octant}: {part}"
                );
                sum += part;
            }
            // Each octant's volume is within ~1e-15·total of exact; eight of them, 1e-12.
            assert!(close(sum, total, total), "seed {seed}: {sum} vs {total}");
        }
    }

    #[test]
    fn oblique_half_space_matches_hull_of_the_kept_points() {
        // Independent check of the general form: the part of a convex hull in n·x ≤ d is
        // the hull of the vertices inside and of the crossings of all vertex pairs. parry's
        // hull and the clipping round differently, so allow 1e-10 relative.
        for seed in [3, 11, 99] {
            let (v, t) = random_stone(seed);
            let mut rng = Lcg(seed + 1000);
            let n = Vector3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5) * 3.0;
            let d = 0.4 * (rng.next() - 0.5);
            let mut kept: Vec<Point3<f64>> = v
                .iter()
                .filter(|p| n.dot(&p.coords) <= d)
                .copied()
                .collect();
            for (i, a) in v.iter().enumerate() {
                for b in &v[i + 1..] {
                    let (sa, sb) = (n.dot(&a.coords) - d, n.dot(&b.coords) - d);
                    if sa * sb < 0.0 {
                        kept.push(a + (b - a) * (sa / (sa - sb)));
                    }
                }
            }
            let expected = convex_hull_volume(&kept).unwrap();
            let got = clipped_convex_volume(faces_of(&v, &t), &[(n, d)]);
            assert!(
                (got - expected).abs() <= 1e-10 * expected,
                "seed {seed}: {got} vs {expected}"
            );
        }
    }

    #[test]
    fn thinner_slab_cut_off_leaves_more() {
        // Boxes that hold the whole stone but a slab of thickness δ at the top of x: as δ
        // shrinks the volume may only grow (up to round-off, 1e-12·total), stays ≤ total, and
        // the slab lost is at most δ times the y–z extent of the stone.
        let (v, t) = random_stone(5);
        let total = mass_properties(&v, &t).volume;
        let pose = Isometry3::from_parts(Translation3::new(-2.0, 1.0, 3.0), Default::default());
        let world: Vec<Point3<f64>> = v.iter().map(|p| pose * p).collect();
        let (lo, hi) = bounding_box(&world);
        let mut previous = 0.0;
        for k in 0..=12 {
            let delta = 0.5 * 10f64.powi(-k);
            let b = boxed(
                [lo.x - 1.0, lo.y - 1.0, lo.z - 1.0],
                [hi.x - delta, hi.y + 1.0, hi.z + 1.0],
            );
            let part = convex_volume_in_box(&v, &t, &pose, &b);
            assert!(
                part >= previous - REL * total,
                "δ = {delta}: {part} < {previous}"
            );
            assert!(part <= total * (1.0 + REL), "δ = {delta}: {part} > {total}");
            let slab_bound = delta * (hi.y - lo.y) * (hi.z - lo.z);
            assert!(
                total - part <= slab_bound + REL * total,
                "δ = {delta}: lost {}",
                total - part
            );
            previous = part;
        }
        let b = boxed([-1e3; 3], [1e3; 3]);
        assert_eq!(convex_volume_in_box(&v, &t, &pose, &b), total);
    }

    #[test]
    fn degenerate_inputs_give_zero() {
        assert_eq!(clipped_convex_volume(Vec::new(), &[]), 0.0);
        let (v, t) = cube(0.0, 1.0);
        // Everything cut away by a half-space, or by a zero normal with d < 0.
        let faces = faces_of(&v, &t);
        assert_eq!(
            clipped_convex_volume(faces.clone(), &[(Vector3::x(), -0.5)]),
            0.0
        );
        assert_eq!(
            clipped_convex_volume(faces.clone(), &[(Vector3::zeros(), -1.0)]),
            0.0
        );
        assert!(close(
            clipped_convex_volume(faces, &[(Vector3::zeros(), 0.0)]),
            1.0,
            1.0
        ));
    }
}
