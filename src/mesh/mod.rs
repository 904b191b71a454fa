//! Tetrahedral meshes read from gmsh MSH 4.1 files (ASCII or binary, through mshio),
//! with physical-group names, node sets, boundary triangles and quality checks.

use crate::{Error, Result};
use nalgebra::Point3;
use std::path::PathBuf;

mod msh;
mod order;
mod quality;
mod surface;

pub use msh::{read_msh, read_msh_bytes};
pub(crate) use order::{bounds, morton_key};
pub use quality::{tet_face_areas, tet_min_altitude, tet_quality, tet_signed_volume, MeshQuality};
pub use surface::{boundary_faces, tet_faces_outward, BoundaryError};

/// A named physical group of the mesh (gmsh `Physical Surface("top")` etc.).
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicalGroup {
    /// The group's name from `$PhysicalNames` (or `group_<tag>` when unnamed).
    pub name: String,
    /// Dimension of the group's entities: 0 points, 1 curves, 2 surfaces, 3 volumes.
    pub dim: u8,
    /// The physical tag.
    pub tag: i32,
    /// Sorted, deduplicated 0-based indices of every node of the group's elements.
    pub nodes: Vec<u32>,
    /// The group's triangles (0-based node indices) for a surface group.
    pub triangles: Vec<[u32; 3]>,
    /// Indices into [`TetMesh::tets`] for a volume group.
    pub tets: Vec<u32>,
}

/// A linear tetrahedral mesh: the input of the QDEM and FEM solvers and of stone bodies.
#[derive(Debug, Clone, PartialEq)]
pub struct TetMesh {
    /// The file the mesh was read from (for error messages).
    pub source: PathBuf,
    /// Node coordinates in metres; index = 0-based node id.
    pub nodes: Vec<Point3<f64>>,
    /// Tetrahedra as 0-based node indices, positively oriented (positive volume).
    pub tets: Vec<[u32; 4]>,
    /// Physical groups of every dimension.
    pub groups: Vec<PhysicalGroup>,
    /// Boundary triangles (faces owned by one tetra), outward oriented.
    pub boundary: Vec<[u32; 3]>,
}

impl TetMesh {
    /// The nodes on the boundary, ascending: where seed 004 puts its contact spheres.
    pub fn surface_nodes(&self) -> Vec<u32> {
        let mut n: Vec<u32> = self.boundary.iter().flatten().copied().collect();
        n.sort_unstable();
        n.dedup();
        n
    }

    /// Builds a checked mesh from parts made in memory (generated meshes, tests): the
    /// same checks as [`read_msh`] (index range, inverted or zero-volume tetra, dangling
    /// node, overlapping tetrahedra) with 0-based `tetra i` / `node i` in messages, which
    /// name `source`. The boundary is computed; `groups` are taken as given.
    pub fn from_parts(
        source: impl Into<PathBuf>,
        nodes: Vec<Point3<f64>>,
        tets: Vec<[u32; 4]>,
        groups: Vec<PhysicalGroup>,
    ) -> Result<Self> {
        let source = source.into();
        let invalid = |what: String| Error::invalid(&source, what);
        if tets.is_empty() {
            return Err(invalid("the mesh has no tetrahedra".into()));
        }
        for (t, tet) in tets.iter().enumerate() {
            if let Some(&n) = tet.iter().find(|&&n| n as usize >= nodes.len()) {
                return Err(invalid(format!(
                    "tetra {t} refers to node {n}, but there are only {} nodes",
                    nodes.len()
                )));
            }
        }
        if let Some(n) = nodes
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
        {
            return Err(invalid(format!("node {n} has a non-finite coordinate")));
        }
        let tetra = |t: usize| format!("tetra {t}");
        msh::check_volumes(&nodes, &tets, tetra).map_err(invalid)?;
        msh::check_dangling(nodes.len(), &tets, |n| format!("node {n}")).map_err(invalid)?;
        let boundary = boundary_faces(&tets)
            .map_err(|e| msh::describe_boundary_error(e, tetra))
            .map_err(invalid)?;
        Ok(TetMesh {
            source,
            nodes,
            tets,
            groups,
            boundary,
        })
    }

    /// The physical group called `name` (the first one if several dimensions share it).
    pub fn group(&self, name: &str) -> Option<&PhysicalGroup> {
        self.groups.iter().find(|g| g.name == name)
    }

    /// Checks that every group in `names` exists; the error names the file, each missing
    /// group and the groups the mesh does have, e.g.
    /// `mesh.msh: physical group "tip" is missing (the mesh has: fixed, top)`.
    pub fn require_groups(&self, names: &[&str]) -> Result<()> {
        let missing: Vec<String> = names
            .iter()
            .filter(|name| self.group(name).is_none())
            .map(|name| format!("\"{name}\""))
            .collect();
        if missing.is_empty() {
            return Ok(());
        }
        let present: Vec<&str> = self.groups.iter().map(|g| g.name.as_str()).collect();
        let present = if present.is_empty() {
            "the mesh has no physical groups".to_string()
        } else {
            format!("the mesh has: {}", present.join(", "))
        };
        let what = if missing.len() == 1 {
            format!("physical group {} is missing ({present})", missing[0])
        } else {
            format!(
                "physical groups {} are missing ({present})",
                missing.join(", ")
            )
        };
        Err(Error::invalid(&self.source, what))
    }

    /// Index of the node closest to `point` (the lowest index on ties; 0 for a mesh
    /// without nodes). A linear scan: meant for placing a few probes and loads.
    pub fn node_nearest(&self, point: Point3<f64>) -> u32 {
        let mut best = (0u32, f64::INFINITY);
        for (i, node) in self.nodes.iter().enumerate() {
            let distance = (node - point).norm_squared();
            if distance < best.1 {
                best = (i as u32, distance);
            }
        }
        best.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corner_nodes() -> Vec<Point3<f64>> {
        vec![
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ]
    }

    #[test]
    fn from_parts_checks_like_the_reader() {
        let mesh = TetMesh::from_parts("gen", corner_nodes(), vec![[0, 1, 2, 3]], vec![]).unwrap();
        assert_eq!(mesh.boundary.len(), 4);
        assert_eq!(mesh.node_nearest(Point3::new(0.9, 0.2, 0.0)), 1);
        let error = |tets: Vec<[u32; 4]>, nodes: Vec<Point3<f64>>| {
            TetMesh::from_parts("gen", nodes, tets, vec![])
                .unwrap_err()
                .to_string()
        };
        assert!(error(vec![[0, 2, 1, 3]], corner_nodes()).contains("tetra 0 is inverted"));
        assert!(error(vec![[0, 1, 2, 7]], corner_nodes()).contains("refers to node 7"));
        let mut five = corner_nodes();
        five.push(Point3::new(5.0, 5.0, 5.0));
        assert!(error(vec![[0, 1, 2, 3]], five).contains("node 4 is used by no tetrahedron"));
        assert!(error(vec![], corner_nodes()).contains("no tetrahedra"));
    }

    #[test]
    fn require_groups_on_a_mesh_without_groups() {
        let mesh =
            TetMesh::from_parts("gen.msh", corner_nodes(), vec![[0, 1, 2, 3]], vec![]).unwrap();
        assert_eq!(
            mesh.require_groups(&["tip"]).unwrap_err().to_string(),
            "gen.msh: physical group \"tip\" is missing (the mesh has no physical groups)"
        );
        assert!(mesh.require_groups(&[]).is_ok());
    }
}
