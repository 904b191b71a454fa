//! NLGS in body-velocity form (seed 000 §2.1.3 without assembling W).
//!
//! The unknowns are the contact impulses r_a and the bodies' velocities V, kept equal
//! to `V_free + M⁻¹ H r` at all times. Contact a between bodies i (normal away from it)
//! and j, with local frame F = [n t s] and lever arms d = p − x:
//!
//! - its relative velocity is `u_a = Fᵀ(v_j − v_i) + A_jᵀ ω_j − A_iᵀ ω_i` (plus the gap
//!   shift on the normal component), with `A = [d×n, d×t, d×s]`;
//! - its diagonal Delassus block is `W_aa = (1/m_i + 1/m_j) I + A_iᵀ I_i⁻¹ A_i + A_jᵀ I_j⁻¹ A_j`;
//! - after the exact local solve ([`LocalCoulomb::solve`]) on the local free velocity
//!   `u_a − W_aa r_a`, the change Δr_a is applied to the two bodies in place:
//!   `v_j += F Δr / m_j`, `ω_j += I_j⁻¹ A_j Δr`, and the opposite on i.
//!
//! A sweep costs O(contacts) and never forms an off-diagonal block.
//!
//! # Error measure
//! The Siconos measure ([`super::residual`]) on the problem with each contact's impulse
//! scaled to a velocity, `r̂_a = W_aa,nn r_a` (Coulomb's law is invariant under this
//! scaling, so the measure is zero exactly at a solution, and both terms are in m/s):
//! `√(Σ_a ‖r̂_a − Π_K(r̂_a − ũ_a)‖²) / max(‖q‖, ‖r̂‖, ‖u‖)`, with q the local free
//! velocities (the relative velocities before any impulse).

use std::marker::PhantomData;
use std::ops::Range;
use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::coulomb::{coulomb_residual_squared, invert, ContactStatus, LocalCoulomb};
use super::nlgs::{NlgsOptions, NlgsReport, Stopping};
use crate::simd::{F64x4, Portable4};

/// Contacts per parallel task of the error measure (fixed, so that its partial sums,
/// and so the stopping decision, do not depend on the thread count).
const MEASURE_CHUNK: usize = 1024;

/// How many contacts ahead the sweep asks for the record of a contact that carries an
/// impulse (a few hundred ns of work at 6–60 ns a contact: about one memory latency).
const PREFETCH_AHEAD: usize = 8;

/// One contact of the body-velocity problem.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactRow {
    /// The two bodies; the normal points from the first to the second.
    pub bodies: [u32; 2],
    /// The local frame `[n, t, s]` (world).
    pub frame: [Vector3<f64>; 3],
    /// Lever arms: contact point minus each body's mass centre (world).
    pub arms: [Vector3<f64>; 2],
    /// Added to the normal relative velocity (gap prediction, m/s).
    pub shift: f64,
    /// Friction coefficient.
    pub mu: f64,
}

/// The bodies' side of the problem: inverse masses and world inverse inertias (zero for
/// bodies that the contacts do not move).
#[derive(Debug, Clone, Copy)]
pub struct BodyInverses<'a> {
    /// 1/m per body.
    pub inverse_mass: &'a [f64],
    /// I⁻¹ (world) per body.
    pub inverse_inertia: &'a [Matrix3<f64>],
}

/// The part of a contact's sweep data that every sweep reads: the normal row of the
/// local Jacobian, the gap shift and the two bodies. An open contact that separates
/// (four in five in a bed at rest) needs nothing else, so these rows are kept apart
/// from the rest ([`Prepared`]) and a sweep streams 112 bytes a contact for it instead
/// of the whole record: on a large bed that path is bound by memory traffic
/// (docs/ddm.md, "Drivers": 22 → 6 ns a contact).
#[derive(Debug, Clone)]
#[repr(C)]
pub(crate) struct NormalRow {
    /// `[f_n, A_j,n, A_i,n]`, acting on `v_j − v_i`, `ω_j` and `−ω_i`.
    jacobian: [[f64; 4]; 3],
    /// Added to the normal relative velocity (gap prediction, m/s).
    shift: f64,
    /// The two bodies (indices in the state the contact is swept on).
    bodies: [u32; 2],
}

/// The rest of a contact's sweep data, read only when it carries an impulse or
/// approaches, in world lanes of four `[x, y, z, 0]` so that each row loads into one
/// vector register (see [`crate::simd`]); the local solver's cold data is kept apart in
/// [`LocalCoulomb`].
#[derive(Debug, Clone)]
#[repr(C, align(64))]
pub(crate) struct Prepared {
    /// Tangential rows of the local Jacobian: for k = t, s, `tangent[k] = [f_k, A_j,k,
    /// A_i,k]`.
    tangent: [[[f64; 4]; 3]; 2],
    /// ± I⁻¹ A_s columns (negated for the first body, which receives −Δr).
    spin: [[[f64; 4]; 3]; 2],
    /// W_aa, row-major (exactly symmetric).
    w: [f64; 9],
    /// W_aa⁻¹ when W_aa is not singular (the local solver's, computed once here).
    w_inverse: Option<[f64; 9]>,
    /// ± 1/m (negated for the first body).
    inverse_mass: [f64; 2],
    mu: f64,
    moves: [bool; 2],
}

/// `[x, y, z, 0]`.
#[inline(always)]
fn lanes(v: &Vector3<f64>) -> [f64; 4] {
    [v.x, v.y, v.z, 0.0]
}

/// The velocity `[v, 0]` and angular velocity `[ω, 0]` halves of a body's state.
#[inline(always)]
fn halves(b: &BodyState) -> (&[f64; 4], &[f64; 4]) {
    let (v, w) = b.split_at(4);
    (v.try_into().unwrap(), w.try_into().unwrap())
}

/// The bodies' velocities as the sweep reads and writes them: a raw view of one array,
/// so that the subdomains of the synchronous DDM can sweep the global array at the same
/// time ([`crate::ddm`]: each subdomain's contacts move only its own grains and read
/// only those and bodies that do not move), without copies.
#[derive(Clone, Copy)]
pub(crate) struct Bodies<'a> {
    ptr: *mut BodyState,
    len: usize,
    _array: PhantomData<&'a mut [BodyState]>,
}

// SAFETY: the view is only dereferenced through `get`, whose callers guarantee that
// no two threads touch the same body while one of them writes it.
unsafe impl Send for Bodies<'_> {}
unsafe impl Sync for Bodies<'_> {}

impl<'a> Bodies<'a> {
    /// A view of `state` (borrowed for as long as the view is used).
    pub(crate) fn new(state: &'a mut [BodyState]) -> Self {
        Bodies {
            ptr: state.as_mut_ptr(),
            len: state.len(),
            _array: PhantomData,
        }
    }

    /// The raw parts, to hand the view to another thread ([`Self::from_raw`]).
    pub(crate) fn raw(&self) -> (*mut BodyState, usize) {
        (self.ptr, self.len)
    }

    /// A view from [`Self::raw`]'s parts. Safety: the array they come from outlives
    /// every use of the view, and no exclusive borrow of it is used meanwhile.
    pub(crate) unsafe fn from_raw(ptr: *mut BodyState, len: usize) -> Self {
        Bodies {
            ptr,
            len,
            _array: PhantomData,
        }
    }

    /// Body `i` (checked against the array's length). Safety: no other thread writes
    /// body `i` while the pointer is used, nor reads it while this one writes.
    #[inline(always)]
    pub(crate) unsafe fn get(&self, i: usize) -> *mut BodyState {
        assert!(i < self.len, "body {i} of {}", self.len);
        self.ptr.add(i)
    }
}

/// Component k of the relative velocity without the gap shift, `f_k·(v_j − v_i) +
/// A_j,k·ω_j − A_i,k·ω_i`, from its Jacobian row `j = [f_k, A_j,k, A_i,k]`.
#[inline(always)]
fn row_velocity<V: F64x4>(j: &[[f64; 4]; 3], dv: V, wj: V, wi: V) -> f64 {
    let own = V::load(&j[1]) * wj;
    V::load(&j[0])
        .mul_add(dv, V::load(&j[2]).neg_mul_add(wi, own))
        .sum()
}

/// `v_j − v_i`, `ω_j`, `ω_i` as lanes, from the two bodies' states.
#[inline(always)]
fn lanes_of<V: F64x4>(first: &BodyState, second: &BodyState) -> (V, V, V) {
    let (vi, wi) = halves(first);
    let (vj, wj) = halves(second);
    (V::load(vj) - V::load(vi), V::load(wj), V::load(wi))
}

impl NormalRow {
    /// Its two bodies as indices.
    #[inline(always)]
    fn pair(&self) -> [usize; 2] {
        [self.bodies[0] as usize, self.bodies[1] as usize]
    }

    /// Its two bodies (their indices in the state it sweeps), to renumber them.
    pub(crate) fn bodies_mut(&mut self) -> &mut [u32; 2] {
        &mut self.bodies
    }

    /// `v_j − v_i`, `ω_j`, `ω_i` as lanes.
    #[inline(always)]
    fn body_lanes<V: F64x4>(&self, state: &[BodyState]) -> (V, V, V) {
        let [i, j] = self.pair();
        lanes_of(&state[i], &state[j])
    }

    /// The normal relative velocity, gap shift included.
    #[inline(always)]
    fn normal<V: F64x4>(&self, dv: V, wj: V, wi: V) -> f64 {
        row_velocity(&self.jacobian, dv, wj, wi) + self.shift
    }
}

impl Prepared {
    /// A contact's sweep data: its normal row and the rest.
    pub(crate) fn new(row: &ContactRow, inv: &BodyInverses) -> (NormalRow, Self) {
        let bodies = [row.bodies[0] as usize, row.bodies[1] as usize];
        let mut jacobian = [[[0.0; 4]; 3]; 3];
        let mut spin = [[[0.0; 4]; 3]; 2];
        let mut inverse_mass = [0.0; 2];
        let mut moves = [false; 2];
        let mut w = [0.0; 9];
        for (k, f) in row.frame.iter().enumerate() {
            jacobian[k][0] = lanes(f);
        }
        for s in 0..2 {
            let b = bodies[s];
            let im = inv.inverse_mass[b];
            let ii = &inv.inverse_inertia[b];
            moves[s] = im > 0.0;
            let sign = if s == 0 { -1.0 } else { 1.0 };
            inverse_mass[s] = sign * im;
            let mut cross = [Vector3::zeros(); 3];
            let mut turn = [Vector3::zeros(); 3];
            // Body j's rows are part 1, body i's part 2.
            let part = if s == 0 { 2 } else { 1 };
            for k in 0..3 {
                cross[k] = row.arms[s].cross(&row.frame[k]);
                turn[k] = ii * cross[k];
                jacobian[k][part] = lanes(&cross[k]);
                spin[s][k] = lanes(&(sign * turn[k]));
            }
            for k in 0..3 {
                for l in 0..3 {
                    let linear = if k == l { im } else { 0.0 };
                    w[3 * k + l] += linear + cross[k].dot(&turn[l]);
                }
            }
        }
        // W is symmetric up to rounding; make it exactly so.
        for (k, l) in [(0, 1), (0, 2), (1, 2)] {
            let m = 0.5 * (w[3 * k + l] + w[3 * l + k]);
            w[3 * k + l] = m;
            w[3 * l + k] = m;
        }
        let normal = NormalRow {
            jacobian: jacobian[0],
            shift: row.shift,
            bodies: row.bodies,
        };
        let rest = Prepared {
            tangent: [jacobian[1], jacobian[2]],
            spin,
            w,
            w_inverse: invert(&w),
            inverse_mass,
            mu: row.mu,
            moves,
        };
        (normal, rest)
    }

    /// Its local Coulomb solver (W_aa, its inverse and µ).
    pub(crate) fn local_solver(&self) -> LocalCoulomb {
        LocalCoulomb::with_inverse(&self.w, self.w_inverse, self.mu)
    }

    /// The tangential components of the relative velocity.
    #[inline(always)]
    fn tangential<V: F64x4>(&self, dv: V, wj: V, wi: V) -> [f64; 2] {
        [
            row_velocity(&self.tangent[0], dv, wj, wi),
            row_velocity(&self.tangent[1], dv, wj, wi),
        ]
    }

    /// The relative velocity (local, gap shift included) of the contact whose normal
    /// row is `normal`, from the bodies' states, in plain arithmetic (the error measure
    /// and the set-up).
    pub(crate) fn velocity(&self, normal: &NormalRow, state: &[BodyState]) -> [f64; 3] {
        let (dv, wj, wi) = normal.body_lanes::<Portable4>(state);
        let [t, s] = self.tangential(dv, wj, wi);
        [normal.normal(dv, wj, wi), t, s]
    }

    /// Applies the impulse change `d` to the two bodies, in plain arithmetic.
    fn apply(&self, normal: &NormalRow, d: [f64; 3], state: &mut [BodyState]) {
        // SAFETY: the view is made from the exclusive borrow just here.
        unsafe { self.apply_lanes::<Portable4>(normal, d, Bodies::new(state)) };
    }

    /// Adds `F d / m_j`, `I_j⁻¹ A_j d` to body j and the opposite to body i.
    /// Safety: as [`Bodies::get`] for the bodies this contact moves.
    #[inline(always)]
    unsafe fn apply_lanes<V: F64x4>(&self, normal: &NormalRow, d: [f64; 3], state: Bodies<'_>) {
        let (d0, d1, d2) = (V::splat(d[0]), V::splat(d[1]), V::splat(d[2]));
        let (n, t) = (&normal.jacobian, &self.tangent);
        let world =
            V::load(&t[1][0]).mul_add(d2, V::load(&t[0][0]).mul_add(d1, V::load(&n[0]) * d0));
        for (s, body) in normal.pair().into_iter().enumerate() {
            if !self.moves[s] {
                continue;
            }
            let spin = &self.spin[s];
            let turn = V::load(&spin[2])
                .mul_add(d2, V::load(&spin[1]).mul_add(d1, V::load(&spin[0]) * d0));
            let b = &mut *state.get(body);
            let (v, w) = b.split_at_mut(4);
            let v: &mut [f64; 4] = v.try_into().unwrap();
            let w: &mut [f64; 4] = w.try_into().unwrap();
            *v = V::splat(self.inverse_mass[s])
                .mul_add(world, V::load(v))
                .to_array();
            *w = (V::load(w) + turn).to_array();
        }
    }

    /// Stick, `r = −W⁻¹ q` strictly inside the cone (µ > 0), exactly as
    /// [`LocalCoulomb::solve`] tests it first; `None` otherwise (the local solver
    /// decides).
    #[inline(always)]
    fn stick(&self, q: [f64; 3]) -> Option<[f64; 3]> {
        let inv = match &self.w_inverse {
            Some(inv) if self.mu > 0.0 => inv,
            _ => return None,
        };
        let r = [
            -(inv[0] * q[0] + inv[1] * q[1] + inv[2] * q[2]),
            -(inv[3] * q[0] + inv[4] * q[1] + inv[5] * q[2]),
            -(inv[6] * q[0] + inv[7] * q[1] + inv[8] * q[2]),
        ];
        let cone = self.mu * r[0];
        (r[0] > 0.0 && r[1] * r[1] + r[2] * r[2] <= cone * cone).then_some(r)
    }
}

/// The cache lines of one [`Prepared`] record (aligned to a line).
const RECORD_LINES: usize = std::mem::size_of::<Prepared>() / 64;

/// The cache lines one [`LocalCoulomb`] may span (not aligned to a line).
const LOCAL_LINES: usize = std::mem::size_of::<LocalCoulomb>().div_ceil(64) + 1;

/// The diagonal Delassus block W_aa (row-major) of each contact.
pub fn delassus_diagonal(rows: &[ContactRow], inverses: &BodyInverses) -> Vec<[f64; 9]> {
    rows.iter()
        .map(|r| Prepared::new(r, inverses).1.w)
        .collect()
}

/// Solves the contact problem by NLGS in body-velocity form.
///
/// On entry `velocity` and `angular_velocity` (world) are the free velocities and
/// `impulse` the warm start (zero for a cold start); on return the impulses and the
/// velocities `V_free + M⁻¹ H r`. Under [`Stopping::Tolerance`] it stops when the error
/// measure (module docs) is at most the tolerance or at the sweep cap; under
/// [`Stopping::Sweeps`] after exactly that many sweeps. The last iterate is returned.
pub fn solve(
    rows: &[ContactRow],
    inverses: &BodyInverses,
    velocity: &mut [Vector3<f64>],
    angular_velocity: &mut [Vector3<f64>],
    impulse: &mut [[f64; 3]],
    options: &NlgsOptions,
) -> NlgsReport {
    solve_by(
        rows,
        inverses,
        velocity,
        angular_velocity,
        impulse,
        options,
        |contacts, impulse, directions, state| sweep(contacts.view(), impulse, directions, state),
    )
}

/// A body's velocities in the sweep: `[v, 0, ω, 0]` (world), padded to lanes of four,
/// one 64-byte cache line per body: the synchronous DDM's subdomains write their own
/// grains in one array at the same time, and two grains of different subdomains must
/// not share a line (false sharing cost 10 % of the parallel part).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C, align(64))]
pub struct BodyState(pub [f64; 8]);

impl std::ops::Deref for BodyState {
    type Target = [f64; 8];
    fn deref(&self) -> &[f64; 8] {
        &self.0
    }
}

impl std::ops::DerefMut for BodyState {
    fn deref_mut(&mut self) -> &mut [f64; 8] {
        &mut self.0
    }
}

/// The contacts of one problem, ready to sweep: the normal rows every sweep reads, the
/// rest of the sweep data and the local Coulomb solvers, in the order of the rows.
pub struct Sweepable {
    /// Normal row, gap shift and bodies per contact.
    pub(crate) normals: Vec<NormalRow>,
    /// The rest of the sweep data per contact.
    pub(crate) prepared: Vec<Prepared>,
    /// Local solver per contact.
    pub(crate) locals: Vec<LocalCoulomb>,
}

impl Sweepable {
    /// The sweep data of `rows` (built in parallel, collected in order).
    pub(crate) fn new(rows: &[ContactRow], inverses: &BodyInverses) -> Self {
        let (normals, prepared): (Vec<NormalRow>, Vec<Prepared>) =
            rows.par_iter().map(|r| Prepared::new(r, inverses)).unzip();
        // The local solvers (W_aa, its inverse, µ): read only by contacts that reach
        // them.
        let locals = prepared.par_iter().map(Prepared::local_solver).collect();
        Sweepable {
            normals,
            prepared,
            locals,
        }
    }

    /// The number of contacts.
    pub fn len(&self) -> usize {
        self.prepared.len()
    }

    /// Whether there is no contact.
    pub fn is_empty(&self) -> bool {
        self.prepared.is_empty()
    }

    /// All its contacts, to sweep.
    pub(crate) fn view(&self) -> Contacts<'_> {
        Contacts {
            normals: &self.normals,
            prepared: &self.prepared,
            locals: &self.locals,
        }
    }
}

/// Some contacts of a [`Sweepable`], borrowed for a sweep: their three parts, of the
/// same length.
#[derive(Clone, Copy)]
pub(crate) struct Contacts<'a> {
    normals: &'a [NormalRow],
    prepared: &'a [Prepared],
    locals: &'a [LocalCoulomb],
}

impl Contacts<'_> {
    /// The contacts `range` of these.
    pub(crate) fn part(self, range: Range<usize>) -> Self {
        Contacts {
            normals: &self.normals[range.clone()],
            prepared: &self.prepared[range.clone()],
            locals: &self.locals[range],
        }
    }
}

/// What a sweep (or a set of sweeps) did: the squared impulse change and size, each
/// contact weighted by `W_aa,nn²` (for [`super::nlgs::ErrorCheck::Light`]), and the
/// local fall-backs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SweepStats {
    /// Σ W_nn² ‖Δr‖².
    pub change: f64,
    /// Σ W_nn² ‖r‖².
    pub size: f64,
    /// Local solves that fell back to the projected fixed point.
    pub fallbacks: usize,
}

impl SweepStats {
    /// Adds another block's statistics (callers add blocks in a fixed order, so the
    /// sums do not depend on scheduling).
    pub fn add(&mut self, other: &SweepStats) {
        self.change += other.change;
        self.size += other.size;
        self.fallbacks += other.fallbacks;
    }
}

/// One Gauss–Seidel sweep over `contacts` (with their `locals`, impulses and slip
/// directions), updating the bodies' velocities in `state` in place. The contacts'
/// body indices refer to `state`.
///
/// Per contact: the normal relative velocity first; an open contact (zero impulse)
/// that is separating stays open without the rest (four in five contacts of a falling
/// heap); otherwise the full local free velocity, stick tried inline, the local solver
/// for the rest, and the impulse change applied to the two bodies. The lane arithmetic
/// runs on AVX2 + FMA when [`crate::simd::avx2_fma`] holds.
pub(crate) fn sweep(
    contacts: Contacts<'_>,
    impulse: &mut [[f64; 3]],
    directions: &mut [[f64; 2]],
    state: &mut [BodyState],
) -> SweepStats {
    // SAFETY: the view is made from the exclusive borrow just here.
    unsafe { sweep_on(contacts, impulse, directions, Bodies::new(state)) }
}

/// [`sweep`] on a view of the bodies. Safety: while it runs, no other thread writes a
/// body these contacts touch, nor touches a body they move (a body with a nonzero
/// inverse mass in their rows).
pub(crate) unsafe fn sweep_on(
    contacts: Contacts<'_>,
    impulse: &mut [[f64; 3]],
    directions: &mut [[f64; 2]],
    state: Bodies<'_>,
) -> SweepStats {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::simd::avx2_fma() {
            // SAFETY: the CPU has AVX2 and FMA (checked just above); the caller's
            // guarantee for `state`.
            return sweep_avx2(contacts, impulse, directions, state);
        }
    }
    sweep_lanes::<Portable4>(contacts, impulse, directions, state)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn sweep_avx2(
    contacts: Contacts<'_>,
    impulse: &mut [[f64; 3]],
    directions: &mut [[f64; 2]],
    state: Bodies<'_>,
) -> SweepStats {
    sweep_lanes::<crate::simd::avx::Avx4>(contacts, impulse, directions, state)
}

#[inline(always)]
unsafe fn sweep_lanes<V: F64x4>(
    contacts: Contacts<'_>,
    impulse: &mut [[f64; 3]],
    directions: &mut [[f64; 2]],
    state: Bodies<'_>,
) -> SweepStats {
    let mut stats = SweepStats::default();
    let count = contacts.normals.len();
    let lengths = [
        impulse.len(),
        directions.len(),
        contacts.prepared.len(),
        contacts.locals.len(),
    ];
    assert!(
        lengths == [count; 4],
        "one impulse, direction and record per contact"
    );
    let imp = impulse.as_mut_ptr();
    let dirs = directions.as_mut_ptr();
    for (i, n) in contacts.normals.iter().enumerate() {
        // The contacts that carry an impulse go the slow path; their records are read
        // out of sequence, so ask for the one a few contacts ahead now, and for its
        // local solver if it slipped in an earlier sweep (a slip direction is kept).
        let ahead = i + PREFETCH_AHEAD;
        if ahead < count && *imp.add(ahead) != [0.0; 3] {
            crate::simd::prefetch(&contacts.prepared[ahead], RECORD_LINES);
            if *dirs.add(ahead) != [0.0; 2] {
                crate::simd::prefetch(&contacts.locals[ahead], LOCAL_LINES);
            }
        }
        // SAFETY: i < count, the length of both, and only these references write them.
        let (old, direction) = (&mut *imp.add(i), &mut *dirs.add(i));
        let o = *old;
        let [first, second] = n.pair();
        let (dv, wj, wi) = lanes_of::<V>(&*state.get(first), &*state.get(second));
        let un = n.normal(dv, wj, wi);
        if un >= 0.0 && o == [0.0; 3] {
            // Open and separating: r stays 0 (q = u), nothing changes; the rest of
            // its data is not read.
            continue;
        }
        let (c, local) = (&contacts.prepared[i], &contacts.locals[i]);
        let w = &c.w;
        let [ut, us] = c.tangential(dv, wj, wi);
        let q = [
            un - (w[0] * o[0] + w[1] * o[1] + w[2] * o[2]),
            ut - (w[3] * o[0] + w[4] * o[1] + w[5] * o[2]),
            us - (w[6] * o[0] + w[7] * o[1] + w[8] * o[2]),
        ];
        // (No closures on this path: see crate::simd.)
        let stick = if q[0] < 0.0 { c.stick(q) } else { None };
        let r = if q[0] >= 0.0 {
            // Take-off without the local solver.
            [0.0; 3]
        } else if let Some(r) = stick {
            r
        } else {
            let (r, status) = local.solve(q, direction);
            if status == ContactStatus::Fallback {
                stats.fallbacks += 1;
            }
            r
        };
        let d = [r[0] - o[0], r[1] - o[1], r[2] - o[2]];
        if d != [0.0; 3] {
            c.apply_lanes::<V>(n, d, state);
        }
        let scale = w[0] * w[0];
        stats.change += scale * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        stats.size += scale * (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
        *old = r;
    }
    stats
}

/// The error measure's sums over some contacts: `[Σ ‖e_a‖², Σ ‖r̂_a‖², Σ ‖u_a‖²]`
/// (module docs), with the relative velocities on the same lanes as the sweep.
fn measure_chunk(contacts: Contacts<'_>, impulse: &[[f64; 3]], state: &[BodyState]) -> [f64; 3] {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::simd::avx2_fma() {
            #[target_feature(enable = "avx2,fma")]
            unsafe fn on_avx(c: Contacts<'_>, i: &[[f64; 3]], s: &[BodyState]) -> [f64; 3] {
                measure_lanes::<crate::simd::avx::Avx4>(c, i, s)
            }
            // SAFETY: the CPU has AVX2 and FMA (checked just above).
            return unsafe { on_avx(contacts, impulse, state) };
        }
    }
    measure_lanes::<Portable4>(contacts, impulse, state)
}

#[inline(always)]
fn measure_lanes<V: F64x4>(
    contacts: Contacts<'_>,
    impulse: &[[f64; 3]],
    state: &[BodyState],
) -> [f64; 3] {
    let (mut sum, mut r_norm, mut u_norm) = (0.0, 0.0, 0.0);
    for ((n, c), r) in contacts.normals.iter().zip(contacts.prepared).zip(impulse) {
        let (dv, wj, wi) = n.body_lanes::<V>(state);
        let [ut, us] = c.tangential(dv, wj, wi);
        let u = [n.normal(dv, wj, wi), ut, us];
        u_norm += u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
        if *r == [0.0; 3] && u[0] >= 0.0 {
            // Open and separating: the residual is exactly zero (Π_K(−ũ) = 0 when
            // u_N ≥ 0, in floating point too), r̂ = 0.
            continue;
        }
        let scaled = [c.w[0] * r[0], c.w[0] * r[1], c.w[0] * r[2]];
        sum += coulomb_residual_squared(scaled, u, c.mu);
        r_norm += scaled[0] * scaled[0] + scaled[1] * scaled[1] + scaled[2] * scaled[2];
    }
    [sum, r_norm, u_norm]
}

/// [`solve`] with the iteration given by the caller: `iteration(contacts, impulse,
/// directions, state)` makes one iteration (one sweep for plain NLGS, one DDM
/// iteration for [`crate::ddm`]) over all contacts and returns its statistics. The
/// set-up ([`Problem::new`]), the stopping test and the error measure
/// ([`run`]) are shared, so every driver stops on the same criterion.
pub fn solve_by<F>(
    rows: &[ContactRow],
    inverses: &BodyInverses,
    velocity: &mut [Vector3<f64>],
    angular_velocity: &mut [Vector3<f64>],
    impulse: &mut [[f64; 3]],
    options: &NlgsOptions,
    iteration: F,
) -> NlgsReport
where
    F: FnMut(&Sweepable, &mut [[f64; 3]], &mut [[f64; 2]], &mut [BodyState]) -> SweepStats,
{
    let start = Instant::now();
    let mut problem = Problem::new(rows, inverses, velocity, angular_velocity, impulse);
    let Problem {
        contacts,
        state,
        free_norm,
    } = &mut problem;
    let mut report = run(
        contacts,
        state,
        *free_norm,
        impulse,
        options,
        iteration,
        |_| {},
    );
    problem.finish(velocity, angular_velocity);
    report.solve_time = start.elapsed();
    report
}

/// A body-velocity contact problem set up for sweeping: the contacts' sweep data, the
/// bodies' velocities (free velocities plus the warm start's `M⁻¹ H r`) and the norm
/// of the local free velocities (the error measure's scale).
pub struct Problem {
    /// The contacts.
    pub contacts: Sweepable,
    /// The bodies' velocities `[v, 0, ω, 0]`.
    pub state: Vec<BodyState>,
    /// The norm of the local free velocities (the error measure's scale).
    pub free_norm: f64,
}

impl Problem {
    /// Sets up the problem of `rows` from the free velocities and the warm-start
    /// `impulse` (applied to the velocities here).
    pub fn new(
        rows: &[ContactRow],
        inverses: &BodyInverses,
        velocity: &[Vector3<f64>],
        angular_velocity: &[Vector3<f64>],
        impulse: &[[f64; 3]],
    ) -> Self {
        assert_eq!(rows.len(), impulse.len(), "one impulse per contact");
        // The bodies' velocities [v, ω], one record per body, for the sweeps.
        let mut state: Vec<BodyState> = velocity
            .iter()
            .zip(angular_velocity.iter())
            .map(|(v, w)| BodyState([v.x, v.y, v.z, 0.0, w.x, w.y, w.z, 0.0]))
            .collect();
        let contacts = Sweepable::new(rows, inverses);
        let pairs = || contacts.normals.iter().zip(&contacts.prepared);
        let free_norm = pairs()
            .flat_map(|(n, c)| c.velocity(n, &state))
            .map(|x| x * x)
            .sum::<f64>()
            .sqrt();
        for ((n, c), r) in pairs().zip(impulse.iter()) {
            if *r != [0.0; 3] {
                c.apply(n, *r, &mut state);
            }
        }
        Problem {
            contacts,
            state,
            free_norm,
        }
    }

    /// Writes the velocities back.
    pub fn finish(&self, velocity: &mut [Vector3<f64>], angular_velocity: &mut [Vector3<f64>]) {
        for ((v, w), s) in velocity
            .iter_mut()
            .zip(angular_velocity.iter_mut())
            .zip(&self.state)
        {
            *v = Vector3::new(s[0], s[1], s[2]);
            *w = Vector3::new(s[4], s[5], s[6]);
        }
    }
}

/// Iterates on a [`Problem`]'s parts (so that other threads may borrow the contacts
/// while this one owns the state) until the stopping rule of `options` (see
/// [`solve`]): `iteration` makes one iteration and returns its statistics; `gather`
/// makes `impulse` current, for a driver whose blocks keep their own impulses (called
/// before every error measure and once at the end). `impulse` is the warm start given
/// to [`Problem::new`] and holds the result. The report's `solve_time` is left at zero.
pub fn run<F, G>(
    contacts: &Sweepable,
    state: &mut [BodyState],
    free_norm: f64,
    impulse: &mut [[f64; 3]],
    options: &NlgsOptions,
    mut iteration: F,
    mut gather: G,
) -> NlgsReport
where
    F: FnMut(&Sweepable, &mut [[f64; 3]], &mut [[f64; 2]], &mut [BodyState]) -> SweepStats,
    G: FnMut(&mut [[f64; 3]]),
{
    let rows_len = contacts.len();
    let mut directions = vec![[0.0f64; 2]; rows_len];
    let mut report = NlgsReport {
        iterations: 0,
        error: 0.0,
        converged: rows_len == 0,
        solve_time: Duration::ZERO,
        error_evaluations: 0,
        local_fallbacks: 0,
        returned_sweep: 0,
    };
    let (tolerance, max_sweeps) = match options.stopping {
        Stopping::Tolerance {
            tolerance,
            max_sweeps,
        } => (tolerance, max_sweeps),
        Stopping::Sweeps(n) => (f64::NEG_INFINITY, n),
    };
    if rows_len > 0 {
        // In parallel over fixed chunks of contacts, the partial sums added in chunk
        // order: the same value on any number of threads.
        let measure = |impulse: &[[f64; 3]], state: &[BodyState]| {
            let parts: Vec<[f64; 3]> = impulse
                .par_chunks(MEASURE_CHUNK)
                .enumerate()
                .map(|(k, impulse)| {
                    let first = k * MEASURE_CHUNK;
                    let part = contacts.view().part(first..first + impulse.len());
                    measure_chunk(part, impulse, state)
                })
                .collect();
            let (mut sum, mut r_norm, mut u_norm) = (0.0, 0.0, 0.0);
            for p in parts {
                sum += p[0];
                r_norm += p[1];
                u_norm += p[2];
            }
            let scale = free_norm.max(r_norm.sqrt()).max(u_norm.sqrt());
            if scale > f64::EPSILON {
                sum.sqrt() / scale
            } else {
                sum.sqrt()
            }
        };
        report.error = f64::INFINITY;
        while report.iterations < max_sweeps {
            let stats = iteration(contacts, impulse, &mut directions, state);
            report.local_fallbacks += stats.fallbacks;
            report.iterations += 1;
            let full =
                options
                    .error_check
                    .due(report.iterations, stats.change, stats.size, tolerance);
            if full {
                gather(impulse);
                report.error = measure(impulse, state);
                report.error_evaluations += 1;
                if report.error <= tolerance {
                    report.converged = true;
                    break;
                }
            }
        }
        gather(impulse);
        if !report.converged {
            report.error = measure(impulse, state);
            report.error_evaluations += 1;
            report.converged = report.error <= tolerance || tolerance == f64::NEG_INFINITY;
        }
    }
    report.returned_sweep = report.iterations;
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nscd::{DelassusBlocks, FrictionProblem};

    /// A sphere-like body (unit mass, inertia 0.4) resting on a fixed body (index 0).
    fn two_bodies() -> (Vec<f64>, Vec<Matrix3<f64>>) {
        (
            vec![0.0, 1.0],
            vec![Matrix3::zeros(), Matrix3::identity() / 0.4],
        )
    }

    #[test]
    fn a_single_contact_matches_the_analytic_impulse() {
        // A unit mass sliding at 1 m/s along t into a floor at 0.5 m/s, µ = 0.3, contact
        // below its centre (arm −0.1 n). Without rotation the answer is r_n = 0.5 and
        // slip; with the arm, the tangential impulse spins the body: solve exactly.
        let (inverse_mass, inverse_inertia) = two_bodies();
        let inverses = BodyInverses {
            inverse_mass: &inverse_mass,
            inverse_inertia: &inverse_inertia,
        };
        let frame = [Vector3::z(), Vector3::x(), Vector3::y()];
        let row = ContactRow {
            bodies: [0, 1],
            frame,
            arms: [Vector3::zeros(), Vector3::new(0.0, 0.0, -0.1)],
            shift: 0.0,
            mu: 0.3,
        };
        // Stick would need |r_t| = v_t / W_tt = 1 / (1 + 0.01/0.4) > 0.3 × 0.5: slip.
        // Slip: u_n = 0 → r_n = 0.5 (W_nt = 0 here), r_t = −0.3 × 0.5.
        let mut v = vec![Vector3::zeros(), Vector3::new(1.0, 0.0, -0.5)];
        let mut w = vec![Vector3::zeros(); 2];
        let mut r = vec![[0.0; 3]];
        let report = solve(
            &[row],
            &inverses,
            &mut v,
            &mut w,
            &mut r,
            &NlgsOptions::default(),
        );
        assert!(report.converged && report.iterations <= 2, "{report:?}");
        assert!((r[0][0] - 0.5).abs() < 1e-14, "{:?}", r[0]);
        assert!((r[0][1] + 0.15).abs() < 1e-14 && r[0][2].abs() < 1e-14);
        assert!(v[1].z.abs() < 1e-14 && (v[1].x - 0.85).abs() < 1e-14);
        // ω = I⁻¹ (d × F r): d = −0.1 z, F r = −0.15 x + 0.5 z → d × (−0.15 x) = 0.015 y.
        assert!(
            (w[1] - Vector3::new(0.0, 0.015 / 0.4, 0.0)).norm() < 1e-14,
            "{:?}",
            w[1]
        );
        // The same problem in W form gives the same impulse.
        let blocks = delassus_diagonal(&[row], &inverses);
        let problem = FrictionProblem::new(
            DelassusBlocks::from_blocks(1, [(0, 0, blocks[0])]),
            vec![-0.5, 1.0, 0.0],
            vec![0.3],
        )
        .unwrap();
        let mut rw = vec![0.0; 3];
        let mut uw = vec![0.0; 3];
        crate::nscd::nlgs::solve(&problem, &mut rw, &mut uw, &NlgsOptions::default());
        for k in 0..3 {
            assert!((rw[k] - r[0][k]).abs() < 1e-14);
        }
    }

    #[test]
    fn delassus_block_of_an_offset_contact() {
        let (inverse_mass, inverse_inertia) = two_bodies();
        let inverses = BodyInverses {
            inverse_mass: &inverse_mass,
            inverse_inertia: &inverse_inertia,
        };
        let row = ContactRow {
            bodies: [0, 1],
            frame: [Vector3::z(), Vector3::x(), Vector3::y()],
            arms: [Vector3::zeros(), Vector3::new(0.2, 0.0, -0.1)],
            shift: 0.0,
            mu: 0.5,
        };
        let w = delassus_diagonal(&[row], &inverses)[0];
        // W = I/m + Aᵀ I⁻¹ A with A = [d×n, d×t, d×s]; d×z = (0, −0.2, 0),
        // d×x = (0, −0.1, 0), d×y = (0.1, 0, 0.2).
        let expect = [
            1.0 + 0.04 / 0.4,
            0.02 / 0.4,
            0.0,
            0.02 / 0.4,
            1.0 + 0.01 / 0.4,
            0.0,
            0.0,
            0.0,
            1.0 + 0.05 / 0.4,
        ];
        for k in 0..9 {
            assert!((w[k] - expect[k]).abs() < 1e-14, "{w:?}");
        }
    }
}
