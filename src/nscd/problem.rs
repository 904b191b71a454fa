//! The plain frictional-contact problem `u = W r + q`, Coulomb's law at every contact.
//!
//! W is stored as block-sparse rows of 3 × 3 blocks: one diagonal block per contact (kept
//! apart, the local solver needs it) and the off-diagonal blocks of each block row stored
//! contiguously (CSR), so one NLGS sweep reads W once, front to back.

/// A 3 × 3 block in row-major order: `[W_nn, W_nt, W_ns, W_tn, …]`.
pub type Block3 = [f64; 9];

/// The Delassus operator W (3nc × 3nc) as block-sparse rows of 3 × 3 blocks.
#[derive(Debug, Clone, PartialEq)]
pub struct DelassusBlocks {
    diagonal: Vec<Block3>,
    row_start: Vec<usize>,
    columns: Vec<u32>,
    off_diagonal: Vec<Block3>,
}

impl DelassusBlocks {
    /// Builds W for `contacts` contacts from `(block row, block column, block)` triplets;
    /// duplicates are summed, missing diagonal blocks are zero. Panics on an index out of
    /// range (callers check their input first).
    pub fn from_blocks(
        contacts: usize,
        blocks: impl IntoIterator<Item = (usize, usize, Block3)>,
    ) -> Self {
        let mut diagonal = vec![[0.0; 9]; contacts];
        let mut off: Vec<(usize, usize, Block3)> = Vec::new();
        for (row, col, block) in blocks {
            assert!(row < contacts && col < contacts, "block index out of range");
            if row == col {
                add_block(&mut diagonal[row], &block);
            } else {
                off.push((row, col, block));
            }
        }
        off.sort_by_key(|&(row, col, _)| (row, col));
        let mut row_start = vec![0usize; contacts + 1];
        let mut columns: Vec<u32> = Vec::with_capacity(off.len());
        let mut off_diagonal: Vec<Block3> = Vec::with_capacity(off.len());
        let mut rows: Vec<usize> = Vec::with_capacity(off.len());
        for (row, col, block) in off {
            if rows.last() == Some(&row) && columns.last() == Some(&(col as u32)) {
                add_block(off_diagonal.last_mut().expect("a previous block"), &block);
            } else {
                rows.push(row);
                columns.push(col as u32);
                off_diagonal.push(block);
            }
        }
        for &row in &rows {
            row_start[row + 1] += 1;
        }
        for a in 0..contacts {
            row_start[a + 1] += row_start[a];
        }
        DelassusBlocks {
            diagonal,
            row_start,
            columns,
            off_diagonal,
        }
    }

    /// Builds W from a dense row-major 3nc × 3nc matrix, skipping all-zero blocks.
    pub fn from_dense(contacts: usize, row_major: &[f64]) -> Self {
        let n = 3 * contacts;
        assert_eq!(row_major.len(), n * n, "dense W must be 3nc × 3nc");
        let mut blocks = Vec::new();
        for a in 0..contacts {
            for b in 0..contacts {
                let mut block = [0.0; 9];
                for i in 0..3 {
                    for j in 0..3 {
                        block[3 * i + j] = row_major[(3 * a + i) * n + 3 * b + j];
                    }
                }
                if a == b || block.iter().any(|&x| x != 0.0) {
                    blocks.push((a, b, block));
                }
            }
        }
        Self::from_blocks(contacts, blocks)
    }

    /// The number of contacts (block rows).
    pub fn contact_count(&self) -> usize {
        self.diagonal.len()
    }

    /// The number of stored off-diagonal blocks.
    pub fn off_diagonal_count(&self) -> usize {
        self.off_diagonal.len()
    }

    /// The diagonal block W_aa of contact `a`.
    pub fn diagonal(&self, a: usize) -> &Block3 {
        &self.diagonal[a]
    }

    /// The off-diagonal blocks of block row `a`: block columns and blocks.
    #[inline]
    pub fn row(&self, a: usize) -> (&[u32], &[Block3]) {
        let range = self.row_start[a]..self.row_start[a + 1];
        (&self.columns[range.clone()], &self.off_diagonal[range])
    }

    /// `out = W r + q`.
    pub fn affine(&self, r: &[f64], q: &[f64], out: &mut [f64]) {
        for a in 0..self.contact_count() {
            let mut u = [q[3 * a], q[3 * a + 1], q[3 * a + 2]];
            mul_add(&self.diagonal[a], &r[3 * a..3 * a + 3], &mut u);
            let (columns, blocks) = self.row(a);
            for (&b, block) in columns.iter().zip(blocks) {
                let b = b as usize;
                mul_add(block, &r[3 * b..3 * b + 3], &mut u);
            }
            out[3 * a..3 * a + 3].copy_from_slice(&u);
        }
    }

    /// W as a dense row-major 3nc × 3nc matrix (for tests and small problems).
    pub fn to_dense(&self) -> Vec<f64> {
        let n = 3 * self.contact_count();
        let mut dense = vec![0.0; n * n];
        let mut put = |a: usize, b: usize, block: &Block3| {
            for i in 0..3 {
                for j in 0..3 {
                    dense[(3 * a + i) * n + 3 * b + j] += block[3 * i + j];
                }
            }
        };
        for a in 0..self.contact_count() {
            put(a, a, &self.diagonal[a]);
            let (columns, blocks) = self.row(a);
            for (&b, block) in columns.iter().zip(blocks) {
                put(a, b as usize, block);
            }
        }
        dense
    }
}

fn add_block(into: &mut Block3, block: &Block3) {
    for (x, y) in into.iter_mut().zip(block) {
        *x += y;
    }
}

/// `u += B r` for one 3 × 3 block.
#[inline(always)]
pub(crate) fn mul_add(block: &Block3, r: &[f64], u: &mut [f64; 3]) {
    let (r0, r1, r2) = (r[0], r[1], r[2]);
    u[0] += block[0] * r0 + block[1] * r1 + block[2] * r2;
    u[1] += block[3] * r0 + block[4] * r1 + block[5] * r2;
    u[2] += block[6] * r0 + block[7] * r1 + block[8] * r2;
}

/// The local frictional-contact problem: find r, u with `u = W r + q` and, at each contact
/// a (normal component first), `r_a ∈ K_µa`, `u_a + µ_a ‖u_aT‖ e_N ∈ K*_µa`, `r_a ⊥ ũ_a`.
#[derive(Debug, Clone, PartialEq)]
pub struct FrictionProblem {
    /// The Delassus operator W.
    pub delassus: DelassusBlocks,
    /// q: the free local velocity (3 per contact).
    pub free_velocity: Vec<f64>,
    /// µ: the friction coefficient of each contact.
    pub friction: Vec<f64>,
}

impl FrictionProblem {
    /// Checks the sizes and values and builds the problem.
    pub fn new(
        delassus: DelassusBlocks,
        free_velocity: Vec<f64>,
        friction: Vec<f64>,
    ) -> crate::Result<Self> {
        let nc = delassus.contact_count();
        if free_velocity.len() != 3 * nc || friction.len() != nc {
            return Err(crate::Error::Message(format!(
                "frictional-contact problem: W has {nc} contacts but q has {} values and µ {}",
                free_velocity.len(),
                friction.len()
            )));
        }
        if let Some(a) = friction.iter().position(|&m| !(m >= 0.0 && m.is_finite())) {
            return Err(crate::Error::Message(format!(
                "frictional-contact problem: µ of contact {a} is {} (must be finite, ≥ 0)",
                friction[a]
            )));
        }
        if free_velocity.iter().any(|x| !x.is_finite()) {
            return Err(crate::Error::Message(
                "frictional-contact problem: q has a non-finite value".into(),
            ));
        }
        Ok(FrictionProblem {
            delassus,
            free_velocity,
            friction,
        })
    }

    /// The number of contacts.
    pub fn contact_count(&self) -> usize {
        self.friction.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_round_trip_and_affine() {
        let n = 6;
        let dense: Vec<f64> = (0..n * n)
            .map(|k| {
                if (k / n) / 3 == (k % n) / 3 || k % 5 == 0 {
                    k as f64
                } else {
                    0.0
                }
            })
            .collect();
        let w = DelassusBlocks::from_dense(2, &dense);
        assert_eq!(w.to_dense(), dense);
        let r = [1.0, -2.0, 0.5, 3.0, 0.0, -1.0];
        let q = [0.1; 6];
        let mut u = [0.0; 6];
        w.affine(&r, &q, &mut u);
        for i in 0..n {
            let expect: f64 = q[i] + (0..n).map(|j| dense[i * n + j] * r[j]).sum::<f64>();
            assert!((u[i] - expect).abs() < 1e-12);
        }
    }

    #[test]
    fn duplicates_are_summed() {
        let one = [1.0; 9];
        let w = DelassusBlocks::from_blocks(2, [(0, 1, one), (0, 1, one), (1, 1, one)]);
        assert_eq!(w.off_diagonal_count(), 1);
        assert_eq!(w.row(0).1[0], [2.0; 9]);
        assert_eq!(*w.diagonal(1), one);
        assert_eq!(*w.diagonal(0), [0.0; 9]);
    }
}
