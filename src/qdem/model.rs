//! The immutable QDEM model: reference geometry, per-tetra D_m⁻¹ and V_0, materials,
//! quarter-volume lumped masses (seed 004 §2.4) and the block colouring of the tetra.

use super::colouring::BlockColouring;
use super::element::{element_stress, reference_inverse, sym_to_matrix};
use super::element::{ElementSums, Vec3};
use super::kernel::{self, Force4, Inputs, TetBatch, TetElement, LANES};
use super::material::{ElementMaterial, QdemMaterial};
use super::stability::StableTimeStep;
use crate::mesh::TetMesh;
use crate::mesh::{bounds, morton_key};
use crate::{Error, Result};
use nalgebra::{Matrix3, Point3};
use std::sync::OnceLock;

/// A tetrahedral body ready for explicit QDEM stepping. Tetra are stored internally in
/// Morton order (for cache locality and the block colouring); every public per-tetra
/// result is in the caller's original order.
#[derive(Debug)]
pub struct QdemModel {
    reference: Vec<Vec3>,
    /// The tetra in internal order, [`LANES`] per batch (what the hot loop streams).
    batches: Vec<TetBatch>,
    tet_count: usize,
    /// Internal element index → original tetra index.
    element_tet: Vec<u32>,
    pub(crate) materials: Vec<ElementMaterial>,
    material_inputs: Vec<QdemMaterial>,
    pub(crate) node_mass: Vec<f64>,
    pub(crate) colouring: BlockColouring,
    min_altitude: f64,
    pub(crate) stable: OnceLock<StableTimeStep>,
}

impl QdemModel {
    /// A single-material model. Errors name the tetra or node at fault (0-based).
    pub fn new(nodes: &[Point3<f64>], tets: &[[u32; 4]], material: &QdemMaterial) -> Result<Self> {
        Self::with_materials(
            nodes,
            tets,
            std::slice::from_ref(material),
            &vec![0; tets.len()],
        )
    }

    /// A model with one material per tetra: `tet_material[t]` indexes `materials`.
    pub fn with_materials(
        nodes: &[Point3<f64>],
        tets: &[[u32; 4]],
        materials: &[QdemMaterial],
        tet_material: &[u32],
    ) -> Result<Self> {
        let fail = |what: String| Err(Error::Message(format!("QDEM model: {what}")));
        if tets.is_empty() {
            return fail("the mesh has no tetrahedra".into());
        }
        if tet_material.len() != tets.len() {
            return fail(format!(
                "{} material indices for {} tetrahedra",
                tet_material.len(),
                tets.len()
            ));
        }
        for (i, m) in materials.iter().enumerate() {
            m.validate()
                .map_err(|e| Error::Message(format!("QDEM model: material {i}: {e}")))?;
        }
        let reference: Vec<Vec3> = nodes.iter().map(|p| [p.x, p.y, p.z]).collect();
        if let Some(n) = reference
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite()))
        {
            return fail(format!("node {n} has a non-finite coordinate"));
        }
        let (lo, size) = bounds(reference.iter().copied());
        let mut node_mass = vec![0.0; nodes.len()];
        let mut records = Vec::with_capacity(tets.len());
        let mut min_altitude = f64::INFINITY;
        for (t, tet) in tets.iter().enumerate() {
            if let Some(&n) = tet.iter().find(|&&n| n as usize >= nodes.len()) {
                return fail(format!(
                    "tetra {t} refers to node {n}, but there are only {} nodes",
                    nodes.len()
                ));
            }
            let material = tet_material[t];
            if material as usize >= materials.len() {
                return fail(format!(
                    "tetra {t} has material {material}, but there are only {} materials",
                    materials.len()
                ));
            }
            let x = tet.map(|n| reference[n as usize]);
            let Some((dm_inv, ref_volume)) = reference_inverse(x) else {
                return fail(format!(
                    "tetra {t} (nodes {tet:?}) is flat or inverted (volume ≤ 0)"
                ));
            };
            // Altitude h_k = 1/|∇N_k|, the smallest over the four vertices.
            let mut grad0 = [0.0; 3];
            for row in &dm_inv {
                let g = (row[0] * row[0] + row[1] * row[1] + row[2] * row[2]).sqrt();
                min_altitude = min_altitude.min(1.0 / g);
                for d in 0..3 {
                    grad0[d] -= row[d];
                }
            }
            let g0 = (grad0[0] * grad0[0] + grad0[1] * grad0[1] + grad0[2] * grad0[2]).sqrt();
            min_altitude = min_altitude.min(1.0 / g0);
            let quarter = 0.25 * materials[material as usize].density * ref_volume;
            for &n in tet {
                node_mass[n as usize] += quarter;
            }
            let centroid = [0, 1, 2].map(|d| 0.25 * (x[0][d] + x[1][d] + x[2][d] + x[3][d]));
            records.push((
                morton_key(centroid, lo, size),
                t as u32,
                TetElement {
                    dm_inv,
                    ref_volume,
                    material,
                },
            ));
        }
        if let Some(n) = node_mass.iter().position(|&m| m == 0.0) {
            return fail(format!(
                "node {n} belongs to no tetra (it would have no mass)"
            ));
        }
        records.sort_unstable_by_key(|r| (r.0, r.1));
        let element_tet: Vec<u32> = records.iter().map(|r| r.1).collect();
        let element_nodes: Vec<[u32; 4]> = element_tet.iter().map(|&t| tets[t as usize]).collect();
        let elements: Vec<TetElement> = records.into_iter().map(|r| r.2).collect();
        let batches = element_nodes
            .chunks(LANES)
            .zip(elements.chunks(LANES))
            .map(|(n, e)| TetBatch::pack(n, e))
            .collect();
        let colouring = BlockColouring::new(element_nodes, nodes.len());
        Ok(QdemModel {
            reference,
            batches,
            tet_count: elements.len(),
            element_tet,
            materials: materials.iter().map(ElementMaterial::from).collect(),
            material_inputs: materials.to_vec(),
            node_mass,
            colouring,
            min_altitude,
            stable: OnceLock::new(),
        })
    }

    /// A single-material model of a checked [`TetMesh`].
    pub fn from_mesh(mesh: &TetMesh, material: &QdemMaterial) -> Result<Self> {
        Self::new(&mesh.nodes, &mesh.tets, material)
    }

    /// Number of nodes (particles).
    pub fn node_count(&self) -> usize {
        self.reference.len()
    }

    /// Number of tetra.
    pub fn tet_count(&self) -> usize {
        self.tet_count
    }

    /// Tetra `e` of the internal order.
    pub(crate) fn element(&self, e: usize) -> TetElement {
        self.batches[e / LANES].element(e % LANES)
    }

    /// Reference node positions (m).
    pub fn reference_positions(&self) -> &[[f64; 3]] {
        &self.reference
    }

    /// Lumped nodal masses: a quarter of each incident tetra's mass (kg).
    pub fn node_masses(&self) -> &[f64] {
        &self.node_mass
    }

    /// The materials as given.
    pub fn materials(&self) -> &[QdemMaterial] {
        &self.material_inputs
    }

    /// Total mass (kg).
    pub fn total_mass(&self) -> f64 {
        self.node_mass.iter().sum()
    }

    /// The smallest altitude over all tetra (m).
    pub fn min_altitude(&self) -> f64 {
        self.min_altitude
    }

    /// Number of colours of the block colouring (a diagnostic of the parallel layout).
    pub fn colour_count(&self) -> usize {
        self.colouring.colours()
    }

    /// Internal (Kelvin–Voigt) nodal forces p_i of eq. 11 for positions `x` and
    /// velocities `v`, written into `forces` (overwritten). Returns the strain energy,
    /// the viscous dissipation rate and the number of inverted tetra.
    pub fn internal_forces(&self, x: &[Vec3], v: &[Vec3], forces: &mut [Vec3]) -> ElementTotals {
        let mut partials = vec![ElementSums::default(); self.colouring.blocks.len()];
        let mut padded = vec![Force4::default(); self.node_count()];
        let totals = self.internal_forces_with(x, v, &mut padded, &mut partials);
        assert_eq!(forces.len(), padded.len());
        for (f, p) in forces.iter_mut().zip(&padded) {
            *f = p.xyz();
        }
        totals
    }

    /// [`Self::internal_forces`] into padded node records, with caller-owned block
    /// partials (no allocation): the stepping path.
    pub(crate) fn internal_forces_with(
        &self,
        x: &[Vec3],
        v: &[Vec3],
        forces: &mut [Force4],
        partials: &mut [ElementSums],
    ) -> ElementTotals {
        let n = self.node_count();
        // The kernel's safety contract: every node index (< node_count, checked by the
        // colouring) is in bounds of x, v and forces.
        assert!(x.len() == n && v.len() == n && forces.len() == n);
        forces.fill(Force4::default());
        let inputs = Inputs {
            x,
            v,
            batches: &self.batches,
            materials: &self.materials,
        };
        let target = crate::qdem::colouring::ForceTarget::new(forces);
        self.colouring
            .run_blocks(partials, |block, sums: &mut ElementSums| {
                // SAFETY: indices in bounds (above); `run_blocks` gives the block's nodes
                // to this call alone.
                unsafe { kernel::block_forces(&inputs, block, &target, sums) }
            });
        let mut totals = ElementTotals::default();
        for (p, block) in partials.iter().zip(&self.colouring.blocks) {
            totals.strain_energy += p.strain_energy;
            totals.dissipation_rate += p.dissipation_rate;
            if p.inverted > 0 && totals.inverted == 0 {
                totals.first_inverted = self.first_inverted(x, block.clone());
            }
            totals.inverted += p.inverted as usize;
        }
        totals
    }

    fn first_inverted(&self, x: &[Vec3], block: std::ops::Range<usize>) -> Option<usize> {
        block
            .filter(|&e| {
                let p = self.colouring.nodes[e].map(|i| x[i as usize]);
                reference_inverse(p).is_none()
            })
            .map(|e| self.element_tet[e] as usize)
            .min()
    }

    /// Cauchy stress T = T_E + T_D (eq. 8) of every tetra, in the original tetra order.
    pub fn stresses(&self, x: &[Vec3], v: &[Vec3]) -> Vec<Matrix3<f64>> {
        let mut out = vec![Matrix3::zeros(); self.tet_count()];
        for (e, tet) in self.colouring.nodes.iter().enumerate() {
            let el = self.element(e);
            let xe = tet.map(|i| x[i as usize]);
            let ve = tet.map(|i| v[i as usize]);
            let st = element_stress(&xe, &ve, &el.dm_inv, &self.materials[el.material as usize]);
            out[self.element_tet[e] as usize] =
                sym_to_matrix(&st.elastic) + sym_to_matrix(&st.viscous);
        }
        out
    }

    /// Σ V_0 (λ + 2µ) over the tetra (J): the energy scale of a unit strain.
    pub(crate) fn modulus_volume(&self) -> f64 {
        (0..self.tet_count)
            .map(|e| {
                let el = self.element(e);
                let m = &self.materials[el.material as usize];
                el.ref_volume * (m.lambda + 2.0 * m.mu)
            })
            .sum()
    }

    /// The material of each internal element (for the stability estimate).
    pub(crate) fn element_material(&self, e: usize) -> &ElementMaterial {
        &self.materials[self.element(e).material as usize]
    }
}

/// Totals of one internal-force evaluation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ElementTotals {
    /// Strain energy Σ V_0 (λ/2 (tr ε)² + µ ε:ε) in J.
    pub strain_energy: f64,
    /// Viscous dissipation rate Σ V T_D : D in W.
    pub dissipation_rate: f64,
    /// Number of tetra with non-positive current volume.
    pub inverted: usize,
    /// The lowest original index of an inverted tetra, if any.
    pub first_inverted: Option<usize>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qdem::structured::structured_box;
    use nalgebra::Vector3;

    #[test]
    fn masses_sum_to_the_body_mass() {
        let (nodes, tets) = structured_box(Vector3::new(2.0, 1.0, 0.5), [4, 3, 2]);
        let m = QdemModel::new(&nodes, &tets, &QdemMaterial::elastic(2000.0, 1e9, 0.25)).unwrap();
        assert!((m.total_mass() / (2000.0 * 1.0) - 1.0).abs() < 1e-12);
        assert_eq!(m.tet_count(), 4 * 3 * 2 * 6);
    }

    #[test]
    fn bad_input_is_named() {
        let (nodes, mut tets) = structured_box(Vector3::new(1.0, 1.0, 1.0), [1, 1, 1]);
        tets[2].swap(0, 1);
        let e = QdemModel::new(&nodes, &tets, &QdemMaterial::elastic(1.0, 1.0, 0.2))
            .unwrap_err()
            .to_string();
        assert!(e.contains("tetra 2") && e.contains("inverted"), "{e}");
        tets[2] = [0, 1, 2, 99];
        let e = QdemModel::new(&nodes, &tets, &QdemMaterial::elastic(1.0, 1.0, 0.2))
            .unwrap_err()
            .to_string();
        assert!(e.contains("node 99"), "{e}");
    }
}
