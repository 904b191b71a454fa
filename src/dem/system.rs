//! A multi-body system of seed 004 §4: deformable QDEM bodies (all merged into one
//! [`QdemModel`], each keeping its own nodes) and rigid bodies, all carrying vertex
//! spheres that touch spheres of other bodies and fixed planes.
//!
//! One step (kick–drift–kick for everything, seed 004 §2.4):
//! 1. rigid bodies: half kick with the last forces, drift;
//! 2. QDEM bodies: [`QdemSolver::step_with`], whose force hook gathers every sphere's
//!    position and half-step velocity, evaluates the contacts ([`Contacts`]), adds the
//!    node spheres' forces and sums the rigid spheres' forces into force and torque;
//! 3. rigid bodies: second half kick with the new forces (in the hook, each body right
//!    after its force is summed: one pass over the bodies, not two).
//!
//! The energy balance covers the whole system (kinetic, strain and spring energy,
//! viscous, slider and dashpot dissipation, work of gravity and loads); a state that is
//! no longer finite, or whose energy grows past [`BLOWUP_FACTOR`] × what was put in,
//! stops the run with an error naming the stable time step of tetra and springs.

use std::ops::Range;

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::contacts::{ContactState, ContactTotals, Contacts, SphereSet};
use super::law::cross;
use super::rigid::{RigidShape, RigidState};
use super::spheres::{GatherTargets, SphereBuffers, SphereSlices};
use crate::qdem::{stability, Boundary, QdemModel, QdemOptions, QdemSolver, State};
use crate::{Error, Result};

/// The system's energy may not exceed this factor × (initial energy + most work put in).
pub const BLOWUP_FACTOR: f64 = 10.0;

/// The contact part of the stable step counts the sphere pairs (and sphere–plane
/// pairs) closer than this gap (m), touching or about to: contacts that may close
/// during the run. It was the Verlet skin until the skin became a cost setting
/// (2 mm, so the time steps of the runs before stayed as they were).
pub const STABLE_STEP_GAP: f64 = 2e-3;

/// Sphere and body loops run on rayon from this many items (below it the tasks cost
/// more than they save).
const PARALLEL_MIN_SPHERES: usize = 4096;

/// The rigid bodies' kicks and drifts (and the partial step's plan) run on rayon from
/// this many bodies.
pub(crate) const PARALLEL_MIN_BODIES: usize = 512;

/// Where a sphere sits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SphereAt {
    /// On node `node` of the merged QDEM model, of deformable body `body` (an index
    /// into [`MultiBody::deformable`]), its centre offset by `inset` (reference frame)
    /// turned with the body's best-fit rotation.
    Node {
        /// Node index.
        node: u32,
        /// Index into [`MultiBody::deformable`].
        body: u32,
        /// Offset of the centre from the node at t = 0 (m).
        inset: [f64; 3],
    },
    /// On rigid body `body`, its `k`-th sphere.
    Rigid {
        /// Index among the rigid bodies.
        body: u32,
        /// Index among that body's spheres.
        k: u32,
    },
}

/// What kind of body a body is, and where its data live.
#[derive(Debug, Clone, PartialEq)]
pub enum BodyKind {
    /// Nodes `nodes` of the merged QDEM model.
    Deformable {
        /// Node range.
        nodes: Range<u32>,
    },
    /// Rigid body `index`.
    Rigid {
        /// Index among the rigid bodies.
        index: u32,
    },
}

/// The fixed description of a multi-body system.
#[derive(Debug)]
pub struct MultiBody {
    /// The deformable bodies, merged (none: an all-rigid system).
    pub model: Option<QdemModel>,
    /// Fixes and loads on the merged model's nodes.
    pub boundary: Boundary,
    /// Rigid bodies' mass properties and spheres.
    pub rigid: Vec<RigidShape>,
    /// One entry per body, in body-id order (the spheres' owners).
    pub bodies: Vec<BodyKind>,
    /// Every sphere: node spheres first (ascending node), then rigid bodies' in order.
    pub spheres: Vec<SphereAt>,
    /// `rigid_spheres[b]`: the range of body b's spheres in `spheres`.
    pub rigid_spheres: Vec<Range<usize>>,
    /// The deformable bodies' node ranges (their spheres' insets turn with the
    /// best-fit rotation of these nodes).
    pub deformable: Vec<Range<u32>>,
    /// Whether any node sphere has an inset (else the best-fit rotations are skipped).
    pub insets: bool,
    /// Radii, owners, materials, masses, planes and laws of the spheres.
    pub set: SphereSet,
    /// Gravity (m/s²).
    pub gravity: [f64; 3],
}

/// The state of the whole system (what a checkpoint stores).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MultiState {
    /// Time (s).
    pub time: f64,
    /// Steps taken.
    pub step: u64,
    /// The merged QDEM model's state.
    pub deformable: Option<State>,
    /// The rigid bodies.
    pub rigid: Vec<RigidState>,
    /// Contact pairs and their springs.
    pub contacts: ContactState,
    /// System energies.
    pub energies: SystemEnergies,
}

/// Energy terms of the whole system (J).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct SystemEnergies {
    /// Kinetic energy of the rigid bodies.
    pub rigid_kinetic: f64,
    /// Work of gravity on the rigid bodies.
    pub rigid_gravity_work: f64,
    /// Stored contact spring energy.
    pub spring: f64,
    /// Dissipated by Coulomb sliders.
    pub slip_dissipated: f64,
    /// Dissipated by contact dashpots.
    pub damping_dissipated: f64,
    /// Taken from the rigid bodies by numerical damping (settling).
    pub numerical_damping: f64,
    /// Total energy at the start.
    pub initial: f64,
    /// Most external work seen so far (the blow-up bound).
    pub most_work: f64,
}

impl MultiState {
    /// Kinetic energy of all bodies.
    pub fn kinetic(&self) -> f64 {
        self.energies.rigid_kinetic + self.deformable.as_ref().map_or(0.0, |s| s.energies.kinetic)
    }

    /// Kinetic + strain + spring energy.
    pub fn mechanical(&self) -> f64 {
        self.kinetic()
            + self.energies.spring
            + self.deformable.as_ref().map_or(0.0, |s| s.energies.strain)
    }

    /// Work of gravity and loads (contact work between bodies excluded).
    pub fn external_work(&self) -> f64 {
        self.energies.rigid_gravity_work
            + self
                .deformable
                .as_ref()
                .map_or(0.0, |s| s.energies.external_work - s.energies.hook_work)
    }

    /// Everything dissipated.
    pub fn dissipated(&self) -> f64 {
        self.energies.slip_dissipated
            + self.energies.damping_dissipated
            + self.energies.numerical_damping
            + self.deformable.as_ref().map_or(0.0, |s| {
                s.energies.viscous_dissipated + s.energies.damping_dissipated
            })
    }

    /// mechanical + dissipated − external work − initial (J): zero for exact dynamics.
    pub fn balance_error(&self) -> f64 {
        let verlet = self
            .deformable
            .as_ref()
            .map_or(0.0, |s| s.energies.verlet_correction);
        self.mechanical() - verlet + self.dissipated()
            - self.external_work()
            - self.energies.initial
    }
}

/// The stable time step of a system: tetra and contact springs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SystemStability {
    /// Of the tetra (Lanczos on the merged model), or ∞ without deformable bodies.
    pub tetra: f64,
    /// Of the contact springs: 2/ω with ω² = Σ k_n / m over the pairs within
    /// [`STABLE_STEP_GAP`] of the stiffest node or rigid body (translation and
    /// rotation), times the dashpot's (√(1+ζ²) − ζ).
    pub contact: f64,
}

impl SystemStability {
    /// The smaller of the two.
    pub fn stable(&self) -> f64 {
        self.tetra.min(self.contact)
    }
}

/// The integrator of a [`MultiBody`].
#[derive(Debug)]
pub struct MultiBodySolver<'m> {
    system: &'m MultiBody,
    qdem: Option<QdemSolver<'m>>,
    contacts: Contacts,
    dt: f64,
    spheres: SphereBuffers,
    /// Contact totals of the last evaluation.
    pub last: ContactTotals,
    stable: Option<SystemStability>,
    primed: bool,
    damping: f64,
    /// Each rigid body's second half kick of the last step, in body order.
    kicked: Vec<Kicked>,
}

/// A rigid body's second half kick: (energy taken by the damping, kinetic energy after
/// the kick, position and velocity finite).
type Kicked = (f64, f64, bool);

/// The rigid bodies' second half kick, given to the force hook of a step so that each
/// body is kicked as soon as its contact force is summed.
struct SecondKick<'k> {
    damping: f64,
    /// One entry per body, in body order (see [`MultiBodySolver::kicked`]).
    out: &'k mut Vec<Kicked>,
}

impl MultiBody {
    /// How many node spheres lead `spheres` (the rigid bodies' follow).
    pub fn node_spheres(&self) -> usize {
        self.rigid_spheres
            .first()
            .map_or(self.spheres.len(), |r| r.start)
    }

    /// The system at rest: QDEM state in the reference configuration, rigid bodies in
    /// their initial placements, no contacts yet.
    pub fn at_rest(&self) -> MultiState {
        MultiState {
            time: 0.0,
            step: 0,
            deformable: self.model.as_ref().map(State::at_rest),
            rigid: self.rigid.iter().map(RigidState::at_rest).collect(),
            contacts: ContactState::default(),
            energies: SystemEnergies::default(),
        }
    }

    /// Number of tetra in the deformable bodies.
    pub fn tet_count(&self) -> usize {
        self.model.as_ref().map_or(0, |m| m.tet_count())
    }

    /// Total mass (kg).
    pub fn total_mass(&self) -> f64 {
        self.model.as_ref().map_or(0.0, |m| m.total_mass())
            + self.rigid.iter().map(|r| r.mass).sum::<f64>()
    }
}

impl<'m> MultiBodySolver<'m> {
    /// A solver with step `dt` and Verlet skin `skin` (m). The time step is checked
    /// against the stable one by [`Self::check_time_step`], not here (the contact part
    /// needs the first neighbour list).
    pub fn new(system: &'m MultiBody, dt: f64, skin: f64) -> Result<Self> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::Message(format!(
                "multi-body: time step {dt} s must be positive"
            )));
        }
        let qdem = match &system.model {
            Some(model) => Some(QdemSolver::new(
                model,
                &system.boundary,
                dt,
                QdemOptions {
                    check_time_step: false,
                    ..QdemOptions::default()
                },
            )?),
            None => None,
        };
        Ok(MultiBodySolver {
            system,
            qdem,
            contacts: Contacts::new(system.set.clone(), skin),
            dt,
            spheres: SphereBuffers::new(system),
            last: ContactTotals::default(),
            stable: None,
            primed: false,
            damping: 0.0,
            kicked: Vec::new(),
        })
    }

    /// The time step (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Mass-proportional numerical damping α (1/s) on every node and rigid body from
    /// the next step on (0: none). For settling a bed before the loads: the force
    /// −α m v vanishes at rest, so the settled state is the undamped equilibrium.
    pub fn set_damping(&mut self, rate: f64) -> Result<()> {
        if let Some(q) = self.qdem.as_mut() {
            q.set_damping(if rate > 0.0 {
                crate::qdem::Damping::MassProportional { rate }
            } else {
                crate::qdem::Damping::None
            })?;
        } else if !(rate.is_finite() && rate >= 0.0 && rate * self.dt < 1.0) {
            return Err(Error::Message(format!(
                "multi-body: damping rate {rate} 1/s must be ≥ 0 with rate × dt < 1"
            )));
        }
        self.damping = rate;
        Ok(())
    }

    /// Stable time steps for `state` (the contact part from its current neighbour
    /// list; the tetra part computed once).
    pub fn stability(&mut self, state: &mut MultiState) -> SystemStability {
        let tetra = match (&self.stable, &self.system.model) {
            (Some(s), _) => s.tetra,
            (None, Some(model)) => stability(model).stable,
            (None, None) => f64::INFINITY,
        };
        let deformable = state.deformable.as_ref().map(|s| s.positions.as_slice());
        let sp = &mut self.spheres;
        gather(
            self.system,
            deformable,
            None,
            &state.rigid,
            sp.targets(false),
        );
        let rebuilt = self.contacts.refresh(&mut state.contacts, &sp.x);
        sp.sync(
            self.system,
            &self.contacts,
            &state.contacts,
            rebuilt,
            &state.rigid,
        );
        let near = self.contacts.within(&sp.x, STABLE_STEP_GAP);
        let contact = contact_stable_step(self.system, &near, &sp.x, &state.rigid);
        let s = SystemStability { tetra, contact };
        self.stable = Some(s);
        s
    }

    /// What the solver carries from one step to the next besides the [`MultiState`]:
    /// the contact forces on the QDEM nodes at the last step (their work over the next
    /// step is trapezoidal). A checkpoint stores it with the state.
    pub fn memory(&self) -> Vec<[f64; 3]> {
        self.qdem
            .as_ref()
            .map_or_else(Vec::new, |q| q.hook_memory().to_vec())
    }

    /// Continues from a saved `state` and [`Self::memory`] (a resumed run): the next
    /// [`Self::step`] gives the bits the uninterrupted run's would.
    pub fn resume(&mut self, state: &MultiState, memory: Vec<[f64; 3]>) {
        self.contacts.restore(&state.contacts);
        self.spheres.forget();
        if let Some(q) = self.qdem.as_mut() {
            q.restore_hook_memory(memory);
        }
        self.primed = true;
    }

    /// Computes forces and energies of a fresh state.
    pub fn prime(&mut self, state: &mut MultiState) -> Result<()> {
        self.deformable_pass(state, true)?;
        let system = self.system;
        let e = &mut state.energies;
        e.spring = self.last.spring_energy;
        e.rigid_kinetic = state
            .rigid
            .iter()
            .zip(&system.rigid)
            .map(|(r, s)| r.kinetic_energy(s))
            .sum();
        e.initial = state_energy(state.deformable.as_ref(), e);
        self.primed = true;
        Ok(())
    }

    /// The QDEM part of priming (`prime`) or of a step, with the contacts as its force
    /// hook (without QDEM bodies, the contacts alone). In a step the hook also gives the
    /// rigid bodies their second half kick (into `kicked`).
    fn deformable_pass(&mut self, state: &mut MultiState, prime: bool) -> Result<()> {
        let MultiBodySolver {
            system,
            qdem,
            contacts,
            dt,
            spheres,
            last,
            damping,
            kicked,
            ..
        } = self;
        let MultiState {
            deformable,
            rigid,
            contacts: cstate,
            ..
        } = state;
        let mut hook = |_t: f64, x: &[[f64; 3]], v: &[[f64; 3]], f: &mut [[f64; 3]]| {
            let kick = (!prime).then_some(SecondKick {
                damping: *damping,
                out: &mut *kicked,
            });
            *last = contact_forces(system, contacts, cstate, rigid, x, v, f, *dt, spheres, kick);
        };
        match (qdem.as_mut(), deformable.as_mut()) {
            (Some(q), Some(s)) if prime => q.prime_with(s, Some(&mut hook)),
            (Some(q), Some(s)) => q.step_with(s, Some(&mut hook)),
            _ => {
                hook(0.0, &[], &[], &mut []);
                Ok(())
            }
        }
    }

    /// Advances the system by one step.
    pub fn step(&mut self, state: &mut MultiState) -> Result<()> {
        // A QDEM state never primed (a solver resumed on a fresh state) is primed here,
        // before the rigid bodies' first half kick: `step_with` would prime it after
        // their drift, with the step's hook, which kicks them.
        let unprimed = state.deformable.as_ref().is_some_and(|s| !s.is_primed());
        if (!self.primed && state.step == 0) || unprimed {
            self.prime(state)?;
        }
        self.primed = true;
        let (system, dt, damping) = (self.system, self.dt, self.damping);
        let half = 0.5 * dt;
        let g = system.gravity;
        // Each body on its own (in parallel for many), its energies summed in body
        // order afterwards: the same bits on any thread count.
        let first_half = |(r, shape): (&mut RigidState, &RigidShape)| {
            let damped = r.kick(shape, g, half, damping);
            r.drift(shape, dt);
            let work = shape.mass
                * dt
                * (g[0] * r.velocity[0] + g[1] * r.velocity[1] + g[2] * r.velocity[2]);
            (damped, work)
        };
        let first = per_body(&mut state.rigid, &system.rigid, first_half);
        let mut gravity_work = 0.0;
        let mut damped = 0.0;
        for &(d, w) in &first {
            damped += d;
            gravity_work += w;
        }
        // The second half kick happens in the force hook.
        self.deformable_pass(state, false)?;
        let mut kinetic = 0.0;
        let mut finite = true;
        for &(d, k, f) in &self.kicked {
            damped += d;
            kinetic += k;
            finite &= f;
        }
        state.time += dt;
        state.step += 1;
        let (e, last) = (&mut state.energies, &self.last);
        e.rigid_kinetic = kinetic;
        e.rigid_gravity_work += gravity_work;
        e.spring = last.spring_energy;
        e.slip_dissipated += last.slip_dissipated;
        e.damping_dissipated += last.damping_dissipated;
        e.numerical_damping += damped;
        let work = state.external_work();
        state.energies.most_work = state.energies.most_work.max(work);
        self.check(state, finite)
    }

    fn check(&self, state: &MultiState, finite: bool) -> Result<()> {
        let e = state.mechanical();
        let bound = BLOWUP_FACTOR
            * (state.energies.initial.max(0.0) + state.energies.most_work.max(0.0))
            + 1e-9 * self.system.total_mass();
        let reason = if !finite || !e.is_finite() {
            Some("the state is no longer finite (NaN or infinity)".to_string())
        } else if e > bound {
            Some(format!(
                "kinetic + strain + spring energy {e:.4e} J exceeds {BLOWUP_FACTOR} × (initial \
                 energy + work put in) = {bound:.4e} J"
            ))
        } else {
            None
        };
        match reason {
            None => Ok(()),
            Some(reason) => {
                let s = self.stable.map(|s| s.stable());
                let stable = s.map_or("unknown".to_string(), |s| format!("{s:.4e} s"));
                Err(Error::Message(format!(
                    "unstable: {reason} at t = {:.6e} s (step {}); the stable time step \
                     (tetra and contact springs) is {stable}, dt = {:.4e} s",
                    state.time, state.step, self.dt
                )))
            }
        }
    }
}

/// `f` over the rigid bodies with their shapes, in parallel for many bodies, its
/// results in body order.
fn per_body<R, F>(rigid: &mut [RigidState], shapes: &[RigidShape], f: F) -> Vec<R>
where
    R: Send,
    F: Fn((&mut RigidState, &RigidShape)) -> R + Sync + Send,
{
    if rigid.len() >= PARALLEL_MIN_BODIES {
        rigid.par_iter_mut().zip(shapes).map(f).collect()
    } else {
        rigid.iter_mut().zip(shapes).map(f).collect()
    }
}

fn state_energy(deformable: Option<&State>, e: &SystemEnergies) -> f64 {
    e.rigid_kinetic
        + e.spring
        + deformable.map_or(0.0, |s| {
            s.energies.kinetic - s.energies.verlet_correction + s.energies.strain
        })
}

/// Sphere positions and velocities from the node arrays and the rigid states: every
/// node sphere, and of the rigid bodies every sphere, or for a partial step
/// ([`SphereBuffers::plan`]) every sphere of the bodies marked whole and the touched
/// ones of the others, these into the touched spheres' own buffers (the whole bodies'
/// touched spheres are copied there too).
fn gather(
    system: &MultiBody,
    x: Option<&[[f64; 3]]>,
    v: Option<&[[f64; 3]]>,
    rigid: &[RigidState],
    targets: GatherTargets,
) {
    let GatherTargets {
        only,
        x: sx,
        v: sv,
        touched,
    } = targets;
    let turns: Vec<nalgebra::Matrix3<f64>> = match (x, &system.model) {
        (Some(x), Some(model)) if !x.is_empty() && system.insets => system
            .deformable
            .iter()
            .map(|r| best_fit_rotation(model, x, r.clone()))
            .collect(),
        _ => vec![nalgebra::Matrix3::identity(); system.deformable.len()],
    };
    // Node spheres come first, then each rigid body's in one run (see `spheres`).
    let (total, nodes) = (sx.len(), system.node_spheres());
    let (sx_nodes, sx_rigid) = sx.split_at_mut(nodes);
    let (sv_nodes, sv_rigid) = sv.split_at_mut(nodes);
    let node = |(s, (px, pv)): (usize, (&mut [f64; 3], &mut [f64; 3]))| {
        if let SphereAt::Node { node, body, inset } = system.spheres[s] {
            let p = x.map_or([0.0; 3], |x| x[node as usize]);
            let o = turns[body as usize] * Vector3::from(inset);
            *px = [p[0] + o.x, p[1] + o.y, p[2] + o.z];
            *pv = v.map_or([0.0; 3], |v| v[node as usize]);
        }
    };
    if nodes >= PARALLEL_MIN_SPHERES {
        sx_nodes
            .par_iter_mut()
            .zip(sv_nodes.par_iter_mut())
            .enumerate()
            .for_each(node);
    } else {
        sx_nodes
            .iter_mut()
            .zip(sv_nodes.iter_mut())
            .enumerate()
            .for_each(node);
    }
    // Each rigid body (tasks of `BODIES_PER_TASK` bodies): its rotation and angular
    // velocity once, then its spheres (all, into the whole set's buffers; or, in a
    // partial step, its touched ones, into its run of the touched spheres' buffers).
    let (tx_rigid, tv_rigid): (&mut [[f64; 3]], &mut [[f64; 3]]) = match touched {
        Some((tx, tv)) => (tx, tv),
        None => (&mut [], &mut []),
    };
    let count = system.rigid_spheres.len();
    let starts = BodyRuns {
        spheres: &system.rigid_spheres,
        touched: only.map_or(&[], |o| o.active.ranges),
    };
    let body = |b: usize, (px, pv): SphereSlices, (tx, tv): SphereSlices| {
        let (r, shape) = (&rigid[b], &system.rigid[b]);
        let mine = only.and_then(|o| o.of(b));
        if mine.is_some_and(|(m, _)| m.is_empty()) {
            return;
        }
        let turn = r.rotation().to_rotation_matrix().into_inner();
        let omega = r.angular_velocity(shape);
        match mine {
            None => {
                for (k, (p, q)) in px.iter_mut().zip(pv.iter_mut()).enumerate() {
                    (*p, *q) = r.sphere(shape, &turn, &omega, k);
                }
                // A body marked whole in a partial step: its touched spheres too.
                if let Some(o) = only {
                    let first = system.rigid_spheres[b].start;
                    for (k, &s) in o.active.of(b).iter().enumerate() {
                        let s = s as usize - first;
                        (tx[k], tv[k]) = (px[s], pv[s]);
                    }
                }
            }
            Some((_, offsets)) => {
                for (k, offset) in offsets.iter().enumerate() {
                    (tx[k], tv[k]) = r.sphere_at(offset, &turn, &omega);
                }
            }
        }
    };
    let leaf = if total - nodes >= PARALLEL_MIN_SPHERES {
        BODIES_PER_TASK
    } else {
        count
    };
    for_bodies(
        0..count,
        leaf,
        &starts,
        (sx_rigid, sv_rigid),
        (tx_rigid, tv_rigid),
        &body,
    );
}

/// Rigid bodies per task of [`for_bodies`].
const BODIES_PER_TASK: usize = 64;

/// Each rigid body's run in the sphere buffers a gather fills: in the whole set's
/// (its spheres) and in the touched rigid spheres' (none outside a partial step).
struct BodyRuns<'a> {
    spheres: &'a [Range<usize>],
    touched: &'a [Range<usize>],
}

/// Two bodies' runs: of the whole set's spheres and of the touched ones.
type Runs<'s> = (SphereSlices<'s>, SphereSlices<'s>);

impl BodyRuns<'_> {
    /// The runs of bodies `from..at` split off the front of buffers that start at body
    /// `from`'s runs: (theirs, the rest).
    fn split<'s>(
        &self,
        from: usize,
        at: usize,
        (x, v): SphereSlices<'s>,
        (tx, tv): SphereSlices<'s>,
    ) -> (Runs<'s>, Runs<'s>) {
        // Where body b's run starts (b = the body count: where the last one ends).
        let start = |runs: &[Range<usize>], b: usize| {
            runs.get(b)
                .map_or_else(|| runs.last().map_or(0, |r| r.end), |r| r.start)
        };
        let s = start(self.spheres, at) - start(self.spheres, from);
        let t = start(self.touched, at) - start(self.touched, from);
        let ((x0, x1), (v0, v1)) = (x.split_at_mut(s), v.split_at_mut(s));
        let ((tx0, tx1), (tv0, tv1)) = (tx.split_at_mut(t), tv.split_at_mut(t));
        (((x0, v0), (tx0, tv0)), ((x1, v1), (tx1, tv1)))
    }
}

/// `body(b, spheres, touched)` for the rigid bodies `bodies`, each with its own runs of
/// the buffers `spheres` and `touched` (which start at the first body's runs). Halves
/// the bodies on rayon down to `leaf` bodies a task, so the buffers are split in
/// parallel too rather than by one serial pass over every body.
fn for_bodies<F>(
    bodies: Range<usize>,
    leaf: usize,
    starts: &BodyRuns<'_>,
    spheres: SphereSlices<'_>,
    touched: SphereSlices<'_>,
    body: &F,
) where
    F: Fn(usize, SphereSlices<'_>, SphereSlices<'_>) + Sync,
{
    if bodies.len() > leaf {
        let mid = bodies.start + bodies.len() / 2;
        let ((s0, t0), (s1, t1)) = starts.split(bodies.start, mid, spheres, touched);
        rayon::join(
            || for_bodies(bodies.start..mid, leaf, starts, s0, t0, body),
            || for_bodies(mid..bodies.end, leaf, starts, s1, t1, body),
        );
    } else {
        let (mut spheres, mut touched) = (spheres, touched);
        for b in bodies {
            let ((s0, t0), rest) = starts.split(b, b + 1, spheres, touched);
            body(b, s0, t0);
            (spheres, touched) = rest;
        }
    }
}

/// The rotation R minimising Σ m |x − x̄ − R (X − X̄)|² over the nodes `range` (Kabsch:
/// the polar factor of Σ m (x − x̄)(X − X̄)ᵀ); the identity for a body at rest.
fn best_fit_rotation(
    model: &QdemModel,
    x: &[[f64; 3]],
    range: Range<u32>,
) -> nalgebra::Matrix3<f64> {
    let (m, r) = (model.node_masses(), model.reference_positions());
    let range = range.start as usize..range.end as usize;
    let total: f64 = m[range.clone()].iter().sum();
    let mut cx = Vector3::zeros();
    let mut cr = Vector3::zeros();
    for i in range.clone() {
        cx += m[i] * Vector3::from(x[i]);
        cr += m[i] * Vector3::from(r[i]);
    }
    cx /= total;
    cr /= total;
    let mut h = nalgebra::Matrix3::zeros();
    for i in range {
        h += m[i] * (Vector3::from(x[i]) - cx) * (Vector3::from(r[i]) - cr).transpose();
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return nalgebra::Matrix3::identity();
    };
    let mut d = nalgebra::Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    u * d * vt
}

/// The force hook: contacts from the drifted state, node forces added into `f`, rigid
/// forces and torques stored in the rigid states.
#[allow(clippy::too_many_arguments)]
fn contact_forces(
    system: &MultiBody,
    contacts: &mut Contacts,
    cstate: &mut ContactState,
    rigid: &mut [RigidState],
    x: &[[f64; 3]],
    v: &[[f64; 3]],
    f: &mut [[f64; 3]],
    dt: f64,
    spheres: &mut SphereBuffers,
    kick: Option<SecondKick>,
) -> ContactTotals {
    let partial = spheres.plan(cstate, rigid, contacts.skin);
    gather(system, Some(x), Some(v), rigid, spheres.targets(partial));
    let stale = if partial {
        contacts.stale_among(cstate, &spheres.x, spheres.scanned(system))
    } else {
        contacts.stale(cstate, &spheres.x)
    };
    if stale {
        if partial {
            // A touched sphere moved the half skin: the rebuild needs every sphere.
            gather(system, Some(x), Some(v), rigid, spheres.targets(false));
        }
        contacts.rebuild(cstate, &spheres.x);
    }
    spheres.sync(system, contacts, cstate, stale, rigid);
    spheres.fill_touched(contacts.touched(), partial && !stale);
    let mut totals = contacts.forces_touched(cstate, &spheres.tx, &spheres.tv, dt);
    totals.rebuilt = stale;
    // The touched spheres' forces: the node spheres' first, then each rigid body's run.
    let (touched, tf) = (contacts.touched(), contacts.touched_forces());
    let nodes = spheres.touched_nodes();
    for (&s, force) in touched[..nodes].iter().zip(&tf[..nodes]) {
        if let SphereAt::Node { node, .. } = system.spheres[s as usize] {
            let fi = &mut f[node as usize];
            for d in 0..3 {
                fi[d] += force[d];
            }
        }
    }
    // Only touched spheres carry a force. Each body sums its own (and is kicked with
    // it in a step), so the bodies may run in parallel with the same bits.
    let active = spheres.active();
    let (tx, tf) = (&spheres.tx[nodes..], &tf[nodes..]);
    let sum = |(b, body): (usize, &mut RigidState)| {
        let c = body.position;
        let mut force = [0.0; 3];
        let mut torque = [0.0; 3];
        for k in active.ranges[b].clone() {
            let r = [tx[k][0] - c[0], tx[k][1] - c[1], tx[k][2] - c[2]];
            let t = cross(r, tf[k]);
            for d in 0..3 {
                force[d] += tf[k][d];
                torque[d] += t[d];
            }
        }
        body.force = force;
        body.torque = torque;
    };
    let many = active.active.len() >= PARALLEL_MIN_SPHERES || rigid.len() >= PARALLEL_MIN_BODIES;
    match kick {
        None if many => rigid.par_iter_mut().enumerate().for_each(sum),
        None => rigid.iter_mut().enumerate().for_each(sum),
        Some(k) => {
            let (g, half, damping) = (system.gravity, 0.5 * dt, k.damping);
            let sum_and_kick = |((b, body), shape): ((usize, &mut RigidState), &RigidShape)| {
                sum((b, &mut *body));
                let damped = body.kick(shape, g, half, damping);
                let finite = body
                    .position
                    .iter()
                    .chain(&body.velocity)
                    .all(|c| c.is_finite());
                (damped, body.kinetic_energy(shape), finite)
            };
            if many {
                let bodies = rigid.par_iter_mut().enumerate().zip(&system.rigid);
                bodies.map(sum_and_kick).collect_into_vec(k.out);
            } else {
                let bodies = rigid.iter_mut().enumerate().zip(&system.rigid);
                k.out.clear();
                k.out.extend(bodies.map(sum_and_kick));
            }
        }
    }
    totals
}

/// 2/ω_max over nodes and rigid bodies, ω² = Σ k_n / m (and Σ k_n r² / I_min for a
/// rigid body's rotation) over `pairs` (sphere pairs, and sphere–plane pairs marked as
/// in [`Contacts::within`]), times the dashpot correction.
fn contact_stable_step(
    system: &MultiBody,
    pairs: &[(u32, u32)],
    sx: &[[f64; 3]],
    rigid: &[RigidState],
) -> f64 {
    use nalgebra::Matrix3;
    let set = &system.set;
    let mut stiffness = vec![0.0; system.spheres.len()];
    let mut zeta: f64 = 0.0;
    // Per rigid body: Σ k n nᵀ (translation) and Σ k (r × n)(r × n)ᵀ (rotation).
    let mut translational = vec![Matrix3::zeros(); system.rigid.len()];
    let mut rotational = vec![Matrix3::zeros(); system.rigid.len()];
    let mut add = |s: usize, k: f64, n: Vector3<f64>| {
        stiffness[s] += k;
        if let SphereAt::Rigid { body, .. } = system.spheres[s] {
            let b = body as usize;
            let r = Vector3::from(sx[s]) - Vector3::from(rigid[b].position);
            let arm = r.cross(&n);
            translational[b] += k * n * n.transpose();
            rotational[b] += k * arm * arm.transpose();
        }
    };
    for &(first, second) in pairs {
        let i = first as usize;
        if second & (1 << 31) != 0 {
            let plane = &set.planes[(second & !(1 << 31)) as usize];
            let law = set.laws[plane.material as usize * set.materials + set.material[i] as usize];
            add(i, law.normal_stiffness, Vector3::from(plane.normal));
            zeta = zeta.max(law.damping_ratio);
        } else {
            let j = second as usize;
            let law = set.laws[set.material[i] as usize * set.materials + set.material[j] as usize];
            let d = super::neighbours::Period::difference(set.period.as_ref(), sx[i], sx[j]);
            let n = Vector3::from(d).try_normalize(0.0).unwrap_or(Vector3::z());
            add(i, law.normal_stiffness, n);
            add(j, law.normal_stiffness, n);
            zeta = zeta.max(law.damping_ratio);
        }
    }
    let mut omega2: f64 = 0.0;
    let masses = system.model.as_ref().map(|m| m.node_masses());
    for (s, at) in system.spheres.iter().enumerate() {
        if let (SphereAt::Node { node, .. }, Some(m)) = (at, masses) {
            omega2 = omega2.max(stiffness[s] / m[*node as usize]);
        }
    }
    for (b, shape) in system.rigid.iter().enumerate() {
        let t = translational[b].symmetric_eigenvalues().max() / shape.mass;
        // I^{-1/2} Rᵀ K_r R I^{-1/2} in the principal frame.
        let r = rigid[b].rotation().to_rotation_matrix();
        let k = r.matrix().transpose() * rotational[b] * r.matrix();
        let scale = Matrix3::from_diagonal(&Vector3::from(
            shape.principal_inertia.map(|i| 1.0 / i.sqrt()),
        ));
        let w = (scale * k * scale).symmetric_eigenvalues().max();
        omega2 = omega2.max(t).max(w);
    }
    if omega2 <= 0.0 {
        return f64::INFINITY;
    }
    2.0 / omega2.sqrt() * ((1.0 + zeta * zeta).sqrt() - zeta)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::{ContactLaw, Plane, SphereMaterial};
    use crate::qdem::structured_box;
    use nalgebra::Point3;

    /// Halving the bodies on rayon hands every body the same runs as one pass does:
    /// its own spheres and touched spheres, empty runs included.
    #[test]
    fn bodies_split_in_halves_get_their_own_runs() {
        let runs = BodyRuns {
            spheres: &[0..3, 3..3, 3..7, 7..8, 8..12],
            touched: &[0..1, 1..1, 1..3, 3..3, 3..5],
        };
        let fill = |n: usize| (0..n).map(|i| [i as f64; 3]).collect::<Vec<_>>();
        let seen = |leaf: usize| {
            let (mut x, mut v, mut tx, mut tv) = (fill(12), fill(12), fill(5), fill(5));
            let got = std::sync::Mutex::new(Vec::new());
            let body = |b: usize, (x, v): SphereSlices, (tx, tv): SphereSlices| {
                assert_eq!((x.len(), tx.len()), (v.len(), tv.len()));
                let first = |s: &[[f64; 3]]| s.first().map(|p| p[0]);
                got.lock()
                    .unwrap()
                    .push((b, x.len(), first(x), tx.len(), first(tx)));
            };
            for_bodies(
                0..5,
                leaf,
                &runs,
                (&mut x, &mut v),
                (&mut tx, &mut tv),
                &body,
            );
            let mut got = got.into_inner().unwrap();
            got.sort_by_key(|g| g.0);
            got
        };
        let expected = vec![
            (0, 3, Some(0.0), 1, Some(0.0)),
            (1, 0, None, 0, None),
            (2, 4, Some(3.0), 2, Some(1.0)),
            (3, 1, Some(7.0), 0, None),
            (4, 4, Some(8.0), 2, Some(3.0)),
        ];
        assert_eq!(seen(5), expected);
        assert_eq!(seen(1), expected);
        assert_eq!(seen(2), expected);
    }

    /// One rigid 0.2 × 0.2 × 0.1 m block (2700 kg/m³) with spheres of radius 10 mm at
    /// its 8 corners inset by r along the diagonal (touching the faces), on the floor.
    fn block_on_floor(mu: f64, gravity: [f64; 3]) -> MultiBody {
        blocks_on_floor(&[([0.0; 3], mu)], gravity)
    }

    /// [`block_on_floor`]'s block at each offset, each with its own friction against
    /// the floor (material b for block b).
    fn blocks_on_floor(blocks: &[([f64; 3], f64)], gravity: [f64; 3]) -> MultiBody {
        let (nodes, tets) = structured_box(Vector3::new(0.2, 0.2, 0.1), [1, 1, 1]);
        let r = 0.01;
        let corners: Vec<Point3<f64>> = nodes
            .iter()
            .map(|p| {
                let c = |x: f64, hi: f64| if x > 0.5 * hi { x - r } else { x + r };
                Point3::new(c(p.x, 0.2), c(p.y, 0.2), c(p.z, 0.1))
            })
            .collect();
        let m = SphereMaterial {
            normal_stiffness: 1e8,
            tangential_stiffness: 4e7,
        };
        let n = corners.len();
        let count = blocks.len();
        let shift = |points: &[Point3<f64>], o: [f64; 3]| -> Vec<Point3<f64>> {
            points.iter().map(|p| p + Vector3::from(o)).collect()
        };
        let rigid = blocks
            .iter()
            .map(|&(o, _)| {
                RigidShape::from_tets(&shift(&nodes, o), &tets, 2700.0, &shift(&corners, o))
                    .unwrap()
            })
            .collect();
        // Material b meets the floor (material 0) with block b's µ; blocks never meet.
        let laws = (0..count * count)
            .map(|ab| ContactLaw::between(&m, &m, blocks[ab % count.max(1)].1, 0.1))
            .collect();
        let owner: Vec<u32> = (0..count * n).map(|s| (s / n) as u32).collect();
        MultiBody {
            model: None,
            boundary: Boundary::default(),
            rigid,
            bodies: (0..count as u32)
                .map(|index| BodyKind::Rigid { index })
                .collect(),
            spheres: (0..(count * n) as u32)
                .map(|s| SphereAt::Rigid {
                    body: s / n as u32,
                    k: s % n as u32,
                })
                .collect(),
            rigid_spheres: (0..count).map(|b| b * n..(b + 1) * n).collect(),
            deformable: Vec::new(),
            insets: false,
            set: SphereSet {
                radius: vec![r; count * n],
                material: owner.iter().map(|&b| b as u16).collect(),
                owner,
                mass: vec![10.8; count * n],
                planes: vec![Plane {
                    point: [0.0; 3],
                    normal: [0.0, 0.0, 1.0],
                    material: 0,
                }],
                laws,
                materials: count,
                period: None,
                shared_rest: false,
            },
            gravity,
        }
    }

    #[test]
    fn a_block_comes_to_rest_on_its_springs() {
        let g = 9.81;
        let system = block_on_floor(0.5, [0.0, 0.0, -g]);
        let mut state = system.at_rest();
        let mut solver = MultiBodySolver::new(&system, 2e-5, 1e-3).unwrap();
        let s = solver.stability(&mut state);
        assert!(s.contact > 2e-5, "{s:?}");
        for _ in 0..20_000 {
            solver.step(&mut state).unwrap();
        }
        // Four bottom spheres carry m g: each overlaps m g / (4 k).
        let mass = system.rigid[0].mass;
        let expect = mass * g / (4.0 * 1e8);
        let sink = system.rigid[0].centre[2] - state.rigid[0].position[2];
        assert!(
            (sink / expect - 1.0).abs() < 1e-3,
            "sink {sink} vs {expect}"
        );
        assert!(state.kinetic() < 1e-9 * mass * g * 0.05);
        assert!(state.balance_error().abs() < 1e-3 * state.external_work().abs());
    }

    /// A solver resumed on a state whose QDEM part was never primed primes it at the
    /// start of its first step, as a fresh solver does: the same bits. (Primed inside
    /// the QDEM step instead, after the rigid drift and with the step's hook, the block
    /// took a second half kick and its contacts were evaluated twice.)
    #[test]
    fn a_solver_resumed_on_an_unprimed_state_runs_as_a_fresh_one() {
        let mut system = block_on_floor(0.5, [0.0, 0.0, -9.81]);
        let (nodes, tets) = structured_box(Vector3::new(0.1, 0.1, 0.1), [1, 1, 1]);
        let away: Vec<Point3<f64>> = nodes
            .iter()
            .map(|p| p + Vector3::new(5.0, 0.0, 1.0))
            .collect();
        let material = crate::qdem::QdemMaterial::elastic(2000.0, 1e7, 0.3);
        system.model = Some(QdemModel::new(&away, &tets, &material).unwrap());
        let run = |resumed: bool| {
            let mut state = system.at_rest();
            let mut solver = MultiBodySolver::new(&system, 2e-5, 1e-3).unwrap();
            if resumed {
                solver.resume(&state.clone(), Vec::new());
            }
            for _ in 0..200 {
                solver.step(&mut state).unwrap();
            }
            state
        };
        let (primed, resumed) = (run(false), run(true));
        // The block has sunk into its springs (the run is not a state at rest).
        let sink = system.rigid[0].centre[2] - primed.rigid[0].position[2];
        assert!(sink > 1e-7, "sink {sink}");
        assert_eq!(primed.rigid, resumed.rigid);
        let positions = |s: MultiState| s.deformable.unwrap().positions;
        assert_eq!(positions(primed), positions(resumed));
    }

    /// The skin sets the cost, not the result: a block dropped 1 cm onto a 35° slope
    /// slides 3 cm down it, beside a second block that rests on the slope (µ = 2). The
    /// lists are rebuilt dozens of times, and the top spheres are in none, so steps
    /// update only the bottom ones while a block has moved little since the last
    /// rebuild: both blocks' while the first one rests or slides slowly, the resting
    /// block's alone while the first one falls (then it touches nothing, and only the
    /// bound on its motion brings its spheres up to date and into the staleness
    /// scan). It lands, and both end in the same bits with skins of 0.25, 1 and 4 mm,
    /// and with the same time step.
    #[test]
    fn the_skin_changes_the_cost_not_the_bits() {
        let g = 9.81;
        let theta = 35f64.to_radians();
        let mut system = blocks_on_floor(
            &[([0.0; 3], 0.5), ([0.0, 1.0, -0.01], 2.0)],
            [g * theta.sin(), 0.0, -g * theta.cos()],
        );
        system.set.planes[0].point = [0.0, 0.0, -0.01];
        let run = |skin: f64| {
            let mut state = system.at_rest();
            let mut solver = MultiBodySolver::new(&system, 2e-5, skin).unwrap();
            let stable = solver.stability(&mut state);
            for _ in 0..10_000 {
                solver.step(&mut state).unwrap();
            }
            (state.rigid.clone(), state.contacts.rebuilds, stable.contact)
        };
        let (reference, rebuilds, stable) = run(1e-3);
        let moved = |b: usize| {
            let (now, then) = (reference[b].position, system.rigid[b].centre);
            [now[0] - then[0], now[1] - then[1], now[2] - then[2]]
        };
        assert!(moved(0)[0] > 0.02, "the first block slides: {:?}", moved(0));
        // On the slope: sunk by its weight's share (≈ 10 µm), not through it.
        let height = moved(0)[2] + 0.01;
        assert!(
            height.abs() < 1e-4,
            "height above the resting level {height}"
        );
        let rest = moved(1);
        assert!(
            rest.iter().all(|d| d.abs() < 2e-5),
            "the second block stays: {rest:?}"
        );
        for skin in [2.5e-4, 4e-3] {
            let (rigid, r, s) = run(skin);
            assert_eq!(rigid, reference, "skin {skin}");
            assert_ne!(r, rebuilds, "skin {skin}: the lists should differ");
            assert_eq!(s, stable, "skin {skin}: the stable step");
        }
    }

    #[test]
    fn a_block_sticks_below_the_friction_angle_and_slides_above_it() {
        let g = 9.81;
        let mu = 0.5;
        for (degrees, slides) in [(20.0f64, false), (35.0, true)] {
            let theta = degrees.to_radians();
            // The floor tilted by θ about y: gravity turned the other way.
            let system = block_on_floor(mu, [g * theta.sin(), 0.0, -g * theta.cos()]);
            let mut state = system.at_rest();
            let mut solver = MultiBodySolver::new(&system, 2e-5, 1e-3).unwrap();
            solver.stability(&mut state);
            let steps = 10_000; // 0.2 s
            for _ in 0..steps {
                solver.step(&mut state).unwrap();
            }
            let x = state.rigid[0].position[0] - system.rigid[0].centre[0];
            let t = steps as f64 * 2e-5;
            let a = g * (theta.sin() - mu * theta.cos());
            if slides {
                // x = a t²/2 after the springs load (a few 0.1 ms): within 1 %.
                assert!(
                    (x / (0.5 * a * t * t) - 1.0).abs() < 0.01,
                    "x {x} vs {}",
                    0.5 * a * t * t
                );
            } else {
                // Only the tangential springs' elastic give: m g sinθ / (4 k_t) ≈ 0.3 µm.
                assert!(x.abs() < 2e-6, "drift {x}");
            }
        }
    }
}
