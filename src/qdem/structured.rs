//! A structured tetrahedral box built in memory, for tests and benchmarks (no gmsh).

use nalgebra::{Point3, Vector3};

/// A box [0, size] split into `cells` hexahedra, each cut into six tetra around its
/// main diagonal (Kuhn/Freudenthal split: conforming, all tetra positively oriented).
/// Node (i, j, k) has index i + (nx + 1)(j + (ny + 1) k).
pub fn structured_box(size: Vector3<f64>, cells: [usize; 3]) -> (Vec<Point3<f64>>, Vec<[u32; 4]>) {
    let [nx, ny, nz] = cells;
    let index = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
    let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                nodes.push(Point3::new(
                    size.x * i as f64 / nx as f64,
                    size.y * j as f64 / ny as f64,
                    size.z * k as f64 / nz as f64,
                ));
            }
        }
    }
    const PERMUTATIONS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut tets = Vec::with_capacity(6 * nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                for perm in PERMUTATIONS {
                    let mut corner = [i, j, k];
                    let mut tet = [index(i, j, k), 0, 0, 0];
                    for (step, &axis) in perm.iter().enumerate() {
                        corner[axis] += 1;
                        tet[step + 1] = index(corner[0], corner[1], corner[2]);
                    }
                    let p = tet.map(|n| nodes[n as usize]);
                    let volume = (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(p[3] - p[0]));
                    if volume < 0.0 {
                        tet.swap(2, 3);
                    }
                    tets.push(tet);
                }
            }
        }
    }
    (nodes, tets)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn volumes_add_up_and_are_positive() {
        let (nodes, tets) = structured_box(Vector3::new(2.0, 1.0, 3.0), [3, 2, 4]);
        let mut total = 0.0;
        for t in &tets {
            let p = t.map(|n| nodes[n as usize]);
            let v = (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(p[3] - p[0])) / 6.0;
            assert!(v > 0.0);
            total += v;
        }
        assert!((total - 6.0).abs() < 1e-12);
    }
}
