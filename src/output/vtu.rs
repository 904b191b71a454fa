//! VTK XML unstructured grids (`.vtu`) through vtkio: binary (base64) arrays, zlib
//! compressed, written atomically.

use std::path::Path;

use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataArray, DataSet, ElementType,
    UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};
use vtkio::xml::Compressor;
use vtkio::IOBuffer;

use super::atomic::write_atomic;
use super::grid::{CellKind, Field, FieldValues, Grid};
use crate::{Error, Result};

/// zlib level: fast, and most of the gain on floating-point state.
const COMPRESSION_LEVEL: u32 = 5;

/// vtkio's compressed block size. For an array whose byte size is a multiple of this (zero
/// included) vtkio 0.7.0-rc2 writes one empty block too many while its header says "last
/// block full", so the header claims 32 KiB more than the data. VTK 9.7 reads such files
/// (it decompresses only the blocks it needs), but the header breaks the format, so those
/// rare files are written uncompressed instead.
const VTKIO_BLOCK_BYTES: usize = 32768;

/// Writes `grid` to `path` as a binary VTK XML unstructured grid, atomically.
pub fn write_vtu(path: impl AsRef<Path>, grid: &Grid) -> Result<()> {
    let path = path.as_ref();
    let bytes = encode(grid, should_compress(grid)).map_err(|what| Error::invalid(path, what))?;
    write_atomic(path, &bytes)
}

/// The `.vtu` file content for `grid` (what [`write_vtu`] writes).
pub fn vtu_bytes(grid: &Grid) -> Result<Vec<u8>> {
    encode(grid, should_compress(grid)).map_err(Error::Message)
}

/// Whether every array avoids vtkio's compressed-block edge case.
fn should_compress(grid: &Grid) -> bool {
    array_byte_sizes(grid).all(|size| size % VTKIO_BLOCK_BYTES != 0)
}

fn encode(grid: &Grid, compress: bool) -> std::result::Result<Vec<u8>, String> {
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(grid.point_coordinates().iter().flatten().copied().collect()),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity: grid.connectivity().to_vec(),
                offsets: grid.offsets().to_vec(),
            },
            types: grid.cell_kinds().iter().map(|&k| cell_type(k)).collect(),
        },
        data: Attributes {
            point: grid.point_fields().iter().map(attribute).collect(),
            cell: grid.cell_fields().iter().map(attribute).collect(),
        },
    };
    let vtk = Vtk {
        version: Version::new_xml(1, 0),
        title: String::new(),
        byte_order: ByteOrder::LittleEndian,
        data: DataSet::inline(piece),
        file_path: None,
    };
    let (compressor, level) = if compress {
        (Compressor::ZLib, COMPRESSION_LEVEL)
    } else {
        (Compressor::None, 0)
    };
    let file = vtk
        .try_into_xml_format(compressor, level)
        .map_err(|e| format!("VTK encoding failed: {e}"))?;
    let mut bytes = Vec::new();
    file.write(&mut bytes)
        .map_err(|e| format!("VTK encoding failed: {e}"))?;
    add_zero_counts(&mut bytes, grid)?;
    Ok(bytes)
}

/// vtkio 0.7.0-rc2 leaves out `NumberOfPoints`/`NumberOfCells` when they are zero, and
/// VTK refuses such a piece; put them back (an empty contact network is an ordinary frame).
fn add_zero_counts(bytes: &mut Vec<u8>, grid: &Grid) -> std::result::Result<(), String> {
    let mut missing = String::new();
    if grid.point_count() == 0 {
        missing.push_str(" NumberOfPoints=\"0\"");
    }
    if grid.cell_count() == 0 {
        missing.push_str(" NumberOfCells=\"0\"");
    }
    if missing.is_empty() {
        return Ok(());
    }
    let tag = b"<Piece";
    let at = bytes
        .windows(tag.len())
        .position(|window| window == tag)
        .ok_or("VTK encoding failed: no Piece element")?;
    let insert_at = at + tag.len();
    bytes.splice(insert_at..insert_at, missing.bytes());
    Ok(())
}

fn cell_type(kind: CellKind) -> CellType {
    match kind {
        CellKind::Vertex => CellType::Vertex,
        CellKind::Line => CellType::Line,
        CellKind::Triangle => CellType::Triangle,
        CellKind::Tetra => CellType::Tetra,
    }
}

/// A data array tagged so that ParaView picks the first scalar, vector and tensor field
/// as the active ones.
fn attribute(field: &Field) -> Attribute {
    let elem = match field.components {
        1 => ElementType::Scalars {
            num_comp: 1,
            lookup_table: None,
        },
        3 => ElementType::Vectors,
        9 => ElementType::Tensors,
        n => ElementType::Generic(n as u32),
    };
    let data = match &field.values {
        FieldValues::F64(values) => IOBuffer::F64(values.clone()),
        FieldValues::I32(values) => IOBuffer::I32(values.clone()),
    };
    Attribute::DataArray(DataArray {
        name: field.name.clone(),
        elem,
        data,
    })
}

/// The byte size of every array vtkio will write for `grid`.
fn array_byte_sizes(grid: &Grid) -> impl Iterator<Item = usize> + '_ {
    let field_bytes = |field: &Field| match &field.values {
        FieldValues::F64(values) => values.len() * 8,
        FieldValues::I32(values) => values.len() * 4,
    };
    [
        grid.point_count() * 24,
        grid.connectivity().len() * 8,
        grid.offsets().len() * 8,
        grid.cell_count(),
    ]
    .into_iter()
    .chain(grid.point_fields().iter().map(field_bytes))
    .chain(grid.cell_fields().iter().map(field_bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(points: usize) -> Grid {
        let coordinates = (0..points).map(|i| [i as f64, 0.5, -1.0]).collect();
        let mut grid = Grid::points(coordinates);
        grid.add_point_field("mass_kg", 1, vec![1.25; points])
            .unwrap();
        grid
    }

    #[test]
    fn compresses_unless_a_size_hits_the_vtkio_block_bug() {
        let small = String::from_utf8(vtu_bytes(&sample(10)).unwrap()).unwrap();
        assert!(small.contains("vtkZLibDataCompressor"), "{small}");
        assert!(small.contains("UnstructuredGrid"));
        assert!(small.contains("format=\"binary\""));
        // 4096 f64 = 32768 bytes: written uncompressed.
        let exact = String::from_utf8(vtu_bytes(&sample(4096)).unwrap()).unwrap();
        assert!(!exact.contains("vtkZLibDataCompressor"));
        let empty = String::from_utf8(vtu_bytes(&Grid::default()).unwrap()).unwrap();
        assert!(!empty.contains("vtkZLibDataCompressor"));
    }
}
