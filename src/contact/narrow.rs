//! Narrow phase: contact points between convex polyhedra and half-spaces, each with
//! its own normal, gap and the parry feature ids that make its [`ContactKey`].
//!
//! # Two polyhedra: a full separating-axis test
//! The separation along every face normal of both bodies (O(faces × vertices)) and
//! along every edge–edge axis `e_a × e_b` whose edges form a face of the Minkowski
//! difference (Gregorius's Gauss-map test, edges near the other body only) gives the
//! separating-axis answer `s`: the distance when apart (face–vertex and edge–edge
//! closest features), minus the penetration depth when overlapping. A pair with
//! `s` above the alert distance has no points. Otherwise its points are
//! - **face points**, for the best face of each body in turn as reference: the other
//!   body's incident face (most opposed to the reference normal) clipped by the
//!   reference face's side planes (Sutherland–Hodgman), plus any other vertex of the
//!   incident body over the reference face; gap along the face normal;
//! - **edge crossings**: every Minkowski edge pair whose edges cross (seen along their
//!   axis, within the alert distance sideways) — one point at the edges' closest
//!   points, normal `e_a × e_b`, gap the separation along it. Two edges of one stone
//!   across an edge of another are two points, each with its own normal;
//! - if none of these, the two support vertices along the best axis, gap `s`.
//!
//! The edge test skips edges far from the other body, which is exact for pairs within
//! the alert distance; a pair left with only the support vertices is checked by GJK
//! bounded by the alert distance (see [`gjk_separation`]: without it, stones a few mm
//! apart came out as overlapping). A point below its reference plane counts only if it
//! is inside the other body (else it is a far-side feature, not an overlap) or it is at
//! the pair's penetration depth on the face or edge pair that gives `s` (next to a
//! sharp corner such a point may poke out through a neighbouring face); when
//! `s > 0` no point is deeper than round-off, when `s ≤ 0` none deeper than `s − alert`,
//! and a point deeper than `s` gets the gap `s` (the pair's penetration depth). Points
//! whose gap exceeds the alert distance are dropped; points closer together than a
//! millionth of the bodies' size are merged, the first kept (coincident corners of
//! aligned faces would otherwise give two equal rows of W; the overall best face comes
//! first, so a resting face pair keeps its reference and keys).
//!
//! Why not parry's polyhedron manifold: it takes the GJK/EPA direction as the single
//! normal and clips the two support features along it; for faces in exact contact that
//! direction is round-off and EPA may fail, and for a tumbling stone's edge contact the
//! clipped points were not the closest ones (gaps of +1.6 mm reported where the stones
//! overlapped by 0.9 mm), so stones sank into each other unseen (`drop_box`).
//!
//! Half-space: every hull vertex within the alert distance.

use nalgebra::{Isometry3, Point3, Translation3, Unit, Vector3};
use parry3d_f64::query::gjk::{CSOPoint, GJKResult, VoronoiSimplex};
use parry3d_f64::shape::{PackedFeatureId, SupportMap};
use rayon::prelude::*;

use super::broad::{aabb_of, candidate_pairs, BroadShape};
use super::shape::{Collider, ConvexShape};
use super::{ContactKey, ContactPoint};
use crate::geometry::Period;

/// Candidate pairs per parallel task of the narrow phase (a pair of stones costs a few
/// µs, so a task is a few hundred µs: large beside rayon's overhead, small beside a
/// step).
const PAIRS_PER_TASK: usize = 128;

/// Contact detection with an alert distance, and its scratch space.
#[derive(Debug, Clone)]
pub struct Detector {
    /// Pairs whose gap is at most this (m) give contact points.
    pub alert_distance: f64,
    /// Each body's own reach (m; empty for none): a pair within `reach_i + reach_j`
    /// gives contact points too, so a fast body is seen by its neighbours without
    /// inflating every other pair's alert distance.
    pub reach: Vec<f64>,
    /// Periodicity along one axis (`None`: none): bodies meet across the cell's ends
    /// through their images (see [`candidate_pairs`]).
    pub period: Option<Period>,
    broad: Vec<BroadShape>,
}

impl Detector {
    /// A detector with the given alert distance (m).
    pub fn new(alert_distance: f64) -> Self {
        Detector {
            alert_distance,
            reach: Vec::new(),
            period: None,
            broad: Vec::new(),
        }
    }

    /// The contact points between `colliders` placed at `poses`; pairs of two bodies
    /// that are not `movable` are skipped. Points are appended to `out` in the order of
    /// the (sorted) body pairs, then parry's order within a pair. A pair across a
    /// periodic end is detected against the second body's image, and its points say
    /// which ([`ContactPoint::shift_b`]).
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
                Collider::Convex(shape) => {
                    BroadShape::Bounded(aabb_of(shape.points(), pose).grown(shape.round()))
                }
                Collider::Spheres(cluster) => {
                    BroadShape::Bounded(aabb_of(&cluster.centres, pose).grown(cluster.radius))
                }
                Collider::HalfSpace(normal) => BroadShape::HalfSpace(
                    Point3::from(pose.translation.vector),
                    pose.rotation * *normal,
                ),
            });
        }
        let reach = |i: usize| self.reach.get(i).copied().unwrap_or(0.0);
        let pairs = candidate_pairs(
            &self.broad,
            movable,
            self.alert_distance,
            &self.reach,
            self.period.as_ref(),
        );
        let period = self.period;
        // The narrow phase in parallel over chunks of the sorted pairs, concatenated in
        // order: the same points in the same order on any number of threads.
        let chunks: Vec<Vec<ContactPoint>> = pairs
            .par_chunks(PAIRS_PER_TASK)
            .map(|chunk| {
                let mut points = Vec::new();
                for &(i, j, image) in chunk {
                    let (i, j) = (i as usize, j as usize);
                    let alert = self.alert_distance.max(reach(i) + reach(j));
                    let first = (i, colliders[i], &poses[i]);
                    match (image, &period) {
                        (0, _) | (_, None) => {
                            pair_contacts(first, (j, colliders[j], &poses[j]), alert, &mut points)
                        }
                        (k, Some(p)) => {
                            let shift = Vector3::from(p.shift(k));
                            let pose_j = Translation3::from(shift) * poses[j];
                            let start = points.len();
                            pair_contacts(first, (j, colliders[j], &pose_j), alert, &mut points);
                            // Half-spaces pair at image 0 only, so the shifted body is
                            // the second of every point found.
                            for p in &mut points[start..] {
                                p.shift_b = shift;
                            }
                        }
                    }
                }
                points
            })
            .collect();
        for points in chunks {
            out.extend(points);
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

/// A contact point of a pair in the first body's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
struct LocalContact {
    /// The point on (or in) the first body.
    on_a: Point3<f64>,
    /// The point on (or in) the second body.
    on_b: Point3<f64>,
    /// Unit normal from the first body to the second.
    normal: Vector3<f64>,
    /// Feature codes on the first and second body.
    features: [u32; 2],
    /// Signed gap along the normal.
    gap: f64,
}

/// The contact points of two convex polyhedra (`pos12`: b's frame in a's; everything
/// in a's frame), as in the module docs: the best face's clipped contact polygon, plus
/// every edge–edge crossing whose own axis separates the bodies better than any face.
fn convex_convex_contacts(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
    alert: f64,
    size: f64,
    out: &mut Vec<LocalContact>,
) {
    // Most pairs whose boxes overlap are apart: one face of each body, the one facing
    // the other body, usually shows it in O(faces + vertices). Any face separating by
    // more than the alert distance makes the full test below return with no points
    // (the same expressions, so the same bits; the margin covers the tie rule).
    if quick_separation(pos12, a, b) > alert + 1e-9 * size {
        return;
    }
    let [face_a, face_b] = face_separations(pos12, a, b);
    // Ties (within 1e-9 of the size) go to a's faces, so that two coplanar faces in
    // contact keep one reference from step to step (and their contact ids).
    let (first, second) = if face_b.separation > face_a.separation + 1e-9 * size {
        (face_b, face_a)
    } else {
        (face_a, face_b)
    };
    if first.separation > alert {
        return;
    }
    let mut edges = Vec::new();
    let edge_best = edge_contacts(pos12, a, b, alert, &mut edges);
    // The separating-axis test's answer: the distance if separated (face–vertex and
    // edge–edge closest features), minus the penetration depth if not.
    let (sat, sat_normal) = if edge_best.0 > first.separation + 1e-6 * size {
        edge_best
    } else {
        (first.separation, *first.normal)
    };
    if sat > alert {
        return;
    }
    // Separated (an axis with a positive separation): no point can be deeper than
    // round-off. Overlapping: a point deeper than this along its own normal is not a
    // contact of the touching features but a far-side feature seen through the body.
    let tolerance = 1e-9 * size;
    let floor = if sat > 0.0 { -tolerance } else { sat - alert };
    // Face contacts: each body's best face as reference, the other's incident face
    // clipped against it (the overall best first: its points win the merge of
    // coincident points).
    for face in [&first, &second] {
        if face.separation > alert {
            continue;
        }
        // The face whose axis is the separating-axis answer: its deepest points are
        // the overlap itself (the support vertices along that axis), kept even where
        // they poke out beside the reference face's rim through a neighbouring face.
        let depth = (sat <= 0.0 && face.separation >= sat - tolerance).then_some(sat);
        let n = *face.normal;
        if face.on_a {
            for c in clip_against_reference(a, face.face, b, pos12, alert, floor, depth) {
                out.push(LocalContact {
                    on_a: c.on_reference,
                    on_b: c.on_incident,
                    normal: n,
                    features: [PackedFeatureId::face(face.face as u32).0, c.incident_id],
                    gap: c.gap,
                });
            }
        } else {
            let pos21 = pos12.inverse();
            for c in clip_against_reference(b, face.face, a, &pos21, alert, floor, depth) {
                out.push(LocalContact {
                    on_a: pos12 * c.on_incident,
                    on_b: pos12 * c.on_reference,
                    normal: n,
                    features: [c.incident_id, PackedFeatureId::face(face.face as u32).0],
                    gap: c.gap,
                });
            }
        }
    }
    // Edge–edge crossings, each with its own normal (a tumbling stone's edge across
    // another's ridge or rim; two edges across one edge are two points).
    // A crossing below the other edge is an overlap only if each point is inside the
    // other body (far from the edges' wedges it is a far-side pair), or if its axis is
    // the pair's separating-axis answer: then its edges are the support features along
    // that axis (EPA's depth), even where a point lies just outside a third face next
    // to the other edge's end (a 1.2 mm crossing with one point 1.8 µm outside was
    // dropped, and the pair reported 0.66 mm apart while its stones sank together).
    let pos21 = pos12.inverse();
    out.extend(edges.into_iter().filter(|c| {
        c.gap >= floor
            && (c.gap >= -tolerance
                || c.gap >= sat - tolerance
                || (a.contains(&c.on_b, tolerance) && b.contains(&(pos21 * c.on_a), tolerance)))
    }));
    // A point deeper along its own normal than the pair's penetration depth −s (a
    // corner under one face but next to another, or an edge crossing along a poor axis)
    // is held to that depth: moved by −s the pair is apart, so no push and no reported
    // overlap should be deeper (table3 bed: points 0.49 mm deep in pairs 1.6 µm deep).
    if sat < 0.0 {
        for p in out.iter_mut() {
            p.gap = p.gap.max(sat);
        }
    }
    if out.is_empty() {
        // No point over either reference face and no crossing edges (the bodies meet
        // corner to corner, or edge to corner): keep the two support vertices along
        // the separating axis, with the separation as the gap, so the pair is not lost
        // — unless GJK finds the pair apart, where its axis stands, or farther apart
        // than the alert distance, where there is no contact (see `gjk_separation`).
        let (sat, sat_normal) = match gjk_separation(pos12, a, b, alert) {
            Some((s, _)) if s > alert => return,
            Some((s, n)) if s > 0.0 && sat <= 0.0 => (s, n),
            _ => (sat, sat_normal),
        };
        let (ia, pa) = support_vertex(a, &sat_normal);
        let (ib, pb) = support_vertex(b, &pos12.inverse_transform_vector(&-sat_normal));
        out.push(LocalContact {
            on_a: pa,
            on_b: pos12 * pb,
            normal: sat_normal,
            features: [PackedFeatureId::vertex(ia).0, PackedFeatureId::vertex(ib).0],
            gap: sat,
        });
    }
}

/// parry's GJK on two hulls (`pos12`: b's frame in a's), bounded by `alert`, started
/// along the line of their centres; `exact` asks for closest points.
fn gjk(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
    alert: f64,
    exact: bool,
) -> GJKResult {
    let start = Unit::try_new(pos12.translation.vector, 1e-12).unwrap_or(Vector3::x_axis());
    let mut simplex = VoronoiSimplex::new();
    simplex.reset(CSOPoint::from_shapes(pos12, a, b, &-start));
    parry3d_f64::query::gjk::closest_points(pos12, a, b, alert, exact, &mut simplex)
}

/// The feature code of the closest-points contact of rounded hulls (one per pair).
const CLOSEST_FEATURE: u32 = u32::MAX;

/// Rounded hulls apart: the hulls' closest points (GJK), unless a point of `out` is as
/// close already. The face and edge points of [`convex_convex_contacts`] hold the
/// closest features' points only where the hulls touch or nearly: a corner a few mm
/// from an edge has neither, and rounded by more than that it is a contact.
fn closest_hull_points(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
    alert: f64,
    size: f64,
    out: &mut Vec<LocalContact>,
) {
    if let GJKResult::ClosestPoints(on_a, on_b, normal) = gjk(pos12, a, b, alert, true) {
        let distance = (on_b - on_a).norm();
        let covered = out
            .iter()
            .any(|p| p.gap > 0.0 && (p.on_b - p.on_a).norm() <= distance + 1e-9 * size);
        if !covered {
            out.push(LocalContact {
                on_a,
                on_b,
                normal: *normal,
                features: [CLOSEST_FEATURE, CLOSEST_FEATURE],
                gap: distance,
            });
        }
    }
}

/// GJK (parry's, bounded by the alert distance): the axis it ends on, `n` (unit, a's
/// frame, from a to b), with the pair's separation `s` along it, or `None` when the
/// pair touches or overlaps. `s > alert` proves the pair is farther apart than the
/// alert distance, `s > 0` that it is apart. `s` is measured with the support points
/// themselves, so a GJK that did not converge cannot drop a contact.
///
/// Why: the edge test tries only edges that come within the alert distance of the other
/// body's bounding sphere, which holds every edge that can touch it within that
/// distance, so the test's answer is exact for pairs closer than the alert distance.
/// For a pair farther apart whose separating axes all come from skipped edges it is
/// not: in a 6 887-stone table3 bed, 104 of 25 054 pairs were such phantoms, stones up
/// to 4.8 mm apart held by a contact 1.6 mm deep. Such a pair has no face point (one
/// over a reference face within the alert distance of it, or under it and inside the
/// body, is within the alert distance of the other body) and no edge crossing (its
/// edges would be within reach), so only the support-vertex fallback needs GJK.
fn gjk_separation(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
    alert: f64,
) -> Option<(f64, Vector3<f64>)> {
    // The separation along unit `n` (a's frame, from a to b): b's lowest point along n
    // less a's highest.
    let along = |n: &Vector3<f64>| {
        let low_b = pos12 * b.local_support_point(&pos12.inverse_transform_vector(&-n));
        let high_a = a.local_support_point(n);
        n.dot(&(low_b - high_a))
    };
    match gjk(pos12, a, b, alert, true) {
        GJKResult::NoIntersection(n)
        | GJKResult::Proximity(n)
        | GJKResult::ClosestPoints(_, _, n) => Some((along(&n), *n)),
        GJKResult::Intersection => None,
    }
}

/// The hull vertex farthest along `dir` (local) and its index.
fn support_vertex(shape: &ConvexShape, dir: &Vector3<f64>) -> (u32, Point3<f64>) {
    let (index, point) =
        shape
            .points()
            .iter()
            .enumerate()
            .fold((0, &shape.points()[0]), |best, (k, p)| {
                if p.coords.dot(dir) > best.1.coords.dot(dir) {
                    (k, p)
                } else {
                    best
                }
            });
    (index as u32, *point)
}

/// The edge–edge crossings of the separating-axis test (Gregorius, "The separating axis
/// test between convex polyhedra", GDC 2013): for every pair of an edge of `a` and an
/// edge of `b` that forms a face of the Minkowski difference (their arcs on the Gauss
/// map cross), the axis `n = e_a × e_b` (oriented out of a) has each edge as its body's
/// support feature, so the separation along it is `n·(p_b − p_a)` for any points of the
/// edges. A pair is a contact when that separation is at most `alert` and the two edges
/// cross (seen along n, their closest points are within `alert` of each other
/// sideways): the point is at the closest points, the normal is n. Only edges that come
/// within `alert` of the other body's bounding sphere are tried; near-parallel edges are
/// skipped (a face normal realises their separation). Returns the largest separation
/// over all the pairs tried and its axis (−∞ if none).
fn edge_contacts(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
    alert: f64,
    out: &mut Vec<LocalContact>,
) -> (f64, Vector3<f64>) {
    let mut best = (f64::NEG_INFINITY, Vector3::z());
    let centre_b = Point3::from(pos12.translation.vector);
    let centre_a = pos12.inverse_transform_point(&Point3::origin());
    let near = |ends: &[Point3<f64>; 2], centre: &Point3<f64>, radius: f64| {
        segment_point_distance(ends, centre) <= radius + alert
    };
    let edges_a: Vec<_> = a
        .edges()
        .iter()
        .filter(|e| near(&e.ends, &centre_b, b.bounding_radius()))
        .collect();
    if edges_a.is_empty() {
        return best;
    }
    // b's edges in a's frame, with the Gauss-map arc of −b (negated face normals).
    let edges_b: Vec<PlacedEdge> = b
        .edges()
        .iter()
        .filter(|e| near(&e.ends, &centre_a, a.bounding_radius()))
        .map(|e| {
            (
                [pos12 * e.ends[0], pos12 * e.ends[1]],
                [-(pos12 * e.normals[0]), -(pos12 * e.normals[1])],
                e.id,
            )
        })
        .collect();
    for ea in &edges_a {
        let [na, nb] = ea.normals;
        let b_x_a = nb.cross(&na);
        let da = ea.ends[1] - ea.ends[0];
        for (ends, [nc, nd], id) in &edges_b {
            // Do the arcs (na, nb) and (nc, nd) cross on the unit sphere?
            let cba = nc.dot(&b_x_a);
            let dba = nd.dot(&b_x_a);
            if cba * dba >= 0.0 {
                continue;
            }
            let d_x_c = nd.cross(nc);
            let adc = na.dot(&d_x_c);
            let bdc = nb.dot(&d_x_c);
            if adc * bdc >= 0.0 || cba * bdc <= 0.0 {
                continue;
            }
            let db = ends[1] - ends[0];
            let axis = da.cross(&db);
            let length = axis.norm();
            // Near-parallel (or degenerate) edges: no reliable axis.
            if length.is_nan() || length <= 1e-3 * da.norm() * db.norm() {
                continue;
            }
            let mut n = axis / length;
            if n.dot(&(na + nb)) < 0.0 {
                n = -n;
            }
            let separation = n.dot(&(ends[0] - ea.ends[0]));
            if separation > best.0 {
                best = (separation, n);
            }
            if separation > alert {
                continue;
            }
            let (on_a, on_b) = closest_points_of_segments(&ea.ends, ends);
            let offset = on_b - on_a;
            if (offset - n * n.dot(&offset)).norm() > alert {
                continue;
            }
            out.push(LocalContact {
                on_a,
                on_b,
                normal: n,
                features: [PackedFeatureId::edge(ea.id).0, PackedFeatureId::edge(*id).0],
                gap: separation,
            });
        }
    }
    best
}

/// An edge of the second body in the first's frame: its ends, the negated normals of
/// its two faces (the Gauss-map arc of −b), its parry id.
type PlacedEdge = ([Point3<f64>; 2], [Vector3<f64>; 2], u32);

/// The distance from `p` to the segment `ends`.
fn segment_point_distance(ends: &[Point3<f64>; 2], p: &Point3<f64>) -> f64 {
    let d = ends[1] - ends[0];
    let t = ((p - ends[0]).dot(&d) / d.norm_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
    (ends[0] + d * t - p).norm()
}

/// The closest points of two segments (Ericson, Real-Time Collision Detection §5.1.9).
fn closest_points_of_segments(
    s1: &[Point3<f64>; 2],
    s2: &[Point3<f64>; 2],
) -> (Point3<f64>, Point3<f64>) {
    let d1 = s1[1] - s1[0];
    let d2 = s2[1] - s2[0];
    let r = s1[0] - s2[0];
    let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let c = d1.dot(&r);
    let b = d1.dot(&d2);
    let denominator = a * e - b * b;
    let mut s = if denominator > 1e-12 * a * e {
        ((b * f - c * e) / denominator).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (b * s + f) / e;
    if t < 0.0 {
        t = 0.0;
        s = (-c / a).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((b - c) / a).clamp(0.0, 1.0);
    }
    (s1[0] + d1 * s, s2[0] + d2 * t)
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
/// (stable while the same edges cross). A point below the reference plane must be
/// inside the reference body, unless it is at `depth` (the pair's penetration depth,
/// given when this face's normal is the pair's separating axis).
fn clip_against_reference(
    reference: &ConvexShape,
    face: usize,
    incident: &ConvexShape,
    pose: &Isometry3<f64>,
    alert: f64,
    floor: f64,
    depth: Option<f64>,
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
    // A point below the reference plane is a contact only if it is inside the reference
    // body (else it is beyond another face, and the touching features are elsewhere: an
    // edge crossing or the other reference face) or at the pair's penetration depth.
    let tolerance = 1e-9 * reference.bounding_radius();
    let at_depth = |gap: f64| depth.is_some_and(|d| gap <= d + tolerance);
    polygon
        .into_iter()
        .filter_map(|(p, id)| {
            let gap = normal.dot(&(p - r0));
            let kept = gap <= alert
                && gap >= floor
                && (gap >= -tolerance || at_depth(gap) || reference.contains(&p, tolerance));
            kept.then(|| Clipped {
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

/// Every point of `b` (hull vertices, or sphere centres) within `alert` of the
/// half-space's plane is a contact point (parry's half-space manifold keeps only the
/// support face's first vertices, which may miss the deepest vertex of a tilted stone).
fn halfspace_contacts(
    pos12: &Isometry3<f64>,
    normal: &Unit<Vector3<f64>>,
    points: &[Point3<f64>],
    alert: f64,
    out: &mut Vec<LocalContact>,
) {
    for (index, p) in points.iter().enumerate() {
        let on_b = pos12 * p;
        let distance = normal.dot(&on_b.coords);
        if distance <= alert {
            out.push(LocalContact {
                on_a: on_b - **normal * distance,
                on_b,
                normal: **normal,
                features: [
                    PackedFeatureId::face(0).0,
                    PackedFeatureId::vertex(index as u32).0,
                ],
                gap: distance,
            });
        }
    }
}

/// The centres of `b`'s spheres against a hull `a` (`pos12`: b's frame in a's): every
/// centre within `alert` of the hull, with the hull's nearest point and the signed
/// distance ([`ConvexShape::nearest_point`]). The hull's feature is not tracked (0):
/// the sphere's index names the point.
fn hull_point_contacts(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    centres: &[Point3<f64>],
    alert: f64,
    out: &mut Vec<LocalContact>,
) {
    let reach = a.bounding_radius() + alert;
    for (index, c) in centres.iter().enumerate() {
        let on_b = pos12 * c;
        if on_b.coords.norm() > reach {
            continue;
        }
        let (on_a, normal, gap) = a.nearest_point(&on_b);
        if gap <= alert {
            out.push(LocalContact {
                on_a,
                on_b,
                normal,
                features: [0, PackedFeatureId::vertex(index as u32).0],
                gap,
            });
        }
    }
}

/// The sphere centres of two clusters within `alert` of each other (`pos12`: b's
/// frame in a's), each pair a point along the line of the centres. Each side is first
/// cut to the centres inside the other's box grown by `alert`, so a pair of stones
/// costs the products of the centres near their meeting place only.
fn centre_pairs(
    pos12: &Isometry3<f64>,
    a: &[Point3<f64>],
    b: &[Point3<f64>],
    alert: f64,
    out: &mut Vec<LocalContact>,
) {
    let identity = Isometry3::identity();
    let a_box = aabb_of(a, &identity).grown(alert);
    let b_near: Vec<(usize, Point3<f64>)> = b
        .iter()
        .enumerate()
        .map(|(j, p)| (j, pos12 * p))
        .filter(|(_, p)| a_box.contains(p))
        .collect();
    if b_near.is_empty() {
        return;
    }
    let b_points: Vec<Point3<f64>> = b_near.iter().map(|(_, p)| *p).collect();
    let b_box = aabb_of(&b_points, &identity).grown(alert);
    let a_near = a
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, p)| b_box.contains(p));
    for (i, ca) in a_near {
        for &(j, cb) in &b_near {
            let between = cb - ca;
            let d = between.norm();
            if d <= alert {
                out.push(LocalContact {
                    on_a: ca,
                    on_b: cb,
                    normal: if d > 0.0 { between / d } else { Vector3::z() },
                    features: [
                        PackedFeatureId::vertex(i as u32).0,
                        PackedFeatureId::vertex(j as u32).0,
                    ],
                    gap: d,
                });
            }
        }
    }
}

/// The separation of `b` from the plane of face `k` of `a`, and that face's normal
/// (a's frame, from a to b).
#[inline(always)]
fn separation_from_a(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
    k: usize,
) -> (f64, Unit<Vector3<f64>>) {
    let pa = a.polyhedron();
    let face = &pa.faces()[k];
    let n = face.normal;
    let on_face =
        pa.points()[pa.vertices_adj_to_face()[face.first_vertex_or_edge as usize] as usize];
    let support = pos12 * b.local_support_point(&pos12.inverse_transform_vector(&-*n));
    (n.dot(&(support - on_face)), n)
}

/// The separation of `a` from the plane of face `k` of `b`, and that face's outward
/// normal (a's frame, from b to a).
#[inline(always)]
fn separation_from_b(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
    k: usize,
) -> (f64, Unit<Vector3<f64>>) {
    let pb = b.polyhedron();
    let face = &pb.faces()[k];
    let n = pos12 * face.normal;
    let on_face =
        pos12 * pb.points()[pb.vertices_adj_to_face()[face.first_vertex_or_edge as usize] as usize];
    let support = a.local_support_point(&-*n);
    (n.dot(&(support - on_face)), n)
}

/// The separation along two face normals: the face of `a` whose normal points most
/// towards `b`'s origin, and the face of `b` whose normal points most towards `a`'s
/// (the same functions as [`face_separations`], so the same bits). A lower bound of what
/// that finds.
fn quick_separation(pos12: &Isometry3<f64>, a: &ConvexShape, b: &ConvexShape) -> f64 {
    // The index of the face whose normal has the largest component along `d`.
    fn facing(p: &parry3d_f64::shape::ConvexPolyhedron, d: &Vector3<f64>) -> Option<usize> {
        (0..p.faces().len()).max_by(|&x, &y| {
            let (nx, ny) = (p.faces()[x].normal, p.faces()[y].normal);
            nx.dot(d).total_cmp(&ny.dot(d))
        })
    }
    let towards_b = pos12.translation.vector;
    let towards_a = pos12.inverse_transform_vector(&-towards_b);
    let from_a = facing(a.polyhedron(), &towards_b).map(|k| separation_from_a(pos12, a, b, k).0);
    let from_b = facing(b.polyhedron(), &towards_a).map(|k| separation_from_b(pos12, a, b, k).0);
    from_a
        .unwrap_or(f64::NEG_INFINITY)
        .max(from_b.unwrap_or(f64::NEG_INFINITY))
}

/// The largest separation of `b` from a face plane of `a`, and of `a` from a face plane
/// of `b`, with the corresponding normals from a to b (a's frame).
fn face_separations(
    pos12: &Isometry3<f64>,
    a: &ConvexShape,
    b: &ConvexShape,
) -> [FaceSeparation; 2] {
    let mut best = FaceSeparation {
        separation: f64::NEG_INFINITY,
        normal: Vector3::z_axis(),
        on_a: true,
        face: 0,
    };
    for k in 0..a.polyhedron().faces().len() {
        let (separation, normal) = separation_from_a(pos12, a, b, k);
        if separation > best.separation {
            best = FaceSeparation {
                separation,
                normal,
                on_a: true,
                face: k,
            };
        }
    }
    let mut best_b = FaceSeparation {
        separation: f64::NEG_INFINITY,
        normal: Vector3::z_axis(),
        on_a: false,
        face: 0,
    };
    for k in 0..b.polyhedron().faces().len() {
        let (separation, n) = separation_from_b(pos12, a, b, k);
        if separation > best_b.separation {
            best_b = FaceSeparation {
                separation,
                normal: -n,
                on_a: false,
                face: k,
            };
        }
    }
    [best, best_b]
}

type Side<'a> = (usize, &'a Collider, &'a Isometry3<f64>);

/// Appends the contact points of one pair. A half-space is always the first body of
/// its contacts (its normal is the contact normal).
fn pair_contacts(first: Side, second: Side, alert: f64, out: &mut Vec<ContactPoint>) {
    // A half-space is always first, and a hull before spheres (its nearest point is a).
    let (a, b) = match (first.1, second.1) {
        (Collider::HalfSpace(_), Collider::HalfSpace(_)) => return,
        (_, Collider::HalfSpace(_)) | (Collider::Spheres(_), Collider::Convex(_)) => {
            (second, first)
        }
        _ => (first, second),
    };
    let pos12 = a.2.inverse() * b.2;
    // Rounded shapes and spheres: the contacts of the hulls (or centres) within the
    // alert distance plus the roundings, each gap less them, the point midway between
    // the rounded surfaces.
    let (round_a, round_b) = (a.1.round(), b.1.round());
    let rounded = round_a + round_b > 0.0;
    let hull_alert = alert + round_a + round_b;
    let mut local = Vec::new();
    let size_b = b.1.hull().map_or(0.0, ConvexShape::bounding_radius);
    let size = size_b.max(a.1.hull().map_or(0.0, ConvexShape::bounding_radius));
    match (a.1, b.1) {
        (Collider::Convex(shape_a), Collider::Convex(shape_b)) => {
            convex_convex_contacts(&pos12, shape_a, shape_b, hull_alert, size, &mut local);
            if rounded {
                closest_hull_points(&pos12, shape_a, shape_b, hull_alert, size, &mut local);
            }
        }
        (Collider::HalfSpace(normal), Collider::Convex(shape_b)) => {
            halfspace_contacts(&pos12, normal, shape_b.points(), hull_alert, &mut local);
        }
        (Collider::HalfSpace(normal), Collider::Spheres(b)) => {
            halfspace_contacts(&pos12, normal, &b.centres, hull_alert, &mut local);
        }
        (Collider::Convex(shape_a), Collider::Spheres(b)) => {
            hull_point_contacts(&pos12, shape_a, &b.centres, hull_alert, &mut local);
        }
        (Collider::Spheres(a), Collider::Spheres(b)) => {
            centre_pairs(&pos12, &a.centres, &b.centres, hull_alert, &mut local);
        }
        _ => unreachable!("ordered above"),
    }
    let merge = 1e-6 * size;
    let start = out.len();
    for p in &local {
        // A point of hulls apart is, on rounded shapes, two spheres of the roundings
        // centred on the hulls' points: their distance, along the line between them.
        // (Along the reference normal, a point beside the closest features, an edge
        // crossing a few mm aside, say, would claim an overlap of hulls a few mm apart.)
        let between = p.on_b - p.on_a;
        let (normal, hull_gap) = match between.norm() {
            d if rounded && p.gap > 0.0 && d > 0.0 => (between / d, d),
            _ => (p.normal, p.gap),
        };
        let gap = hull_gap - round_a - round_b;
        if gap > alert {
            continue;
        }
        let on_a = p.on_a.coords + normal * round_a;
        let on_b = p.on_b.coords - normal * round_b;
        let point = a.2 * Point3::from(0.5 * (on_a + on_b));
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
                feature_a: p.features[0],
                feature_b: p.features[1],
            },
            point,
            normal: a.2.rotation * normal,
            gap,
            shift_b: Vector3::zeros(),
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

    /// The contacts of `block` with its centre at `height` over the floor z = 0 (alert
    /// distance 1 mm; the floor is body 0).
    fn on_floor(block: &Collider, height: f64) -> Vec<ContactPoint> {
        let floor = Collider::HalfSpace(Vector3::z_axis());
        let poses = [
            Isometry3::identity(),
            Isometry3::translation(0.0, 0.0, height),
        ];
        detect(&[&floor, block], &poses, &[false, true], 1e-3)
    }

    #[test]
    fn a_cube_on_a_plane_has_four_corner_contacts() {
        let block = cube(0.5);
        let contacts = on_floor(&block, 0.5 + 1e-4);
        assert_eq!(contacts.len(), 4);
        for c in &contacts {
            assert_eq!((c.key.body_a, c.key.body_b), (0, 1));
            assert!((c.gap - 1e-4).abs() < 1e-12, "{}", c.gap);
            assert!((c.normal - Vector3::z()).norm() < 1e-12);
            assert!((c.point.x.abs() - 0.5).abs() < 1e-12 && (c.point.y.abs() - 0.5).abs() < 1e-12);
        }
        // Beyond the alert distance: nothing.
        assert!(on_floor(&block, 0.502).is_empty());
    }

    /// A unit cube standing on its edge along x (rotated 45° about x), and above it one
    /// standing on its edge along y (45° about y), its centre at `(dx, 0, 2 h + gap)`
    /// with h = √2/2: the two edges cross at 90° at `(dx, 0, h)`.
    fn crossed_edges(dx: f64, gap: f64) -> Vec<ContactPoint> {
        let lower = cube(0.5);
        let upper = cube(0.5);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let quarter = std::f64::consts::FRAC_PI_4;
        let poses = [
            Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), quarter),
            ),
            Isometry3::from_parts(
                Translation3::new(dx, 0.0, 2.0 * h + gap),
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), quarter),
            ),
        ];
        detect(&[&lower, &upper], &poses, &[true, true], 1e-2)
    }

    #[test]
    fn crossed_edges_touch_at_one_point_along_their_common_normal() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        for (dx, gap) in [(0.0, 1e-4), (0.2, 1e-4), (0.2, -2e-3), (-0.3, 0.0)] {
            let contacts = crossed_edges(dx, gap);
            assert_eq!(contacts.len(), 1, "dx {dx}, gap {gap}: {contacts:?}");
            let c = &contacts[0];
            assert!((c.gap - gap).abs() < 1e-12, "{c:?}");
            assert!((c.normal - Vector3::z()).norm() < 1e-12, "{c:?}");
            let expect = Point3::new(dx, 0.0, h + 0.5 * gap);
            assert!((c.point - expect).norm() < 1e-12, "{c:?}");
            // Both features are edges (a persistent key while the edges cross).
            assert_eq!(c.key.feature_a >> 30, 2, "{:x}", c.key.feature_a);
            assert_eq!(c.key.feature_b >> 30, 2, "{:x}", c.key.feature_b);
        }
        // The edges pass each other (the upper one beyond the lower edge's end): no
        // crossing, and the cubes are 0.1 apart: nothing within the alert distance.
        assert!(crossed_edges(1.1, 0.0).is_empty());
    }

    #[test]
    fn an_edge_across_a_roof_ridge_touches_the_ridge_line() {
        // A cube standing on its edge along y, lying across a roof (a 1 × 0.3 box with
        // a ridge line along x at y = 0, 0.05 above its eaves): the upper edge crosses
        // the ridge edge, a tumbling stone across another's ridge. The ridge crossing
        // is an edge–edge point with normal +z at the gap; the roof faces see the edge
        // at their true distances (the edge rises away from them).
        let mut points = Vec::new();
        for k in 0..8 {
            points.push(Point3::new(
                if k & 1 == 0 { -0.5 } else { 0.5 },
                if k & 2 == 0 { -0.15 } else { 0.15 },
                if k & 4 == 0 { -0.5 } else { 0.0 },
            ));
        }
        points.push(Point3::new(-0.5, 0.0, 0.05));
        points.push(Point3::new(0.5, 0.0, 0.05));
        let roof = Collider::Convex(ConvexShape::from_points(&points).unwrap());
        let upper = cube(0.5);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        for gap in [1e-4, -1e-4] {
            let poses = [
                Isometry3::identity(),
                Isometry3::from_parts(
                    Translation3::new(0.1, 0.0, 0.05 + h + gap),
                    UnitQuaternion::from_axis_angle(
                        &Vector3::y_axis(),
                        std::f64::consts::FRAC_PI_4,
                    ),
                ),
            ];
            let contacts = detect(&[&roof, &upper], &poses, &[true, true], 1e-2);
            let ridge: Vec<_> = contacts
                .iter()
                .filter(|c| c.key.feature_a >> 30 == 2 && c.key.feature_b >> 30 == 2)
                .collect();
            assert_eq!(ridge.len(), 1, "{contacts:?}");
            assert!((ridge[0].gap - gap).abs() < 1e-12, "{contacts:?}");
            assert!((ridge[0].normal - Vector3::z()).norm() < 1e-12);
            assert!((ridge[0].point - Point3::new(0.1, 0.0, 0.05 + 0.5 * gap)).norm() < 1e-12);
            // (Overlapping, the edge's point just past the ridge is as deep below the
            // roof face: 1e-4 / cos(18.4°).)
            let least = if gap > 0.0 { gap } else { 1.06 * gap };
            assert!(
                contacts.iter().all(|c| c.gap >= least - 1e-12),
                "{contacts:?}"
            );
        }
    }

    /// Random unit vectors, uniform on the sphere, from a seeded xorshift generator (the
    /// same sequence on every machine).
    fn unit_vectors(mut seed: u64) -> impl FnMut() -> Vector3<f64> {
        let mut random = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        move || {
            let (z, phi): (f64, f64) = (2.0 * random() - 1.0, std::f64::consts::TAU * random());
            let r = (1.0 - z * z).sqrt();
            Vector3::new(r * phi.cos(), r * phi.sin(), z)
        }
    }

    /// Two random hulls (`count` points each on the ellipsoid of semi-axes `axes`),
    /// their random orientations and a random direction, drawn in that order.
    fn random_pair(
        unit: &mut dyn FnMut() -> Vector3<f64>,
        count: usize,
        axes: Vector3<f64>,
    ) -> (
        ConvexShape,
        ConvexShape,
        [UnitQuaternion<f64>; 2],
        Vector3<f64>,
    ) {
        let mut hull = || {
            let points: Vec<Point3<f64>> = (0..count)
                .map(|_| Point3::from(unit().component_mul(&axes)))
                .collect();
            ConvexShape::from_points(&points).unwrap()
        };
        let (a, b) = (hull(), hull());
        let ra = UnitQuaternion::from_scaled_axis(unit() * 3.0);
        let rb = UnitQuaternion::from_scaled_axis(unit() * 3.0);
        (a, b, [ra, rb], unit())
    }

    /// A random pair of stone-like hulls (20 points on an ellipsoid, [`random_pair`]),
    /// the second moved along a random direction (by at most `reach`, bisection) until
    /// GJK/EPA (parry) gives the signed distance `target`: the two shapes, their poses
    /// and the signed distance reached (`None` if parry gives none).
    fn pair_at_distance(
        unit: &mut dyn FnMut() -> Vector3<f64>,
        target: f64,
        reach: f64,
    ) -> Option<(ConvexShape, ConvexShape, [Isometry3<f64>; 2], f64)> {
        hulls_at_distance(unit, 20, Vector3::new(0.03, 0.02, 0.015), target, reach)
    }

    /// [`pair_at_distance`] for hulls of `count` points on the ellipsoid of semi-axes
    /// `axes`.
    fn hulls_at_distance(
        unit: &mut dyn FnMut() -> Vector3<f64>,
        count: usize,
        axes: Vector3<f64>,
        target: f64,
        reach: f64,
    ) -> Option<(ConvexShape, ConvexShape, [Isometry3<f64>; 2], f64)> {
        use parry3d_f64::query::details::contact_support_map_support_map;
        let (a, b, [ra, rb], direction) = random_pair(unit, count, axes);
        let signed = |t: f64| {
            let pos12 = Isometry3::from_parts(Translation3::identity(), ra).inverse()
                * Isometry3::from_parts(Translation3::from(direction * t), rb);
            contact_support_map_support_map(&pos12, &a, &b, 1.0).map(|c| c.dist)
        };
        // Bisection on the offset for the target signed distance.
        let (mut lo, mut hi) = (0.0, reach);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            match signed(mid) {
                Some(d) if d < target => lo = mid,
                _ => hi = mid,
            }
        }
        let d = signed(hi)?;
        let poses = [
            Isometry3::from_parts(Translation3::identity(), ra),
            Isometry3::from_parts(Translation3::from(direction * hi), rb),
        ];
        Some((a, b, poses, d))
    }

    #[test]
    fn random_hulls_report_their_closest_or_deepest_point() {
        // Random stone-like hulls (20 points on an ellipsoid) at random orientations,
        // moved along a random direction until GJK/EPA (parry) gives a signed distance
        // d: the detected points must include one at least as close as d (a contact is
        // never missed, nor reported farther than it is), and when the hulls are apart
        // no point may claim an overlap. parry's own manifold clipped the support
        // features along GJK's normal and could report only points gaps above d.
        let mut unit = unit_vectors(0x2545_f491_4f6c_dd1du64);
        let mut checked = 0;
        for _ in 0..200 {
            let target = [-1e-3, -1e-5, 1e-5, 1e-3][checked % 4];
            let Some((a, b, poses, d)) = pair_at_distance(&mut unit, target, 0.1) else {
                continue;
            };
            let (ca, cb) = (Collider::Convex(a), Collider::Convex(b));
            let contacts = detect(&[&ca, &cb], &poses, &[true, true], 2e-3);
            let least = contacts.iter().map(|c| c.gap).fold(f64::INFINITY, f64::min);
            assert!(least <= d + 1e-9, "d {d}, least gap {least}: {contacts:?}");
            if d > 0.0 {
                assert!(least >= -1e-9, "apart by {d}, reported {least}");
            } else {
                // No point deeper than the pair's penetration depth.
                assert!(least >= d - 1e-9, "depth {d}, reported {least}");
            }
            checked += 1;
        }
        assert!(checked > 150, "{checked}");
    }

    #[test]
    fn sharp_hulls_report_their_penetration_depth() {
        // Hulls of few points on a flat ellipsoid have sharp corners: an edge crossing
        // that is the pair's overlap (its axis is EPA's) may have a point just outside a
        // third face of the other body, next to its edge's end. Such a pair was reported
        // apart (a quick bed's stones sank 1.4 mm into each other unseen). Each pair
        // pushed together to a depth d (parry's EPA) must report a point at d.
        let mut unit = unit_vectors(0x6a09_e667_f3bc_c909u64);
        let mut checked = 0;
        for k in 0..600 {
            let target = [-2e-3, -1.2e-3, -5e-4][k % 3];
            let Some((a, b, poses, d)) =
                hulls_at_distance(&mut unit, 10, Vector3::new(0.03, 0.02, 0.008), target, 0.1)
            else {
                continue;
            };
            if (d - target).abs() > 1e-6 {
                continue; // the bisection did not reach the depth
            }
            let (ca, cb) = (Collider::Convex(a), Collider::Convex(b));
            let contacts = detect(&[&ca, &cb], &poses, &[true, true], 2e-3);
            let least = contacts.iter().map(|c| c.gap).fold(f64::INFINITY, f64::min);
            assert!(
                (least - d).abs() <= 1e-9,
                "pair {k}: depth {d}, deepest point {least}: {contacts:?}"
            );
            checked += 1;
        }
        assert!(checked > 500, "{checked}");
    }

    #[test]
    fn random_rounded_hulls_report_their_closest_point() {
        // The hulls of the test above rounded by 6 mm, moved apart until their hulls
        // are d apart (parry), d between 0 and 2r + the alert distance: the rounded
        // shapes are d − 2r apart, and the detected points must include one at least
        // that close.
        let r = 6e-3;
        let mut unit = unit_vectors(0x9e37_79b9_7f4a_7c15u64);
        let mut checked = 0;
        for k in 0..200 {
            let target = [1e-4, 3e-3, 6e-3, 1.19e-2, 1.3e-2][k % 5];
            let Some((a, b, poses, d)) = pair_at_distance(&mut unit, target, 0.2) else {
                continue;
            };
            let (ca, cb) = (
                Collider::Convex(a.rounded(r)),
                Collider::Convex(b.rounded(r)),
            );
            let contacts = detect(&[&ca, &cb], &poses, &[true, true], 2e-3);
            let least = contacts.iter().map(|c| c.gap).fold(f64::INFINITY, f64::min);
            assert!(
                least <= d - 2.0 * r + 1e-9,
                "hulls {d} apart, least gap {least}: {contacts:?}"
            );
            // Nor closer than the rounded shapes are: a point's gap is the distance of
            // two spheres inside them.
            assert!(
                least >= d - 2.0 * r - 1e-9,
                "hulls {d} apart, a point claims {least}: {contacts:?}"
            );
            checked += 1;
        }
        assert!(checked > 150, "{checked}");
    }

    #[test]
    fn hulls_beyond_the_alert_distance_have_no_points() {
        // Angular random hulls (10 points on a 2 cm sphere) at random orientations and
        // 2.5 to 8 mm apart (GJK), alert 2 mm: no point at all. The edge test skips the
        // edges beyond the other hull's bounding sphere, and for about 1 % of these
        // pairs every axis that separates them by more than the alert distance comes
        // from such edges: without the GJK check 35 of 3 000 pairs had points (the
        // table3 bed's phantoms; in a scan of flatter hulls one claimed 1.8 mm of
        // overlap between hulls 5.5 mm apart).
        use parry3d_f64::query::details::distance_support_map_support_map;
        let mut unit = unit_vectors(0x9e37_79b9_7f4a_7c15u64);
        let alert = 2e-3;
        for trial in 0..3000 {
            let (a, b, [ra, rb], direction) = random_pair(&mut unit, 10, Vector3::repeat(0.02));
            let target = 2.5e-3 + 5.5e-3 * (trial % 8) as f64 / 7.0;
            let pose_b = |t: f64| Isometry3::from_parts(Translation3::from(direction * t), rb);
            let pose_a = Isometry3::from_parts(Translation3::identity(), ra);
            let distance =
                |t: f64| distance_support_map_support_map(&(pose_a.inverse() * pose_b(t)), &a, &b);
            let (mut lo, mut hi) = (0.0, 0.3);
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                if distance(mid) < target {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let d = distance(hi);
            assert!(d > alert, "{d}");
            let (ca, cb) = (Collider::Convex(a), Collider::Convex(b));
            let contacts = detect(&[&ca, &cb], &[pose_a, pose_b(hi)], &[true, true], alert);
            assert!(
                contacts.is_empty(),
                "trial {trial}: apart by {d}, reported {contacts:?}"
            );
        }
    }

    #[test]
    fn corner_to_corner_cubes_are_not_reported_as_overlapping() {
        // Two axis-aligned unit cubes offset diagonally by 1 + d in x and y: every face
        // normal separates them by d, their closest features are two parallel edges.
        // The pair is kept (one point at gap d), and no point is below a face plane.
        let d = 1e-3;
        let lower = cube(0.5);
        let upper = cube(0.5);
        let poses = [
            Isometry3::identity(),
            Isometry3::translation(1.0 + d, 1.0 + d, 0.3),
        ];
        let contacts = detect(&[&lower, &upper], &poses, &[true, true], 1e-2);
        assert!(!contacts.is_empty());
        assert!(
            contacts.iter().all(|c| (c.gap - d).abs() < 1e-12),
            "{contacts:?}"
        );
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

    fn rounded_cube(half: f64, round: f64) -> Collider {
        let Collider::Convex(shape) = cube(half) else {
            unreachable!()
        };
        Collider::Convex(shape.rounded(round))
    }

    #[test]
    fn rounded_cubes_touch_at_their_rounded_faces() {
        // Two unit cubes rounded by 5 mm: their rounded faces meet when the hulls are
        // 10 mm apart. Hulls 10.3 mm apart along z: four points, gap 0.3 mm, on the
        // plane midway between the rounded faces (z = 0.5 + 5 mm + 0.15 mm), found by
        // the broad phase although the hulls' boxes are 10 mm apart, beyond the 1 mm
        // alert distance.
        let r = 5e-3;
        let (lower, upper) = (rounded_cube(0.5, r), rounded_cube(0.5, r));
        let at = |z: f64| {
            [
                Isometry3::identity(),
                Isometry3::translation(0.1, 0.05, 1.0 + z),
            ]
        };
        let near = detect(&[&lower, &upper], &at(2.0 * r + 3e-4), &[true, true], 1e-3);
        assert_eq!(near.len(), 4, "{near:?}");
        for c in &near {
            assert!((c.gap - 3e-4).abs() < 1e-12, "gap {}", c.gap);
            assert!((c.normal - Vector3::z()).norm() < 1e-12);
            assert!(
                (c.point.z - (0.5 + r + 1.5e-4)).abs() < 1e-12,
                "{}",
                c.point
            );
        }
        // Overlapping rounded faces (hulls 9 mm apart): a gap of −1 mm.
        let deep = detect(&[&lower, &upper], &at(2.0 * r - 1e-3), &[true, true], 1e-3);
        assert_eq!(deep.len(), 4);
        assert!(deep.iter().all(|c| (c.gap + 1e-3).abs() < 1e-12));
        let none_at = |a: &Collider, b: &Collider, distance: f64| {
            detect(&[a, b], &at(distance), &[true, true], 1e-3).is_empty()
        };
        // Beyond the alert distance from the rounded faces: nothing.
        assert!(none_at(&lower, &upper, 2.0 * r + 1.5e-3));
        // The bare cubes at 10.3 mm: nothing either.
        assert!(none_at(&cube(0.5), &cube(0.5), 2.0 * r + 3e-4));
    }

    #[test]
    fn a_rounded_cube_rests_on_a_plane_by_its_rounding() {
        let r = 5e-3;
        let contacts = on_floor(&rounded_cube(0.5, r), 0.5 + r + 1e-4);
        assert_eq!(contacts.len(), 4);
        for c in &contacts {
            assert!((c.gap - 1e-4).abs() < 1e-12, "{}", c.gap);
            // Midway between the plane and the rounded corner's lowest point.
            assert!((c.point.z - 0.5e-4).abs() < 1e-12, "{}", c.point);
        }
    }

    /// The unit cube (half 0.5) with spheres of radius `r` at its eight corners and at
    /// the centre of each face.
    fn cube_of_spheres(r: f64) -> Collider {
        let Collider::Convex(hull) = cube(0.5) else {
            unreachable!()
        };
        let mut centres: Vec<Point3<f64>> = hull.points().to_vec();
        for d in 0..3 {
            for s in [-0.5, 0.5] {
                let mut p = Point3::origin();
                p[d] = s;
                centres.push(p);
            }
        }
        Collider::Convex(hull).with_spheres(centres, r).unwrap()
    }

    #[test]
    fn sphere_clusters_touch_sphere_by_sphere_along_the_line_of_centres() {
        let r = 0.012;
        let (lower, upper) = (cube_of_spheres(r), cube_of_spheres(r));
        // Stacked face to face, the spheres 0.1 mm apart: five pairs (the four
        // corners and the face centres, each against its twin; every other pair is
        // 0.5 m or more apart), each a gap of 0.1 mm, normal +z, midway.
        let gap = 1e-4;
        let poses = [
            Isometry3::identity(),
            Isometry3::translation(0.0, 0.0, 1.0 + 2.0 * r + gap),
        ];
        let contacts = detect(&[&lower, &upper], &poses, &[true, true], 1e-3);
        assert_eq!(contacts.len(), 5, "{contacts:?}");
        for c in &contacts {
            assert!((c.gap - gap).abs() < 1e-12, "{}", c.gap);
            assert!((c.normal - Vector3::z()).norm() < 1e-12);
            assert!((c.point.z - (0.5 + r + 0.5 * gap)).abs() < 1e-12);
        }
        // Overlapping by 1 mm, shifted sideways by 3 mm: the corner pairs are 3 mm
        // apart sideways, so the normal tilts and the gap is the centres' distance
        // less 2r.
        let dz = 1.0 + 2.0 * r - 1e-3;
        let poses = [Isometry3::identity(), Isometry3::translation(3e-3, 0.0, dz)];
        let contacts = detect(&[&lower, &upper], &poses, &[true, true], 1e-3);
        assert_eq!(contacts.len(), 5);
        let expected = (dz - 1.0).hypot(3e-3) - 2.0 * r;
        for c in &contacts {
            assert!(
                (c.gap - expected).abs() < 1e-12,
                "{} against {expected}",
                c.gap
            );
        }
        // Beyond the alert distance: nothing.
        let far = [
            Isometry3::identity(),
            Isometry3::translation(0.0, 0.0, 1.0 + 2.0 * r + 1.5e-3),
        ];
        assert!(detect(&[&lower, &upper], &far, &[true, true], 1e-3).is_empty());
    }

    #[test]
    fn a_sphere_cluster_rests_on_a_plane_and_on_a_hull_by_its_spheres() {
        let r = 0.012;
        let block = cube_of_spheres(r);
        // On the floor 0.1 mm clear: the four lower corners and the bottom face's
        // centre, each gap 0.1 mm, midway between plane and sphere.
        let contacts = on_floor(&block, 0.5 + r + 1e-4);
        assert_eq!(contacts.len(), 5);
        for c in &contacts {
            assert_eq!((c.key.body_a, c.key.body_b), (0, 1));
            assert!((c.gap - 1e-4).abs() < 1e-12, "{}", c.gap);
            assert!((c.point.z - 0.5e-4).abs() < 1e-12, "{}", c.point);
        }
        // On a bare cube (the hull first, whichever the body order): 0.1 mm clear of
        // its top face, and sunk with the lower sphere centres 10 mm under the face,
        // which is then their nearest feature: a gap of −(10 mm + r).
        let hull = cube(1.0);
        for (height, gap) in [(1.5 + r + 1e-4, 1e-4), (1.5 - 0.01, -0.01 - r)] {
            let poses = [
                Isometry3::translation(0.0, 0.0, height),
                Isometry3::identity(),
            ];
            let contacts = detect(&[&block, &hull], &poses, &[true, true], 1e-3);
            assert_eq!(contacts.len(), 5, "at {height}: {contacts:?}");
            for c in &contacts {
                assert_eq!((c.key.body_a, c.key.body_b), (1, 0), "hull first");
                assert!((c.gap - gap).abs() < 1e-12, "{} against {gap}", c.gap);
                assert!((c.normal - Vector3::z()).norm() < 1e-12);
            }
        }
        // Beside the hull's edge, a corner sphere's nearest point is the edge: the
        // gap is the distance to it less r, along the line from the edge.
        let hull = cube(0.5);
        let poses = [
            Isometry3::identity(),
            Isometry3::translation(1.0 + 0.01, 0.0, 1.0 + 0.01),
        ];
        let contacts = detect(&[&hull, &block], &poses, &[true, true], 0.01);
        // Two corner spheres (y = ±0.5) face the hull's edge along y.
        let expected = 0.01f64.hypot(0.01) - r;
        assert_eq!(contacts.len(), 2, "{contacts:?}");
        for c in &contacts {
            assert!((c.gap - expected).abs() < 1e-9, "{}", c.gap);
            let diagonal = Vector3::new(1.0, 0.0, 1.0).normalize();
            assert!((c.normal - diagonal).norm() < 1e-9, "{}", c.normal);
        }
    }
}
