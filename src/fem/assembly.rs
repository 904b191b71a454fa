//! Sparse assembly: the node graph of the mesh, the reduced (free-DOF) pattern of a
//! symmetric matrix stored with both triangles in compressed columns, and a parallel,
//! deterministic owner-gathers assembly (each node fills its own columns).

use super::dirichlet::{DofMap, FIXED};

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use nalgebra::Matrix3;
use rayon::prelude::*;

/// Node adjacency of a tetrahedral mesh: the tetra around each node and the sorted
/// neighbour list of each node (itself included).
#[derive(Debug, Clone)]
pub(crate) struct NodeGraph {
    /// `node_tets[tet_ptr[n]..tet_ptr[n + 1]]` = (tetra, local vertex) pairs of node n.
    pub tet_ptr: Vec<usize>,
    pub node_tets: Vec<(u32, u8)>,
    /// `neighbours[nbr_ptr[n]..nbr_ptr[n + 1]]` = sorted nodes sharing a tetra with n.
    pub nbr_ptr: Vec<usize>,
    pub neighbours: Vec<u32>,
}

impl NodeGraph {
    pub fn new(node_count: usize, tets: &[[u32; 4]]) -> Self {
        let mut tet_ptr = vec![0usize; node_count + 1];
        for tet in tets {
            for &n in tet {
                tet_ptr[n as usize + 1] += 1;
            }
        }
        for n in 0..node_count {
            tet_ptr[n + 1] += tet_ptr[n];
        }
        let mut fill = tet_ptr.clone();
        let mut node_tets = vec![(0u32, 0u8); tet_ptr[node_count]];
        for (t, tet) in tets.iter().enumerate() {
            for (a, &n) in tet.iter().enumerate() {
                node_tets[fill[n as usize]] = (t as u32, a as u8);
                fill[n as usize] += 1;
            }
        }
        let lists: Vec<Vec<u32>> = (0..node_count)
            .into_par_iter()
            .with_min_len(256)
            .map(|n| {
                let mut list: Vec<u32> = node_tets[tet_ptr[n]..tet_ptr[n + 1]]
                    .iter()
                    .flat_map(|&(t, _)| tets[t as usize])
                    .collect();
                list.push(n as u32);
                list.sort_unstable();
                list.dedup();
                list
            })
            .collect();
        let mut nbr_ptr = Vec::with_capacity(node_count + 1);
        nbr_ptr.push(0);
        for list in &lists {
            nbr_ptr.push(nbr_ptr.last().unwrap() + list.len());
        }
        let neighbours = lists.concat();
        NodeGraph {
            tet_ptr,
            node_tets,
            nbr_ptr,
            neighbours,
        }
    }

    pub fn node_count(&self) -> usize {
        self.tet_ptr.len() - 1
    }

    pub fn neighbours_of(&self, n: usize) -> &[u32] {
        &self.neighbours[self.nbr_ptr[n]..self.nbr_ptr[n + 1]]
    }
}

/// The compressed-column pattern of a symmetric matrix on the free DOFs (both
/// triangles stored). All columns of one node share the same row list.
#[derive(Debug, Clone)]
pub(crate) struct ReducedPattern {
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
    /// First reduced column of each node (length nodes + 1).
    pub node_col: Vec<usize>,
    /// For each entry of `NodeGraph::neighbours`: offset of that neighbour's rows within
    /// the owning node's columns.
    pub nbr_offset: Vec<u32>,
}

impl ReducedPattern {
    pub fn new(graph: &NodeGraph, dofs: &DofMap) -> Self {
        let node_count = graph.node_count();
        let mut node_col = Vec::with_capacity(node_count + 1);
        node_col.push(0usize);
        for n in 0..node_count {
            let free = (0..3).filter(|&c| dofs.reduced[3 * n + c] != FIXED).count();
            node_col.push(node_col[n] + free);
        }
        let free_of = |n: usize| node_col[n + 1] - node_col[n];
        let mut nbr_offset = vec![0u32; graph.neighbours.len()];
        let mut col_ptr = Vec::with_capacity(dofs.free_count() + 1);
        col_ptr.push(0usize);
        let mut row_idx = Vec::new();
        for n in 0..node_count {
            let range = graph.nbr_ptr[n]..graph.nbr_ptr[n + 1];
            let mut offset = 0u32;
            let mut rows = Vec::new();
            for (slot, &m) in range.clone().zip(&graph.neighbours[range]) {
                nbr_offset[slot] = offset;
                let m = m as usize;
                offset += free_of(m) as u32;
                rows.extend(node_col[m]..node_col[m + 1]);
            }
            for _ in 0..free_of(n) {
                row_idx.extend_from_slice(&rows);
                col_ptr.push(row_idx.len());
            }
        }
        ReducedPattern {
            col_ptr,
            row_idx,
            node_col,
            nbr_offset,
        }
    }

    pub fn dim(&self) -> usize {
        self.col_ptr.len() - 1
    }

    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    pub fn symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        SymbolicSparseColMatRef::new_checked(
            self.dim(),
            self.dim(),
            &self.col_ptr,
            None,
            &self.row_idx,
        )
    }

    pub fn view<'a>(&'a self, values: &'a [f64]) -> SparseColMatRef<'a, usize, f64> {
        SparseColMatRef::new(self.symbolic(), values)
    }

    /// The value slices of every node's columns, in node order (disjoint).
    fn node_slices<'a>(&self, values: &'a mut [f64]) -> Vec<&'a mut [f64]> {
        let node_count = self.node_col.len() - 1;
        let mut slices = Vec::with_capacity(node_count);
        let mut rest = values;
        for n in 0..node_count {
            let len = self.col_ptr[self.node_col[n + 1]] - self.col_ptr[self.node_col[n]];
            let (head, tail) = rest.split_at_mut(len);
            slices.push(head);
            rest = tail;
        }
        slices
    }

    /// Assembles Σ_e blocks: `block(tet, a, b)` is the 3×3 coupling of vertex `a` (rows)
    /// with vertex `b` (columns) of tetra `tet`. Fixed DOFs are skipped. Each node sums
    /// its own columns in a fixed order, so the result does not depend on the threads.
    pub fn assemble<F>(
        &self,
        graph: &NodeGraph,
        dofs: &DofMap,
        tets: &[[u32; 4]],
        block: F,
    ) -> Vec<f64>
    where
        F: Fn(usize, usize, usize) -> Matrix3<f64> + Sync,
    {
        let mut values = vec![0.0; self.nnz()];
        let slices = self.node_slices(&mut values);
        slices
            .into_par_iter()
            .enumerate()
            .with_min_len(64)
            .for_each(|(j, slice)| {
                let col_count = self.node_col[j + 1] - self.node_col[j];
                if col_count == 0 {
                    return;
                }
                let col_len = slice.len() / col_count;
                let nbrs = graph.neighbours_of(j);
                let nbr_base = graph.nbr_ptr[j];
                let col_comps: Vec<usize> = (0..3)
                    .filter(|&c| dofs.reduced[3 * j + c] != FIXED)
                    .collect();
                for &(t, b) in &graph.node_tets[graph.tet_ptr[j]..graph.tet_ptr[j + 1]] {
                    let tet = tets[t as usize];
                    for (a, &i) in tet.iter().enumerate() {
                        let slot = nbrs.binary_search(&i).expect("neighbour in graph");
                        let offset = self.nbr_offset[nbr_base + slot] as usize;
                        let k = block(t as usize, a, b as usize);
                        let i = i as usize;
                        for ci in 0..3 {
                            let r = dofs.reduced[3 * i + ci];
                            if r == FIXED {
                                continue;
                            }
                            let row = offset + (r as usize - self.node_col[i]);
                            for (local_col, &cj) in col_comps.iter().enumerate() {
                                slice[local_col * col_len + row] += k[(ci, cj)];
                            }
                        }
                    }
                }
            });
        values
    }

    /// Adds a 3×3 block on the diagonal block of `node` (fixed components skipped).
    pub fn add_node_block(
        &self,
        graph: &NodeGraph,
        dofs: &DofMap,
        values: &mut [f64],
        node: usize,
        block: &Matrix3<f64>,
    ) {
        let nbrs = graph.neighbours_of(node);
        let slot = nbrs
            .binary_search(&(node as u32))
            .expect("node is its own neighbour");
        let offset = self.nbr_offset[graph.nbr_ptr[node] + slot] as usize;
        for cj in 0..3 {
            let col = dofs.reduced[3 * node + cj];
            if col == FIXED {
                continue;
            }
            let start = self.col_ptr[col as usize];
            for ci in 0..3 {
                let r = dofs.reduced[3 * node + ci];
                if r == FIXED {
                    continue;
                }
                values[start + offset + (r as usize - self.node_col[node])] += block[(ci, cj)];
            }
        }
    }

    /// y = A x for the symmetric matrix with `values` (columns read as rows).
    pub fn mul_vec(&self, values: &[f64], x: &[f64], y: &mut [f64]) {
        y.par_iter_mut()
            .enumerate()
            .with_min_len(512)
            .for_each(|(c, yc)| {
                let range = self.col_ptr[c]..self.col_ptr[c + 1];
                *yc = self.row_idx[range.clone()]
                    .iter()
                    .zip(&values[range])
                    .map(|(&r, &v)| v * x[r])
                    .sum();
            });
    }

    /// The diagonal of the matrix with `values`.
    pub fn diagonal(&self, values: &[f64]) -> Vec<f64> {
        (0..self.dim())
            .map(|c| {
                let range = self.col_ptr[c]..self.col_ptr[c + 1];
                let p = self.row_idx[range.clone()]
                    .binary_search(&c)
                    .expect("diagonal entry in pattern");
                values[range.start + p]
            })
            .collect()
    }
}
