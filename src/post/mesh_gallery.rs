//! The mesh gallery scene: every mesh of the pipeline read with its checks, exported to
//! VTK with per-tetra quality, and tabulated (nodes, tetra, volume, mass, quality).
//!
//! It is the default scene of `make` until a solver scene takes its place: it proves that
//! geometry → gmsh → import → VTK works end to end, and it is the place to look when a
//! mesh is suspect (the worst elements are in the `quality` cell field).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde_json::{json, Value};

use crate::mesh::{read_msh, tet_quality, MeshQuality, TetMesh};
use crate::output::{points_from_nalgebra, write_atomic, write_json, write_vtu, Grid};
use crate::scene::{Material, PhaseTimer, RunContext, Summary, Validate, Validator};
use crate::{Error, Result};

/// The gallery scene file (`scenes/mesh_gallery.toml`). Paths are relative to the scene
/// file's directory.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GalleryScene {
    /// The materials the meshes refer to by name.
    pub material: Vec<Material>,
    /// The object meshes, one VTK file each.
    pub mesh: Vec<GalleryMesh>,
    /// A stone family shown together in one VTK file.
    #[serde(default)]
    pub stones: Option<GalleryStones>,
}

/// One object mesh of the gallery.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GalleryMesh {
    /// Name of the VTK file and of the table row.
    pub name: String,
    /// The `.msh` file.
    pub file: PathBuf,
    /// Name of a `[[material]]` entry (gives the mass).
    pub material: String,
    /// Physical groups the mesh must have (the solvers' scenes rely on them).
    #[serde(default)]
    pub groups: Vec<String>,
}

/// A directory of stone meshes (`stone_*.msh`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GalleryStones {
    /// The directory holding the stone meshes.
    pub dir: PathBuf,
    /// Name of a `[[material]]` entry.
    pub material: String,
}

impl Validate for GalleryScene {
    fn validate(&self, v: &mut Validator) {
        v.each("material", &self.material);
        v.check("mesh", !self.mesh.is_empty(), "must list at least one mesh");
        let known: Vec<&str> = self.material.iter().map(|m| m.name.as_str()).collect();
        let mut check_material = |key: String, name: &str| {
            v.check(
                &key,
                known.contains(&name),
                format!(
                    "no [[material]] named \"{name}\" (have: {})",
                    known.join(", ")
                ),
            );
        };
        for (i, mesh) in self.mesh.iter().enumerate() {
            check_material(format!("mesh[{i}].material"), &mesh.material);
        }
        if let Some(stones) = &self.stones {
            check_material("stones.material".to_string(), &stones.material);
        }
    }
}

/// One row of the gallery table.
#[derive(Debug, Clone)]
pub struct GalleryRow {
    /// Mesh name.
    pub name: String,
    /// The VTK file written, relative to the output directory.
    pub vtu: String,
    /// Counts, volume and quality.
    pub quality: MeshQuality,
    /// Mass in kg from the material density.
    pub mass_kg: f64,
    /// Number of meshes merged in the row (1, or the number of stones).
    pub parts: usize,
}

/// Runs the gallery scene: reads and checks every mesh, writes `<name>.vtu` per mesh,
/// `stones.vtu`, `mesh_table.md` and `summary.json` into the run's output directory,
/// and returns the table as text.
pub fn run_gallery(ctx: &RunContext) -> Result<String> {
    let mut timer = PhaseTimer::new();
    let (scene, inputs): (GalleryScene, _) = ctx.load_scene()?;
    let base = ctx.scene_path.parent().unwrap_or(Path::new("."));
    let density: BTreeMap<&str, f64> = scene
        .material
        .iter()
        .map(|m| (m.name.as_str(), m.density.si()))
        .collect();
    std::fs::create_dir_all(&ctx.out_dir).map_err(|e| Error::io(&ctx.out_dir, e))?;

    let mut rows = Vec::new();
    for entry in &scene.mesh {
        let mesh = timer.time("read", || read_msh(&base.join(&entry.file)))?;
        let groups: Vec<&str> = entry.groups.iter().map(String::as_str).collect();
        mesh.require_groups(&groups)?;
        let vtu = format!("{}.vtu", entry.name);
        timer.time("write", || {
            write_vtu(ctx.out_dir.join(&vtu), &mesh_grid(&[(&mesh, 0)])?)
        })?;
        let quality = mesh.quality();
        rows.push(GalleryRow {
            name: entry.name.clone(),
            vtu,
            mass_kg: quality.volume_m3 * density[entry.material.as_str()],
            quality,
            parts: 1,
        });
    }
    if let Some(stones) = &scene.stones {
        let dir = base.join(&stones.dir);
        let meshes = timer.time("read", || read_stone_dir(&dir))?;
        let vtu = "stones.vtu".to_string();
        let laid_out = lay_out_in_rows(&meshes);
        let parts: Vec<(&TetMesh, usize)> = laid_out.iter().zip(0..).collect();
        timer.time("write", || {
            write_vtu(ctx.out_dir.join(&vtu), &mesh_grid(&parts)?)
        })?;
        let quality = merged_quality(&meshes);
        rows.push(GalleryRow {
            name: format!("stones ({} meshes)", meshes.len()),
            vtu,
            mass_kg: quality.volume_m3 * density[stones.material.as_str()],
            quality,
            parts: meshes.len(),
        });
    }

    let table = format_table(&rows);
    write_atomic(ctx.out_dir.join("mesh_table.md"), table.as_bytes())?;
    let meshes: Vec<Value> = rows
        .iter()
        .map(|r| {
            json!({
                "name": r.name, "vtu": r.vtu, "parts": r.parts,
                "nodes": r.quality.nodes, "tets": r.quality.tets,
                "volume_m3": r.quality.volume_m3, "mass_kg": r.mass_kg,
                "min_altitude_m": r.quality.min_altitude_m,
                "min_quality": r.quality.min_quality, "mean_quality": r.quality.mean_quality,
            })
        })
        .collect();
    let summary = Summary::new(ctx, &inputs)
        .figure("meshes", meshes)
        .wall_times(&timer)
        .to_json();
    write_json(ctx.out_dir.join("summary.json"), &summary)?;
    Ok(table)
}

/// Reads every `stone_*.msh` of `dir`, in name order; an empty directory is an error.
fn read_stone_dir(dir: &Path) -> Result<Vec<TetMesh>> {
    let listing = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut files: Vec<PathBuf> = listing
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().is_some_and(|x| x == "msh")
                && p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("stone_"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(Error::invalid(
            dir,
            "no stone_*.msh meshes (run `make stones`)",
        ));
    }
    files.iter().map(|f| read_msh(f)).collect()
}

/// Copies of `meshes` translated onto a square grid of cells, so a family can be seen at
/// once (spacing: 1.5 × the largest bounding-box extent).
fn lay_out_in_rows(meshes: &[TetMesh]) -> Vec<TetMesh> {
    let extent = |m: &TetMesh| {
        let (mut lo, mut hi) = (m.nodes[0], m.nodes[0]);
        for p in &m.nodes {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (lo, hi)
    };
    let spacing = 1.5
        * meshes
            .iter()
            .map(|m| {
                let (lo, hi) = extent(m);
                (hi - lo).max()
            })
            .fold(0.0, f64::max);
    let per_row = (meshes.len() as f64).sqrt().ceil() as usize;
    meshes
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let (lo, hi) = extent(m);
            let centre = nalgebra::center(&lo, &hi);
            let target = nalgebra::Vector3::new(
                (k % per_row) as f64 * spacing,
                (k / per_row) as f64 * spacing,
                0.0,
            );
            let mut moved = m.clone();
            for p in &mut moved.nodes {
                *p = *p - centre.coords + target;
            }
            moved
        })
        .collect()
}

/// One tetra grid of several meshes, with cell fields `part` (which mesh),
/// `volume_m3` and `quality` (normalised radius ratio, 1 = regular tetra).
fn mesh_grid(parts: &[(&TetMesh, usize)]) -> Result<Grid> {
    let mut points = Vec::new();
    let mut tets = Vec::new();
    let (mut part, mut volume, mut quality) = (Vec::new(), Vec::new(), Vec::new());
    for &(mesh, id) in parts {
        let offset = points.len();
        points.extend(points_from_nalgebra(&mesh.nodes));
        for (t, tet) in mesh.tets.iter().enumerate() {
            tets.push(tet.map(|n| n as usize + offset));
            let corners = mesh.tet_corners(t);
            part.push(id as i32);
            volume.push(mesh.tet_volume(t));
            quality.push(tet_quality(corners));
        }
    }
    let mut grid = Grid::tetra(points, &tets)?;
    grid.add_cell_field("part", 1, part)?;
    grid.add_cell_field("volume_m3", 1, volume)?;
    grid.add_cell_field("quality", 1, quality)?;
    Ok(grid)
}

/// Quality of several meshes taken together (counts and volume add up).
fn merged_quality(meshes: &[TetMesh]) -> MeshQuality {
    let each: Vec<MeshQuality> = meshes.iter().map(TetMesh::quality).collect();
    let tets: usize = each.iter().map(|q| q.tets).sum();
    MeshQuality {
        nodes: each.iter().map(|q| q.nodes).sum(),
        tets,
        volume_m3: each.iter().map(|q| q.volume_m3).sum(),
        min_altitude_m: each
            .iter()
            .map(|q| q.min_altitude_m)
            .fold(f64::INFINITY, f64::min),
        min_quality: each
            .iter()
            .map(|q| q.min_quality)
            .fold(f64::INFINITY, f64::min),
        mean_quality: each
            .iter()
            .map(|q| q.mean_quality * q.tets as f64)
            .sum::<f64>()
            / tets.max(1) as f64,
    }
}

/// The gallery as a Markdown table.
pub fn format_table(rows: &[GalleryRow]) -> String {
    let mut out = String::from(
        "| mesh | nodes | tetra | volume (m³) | mass (kg) | min altitude (mm) | quality min | quality mean |\n\
         |---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let q = &r.quality;
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.6} | {:.2} | {:.2} | {:.3} | {:.3} |",
            r.name,
            q.nodes,
            q.tets,
            q.volume_m3,
            r.mass_kg,
            q.min_altitude_m * 1e3,
            q.min_quality,
            q.mean_quality
        );
    }
    out
}
