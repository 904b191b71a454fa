//! Reader of the real grain library `BIBLIGRAINS.DAT` (LMGC90 format, Fortran numbers).
//!
//! Layout: the number of grains; then per grain the vertex count nv, nv lines `x y z`, the
//! face count nf and nf lines of three 1-based vertex indices; grains may be separated by
//! `$$$$$$` lines. Exponents may be written with `D` (Fortran double precision) or `E`.

use super::shape::ShapeMeasures;
use crate::{Error, Result};
use nalgebra::Point3;
use std::path::Path;

/// One grain of the library: a closed, outward-oriented triangulated convex polyhedron,
/// recentred on its vertices' mean (the file scatters grains over its frame).
#[derive(Debug, Clone, PartialEq)]
pub struct Grain {
    /// Vertex coordinates (m).
    pub vertices: Vec<Point3<f64>>,
    /// Triangles as 0-based vertex indices, outward oriented.
    pub triangles: Vec<[u32; 3]>,
}

impl Grain {
    /// The grain's shape measures (PCA extents over all its vertices, as the README does).
    pub fn shape(&self) -> ShapeMeasures {
        ShapeMeasures::of_polyhedron(&self.vertices, &self.triangles, &self.vertices)
    }
}

/// Reads every grain of a `BIBLIGRAINS.DAT` file. Triangles are reoriented outwards when
/// the file lists a grain inside out (negative volume).
pub fn read_grain_library(path: &Path) -> Result<Vec<Grain>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_grain_library(path, &text)
}

/// Parses the text of a grain library; `path` is only used in error messages.
pub fn parse_grain_library(path: &Path, text: &str) -> Result<Vec<Grain>> {
    let mut lines = text.lines().enumerate().filter(|(_, line)| {
        let line = line.trim();
        // Blank lines and LMGC90's `$$$$$$` grain separators carry nothing.
        !line.is_empty() && !line.starts_with('$')
    });
    let mut next_line = |what: &str| {
        lines
            .next()
            .ok_or_else(|| Error::invalid(path, format!("file ends before {what}")))
    };
    let (n, line) = next_line("the grain count")?;
    let count: usize = parse_count(path, n, line, "grain count")?;
    let mut grains = Vec::with_capacity(count);
    for g in 0..count {
        let (n, line) = next_line(&format!("grain {}", g + 1))?;
        let nv = parse_count(path, n, line, "vertex count")?;
        let mut vertices = Vec::with_capacity(nv);
        for _ in 0..nv {
            let (n, line) = next_line(&format!("the vertices of grain {}", g + 1))?;
            let xyz = parse_numbers(path, n, line)?;
            if xyz.len() != 3 {
                return Err(Error::invalid(
                    path,
                    format!(
                        "line {}: expected 3 coordinates, found {}",
                        n + 1,
                        xyz.len()
                    ),
                ));
            }
            vertices.push(Point3::new(xyz[0], xyz[1], xyz[2]));
        }
        let (n, line) = next_line(&format!("the face count of grain {}", g + 1))?;
        let nf = parse_count(path, n, line, "face count")?;
        let mut triangles = Vec::with_capacity(nf);
        for _ in 0..nf {
            let (n, line) = next_line(&format!("the faces of grain {}", g + 1))?;
            let ids: Vec<&str> = line.split_whitespace().collect();
            if ids.len() != 3 {
                return Err(Error::invalid(
                    path,
                    format!("line {}: expected 3 vertex indices", n + 1),
                ));
            }
            let mut tri = [0u32; 3];
            for (slot, id) in tri.iter_mut().zip(&ids) {
                let index: usize = id.parse().map_err(|_| {
                    Error::invalid(path, format!("line {}: bad vertex index {id:?}", n + 1))
                })?;
                if index == 0 || index > nv {
                    return Err(Error::invalid(
                        path,
                        format!("line {}: vertex index {index} outside 1..={nv}", n + 1),
                    ));
                }
                *slot = (index - 1) as u32;
            }
            triangles.push(tri);
        }
        if nv < 4 || nf < 4 {
            return Err(Error::invalid(
                path,
                format!(
                    "grain {}: {nv} vertices and {nf} faces do not close a solid",
                    g + 1
                ),
            ));
        }
        let centre = vertices
            .iter()
            .map(|p| p.coords)
            .sum::<nalgebra::Vector3<f64>>()
            / nv as f64;
        for p in &mut vertices {
            *p -= centre;
        }
        let mut grain = Grain {
            vertices,
            triangles,
        };
        if super::polyhedron::mass_properties(&grain.vertices, &grain.triangles).volume < 0.0 {
            for tri in &mut grain.triangles {
                tri.swap(1, 2);
            }
        }
        grains.push(grain);
    }
    Ok(grains)
}

fn parse_count(path: &Path, n: usize, line: &str, what: &str) -> Result<usize> {
    line.trim().parse().map_err(|_| {
        Error::invalid(
            path,
            format!("line {}: bad {what} {:?}", n + 1, line.trim()),
        )
    })
}

/// Parses whitespace-separated reals, accepting Fortran `D` exponents.
fn parse_numbers(path: &Path, n: usize, line: &str) -> Result<Vec<f64>> {
    line.split_whitespace()
        .map(|word| {
            word.replace(['D', 'd'], "E")
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| Error::invalid(path, format!("line {}: bad number {word:?}", n + 1)))
        })
        .collect()
}
