//! From a [`SolidScene`] and its mesh to what the solvers take: the material with a
//! case's overrides, the boundary conditions on node lists, and the probes' nodes.
//! Every error names the scene file and the key (or the mesh file and the group).

use std::path::Path;

use nalgebra::{Point3, Vector3};

use super::scene::{CaseSpec, FixSpec, LoadSpec, ProbeSpec, SolidScene, TimeSpec};
use crate::mesh::TetMesh;
use crate::qdem::{Boundary, NodalLoad, QdemMaterial, TimeFunction};
use crate::scene::Material;
use crate::{Error, Result};

/// The scene's material with the case's viscosities, in the QDEM solver's form.
pub fn case_material(material: &Material, case: &CaseSpec) -> QdemMaterial {
    let (_, scene_mu) = material.viscous_lame();
    let mu = case.shear_viscosity.map_or(scene_mu, |v| v.si());
    let kappa = case
        .bulk_viscosity
        .or(material.bulk_viscosity)
        .map_or(0.0, |v| v.si());
    QdemMaterial {
        density: material.density.si(),
        young_modulus: material.young_modulus.si(),
        poisson_ratio: material.poisson,
        shear_viscosity: mu,
        bulk_viscosity: kappa,
    }
}

/// Fixes of the scene followed by the case's, with the key each came from.
pub fn case_fixes<'a>(scene: &'a SolidScene, case: &'a CaseSpec) -> Vec<(String, &'a FixSpec)> {
    let scene_fixes = scene
        .fix
        .iter()
        .enumerate()
        .map(|(i, f)| (format!("fix[{i}]"), f));
    let case_index = scene.case.iter().position(|c| c.name == case.name);
    let extra = case
        .fix
        .iter()
        .enumerate()
        .map(move |(i, f)| (format!("case[{}].fix[{i}]", case_index.unwrap_or(0)), f));
    scene_fixes.chain(extra).collect()
}

/// The boundary conditions of one case on `mesh`.
pub fn boundary(
    scene_path: &Path,
    scene: &SolidScene,
    case: &CaseSpec,
    mesh: &TetMesh,
) -> Result<Boundary> {
    let mut b = Boundary::default();
    for (key, fix) in case_fixes(scene, case) {
        let mask = fix.mask().expect("validated");
        b.constraints
            .fix(group_nodes(scene_path, mesh, &key, &fix.group)?, mask);
    }
    for (i, load) in scene.load.iter().enumerate() {
        b.loads.push(nodal_load(scene_path, mesh, i, load)?);
    }
    if let Some(g) = &scene.gravity {
        b.gravity = Vector3::new(g[0].si(), g[1].si(), g[2].si());
    }
    Ok(b)
}

fn nodal_load(scene_path: &Path, mesh: &TetMesh, i: usize, load: &LoadSpec) -> Result<NodalLoad> {
    let key = format!("load[{i}]");
    let nodes = group_nodes(scene_path, mesh, &key, &load.group)?.to_vec();
    let time_fn = match &load.time {
        None => TimeFunction::Constant,
        Some(t) => time_function(scene_path, &format!("{key}.time"), t)?,
    };
    Ok(NodalLoad {
        nodes,
        total_force: Vector3::new(load.force[0].si(), load.force[1].si(), load.force[2].si()),
        time_fn,
    })
}

/// The nodes of a named group; the error names the scene key, the mesh and the groups
/// it has.
pub fn group_nodes<'m>(
    scene_path: &Path,
    mesh: &'m TetMesh,
    key: &str,
    group: &str,
) -> Result<&'m [u32]> {
    match mesh.group(group) {
        Some(g) if !g.nodes.is_empty() => Ok(&g.nodes),
        Some(_) => Err(Error::invalid(
            scene_path,
            format!(
                "key {key}.group: group \"{group}\" of {} has no nodes",
                mesh.source.display()
            ),
        )),
        None => {
            let have: Vec<&str> = mesh.groups.iter().map(|g| g.name.as_str()).collect();
            Err(Error::invalid(
                scene_path,
                format!(
                    "key {key}.group: {} has no physical group \"{group}\" (it has: {})",
                    mesh.source.display(),
                    have.join(", ")
                ),
            ))
        }
    }
}

/// The time function of a load; a table is read from its CSV (`time_s,factor`).
pub fn time_function(scene_path: &Path, key: &str, spec: &TimeSpec) -> Result<TimeFunction> {
    Ok(match spec.kind.as_str() {
        "constant" => TimeFunction::Constant,
        "ramp" => TimeFunction::Ramp {
            t_ramp: spec.duration.expect("validated").si(),
        },
        "switch_off" => TimeFunction::SwitchOff {
            t0: spec.t0.expect("validated").si(),
        },
        "table" => {
            let file = SolidScene::resolve(scene_path, spec.file.as_ref().expect("validated"));
            let (times, values) = read_factor_table(&file)?;
            let f = TimeFunction::Table { times, values };
            f.validate()
                .map_err(|e| Error::invalid(&file, format!("{e} (from {key}.file)")))?;
            f
        }
        other => {
            return Err(Error::invalid(
                scene_path,
                format!("key {key}.kind: unknown time function \"{other}\""),
            ))
        }
    })
}

/// Reads a two-column CSV `time_s,factor` (header line first).
fn read_factor_table(path: &Path) -> Result<(Vec<f64>, Vec<f64>)> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, header)) if header.trim().replace(' ', "") == "time_s,factor" => {}
        Some((_, header)) => {
            return Err(Error::invalid(
                path,
                format!("line 1: header \"{header}\" must be \"time_s,factor\""),
            ))
        }
        None => return Err(Error::invalid(path, "the file is empty")),
    }
    let (mut times, mut values) = (Vec::new(), Vec::new());
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let parsed: Option<Vec<f64>> = fields.iter().map(|f| f.parse().ok()).collect();
        match parsed.as_deref() {
            Some([t, v]) => {
                times.push(*t);
                values.push(*v);
            }
            _ => {
                return Err(Error::invalid(
                    path,
                    format!(
                        "line {}: \"{line}\" is not two numbers time_s,factor",
                        i + 1
                    ),
                ))
            }
        }
    }
    Ok((times, values))
}

/// A probe resolved to nodes: the displacement reported is the mean over `nodes`.
#[derive(Debug, Clone)]
pub struct Probe {
    /// Column prefix.
    pub name: String,
    /// The nodes averaged (one for a point probe).
    pub nodes: Vec<u32>,
}

impl Probe {
    /// Mean displacement of the probe's nodes, given per-node positions and reference
    /// positions.
    pub fn displacement(&self, positions: &[[f64; 3]], reference: &[[f64; 3]]) -> [f64; 3] {
        let mut u = [0.0; 3];
        for &n in &self.nodes {
            for d in 0..3 {
                u[d] += positions[n as usize][d] - reference[n as usize][d];
            }
        }
        u.map(|x| x / self.nodes.len() as f64)
    }
}

/// Resolves the scene's probes on `mesh`.
pub fn probes(scene_path: &Path, specs: &[ProbeSpec], mesh: &TetMesh) -> Result<Vec<Probe>> {
    specs
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let nodes = match (&p.group, &p.point) {
                (Some(group), _) => {
                    group_nodes(scene_path, mesh, &format!("probe[{i}]"), group)?.to_vec()
                }
                (None, Some(x)) => {
                    vec![mesh.node_nearest(Point3::new(x[0].si(), x[1].si(), x[2].si()))]
                }
                (None, None) => unreachable!("validated"),
            };
            Ok(Probe {
                name: p.name.clone(),
                nodes,
            })
        })
        .collect()
}

/// Area of a surface group (sum of its triangles' areas), for the stress of a load.
pub fn group_area(mesh: &TetMesh, group: &str) -> f64 {
    mesh.group(group).map_or(0.0, |g| {
        g.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|n| mesh.nodes[n as usize]);
                0.5 * (b - a).cross(&(c - a)).norm()
            })
            .sum()
    })
}
