//! Explicit velocity-Verlet stepping of a QDEM body (seed 004 §2.4).
//!
//! One step from t_n to t_{n+1} = t_n + dt, in three phases:
//! 1. nodes: v_{n+½} = v_n + dt/2 a_n, x_{n+1} = x_n + dt v_{n+½} (fixed directions held);
//! 2. tetra: stress T(x_{n+1}, v_{n+½}) (eq. 1–8) and internal forces p_i (eq. 9–11),
//!    by coloured blocks (bitwise identical for any thread count); then the group
//!    springs and the group loads;
//! 3. nodes: a_{n+1} = (p + f_ext + m g − damping)/m, v_{n+1} = v_{n+½} + dt/2 a_{n+1}.
//!
//! The viscous stress uses the half-step velocity (the lagged central difference of
//! explicit FEM), whose stability limit [`super::stability`] computes. The energies are
//! updated every step and checked: a non-finite state, an inverted tetra or a mechanical
//! energy above [`QdemOptions::blowup_energy_factor`] × (initial energy + most work put
//! in) stops the run with an error naming the stable time step.

use super::boundary::{Boundary, GroupSpring, NodalLoad};
use super::colouring::PARALLEL_MIN_TETS;
use super::element::{ElementSums, Vec3};
use super::energy::Energies;
use super::kernel::Force4;
use super::model::{ElementTotals, QdemModel};
use super::stability::stability;
use crate::{Error, Result};
use nalgebra::Matrix3;
use rayon::prelude::*;

/// Numerical damping for reaching a steady state (dynamic relaxation). Both vanish at
/// rest, so a converged static solution is the undamped one; neither is physical (the
/// material's own damping is its viscosity).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Damping {
    /// No numerical damping: the paper's scheme.
    #[default]
    None,
    /// Mass-proportional damping force −rate · m v (rate in 1/s, using v_{n+½}).
    /// Critical damping of a mode of angular frequency ω is rate = 2ω.
    MassProportional {
        /// Damping rate α (1/s).
        rate: f64,
    },
    /// Kinetic damping (Cundall): whenever the total kinetic energy falls after a peak,
    /// all velocities are set to zero. Needs no parameter; the steady state is exact.
    KineticPeak,
}

/// Options of the integrator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QdemOptions {
    /// Numerical damping (default none).
    pub damping: Damping,
    /// Refuse a time step above the stable one at construction (default true). With
    /// false the run starts and the blow-up check stops it.
    pub check_time_step: bool,
    /// The run stops when kinetic + strain energy exceeds this factor times (initial
    /// energy + the most external work done so far). Default 10: far above the Verlet
    /// energy fluctuation (which reaches a few × for modes near the limit), far below
    /// what an unstable mode reaches within a few dozen steps.
    pub blowup_energy_factor: f64,
}

impl Default for QdemOptions {
    fn default() -> Self {
        QdemOptions {
            damping: Damping::None,
            check_time_step: true,
            blowup_energy_factor: 10.0,
        }
    }
}

/// The state of a body: positions, velocities, accelerations at time `time`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct State {
    /// Time (s).
    pub time: f64,
    /// Steps taken.
    pub step: u64,
    /// Node positions (m), one `[x, y, z]` per node (interleaved so that a tetra's
    /// gather reads one cache line per node).
    pub positions: Vec<[f64; 3]>,
    /// Node velocities (m/s).
    pub velocities: Vec<[f64; 3]>,
    /// Node accelerations (m/s²) at `time` (valid once the solver has primed the state).
    pub accelerations: Vec<[f64; 3]>,
    /// Energy terms.
    pub energies: Energies,
    primed: bool,
    /// kinetic + strain at the start, and the most external work done so far: the
    /// bound of the blow-up check.
    initial_mechanical: f64,
    most_work: f64,
}

impl State {
    /// Whether a solver has computed this state's forces and accelerations (a step
    /// primes an unprimed state first).
    pub fn is_primed(&self) -> bool {
        self.primed
    }

    /// The model at rest in its reference configuration at t = 0.
    pub fn at_rest(model: &QdemModel) -> Self {
        let n = model.node_count();
        State {
            time: 0.0,
            step: 0,
            positions: model.reference_positions().to_vec(),
            velocities: vec![[0.0; 3]; n],
            accelerations: vec![[0.0; 3]; n],
            energies: Energies::default(),
            primed: false,
            initial_mechanical: 0.0,
            most_work: 0.0,
        }
    }

    /// Displacements from the reference configuration (m).
    pub fn displacements(&self, model: &QdemModel) -> Vec<[f64; 3]> {
        self.positions
            .iter()
            .zip(model.reference_positions())
            .map(|(x, r)| [x[0] - r[0], x[1] - r[1], x[2] - r[2]])
            .collect()
    }
}

/// Nodes per task of the node phases: a few tasks even on a sleeper of ~5 000 nodes
/// (4 096 gave two uneven ones there).
const NODE_CHUNK: usize = 1024;

/// One chunk of a node phase: (index, (((x, v), a), sums)) for the drift,
/// (index, (((v, a), f), sums)) for the kick.
type ChunkItem<'a, 'b, R = Vec3> = (
    usize,
    (
        ((&'a mut [Vec3], &'a mut [Vec3]), &'a [R]),
        &'b mut NodeSums,
    ),
);

#[derive(Debug, Clone, Copy, Default)]
struct NodeSums {
    gravity_work: f64,
    damping_work: f64,
    kinetic: f64,
    acceleration_squared: f64,
    /// Σ ½(f_n + f_{n+1})·Δx of the hook's forces (0 when priming).
    hook_work: f64,
    /// Σ |f|²/m of the hook's forces (part of `pending_energy`).
    hook_pending: f64,
    non_finite: bool,
}

/// The integrator: a model, its boundary conditions, the step and scratch buffers.
/// The state is passed to [`QdemSolver::step`] explicitly.
#[derive(Debug)]
pub struct QdemSolver<'m> {
    model: &'m QdemModel,
    dt: f64,
    options: QdemOptions,
    masks: Vec<u8>,
    loads: Vec<NodalLoad>,
    springs: Vec<GroupSpring>,
    gravity: Vec3,
    forces: Vec<Force4>,
    /// Kinetic energy the current external forces alone would give in one step,
    /// Σ dt² |f_ext|² / (2m): the blow-up bound's allowance for a load that has only
    /// just started (its work lags the energy by half a step in Verlet).
    pending_energy: f64,
    /// Strain energy of a strain of 1e-12 everywhere: below it energies are round-off
    /// (a body at rest has F = I only to round-off) and the blow-up check ignores them.
    energy_floor: f64,
    element_partials: Vec<ElementSums>,
    node_partials: Vec<NodeSums>,
    /// Forces of the caller's hook ([`QdemSolver::step_with`]) at the last and the
    /// current evaluation, for the trapezoidal work of those forces.
    hook_forces: Vec<Vec3>,
    hook_previous: Vec<Vec3>,
}

/// Nodal forces a caller adds to the internal ones every step (e.g. contacts):
/// `hook(time, positions, velocities, forces)` with the drifted positions x_{n+1} and
/// the half-step velocities v_{n+½} (v_0 when priming), adding into `forces` (zeroed).
/// `Send`, so that it may run beside the element forces (see
/// `forces_and_accelerations`).
pub type ForceHook<'h> = dyn FnMut(f64, &[Vec3], &[Vec3], &mut [Vec3]) + Send + 'h;

impl<'m> QdemSolver<'m> {
    /// Checks the boundary conditions and the time step `dt` (s) against the model.
    pub fn new(
        model: &'m QdemModel,
        boundary: &Boundary,
        dt: f64,
        options: QdemOptions,
    ) -> Result<Self> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::Message(format!(
                "QDEM: time step dt = {dt} s must be positive"
            )));
        }
        let n = model.node_count();
        let masks = boundary.constraints.masks(n)?;
        for (i, load) in boundary.loads.iter().enumerate() {
            load.validate(i, n)?;
        }
        for (i, spring) in boundary.springs.iter().enumerate() {
            spring.validate(i, n)?;
        }
        if boundary.gravity.iter().any(|g| !g.is_finite()) {
            return Err(Error::Message("QDEM: gravity is not finite".into()));
        }
        check_damping(options.damping, dt)?;
        if options.check_time_step {
            let s = stability(model);
            if dt > s.stable {
                return Err(Error::Message(format!(
                    "QDEM: time step dt = {dt:.4e} s exceeds the stable time step {:.4e} s \
                     ({:.2} × stable; {:.4e} s is recommended)",
                    s.stable,
                    dt / s.stable,
                    s.recommended()
                )));
            }
        }
        Ok(QdemSolver {
            model,
            dt,
            options,
            masks,
            loads: boundary.loads.clone(),
            springs: boundary.springs.clone(),
            gravity: [boundary.gravity.x, boundary.gravity.y, boundary.gravity.z],
            forces: vec![Force4::default(); n],
            pending_energy: 0.0,
            energy_floor: 0.5e-24 * model.modulus_volume(),
            element_partials: vec![ElementSums::default(); model.colouring.blocks.len()],
            node_partials: vec![NodeSums::default(); n.div_ceil(NODE_CHUNK)],
            hook_forces: Vec::new(),
            hook_previous: Vec::new(),
        })
    }

    /// The hook forces of the last step, which the next step's trapezoidal hook work
    /// uses (what a checkpoint keeps of the solver besides the [`State`]).
    pub fn hook_memory(&self) -> &[Vec3] {
        &self.hook_forces
    }

    /// Puts back the hook forces saved by [`Self::hook_memory`] (resuming a run).
    pub fn restore_hook_memory(&mut self, forces: Vec<Vec3>) {
        self.hook_forces = forces;
    }

    /// The time step (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Changes the numerical damping between steps (e.g. damped settling, then the
    /// undamped run); the same checks as at construction.
    pub fn set_damping(&mut self, damping: Damping) -> Result<()> {
        check_damping(damping, self.dt)?;
        self.options.damping = damping;
        Ok(())
    }

    /// The model.
    pub fn model(&self) -> &'m QdemModel {
        self.model
    }

    /// Computes the accelerations and energies of a fresh state (done by the first
    /// [`Self::step`] if not called); zeroes velocities in fixed directions.
    pub fn prime(&mut self, state: &mut State) -> Result<()> {
        self.prime_with(state, None)
    }

    /// [`Self::prime`] with a force hook (see [`ForceHook`]).
    pub fn prime_with(
        &mut self,
        state: &mut State,
        hook: Option<&mut ForceHook<'_>>,
    ) -> Result<()> {
        let n = self.model.node_count();
        if state.positions.len() != n || state.velocities.len() != n {
            return Err(Error::Message(format!(
                "QDEM: the state has {} nodes, the model {n}",
                state.positions.len()
            )));
        }
        state.accelerations.resize(n, [0.0; 3]);
        for (v, &mask) in state.velocities.iter_mut().zip(&self.masks) {
            for (d, c) in v.iter_mut().enumerate() {
                if mask & (1 << d) != 0 {
                    *c = 0.0;
                }
            }
        }
        let totals = self.forces_and_accelerations(state, 0.0, hook);
        let sums = self.node_partials.iter().fold(NodeSums::default(), merge);
        self.pending_energy += 0.5 * self.dt * self.dt * sums.hook_pending;
        let verlet_correction = self.dt * self.dt / 8.0 * sums.acceleration_squared;
        state.energies = Energies {
            kinetic: sums.kinetic,
            verlet_correction,
            strain: totals.strain_energy,
            initial: sums.kinetic - verlet_correction + totals.strain_energy,
            ..Energies::default()
        };
        state.primed = true;
        state.initial_mechanical = state.energies.mechanical();
        state.most_work = 0.0;
        self.check(state, &totals, sums.non_finite)
    }

    /// Advances `state` by one step dt.
    pub fn step(&mut self, state: &mut State) -> Result<()> {
        self.step_with(state, None)
    }

    /// [`Self::step`] with nodal forces added by `hook` after the drift (contacts with
    /// other bodies): their work, ½(f_n + f_{n+1})·Δx, is counted as external work.
    pub fn step_with(
        &mut self,
        state: &mut State,
        mut hook: Option<&mut ForceHook<'_>>,
    ) -> Result<()> {
        if !state.primed {
            self.prime_with(state, hook.as_deref_mut())?;
        }
        let dt = self.dt;
        let half = 0.5 * dt;
        let masses = self.model.node_masses();
        let (g, rate) = (self.gravity, self.damping_rate());
        // Phase 1: half kick and drift.
        let masks = &self.masks;
        let drift = |(chunk, (((x, v), a), sums)): ChunkItem<'_, '_>| {
            let start = chunk * NODE_CHUNK;
            let mut s = NodeSums::default();
            for i in 0..x.len() {
                let mask = masks[start + i];
                let m = masses[start + i];
                let mut v2 = 0.0;
                for d in 0..3 {
                    let vd = if mask & (1 << d) != 0 {
                        0.0
                    } else {
                        v[i][d] + half * a[i][d]
                    };
                    v[i][d] = vd;
                    x[i][d] += dt * vd;
                    s.gravity_work += m * g[d] * dt * vd;
                    v2 += vd * vd;
                }
                s.damping_work += rate * m * v2 * dt;
            }
            *sums = s;
        };
        if self.parallel() {
            state
                .positions
                .par_chunks_mut(NODE_CHUNK)
                .zip(state.velocities.par_chunks_mut(NODE_CHUNK))
                .zip(state.accelerations.par_chunks(NODE_CHUNK))
                .zip(self.node_partials.par_iter_mut())
                .enumerate()
                .for_each(drift);
        } else {
            state
                .positions
                .chunks_mut(NODE_CHUNK)
                .zip(state.velocities.chunks_mut(NODE_CHUNK))
                .zip(state.accelerations.chunks(NODE_CHUNK))
                .zip(self.node_partials.iter_mut())
                .enumerate()
                .for_each(drift);
        }
        let phase1 = self.node_partials.iter().fold(NodeSums::default(), merge);
        let t_new = state.time + dt;
        let load_work = self.load_work(state, t_new);
        // Phases 2 and 3.
        let totals = self.forces_and_accelerations(state, t_new, hook);
        let phase3 = self.node_partials.iter().fold(NodeSums::default(), merge);
        self.pending_energy += 0.5 * dt * dt * phase3.hook_pending;
        let hook_work = phase3.hook_work;
        state.time = t_new;
        state.step += 1;
        let e = &mut state.energies;
        let previous_kinetic = e.kinetic;
        e.kinetic = phase3.kinetic;
        e.verlet_correction = dt * dt / 8.0 * phase3.acceleration_squared;
        e.strain = totals.strain_energy;
        e.viscous_dissipated += dt * totals.dissipation_rate;
        e.damping_dissipated += phase1.damping_work;
        e.external_work += phase1.gravity_work + load_work + hook_work;
        e.hook_work += hook_work;
        if self.options.damping == Damping::KineticPeak && e.kinetic < previous_kinetic {
            e.damping_dissipated += e.kinetic;
            e.kinetic = 0.0;
            state.velocities.fill([0.0; 3]);
        }
        state.most_work = state.most_work.max(state.energies.external_work);
        self.check(state, &totals, phase1.non_finite || phase3.non_finite)
    }

    /// Takes `steps` steps (stops at the first error).
    pub fn advance(&mut self, state: &mut State, steps: usize) -> Result<()> {
        for _ in 0..steps {
            self.step(state)?;
        }
        Ok(())
    }

    /// Cauchy stress T = T_E + T_D of every tetra (original order) in `state`.
    pub fn stresses(&self, state: &State) -> Vec<Matrix3<f64>> {
        self.model.stresses(&state.positions, &state.velocities)
    }

    /// Whether the node phases go to the thread pool (same results either way).
    fn parallel(&self) -> bool {
        self.model.tet_count() >= PARALLEL_MIN_TETS
    }

    fn damping_rate(&self) -> f64 {
        match self.options.damping {
            Damping::MassProportional { rate } => rate,
            _ => 0.0,
        }
    }

    /// Work of the group loads over the step just drifted: ½(φ_n + φ_{n+1}) F/N · Σ Δx.
    fn load_work(&self, state: &State, t_new: f64) -> f64 {
        let mut work = 0.0;
        for load in &self.loads {
            let phi = 0.5 * (load.time_fn.value(state.time) + load.time_fn.value(t_new));
            let per_node = load.total_force / load.nodes.len() as f64 * phi;
            let mut moved = [0.0; 3];
            for &n in &load.nodes {
                let v = state.velocities[n as usize];
                for d in 0..3 {
                    moved[d] += self.dt * v[d];
                }
            }
            work += per_node.x * moved[0] + per_node.y * moved[1] + per_node.z * moved[2];
        }
        work
    }

    /// Internal forces at (x, v), loads at `time`, the hook's forces, then
    /// accelerations and the second half kick (velocities are the half-step ones on
    /// entry when stepping; on priming dt/2 kick is skipped). Node sums, with the hook
    /// forces' work and their share of `pending_energy`, land in `node_partials`: the
    /// hook's forces are added in the kick's own parallel pass rather than in a serial
    /// pass over every node before it. Returns the element totals.
    fn forces_and_accelerations(
        &mut self,
        state: &mut State,
        time: f64,
        hook: Option<&mut ForceHook<'_>>,
    ) -> ElementTotals {
        // The element forces and the hook's (contacts) read the same positions and
        // velocities and write their own buffers, so they run side by side: a thread
        // that is done with one helps with the other's parallel loops, and neither
        // waits at the other's end. The bits do not depend on it.
        let (model, x, v) = (self.model, &state.positions, &state.velocities);
        let (forces, partials) = (&mut self.forces, &mut self.element_partials);
        let mut internal = || model.internal_forces_with(x, v, forces, partials);
        let (mut totals, hooked) = match hook {
            Some(hook) => {
                let (current, previous) = (&mut self.hook_forces, &mut self.hook_previous);
                let call = || call_hook(current, previous, (time, x, v), hook);
                (rayon::join(internal, call).0, true)
            }
            None => (internal(), false),
        };
        totals.strain_energy += self.add_spring_forces(&state.positions);
        let gravity_squared = self.gravity.iter().map(|g| g * g).sum::<f64>();
        let dt2 = self.dt * self.dt;
        self.pending_energy = 0.5 * dt2 * gravity_squared * self.model.total_mass();
        for load in &self.loads {
            let per_node = load.total_force / load.nodes.len() as f64 * load.time_fn.value(time);
            for &n in &load.nodes {
                self.pending_energy +=
                    0.5 * dt2 * per_node.norm_squared() / self.model.node_masses()[n as usize];
                let f = &mut self.forces[n as usize].0;
                f[0] += per_node.x;
                f[1] += per_node.y;
                f[2] += per_node.z;
            }
        }
        // The hook's forces of this evaluation, and of the last one for the trapezoidal
        // work (none when priming, or on the first call).
        let hook = hooked.then(|| {
            let n = self.model.node_count();
            let previous = (state.primed && self.hook_previous.len() == n)
                .then_some(self.hook_previous.as_slice());
            (self.hook_forces.as_slice(), previous)
        });
        let half = if state.primed { 0.5 * self.dt } else { 0.0 };
        let dt = self.dt;
        let masses = self.model.node_masses();
        let (g, rate) = (self.gravity, self.damping_rate());
        let masks = &self.masks;
        let kick = |(chunk, (((v, a), f), sums)): ChunkItem<'_, '_, Force4>| {
            let start = chunk * NODE_CHUNK;
            let mut s = NodeSums::default();
            for i in 0..v.len() {
                let mask = masks[start + i];
                let m = masses[start + i];
                let mut fi = f[i].0;
                if let Some((forces, previous)) = hook {
                    let fh = forces[start + i];
                    if let Some(previous) = previous {
                        let p = previous[start + i];
                        for d in 0..3 {
                            s.hook_work += 0.5 * (fh[d] + p[d]) * dt * v[i][d];
                        }
                    }
                    for d in 0..3 {
                        fi[d] += fh[d];
                    }
                    s.hook_pending += (fh[0] * fh[0] + fh[1] * fh[1] + fh[2] * fh[2]) / m;
                }
                let (mut v2, mut a2) = (0.0, 0.0);
                for d in 0..3 {
                    let (ad, vd) = if mask & (1 << d) != 0 {
                        (0.0, 0.0)
                    } else {
                        let ad = (fi[d] - rate * m * v[i][d]) / m + g[d];
                        (ad, v[i][d] + half * ad)
                    };
                    a[i][d] = ad;
                    v[i][d] = vd;
                    v2 += vd * vd;
                    a2 += ad * ad;
                    s.non_finite |= !(ad.is_finite() && vd.is_finite());
                }
                s.kinetic += 0.5 * m * v2;
                s.acceleration_squared += m * a2;
            }
            *sums = s;
        };
        if self.parallel() {
            state
                .velocities
                .par_chunks_mut(NODE_CHUNK)
                .zip(state.accelerations.par_chunks_mut(NODE_CHUNK))
                .zip(self.forces.par_chunks(NODE_CHUNK))
                .zip(self.node_partials.par_iter_mut())
                .enumerate()
                .for_each(kick);
        } else {
            state
                .velocities
                .chunks_mut(NODE_CHUNK)
                .zip(state.accelerations.chunks_mut(NODE_CHUNK))
                .zip(self.forces.chunks(NODE_CHUNK))
                .zip(self.node_partials.iter_mut())
                .enumerate()
                .for_each(kick);
        }
        totals
    }

    /// Adds the group springs' forces −k ū e / N at positions `x` and returns their
    /// potential Σ ½ k ū² ([`GroupSpring`]).
    fn add_spring_forces(&mut self, x: &[Vec3]) -> f64 {
        let reference = self.model.reference_positions();
        let mut energy = 0.0;
        for spring in &self.springs {
            let e = spring.direction;
            let mut sum = 0.0;
            for &n in &spring.nodes {
                let (xi, ri) = (x[n as usize], reference[n as usize]);
                sum += e.x * (xi[0] - ri[0]) + e.y * (xi[1] - ri[1]) + e.z * (xi[2] - ri[2]);
            }
            let count = spring.nodes.len() as f64;
            let mean = sum / count;
            energy += 0.5 * spring.stiffness * mean * mean;
            let per_node = -spring.stiffness * mean / count;
            for &n in &spring.nodes {
                let f = &mut self.forces[n as usize].0;
                f[0] += per_node * e.x;
                f[1] += per_node * e.y;
                f[2] += per_node * e.z;
            }
        }
        energy
    }

    /// Stops a run that has blown up, naming the stable time step.
    fn check(&self, state: &State, totals: &ElementTotals, non_finite: bool) -> Result<()> {
        let e = &state.energies;
        let reason = if non_finite || !(e.kinetic.is_finite() && e.strain.is_finite()) {
            Some("the state is no longer finite (NaN or infinity)".to_string())
        } else if totals.inverted > 0 {
            Some(format!(
                "{} tetra are inverted (first: tetra {})",
                totals.inverted,
                totals.first_inverted.unwrap_or(0)
            ))
        } else {
            let bound = state.initial_mechanical
                + state.most_work.max(0.0)
                + self.pending_energy
                + self.energy_floor;
            let factor = self.options.blowup_energy_factor;
            (e.mechanical() > factor * bound).then(|| {
                format!(
                    "kinetic + strain energy {:.4e} J exceeds {factor} × (initial energy + work \
                     done on the body + one step of load + round-off) = {:.4e} J",
                    e.mechanical(),
                    factor * bound
                )
            })
        };
        match reason {
            None => Ok(()),
            Some(reason) => {
                let stable = stability(self.model).stable;
                Err(Error::Message(format!(
                    "unstable: {reason} at t = {:.6e} s (step {}); the stable time step is \
                     {stable:.4e} s (dt = {:.4e} s = {:.2} × stable)",
                    state.time,
                    state.step,
                    self.dt,
                    self.dt / stable
                )))
            }
        }
    }
}

/// A mass-proportional rate must be finite, ≥ 0, and below 1/dt.
fn check_damping(damping: Damping, dt: f64) -> Result<()> {
    if let Damping::MassProportional { rate } = damping {
        if !(rate.is_finite() && rate >= 0.0 && rate * dt < 1.0) {
            return Err(Error::Message(format!(
                "QDEM: mass-proportional damping rate {rate} 1/s must be ≥ 0 with rate × dt < 1"
            )));
        }
    }
    Ok(())
}

/// Calls `hook` at (time, x, v) for this evaluation's forces into `current` (zeroed
/// first, one per node), keeping the last evaluation's in `previous`.
fn call_hook(
    current: &mut Vec<Vec3>,
    previous: &mut Vec<Vec3>,
    (time, x, v): (f64, &[Vec3], &[Vec3]),
    hook: &mut ForceHook<'_>,
) {
    std::mem::swap(current, previous);
    current.clear();
    current.resize(x.len(), [0.0; 3]);
    hook(time, x, v, current);
}

fn merge(a: NodeSums, b: &NodeSums) -> NodeSums {
    NodeSums {
        gravity_work: a.gravity_work + b.gravity_work,
        damping_work: a.damping_work + b.damping_work,
        kinetic: a.kinetic + b.kinetic,
        acceleration_squared: a.acceleration_squared + b.acceleration_squared,
        hook_work: a.hook_work + b.hook_work,
        hook_pending: a.hook_pending + b.hook_pending,
        non_finite: a.non_finite || b.non_finite,
    }
}
