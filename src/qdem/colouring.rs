//! Deterministic parallel assembly of nodal forces by coloured blocks of tetra.
//!
//! Tetra are sorted along a Morton curve and cut into blocks of [`BLOCK_SIZE`]
//! consecutive tetra; blocks that share a node get different colours. One colour's
//! blocks run in parallel (no two of them touch the same node), each block adds its
//! tetra's forces in a fixed order, and colours run one after the other. Every nodal sum
//! is thus taken in the same order whatever the thread count: results are bitwise
//! reproducible, without atomics or a per-tetra force buffer (fenris-paradis style).

use super::element::Vec3;
use rayon::prelude::*;
use std::marker::PhantomData;
use std::ops::Range;

/// Tetra per block: small enough that a block's nodes stay in L1/L2, large enough that
/// a colour has few, long tasks.
pub(crate) const BLOCK_SIZE: usize = 256;

/// Below this many tetra the phases run on the calling thread: handing a few hundred
/// tetra to a thread pool costs more than computing them. The summation order is the
/// same either way, so the results are too.
pub(crate) const PARALLEL_MIN_TETS: usize = 8192;

pub(crate) use super::kernel::LANES;

/// Blocks of consecutive tetra grouped by colour.
#[derive(Debug, Clone)]
pub(crate) struct BlockColouring {
    /// The tetra (node indices), in the order the blocks cut.
    pub nodes: Vec<[u32; 4]>,
    /// Number of nodes (every index in `nodes` is below it).
    pub node_count: usize,
    /// Element ranges of the blocks, ordered by colour.
    pub blocks: Vec<Range<usize>>,
    /// `blocks[colour_offsets[c]..colour_offsets[c + 1]]` are the blocks of colour c.
    pub colour_offsets: Vec<usize>,
}

impl BlockColouring {
    /// Greedy first-fit colouring of the blocks of `nodes` (already in locality order).
    pub fn new(nodes: Vec<[u32; 4]>, node_count: usize) -> Self {
        assert!(
            nodes.iter().flatten().all(|&n| (n as usize) < node_count),
            "block colouring: node index out of range"
        );
        let ranges: Vec<Range<usize>> = (0..nodes.len())
            .step_by(BLOCK_SIZE)
            .map(|start| start..(start + BLOCK_SIZE).min(nodes.len()))
            .collect();
        // node → blocks touching it (CSR, each block once per node).
        let mut count = vec![0u32; node_count + 1];
        let mut last_block = vec![u32::MAX; node_count];
        for (b, r) in ranges.iter().enumerate() {
            for tet in &nodes[r.clone()] {
                for &n in tet {
                    if last_block[n as usize] != b as u32 {
                        last_block[n as usize] = b as u32;
                        count[n as usize + 1] += 1;
                    }
                }
            }
        }
        for i in 0..node_count {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut node_blocks = vec![0u32; count[node_count] as usize];
        last_block.fill(u32::MAX);
        for (b, r) in ranges.iter().enumerate() {
            for tet in &nodes[r.clone()] {
                for &n in tet {
                    if last_block[n as usize] != b as u32 {
                        last_block[n as usize] = b as u32;
                        node_blocks[fill[n as usize] as usize] = b as u32;
                        fill[n as usize] += 1;
                    }
                }
            }
        }
        let mut colour = vec![u32::MAX; ranges.len()];
        let mut forbidden: Vec<usize> = Vec::new(); // forbidden[c] == b: c is taken near b
        for (b, r) in ranges.iter().enumerate() {
            for tet in &nodes[r.clone()] {
                for &n in tet {
                    let n = n as usize;
                    for &other in &node_blocks[count[n] as usize..count[n + 1] as usize] {
                        let c = colour[other as usize];
                        if c != u32::MAX {
                            forbidden[c as usize] = b;
                        }
                    }
                }
            }
            let c = (0..forbidden.len())
                .find(|&c| forbidden[c] != b)
                .unwrap_or_else(|| {
                    forbidden.push(usize::MAX);
                    forbidden.len() - 1
                });
            colour[b] = c as u32;
        }
        let colours = forbidden.len();
        let mut colour_offsets = vec![0usize; colours + 1];
        for &c in &colour {
            colour_offsets[c as usize + 1] += 1;
        }
        for c in 0..colours {
            colour_offsets[c + 1] += colour_offsets[c];
        }
        let mut order: Vec<usize> = (0..ranges.len()).collect();
        order.sort_by_key(|&b| (colour[b], b));
        let blocks: Vec<Range<usize>> = order.into_iter().map(|b| ranges[b].clone()).collect();
        let colouring = BlockColouring {
            nodes,
            node_count,
            blocks,
            colour_offsets,
        };
        colouring.verify();
        colouring
    }

    /// Number of colours.
    pub fn colours(&self) -> usize {
        self.colour_offsets.len() - 1
    }

    /// Checks the invariant the unsafe scatter relies on: the blocks of one colour touch
    /// disjoint node sets. O(tetra); a failure is a bug here, hence a panic.
    fn verify(&self) {
        let nodes = &self.nodes;
        let mut owner = vec![usize::MAX; self.node_count];
        for c in 0..self.colours() {
            for b in self.colour_offsets[c]..self.colour_offsets[c + 1] {
                for tet in &nodes[self.blocks[b].clone()] {
                    for &n in tet {
                        let o = &mut owner[n as usize];
                        assert!(
                            *o == b || *o == usize::MAX || *o < self.colour_offsets[c],
                            "block colouring: node {n} is shared by two blocks of colour {c}"
                        );
                        *o = b;
                    }
                }
            }
        }
    }

    /// Runs `kernel(block, partial)` on every block: the blocks of one colour in
    /// parallel (touching disjoint node sets, see `verify`), colours one after the
    /// other; `partials[b]` is block b's accumulator (reset to default first). A kernel
    /// that writes only to its own block's nodes is therefore race-free and sums every
    /// node in the same order for any thread count (see the module note).
    pub fn run_blocks<P, K>(&self, partials: &mut [P], kernel: K)
    where
        P: Send + Default,
        K: Fn(Range<usize>, &mut P) + Sync,
    {
        assert_eq!(partials.len(), self.blocks.len());
        let run = |block: &Range<usize>, partial: &mut P| {
            *partial = P::default();
            kernel(block.clone(), partial);
        };
        let parallel = self.nodes.len() >= PARALLEL_MIN_TETS;
        for c in 0..self.colours() {
            let range = self.colour_offsets[c]..self.colour_offsets[c + 1];
            if parallel {
                self.blocks[range.clone()]
                    .par_iter()
                    .zip(partials[range].par_iter_mut())
                    .for_each(|(block, partial)| run(block, partial));
            } else {
                for (block, partial) in self.blocks[range.clone()].iter().zip(&mut partials[range])
                {
                    run(block, partial);
                }
            }
        }
    }

    /// Runs `kernel` on every tetra, [`LANES`] at a time, and adds the four forces it
    /// returns per tetra to `forces` at the tetra's nodes. `kernel(first, count, partial)`
    /// gets tetra `first..first + count` (count ≤ LANES; the forces of lanes ≥ count are
    /// ignored); `partials[b]` is block b's accumulator (reset to default first).
    /// Deterministic for any thread count (see the module note).
    pub fn assemble<P, K>(&self, forces: &mut [Vec3], partials: &mut [P], kernel: K)
    where
        P: Send + Default,
        K: Fn(usize, usize, &mut P) -> [[Vec3; 4]; LANES] + Sync,
    {
        assert_eq!(forces.len(), self.node_count);
        let nodes = &self.nodes;
        let target = ForceTarget::new(forces);
        self.run_blocks(partials, |block, partial| {
            let mut first = block.start;
            while first < block.end {
                let count = LANES.min(block.end - first);
                let f = kernel(first, count, partial);
                for (lane, fl) in f.iter().enumerate().take(count) {
                    for (k, &n) in nodes[first + lane].iter().enumerate() {
                        // SAFETY: `n < node_count == forces.len()` (checked in `new` and
                        // above), and `run_blocks` gives this block its nodes alone.
                        let p = unsafe { &mut *target.node(n as usize) };
                        for d in 0..3 {
                            p[d] += fl[k][d];
                        }
                    }
                }
                first += count;
            }
        });
    }
}

/// A nodal array shared by the blocks of one colour (see [`BlockColouring::run_blocks`]).
pub(crate) struct ForceTarget<'a, T> {
    ptr: *mut T,
    len: usize,
    _lifetime: PhantomData<&'a mut [T]>,
}

// SAFETY: the only access goes through `node`, whose callers guarantee exclusive access
// per node (see `run_blocks`).
unsafe impl<T: Send> Sync for ForceTarget<'_, T> {}
unsafe impl<T: Send> Send for ForceTarget<'_, T> {}

impl<'a, T> ForceTarget<'a, T> {
    /// Borrows `values` for the blocks.
    pub fn new(values: &'a mut [T]) -> Self {
        ForceTarget {
            ptr: values.as_mut_ptr(),
            len: values.len(),
            _lifetime: PhantomData,
        }
    }

    /// Node `n`. Safety: `n < len` and no other thread touches node `n` while the
    /// pointer is used.
    #[inline(always)]
    pub unsafe fn node(&self, n: usize) -> *mut T {
        debug_assert!(n < self.len);
        self.ptr.add(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_of_a_chain_alternate() {
        // 2000 tetra in a chain sharing one node with the next: blocks alternate colours.
        let tets: Vec<[u32; 4]> = (0..2000u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2, 3 * i + 3])
            .collect();
        let c = BlockColouring::new(tets, 6004);
        assert_eq!(c.colours(), 2);
        let mut forces = vec![[0.0; 3]; 6004];
        let mut partials = vec![0u32; c.blocks.len()];
        c.assemble(&mut forces, &mut partials, |_, count, p| {
            *p += count as u32;
            [[[1.0; 3]; 4]; LANES]
        });
        assert_eq!(partials.iter().sum::<u32>(), 2000);
        assert_eq!(forces[3][0], 2.0);
        assert_eq!(forces[1][0], 1.0);
    }

    #[test]
    fn morton_keys_interleave() {
        use crate::mesh::morton_key;
        let k = morton_key([1.0, 0.0, 0.0], [0.0; 3], [1.0; 3]);
        assert_eq!(k & 0b111, 0b001);
        assert!(morton_key([0.0; 3], [0.0; 3], [1.0; 3]) == 0);
    }
}
