//! Elastic foundations: nodal 3×3 spring blocks, e.g. a Winkler bed under a surface
//! group (normal stiffness per unit area lumped on the nodes by tributary area).

use nalgebra::{Matrix3, Point3};
use std::collections::BTreeMap;

/// Grounded springs: a symmetric positive semi-definite 3×3 stiffness (N/m) per node,
/// added to the diagonal blocks of K.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Springs {
    blocks: BTreeMap<u32, Matrix3<f64>>,
}

impl Springs {
    /// No springs.
    pub fn new() -> Self {
        Self::default()
    }

    /// A Winkler foundation under the surface `triangles` (node indices into `nodes`):
    /// each triangle of area A and unit normal n gives each of its three nodes
    /// (A / 3) · `k_per_area` · n nᵀ, so the bed resists normal motion only and its
    /// total stiffness is `k_per_area` × area for a flat surface.
    /// `k_per_area` is the bed modulus in N/m³ (Pa/m).
    pub fn winkler(nodes: &[Point3<f64>], triangles: &[[u32; 3]], k_per_area: f64) -> Self {
        let mut springs = Self::new();
        springs.add_winkler(nodes, triangles, k_per_area);
        springs
    }

    /// Adds a Winkler bed (see [`Springs::winkler`]).
    pub fn add_winkler(&mut self, nodes: &[Point3<f64>], triangles: &[[u32; 3]], k_per_area: f64) {
        for tri in triangles {
            let [a, b, c] = tri.map(|n| nodes[n as usize]);
            let cross = (b - a).cross(&(c - a));
            let double_area = cross.norm();
            if double_area == 0.0 {
                continue;
            }
            let normal = cross / double_area;
            let block = normal * normal.transpose() * (k_per_area * double_area / 6.0);
            for &n in tri {
                self.add_block(n, block);
            }
        }
    }

    /// Adds a 3×3 spring block at `node`.
    pub fn add_block(&mut self, node: u32, block: Matrix3<f64>) {
        *self.blocks.entry(node).or_insert_with(Matrix3::zeros) += block;
    }

    /// The per-node blocks in node order.
    pub fn iter(&self) -> impl Iterator<Item = (u32, &Matrix3<f64>)> + '_ {
        self.blocks.iter().map(|(&n, b)| (n, b))
    }

    /// Whether there is no spring.
    pub fn is_empty(&self) -> bool {
        self.blocks.is_empty()
    }

    /// The largest node index named, if any.
    pub fn max_node(&self) -> Option<u32> {
        self.blocks.keys().next_back().copied()
    }

    /// The sum of all blocks (for a flat bed: `k_per_area` × area × n nᵀ).
    pub fn total(&self) -> Matrix3<f64> {
        self.blocks.values().sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_bed_total_is_modulus_times_area_in_the_normal_direction() {
        let nodes = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(2.0, 0.0, 0.0),
            Point3::new(2.0, 0.5, 0.0),
            Point3::new(0.0, 0.5, 0.0),
        ];
        let triangles = [[0, 2, 1], [0, 3, 2]];
        let springs = Springs::winkler(&nodes, &triangles, 1e8);
        let total = springs.total();
        assert!((total[(2, 2)] - 1e8 * 1.0).abs() < 1e-6);
        assert!(total[(0, 0)].abs() < 1e-9 && total[(1, 1)].abs() < 1e-9);
        // Node 0 and 2 touch both triangles: 2 × (0.5 / 3) of the area.
        let node0 = springs.iter().next().unwrap().1;
        assert!((node0[(2, 2)] - 1e8 / 3.0).abs() < 1e-6);
    }
}
