//! Tetrahedral meshes read from gmsh MSH 4.1 files (ASCII or binary, through mshio),
//! with physical-group names, node sets, boundary triangles and quality checks.

use nalgebra::Point3;
use std::path::PathBuf;

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
