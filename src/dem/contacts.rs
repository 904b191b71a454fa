//! Contacts between vertex spheres of different bodies, and between spheres and fixed
//! planes (the rigid base, side walls), with a Verlet list: the pairs closer than
//! r_i + r_j + skin are found by [`super::neighbours`] and kept until some sphere has
//! moved more than half the skin, so the cell search runs every few hundred steps, not
//! every step. Each pair carries its tangential spring across steps and rebuilds.
//!
//! Forces are computed pair by pair in parallel (each pair writes only its own record
//! and force) and gathered per sphere in the order of the sphere's pair list: the sums,
//! hence the whole run, are bitwise the same on any number of threads.

use std::ops::Range;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::law::{dot, norm, scale, sub, ContactLaw, PairForce};
use super::neighbours::{close_pairs, Period};

/// A fixed plane: the half-space (x − point)·normal ≥ 0 is free.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Plane {
    /// A point on the plane (m).
    pub point: [f64; 3],
    /// Unit normal pointing into the free side.
    pub normal: [f64; 3],
    /// Index of the plane's material in the law table.
    pub material: u16,
}

/// The immutable description of the spheres and planes.
#[derive(Debug, Clone)]
pub struct SphereSet {
    /// Radius of each sphere (m).
    pub radius: Vec<f64>,
    /// The body each sphere belongs to (no contact within a body).
    pub owner: Vec<u32>,
    /// Material index of each sphere.
    pub material: Vec<u16>,
    /// Mass that moves with each sphere for the dashpot's reduced mass (kg): the node's
    /// lumped mass, or a rigid body's mass.
    pub mass: Vec<f64>,
    /// Fixed planes.
    pub planes: Vec<Plane>,
    /// `laws[a * materials + b]`: the law between materials a and b.
    pub laws: Vec<ContactLaw>,
    /// Number of materials.
    pub materials: usize,
    /// Periodicity, if any.
    pub period: Option<Period>,
    /// Whether the pairs resting at their first-build overlap share one spring per
    /// pair of bodies (or body and plane): each of the n pairs carries 1/n of its
    /// force (`track.rest_pairs = "shared"`); false: each is a full spring.
    pub shared_rest: bool,
}

impl SphereSet {
    fn law_index(&self, a: u16, b: u16) -> u32 {
        (a as usize * self.materials + b as usize) as u32
    }

    /// The constants of a pair ([`PairConstants`]), each computed in one fixed order of
    /// operations, so the force loop's bits do not depend on when they were gathered.
    /// A pair's constants; `rank` gives each touched sphere's place in the touched
    /// list ([`PairConstants::a`]).
    fn constants(&self, p: &PairState, rank: &[u32]) -> PairConstants {
        let i = p.first as usize;
        if p.second & PLANE != 0 {
            let plane = &self.planes[(p.second & !PLANE) as usize];
            PairConstants {
                reach: self.radius[i],
                m_eff: self.mass[i],
                law: self.law_index(plane.material, self.material[i]),
                a: rank[i],
                b: 0,
            }
        } else {
            let j = p.second as usize;
            let (mi, mj) = (self.mass[i], self.mass[j]);
            PairConstants {
                reach: self.radius[i] + self.radius[j],
                m_eff: mi * mj / (mi + mj),
                law: self.law_index(self.material[i], self.material[j]),
                a: rank[i],
                b: rank[j],
            }
        }
    }

    /// The largest radius.
    pub fn max_radius(&self) -> f64 {
        self.radius.iter().fold(0.0, |m, &r| m.max(r))
    }
}

/// Marks a pair whose second member is a plane: `second = PLANE | plane index`.
const PLANE: u32 = 1 << 31;

/// One candidate pair and its history.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PairState {
    /// First sphere.
    pub first: u32,
    /// Second sphere, or `PLANE | plane`.
    pub second: u32,
    /// Tangential spring elongation (m).
    pub xi: [f64; 3],
    /// Rest overlap (m): the overlap of a pair already overlapping when the list was
    /// first built, which then carries no force (an imported packing starts at rest
    /// rather than exploding); 0 for pairs that meet later. A resting pair keeps it
    /// for the whole run, also after it has left the list and come back
    /// ([`ContactState::resting`]).
    pub rest: f64,
    /// Share of the law's force this pair carries: 1, or 1/n for one of the n resting
    /// pairs of a pair of bodies when the set's `shared_rest` is on.
    pub share: f64,
}

/// The evolving contact state (what a checkpoint stores).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactState {
    /// Candidate pairs, sorted by (first, second).
    pub pairs: Vec<PairState>,
    /// The pairs that overlapped when the list was first built, with their rest
    /// overlap and share, sorted by (first, second): kept for the run, so a resting
    /// pair that drifts out of the list and back rests where it did, whatever the skin.
    pub resting: Vec<RestingPair>,
    /// Sphere positions at the last rebuild.
    pub anchors: Vec<[f64; 3]>,
    /// Rebuilds so far.
    pub rebuilds: u64,
}

/// A pair that overlapped when the list was first built ([`PairState::rest`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RestingPair {
    /// First sphere.
    pub first: u32,
    /// Second sphere, or `PLANE | plane`.
    pub second: u32,
    /// Rest overlap (m).
    pub rest: f64,
    /// Share of the law's force ([`PairState::share`]).
    pub share: f64,
}

/// What a pair's force needs of its two members that does not change during a run,
/// gathered at each rebuild beside the pair list: the force loop then reads two
/// scattered sphere records per pair (position, velocity) instead of five (with
/// radius, mass and material), the cache misses of a large track.
#[derive(Debug, Clone, Copy)]
struct PairConstants {
    /// r_i + r_j for two spheres, r_i for a sphere and a plane (m).
    reach: f64,
    /// The dashpot's reduced mass (kg): m_i m_j / (m_i + m_j), or m_i against a plane.
    m_eff: f64,
    /// The pair's law: an index into [`SphereSet::laws`].
    law: u32,
    /// The first and second sphere's places in [`Contacts::touched`] (the second's
    /// unused for a plane pair): the force loop reads the touched spheres' positions
    /// and velocities from arrays in that order, not from the whole sphere set's.
    a: u32,
    b: u32,
}

/// Totals of one contact evaluation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactTotals {
    /// Pairs in contact (overlap > 0), spheres with spheres.
    pub touching: usize,
    /// Spheres touching a plane.
    pub touching_planes: usize,
    /// Candidate pairs in the Verlet list.
    pub candidates: usize,
    /// Deepest sphere overlap (m).
    pub max_overlap: f64,
    /// Mean overlap over touching pairs (m).
    pub mean_overlap: f64,
    /// Stored spring energy (J).
    pub spring_energy: f64,
    /// Energy taken by sliders this step (J).
    pub slip_dissipated: f64,
    /// Energy taken by dashpots this step (J).
    pub damping_dissipated: f64,
    /// Whether the list was rebuilt this step.
    pub rebuilt: bool,
}

/// The contact engine: sphere set, skin, and the per-sphere gather lists.
#[derive(Debug, Clone)]
pub struct Contacts {
    /// The spheres and planes.
    pub set: SphereSet,
    /// Verlet skin (m).
    pub skin: f64,
    /// gather[offsets[t]..offsets[t + 1]]: (pair index, +1 second / −1 first) of the
    /// touched sphere `touched[t]`.
    offsets: Vec<u32>,
    gather: Vec<(u32, f64)>,
    /// One per candidate pair, in the list's order.
    constants: Vec<PairConstants>,
    /// Each candidate pair's force on its second member this step (N), in the list's
    /// order: apart from [`PairState`] so that the per-sphere gather, which reads them
    /// in a scattered order, loads 24 bytes a pair instead of the whole record.
    pair_forces: Vec<[f64; 3]>,
    /// The spheres with at least one candidate pair, ascending: the only ones whose
    /// force can be non-zero until the next rebuild.
    touched: Vec<u32>,
    /// Their forces (N), in the same order.
    touched_forces: Vec<[f64; 3]>,
    /// Set when the list changes: the next evaluation zeroes every sphere's force
    /// first, so that spheres no longer touched do not keep an old one.
    clear_forces: bool,
}

/// Below this many pairs the force loop runs on the calling thread.
const PARALLEL_MIN_PAIRS: usize = 4096;

/// Pairs per chunk of the force loop (the unit of its ordered reduction).
const PAIR_CHUNK: usize = 1024;

impl Contacts {
    /// An engine over `set` with Verlet skin `skin` (m).
    pub fn new(set: SphereSet, skin: f64) -> Self {
        Contacts {
            set,
            skin,
            offsets: Vec::new(),
            gather: Vec::new(),
            constants: Vec::new(),
            pair_forces: Vec::new(),
            touched: Vec::new(),
            touched_forces: Vec::new(),
            clear_forces: true,
        }
    }

    /// Whether the candidate list must be rebuilt for `positions`: the first call, or
    /// some sphere has moved more than half the skin since the last build.
    pub fn stale(&self, state: &ContactState, positions: &[[f64; 3]]) -> bool {
        self.stale_among(state, positions, std::iter::once(0..positions.len()))
    }

    /// [`Self::stale`], with only the spheres in `ranges` scanned for their move: for a
    /// caller that knows the others cannot have moved half the skin.
    pub fn stale_among(
        &self,
        state: &ContactState,
        positions: &[[f64; 3]],
        ranges: impl IntoIterator<Item = Range<usize>>,
    ) -> bool {
        let n = positions.len();
        let limit = 0.25 * self.skin * self.skin;
        state.anchors.len() != n
            || self.offsets.is_empty()
            || ranges.into_iter().any(|range| {
                positions[range.clone()]
                    .iter()
                    .zip(&state.anchors[range])
                    .any(|(p, a)| {
                        let d = sub(*p, *a);
                        dot(d, d) > limit
                    })
            })
    }

    /// The spheres that have a candidate pair in the current list, ascending. Only
    /// they can carry a force, and only their positions and velocities are read by
    /// [`Self::forces`].
    pub fn touched(&self) -> &[u32] {
        &self.touched
    }

    /// The touched spheres' contact forces (N) of the last [`Self::forces_touched`] (or
    /// [`Self::forces`]), in the order of [`Self::touched`].
    pub fn touched_forces(&self) -> &[[f64; 3]] {
        &self.touched_forces
    }

    /// Rebuilds the candidate list if needed (first call, or a sphere moved more than
    /// half the skin since the last build); whether it did.
    pub fn refresh(&mut self, state: &mut ContactState, positions: &[[f64; 3]]) -> bool {
        let stale = self.stale(state, positions);
        if stale {
            self.rebuild(state, positions);
        }
        stale
    }

    /// Rebuilds the candidate list for `positions`, keeping the tangential springs of
    /// pairs that stay, and the rest of resting pairs.
    pub fn rebuild(&mut self, state: &mut ContactState, positions: &[[f64; 3]]) {
        let n = positions.len();
        let mut fresh: Vec<PairState> = self
            .within(positions, self.skin)
            .into_iter()
            .map(|(first, second)| PairState {
                first,
                second,
                xi: [0.0; 3],
                rest: 0.0,
                share: 1.0,
            })
            .collect();
        fresh.sort_unstable_by_key(|p| (p.first, p.second));
        // Carry the springs of pairs in both lists, and the rest of resting pairs
        // (all sorted: merge joins).
        let old = std::mem::take(&mut state.pairs);
        let (mut k, mut r) = (0, 0);
        let resting = &state.resting;
        for p in &mut fresh {
            let key = (p.first, p.second);
            while k < old.len() && (old[k].first, old[k].second) < key {
                k += 1;
            }
            if k < old.len() && (old[k].first, old[k].second) == key {
                p.xi = old[k].xi;
            }
            while r < resting.len() && (resting[r].first, resting[r].second) < key {
                r += 1;
            }
            if r < resting.len() && (resting[r].first, resting[r].second) == key {
                p.rest = resting[r].rest;
                p.share = resting[r].share;
            }
        }
        if state.rebuilds == 0 {
            for p in &mut fresh {
                p.rest = self.overlap(p, positions).max(0.0);
            }
            if self.set.shared_rest {
                self.share_rest(&mut fresh);
            }
            state.resting = fresh
                .iter()
                .filter(|p| p.rest > 0.0)
                .map(|p| RestingPair {
                    first: p.first,
                    second: p.second,
                    rest: p.rest,
                    share: p.share,
                })
                .collect();
        }
        state.pairs = fresh;
        state.anchors = positions.to_vec();
        state.rebuilds += 1;
        self.index_gather(&state.pairs, n);
    }

    /// The sphere pairs of different bodies closer than r_i + r_j + `gap`, and the
    /// sphere–plane pairs closer than r_i + `gap`, as (first, second) with
    /// `second = PLANE | plane` for the latter; unsorted. The Verlet list is this with
    /// the skin; the stable step counts the pairs within a fixed gap
    /// ([`super::system::STABLE_STEP_GAP`]), whatever the skin.
    pub fn within(&self, positions: &[[f64; 3]], gap: f64) -> Vec<(u32, u32)> {
        let cutoff = 2.0 * self.set.max_radius() + gap;
        let period = self.set.period.as_ref();
        let radius = &self.set.radius;
        let mut pairs: Vec<(u32, u32)> = close_pairs(positions, &self.set.owner, cutoff, period)
            .into_iter()
            .filter(|&(i, j)| {
                let d = Period::difference(period, positions[i as usize], positions[j as usize]);
                norm(d) < radius[i as usize] + radius[j as usize] + gap
            })
            .collect();
        for (i, p) in positions.iter().enumerate() {
            for (k, plane) in self.set.planes.iter().enumerate() {
                if dot(sub(*p, plane.point), plane.normal) - radius[i] < gap {
                    pairs.push((i as u32, PLANE | k as u32));
                }
            }
        }
        pairs
    }

    /// Takes up a saved contact state (resuming a run): indexes its pairs for the
    /// gather without rebuilding the list, so the run goes on as if never stopped.
    pub fn restore(&mut self, state: &ContactState) {
        self.index_gather(&state.pairs, state.anchors.len());
    }

    /// The geometric overlap of a pair (m; negative: a gap).
    fn overlap(&self, p: &PairState, positions: &[[f64; 3]]) -> f64 {
        let set = &self.set;
        let i = p.first as usize;
        if p.second & PLANE != 0 {
            let plane = &set.planes[(p.second & !PLANE) as usize];
            set.radius[i] - dot(sub(positions[i], plane.point), plane.normal)
        } else {
            let j = p.second as usize;
            let d = Period::difference(set.period.as_ref(), positions[i], positions[j]);
            set.radius[i] + set.radius[j] - norm(d)
        }
    }

    fn index_gather(&mut self, pairs: &[PairState], n: usize) {
        let mut counts = vec![0u32; n];
        for p in pairs {
            counts[p.first as usize] += 1;
            if p.second & PLANE == 0 {
                counts[p.second as usize] += 1;
            }
        }
        // The touched spheres, ascending, and each sphere's place among them.
        let mut rank = vec![u32::MAX; n];
        self.touched.clear();
        let mut offsets = vec![0u32];
        for (s, &c) in counts.iter().enumerate() {
            if c > 0 {
                rank[s] = self.touched.len() as u32;
                self.touched.push(s as u32);
                offsets.push(offsets[offsets.len() - 1] + c);
            }
        }
        let mut fill = offsets.clone();
        let mut gather = vec![(0u32, 0.0); offsets[offsets.len() - 1] as usize];
        for (k, p) in pairs.iter().enumerate() {
            // The law gives the force on the second member; a plane pair's sphere is
            // its first member but plays the second (the normal points to it).
            let f = &mut fill[rank[p.first as usize] as usize];
            let sign = if p.second & PLANE != 0 { 1.0 } else { -1.0 };
            gather[*f as usize] = (k as u32, sign);
            *f += 1;
            if p.second & PLANE == 0 {
                let f = &mut fill[rank[p.second as usize] as usize];
                gather[*f as usize] = (k as u32, 1.0);
                *f += 1;
            }
        }
        self.constants = pairs.iter().map(|p| self.set.constants(p, &rank)).collect();
        self.pair_forces = vec![[0.0; 3]; pairs.len()];
        self.touched_forces = vec![[0.0; 3]; self.touched.len()];
        self.clear_forces = true;
        self.offsets = offsets;
        self.gather = gather;
    }

    /// Gives each of the n resting pairs (rest overlap > 0) of one pair of bodies, or of
    /// a body and a plane, the share 1/n (`SphereSet::shared_rest`).
    fn share_rest(&self, pairs: &mut [PairState]) {
        let owner = &self.set.owner;
        let key = |p: &PairState| {
            let a = owner[p.first as usize];
            if p.second & PLANE != 0 {
                (a, p.second)
            } else {
                let b = owner[p.second as usize];
                (a.min(b), a.max(b))
            }
        };
        let mut count: std::collections::HashMap<(u32, u32), u32> = Default::default();
        for p in pairs.iter().filter(|p| p.rest > 0.0) {
            *count.entry(key(p)).or_default() += 1;
        }
        for p in pairs.iter_mut().filter(|p| p.rest > 0.0) {
            p.share = 1.0 / count[&key(p)] as f64;
        }
    }

    /// [`Self::refresh`], then [`Self::forces`]: the list brought up to date, then the
    /// forces on it.
    pub fn evaluate(
        &mut self,
        state: &mut ContactState,
        positions: &[[f64; 3]],
        velocities: &[[f64; 3]],
        dt: f64,
        forces: &mut [[f64; 3]],
    ) -> ContactTotals {
        let rebuilt = self.refresh(state, positions);
        let mut totals = self.forces(state, positions, velocities, dt, forces);
        totals.rebuilt = rebuilt;
        totals
    }

    /// Contact forces on the current list for sphere positions and velocities (the
    /// half-step velocities in Verlet), written into `forces` (one per sphere; the
    /// caller keeps the buffer from call to call: only the [`Self::touched`] spheres'
    /// entries are rewritten, the others are zeroed when the list changes); `dt`
    /// advances the tangential springs. Only the touched spheres' positions and
    /// velocities are read. The list is not checked: see [`Self::evaluate`].
    pub fn forces(
        &mut self,
        state: &mut ContactState,
        positions: &[[f64; 3]],
        velocities: &[[f64; 3]],
        dt: f64,
        forces: &mut [[f64; 3]],
    ) -> ContactTotals {
        let (x, v): (Vec<[f64; 3]>, Vec<[f64; 3]>) = self
            .touched
            .iter()
            .map(|&s| (positions[s as usize], velocities[s as usize]))
            .unzip();
        let totals = self.forces_touched(state, &x, &v, dt);
        if std::mem::take(&mut self.clear_forces) {
            forces.fill([0.0; 3]);
        }
        for (&s, f) in self.touched.iter().zip(&self.touched_forces) {
            forces[s as usize] = *f;
        }
        totals
    }

    /// [`Self::forces`] for the touched spheres alone: `x` and `v` hold their positions
    /// and velocities in the order of [`Self::touched`], and their forces are left in
    /// [`Self::touched_forces`], in that order too. The force loop reads the second
    /// member of each pair at random: from arrays of the touched spheres alone that
    /// read stays in cache, where from the whole set's (118 089 spheres on the paper
    /// bed, 2.8 MB an array) it did not.
    pub fn forces_touched(
        &mut self,
        state: &mut ContactState,
        x: &[[f64; 3]],
        v: &[[f64; 3]],
        dt: f64,
    ) -> ContactTotals {
        assert_eq!(
            self.constants.len(),
            state.pairs.len(),
            "contact list not indexed: refresh or restore it first"
        );
        let n = self.touched.len();
        assert!(
            x.len() == n && v.len() == n,
            "one position and one velocity per touched sphere"
        );
        let set = &self.set;
        let period = set.period.as_ref();
        type Pair<'a> = ((&'a mut PairState, &'a mut [f64; 3]), &'a PairConstants);
        let one = |((p, pf), c): Pair| -> (PairForce, f64, bool) {
            let i = c.a as usize;
            let (n, overlap, v_rel, plane) = if p.second & PLANE != 0 {
                let plane = &set.planes[(p.second & !PLANE) as usize];
                let gap = dot(sub(x[i], plane.point), plane.normal) - c.reach;
                // The sphere is the "second" body seen from the plane: n points to it.
                (plane.normal, -gap, v[i], true)
            } else {
                let j = c.b as usize;
                let d = Period::difference(period, x[i], x[j]);
                // Apart (beyond the rest overlap): no force, and no square root.
                let reach = c.reach - p.rest;
                if dot(d, d) >= reach * reach {
                    forget_spring(p);
                    *pf = [0.0; 3];
                    return (PairForce::default(), 0.0, false);
                }
                let dist = norm(d);
                let overlap = c.reach - dist;
                let n = if dist > 0.0 {
                    scale(d, 1.0 / dist)
                } else {
                    [0.0, 0.0, 1.0]
                };
                (n, overlap, sub(v[j], v[i]), false)
            };
            let overlap = overlap - p.rest;
            if overlap <= 0.0 {
                forget_spring(p);
                *pf = [0.0; 3];
                return (PairForce::default(), 0.0, plane);
            }
            let law = &set.laws[c.law as usize];
            let mut f = law.force(n, overlap, v_rel, &mut p.xi, c.m_eff, dt);
            if p.share != 1.0 {
                // One of n resting pairs sharing a spring. The slider's limit scales with
                // the normal force, so the spring slips where the full one would; the
                // dashpot scales too, so the cluster is one spring and dashpot of the
                // law's damping ratio.
                f = f.scaled(p.share);
            }
            *pf = f.force;
            (f, overlap, plane)
        };
        let fold = |mut t: ContactTotals, (f, overlap, plane): (PairForce, f64, bool)| {
            if overlap > 0.0 {
                if plane {
                    t.touching_planes += 1;
                } else {
                    t.touching += 1;
                    t.mean_overlap += overlap;
                }
                t.max_overlap = t.max_overlap.max(overlap);
                t.spring_energy += f.spring_energy;
                t.slip_dissipated += f.slip_dissipated;
                t.damping_dissipated += f.damping_dissipated;
            }
            t
        };
        // Fixed chunks of pairs, each folded in order, then the chunk totals folded in
        // order: the sums do not depend on the thread count.
        type Chunk<'a> = (
            (&'a mut [PairState], &'a mut [[f64; 3]]),
            &'a [PairConstants],
        );
        let chunk = |((pairs, forces), constants): Chunk| {
            pairs
                .iter_mut()
                .zip(forces.iter_mut())
                .zip(constants)
                .map(one)
                .fold(ContactTotals::default(), fold)
        };
        let (constants, pair_forces) = (&self.constants, &mut self.pair_forces);
        let partials: Vec<ContactTotals> = if state.pairs.len() >= PARALLEL_MIN_PAIRS {
            state
                .pairs
                .par_chunks_mut(PAIR_CHUNK)
                .zip(pair_forces.par_chunks_mut(PAIR_CHUNK))
                .zip(constants.par_chunks(PAIR_CHUNK))
                .map(chunk)
                .collect()
        } else {
            state
                .pairs
                .chunks_mut(PAIR_CHUNK)
                .zip(pair_forces.chunks_mut(PAIR_CHUNK))
                .zip(constants.chunks(PAIR_CHUNK))
                .map(chunk)
                .collect()
        };
        let mut totals = partials
            .into_iter()
            .fold(ContactTotals::default(), |mut t, c| {
                t.touching += c.touching;
                t.touching_planes += c.touching_planes;
                t.mean_overlap += c.mean_overlap;
                t.max_overlap = t.max_overlap.max(c.max_overlap);
                t.spring_energy += c.spring_energy;
                t.slip_dissipated += c.slip_dissipated;
                t.damping_dissipated += c.damping_dissipated;
                t
            });
        if totals.touching > 0 {
            totals.mean_overlap /= totals.touching as f64;
        }
        totals.candidates = state.pairs.len();
        let pair_forces = &self.pair_forces;
        let (offsets, gather) = (&self.offsets, &self.gather);
        let sum = |(t, f): (usize, &mut [f64; 3])| {
            let mut acc = [0.0; 3];
            for &(k, sign) in &gather[offsets[t] as usize..offsets[t + 1] as usize] {
                let pf = pair_forces[k as usize];
                for d in 0..3 {
                    acc[d] += sign * pf[d];
                }
            }
            *f = acc;
        };
        let summed = &mut self.touched_forces;
        if summed.len() >= PARALLEL_MIN_PAIRS {
            summed.par_iter_mut().enumerate().for_each(sum);
        } else {
            summed.iter_mut().enumerate().for_each(sum);
        }
        totals
    }
}

/// Zeroes a pair's tangential spring when it is apart, writing only when it is not
/// zero already (compared bit for bit, so a −0 is still reset to +0): most candidate
/// pairs stay apart step after step, and leaving their records unwritten keeps those
/// cache lines clean.
fn forget_spring(p: &mut PairState) {
    if p.xi.iter().any(|x| x.to_bits() != 0) {
        p.xi = [0.0; 3];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::law::SphereMaterial;

    fn set(n: usize, owner: Vec<u32>) -> SphereSet {
        let m = SphereMaterial {
            normal_stiffness: 1e6,
            tangential_stiffness: 4e5,
        };
        SphereSet {
            radius: vec![0.012; n],
            owner,
            material: vec![0; n],
            mass: vec![1.0; n],
            planes: vec![Plane {
                point: [0.0; 3],
                normal: [0.0, 0.0, 1.0],
                material: 0,
            }],
            laws: vec![ContactLaw::between(&m, &m, 0.5, 0.0)],
            materials: 1,
            period: None,
            shared_rest: false,
        }
    }

    #[test]
    fn forces_are_equal_and_opposite_and_the_plane_pushes_up() {
        let mut c = Contacts::new(set(3, vec![0, 1, 1]), 0.005);
        let mut state = ContactState::default();
        // The first list is built apart (pairs overlapping then would rest there).
        let apart = [[0.0, 0.0, 0.5], [0.03, 0.0, 0.5], [0.5, 0.0, 0.02]];
        let mut f = [[0.0; 3]; 3];
        c.evaluate(&mut state, &apart, &[[0.0; 3]; 3], 1e-5, &mut f);
        assert!(f.iter().flatten().all(|&x| x == 0.0));
        // Sphere 0 overlaps sphere 1 by 4 mm; 1 and 2 share a body; 2 sits 2 mm into the floor.
        let x = [[0.0, 0.0, 0.5], [0.02, 0.0, 0.5], [0.5, 0.0, 0.010]];
        let v = [[0.0; 3]; 3];
        let t = c.evaluate(&mut state, &x, &v, 1e-5, &mut f);
        assert_eq!((t.touching, t.touching_planes), (1, 1));
        assert!((f[0][0] + 1e6 * 0.004).abs() < 1e-6 && (f[1][0] - 1e6 * 0.004).abs() < 1e-6);
        assert!((f[2][2] - 1e6 * 0.002).abs() < 1e-6);
        assert!((t.max_overlap - 0.004).abs() < 1e-12);
        let e = 0.5 * 1e6 * (0.004f64.powi(2) + 0.002f64.powi(2));
        assert!((t.spring_energy - e).abs() < 1e-9);
        // No rebuild while nothing moves; a move past half the skin rebuilds.
        assert!(!c.evaluate(&mut state, &x, &v, 1e-5, &mut f).rebuilt);
        let moved = [[0.0, 0.0, 0.5], [0.02, 0.0, 0.5], [0.5, 0.0, 0.013]];
        assert!(c.evaluate(&mut state, &moved, &v, 1e-5, &mut f).rebuilt);
    }

    /// A pair that overlapped when the list was first built rests at that overlap for
    /// the whole run: pulled out of the list (past the skin) and pushed back to where
    /// it started, it carries no force; pushed 0.5 mm further, k · 0.5 mm.
    #[test]
    fn a_resting_pair_keeps_its_rest_after_leaving_the_list() {
        let mut c = Contacts::new(set(2, vec![0, 1]), 0.0005);
        let mut state = ContactState::default();
        let v = [[0.0; 3]; 2];
        let mut f = [[0.0; 3]; 2];
        // 1 mm into each other (centres 23 mm apart, radii 12 mm).
        let at = |gap: f64| [[0.0, 0.0, 0.5], [0.023 + gap, 0.0, 0.5]];
        c.evaluate(&mut state, &at(0.0), &v, 1e-5, &mut f);
        assert_eq!(state.pairs.len(), 1);
        assert!(f.iter().flatten().all(|&x| x == 0.0), "at rest");
        // 5 mm apart: past rest + skin, out of the list.
        assert!(c.evaluate(&mut state, &at(0.006), &v, 1e-5, &mut f).rebuilt);
        assert!(state.pairs.is_empty());
        // Back where it started: in the list again, at rest.
        assert!(c.evaluate(&mut state, &at(0.0), &v, 1e-5, &mut f).rebuilt);
        assert_eq!(state.pairs.len(), 1);
        assert!(f.iter().flatten().all(|&x| x == 0.0), "back at rest: {f:?}");
        c.evaluate(&mut state, &at(-0.0005), &v, 1e-5, &mut f);
        assert!((f[1][0] - 1e6 * 0.0005).abs() < 1e-6, "{f:?}");
    }

    /// Shared rest: a body resting on another through three overlapping sphere pairs,
    /// and one on the floor through two, share one spring per touching pair (a 0.5 mm
    /// push gives k · 0.5 mm, not 3 k · 0.5 mm); a pair that meets later is a full spring.
    #[test]
    fn resting_pairs_of_one_body_pair_share_one_spring() {
        let mut shared = set(10, vec![0, 0, 0, 1, 1, 1, 2, 2, 3, 4]);
        shared.shared_rest = true;
        let mut c = Contacts::new(shared, 0.005);
        let mut state = ContactState::default();
        // Body 0 over body 1, 1 mm into it (centres 23 mm apart, radii 12 mm); body 2
        // 1 mm into the floor; body 4's sphere 10 mm above body 3's.
        let mut x = [[0.0; 3]; 10];
        for k in 0..3 {
            x[k] = [0.1 * k as f64, 0.0, 0.5];
            x[3 + k] = [0.1 * k as f64, 0.0, 0.477];
        }
        x[6] = [0.5, 0.0, 0.011];
        x[7] = [0.6, 0.0, 0.011];
        x[8] = [0.8, 0.0, 0.3];
        x[9] = [0.8, 0.0, 0.334];
        let v = [[0.0; 3]; 10];
        let mut forces = [[0.0; 3]; 10];
        c.evaluate(&mut state, &x, &v, 1e-5, &mut forces);
        assert!(forces.iter().flatten().all(|&f| f == 0.0), "at rest");
        let mut shares: Vec<f64> = state.pairs.iter().map(|p| p.share).collect();
        shares.sort_by(f64::total_cmp);
        assert_eq!(
            shares,
            [1.0 / 3.0; 3]
                .into_iter()
                .chain([0.5; 2])
                .collect::<Vec<_>>()
        );
        // Body 0 pressed 0.5 mm further, body 2 too, and body 4 brought 4 mm into body 3
        // (a rebuild, which keeps the shares).
        for k in [0, 1, 2, 6, 7] {
            x[k][2] -= 0.0005;
        }
        x[9][2] = 0.32;
        assert!(c.evaluate(&mut state, &x, &v, 1e-5, &mut forces).rebuilt);
        let on = |r: std::ops::Range<usize>| forces[r].iter().map(|f| f[2]).sum::<f64>();
        assert!(
            (on(0..3) - 1e6 * 0.0005).abs() < 1e-6,
            "body 0: {}",
            on(0..3)
        );
        assert!(
            (on(6..8) - 1e6 * 0.0005).abs() < 1e-6,
            "body 2: {}",
            on(6..8)
        );
        assert!(
            (on(9..10) - 1e6 * 0.004).abs() < 1e-6,
            "body 4: {}",
            on(9..10)
        );
    }
}
