//! Sparse Cholesky (faer) with a fill-reducing ordering computed once per pattern: the
//! sparser of geometric nested dissection and approximate minimum degree, both on the
//! node graph (3× smaller than the DOF graph) and expanded to the free DOFs of each node.
//! At the paper's resolution (96 000 nodes) dissection gives a factor 25 % smaller than
//! minimum degree. The symbolic factorisation is shared by every
//! numeric factorisation on the same pattern (K for statics, K − σM for modes).

use super::assembly::{NodeGraph, ReducedPattern};
use crate::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::SymbolicSparseColMatRef;
use faer::{Conj, MatMut, Side};
use nalgebra::Point3;
use std::sync::Arc;

/// The ordering and symbolic Cholesky factor of one reduced pattern.
#[derive(Debug, Clone)]
pub(crate) struct SymbolicFactor {
    inner: Arc<SymbolicCholesky<usize>>,
}

impl SymbolicFactor {
    /// Orders the free DOFs two ways — geometric nested dissection and approximate
    /// minimum degree, both on the node graph — and keeps the sparser factor.
    pub fn new(graph: &NodeGraph, pattern: &ReducedPattern, nodes: &[Point3<f64>]) -> Result<Self> {
        let (active, col_ptr, row_idx) = active_node_graph(graph, pattern);
        let coords: Vec<Point3<f64>> = active.iter().map(|&n| nodes[n]).collect();
        let dissection = nested_dissection(&coords, &col_ptr, &row_idx);
        let min_degree = minimum_degree(&col_ptr, &row_idx)?;
        let mut best: Option<SymbolicCholesky<usize>> = None;
        for node_order in [dissection, min_degree] {
            let candidate = symbolic_with(pattern, &expand_to_dofs(&node_order, &active, pattern))?;
            if best
                .as_ref()
                .is_none_or(|b| candidate.len_val() < b.len_val())
            {
                best = Some(candidate);
            }
        }
        Ok(SymbolicFactor {
            inner: Arc::new(best.expect("two candidates")),
        })
    }

    /// The number of stored entries of the Cholesky factor L.
    pub fn factor_nnz(&self) -> usize {
        self.inner.len_val()
    }
}

/// A numeric L Lᵀ factorisation.
#[derive(Debug)]
pub(crate) struct Factor {
    symbolic: SymbolicFactor,
    values: Vec<f64>,
}

impl Factor {
    /// Factorises the lower triangle of the matrix with `values` on `pattern`; `None`
    /// when it is not numerically positive definite.
    pub fn new(
        symbolic: &SymbolicFactor,
        pattern: &ReducedPattern,
        values: &[f64],
    ) -> Result<Option<Self>> {
        let inner = &symbolic.inner;
        let par = faer::get_global_parallelism();
        let mut l_values = vec![0.0; inner.len_val()];
        let mut mem =
            MemBuffer::try_new(inner.factorize_numeric_llt_scratch::<f64>(par, Default::default()))
                .map_err(|_| Error::Message("fem: out of memory for the Cholesky factor".into()))?;
        let outcome = inner.factorize_numeric_llt(
            &mut l_values,
            pattern.view(values),
            Side::Lower,
            Default::default(),
            par,
            MemStack::new(&mut mem),
            Default::default(),
        );
        let positive_definite = outcome.is_ok();
        Ok(positive_definite.then(|| Factor {
            symbolic: symbolic.clone(),
            values: l_values,
        }))
    }

    /// Overwrites the columns of `rhs` with the solutions.
    pub fn solve_in_place(&self, rhs: MatMut<'_, f64>) {
        let inner = &self.symbolic.inner;
        let par = faer::get_global_parallelism();
        let mut mem = MemBuffer::new(inner.solve_in_place_scratch::<f64>(rhs.ncols(), par));
        LltRef::new(inner, &self.values).solve_in_place_with_conj(
            Conj::No,
            rhs,
            par,
            MemStack::new(&mut mem),
        );
    }
}

/// The symbolic factor of `pattern` under the DOF order `fwd` (new → reduced DOF).
fn symbolic_with(pattern: &ReducedPattern, fwd: &[usize]) -> Result<SymbolicCholesky<usize>> {
    let mut inv = vec![0usize; fwd.len()];
    for (new, &old) in fwd.iter().enumerate() {
        inv[old] = new;
    }
    let perm = PermRef::new_checked(fwd, &inv, fwd.len());
    factorize_symbolic_cholesky(
        pattern.symbolic(),
        Side::Lower,
        SymmetricOrdering::Custom(perm),
        Default::default(),
    )
    .map_err(|e| Error::Message(format!("fem: symbolic Cholesky failed: {e:?}")))
}

/// The graph of the nodes that keep a free DOF: (their indices, column pointers, rows
/// in compact numbering).
fn active_node_graph(
    graph: &NodeGraph,
    pattern: &ReducedPattern,
) -> (Vec<usize>, Vec<usize>, Vec<usize>) {
    let node_count = graph.node_count();
    let free = |n: usize| pattern.node_col[n + 1] - pattern.node_col[n];
    let mut compact = vec![usize::MAX; node_count];
    let mut active = Vec::new();
    for (n, slot) in compact.iter_mut().enumerate() {
        if free(n) > 0 {
            *slot = active.len();
            active.push(n);
        }
    }
    let mut col_ptr = Vec::with_capacity(active.len() + 1);
    col_ptr.push(0usize);
    let mut row_idx = Vec::new();
    for &n in &active {
        row_idx.extend(
            graph
                .neighbours_of(n)
                .iter()
                .map(|&m| compact[m as usize])
                .filter(|&m| m != usize::MAX),
        );
        col_ptr.push(row_idx.len());
    }
    (active, col_ptr, row_idx)
}

/// A node order (new position → compact node) expanded to the free DOFs of each node.
fn expand_to_dofs(order: &[usize], active: &[usize], pattern: &ReducedPattern) -> Vec<usize> {
    let mut fwd = Vec::with_capacity(pattern.dim());
    for &p in order {
        let n = active[p];
        fwd.extend(pattern.node_col[n]..pattern.node_col[n + 1]);
    }
    fwd
}

/// Approximate minimum degree (faer's AMD) of the compact node graph.
fn minimum_degree(col_ptr: &[usize], row_idx: &[usize]) -> Result<Vec<usize>> {
    let m = col_ptr.len() - 1;
    let node_graph = SymbolicSparseColMatRef::new_checked(m, m, col_ptr, None, row_idx);
    let mut perm = vec![0usize; m];
    let mut perm_inv = vec![0usize; m];
    let mut mem = MemBuffer::try_new(amd::order_scratch::<usize>(m, row_idx.len()))
        .map_err(|_| Error::Message("fem: out of memory for the AMD ordering".into()))?;
    amd::order(
        &mut perm,
        &mut perm_inv,
        node_graph,
        amd::Control::default(),
        MemStack::new(&mut mem),
    )
    .map_err(|e| Error::Message(format!("fem: AMD ordering failed: {e:?}")))?;
    Ok(perm)
}

/// Subdomains at most this many nodes are not dissected further.
const LEAF_NODES: usize = 24;

/// Geometric nested dissection of a node graph: split at the median of the longest
/// bounding-box axis, take as separator the nodes of the smaller side that touch the
/// other side, order both halves recursively and the separator last.
/// Returns the order (new position → node).
fn nested_dissection(coords: &[Point3<f64>], col_ptr: &[usize], row_idx: &[usize]) -> Vec<usize> {
    let n = coords.len();
    let mut order = Vec::with_capacity(n);
    // side[v]: the subdomain stamp of v (0 or 1 while splitting); stamp marks membership.
    let mut side = vec![0u8; n];
    let mut stamp = vec![0u32; n];
    let mut next_stamp = 1u32;
    // Work list of (nodes, separator-to-append-after) in depth-first post-order.
    enum Task {
        Split(Vec<usize>),
        Emit(Vec<usize>),
    }
    let mut tasks = vec![Task::Split((0..n).collect())];
    while let Some(task) = tasks.pop() {
        let mut nodes = match task {
            Task::Emit(nodes) => {
                order.extend(nodes);
                continue;
            }
            Task::Split(nodes) => nodes,
        };
        if nodes.len() <= LEAF_NODES {
            order.extend(nodes);
            continue;
        }
        let mut lower = [f64::INFINITY; 3];
        let mut upper = [f64::NEG_INFINITY; 3];
        for &v in &nodes {
            for a in 0..3 {
                lower[a] = lower[a].min(coords[v][a]);
                upper[a] = upper[a].max(coords[v][a]);
            }
        }
        let axis = (0..3)
            .max_by(|&a, &b| (upper[a] - lower[a]).total_cmp(&(upper[b] - lower[b])))
            .unwrap_or(0);
        let half = nodes.len() / 2;
        nodes.select_nth_unstable_by(half, |&a, &b| coords[a][axis].total_cmp(&coords[b][axis]));
        let cut = coords[nodes[half]][axis];
        let current = next_stamp;
        next_stamp += 1;
        for &v in &nodes {
            stamp[v] = current;
            side[v] = u8::from(coords[v][axis] >= cut);
        }
        let touches = |v: usize, other: u8, side: &[u8], stamp: &[u32]| {
            row_idx[col_ptr[v]..col_ptr[v + 1]]
                .iter()
                .any(|&w| stamp[w] == current && side[w] == other)
        };
        let left_sep: Vec<usize> = nodes
            .iter()
            .copied()
            .filter(|&v| side[v] == 0 && touches(v, 1, &side, &stamp))
            .collect();
        let right_sep: Vec<usize> = nodes
            .iter()
            .copied()
            .filter(|&v| side[v] == 1 && touches(v, 0, &side, &stamp))
            .collect();
        let separator = if left_sep.len() <= right_sep.len() {
            left_sep
        } else {
            right_sep
        };
        for &v in &separator {
            side[v] = 2;
        }
        let left: Vec<usize> = nodes.iter().copied().filter(|&v| side[v] == 0).collect();
        let right: Vec<usize> = nodes.iter().copied().filter(|&v| side[v] == 1).collect();
        if left.is_empty() || right.is_empty() {
            // No progress (coincident coordinates): stop dissecting here.
            order.extend(nodes);
            continue;
        }
        tasks.push(Task::Emit(separator));
        tasks.push(Task::Split(right));
        tasks.push(Task::Split(left));
    }
    order
}
