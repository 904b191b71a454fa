//! A format-independent unstructured grid that solvers fill and writers serialise:
//! points, cells of a few linear kinds, and named point and cell fields.

use crate::{Error, Result};

/// The cell kinds the writers support (VTK's linear cells of the same names).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CellKind {
    /// A single point (VTK_VERTEX).
    Vertex,
    /// A two-node segment (VTK_LINE).
    Line,
    /// A three-node triangle (VTK_TRIANGLE).
    Triangle,
    /// A four-node tetrahedron (VTK_TETRA).
    Tetra,
}

impl CellKind {
    /// The number of nodes of a cell of this kind.
    pub fn node_count(self) -> usize {
        match self {
            CellKind::Vertex => 1,
            CellKind::Line => 2,
            CellKind::Triangle => 3,
            CellKind::Tetra => 4,
        }
    }

    /// The VTK cell type number.
    pub fn vtk_type(self) -> u8 {
        match self {
            CellKind::Vertex => 1,
            CellKind::Line => 3,
            CellKind::Triangle => 5,
            CellKind::Tetra => 10,
        }
    }
}

/// The values of a field, flat (component fastest), in one of the stored scalar types.
#[derive(Clone, Debug, PartialEq)]
pub enum FieldValues {
    /// Floating-point values (state, stresses, …).
    F64(Vec<f64>),
    /// Integer values (ids, subdomains, flags).
    I32(Vec<i32>),
}

impl FieldValues {
    /// The number of scalar values (tuples × components).
    pub fn len(&self) -> usize {
        match self {
            FieldValues::F64(values) => values.len(),
            FieldValues::I32(values) => values.len(),
        }
    }

    /// Whether there are no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl From<Vec<f64>> for FieldValues {
    fn from(values: Vec<f64>) -> Self {
        FieldValues::F64(values)
    }
}

impl From<&[f64]> for FieldValues {
    fn from(values: &[f64]) -> Self {
        FieldValues::F64(values.to_vec())
    }
}

impl From<Vec<i32>> for FieldValues {
    fn from(values: Vec<i32>) -> Self {
        FieldValues::I32(values)
    }
}

impl From<&[i32]> for FieldValues {
    fn from(values: &[i32]) -> Self {
        FieldValues::I32(values.to_vec())
    }
}

impl<const N: usize> From<&[[f64; N]]> for FieldValues {
    fn from(values: &[[f64; N]]) -> Self {
        FieldValues::F64(values.iter().flatten().copied().collect())
    }
}

impl<const N: usize> From<Vec<[f64; N]>> for FieldValues {
    fn from(values: Vec<[f64; N]>) -> Self {
        FieldValues::from(values.as_slice())
    }
}

impl From<&[nalgebra::Vector3<f64>]> for FieldValues {
    fn from(values: &[nalgebra::Vector3<f64>]) -> Self {
        FieldValues::F64(values.iter().flat_map(|v| [v.x, v.y, v.z]).collect())
    }
}

impl From<&[nalgebra::Matrix3<f64>]> for FieldValues {
    /// Row-major 3×3 tensors, as VTK expects (`t00 t01 t02 t10 …`).
    fn from(values: &[nalgebra::Matrix3<f64>]) -> Self {
        FieldValues::F64(
            values
                .iter()
                .flat_map(|m| (0..3).flat_map(move |i| (0..3).map(move |j| m[(i, j)])))
                .collect(),
        )
    }
}

/// A named array attached to points or cells.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// The array name; by convention it carries the unit (`displacement_m`).
    pub name: String,
    /// Components per tuple: 1 scalar, 3 vector, 9 tensor (row-major).
    pub components: usize,
    /// `components` values per point or cell, component fastest.
    pub values: FieldValues,
}

/// An unstructured grid: points, cells (possibly of mixed kinds) and fields.
///
/// Cells are stored VTK-style: a flat `connectivity`, the end `offsets` of each cell in it,
/// and one kind per cell. Builders check indices and lengths and return
/// [`Error::Message`] on a mismatch instead of panicking.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Grid {
    points: Vec<[f64; 3]>,
    connectivity: Vec<u64>,
    offsets: Vec<u64>,
    kinds: Vec<CellKind>,
    point_data: Vec<Field>,
    cell_data: Vec<Field>,
}

impl Grid {
    /// A grid of `points` and no cells yet.
    pub fn new(points: Vec<[f64; 3]>) -> Self {
        Grid {
            points,
            ..Grid::default()
        }
    }

    /// Tetrahedra (`tets` index `points`).
    pub fn tetra(points: Vec<[f64; 3]>, tets: &[[usize; 4]]) -> Result<Self> {
        Self::with_cells(points, CellKind::Tetra, tets)
    }

    /// Triangles (`triangles` index `points`), e.g. grain surfaces.
    pub fn triangles(points: Vec<[f64; 3]>, triangles: &[[usize; 3]]) -> Result<Self> {
        Self::with_cells(points, CellKind::Triangle, triangles)
    }

    /// Line segments (`lines` index `points`), e.g. contact force chains.
    pub fn lines(points: Vec<[f64; 3]>, lines: &[[usize; 2]]) -> Result<Self> {
        Self::with_cells(points, CellKind::Line, lines)
    }

    /// One vertex cell per point (grain centres, DEM particles), so that cell data and
    /// ParaView's surface rendering both work.
    pub fn points(points: Vec<[f64; 3]>) -> Self {
        let count = points.len() as u64;
        Grid {
            points,
            connectivity: (0..count).collect(),
            offsets: (1..=count).collect(),
            kinds: vec![CellKind::Vertex; count as usize],
            ..Grid::default()
        }
    }

    fn with_cells<const N: usize>(
        points: Vec<[f64; 3]>,
        kind: CellKind,
        cells: &[[usize; N]],
    ) -> Result<Self> {
        let mut grid = Grid::new(points);
        grid.add_cells(kind, cells)?;
        Ok(grid)
    }

    /// Appends cells of one kind; each cell lists `kind.node_count()` point indices.
    /// Cell fields already added must be added again, so add cells first.
    pub fn add_cells<const N: usize>(
        &mut self,
        kind: CellKind,
        cells: &[[usize; N]],
    ) -> Result<()> {
        if N != kind.node_count() {
            return Err(Error::Message(format!(
                "a {kind:?} cell has {} nodes, got cells of {N}",
                kind.node_count()
            )));
        }
        if !self.cell_data.is_empty() {
            return Err(Error::Message(format!(
                "cells added after cell field `{}`: add all cells first",
                self.cell_data[0].name
            )));
        }
        let point_count = self.points.len();
        if let Some((cell, node)) = cells.iter().enumerate().find_map(|(i, cell)| {
            cell.iter()
                .find(|&&node| node >= point_count)
                .map(|&node| (i, node))
        }) {
            return Err(Error::Message(format!(
                "{kind:?} cell {cell} refers to point {node}, but the grid has {point_count} points"
            )));
        }
        self.connectivity.reserve(cells.len() * N);
        self.offsets.reserve(cells.len());
        for cell in cells {
            self.connectivity
                .extend(cell.iter().map(|&node| node as u64));
            self.offsets.push(self.connectivity.len() as u64);
            self.kinds.push(kind);
        }
        Ok(())
    }

    /// Adds a point field of `components` values per point.
    pub fn add_point_field(
        &mut self,
        name: impl Into<String>,
        components: usize,
        values: impl Into<FieldValues>,
    ) -> Result<()> {
        let field = make_field(
            name.into(),
            components,
            values.into(),
            self.point_count(),
            "point",
        )?;
        check_unique(&self.point_data, &field.name, "point")?;
        self.point_data.push(field);
        Ok(())
    }

    /// Adds a cell field of `components` values per cell.
    pub fn add_cell_field(
        &mut self,
        name: impl Into<String>,
        components: usize,
        values: impl Into<FieldValues>,
    ) -> Result<()> {
        let field = make_field(
            name.into(),
            components,
            values.into(),
            self.cell_count(),
            "cell",
        )?;
        check_unique(&self.cell_data, &field.name, "cell")?;
        self.cell_data.push(field);
        Ok(())
    }

    /// The number of points.
    pub fn point_count(&self) -> usize {
        self.points.len()
    }

    /// The number of cells.
    pub fn cell_count(&self) -> usize {
        self.kinds.len()
    }

    /// The point coordinates.
    pub fn point_coordinates(&self) -> &[[f64; 3]] {
        &self.points
    }

    /// All cells' point indices, concatenated.
    pub fn connectivity(&self) -> &[u64] {
        &self.connectivity
    }

    /// The end of each cell in [`Grid::connectivity`] (no leading zero, as in VTK XML).
    pub fn offsets(&self) -> &[u64] {
        &self.offsets
    }

    /// The kind of each cell.
    pub fn cell_kinds(&self) -> &[CellKind] {
        &self.kinds
    }

    /// The point fields, in the order they were added.
    pub fn point_fields(&self) -> &[Field] {
        &self.point_data
    }

    /// The cell fields, in the order they were added.
    pub fn cell_fields(&self) -> &[Field] {
        &self.cell_data
    }
}

/// Converts nalgebra points (the geometry's type) into the grid's coordinate arrays.
pub fn points_from_nalgebra(points: &[nalgebra::Point3<f64>]) -> Vec<[f64; 3]> {
    points.iter().map(|p| [p.x, p.y, p.z]).collect()
}

fn make_field(
    name: String,
    components: usize,
    values: FieldValues,
    tuples: usize,
    location: &str,
) -> Result<Field> {
    if name.is_empty() {
        return Err(Error::Message(format!(
            "{location} field with an empty name"
        )));
    }
    if components == 0 {
        return Err(Error::Message(format!(
            "{location} field `{name}` has zero components"
        )));
    }
    if values.len() != tuples * components {
        return Err(Error::Message(format!(
            "{location} field `{name}`: {} values for {tuples} {location}s × {components} components (expected {})",
            values.len(),
            tuples * components
        )));
    }
    Ok(Field {
        name,
        components,
        values,
    })
}

fn check_unique(fields: &[Field], name: &str, location: &str) -> Result<()> {
    if fields.iter().any(|f| f.name == name) {
        return Err(Error::Message(format!(
            "{location} field `{name}` added twice"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_tetra() -> Vec<[f64; 3]> {
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ]
    }

    #[test]
    fn builds_cells_vtk_style() {
        let mut grid = Grid::tetra(unit_tetra(), &[[0, 1, 2, 3]]).unwrap();
        grid.add_cells(CellKind::Triangle, &[[0, 1, 2]]).unwrap();
        assert_eq!(grid.connectivity(), [0, 1, 2, 3, 0, 1, 2]);
        assert_eq!(grid.offsets(), [4, 7]);
        assert_eq!(grid.cell_kinds(), [CellKind::Tetra, CellKind::Triangle]);
        let points = Grid::points(unit_tetra());
        assert_eq!(points.cell_count(), 4);
        assert_eq!(points.offsets(), [1, 2, 3, 4]);
    }

    #[test]
    fn rejects_bad_indices_and_lengths() {
        let error = Grid::tetra(unit_tetra(), &[[0, 1, 2, 4]]).unwrap_err();
        assert!(error.to_string().contains("point 4"), "{error}");
        let mut grid = Grid::tetra(unit_tetra(), &[[0, 1, 2, 3]]).unwrap();
        let error = grid
            .add_point_field("displacement_m", 3, vec![0.0; 11])
            .unwrap_err();
        assert!(error.to_string().contains("displacement_m"), "{error}");
        assert!(grid.add_cell_field("subdomain", 1, vec![2_i32]).is_ok());
        assert!(grid.add_cell_field("subdomain", 1, vec![2_i32]).is_err());
        assert!(grid.add_cells(CellKind::Vertex, &[[0]]).is_err());
        assert!(grid.add_cells(CellKind::Line, &[[0, 1, 2]]).is_err());
    }

    #[test]
    fn tensors_are_row_major() {
        let m = nalgebra::Matrix3::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0);
        let values = FieldValues::from(&[m][..]);
        assert_eq!(
            values,
            FieldValues::F64(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
        );
    }
}
