//! The bodies of a `ballast-pack` packing file ([`Packing`]), for a `[packing]` table
//! of an NSCD scene: every stone as the convex hull of its mesh placed as the file says,
//! the sleepers (cuboids or mesh hulls) as dynamic bodies that do not yaw (held
//! square to the track by their rails, [`Body::without_yaw`]), and the container's floor and
//! side walls as half-spaces.
//!
//! A placement maps the (scaled) mesh coordinates to the world; a body's state is in
//! its principal frame, so its pose is `placement · principal frame in the mesh`, the
//! inverse of what `ballast-pack` wrote: a packing read back gives the bodies it was
//! built from, to round-off.

use std::path::Path;
use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Unit, Vector3};

use super::body::{Body, BodyShape, Motion};
use super::motion::{mesh_pieces, Pieces};
use super::scene::{read_stone_shape, StoneShape};
use crate::pack::contacts::BodyRef;
use crate::pack::Packing;
use crate::{Error, Result};

/// Material index and density (kg/m³) of a kind of body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stuff {
    /// Index into the scene's materials.
    pub material: u32,
    /// Density (kg/m³).
    pub density: f64,
}

/// What the scene makes of a packing's bodies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackedMaterials {
    /// The stones.
    pub stones: Stuff,
    /// The sleepers (dynamic); `None` leaves them out.
    pub sleepers: Option<Stuff>,
    /// Material of the floor and the side walls; `None` adds no boundary.
    pub walls: Option<u32>,
}

/// The bodies of a packing: boundaries, sleepers, stones, in that order.
#[derive(Debug, Clone)]
pub struct PackedBodies {
    /// The bodies: the walls, the sleepers, the stones.
    pub bodies: Vec<Body>,
    /// Equivalent-sphere diameters of the stones (m), in body order.
    pub stone_diameters: Vec<f64>,
    /// Where each kind of body is among them.
    pub layout: PackedLayout,
}

/// Where a packing's bodies are in a body list: from `offset`, its walls, then its
/// sleepers, then its stones.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PackedLayout {
    /// Index of the first.
    pub offset: usize,
    /// Walls (0 without a wall material).
    pub walls: usize,
    /// Sleepers (0 without a sleeper material).
    pub sleepers: usize,
    /// Stones.
    pub stones: usize,
}

impl PackedLayout {
    /// Index of a body the packing names (`None`: not built).
    pub fn index(&self, body: BodyRef) -> Option<usize> {
        let (first, count, k) = match body {
            BodyRef::Wall(k) => (0, self.walls, k),
            BodyRef::Sleeper(k) => (self.walls, self.sleepers, k),
            BodyRef::Stone(k) => (self.walls + self.sleepers, self.stones, k),
        };
        (k < count).then_some(self.offset + first + k)
    }
}

/// The floor (a half-space through `floor`, normal +z) and the walls of the box
/// `x[0]..x[1]` × `y[0]..y[1]` as fixed half-spaces of `material`, named `floor`,
/// `wall_x_min` …: four walls, or only the two across y when the bed is periodic along
/// x. ballast-pack's container and a packing's boundaries.
pub fn container_planes(
    floor: Vector3<f64>,
    x: [f64; 2],
    y: [f64; 2],
    periodic_x: bool,
    material: u32,
) -> Vec<Body> {
    let mut planes = vec![("floor", Vector3::z(), floor)];
    if !periodic_x {
        planes.extend([
            ("wall_x_min", Vector3::x(), Vector3::new(x[0], 0.0, 0.0)),
            ("wall_x_max", -Vector3::x(), Vector3::new(x[1], 0.0, 0.0)),
        ]);
    }
    planes.extend([
        ("wall_y_min", Vector3::y(), Vector3::new(0.0, y[0], 0.0)),
        ("wall_y_max", -Vector3::y(), Vector3::new(0.0, y[1], 0.0)),
    ]);
    planes
        .into_iter()
        .map(|(name, normal, point)| {
            Body::fixed(
                name,
                Arc::new(BodyShape::half_space(Unit::new_normalize(normal))),
                material,
                Isometry3::translation(point.x, point.y, point.z),
                Motion::Static,
            )
        })
        .collect()
}

/// Builds the bodies of `packing` (read from `path`, which errors name).
pub fn packed_bodies(
    path: &Path,
    packing: &Packing,
    materials: &PackedMaterials,
) -> Result<PackedBodies> {
    let mut bodies = Vec::new();
    if let Some(wall) = materials.walls {
        let (lo, hi) = (packing.container_min, packing.container_max);
        // In x unless the packing is periodic along x (the engine then needs
        // `Packing::period`).
        bodies.extend(container_planes(
            Vector3::new(lo[0], lo[1], lo[2]),
            [lo[0], hi[0]],
            [lo[1], hi[1]],
            packing.period().is_some(),
            wall,
        ));
    }
    let walls = bodies.len();
    let mesh_error =
        |i: usize, e: Error| Error::invalid(path, format!("key mesh[{i}].file: {}", one_line(&e)));
    if let Some(stuff) = materials.sleepers {
        for (k, s) in packing.sleepers.iter().enumerate() {
            let (shape, frame) = match (s.mesh, s.size) {
                (None, Some(size)) => (
                    BodyShape::cuboid(Vector3::from(size))
                        .map_err(|e| Error::invalid(path, format!("key sleeper[{k}].size: {e}")))?,
                    Isometry3::identity(),
                ),
                (Some(m), None) => {
                    let spec = &packing.meshes[m];
                    let mesh = crate::mesh::read_msh(&spec.file).map_err(|e| mesh_error(m, e))?;
                    let pieces = mesh_pieces(&mesh, &Pieces::Hull)
                        .map_err(|e| Error::invalid(path, format!("key mesh[{m}].file: {e}")))?;
                    let points: Vec<Point3<f64>> =
                        pieces[0].1.iter().map(|p| p * spec.scale).collect();
                    let mut principal =
                        BodyShape::convex_hull(&points, &spec.file.display().to_string())
                            .map_err(|e| mesh_error(m, e))?;
                    if spec.spheres_m > 0.0 {
                        let identity = Isometry3::identity();
                        principal.with_vertex_spheres(&mesh, &identity, spec.scale, spec.spheres_m);
                    }
                    (principal.shape, principal.pose)
                }
                _ => unreachable!("Packing::read checks one of mesh or size"),
            };
            bodies.push(
                Body::dynamic(
                    &format!("sleeper_{}", k + 1),
                    Arc::new(shape),
                    stuff.density,
                    stuff.material,
                    s.pose() * frame,
                )
                .without_yaw(),
            );
        }
    }
    let sleepers = bodies.len() - walls;
    let mut shapes: Vec<Option<StoneShape>> = vec![None; packing.meshes.len()];
    let mut stone_diameters = Vec::with_capacity(packing.stones.len());
    for (k, s) in packing.stones.iter().enumerate() {
        let Some(m) = s.mesh else {
            return Err(Error::invalid(
                path,
                format!("key stone[{k}]: a stone needs a mesh index, not a size"),
            ));
        };
        if shapes[m].is_none() {
            let spec = &packing.meshes[m];
            shapes[m] = Some(
                read_stone_shape(&spec.file, spec.scale)
                    .map_err(|e| mesh_error(m, e))?
                    .rounded(spec.round_m)
                    .with_vertex_spheres(spec.spheres_m),
            );
        }
        let stone = shapes[m].as_ref().expect("read above");
        stone_diameters.push(stone.diameter());
        bodies.push(stone.body(
            k,
            materials.stones.density,
            materials.stones.material,
            s.pose() * stone.mesh_pose,
        ));
    }
    let layout = PackedLayout {
        offset: 0,
        walls,
        sleepers,
        stones: bodies.len() - walls - sleepers,
    };
    Ok(PackedBodies {
        bodies,
        stone_diameters,
        layout,
    })
}

/// An error's text without the file prefix it may already carry twice (kept short).
pub(crate) fn one_line(e: &Error) -> String {
    e.to_string().lines().next().unwrap_or_default().to_string()
}
