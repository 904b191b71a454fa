//! Dirichlet conditions by elimination: a set of prescribed DOFs and the map between the
//! full DOF numbering (3·node + component) and the reduced (free) numbering.

use nalgebra::Vector3;
use std::collections::BTreeMap;

/// Prescribed displacement components: (node, component 0..3) → value in metres.
/// Fixed DOFs are removed from the system; a non-zero value moves its load to the right
/// hand side of the free DOFs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DofSet {
    values: BTreeMap<(u32, u8), f64>,
}

impl DofSet {
    /// No prescribed DOF (a free body).
    pub fn new() -> Self {
        Self::default()
    }

    /// All three components of every node in `nodes` held at zero (a clamp).
    pub fn clamped(nodes: &[u32]) -> Self {
        let mut set = Self::new();
        set.fix_nodes(nodes);
        set
    }

    /// Holds all three components of `nodes` at zero.
    pub fn fix_nodes(&mut self, nodes: &[u32]) {
        for &node in nodes {
            self.prescribe_node(node, Vector3::zeros());
        }
    }

    /// Holds component `component` (0 = x, 1 = y, 2 = z) of `node` at `value`.
    ///
    /// # Panics
    /// If `component > 2` (a programming error, not an input error).
    pub fn prescribe(&mut self, node: u32, component: usize, value: f64) {
        assert!(component < 3, "component {component} is not 0, 1 or 2");
        self.values.insert((node, component as u8), value);
    }

    /// Prescribes the whole displacement of `node`.
    pub fn prescribe_node(&mut self, node: u32, displacement: Vector3<f64>) {
        for c in 0..3 {
            self.prescribe(node, c, displacement[c]);
        }
    }

    /// The number of prescribed components.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether no component is prescribed.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// The prescribed (node, component, value) triples in (node, component) order.
    pub fn iter(&self) -> impl Iterator<Item = (u32, usize, f64)> + '_ {
        self.values.iter().map(|(&(n, c), &v)| (n, c as usize, v))
    }

    /// The largest node index named, if any.
    pub fn max_node(&self) -> Option<u32> {
        self.values.keys().next_back().map(|&(n, _)| n)
    }
}

/// Marks a full DOF that is prescribed (not in the reduced system).
pub(crate) const FIXED: u32 = u32::MAX;

/// The full ↔ reduced DOF numbering for one [`DofSet`]. Reduced indices follow the full
/// order, so a node's free components stay contiguous and sorted.
#[derive(Debug, Clone)]
pub(crate) struct DofMap {
    /// Reduced index of each full DOF, or [`FIXED`].
    pub reduced: Vec<u32>,
    /// Full DOF of each reduced index.
    pub full: Vec<u32>,
    /// Prescribed value of each full DOF (0 for free DOFs).
    pub prescribed: Vec<f64>,
    /// Whether any prescribed value is non-zero.
    pub has_nonzero: bool,
}

impl DofMap {
    pub fn new(node_count: usize, fixed: &DofSet) -> Self {
        let dof_count = 3 * node_count;
        let mut prescribed = vec![0.0; dof_count];
        let mut is_fixed = vec![false; dof_count];
        let mut has_nonzero = false;
        for (node, c, value) in fixed.iter() {
            let dof = 3 * node as usize + c;
            is_fixed[dof] = true;
            prescribed[dof] = value;
            has_nonzero |= value != 0.0;
        }
        let mut reduced = vec![FIXED; dof_count];
        let mut full = Vec::with_capacity(dof_count - fixed.len());
        for dof in 0..dof_count {
            if !is_fixed[dof] {
                reduced[dof] = full.len() as u32;
                full.push(dof as u32);
            }
        }
        DofMap {
            reduced,
            full,
            prescribed,
            has_nonzero,
        }
    }

    /// The number of free DOFs.
    pub fn free_count(&self) -> usize {
        self.full.len()
    }

    /// Scatters a reduced vector into full nodal vectors; fixed DOFs get their values.
    pub fn expand(&self, reduced: &[f64]) -> Vec<Vector3<f64>> {
        let mut out: Vec<Vector3<f64>> = self
            .prescribed
            .chunks_exact(3)
            .map(|c| Vector3::new(c[0], c[1], c[2]))
            .collect();
        for (r, &dof) in self.full.iter().enumerate() {
            out[dof as usize / 3][dof as usize % 3] = reduced[r];
        }
        out
    }

    /// The prescribed values as nodal vectors (zero at free DOFs).
    pub fn expand_homogeneous_fixed(&self) -> Vec<Vector3<f64>> {
        self.prescribed
            .chunks_exact(3)
            .map(|c| Vector3::new(c[0], c[1], c[2]))
            .collect()
    }

    /// Scatters a reduced vector into full nodal vectors with zero at fixed DOFs.
    pub fn expand_homogeneous(&self, reduced: &[f64]) -> Vec<Vector3<f64>> {
        let mut out = vec![Vector3::zeros(); self.prescribed.len() / 3];
        for (r, &dof) in self.full.iter().enumerate() {
            out[dof as usize / 3][dof as usize % 3] = reduced[r];
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduced_numbering_skips_fixed_dofs_in_order() {
        let mut fixed = DofSet::clamped(&[1]);
        fixed.prescribe(2, 2, 0.5);
        let map = DofMap::new(3, &fixed);
        assert_eq!(map.free_count(), 5);
        assert_eq!(map.full, vec![0, 1, 2, 6, 7]);
        assert_eq!(map.reduced[3], FIXED);
        assert_eq!(map.reduced[6], 3);
        assert!(map.has_nonzero);
        let u = map.expand(&[1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(u[0], Vector3::new(1.0, 2.0, 3.0));
        assert_eq!(u[1], Vector3::zeros());
        assert_eq!(u[2], Vector3::new(4.0, 5.0, 0.5));
    }
}
