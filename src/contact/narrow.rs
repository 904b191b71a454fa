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
    let tolerance = 1e-9 * size;
    let best = face_separation(pos12, a, b, tolerance);
    if best.separation > alert {
        return;
    }
    if let GJKResult::ClosestPoints(p1, p2, dir) = contact_support_map_support_map_with_params(
        pos12,
        a,
        b,
        alert,
        &mut VoronoiSimplex::new(),
        Some(best.normal),
    ) {
        let distance = (p2 - p1).dot(&dir);
        if distance > best.separation + tolerance {
            edge_manifold(pos12, a, b, dir, manifold);
            if manifold.points.iter().all(|c| c.dist > alert) {
                // The clipped support features missed each other: keep GJK's pair of
                // closest points, so the contact is not lost.
                manifold.points.push(TrackedContact::new(
                    p1,
                    pos12.inverse_transform_point(&p2),
                    PackedFeatureId::UNKNOWN,
                    PackedFeatureId::UNKNOWN,
                    distance,
                ));
            }
            return;
        }
    }
    // Face contact: clip the other body's incident face against the reference face.
    if best.on_a {
        for c in clip_against_reference(a, best.face, b, pos12, alert) {
            manifold.points.push(TrackedContact::new(
                c.on_reference,
                pos12.inverse_transform_point(&c.on_incident),
                PackedFeatureId::face(best.face as u32),
                PackedFeatureId(c.incident_id),
                c.gap,
            ));
        }
        manifold.local_n1 = *best.normal;
        manifold.local_n2 = pos12.inverse_transform_vector(&-*best.normal);
    } else {
        let pos21 = pos12.inverse();
        for c in clip_against_reference(b, best.face, a, &pos21, alert) {
            manifold.points.push(TrackedContact::new(
                pos21.inverse_transform_point(&c.on_incident),
                c.on_reference,
                PackedFeatureId(c.incident_id),
                PackedFeatureId::face(best.face as u32),
                c.gap,
            ));
        }
        manifold.local_n1 = *best.normal;
        manifold.local_n2 = pos12.inverse_transform_vector(&-*best.normal);
    }
}

/// An edge–edge contact: parry's clipping of the support features along `normal`.
fn edge_manifold(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
    normal: Unit<Vector3<f64>>,
    manifold: &mut ContactManifold<(), ()>,
) {
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

/// A clipped point of an incident face, in the reference body's frame.
struct Clipped {
    on_reference: Point3<f64>,
    on_incident: Point3<f64>,
    gap: f64,
    incident_id: u32,
}

/// Sutherland–Hodgman: the incident face of `incident` (placed by `pose`, its frame in
/// the reference's) — the face most opposed to the reference face's normal — clipped by
/// the side planes of face `face` of `reference`; the points within `alert` of the
/// reference plane. Ids: an incident vertex keeps its parry vertex id; a point made by
/// side plane k on the edge that starts at point id i gets `0x8000_0000 | k << 20 | i`
/// (stable while the same edges cross).
fn clip_against_reference(
    reference: &ConvexShape,
    face: usize,
    incident: &ConvexShape,
    pose: &Isometry3<f64>,
    alert: f64,
) -> Vec<Clipped> {
    let pr = reference.polyhedron();
    let rf = &pr.faces()[face];
    let normal = *rf.normal;
    let loop_of = |poly: &parry3d_f64::shape::ConvexPolyhedron, f: usize| {
        let face = &poly.faces()[f];
        let first = face.first_vertex_or_edge as usize;
        poly.vertices_adj_to_face()[first..first + face.num_vertices_or_edges as usize].to_vec()
    };
    let reference_loop: Vec<Point3<f64>> = loop_of(pr, face)
        .iter()
        .map(|&v| pr.points()[v as usize])
        .collect();
    let pi = incident.polyhedron();
    let local_normal = pose.inverse_transform_vector(&normal);
    let (incident_face, _) = pi
        .faces()
        .iter()
        .enumerate()
        .map(|(k, f)| (k, f.normal.dot(&local_normal)))
        .fold(
            (0, f64::INFINITY),
            |best, x| if x.1 < best.1 { x } else { best },
        );
    let mut polygon: Vec<(Point3<f64>, u32)> = loop_of(pi, incident_face)
        .iter()
        .map(|&v| (pose * pi.points()[v as usize], PackedFeatureId::vertex(v).0))
        .collect();
    let centre = reference_loop
        .iter()
        .map(|p| p.coords)
        .sum::<Vector3<f64>>()
        / reference_loop.len() as f64;
    let count = reference_loop.len();
    for k in 0..count {
        let (r0, r1) = (reference_loop[k], reference_loop[(k + 1) % count]);
        let mut side = (r1 - r0).cross(&normal);
        if side.dot(&(r0.coords - centre)) < 0.0 {
            side = -side;
        }
        let distance = |p: &Point3<f64>| side.dot(&(p - r0));
        let mut next = Vec::with_capacity(polygon.len() + 2);
        for j in 0..polygon.len() {
            let (p, id) = polygon[j];
            let (q, _) = polygon[(j + 1) % polygon.len()];
            let (dp, dq) = (distance(&p), distance(&q));
            if dp <= 0.0 {
                next.push((p, id));
            }
            if (dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0) {
                let t = dp / (dp - dq);
                let crossing = p + (q - p) * t;
                next.push((crossing, 0x8000_0000 | ((k as u32) << 20) | (id & 0xF_FFFF)));
            }
        }
        polygon = next;
        if polygon.is_empty() {
            break;
        }
    }
    // Any other vertex of the incident body over the reference face and within the alert
    // distance (a corner that is not on the incident face: a tilted stone's lowest point).
    let sides: Vec<(Point3<f64>, Vector3<f64>)> = (0..count)
        .map(|k| {
            let (r0, r1) = (reference_loop[k], reference_loop[(k + 1) % count]);
            let mut side = (r1 - r0).cross(&normal);
            if side.dot(&(r0.coords - centre)) < 0.0 {
                side = -side;
            }
            (r0, side)
        })
        .collect();
    let r0 = reference_loop[0];
    for (v, p) in pi.points().iter().enumerate() {
        let id = PackedFeatureId::vertex(v as u32).0;
        let q = pose * p;
        if normal.dot(&(q - r0)) <= alert
            && sides.iter().all(|(r, side)| side.dot(&(q - r)) <= 0.0)
            && polygon.iter().all(|(_, other)| *other != id)
        {
            polygon.push((q, id));
        }
    }
    polygon
        .into_iter()
        .filter_map(|(p, id)| {
            let gap = normal.dot(&(p - r0));
            (gap <= alert).then(|| Clipped {
                on_reference: p - normal * gap,
                on_incident: p,
                gap,
                incident_id: id,
            })
        })
        .collect()
}

/// The best separating face of two polyhedra.
struct FaceSeparation {
    separation: f64,
    /// From a to b, a's frame.
    normal: Unit<Vector3<f64>>,
    on_a: bool,
    face: usize,
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
    tie: f64,
) -> FaceSeparation {
    let mut best = FaceSeparation {
        separation: f64::NEG_INFINITY,
        normal: Vector3::z_axis(),
        on_a: true,
        face: 0,
    };
    let pa = a.polyhedron();
    for (k, face) in pa.faces().iter().enumerate() {
        let n = face.normal;
        let on_face =
            pa.points()[pa.vertices_adj_to_face()[face.first_vertex_or_edge as usize] as usize];
        let support = pos12 * b.local_support_point(&pos12.inverse_transform_vector(&-*n));
        let separation = n.dot(&(support - on_face));
        if separation > best.separation {
            best = FaceSeparation {
                separation,
                normal: n,
                on_a: true,
                face: k,
            };
        }
    }
    let pb = b.polyhedron();
    for (k, face) in pb.faces().iter().enumerate() {
        let n = pos12 * face.normal;
        let on_face = pos12
            * pb.points()[pb.vertices_adj_to_face()[face.first_vertex_or_edge as usize] as usize];
        let support = a.local_support_point(&-*n);
        let separation = n.dot(&(support - on_face));
        // Ties (within `tie`) go to a's faces, so that two coplanar faces in contact
        // keep one reference from step to step (and their contact ids).
        if separation > best.separation + tie {
            best = FaceSeparation {
                separation,
                normal: -n,
                on_a: false,
                face: k,
            };
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
