//! Linear elastic finite elements on 4-node tetrahedra: the yardstick for QDEM accuracy
//! (as FrontISTR and CalculiX were in seed 004).
//!
//! - [`FemModel`] holds the mesh (plain slices), the material and the per-element
//!   shape-function gradients, plus the node graph the sparse patterns come from.
//! - [`FemModel::system`] eliminates the prescribed DOFs of a [`DofSet`], assembles K
//!   (plus optional grounded [`Springs`], e.g. a Winkler bed) in parallel on a
//!   compressed-column pattern of the free DOFs and computes the fill-reducing ordering
//!   and symbolic Cholesky factor once; statics and modes on that system share them.
//! - [`FemSystem::static_solve`] factorises K (faer sparse Cholesky) and solves.
//! - [`FemSystem::modes`] finds the lowest eigenpairs of K φ = ω² M φ by shift-invert
//!   block Lanczos with thick restarts and Rayleigh–Ritz on K and M (see [`modes`]).
//!
//! The core knows nothing of files, TOML or the CLI.

mod assembly;
mod cholesky;
mod dirichlet;
mod element;
pub mod modes;
mod rigid;
mod static_solve;
mod winkler;

pub use dirichlet::DofSet;
pub use element::{LinearElastic, TetGeometry};
pub use modes::{MassKind, ModeOptions, Modes, Shift};
pub use static_solve::StaticSolution;
pub use winkler::Springs;

use crate::{Error, Result};
use assembly::{NodeGraph, ReducedPattern};
use cholesky::{Factor, SymbolicFactor};
use dirichlet::DofMap;
use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;
use std::time::Instant;

/// Wall time per phase in seconds (the phases a run reports).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhaseTimes {
    /// Sparse assembly of K and M (and springs).
    pub assembly_s: f64,
    /// Fill-reducing ordering and symbolic factorisation.
    pub ordering_s: f64,
    /// Numeric Cholesky factorisations.
    pub factorisation_s: f64,
    /// Triangular solves of the static problem.
    pub solve_s: f64,
    /// The eigensolver, its own solves included.
    pub eigen_s: f64,
}

impl PhaseTimes {
    /// The sum of all phases.
    pub fn total_s(&self) -> f64 {
        self.assembly_s + self.ordering_s + self.factorisation_s + self.solve_s + self.eigen_s
    }
}

impl std::fmt::Display for PhaseTimes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "assembly {:.3} s, ordering {:.3} s, factorisation {:.3} s, solve {:.3} s, eigen {:.3} s (total {:.3} s)",
            self.assembly_s,
            self.ordering_s,
            self.factorisation_s,
            self.solve_s,
            self.eigen_s,
            self.total_s()
        )
    }
}

fn seconds_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64()
}

/// A linear elastic tetrahedral model: nodes, tetra, one material.
#[derive(Debug, Clone)]
pub struct FemModel {
    nodes: Vec<Point3<f64>>,
    tets: Vec<[u32; 4]>,
    material: LinearElastic,
    geometry: Vec<TetGeometry>,
    graph: NodeGraph,
}

impl FemModel {
    /// Checks the input (material ranges, node indices, degenerate tetra, nodes that
    /// belong to no tetra) and precomputes element gradients and the node graph.
    /// Errors name the tetra or node (0-based) and the reason.
    pub fn new(nodes: &[Point3<f64>], tets: &[[u32; 4]], material: LinearElastic) -> Result<Self> {
        let fail = |what: String| Error::Message(format!("fem: {what}"));
        material.check().map_err(fail)?;
        if tets.is_empty() {
            return Err(fail("the mesh has no tetrahedra".into()));
        }
        if nodes.len() > (u32::MAX / 3) as usize {
            return Err(fail(format!("too many nodes ({})", nodes.len())));
        }
        if let Some(n) = nodes
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
        {
            return Err(fail(format!("node {n} has a non-finite coordinate")));
        }
        for (t, tet) in tets.iter().enumerate() {
            if let Some(&n) = tet.iter().find(|&&n| n as usize >= nodes.len()) {
                return Err(fail(format!(
                    "tetra {t} refers to node {n}, but there are only {} nodes",
                    nodes.len()
                )));
            }
        }
        let geometry: Vec<Option<TetGeometry>> = tets
            .par_iter()
            .map(|tet| TetGeometry::new(tet.map(|n| nodes[n as usize])))
            .collect();
        if let Some(t) = geometry.iter().position(Option::is_none) {
            return Err(fail(format!("tetra {t} is degenerate (zero volume)")));
        }
        let geometry: Vec<TetGeometry> = geometry.into_iter().flatten().collect();
        let graph = NodeGraph::new(nodes.len(), tets);
        if let Some(n) = (0..nodes.len()).find(|&n| graph.tet_ptr[n] == graph.tet_ptr[n + 1]) {
            return Err(fail(format!("node {n} belongs to no tetra")));
        }
        Ok(FemModel {
            nodes: nodes.to_vec(),
            tets: tets.to_vec(),
            material,
            geometry,
            graph,
        })
    }

    /// Node coordinates.
    pub fn nodes(&self) -> &[Point3<f64>] {
        &self.nodes
    }

    /// Tetrahedra (node indices).
    pub fn tets(&self) -> &[[u32; 4]] {
        &self.tets
    }

    /// The material.
    pub fn material(&self) -> &LinearElastic {
        &self.material
    }

    /// Gradients and volume of each tetra.
    pub fn geometry(&self) -> &[TetGeometry] {
        &self.geometry
    }

    /// Total volume in m³.
    pub fn volume(&self) -> f64 {
        self.geometry.iter().map(|g| g.volume).sum()
    }

    /// Total mass in kg.
    pub fn mass(&self) -> f64 {
        self.volume() * self.material.density
    }

    /// Eliminates `fixed`, assembles K (+ `springs`) on the free DOFs and computes the
    /// ordering and symbolic factorisation, ready for [`FemSystem::static_solve`] and
    /// [`FemSystem::modes`].
    pub fn system(&self, fixed: &DofSet, springs: Option<&Springs>) -> Result<FemSystem<'_>> {
        let node_count = self.nodes.len();
        let out_of_range = |what: &str, n: u32| {
            Error::Message(format!(
                "fem: {what} names node {n}, but there are only {node_count} nodes"
            ))
        };
        if let Some(n) = fixed.max_node().filter(|&n| n as usize >= node_count) {
            return Err(out_of_range("the fixed DOF set", n));
        }
        if let Some(springs) = springs {
            if let Some(n) = springs.max_node().filter(|&n| n as usize >= node_count) {
                return Err(out_of_range("the spring set", n));
            }
        }
        let dofs = DofMap::new(node_count, fixed);
        if dofs.free_count() == 0 {
            return Err(Error::Message("fem: every DOF is fixed".into()));
        }
        let start = Instant::now();
        let pattern = ReducedPattern::new(&self.graph, &dofs);
        let mut stiffness = self.assemble_stiffness(&pattern, &dofs);
        if let Some(springs) = springs {
            for (node, block) in springs.iter() {
                pattern.add_node_block(&self.graph, &dofs, &mut stiffness, node as usize, block);
            }
        }
        let assembly_s = seconds_since(start);
        let start = Instant::now();
        let symbolic = SymbolicFactor::new(&self.graph, &pattern, &self.nodes)?;
        let ordering_s = seconds_since(start);
        let anchored = rigid::is_anchored(self, fixed, springs);
        Ok(FemSystem {
            model: self,
            dofs,
            pattern,
            stiffness,
            springs: springs.cloned(),
            symbolic,
            stiffness_factor: None,
            anchored,
            setup_times: PhaseTimes {
                assembly_s,
                ordering_s,
                ..PhaseTimes::default()
            },
        })
    }

    /// Static solution under nodal `loads` (N, one per node) with `fixed` DOFs.
    pub fn static_solve(&self, fixed: &DofSet, loads: &[Vector3<f64>]) -> Result<StaticSolution> {
        self.system(fixed, None)?.static_solve(loads)
    }

    /// The lowest `k` modes with `fixed` DOFs and optional grounded `springs`.
    pub fn modes(
        &self,
        fixed: &DofSet,
        k: usize,
        springs: Option<&Springs>,
        options: &ModeOptions,
    ) -> Result<Modes> {
        self.system(fixed, springs)?.modes(k, options)
    }

    /// The (constant) small strain of every tetra for nodal `displacement`.
    pub fn tet_strain(&self, displacement: &[Vector3<f64>]) -> Vec<Matrix3<f64>> {
        self.tets
            .par_iter()
            .zip(&self.geometry)
            .map(|(tet, geom)| geom.strain(tet.map(|n| displacement[n as usize])))
            .collect()
    }

    /// The Cauchy stress of every tetra for nodal `displacement`.
    pub fn tet_stress(&self, displacement: &[Vector3<f64>]) -> Vec<Matrix3<f64>> {
        self.tet_strain(displacement)
            .iter()
            .map(|e| self.material.stress(e))
            .collect()
    }

    /// Elastic nodal forces K u of the whole (unconstrained) mesh, gathered per node.
    pub fn internal_forces(&self, displacement: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let (lambda, mu) = (self.material.lame_lambda(), self.material.shear_modulus());
        let g = &self.graph;
        (0..self.nodes.len())
            .into_par_iter()
            .with_min_len(256)
            .map(|n| {
                let mut force = Vector3::zeros();
                for &(t, a) in &g.node_tets[g.tet_ptr[n]..g.tet_ptr[n + 1]] {
                    let geom = &self.geometry[t as usize];
                    for (b, &m) in self.tets[t as usize].iter().enumerate() {
                        force += geom.stiffness_block(a as usize, b, lambda, mu)
                            * displacement[m as usize];
                    }
                }
                force
            })
            .collect()
    }

    fn assemble_stiffness(&self, pattern: &ReducedPattern, dofs: &DofMap) -> Vec<f64> {
        let (lambda, mu) = (self.material.lame_lambda(), self.material.shear_modulus());
        pattern.assemble(&self.graph, dofs, &self.tets, |t, a, b| {
            self.geometry[t].stiffness_block(a, b, lambda, mu)
        })
    }

    fn assemble_mass(&self, pattern: &ReducedPattern, dofs: &DofMap, kind: MassKind) -> Vec<f64> {
        let rho = self.material.density;
        match kind {
            MassKind::Consistent => pattern.assemble(&self.graph, dofs, &self.tets, |t, a, b| {
                Matrix3::identity() * self.geometry[t].consistent_mass(a, b, rho)
            }),
            MassKind::Lumped => pattern.assemble(&self.graph, dofs, &self.tets, |t, a, b| {
                if a == b {
                    Matrix3::identity() * self.geometry[t].lumped_mass(rho)
                } else {
                    Matrix3::zeros()
                }
            }),
        }
    }
}

/// A model with its Dirichlet set eliminated: the assembled stiffness on the free DOFs,
/// its ordering and symbolic factor, and (once computed) the numeric factor of K.
#[derive(Debug)]
pub struct FemSystem<'m> {
    model: &'m FemModel,
    dofs: DofMap,
    pattern: ReducedPattern,
    stiffness: Vec<f64>,
    springs: Option<Springs>,
    symbolic: SymbolicFactor,
    stiffness_factor: Option<Factor>,
    anchored: bool,
    setup_times: PhaseTimes,
}

impl FemSystem<'_> {
    /// The number of free DOFs (unknowns).
    pub fn free_dof_count(&self) -> usize {
        self.dofs.free_count()
    }

    /// Stored entries of the reduced stiffness matrix (both triangles).
    pub fn matrix_nnz(&self) -> usize {
        self.pattern.nnz()
    }

    /// Stored entries of the Cholesky factor.
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.factor_nnz()
    }

    /// Whether the fixed DOFs and springs remove the six rigid-body motions of every
    /// connected part of the mesh (K is then positive definite).
    pub fn is_anchored(&self) -> bool {
        self.anchored
    }

    /// Times spent building this system (assembly and ordering).
    pub fn setup_times(&self) -> PhaseTimes {
        self.setup_times
    }

    /// Factorises K once (kept for later solves); the time is added to `times`.
    fn stiffness_factor(&mut self, times: &mut PhaseTimes) -> Result<&Factor> {
        if self.stiffness_factor.is_none() {
            let start = Instant::now();
            let factor = Factor::new(&self.symbolic, &self.pattern, &self.stiffness)?;
            times.factorisation_s += seconds_since(start);
            match factor {
                Some(factor) => self.stiffness_factor = Some(factor),
                None => {
                    return Err(Error::Message(
                        "fem: the stiffness matrix is not positive definite: the fixed DOFs \
                         (and springs) do not remove every rigid-body motion"
                            .into(),
                    ))
                }
            }
        }
        Ok(self
            .stiffness_factor
            .as_ref()
            .expect("factor just computed"))
    }
}
