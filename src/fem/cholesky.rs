//! Sparse Cholesky (faer) with a fill-reducing ordering computed once per pattern:
//! approximate minimum degree on the node graph (3× smaller than the DOF graph),
//! expanded to the free DOFs of each node. The symbolic factorisation is shared by every
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
use std::sync::Arc;

/// The ordering and symbolic Cholesky factor of one reduced pattern.
#[derive(Debug, Clone)]
pub(crate) struct SymbolicFactor {
    inner: Arc<SymbolicCholesky<usize>>,
}

impl SymbolicFactor {
    pub fn new(graph: &NodeGraph, pattern: &ReducedPattern) -> Result<Self> {
        let fwd = dof_ordering(graph, pattern)?;
        let mut inv = vec![0usize; fwd.len()];
        for (new, &old) in fwd.iter().enumerate() {
            inv[old] = new;
        }
        let perm = PermRef::new_checked(&fwd, &inv, fwd.len());
        let inner = factorize_symbolic_cholesky(
            pattern.symbolic(),
            Side::Lower,
            SymmetricOrdering::Custom(perm),
            Default::default(),
        )
        .map_err(|e| Error::Message(format!("fem: symbolic Cholesky failed: {e:?}")))?;
        Ok(SymbolicFactor {
            inner: Arc::new(inner),
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

/// AMD on the graph of the nodes that keep a free DOF, expanded node by node to the
/// free DOFs: the forward permutation (new position → reduced DOF).
fn dof_ordering(graph: &NodeGraph, pattern: &ReducedPattern) -> Result<Vec<usize>> {
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
    let m = active.len();
    let node_graph = SymbolicSparseColMatRef::new_checked(m, m, &col_ptr, None, &row_idx);
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
    let mut fwd = Vec::with_capacity(pattern.dim());
    for &p in &perm {
        let n = active[p];
        fwd.extend(pattern.node_col[n]..pattern.node_col[n + 1]);
    }
    Ok(fwd)
}
