//! Narrow phase: parry3d contact manifolds between convex polyhedra and half-spaces.
//!
//! A face contact gives several points (parry clips the two support faces against each
//! other), each with the parry feature ids that make its [`ContactKey`]. Points whose
//! gap exceeds the alert distance are dropped; parry's extra GJK point (unknown
//! features) is kept only when the clipping found nothing; points closer together than
//! a millionth of the bodies' size are merged (coincident corners of aligned faces would
//! otherwise give two rows of W that are equal).
//!
//! # The normal of two polyhedra
//! parry's own polyhedron–polyhedron manifold takes the GJK direction as the normal;
//! for faces in exact or near contact (a resting stack: distance ≈ 0) that direction is
//! round-off, and EPA may fail outright, losing the contact. Here the separation along
//! every face normal of both bodies is computed first (a partial separating-axis test,
//! O(faces × vertices)): a face normal realises the separation of any face–face or
//! face–vertex contact, and GJK/EPA's direction is taken only when it separates the
//! bodies clearly better (an edge–edge contact). The support faces are then clipped by
//! parry along that normal.

use nalgebra::{Isometry3, Point3, Unit, Vector3};
use parry3d_f64::query::details::contact_support_map_support_map_with_params;
use parry3d_f64::query::gjk::{GJKResult, VoronoiSimplex};
use parry3d_f64::query::{ContactManifold, TrackedContact};
use parry3d_f64::shape::{PackedFeatureId, PolygonalFeature, PolygonalFeatureMap, SupportMap};

use super::broad::{aabb_of, candidate_pairs, BroadShape};
use super::shape::{Collider, ConvexShape};
use super::{ContactKey, ContactPoint};

/// Contact detection with an alert distance, and its scratch space.
#[derive(Debug, Clone)]
pub struct Detector {
    /// Pairs whose gap is at most this (m) give contact points.
    pub alert_distance: f64,
    broad: Vec<BroadShape>,
}

impl Detector {
    /// A detector with the given alert distance (m).
    pub fn new(alert_distance: f64) -> Self {
        Detector {
            alert_distance,
            broad: Vec::new(),
        }
    }

    /// The contact points between `colliders` placed at `poses`; pairs of two bodies
    /// that are not `movable` are skipped. Points are appended to `out` in the order of
    /// the (sorted) body pairs, then parry's order within a pair.
    pub fn detect(
        &mut self,
        colliders: &[&Collider],
        poses: &[Isometry3<f64>],
        movable: &[bool],
        out: &mut Vec<ContactPoint>,
    ) {
        self.broad.clear();
        for (collider, pose) in colliders.iter().zip(poses) {
            self.broad.push(match collider {
                Collider::Convex(shape) => BroadShape::Bounded(aabb_of(shape.points(), pose)),
                Collider::HalfSpace(normal) => BroadShape::HalfSpace(
                    Point3::from(pose.translation.vector),
                    pose.rotation * *normal,
                ),
            });
        }
        for (i, j) in candidate_pairs(&self.broad, movable, self.alert_distance) {
            let (i, j) = (i as usize, j as usize);
            pair_contacts(
                (i, colliders[i], &poses[i]),
                (j, colliders[j], &poses[j]),
                self.alert_distance,
                out,
            );
        }
    }
}

/// One-shot detection (see [`Detector::detect`]).
pub fn detect(
    colliders: &[&Collider],
    poses: &[Isometry3<f64>],
    movable: &[bool],
    alert_distance: f64,
) -> Vec<ContactPoint> {
    let mut out = Vec::new();
    Detector::new(alert_distance).detect(colliders, poses, movable, &mut out);
    out
}

/// The contact manifold of two convex polyhedra (`pos12`: b's frame in a's), normal
/// chosen as in the module docs.
fn convex_convex_manifold(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
    alert: f64,
    size: f64,
    manifold: &mut ContactManifold<(), ()>,
) {
    let (face_separation, face_normal) = face_separation(pos12, a, b);
    if face_separation > alert {
        return;
    }
    let tolerance = 1e-9 * size;
    let mut normal = face_normal;
    if let GJKResult::ClosestPoints(p1, p2, dir) = contact_support_map_support_map_with_params(
        pos12,
        a,
        b,
        alert,
        &mut VoronoiSimplex::new(),
        Some(face_normal),
    ) {
        let distance = (p2 - p1).dot(&dir);
        if distance > face_separation + tolerance {
            normal = dir;
        }
    }
    let normal2 = pos12.inverse_transform_unit_vector(&-normal);
    let mut feature_a = PolygonalFeature::default();
    let mut feature_b = PolygonalFeature::default();
    a.local_support_feature(&normal, &mut feature_a);
    b.local_support_feature(&normal2, &mut feature_b);
    PolygonalFeature::contacts(
        pos12,
        &pos12.inverse(),
        &normal,
        &normal2,
        &feature_a,
        &feature_b,
        manifold,
        false,
    );
    manifold.local_n1 = *normal;
    manifold.local_n2 = *normal2;
}

/// Every hull vertex of `b` within `alert` of the half-space's plane is a contact point
/// (parry's half-space manifold keeps only the support face's first vertices, which may
/// miss the deepest vertex of a tilted stone).
fn halfspace_manifold(
    pos12: &Isometry3<f64>,
    normal: &Unit<Vector3<f64>>,
    b: &ConvexShape,
    alert: f64,
    manifold: &mut ContactManifold<(), ()>,
) {
    let normal_b = pos12.inverse_transform_unit_vector(normal);
    for (index, p) in b.points().iter().enumerate() {
        let on_b = pos12 * p;
        let distance = normal.dot(&on_b.coords);
        if distance <= alert {
            manifold.points.push(TrackedContact::new(
                on_b - **normal * distance,
                *p,
                PackedFeatureId::face(0),
                PackedFeatureId::vertex(index as u32),
                distance,
            ));
        }
    }
    manifold.local_n1 = **normal;
    manifold.local_n2 = -*normal_b;
}

/// The largest separation of `b` from a face plane of `a`, or of `a` from a face plane
/// of `b`, and the corresponding normal from a to b (a's frame).
fn face_separation(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
) -> (f64, Unit<Vector3<f64>>) {
    let mut best = (f64::NEG_INFINITY, Vector3::z_axis());
    let pa = a.polyhedron();
    for face in pa.faces() {
        let n = face.normal;
        let on_face =
            pa.points()[pa.vertices_adj_to_face()[face.first_vertex_or_edge as usize] as usize];
        let support = pos12 * b.local_support_point(&pos12.inverse_transform_vector(&-*n));
        let separation = n.dot(&(support - on_face));
        if separation > best.0 {
            best = (separation, n);
        }
    }
    let pb = b.polyhedron();
    for face in pb.faces() {
        let n = pos12 * face.normal;
        let on_face = pos12
            * pb.points()[pb.vertices_adj_to_face()[face.first_vertex_or_edge as usize] as usize];
        let support = a.local_support_point(&-*n);
        let separation = n.dot(&(support - on_face));
        if separation > best.0 {
            best = (separation, -n);
        }
    }
    best
}

type Side<'a> = (usize, &'a Collider, &'a Isometry3<f64>);

/// Appends the contact points of one pair. A half-space is always the first body of
/// its contacts (its normal is the contact normal).
fn pair_contacts(first: Side, second: Side, alert: f64, out: &mut Vec<ContactPoint>) {
    let (a, b) = match (first.1, second.1) {
        (Collider::HalfSpace(_), Collider::HalfSpace(_)) => return,
        (Collider::Convex(_), Collider::HalfSpace(_)) => (second, first),
        _ => (first, second),
    };
    let pos12 = a.2.inverse() * b.2;
    let mut manifold = ContactManifold::<(), ()>::new();
    let Collider::Convex(shape_b) = b.1 else {
        return;
    };
    let size = match a.1 {
        Collider::Convex(shape_a) => {
            let size = shape_a.bounding_radius().max(shape_b.bounding_radius());
            convex_convex_manifold(&pos12, shape_a, shape_b, alert, size, &mut manifold);
            size
        }
        Collider::HalfSpace(normal) => {
            halfspace_manifold(&pos12, normal, shape_b, alert, &mut manifold);
            shape_b.bounding_radius()
        }
    };
    let known = manifold
        .points
        .iter()
        .filter(|p| p.dist <= alert && p.fid1 != PackedFeatureId::UNKNOWN)
        .count();
    let normal = a.2.rotation * manifold.local_n1;
    let merge = 1e-6 * size;
    let start = out.len();
    for p in &manifold.points {
        if p.dist > alert || (known > 0 && p.fid1 == PackedFeatureId::UNKNOWN) {
            continue;
        }
        let on_a = a.2 * p.local_p1;
        let on_b = b.2 * p.local_p2;
        let point = Point3::from(0.5 * (on_a.coords + on_b.coords));
        if out[start..]
            .iter()
            .any(|q| (q.point - point).norm() < merge)
        {
            continue;
        }
        out.push(ContactPoint {
            key: ContactKey {
                body_a: a.0 as u32,
                body_b: b.0 as u32,
                feature_a: p.fid1.0,
                feature_b: p.fid2.0,
            },
            point,
            normal,
            gap: p.dist,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn cube(half: f64) -> Collider {
        let mut points = Vec::new();
        for k in 0..8 {
            points.push(Point3::new(
                if k & 1 == 0 { -half } else { half },
                if k & 2 == 0 { -half } else { half },
                if k & 4 == 0 { -half } else { half },
            ));
        }
        Collider::Convex(ConvexShape::from_points(&points).unwrap())
    }

    #[test]
    fn a_cube_on_a_plane_has_four_corner_contacts() {
        let floor = Collider::HalfSpace(Vector3::z_axis());
        let block = cube(0.5);
        let poses = [
            Isometry3::identity(),
            Isometry3::translation(0.0, 0.0, 0.5 + 1e-4),
        ];
        let contacts = detect(&[&floor, &block], &poses, &[false, true], 1e-3);
        assert_eq!(contacts.len(), 4);
        for c in &contacts {
            assert_eq!((c.key.body_a, c.key.body_b), (0, 1));
            assert!((c.gap - 1e-4).abs() < 1e-12, "{}", c.gap);
            assert!((c.normal - Vector3::z()).norm() < 1e-12);
            assert!((c.point.x.abs() - 0.5).abs() < 1e-12 && (c.point.y.abs() - 0.5).abs() < 1e-12);
        }
        // Beyond the alert distance: nothing.
        let far = [
            Isometry3::identity(),
            Isometry3::translation(0.0, 0.0, 0.502),
        ];
        assert!(detect(&[&floor, &block], &far, &[false, true], 1e-3).is_empty());
    }

    #[test]
    fn stacked_cubes_give_a_face_contact_with_stable_ids() {
        let lower = cube(0.5);
        let upper = cube(0.5);
        let pose = |dx: f64| {
            [
                Isometry3::identity(),
                Isometry3::from_parts(
                    Translation3::new(0.1 + dx, 0.05, 1.0 - 2e-5),
                    UnitQuaternion::identity(),
                ),
            ]
        };
        let first = detect(&[&lower, &upper], &pose(0.0), &[true, true], 1e-3);
        assert_eq!(first.len(), 4, "{first:?}");
        for c in &first {
            assert!((c.gap + 2e-5).abs() < 1e-9, "{}", c.gap);
            assert!((c.normal - Vector3::z()).norm() < 1e-9);
        }
        // A small slide keeps the same features in touch: the same keys.
        let second = detect(&[&lower, &upper], &pose(1e-3), &[true, true], 1e-3);
        let keys = |v: &[ContactPoint]| {
            let mut k: Vec<ContactKey> = v.iter().map(|c| c.key).collect();
            k.sort();
            k
        };
        assert_eq!(keys(&first), keys(&second));
    }
}
