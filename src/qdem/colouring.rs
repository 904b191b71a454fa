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

/// Tetra handed to the kernel at once (SIMD lanes of the element kernel).
pub(crate) const LANES: usize = 4;

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
        assert_eq!(partials.len(), self.blocks.len());
        assert_eq!(forces.len(), self.node_count);
        let nodes = &self.nodes;
        let target = ForceTarget {
            ptr: forces.as_mut_ptr(),
            _lifetime: PhantomData,
        };
        let run_block = |block: &Range<usize>, partial: &mut P| {
            *partial = P::default();
            let mut first = block.start;
            while first < block.end {
                let count = LANES.min(block.end - first);
                let f = kernel(first, count, partial);
                for (lane, fl) in f.iter().enumerate().take(count) {
                    for (k, &n) in nodes[first + lane].iter().enumerate() {
                        // SAFETY: `n < node_count == forces.len()` (checked in `new` and
                        // above) and, within one colour, no other block touches node n
                        // (`verify`), so this is the only access to `forces[n]` while the
                        // colour runs; a colour's blocks all finish before the next
                        // colour starts.
                        unsafe { target.add(n as usize, fl[k]) };
                    }
                }
                first += count;
            }
        };
        let parallel = nodes.len() >= PARALLEL_MIN_TETS;
        for c in 0..self.colours() {
            let range = self.colour_offsets[c]..self.colour_offsets[c + 1];
            if parallel {
                self.blocks[range.clone()]
                    .par_iter()
                    .zip(partials[range].par_iter_mut())
                    .for_each(|(block, partial)| run_block(block, partial));
            } else {
                for (block, partial) in self.blocks[range.clone()].iter().zip(&mut partials[range])
                {
                    run_block(block, partial);
                }
            }
        }
    }
}

/// The nodal force array shared by the blocks of one colour.
struct ForceTarget<'a> {
    ptr: *mut Vec3,
    _lifetime: PhantomData<&'a mut [Vec3]>,
}

// SAFETY: the only access goes through `add`, whose callers guarantee exclusive access
// per node (see `assemble`).
unsafe impl Sync for ForceTarget<'_> {}
unsafe impl Send for ForceTarget<'_> {}

impl ForceTarget<'_> {
    /// Adds `f` to node `n`. Safety: `n` is in bounds and no other thread touches node
    /// `n` meanwhile.
    #[inline(always)]
    unsafe fn add(&self, n: usize, f: Vec3) {
        let p = &mut *self.ptr.add(n);
        p[0] += f[0];
        p[1] += f[1];
        p[2] += f[2];
    }
}

/// Morton (Z-order) key of a point inside the box [lo, lo + size] (21 bits per axis).
pub(crate) fn morton_key(p: Vec3, lo: Vec3, size: Vec3) -> u64 {
    let spread = |v: u64| {
        let mut x = v & 0x1f_ffff;
        x = (x | (x << 32)) & 0x1f_0000_0000_ffff;
        x = (x | (x << 16)) & 0x1f_0000_ff00_00ff;
        x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
        x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
        x = (x | (x << 2)) & 0x1249_2492_4924_9249;
        x
    };
    let q = |d: usize| {
        let t = if size[d] > 0.0 {
            (p[d] - lo[d]) / size[d]
        } else {
            0.0
        };
        (t.clamp(0.0, 1.0) * 2_097_151.0) as u64
    };
    spread(q(0)) | (spread(q(1)) << 1) | (spread(q(2)) << 2)
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
        let k = morton_key([1.0, 0.0, 0.0], [0.0; 3], [1.0; 3]);
        assert_eq!(k & 0b111, 0b001);
        assert!(morton_key([0.0; 3], [0.0; 3], [1.0; 3]) == 0);
    }
}
