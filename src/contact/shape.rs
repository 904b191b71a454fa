//! Collision shapes of NSCD bodies: convex polyhedra (parry's `ConvexPolyhedron` behind a
//! support-face rule that keeps whole faces), clusters of equal spheres (the contact
//! shape of seed 004's QDEM bodies) and half-spaces (planes).

use std::sync::Arc;

use nalgebra::{Point3, Unit, Vector3};
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::{
    ConvexPolyhedron, PackedFeatureId, PolygonalFeature, PolygonalFeatureMap, SupportMap,
};

/// A convex polyhedron for contact detection.
///
/// parry's polygonal support feature holds at most four vertices and takes the first four
/// of a larger face, which on a cut stone can be a sliver at one corner. Here a face with
/// more vertices is represented by four vertices spread evenly around it (indices
/// 0, n/4, n/2, 3n/4 of its loop), so the contact polygon spans the face.
#[derive(Debug, Clone)]
pub struct ConvexShape {
    polyhedron: ConvexPolyhedron,
    /// Edges and face planes (boxed: keeps [`Collider`]'s variants close in size).
    derived: Box<Derived>,
    radius: f64,
    /// The rounding: the shape is the hull swept by a sphere of this radius (m; 0 for
    /// the bare hull).
    round: f64,
}

#[derive(Debug, Clone)]
struct Derived {
    edges: Vec<HullEdge>,
    /// Face planes: outward normal and offset (n·x ≤ offset inside).
    planes: Vec<(Vector3<f64>, f64)>,
}

/// An edge of the hull between two of its (merged, polygonal) faces, for the
/// edge–edge axes of the separating-axis test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HullEdge {
    /// parry's edge id (its feature code is `PackedFeatureId::edge(id)`).
    pub id: u32,
    /// The two end points (local).
    pub ends: [Point3<f64>; 2],
    /// The outward normals of the two faces that meet at the edge.
    pub normals: [Vector3<f64>; 2],
}

impl ConvexShape {
    /// The convex hull of `points` (local coordinates); `None` if degenerate.
    pub fn from_points(points: &[Point3<f64>]) -> Option<Self> {
        let polyhedron = ConvexPolyhedron::from_convex_hull(points)?;
        let faces = polyhedron.faces();
        let vertices = polyhedron.points();
        // parry keeps the triangulation's interior edges of merged coplanar faces (both
        // sides on one face): only the edges between two distinct faces are hull edges.
        let edges = polyhedron
            .edges()
            .iter()
            .enumerate()
            .filter_map(|(id, e)| {
                let (f0, f1) = (e.faces[0] as usize, e.faces[1] as usize);
                if f0 == f1 || f0 >= faces.len() || f1 >= faces.len() {
                    return None;
                }
                let (n0, n1) = (*faces[f0].normal, *faces[f1].normal);
                (n0.cross(&n1).norm() > 1e-9).then(|| HullEdge {
                    id: id as u32,
                    ends: [
                        vertices[e.vertices[0] as usize],
                        vertices[e.vertices[1] as usize],
                    ],
                    normals: [n0, n1],
                })
            })
            .collect();
        let radius = vertices.iter().map(|p| p.coords.norm()).fold(0.0, f64::max);
        let planes = faces
            .iter()
            .map(|f| {
                let on = vertices
                    [polyhedron.vertices_adj_to_face()[f.first_vertex_or_edge as usize] as usize];
                (*f.normal, f.normal.dot(&on.coords))
            })
            .collect();
        Some(ConvexShape {
            polyhedron,
            derived: Box::new(Derived { edges, planes }),
            radius,
            round: 0.0,
        })
    }

    /// The hull swept by a sphere of radius `round` (m): every point within `round` of
    /// it (a sphero-polyhedron). Contacts are those of the hulls with the gap less
    /// `round` on each side ([`super::narrow`]).
    pub fn rounded(mut self, round: f64) -> Self {
        self.round = round;
        self
    }

    /// The rounding radius (m; 0 for the bare hull).
    pub fn round(&self) -> f64 {
        self.round
    }

    /// Whether `p` (local) is inside the hull or within `tolerance` of it (every face
    /// plane).
    pub fn contains(&self, p: &Point3<f64>, tolerance: f64) -> bool {
        self.derived
            .planes
            .iter()
            .all(|(n, offset)| n.dot(&p.coords) <= offset + tolerance)
    }

    /// The hull's edges between distinct faces.
    pub fn edges(&self) -> &[HullEdge] {
        &self.derived.edges
    }

    /// The underlying parry polyhedron.
    pub fn polyhedron(&self) -> &ConvexPolyhedron {
        &self.polyhedron
    }

    /// The hull's vertices (local coordinates).
    pub fn points(&self) -> &[Point3<f64>] {
        self.polyhedron.points()
    }

    /// The radius of the smallest origin-centred sphere holding the hull (without the
    /// rounding).
    pub fn bounding_radius(&self) -> f64 {
        self.radius
    }

    /// The hull's point nearest to `p` (local), the unit normal from the hull towards
    /// `p`, and the signed distance (negative inside). Inside, the nearest point lies on
    /// the nearest face plane (exact for a convex hull); outside, parry's projection.
    pub fn nearest_point(&self, p: &Point3<f64>) -> (Point3<f64>, Vector3<f64>, f64) {
        let (mut depth, mut normal) = (f64::NEG_INFINITY, Vector3::z());
        for (n, offset) in &self.derived.planes {
            let s = n.dot(&p.coords) - offset;
            if s > depth {
                (depth, normal) = (s, *n);
            }
        }
        if depth <= 0.0 {
            return (p - normal * depth, normal, depth);
        }
        let q = self.polyhedron.project_local_point(p, true).point;
        let d = (p - q).norm();
        match d {
            d if d > 0.0 => (q, (p - q) / d, d),
            _ => (q, normal, 0.0),
        }
    }
}

/// Equal spheres centred at given points of a body: its contact shape where seed 004's
/// QDEM puts a sphere at every surface vertex (§4), so that a bed packed with it
/// meets the QDEM model's spheres at rest. The hull of the vertices is kept for what
/// is not contact (volumes in control boxes, pictures).
#[derive(Debug, Clone)]
pub struct SphereCluster {
    /// The convex hull of the body (local).
    pub hull: ConvexShape,
    /// The sphere centres (local).
    pub centres: Arc<[Point3<f64>]>,
    /// The spheres' radius (m).
    pub radius: f64,
}

impl SupportMap for ConvexShape {
    #[inline]
    fn local_support_point(&self, dir: &Vector3<f64>) -> Point3<f64> {
        self.polyhedron.local_support_point(dir)
    }
}

impl PolygonalFeatureMap for ConvexShape {
    fn local_support_feature(&self, dir: &Unit<Vector3<f64>>, out_feature: &mut PolygonalFeature) {
        let faces = self.polyhedron.faces();
        let mut best = 0;
        let mut best_dot = faces[0].normal.dot(dir);
        for (index, face) in faces.iter().enumerate().skip(1) {
            let dot = face.normal.dot(dir);
            if dot > best_dot {
                best = index;
                best_dot = dot;
            }
        }
        let face = &faces[best];
        let first = face.first_vertex_or_edge as usize;
        let count = face.num_vertices_or_edges as usize;
        let vertices = &self.polyhedron.vertices_adj_to_face()[first..first + count];
        let edges = &self.polyhedron.edges_adj_to_face()[first..first + count];
        let taken = count.min(4);
        let points = self.polyhedron.points();
        for slot in 0..taken {
            let k = slot * count / taken;
            out_feature.vertices[slot] = points[vertices[k] as usize];
            out_feature.vids[slot] = PackedFeatureId::vertex(vertices[k]);
            // A chord of a larger face keeps the id of the edge it starts on: stable from
            // step to step, which is all the ids are used for.
            out_feature.eids[slot] = PackedFeatureId::edge(edges[k]);
        }
        out_feature.fid = PackedFeatureId::face(best as u32);
        out_feature.num_vertices = taken;
    }

    fn is_convex_polyhedron(&self) -> bool {
        true
    }
}

/// What a body collides with.
#[derive(Debug, Clone)]
pub enum Collider {
    /// A convex polyhedron in the body's frame.
    Convex(ConvexShape),
    /// The half-space `{x : n·x ≤ 0}` in the body's frame (its boundary plane passes
    /// through the body's origin, `n` is the outward normal).
    HalfSpace(Unit<Vector3<f64>>),
    /// Equal spheres at points of the body (inside or on its hull).
    Spheres(SphereCluster),
}

impl Collider {
    /// Whether the collider is bounded (a half-space is not).
    pub fn is_bounded(&self) -> bool {
        !matches!(self, Collider::HalfSpace(_))
    }

    /// How far the contact shape reaches beyond the hull's vertices: the rounding of a
    /// polyhedron (0 for a bare one), the spheres' radius, 0 for a half-space.
    pub fn round(&self) -> f64 {
        match self {
            Collider::Convex(shape) => shape.round(),
            Collider::Spheres(cluster) => cluster.radius,
            Collider::HalfSpace(_) => 0.0,
        }
    }

    /// The diameter of its spheres (m; 0 for other shapes).
    pub fn sphere_diameter(&self) -> f64 {
        match self {
            Collider::Spheres(cluster) => 2.0 * cluster.radius,
            _ => 0.0,
        }
    }

    /// The body's convex hull (none for a half-space).
    pub fn hull(&self) -> Option<&ConvexShape> {
        match self {
            Collider::Convex(shape) => Some(shape),
            Collider::Spheres(cluster) => Some(&cluster.hull),
            Collider::HalfSpace(_) => None,
        }
    }

    /// The same body with spheres of `radius` (m) centred at `centres` (local; on or
    /// inside the hull) as its contact shape; `None` for a half-space.
    pub fn with_spheres(&self, centres: Vec<Point3<f64>>, radius: f64) -> Option<Collider> {
        let hull = self.hull()?.clone().rounded(0.0);
        Some(Collider::Spheres(SphereCluster {
            hull,
            centres: centres.into(),
            radius,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_faces_keep_four_spread_vertices() {
        // An octagonal prism: the top face has eight vertices.
        let mut points = Vec::new();
        for k in 0..8 {
            let a = k as f64 * std::f64::consts::TAU / 8.0;
            points.push(Point3::new(a.cos(), a.sin(), 0.5));
            points.push(Point3::new(a.cos(), a.sin(), -0.5));
        }
        let shape = ConvexShape::from_points(&points).unwrap();
        let mut feature = PolygonalFeature::default();
        shape.local_support_feature(&Vector3::z_axis(), &mut feature);
        assert_eq!(feature.num_vertices, 4);
        // Spread: the four points span the face (their centroid is near its centre).
        let centroid: Vector3<f64> = feature
            .vertices
            .iter()
            .map(|p| p.coords)
            .sum::<Vector3<f64>>()
            / 4.0;
        assert!(centroid.xy().norm() < 1e-9, "{centroid:?}");
        assert!(feature.vertices.iter().all(|p| (p.z - 0.5).abs() < 1e-12));
    }
}
