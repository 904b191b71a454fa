//! The DDM–NLGS drivers (seed 000 Algorithm 1 and §4.1) on the body-velocity NLGS.
//!
//! Each subdomain E keeps its own copy of the velocities of the bodies its contacts
//! touch (its grains, and read-only copies of walls and tools). Its contacts move only
//! its own grains, so the subdomains sweep in parallel on disjoint data, in safe Rust.
//!
//! - **Synchronous** (Algorithm 1): per DDM iteration, every subdomain makes `n` NLGS
//!   sweeps over its contacts, in parallel; their grains' velocities are written back;
//!   then the interface Γ makes `m` sweeps, sequentially, on the global velocities; the
//!   subdomains' copies are refreshed. With n = m = 1 this is, operation for operation,
//!   one sequential NLGS sweep over the contacts numbered subdomain by subdomain and
//!   then Γ (the seed's remark after Algorithm 1), so the result is bitwise the same
//!   on any number of threads.
//! - **Asynchronous** (§4.1: block Jacobi between the blocks, Gauss–Seidel within
//!   each): Γ is one more block of the same parallel loop, and every block sweeps its
//!   own copy of the velocities its contacts touch, taken at the start of the
//!   iteration. The literal splitting — each block's velocity change added up — does
//!   not converge on stacked grains: two blocks that push the same grain both correct
//!   it in full (on the 6 × 3 × 4 lattice of the tests, the error measure was still
//!   0.63 after 20 000 iterations where the synchronous driver reached 1e-8 in 2 035).
//!   The seed's OpenMP code is saved by its races (an interface contact often reads a
//!   velocity a subdomain has just written). The update here is deterministic and
//!   converges: mass splitting (Tonge, Benevolenski & Voroshilov 2012) — a grain that
//!   k blocks touch has mass m/k in each block's copy, and after the loop it gets the
//!   mean of the k copies. Since each copy moved by `k M⁻¹ H_b Δr_b`, the mean is
//!   exactly `V_free + M⁻¹ H r` for every block's new impulses, and at a fixed point
//!   the copies agree, so the solution is one of the original problem. The result
//!   does not depend on the number of threads (the seed's differs from run to run).
//!
//! Stopping (a fixed n_DDM, or the error measure) is [`body_nlgs::solve_by`]'s, on the
//! whole problem, counted in DDM iterations.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Vector3};

use super::partition::Decomposition;
use crate::nscd::body_nlgs::{
    self, Bodies, BodyInverses, BodyState, ContactRow, Problem, SweepStats, Sweepable,
};
use crate::nscd::nlgs::{NlgsOptions, NlgsReport};

/// Which DDM driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Driver {
    /// Subdomains in parallel, then the interface sequentially (Algorithm 1).
    Synchronous,
    /// The interface as one more block of the parallel loop (§4.1).
    Asynchronous,
}

/// DDM settings: the driver and the NLGS sweeps per DDM iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DdmOptions {
    /// The driver.
    pub driver: Driver,
    /// NLGS sweeps in each subdomain per DDM iteration (the seed's n).
    pub subdomain_sweeps: usize,
    /// NLGS sweeps on the interface per DDM iteration (the seed's m).
    pub interface_sweeps: usize,
}

impl DdmOptions {
    /// `driver` with n = m = 1 (the seed's choice, after Hoang et al. 2011a).
    pub fn new(driver: Driver) -> Self {
        DdmOptions {
            driver,
            subdomain_sweeps: 1,
            interface_sweeps: 1,
        }
    }
}

/// What a DDM solve did: the NLGS report (iterations = DDM iterations) and the wall
/// time of the parallel subdomain part and of the sequential interface part (the
/// seed's Table 1 split; the asynchronous driver has no sequential part).
#[derive(Debug, Clone, PartialEq)]
pub struct DdmReport {
    /// The solve's report.
    pub nlgs: NlgsReport,
    /// Parallel loop over the blocks, including the write-back.
    pub subdomain_time: Duration,
    /// Sequential interface sweeps.
    pub interface_time: Duration,
    /// Each block's own sweeping time, summed over the iterations: the subdomains in
    /// order, then (asynchronous driver) the interface. Beside `subdomain_time` it
    /// splits the parallel part's loss between imbalance (threads waiting for the
    /// last block) and blocks that sweep slower side by side than alone.
    pub block_busy: Vec<Duration>,
}

/// A block's own copy of the velocities its contacts touch (asynchronous driver).
struct OwnVelocities {
    /// Its contacts with bodies renumbered into `state` (and split masses).
    contacts: Sweepable,
    /// Local body → global body.
    global: Vec<usize>,
    /// Whether each local body moves (is written back).
    moves: Vec<bool>,
    /// The velocities of its bodies.
    state: Vec<BodyState>,
}

impl OwnVelocities {
    /// Refreshes the moving bodies from the global state.
    fn refresh(&mut self, state: &[BodyState]) {
        for ((&g, s), &m) in self.global.iter().zip(&mut self.state).zip(&self.moves) {
            if m {
                *s = state[g];
            }
        }
    }
}

/// One block of contacts: a subdomain, or (asynchronous driver) the interface.
struct Block {
    /// Its contacts (in the global numbering).
    range: Range<usize>,
    /// `None`: it sweeps the problem's contacts on the global velocities (synchronous
    /// driver; its contacts move only its own grains).
    own: Option<OwnVelocities>,
    /// Its contacts' impulses and slip directions (the block owns them while sweeping).
    impulse: Vec<[f64; 3]>,
    directions: Vec<[f64; 2]>,
    /// NLGS sweeps per DDM iteration (n or m).
    sweeps: usize,
    /// The last sweep's statistics.
    stats: SweepStats,
    /// Time spent in its sweeps over the solve.
    busy: Duration,
}

impl Block {
    /// The block of contacts `range` on the global velocities, its impulses from
    /// `impulse`.
    fn shared(range: Range<usize>, impulse: &[[f64; 3]], sweeps: usize) -> Self {
        Block {
            impulse: impulse[range.clone()].to_vec(),
            directions: vec![[0.0; 2]; range.len()],
            range,
            own: None,
            sweeps,
            stats: SweepStats::default(),
            busy: Duration::ZERO,
        }
    }

    /// The block of contacts `range` with its own copy of the velocities: its sweep
    /// data `contacts` (bodies in the global numbering, renumbered here in place into
    /// its own state); its state copied from `state`, its impulses from `impulse`;
    /// `moving` tells which bodies move. `slot` is scratch of one entry per body, all
    /// `usize::MAX` on entry and on return.
    fn own(
        mut contacts: Sweepable,
        range: Range<usize>,
        (state, impulse): (&[BodyState], &[[f64; 3]]),
        sweeps: usize,
        moving: &[bool],
        slot: &mut [usize],
    ) -> Self {
        let mut global = Vec::new();
        for c in &mut contacts.normals {
            for b in c.bodies_mut() {
                let g = *b as usize;
                if slot[g] == usize::MAX {
                    slot[g] = global.len();
                    global.push(g);
                }
                *b = slot[g] as u32;
            }
        }
        for &b in &global {
            slot[b] = usize::MAX;
        }
        Block {
            own: Some(OwnVelocities {
                contacts,
                moves: global.iter().map(|&b| moving[b]).collect(),
                state: global.iter().map(|&b| state[b]).collect(),
                global,
            }),
            ..Block::shared(range, impulse, sweeps)
        }
    }

    /// The block's NLGS sweeps of one DDM iteration, on its own state or on `global`
    /// (blocks without their own); keeps the last sweep's statistics. Safety: with
    /// `global`, no other thread touches the bodies this block's contacts move, nor
    /// writes the others they read, meanwhile.
    unsafe fn sweep(&mut self, contacts: &Sweepable, global: Option<Bodies<'_>>) {
        for _ in 0..self.sweeps {
            self.stats = match (&mut self.own, global) {
                (Some(own), _) => body_nlgs::sweep(
                    own.contacts.view(),
                    &mut self.impulse,
                    &mut self.directions,
                    &mut own.state,
                ),
                (None, Some(global)) => body_nlgs::sweep_on(
                    contacts.view().part(self.range.clone()),
                    &mut self.impulse,
                    &mut self.directions,
                    global,
                ),
                (None, None) => unreachable!("a shared block swept without the velocities"),
            };
        }
    }
}

/// How many of the blocks (contact `ranges`) touch each moving body.
fn block_multiplicity(
    rows: &[ContactRow],
    ranges: &[Range<usize>],
    moving: &[bool],
    bodies: usize,
) -> Vec<u32> {
    let mut count = vec![0u32; bodies];
    let mut last = vec![usize::MAX; bodies];
    for (k, range) in ranges.iter().enumerate() {
        for row in &rows[range.clone()] {
            for &b in &row.bodies {
                let b = b as usize;
                if moving[b] && last[b] != k {
                    last[b] = k;
                    count[b] += 1;
                }
            }
        }
    }
    count
}

/// Inverse masses and inertias scaled by the number of blocks that share each body
/// (mass splitting: a body k blocks touch weighs m/k in each).
struct SplitMasses {
    inverse_mass: Vec<f64>,
    inverse_inertia: Vec<Matrix3<f64>>,
}

impl SplitMasses {
    fn new(inverses: &BodyInverses, multiplicity: &[u32]) -> Self {
        let k = |b: usize| f64::from(multiplicity[b].max(1));
        SplitMasses {
            inverse_mass: (inverses.inverse_mass.iter().enumerate())
                .map(|(b, m)| k(b) * m)
                .collect(),
            inverse_inertia: (inverses.inverse_inertia.iter().enumerate())
                .map(|(b, i)| i * k(b))
                .collect(),
        }
    }

    fn inverses(&self) -> BodyInverses<'_> {
        BodyInverses {
            inverse_mass: &self.inverse_mass,
            inverse_inertia: &self.inverse_inertia,
        }
    }
}

/// Solves the body-velocity contact problem with the DDM driver `ddm`. `rows` must be
/// numbered as `decomposition` says (subdomain by subdomain, then the interface, as
/// [`super::partition::decompose`] orders them); the other arguments are those of
/// [`body_nlgs::solve`], whose stopping rule and error measure apply, per DDM iteration.
/// Parallel over the blocks on the current rayon pool; the result does not depend on
/// its size.
#[allow(clippy::too_many_arguments)]
pub fn solve(
    rows: &[ContactRow],
    decomposition: &Decomposition,
    inverses: &BodyInverses,
    velocity: &mut [Vector3<f64>],
    angular_velocity: &mut [Vector3<f64>],
    impulse: &mut [[f64; 3]],
    options: &NlgsOptions,
    ddm: &DdmOptions,
) -> DdmReport {
    assert_eq!(
        decomposition.contacts(),
        rows.len(),
        "the decomposition numbers every contact"
    );
    let start = Instant::now();
    let moving: Vec<bool> = inverses.inverse_mass.iter().map(|&m| m > 0.0).collect();
    let asynchronous = ddm.driver == Driver::Asynchronous;
    let mut problem = Problem::new(rows, inverses, velocity, angular_velocity, impulse);
    let (contacts, state) = (&problem.contacts, &mut problem.state);
    // The blocks: the subdomains, and for the asynchronous driver the interface too,
    // each with its own copy of what it touches.
    let mut slot = vec![usize::MAX; state.len()];
    let mut ranges = decomposition.subdomains.clone();
    let mut sweeps = vec![ddm.subdomain_sweeps; ranges.len()];
    let mut multiplicity: Vec<u32> = Vec::new();
    // Asynchronous: the interface is one more block, and shared grains' masses split.
    let split = asynchronous.then(|| {
        ranges.push(decomposition.interface.clone());
        sweeps.push(ddm.interface_sweeps);
        multiplicity = block_multiplicity(rows, &ranges, &moving, state.len());
        SplitMasses::new(inverses, &multiplicity)
    });
    let blocks: Vec<Mutex<Block>> = ranges
        .iter()
        .zip(&sweeps)
        .map(|(r, &n)| {
            let block = match &split {
                Some(split) => {
                    let own = Sweepable::new(&rows[r.clone()], &split.inverses());
                    Block::own(own, r.clone(), (state, impulse), n, &moving, &mut slot)
                }
                None => Block::shared(r.clone(), impulse, n),
            };
            Mutex::new(block)
        })
        .collect();
    let mut sums: Vec<BodyState> =
        vec![BodyState::default(); if asynchronous { state.len() } else { 0 }];
    let team = Team::new(&ranges.iter().map(Range::len).collect::<Vec<_>>());
    let helpers = rayon::current_num_threads()
        .min(blocks.len())
        .saturating_sub(1);
    let (mut subdomain_time, mut interface_time) = (Duration::ZERO, Duration::ZERO);
    let free_norm = problem.free_norm;
    let mut nlgs = rayon::scope(|scope| {
        let main = rayon::current_thread_index();
        for _ in 0..helpers {
            let (team, blocks) = (&team, &blocks);
            scope.spawn(move |_| {
                // Run inline by the main thread while it waits inside a parallel loop
                // (rayon may do that): nothing to do, the main thread sweeps itself.
                if rayon::current_thread_index() != main {
                    team.help(blocks, contacts);
                }
            });
        }
        let report = body_nlgs::run(
            contacts,
            state,
            free_norm,
            impulse,
            options,
            |contacts, impulse, directions, state| {
                let clock = Instant::now();
                // Synchronous: the subdomains sweep the global velocities in place,
                // each moving only its own grains (a view that lives for this loop).
                team.iterate(
                    &blocks,
                    contacts,
                    (!asynchronous).then(|| Bodies::new(state)),
                );
                let mut stats = SweepStats::default();
                let mut blocks: Vec<_> = blocks
                    .iter()
                    .map(|b| b.lock().expect("a block not poisoned"))
                    .collect();
                for b in blocks.iter() {
                    stats.add(&b.stats);
                }
                if asynchronous {
                    // A body one block touches takes that block's copy; one that k
                    // blocks touch, the mean of the k copies (summed in block order).
                    for own in blocks.iter().filter_map(|b| b.own.as_ref()) {
                        for ((&g, s), &m) in own.global.iter().zip(&own.state).zip(&own.moves) {
                            if !m {
                                continue;
                            }
                            if multiplicity[g] == 1 {
                                state[g] = *s;
                            } else {
                                for x in 0..8 {
                                    sums[g][x] += s[x];
                                }
                            }
                        }
                    }
                    for (g, k) in multiplicity.iter().enumerate() {
                        if *k > 1 {
                            let k = f64::from(*k);
                            for x in 0..8 {
                                state[g][x] = sums[g][x] / k;
                            }
                            sums[g] = BodyState::default();
                        }
                    }
                    for own in blocks.iter_mut().filter_map(|b| b.own.as_mut()) {
                        own.refresh(state);
                    }
                    subdomain_time += clock.elapsed();
                } else {
                    subdomain_time += clock.elapsed();
                    let clock = Instant::now();
                    let gamma = decomposition.interface.clone();
                    let mut last = SweepStats::default();
                    for _ in 0..ddm.interface_sweeps {
                        last = body_nlgs::sweep(
                            contacts.view().part(gamma.clone()),
                            &mut impulse[gamma.clone()],
                            &mut directions[gamma.clone()],
                            state,
                        );
                    }
                    stats.add(&last);
                    interface_time += clock.elapsed();
                }
                stats
            },
            |impulse| {
                // The blocks' impulses, only when the measure or the caller reads them
                // (the velocities are current: the synchronous blocks sweep them in
                // place, the asynchronous driver merges them every iteration).
                for b in &blocks {
                    let b = b.lock().expect("a block not poisoned");
                    impulse[b.range.clone()].copy_from_slice(&b.impulse);
                }
            },
        );
        team.stop();
        report
    });
    problem.finish(velocity, angular_velocity);
    nlgs.solve_time = start.elapsed();
    DdmReport {
        nlgs,
        subdomain_time,
        interface_time,
        block_busy: blocks
            .into_iter()
            .map(|b| b.into_inner().expect("a block not poisoned").busy)
            .collect(),
    }
}

/// The threads that sweep the blocks of one solve: the main thread (which runs the
/// NLGS loop) and helpers that live for the whole solve and spin between iterations
/// (a rayon loop per iteration put the idle worker to sleep and paid a wake-up each
/// time, beside about 0.3 ms of work). Blocks are claimed from a counter, so the main
/// thread sweeps every block no helper has taken: a helper that never starts (all
/// workers busy) costs time, never progress.
///
/// The blocks are claimed largest first (by contact count; the cost per contact was
/// within ±6 % between the Table 3 case's four slabs at mid-squeeze), in the same order
/// in every iteration, so a thread tends to sweep the same blocks and find their
/// bodies in its cache. Claimed in numbering order instead, 4 slabs on 2 threads gave
/// one thread both end slabs: at mid-squeeze of the Table 3 case (32 900, 26 200,
/// 24 300 and 31 300 contact points) 64 200 points against 57 400 for the best split.
/// Ordered by each block's time in the previous iteration, the balance was better but
/// the blocks changed threads and swept 3–7 % slower (docs/tamping.md). Which thread
/// sweeps a block does not change its result: the synchronous blocks touch disjoint
/// grains, the asynchronous blocks their own copies.
struct Team {
    /// Incremented by the main thread to start an iteration.
    epoch: AtomicUsize,
    /// The next block to claim in this iteration.
    next: AtomicUsize,
    /// Blocks swept in this iteration.
    completed: AtomicUsize,
    /// Set when the solve is over.
    stopped: AtomicBool,
    /// This iteration's view of the global velocities (null: none), published by the
    /// epoch's increment.
    view: AtomicPtr<BodyState>,
    view_len: AtomicUsize,
    /// The blocks in the order they are claimed.
    order: Vec<usize>,
}

impl Team {
    /// A team for blocks of `sizes` contacts, claimed largest first (ties by number).
    fn new(sizes: &[usize]) -> Self {
        let mut order: Vec<usize> = (0..sizes.len()).collect();
        order.sort_by_key(|&k| std::cmp::Reverse(sizes[k]));
        Team {
            epoch: AtomicUsize::new(0),
            next: AtomicUsize::new(sizes.len()),
            completed: AtomicUsize::new(0),
            stopped: AtomicBool::new(false),
            view: AtomicPtr::new(std::ptr::null_mut()),
            view_len: AtomicUsize::new(0),
            order,
        }
    }

    /// Claims and sweeps blocks until none is left.
    fn claim(&self, blocks: &[Mutex<Block>], contacts: &Sweepable, view: Option<Bodies<'_>>) {
        loop {
            let k = self.next.fetch_add(1, Ordering::AcqRel);
            if k >= self.order.len() {
                return;
            }
            let k = self.order[k];
            let mut block = blocks[k].lock().expect("a block not poisoned");
            // SAFETY: the blocks of the synchronous driver are the subdomains, whose
            // contacts move only their own grains and read only those and bodies that
            // do not move (crate::ddm::partition): blocks swept at the same time touch
            // disjoint moving bodies. The view is valid until `iterate` returns, which
            // waits for every block of the iteration.
            let clock = Instant::now();
            unsafe { block.sweep(contacts, view) };
            block.busy += clock.elapsed();
            drop(block);
            self.completed.fetch_add(1, Ordering::AcqRel);
        }
    }

    /// The main thread: one iteration's block sweeps, with whoever helps, on `view` for
    /// blocks without their own velocities.
    fn iterate(&self, blocks: &[Mutex<Block>], contacts: &Sweepable, view: Option<Bodies<'_>>) {
        let (ptr, len) = view.map_or((std::ptr::null_mut(), 0), |v| v.raw());
        self.view.store(ptr, Ordering::Relaxed);
        self.view_len.store(len, Ordering::Relaxed);
        self.completed.store(0, Ordering::Release);
        self.next.store(0, Ordering::Release);
        self.epoch.fetch_add(1, Ordering::AcqRel);
        self.claim(blocks, contacts, view);
        let mut spins = 0u32;
        while self.completed.load(Ordering::Acquire) < self.order.len() {
            backoff(&mut spins);
        }
    }

    /// The view `iterate` published with the current epoch.
    fn published_view(&self) -> Option<Bodies<'_>> {
        let ptr = self.view.load(Ordering::Relaxed);
        // SAFETY: published by `iterate` before the epoch this helper has seen (with
        // acquire ordering), and valid until that iteration's blocks are all swept.
        (!ptr.is_null())
            .then(|| unsafe { Bodies::from_raw(ptr, self.view_len.load(Ordering::Relaxed)) })
    }

    /// A helper: sweeps blocks at each new iteration until the solve stops.
    fn help(&self, blocks: &[Mutex<Block>], contacts: &Sweepable) {
        let mut seen = self.epoch.load(Ordering::Acquire);
        let mut spins = 0u32;
        loop {
            let epoch = self.epoch.load(Ordering::Acquire);
            if epoch != seen {
                seen = epoch;
                self.claim(blocks, contacts, self.published_view());
                spins = 0;
            } else if self.stopped.load(Ordering::Acquire) {
                return;
            } else if spins >= 64 && rayon::yield_now() == Some(rayon::Yield::Executed) {
                // Between iterations (the interface sweeps, the error measure) a
                // helper takes the main thread's parallel chunks of the measure.
                spins = 0;
            } else {
                backoff(&mut spins);
            }
        }
    }

    fn stop(&self) {
        self.stopped.store(true, Ordering::Release);
    }
}

/// Spins a while, then yields the core (when more threads than cores wait).
fn backoff(spins: &mut u32) {
    if *spins < 1 << 14 {
        *spins += 1;
        std::hint::spin_loop();
    } else {
        std::thread::yield_now();
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Matrix3;

    use super::*;
    use crate::contact::local_frame;
    use crate::ddm::{decompose, Partitioning};
    use crate::geometry::random::SplitMix;
    use crate::nscd::nlgs::{ErrorCheck, Stopping};

    /// A heap-like problem: unit-mass bodies on an `nx × ny × nz` lattice with spacing
    /// 1 over a fixed floor (body 0), falling at 1 m/s with small random velocities;
    /// a contact between lattice neighbours (slightly perturbed normals) and between
    /// the bottom layer and the floor.
    struct Lattice {
        rows: Vec<ContactRow>,
        centres: Vec<Vector3<f64>>,
        inverse_mass: Vec<f64>,
        inverse_inertia: Vec<Matrix3<f64>>,
        velocity: Vec<Vector3<f64>>,
    }

    fn lattice(nx: usize, ny: usize, nz: usize) -> Lattice {
        let mut random = SplitMix(7);
        let mut jitter = |s: f64| s * random.next_signed();
        let index = |i: usize, j: usize, k: usize| 1 + i + nx * (j + ny * k);
        let mut centres = vec![Vector3::new(0.0, 0.0, -0.5)];
        let mut velocity = vec![Vector3::zeros()];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    centres.push(Vector3::new(i as f64, j as f64, k as f64 + 0.5));
                    velocity.push(Vector3::new(jitter(0.1), jitter(0.1), -1.0 + jitter(0.1)));
                }
            }
        }
        let n = centres.len();
        let mut inverse_mass = vec![1.0; n];
        let mut inverse_inertia = vec![Matrix3::identity() * 6.0; n];
        inverse_mass[0] = 0.0;
        inverse_inertia[0] = Matrix3::zeros();
        let mut rows = Vec::new();
        let mut contact = |a: usize, b: usize, normal: Vector3<f64>, point: Vector3<f64>| {
            let normal =
                (normal + Vector3::new(jitter(0.05), jitter(0.05), jitter(0.05))).normalize();
            rows.push(ContactRow {
                bodies: [a as u32, b as u32],
                frame: local_frame(&normal),
                arms: [point - centres[a], point - centres[b]],
                shift: jitter(0.01),
                mu: 0.5 + jitter(0.3),
            });
        };
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let b = index(i, j, k);
                    let c = centres[b];
                    if k == 0 {
                        contact(0, b, Vector3::z(), c - 0.5 * Vector3::z());
                    } else {
                        let below = index(i, j, k - 1);
                        contact(below, b, Vector3::z(), c - 0.5 * Vector3::z());
                    }
                    if i > 0 {
                        contact(index(i - 1, j, k), b, Vector3::x(), c - 0.5 * Vector3::x());
                    }
                    if j > 0 {
                        contact(index(i, j - 1, k), b, Vector3::y(), c - 0.5 * Vector3::y());
                    }
                }
            }
        }
        Lattice {
            rows,
            centres,
            inverse_mass,
            inverse_inertia,
            velocity,
        }
    }

    type Solution = (
        Vec<[f64; 3]>,
        Vec<Vector3<f64>>,
        Vec<Vector3<f64>>,
        NlgsReport,
    );

    impl Lattice {
        /// The rows renumbered for `partitioning`.
        fn decomposed(&self, partitioning: &Partitioning) -> (Vec<ContactRow>, Decomposition) {
            let movable: Vec<bool> = self.inverse_mass.iter().map(|&m| m > 0.0).collect();
            let owner = partitioning.assign(&self.centres, &movable);
            let pairs: Vec<[usize; 2]> = self
                .rows
                .iter()
                .map(|r| [r.bodies[0] as usize, r.bodies[1] as usize])
                .collect();
            let (order, d) = decompose(&pairs, &owner, partitioning.subdomains());
            (order.iter().map(|&k| self.rows[k]).collect(), d)
        }

        fn inverses(&self) -> BodyInverses<'_> {
            BodyInverses {
                inverse_mass: &self.inverse_mass,
                inverse_inertia: &self.inverse_inertia,
            }
        }

        fn solve_plain(&self, rows: &[ContactRow], options: &NlgsOptions) -> Solution {
            let (mut v, mut w) = (self.velocity.clone(), vec![Vector3::zeros(); v_len(self)]);
            let mut r = vec![[0.0; 3]; rows.len()];
            let report = body_nlgs::solve(rows, &self.inverses(), &mut v, &mut w, &mut r, options);
            (r, v, w, report)
        }

        fn solve_ddm(
            &self,
            partitioning: &Partitioning,
            options: &NlgsOptions,
            ddm: &DdmOptions,
            threads: usize,
        ) -> Solution {
            let (rows, d) = self.decomposed(partitioning);
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            pool.install(|| {
                let (mut v, mut w) = (self.velocity.clone(), vec![Vector3::zeros(); v_len(self)]);
                let mut r = vec![[0.0; 3]; rows.len()];
                let report = solve(
                    &rows,
                    &d,
                    &self.inverses(),
                    &mut v,
                    &mut w,
                    &mut r,
                    options,
                    ddm,
                );
                (r, v, w, report.nlgs)
            })
        }
    }

    fn v_len(l: &Lattice) -> usize {
        l.velocity.len()
    }

    fn slabs() -> Partitioning {
        Partitioning::even_slabs(0, -0.5, 5.5, 3)
    }

    #[test]
    fn blocks_are_claimed_largest_first() {
        // Ties keep the numbering (a stable sort).
        assert_eq!(Team::new(&[3, 1, 6, 0, 3]).order, [2, 0, 4, 1, 3]);
    }

    #[test]
    fn synchronous_is_bitwise_sequential_nlgs_on_any_thread_count() {
        let l = lattice(6, 3, 4);
        let (rows, d) = l.decomposed(&slabs());
        assert!(d.subdomains.iter().all(|r| !r.is_empty()) && !d.interface.is_empty());
        for options in [
            NlgsOptions {
                stopping: Stopping::Sweeps(40),
                error_check: ErrorCheck::Light { every: 20 },
            },
            NlgsOptions {
                stopping: Stopping::Tolerance {
                    tolerance: 1e-10,
                    max_sweeps: 5000,
                },
                error_check: ErrorCheck::EverySweep,
            },
        ] {
            let plain = l.solve_plain(&rows, &options);
            for threads in [1, 2, 4] {
                let sync = l.solve_ddm(
                    &slabs(),
                    &options,
                    &DdmOptions::new(Driver::Synchronous),
                    threads,
                );
                assert_eq!(sync.0, plain.0, "impulses, {threads} threads, {options:?}");
                assert_eq!(sync.1, plain.1, "velocities, {threads} threads");
                assert_eq!(sync.2, plain.2, "angular velocities, {threads} threads");
                assert_eq!(sync.3.iterations, plain.3.iterations);
                assert_eq!(sync.3.error.to_bits(), plain.3.error.to_bits());
            }
            assert!(plain.3.converged, "{:?}", plain.3);
        }
    }

    #[test]
    fn more_sweeps_per_iteration_stay_independent_of_threads() {
        let l = lattice(6, 3, 4);
        let options = NlgsOptions {
            stopping: Stopping::Sweeps(15),
            error_check: ErrorCheck::EverySweep,
        };
        for driver in [Driver::Synchronous, Driver::Asynchronous] {
            let ddm = DdmOptions {
                driver,
                subdomain_sweeps: 3,
                interface_sweeps: 2,
            };
            let one = l.solve_ddm(&slabs(), &options, &ddm, 1);
            for threads in [2, 4] {
                let many = l.solve_ddm(&slabs(), &options, &ddm, threads);
                assert_eq!(one.0, many.0, "{driver:?}, {threads} threads");
                assert_eq!(one.1, many.1, "{driver:?}, {threads} threads");
            }
        }
    }

    #[test]
    fn asynchronous_converges_to_a_coulomb_solution() {
        // Block Jacobi between blocks converges more slowly than Gauss–Seidel (6 735
        // iterations against 2 035 when written), but to
        // a solution of the same problem: the same error measure reaches the tolerance,
        // and the total vertical impulse on the falling lattice is the same (it must
        // stop 72 unit masses falling at about 1 m/s) to the tolerance.
        let l = lattice(6, 3, 4);
        let options = NlgsOptions {
            stopping: Stopping::Tolerance {
                tolerance: 1e-8,
                max_sweeps: 20_000,
            },
            error_check: ErrorCheck::Light { every: 10 },
        };
        let sync = l.solve_ddm(&slabs(), &options, &DdmOptions::new(Driver::Synchronous), 2);
        let asyn = l.solve_ddm(
            &slabs(),
            &options,
            &DdmOptions::new(Driver::Asynchronous),
            2,
        );
        assert!(
            sync.3.converged && asyn.3.converged,
            "{:?} {:?}",
            sync.3,
            asyn.3
        );
        assert!(
            asyn.3.iterations >= sync.3.iterations,
            "{:?} {:?}",
            sync.3,
            asyn.3
        );
        let momentum = |s: &Solution| s.1.iter().skip(1).map(|v| v.z).sum::<f64>();
        let (ms, ma) = (momentum(&sync), momentum(&asyn));
        assert!((ms - ma).abs() < 1e-5 * 72.0, "{ms} vs {ma}");
    }
}
