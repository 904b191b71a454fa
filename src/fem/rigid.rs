//! Rigid-body motions: whether the supports of a model remove all six of them from every
//! connected part of the mesh (then K is positive definite and σ = 0 is a safe shift).

use super::{DofSet, FemModel, Springs};
use nalgebra::{Matrix3, Matrix6, SMatrix, Vector3, Vector6};

/// The six rigid modes at `x` about `centre`, rotations scaled by 1/`length` so that all
/// columns have comparable size: a 3×6 matrix [I | −[r]× / L].
fn rigid_modes_at(x: &Vector3<f64>, centre: &Vector3<f64>, length: f64) -> SMatrix<f64, 3, 6> {
    let r = (x - centre) / length;
    let mut modes = SMatrix::<f64, 3, 6>::zeros();
    modes
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::identity());
    for k in 0..3 {
        let axis = Vector3::ith(k, 1.0);
        modes.set_column(3 + k, &axis.cross(&r));
    }
    modes
}

/// Connected parts of the mesh (tetra sharing a node), as a part index per node.
fn node_parts(node_count: usize, tets: &[[u32; 4]]) -> (Vec<usize>, usize) {
    let mut parent: Vec<usize> = (0..node_count).collect();
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for tet in tets {
        let root = find(&mut parent, tet[0] as usize);
        for &n in &tet[1..] {
            let other = find(&mut parent, n as usize);
            if other != root {
                parent[other] = root;
            }
        }
    }
    let mut label = vec![usize::MAX; node_count];
    let mut part = vec![0; node_count];
    let mut count = 0;
    for (n, part) in part.iter_mut().enumerate() {
        let root = find(&mut parent, n);
        if label[root] == usize::MAX {
            label[root] = count;
            count += 1;
        }
        *part = label[root];
    }
    (part, count)
}

/// Whether `fixed` and `springs` restrain the six rigid motions of every connected part.
pub(crate) fn is_anchored(model: &FemModel, fixed: &DofSet, springs: Option<&Springs>) -> bool {
    let nodes = model.nodes();
    let (part, count) = node_parts(nodes.len(), model.tets());
    let mut lower = vec![Vector3::repeat(f64::INFINITY); count];
    let mut upper = vec![Vector3::repeat(f64::NEG_INFINITY); count];
    for (n, x) in nodes.iter().enumerate() {
        lower[part[n]] = lower[part[n]].inf(&x.coords);
        upper[part[n]] = upper[part[n]].sup(&x.coords);
    }
    let centre: Vec<Vector3<f64>> = (0..count).map(|p| (lower[p] + upper[p]) * 0.5).collect();
    let length: Vec<f64> = (0..count)
        .map(|p| (upper[p] - lower[p]).norm().max(f64::MIN_POSITIVE))
        .collect();
    let modes = |n: usize| rigid_modes_at(&nodes[n].coords, &centre[part[n]], length[part[n]]);
    let mut gram = vec![Matrix6::<f64>::zeros(); count];
    for (node, c, _) in fixed.iter() {
        let row: Vector6<f64> = modes(node as usize).row(c).transpose();
        gram[part[node as usize]] += row * row.transpose();
    }
    if let Some(springs) = springs {
        let largest = springs.iter().map(|(_, b)| b.norm()).fold(0.0, f64::max);
        if largest > 0.0 {
            for (node, block) in springs.iter() {
                let r = modes(node as usize);
                gram[part[node as usize]] += r.transpose() * (block / largest) * r;
            }
        }
    }
    gram.iter().all(|g| {
        let eig = g.symmetric_eigenvalues();
        let max = eig.max();
        max > 0.0 && eig.min() > 1e-9 * max
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_are_found() {
        let tets = [[0, 1, 2, 3], [4, 5, 6, 7], [3, 8, 9, 10]];
        let (part, count) = node_parts(11, &tets);
        assert_eq!(count, 2);
        assert_eq!(part[8], part[0]);
        assert_ne!(part[4], part[0]);
    }
}
