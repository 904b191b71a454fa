//! The Moreau–Jean time step with the θ-method (seed 000 §2.1, Algorithm 1's inner part).
//!
//! [`MoreauJean::step`] runs, each with its own timer:
//! 1. **detect**: contact points at the start configuration, kept when their gap is
//!    within the alert distance or within the two bodies' reaches (gap prediction; a
//!    body's reach is twice the distance its points can travel in the step, so no
//!    contact closes unseen), ordered from the top down along gravity (the NLGS order);
//! 2. **build**: local frames, lever arms, friction per material pair, the gap shift of
//!    each contact's normal velocity, warm-start impulses by contact identity, and the
//!    free velocities `V_free = V_i + h M⁻¹ F_ext` (gyroscopic term explicit);
//! 3. **solve**: NLGS in body-velocity form ([`super::body_nlgs`]), or, with a
//!    [`DdmSetup`], the grains partitioned by mass centre, the contacts renumbered
//!    subdomain by subdomain then the interface, and the DDM driver of [`crate::ddm`];
//! 4. **update**: `x_{i+1} = x_i + h((1 − θ) v_i + θ v_{i+1})`, rotations by the
//!    exponential map `q_{i+1} = q_i exp(h ω_θ)` with ω_θ the θ-average (body frame).
//!
//! # The contact law with gap prediction
//! With the θ-method the end-of-step gap of a contact is, to first order,
//! `g_{i+1} = g_i + h((1 − θ) u_n^i + θ u_n^{i+1})`. Let `g* = g_i + h(1 − θ) u_n^i`
//! (known at the start). The law is Coulomb's on the shifted normal velocity
//! `ũ_n = u_n^{i+1} + max(g*, 0)/(θh)`: a contact that is still open at g* may close
//! but not cross (g_{i+1} ≥ 0); one already closed (g* ≤ 0) gets Moreau's inelastic
//! `u_n^{i+1} ≥ 0`, which neither pushes it apart (no energy put in) nor lets it sink
//! further. Existing interpenetration is not corrected; with θ = 1 an impact closes
//! exactly at zero gap, with θ < 1 it may sink up to h(1 − θ)|u_n^i|. Only when
//! [`StepParams::depenetration_speed`] is set (packings, not the seed's scenes) does a
//! closed contact get `ũ_n = u_n^{i+1} + max(g*/(θh), −v_dep)`, which pushes an
//! overlap out at most at that speed.

use std::collections::HashSet;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

use super::body::{Body, Motion, Spring};
use super::body_nlgs::{self, BodyInverses, ContactRow};
use super::nlgs::{NlgsOptions, NlgsReport};
use crate::contact::{local_frame, Collider, ContactKey, ContactPoint, Detector, ImpulseMemory};
use crate::ddm::{self, DdmOptions, Decomposition, Partitioning};
use crate::geometry::Period;

/// The opening speed (m/s) above which a pushing contact's impulse is not carried into
/// the next step by the asynchronous driver ([`MoreauJean`]'s `drop_opening_pushes`):
/// 1 cm/s, above the 8 mm/s that gravity gives in a 0.8 ms step and far below the
/// 0.1–0.3 m/s of the impulses that fed the instability it stops.
pub const OPENING_PUSH_SPEED: f64 = 0.01;

/// An end-of-step check solves the step again only for a missed overlap deeper than
/// this fraction of the alert distance (0.1 mm at the deposit's 2 mm): shallower ones
/// are in the next step's problem and, in packings, pushed out at the depenetration
/// speed.
const END_CHECK_DEPTH: f64 = 0.05;

/// Time-stepping parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepParams {
    /// Time step h (s).
    pub dt: f64,
    /// θ of the θ-method, in [0.5, 1].
    pub theta: f64,
    /// Gravitational acceleration (m/s²).
    pub gravity: Vector3<f64>,
    /// Alert distance of contact detection (m).
    pub alert_distance: f64,
    /// Largest speed (m/s) at which an existing interpenetration is pushed out; 0 (the
    /// seed's law) leaves it as it is. A position correction, not mechanics: for
    /// building packings, where an unconverged step's overlap must not stay.
    pub depenetration_speed: f64,
    /// Periodicity along one axis (`None`: none): contacts across the cell's ends are
    /// detected between a body and the other's image, and a moving body that leaves
    /// the cell re-enters it at the other end (seed 004 §4's bed, periodic along the
    /// track).
    pub period: Option<Period>,
    /// End-of-step checks (0: none, the seed's step): after the solve, contacts are
    /// detected at the poses the solved velocities give; if feature pairs that were not
    /// in the problem overlap there by more than a twentieth of the alert distance (an
    /// edge that the step's rotation swings over a corner onto the corner's next edge),
    /// they are carried back to the start poses and added, and the step is solved
    /// again, at most this many times. Each check costs a detection, each new solve a
    /// solve.
    pub end_checks: usize,
}

/// Friction coefficients per pair of materials (symmetric).
#[derive(Debug, Clone, PartialEq)]
pub struct FrictionTable {
    materials: usize,
    mu: Vec<f64>,
}

impl FrictionTable {
    /// `materials` materials, every pair with coefficient `default`.
    pub fn uniform(materials: usize, default: f64) -> Self {
        FrictionTable {
            materials,
            mu: vec![default; materials * materials],
        }
    }

    /// Sets µ for the pair (a, b) and (b, a).
    pub fn set(&mut self, a: u32, b: u32, mu: f64) {
        let (a, b) = (a as usize, b as usize);
        self.mu[a * self.materials + b] = mu;
        self.mu[b * self.materials + a] = mu;
    }

    /// µ of the pair (a, b).
    pub fn get(&self, a: u32, b: u32) -> f64 {
        self.mu[a as usize * self.materials + b as usize]
    }
}

/// A contact of the last step, for output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolvedContact {
    /// The detected point (start of the step).
    pub contact: ContactPoint,
    /// The local frame `[n, t, s]`.
    pub frame: [Vector3<f64>; 3],
    /// The impulse in the local frame (N·s).
    pub impulse: [f64; 3],
}

impl SolvedContact {
    /// The impulse in world axes (N·s): it acts on the second body along +world and
    /// on the first along −world.
    pub fn world_impulse(&self) -> Vector3<f64> {
        self.frame[0] * self.impulse[0]
            + self.frame[1] * self.impulse[1]
            + self.frame[2] * self.impulse[2]
    }
}

/// What one step did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepReport {
    /// Contact points in the problem.
    pub contacts: usize,
    /// Of which warm-started from the previous step.
    pub warm_started: usize,
    /// The NLGS run.
    pub nlgs: NlgsReport,
    /// Largest interpenetration among the contacts detected at the start of the step (m;
    /// not the contacts an end-of-step check carried back, whose gaps are linearised).
    pub max_interpenetration: f64,
    /// Mean interpenetration over the contacts that carry a normal impulse (m).
    pub mean_interpenetration: f64,
    /// Largest normal impulse of the step over its length (N): the strongest contact.
    /// A self-stress that a warm start carries over and grows (docs/nscd.md, "Warm
    /// start and self-stress") shows here first, long before the kinetic energy does.
    pub max_contact_force: f64,
    /// Kinetic energy at the end of the step (J).
    pub kinetic_energy: f64,
    /// Work of gravity and of the driven bodies over the step (J).
    pub external_work: f64,
    /// ΔKE − external work over the step (J): ≤ 0 up to rounding and the NLGS
    /// tolerance when contacts only dissipate.
    pub energy_rise: f64,
    /// Wall time per phase: detect, build, solve, update.
    pub phase_times: [Duration; 4],
    /// Of the solve, with a DDM: the parallel subdomain part and the sequential
    /// interface part (zero without one).
    pub solve_split: [Duration; 2],
    /// Contacts on the interface Γ (0 without a DDM).
    pub interface_contacts: usize,
    /// Mean interpenetration over the interface contacts that carry a normal impulse
    /// (m; 0 without a DDM): where the asynchronous driver's mass splitting leaves its
    /// residual (docs/tamping.md, "Interpenetration of the asynchronous driver").
    pub interface_mean_interpenetration: f64,
}

/// Domain decomposition of the solve: how grains are partitioned and which driver.
#[derive(Debug, Clone, PartialEq)]
pub struct DdmSetup {
    /// Subdomain boxes.
    pub partitioning: Partitioning,
    /// Driver and sweeps per DDM iteration.
    pub options: DdmOptions,
}

/// The time-stepping pipeline: owns scratch buffers and the impulse memory; the bodies
/// are passed to each step.
#[derive(Debug, Clone)]
pub struct MoreauJean {
    /// Time-stepping parameters.
    pub params: StepParams,
    /// NLGS options.
    pub options: NlgsOptions,
    /// Domain decomposition of the solve (`None`: plain sequential NLGS).
    pub ddm: Option<DdmSetup>,
    detector: Detector,
    owner: Vec<Option<u32>>,
    /// Each body's index in the solve: its own, or for a sprung piece its tool's first
    /// piece (the pieces of one tool move as one body).
    lead: Vec<usize>,
    /// A tool's mass (kg), at its first piece's index.
    tool_mass: Vec<f64>,
    decomposition: Decomposition,
    memory: ImpulseMemory,
    points: Vec<ContactPoint>,
    rows: Vec<ContactRow>,
    impulses: Vec<[f64; 3]>,
    velocity: Vec<Vector3<f64>>,
    angular: Vec<Vector3<f64>>,
    inverse_mass: Vec<f64>,
    inverse_inertia: Vec<Matrix3<f64>>,
    solved: Vec<SolvedContact>,
    /// The keys of the contacts this step's end-of-step checks added.
    carried: HashSet<ContactKey>,
    /// The share of its last impulse each contact starts the step from
    /// ([`Self::set_warm_start`]).
    warm_start: f64,
    /// Each DDM block's sweeping time in the last step ([`Self::block_busy`]).
    block_busy: Vec<Duration>,
}

impl MoreauJean {
    /// A pipeline with these parameters and options.
    pub fn new(params: StepParams, options: NlgsOptions) -> Self {
        MoreauJean {
            params,
            options,
            ddm: None,
            detector: Detector::new(params.alert_distance),
            owner: Vec::new(),
            lead: Vec::new(),
            tool_mass: Vec::new(),
            decomposition: Decomposition::default(),
            memory: ImpulseMemory::new(),
            points: Vec::new(),
            rows: Vec::new(),
            impulses: Vec::new(),
            velocity: Vec::new(),
            angular: Vec::new(),
            inverse_mass: Vec::new(),
            inverse_inertia: Vec::new(),
            solved: Vec::new(),
            carried: HashSet::new(),
            warm_start: 1.0,
            block_busy: Vec::new(),
        }
    }

    /// Sets the share of its previous impulse that each contact starts the next solve
    /// from (1, the default: all of it). Rigid contacts leave the self-stress of a
    /// hyperstatic cluster undetermined (a stone column between a held sleeper and the
    /// floor carries any compression), and a fully warm-started solve carries it from
    /// step to step, where (as we read it) the small turn of the contact frames in each
    /// step converts part of it into motion and the next solve into more self-stress:
    /// on the quick bed's final settle it grew from 0.1 to 190 N·s in 52 steps, faster
    /// with more sweeps, and threw the bed up (docs/nscd.md, "Warm start and
    /// self-stress"). Below 1 that part decays by this factor per step unless the loads
    /// make it again.
    pub fn set_warm_start(&mut self, factor: f64) {
        self.warm_start = factor;
    }

    /// The contacts of the last step with their impulses.
    pub fn contacts(&self) -> &[SolvedContact] {
        &self.solved
    }

    /// Each DDM block's own sweeping time in the last step (the subdomains in order,
    /// then the asynchronous driver's interface block; empty without a DDM), summed
    /// over the step's solves: [`ddm::DdmReport::block_busy`].
    pub fn block_busy(&self) -> &[Duration] {
        &self.block_busy
    }

    /// The last step's contacts numbered subdomain by subdomain, then the interface
    /// (empty without a DDM).
    pub fn decomposition(&self) -> &Decomposition {
        &self.decomposition
    }

    /// Each body's subdomain in the last step (`None`: not a grain, or no DDM).
    pub fn subdomains(&self) -> &[Option<u32>] {
        &self.owner
    }

    /// The impulse memory (warm starts of the next step).
    pub fn memory(&self) -> &ImpulseMemory {
        &self.memory
    }

    /// Replaces the warm-start memory (resuming from a checkpoint).
    pub fn set_memory(&mut self, memory: ImpulseMemory) {
        self.memory = memory;
    }

    /// Detects the contacts of the current configuration (no step), e.g. to measure
    /// the final interpenetration.
    pub fn detect(&mut self, bodies: &[Body]) -> Vec<ContactPoint> {
        let mut out = Vec::new();
        self.detector.alert_distance = self.params.alert_distance;
        self.detector.period = self.params.period;
        self.detector.reach.clear();
        let poses: Vec<Isometry3<f64>> = bodies.iter().map(Body::pose).collect();
        detect_into(&mut self.detector, bodies, &poses, &mut out);
        out
    }

    /// Advances `bodies` from `time` to `time + dt`.
    pub fn step(&mut self, bodies: &mut [Body], time: f64, friction: &FrictionTable) -> StepReport {
        let StepParams { dt, gravity, .. } = self.params;
        let mut phase_times = [Duration::ZERO; 4];
        let kinetic_before: f64 = bodies.iter().map(balance_energy).sum();

        // 1. Detect at the start configuration.
        let clock = Instant::now();
        self.points.clear();
        // Gap prediction needs every contact that can close within the step: a pair is
        // detected within the alert distance or within the sum of its bodies' reaches,
        // twice the distance each body's points can move in h.
        self.detector.alert_distance = self.params.alert_distance;
        self.detector.period = self.params.period;
        self.detector.reach.clear();
        self.detector.reach.extend(bodies.iter().map(|b| {
            if matches!(b.motion, Motion::Static) {
                0.0
            } else {
                let speed = b.point_speed_bound();
                let fall = if b.is_movable() {
                    dt * gravity.norm()
                } else {
                    0.0
                };
                2.0 * dt * (speed + fall)
            }
        }));
        let poses: Vec<Isometry3<f64>> = bodies.iter().map(Body::pose).collect();
        detect_into(&mut self.detector, bodies, &poses, &mut self.points);
        self.find_tools(bodies);
        self.order_points(bodies);
        phase_times[0] = clock.elapsed();

        // The velocities at the start of the step (the build sets a driven body's to
        // its end-of-step velocity).
        let start_velocity: Vec<Vector3<f64>> = bodies.iter().map(|b| b.velocity).collect();
        let start_angular: Vec<Vector3<f64>> =
            bodies.iter().map(Body::angular_velocity_world).collect();
        let mut warm_started = 0;
        let mut solve_split = [Duration::ZERO; 2];
        self.block_busy.clear();
        let mut interface_contacts = 0;
        let mut pass = 0;
        self.carried.clear();
        let nlgs = loop {
            // 2. Build: driven velocities at the end of the step, free velocities, rows.
            let clock = Instant::now();
            let warm = self.build(bodies, time, friction, &start_velocity, &start_angular);
            if pass == 0 {
                warm_started = warm;
            }
            phase_times[1] += clock.elapsed();

            // 3. Solve.
            let clock = Instant::now();
            let inverses = BodyInverses {
                inverse_mass: &self.inverse_mass,
                inverse_inertia: &self.inverse_inertia,
            };
            let nlgs = match &self.ddm {
                None => body_nlgs::solve(
                    &self.rows,
                    &inverses,
                    &mut self.velocity,
                    &mut self.angular,
                    &mut self.impulses,
                    &self.options,
                ),
                Some(setup) => {
                    let report = ddm::solve(
                        &self.rows,
                        &self.decomposition,
                        &inverses,
                        &mut self.velocity,
                        &mut self.angular,
                        &mut self.impulses,
                        &self.options,
                        &setup.options,
                    );
                    solve_split[0] += report.subdomain_time;
                    solve_split[1] += report.interface_time;
                    self.block_busy
                        .resize(report.block_busy.len(), Duration::ZERO);
                    for (total, t) in self.block_busy.iter_mut().zip(&report.block_busy) {
                        *total += *t;
                    }
                    interface_contacts = self.decomposition.interface.len();
                    report.nlgs
                }
            };
            phase_times[2] += clock.elapsed();
            // The other pieces of a tool move with its first.
            for (k, &lead) in self.lead.iter().enumerate() {
                if lead != k {
                    self.velocity[k] = self.velocity[lead];
                }
            }
            if pass == self.params.end_checks {
                break nlgs;
            }
            pass += 1;

            // An end-of-step check: the overlaps the solved motion makes between
            // features that are not in the problem.
            let clock = Instant::now();
            let missed = self.missed_contacts(bodies, &poses, &start_velocity, &start_angular);
            phase_times[0] += clock.elapsed();
            if missed.is_empty() {
                break nlgs;
            }
            // Solved again, warm from this pass's impulses, the new contacts cold.
            self.memory.store(
                self.points
                    .iter()
                    .zip(&self.impulses)
                    .map(|(c, r)| (c.key, r)),
            );
            self.carried.extend(missed.iter().map(|c| c.key));
            self.points.extend(missed);
            self.order_points(bodies);
        };

        // 4. Update positions and rotations; energy bookkeeping.
        let clock = Instant::now();
        let mut external_work = 0.0;
        for (k, body) in bodies.iter_mut().enumerate() {
            if let Motion::Sprung(spring) = &body.motion {
                let (displacement, _) = self.theta_motion(k, body, &start_velocity);
                // The spring holds the tool: its force acts once, on the first piece.
                let force = if self.lead[k] == k {
                    spring_force(spring, body, &self.velocity[k], time, self.params)
                } else {
                    Vector3::zeros()
                };
                let anchor_move = spring.drive.displacement(time, time + dt);
                external_work += (force + body.mass * gravity).dot(&displacement);
                body.position += displacement;
                body.velocity = self.velocity[k];
                if let Motion::Sprung(s) = &mut body.motion {
                    s.anchor += anchor_move;
                }
                continue;
            }
            match body.motion {
                Motion::Dynamic => {
                    let w_new = body.orientation.inverse() * self.angular[k];
                    let (displacement, orientation) = self.theta_motion(k, body, &start_velocity);
                    external_work += body.mass * gravity.dot(&displacement);
                    body.position += displacement;
                    if let Some(p) = &self.params.period {
                        body.position[p.axis] = p.wrap(body.position[p.axis]);
                    }
                    body.orientation = orientation;
                    body.orientation.renormalize();
                    body.velocity = self.velocity[k];
                    body.angular_velocity = w_new;
                }
                Motion::Driven(_) => {
                    body.position += self.theta_motion(k, body, &start_velocity).0;
                }
                // Moved above.
                Motion::Sprung(_) | Motion::Static => {}
            }
        }
        // Work of driven bodies: the impulse they give times their velocity.
        let mut max_pen: f64 = 0.0;
        let (mut pen_sum, mut active) = (0.0, 0usize);
        let (mut interface_pen_sum, mut interface_active) = (0.0, 0usize);
        // Empty without a DDM (the decomposition is only set with one).
        let interface = self.decomposition.interface.clone();
        let mut max_normal: f64 = 0.0;
        self.solved.clear();
        for (k, ((c, row), r)) in
            (self.points.iter().zip(&self.rows).zip(&self.impulses)).enumerate()
        {
            let solved = SolvedContact {
                contact: *c,
                frame: row.frame,
                impulse: *r,
            };
            let world = solved.world_impulse();
            let (a, b) = (c.key.body_a as usize, c.key.body_b as usize);
            if matches!(bodies[a].motion, Motion::Driven(_)) {
                external_work += world.dot(&bodies[a].velocity);
            }
            if matches!(bodies[b].motion, Motion::Driven(_)) {
                external_work -= world.dot(&bodies[b].velocity);
            }
            max_normal = max_normal.max(r[0]);
            // A contact carried back by an end-of-step check has a linearised gap,
            // not a distance at the start: the start's overlaps are the detected ones.
            if !self.carried.contains(&c.key) {
                max_pen = max_pen.max(-c.gap);
                if r[0] > 0.0 {
                    let overlap = (-c.gap).max(0.0);
                    pen_sum += overlap;
                    active += 1;
                    if interface.contains(&k) {
                        interface_pen_sum += overlap;
                        interface_active += 1;
                    }
                }
            }
            self.solved.push(solved);
        }
        if self
            .ddm
            .as_ref()
            .is_some_and(|d| d.options.driver == ddm::Driver::Asynchronous)
        {
            self.drop_opening_pushes();
        }
        self.memory.store(
            self.points
                .iter()
                .zip(&self.impulses)
                .map(|(c, r)| (c.key, r)),
        );
        let kinetic_energy: f64 = bodies.iter().map(Body::kinetic_energy).sum();
        let balance_after: f64 = bodies.iter().map(balance_energy).sum();
        phase_times[3] = clock.elapsed();
        StepReport {
            contacts: self.points.len(),
            warm_started,
            nlgs,
            max_interpenetration: max_pen,
            mean_interpenetration: mean(pen_sum, active),
            interface_mean_interpenetration: mean(interface_pen_sum, interface_active),
            max_contact_force: max_normal / self.params.dt,
            kinetic_energy,
            external_work,
            energy_rise: balance_after - kinetic_before - external_work,
            phase_times,
            solve_split,
            interface_contacts,
        }
    }

    /// Clears, for the next step's warm start, the impulse of every contact of a grain
    /// the interface shares with a subdomain that pushes (r_n > 0) while it opens at
    /// more than [`OPENING_PUSH_SPEED`] by the end of the step (predicted gap rate
    /// u_n + g/h, with this step's solved velocities). The contact law gives such a
    /// contact no impulse; a solve stopped before it converged can leave one, and
    /// carried into the next step it does work again. The
    /// asynchronous driver's mass splitting left such impulses at a grain the interface
    /// shares and grew them step after step through the warm start, until a stone was
    /// thrown out of a bed at rest (docs/tamping.md, "Interpenetration of the
    /// asynchronous driver"). Applied to every contact it also dropped the warm start
    /// of the many contacts a vibrating tine opens, and the overlap grew; the shared
    /// grains are where the driver leaves such impulses. This step's velocities and
    /// outputs keep the impulses.
    fn drop_opening_pushes(&mut self) {
        // The moving bodies the interface touches (the mass-split grains are among them;
        // walls, tools and held bodies are not split).
        let mut shared = vec![false; self.velocity.len()];
        for row in &self.rows[self.decomposition.interface.clone()] {
            for b in row.bodies.map(|x| x as usize) {
                shared[b] = self.inverse_mass[b] > 0.0;
            }
        }
        for (row, r) in self.rows.iter().zip(self.impulses.iter_mut()) {
            let [a, b] = row.bodies.map(|x| x as usize);
            if r[0] > 0.0 && (shared[a] || shared[b]) {
                let opening = normal_velocity(
                    &row.frame[0],
                    &row.arms,
                    [a, b],
                    &self.velocity,
                    &self.angular,
                ) + row.shift;
                if opening > OPENING_PUSH_SPEED {
                    *r = [0.0; 3];
                }
            }
        }
    }

    /// Body `k`'s displacement over the step and its orientation at the end, with the
    /// solved velocities (θ-method: `h((1 − θ) v_i + θ v_{i+1})`, `q exp(h ω_θ)` with ω_θ
    /// the θ-average in the body frame): what the update applies, and where an
    /// end-of-step check detects. Before the update (the body still holds its start
    /// state; `start_velocity` for a driven body, whose velocity the build set).
    fn theta_motion(
        &self,
        k: usize,
        body: &Body,
        start_velocity: &[Vector3<f64>],
    ) -> (Vector3<f64>, UnitQuaternion<f64>) {
        let StepParams { dt, theta, .. } = self.params;
        match body.motion {
            // A sprung body's angular velocity is zero: it does not turn.
            Motion::Dynamic | Motion::Sprung(_) => {
                let w_new = body.orientation.inverse() * self.angular[k];
                let w_theta = (1.0 - theta) * body.angular_velocity + theta * w_new;
                (
                    dt * ((1.0 - theta) * start_velocity[k] + theta * self.velocity[k]),
                    body.orientation * UnitQuaternion::from_scaled_axis(dt * w_theta),
                )
            }
            Motion::Driven(_) => (
                dt * ((1.0 - theta) * start_velocity[k] + theta * body.velocity),
                body.orientation,
            ),
            Motion::Static => (Vector3::zeros(), body.orientation),
        }
    }

    /// Finds the tools: the sprung bodies of one group move as one, solved as the
    /// group's first body with the group's mass ([`Self::lead`]).
    fn find_tools(&mut self, bodies: &[Body]) {
        self.lead.clear();
        self.tool_mass.clear();
        self.tool_mass.resize(bodies.len(), 0.0);
        let mut first: Vec<Option<usize>> = Vec::new();
        for (k, body) in bodies.iter().enumerate() {
            let lead = match body.spring_group() {
                Some(group) => {
                    let g = group as usize;
                    if first.len() <= g {
                        first.resize(g + 1, None);
                    }
                    *first[g].get_or_insert(k)
                }
                None => k,
            };
            self.tool_mass[lead] += body.mass;
            self.lead.push(lead);
        }
    }

    /// Puts the contact points in the NLGS order: from the top down along gravity, so
    /// that one sweep carries the weight of a column down to its base (bottom-up, it
    /// would take one sweep per layer), ties by key; with a DDM, then subdomain by
    /// subdomain and the interface last, each block keeping that order.
    fn order_points(&mut self, bodies: &[Body]) {
        let gravity = self.params.gravity;
        if gravity != Vector3::zeros() {
            let down = gravity.normalize();
            let height = |c: &ContactPoint| -down.dot(&c.point.coords);
            self.points
                .sort_by(|a, b| height(b).total_cmp(&height(a)).then(a.key.cmp(&b.key)));
        }
        self.owner.clear();
        if let Some(setup) = &self.ddm {
            // Grains to subdomains by mass centre.
            let centres: Vec<Vector3<f64>> = bodies.iter().map(|b| b.position).collect();
            let movable: Vec<bool> = bodies.iter().map(Body::is_movable).collect();
            self.owner = setup.partitioning.assign(&centres, &movable);
            let pairs: Vec<[usize; 2]> = self
                .points
                .iter()
                .map(|c| {
                    [
                        self.lead[c.key.body_a as usize],
                        self.lead[c.key.body_b as usize],
                    ]
                })
                .collect();
            let (order, decomposition) =
                ddm::decompose(&pairs, &self.owner, setup.partitioning.subdomains());
            self.points = order.iter().map(|&k| self.points[k]).collect();
            self.decomposition = decomposition;
        }
    }

    /// Builds the problem of the step: free velocities (gravity, gyroscopic term), a
    /// driven body's prescribed end velocity, inverse masses and inertias, and one row
    /// per contact point (frame, lever arms, gap shift, µ) with its warm start from the
    /// memory. Returns how many rows were warm-started.
    fn build(
        &mut self,
        bodies: &mut [Body],
        time: f64,
        friction: &FrictionTable,
        start_velocity: &[Vector3<f64>],
        start_angular: &[Vector3<f64>],
    ) -> usize {
        let StepParams {
            dt, theta, gravity, ..
        } = self.params;
        self.velocity.clear();
        self.angular.clear();
        self.inverse_mass.clear();
        self.inverse_inertia.clear();
        for (k, body) in bodies.iter_mut().enumerate() {
            match &body.motion {
                Motion::Dynamic => {
                    let free = body.velocity + dt * gravity;
                    let w_free = free_rotation(body, dt);
                    self.velocity.push(free);
                    self.angular.push(body.orientation * w_free);
                }
                Motion::Driven(prescribed) => {
                    body.velocity = prescribed.velocity_at(time + dt);
                    self.velocity.push(body.velocity);
                    self.angular.push(Vector3::zeros());
                }
                Motion::Sprung(spring) => {
                    let lead = self.lead[k];
                    if lead == k {
                        let (free, effective_mass) = sprung_free_velocity(
                            spring,
                            body,
                            self.tool_mass[k],
                            time,
                            self.params,
                        );
                        self.velocity.push(free);
                        self.inverse_mass.push(1.0 / effective_mass);
                    } else {
                        // Solved as its tool's first piece (no row refers to it).
                        self.velocity.push(self.velocity[lead]);
                        self.inverse_mass.push(0.0);
                    }
                    self.angular.push(Vector3::zeros());
                    self.inverse_inertia.push(Matrix3::zeros());
                    continue;
                }
                Motion::Static => {
                    self.velocity.push(Vector3::zeros());
                    self.angular.push(Vector3::zeros());
                }
            }
            self.inverse_mass.push(body.inverse_mass());
            self.inverse_inertia.push(body.inverse_inertia_world());
        }
        self.rows.clear();
        self.impulses.clear();
        let mut warm_started = 0;
        for c in &self.points {
            let (a, b) = (c.key.body_a as usize, c.key.body_b as usize);
            let frame = local_frame(&c.normal);
            let arms = lever_arms(c, bodies);
            // Normal relative velocity at the start of the step.
            let u_start = normal_velocity(&frame[0], &arms, [a, b], start_velocity, start_angular);
            let predicted = c.gap + dt * (1.0 - theta) * u_start;
            // Open: may close but not cross. Closed (predicted ≤ 0): u_n ≥ 0, or with a
            // depenetration speed u_n ≥ min(−g*/(θh), that speed). A contact carried
            // back by an end-of-step check is not capped: its overlap is the step's own
            // (features swung through each other), so the step must end without it.
            let shift = if self.carried.contains(&c.key) {
                predicted / (theta * dt)
            } else {
                (predicted / (theta * dt)).max(-self.params.depenetration_speed)
            };
            self.rows.push(ContactRow {
                bodies: [self.lead[a] as u32, self.lead[b] as u32],
                frame,
                arms,
                shift,
                mu: friction.get(bodies[a].material, bodies[b].material),
            });
            if self.memory.contains(&c.key) {
                warm_started += 1;
            }
            let warm = self.memory.get(&c.key);
            self.impulses.push(warm.map(|r| self.warm_start * r));
        }
        warm_started
    }

    /// The end-of-step check ([`StepParams::end_checks`]): detects at the poses the
    /// solved velocities give (θ-method, as the update) and returns the points that
    /// overlap there between features not in the problem, carried back to the start
    /// `poses` (the two points stay fixed on their bodies, the normal turns with body
    /// a), with the gap that the step's solved motion turns into the overlap found (so
    /// the law, linearised about that motion, keeps the features from crossing). Only
    /// pairs with a moving body are detected, and only overlaps count (no alert
    /// distance, no reach).
    fn missed_contacts(
        &mut self,
        bodies: &[Body],
        poses: &[Isometry3<f64>],
        start_velocity: &[Vector3<f64>],
        start_angular: &[Vector3<f64>],
    ) -> Vec<ContactPoint> {
        let StepParams { dt, theta, .. } = self.params;
        let ends: Vec<Isometry3<f64>> = bodies
            .iter()
            .enumerate()
            .map(|(k, body)| {
                let (displacement, orientation) = self.theta_motion(k, body, start_velocity);
                Isometry3::from_parts(
                    Translation3::from(body.position + displacement),
                    orientation,
                )
            })
            .collect();
        let (alert, reach) = (
            self.detector.alert_distance,
            std::mem::take(&mut self.detector.reach),
        );
        self.detector.alert_distance = 0.0;
        let mut found = Vec::new();
        detect_into(&mut self.detector, bodies, &ends, &mut found);
        self.detector.alert_distance = alert;
        self.detector.reach = reach;
        let known: HashSet<ContactKey> = self.points.iter().map(|c| c.key).collect();
        found.retain(|c| c.gap < 0.0 && !known.contains(&c.key));
        // Shallow cuts are left to the next step (and the depenetration speed): a
        // second solve of the whole problem is for the deep ones.
        let depth = END_CHECK_DEPTH * alert;
        if found.iter().all(|c| c.gap > -depth) {
            return Vec::new();
        }
        found
            .into_iter()
            .map(|c| {
                let (a, b) = (c.key.body_a as usize, c.key.body_b as usize);
                let image = Translation3::from(c.shift_b);
                // End-of-step points on a and b, then the same material points at the
                // start.
                let on_a = c.point - 0.5 * c.gap * c.normal;
                let on_b = c.point + 0.5 * c.gap * c.normal;
                let on_a = poses[a] * (ends[a].inverse() * on_a);
                let on_b = image * (poses[b] * (ends[b].inverse() * (image.inverse() * on_b)));
                let normal = poses[a].rotation * (ends[a].rotation.inverse() * c.normal);
                let point = nalgebra::center(&on_a, &on_b);
                // The gap that, with this step's normal velocities, gives the overlap
                // found at the end: the law then acts on the change of the motion,
                // linearised where the solve left it (the start distance along the
                // normal is no gap when the features do not face each other there).
                let carried = ContactPoint { point, normal, ..c };
                let arms = lever_arms(&carried, bodies);
                let u_start =
                    normal_velocity(&normal, &arms, [a, b], start_velocity, start_angular);
                let u_end = normal_velocity(&normal, &arms, [a, b], &self.velocity, &self.angular);
                ContactPoint {
                    gap: c.gap - dt * ((1.0 - theta) * u_start + theta * u_end),
                    ..carried
                }
            })
            .collect()
    }
}

/// `sum / count`, or 0 for no term.
fn mean(sum: f64, count: usize) -> f64 {
    if count > 0 {
        sum / count as f64
    } else {
        0.0
    }
}

/// The lever arms of contact `c` from its two bodies' centres (body b's periodic image).
fn lever_arms(c: &ContactPoint, bodies: &[Body]) -> [Vector3<f64>; 2] {
    let (a, b) = (c.key.body_a as usize, c.key.body_b as usize);
    [
        c.point.coords - bodies[a].position,
        c.point.coords - (bodies[b].position + c.shift_b),
    ]
}

/// The relative velocity of body b's point from body a's along `normal`, the points at
/// `arms` from the centres of bodies `[a, b]`, with velocities `v` and world angular
/// velocities `w`.
fn normal_velocity(
    normal: &Vector3<f64>,
    arms: &[Vector3<f64>; 2],
    [a, b]: [usize; 2],
    v: &[Vector3<f64>],
    w: &[Vector3<f64>],
) -> f64 {
    normal.dot(&(v[b] + w[b].cross(&arms[1]) - (v[a] + w[a].cross(&arms[0]))))
}

/// The free angular velocity (body frame) after `dt` without torques: explicit
/// gyroscopic term `ω − h I⁻¹(ω × Iω)`, rescaled to keep the rotational kinetic energy
/// (exact torque-free rotation conserves it; the explicit step alone would add
/// O(h²) energy each step).
fn free_rotation(body: &Body, dt: f64) -> Vector3<f64> {
    let w = body.angular_velocity;
    let inertia = body.inertia;
    // A held axis (infinite inertia, ω = 0 about it) carries no momentum here.
    let momentum = Vector3::from_fn(|k, _| {
        if inertia[k].is_finite() {
            inertia[k] * w[k]
        } else {
            0.0
        }
    });
    let mut next = w - dt * w.cross(&momentum).component_div(&inertia);
    let energy = |v: &Vector3<f64>| super::body::rotational_energy(&inertia, v);
    let (before, after) = (energy(&w), energy(&next));
    if after > 0.0 {
        next *= (before / after).sqrt();
    }
    next
}

/// Detection over `bodies` placed at `poses` into `out`.
fn detect_into(
    detector: &mut Detector,
    bodies: &[Body],
    poses: &[Isometry3<f64>],
    out: &mut Vec<ContactPoint>,
) {
    let colliders: Vec<&Collider> = bodies.iter().map(|b| &b.shape.collider).collect();
    // Pairs without a moving grain (driven against fixed, two pieces of one tool) carry
    // no impulse that could change anything: skipped.
    let movable: Vec<bool> = bodies.iter().map(Body::is_movable).collect();
    detector.detect(&colliders, poses, &movable, out);
    // Two sprung pieces of one tool hang on the same drive: they do not touch. (Scenes
    // without sprung bodies, all but tamping with tine_stiffness, skip the pass.)
    if bodies.iter().any(|b| b.spring_group().is_some()) {
        out.retain(|c| {
            let group = bodies[c.key.body_a as usize].spring_group();
            group.is_none() || group != bodies[c.key.body_b as usize].spring_group()
        });
    }
}

/// The free velocity of a sprung body (of `mass`: its tool's) over the step from `time`
/// (its velocity at the end with no contact impulse) and its effective mass
/// `m + hθC + h²θ²K`: the θ-method on
/// `m v̇ = m g + K (a − x) + C (v_a − v)` with the anchor `a` moving as its drive
/// prescribes (Moreau–Jean for linear forces; with θ = 1 implicit Euler). The contact
/// impulse `p` then changes the velocity by `p / (m + hθC + h²θ²K)`.
fn sprung_free_velocity(
    spring: &Spring,
    body: &Body,
    mass: f64,
    time: f64,
    params: StepParams,
) -> (Vector3<f64>, f64) {
    let StepParams {
        dt: h,
        theta,
        gravity,
        ..
    } = params;
    let (k, c, m, v) = (spring.stiffness, spring.damping, mass, body.velocity);
    let (anchor_theta, anchor_velocity) = spring.anchor_theta(time, h, theta);
    let stretch = body.position - anchor_theta + theta * h * (1.0 - theta) * v;
    let momentum =
        m * v + h * m * gravity - h * c * ((1.0 - theta) * v - anchor_velocity) - h * k * stretch;
    let effective = m + h * theta * c + h * h * theta * theta * k;
    (momentum / effective, effective)
}

/// The θ-average of a sprung body's spring and dashpot force over the step from `time`,
/// with `velocity` its velocity at the end (before the update moves the body): the
/// force whose work, with gravity's, enters the step's energy balance.
fn spring_force(
    spring: &Spring,
    body: &Body,
    velocity: &Vector3<f64>,
    time: f64,
    params: StepParams,
) -> Vector3<f64> {
    let StepParams { dt: h, theta, .. } = params;
    let x_end = body.position + h * ((1.0 - theta) * body.velocity + theta * velocity);
    let x_theta = (1.0 - theta) * body.position + theta * x_end;
    let v_theta = (1.0 - theta) * body.velocity + theta * velocity;
    let (a_theta, va_theta) = spring.anchor_theta(time, h, theta);
    spring.stiffness * (a_theta - x_theta) + spring.damping * (va_theta - v_theta)
}

/// The kinetic energy the step's balance counts: the free bodies' and the sprung ones'.
fn balance_energy(body: &Body) -> f64 {
    body.kinetic_energy() + body.sprung_kinetic_energy()
}

/// The keys of `contacts` (for tests of persistence).
pub fn contact_keys(contacts: &[SolvedContact]) -> Vec<ContactKey> {
    contacts.iter().map(|c| c.contact.key).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nscd::body::{BodyShape, Prescribed};
    use crate::nscd::nlgs::{ErrorCheck, Stopping};
    use std::sync::Arc;

    /// Two frictional cubes that collide across the end of a periodic cell move exactly
    /// as the same cubes in free space with the second one a cell length further on:
    /// the contact is found through the image, and the image's lever arm (which the
    /// friction's torque depends on) is taken from the image, not the body.
    #[test]
    fn a_collision_across_a_periodic_end_is_the_unwrapped_collision() {
        let run = |period: Option<Period>, second_x: f64| {
            let params = StepParams {
                dt: 1e-3,
                theta: 0.5,
                gravity: Vector3::zeros(),
                alert_distance: 5e-3,
                depenetration_speed: 0.0,
                period,
                end_checks: 0,
            };
            let options = NlgsOptions {
                stopping: Stopping::Tolerance {
                    tolerance: 1e-13,
                    max_sweeps: 500,
                },
                error_check: ErrorCheck::EverySweep,
            };
            let cube = Arc::new(BodyShape::cuboid(Vector3::repeat(0.1)).unwrap());
            let mut bodies = vec![
                Body::dynamic(
                    "a",
                    cube.clone(),
                    2000.0,
                    0,
                    Isometry3::translation(0.93, 0.0, 0.0),
                ),
                Body::dynamic(
                    "b",
                    cube,
                    1000.0,
                    0,
                    Isometry3::translation(second_x, 0.02, 0.01),
                ),
            ];
            bodies[0].velocity = Vector3::new(1.0, 0.4, 0.0);
            let friction = FrictionTable::uniform(1, 0.5);
            let mut engine = MoreauJean::new(params, options);
            let mut touched = 0;
            for k in 0..200 {
                let report = engine.step(&mut bodies, k as f64 * 1e-3, &friction);
                touched += usize::from(report.contacts > 0);
            }
            (bodies, touched)
        };
        let period = Period {
            axis: 0,
            low: 0.0,
            length: 1.0,
        };
        let (wrapped, touched) = run(Some(period), 0.04);
        let (free, _) = run(None, 1.04);
        assert!(touched > 150, "the cubes touched in {touched} steps");
        for (w, f) in wrapped.iter().zip(&free) {
            assert!((0.0..1.0).contains(&w.position.x), "{}", w.position.x);
            let dx = Period::difference(
                Some(&period),
                [w.position.x, 0.0, 0.0],
                [f.position.x, 0.0, 0.0],
            );
            assert!(dx[0].abs() < 1e-9, "{} vs {}", w.position.x, f.position.x);
            assert!((w.position.yz() - f.position.yz()).norm() < 1e-9);
            assert!(
                (w.velocity - f.velocity).norm() < 1e-9,
                "{} {}",
                w.velocity,
                f.velocity
            );
            let spin = (w.angular_velocity - f.angular_velocity).norm();
            assert!(spin < 1e-8, "angular velocities differ by {spin}");
            assert!(w.orientation.angle_to(&f.orientation) < 1e-9);
        }
        // The friction turned them (the check above would pass trivially otherwise).
        assert!(
            free[1].angular_velocity.norm() > 1e-3,
            "{}",
            free[1].angular_velocity
        );
    }

    /// A cube of 1 kg (0.1 m, 1000 kg/m³) on a spring of `stiffness` to an anchor at
    /// its centre, `z` above the origin, its drive at rest.
    fn sprung_cube(stiffness: f64, damping_ratio: f64, z: f64, group: u32) -> Body {
        let cube = Arc::new(BodyShape::cuboid(Vector3::repeat(0.1)).unwrap());
        let mut body = Body::dynamic("tine", cube, 1000.0, 0, Isometry3::translation(0.0, 0.0, z))
            .translation_only();
        body.motion = Motion::Sprung(Spring {
            drive: Prescribed::default(),
            anchor: body.position,
            rest: body.position,
            stiffness,
            damping: 2.0 * damping_ratio * (stiffness * body.mass).sqrt(),
            group,
        });
        body
    }

    fn sprung_params(theta: f64, gravity: f64) -> StepParams {
        StepParams {
            dt: 1e-4,
            theta,
            gravity: Vector3::new(0.0, 0.0, -gravity),
            alert_distance: 1e-3,
            depenetration_speed: 0.0,
            period: None,
            end_checks: 0,
        }
    }

    fn exact_options() -> NlgsOptions {
        NlgsOptions {
            stopping: Stopping::Tolerance {
                tolerance: 1e-14,
                max_sweeps: 200,
            },
            error_check: ErrorCheck::EverySweep,
        }
    }

    /// Without contacts a sprung body is a linear oscillator: with θ = ½ (the
    /// trapezoidal rule) it keeps ½mv² + ½Kx² to rounding and rings at ω = √(K/m)
    /// with the rule's phase lag, ω t (ωh)²/12 (8 × 10⁻⁶ of a radian per radian here);
    /// with θ = 1 and damping it comes to rest where the spring carries its weight,
    /// mg/K under the anchor.
    #[test]
    fn a_sprung_body_rings_at_its_frequency_and_rests_under_its_weight() {
        let (k, x0) = (1e4, 1e-3);
        let mut bodies = vec![sprung_cube(k, 0.0, 0.0, 0)];
        bodies[0].position.x = x0;
        let mut engine = MoreauJean::new(sprung_params(0.5, 0.0), exact_options());
        let friction = FrictionTable::uniform(1, 0.5);
        let omega = (k / bodies[0].mass).sqrt();
        let energy = |b: &Body| {
            0.5 * b.mass * b.velocity.norm_squared() + 0.5 * k * b.position.norm_squared()
        };
        let e0 = energy(&bodies[0]);
        for step in 0..1000 {
            let report = engine.step(&mut bodies, step as f64 * 1e-4, &friction);
            // The spring's work is the only work: the balance closes.
            assert!(report.energy_rise.abs() < 1e-12, "{}", report.energy_rise);
        }
        let t = 0.1;
        let lag = omega * t * (omega * 1e-4f64).powi(2) / 12.0;
        let x = bodies[0].position.x;
        assert!((x - x0 * (omega * t - lag).cos()).abs() < 1e-12, "x = {x}");
        assert!(
            (x - x0 * (omega * t).cos()).abs() > 1e-9,
            "the lag is measured"
        );
        assert!((energy(&bodies[0]) / e0 - 1.0).abs() < 1e-12);

        let mut bodies = vec![sprung_cube(k, 0.7, 0.0, 0)];
        let mut engine = MoreauJean::new(sprung_params(1.0, 9.81), exact_options());
        for step in 0..20_000 {
            engine.step(&mut bodies, step as f64 * 1e-4, &friction);
        }
        let sag = -bodies[0].mass * 9.81 / k;
        assert!(
            (bodies[0].position.z - sag).abs() < 1e-12,
            "{}",
            bodies[0].position.z
        );
    }

    /// A tool of two sprung pieces whose drive goes on into a rigid floor presses on it
    /// with its spring's stretch, K δ + mg (m both pieces' mass), whatever the time
    /// step: the force a jam meets is bounded by the hold, where a driven body would
    /// push with whatever the solve gives. Only one piece touches the floor; the other
    /// moves with it.
    #[test]
    fn a_sprung_tool_driven_into_a_floor_presses_with_its_springs_stretch() {
        let (k, v, steps) = (1e4, 0.1, 500);
        let floor = Body::fixed(
            "floor",
            Arc::new(BodyShape::half_space(Vector3::z_axis())),
            0,
            Isometry3::identity(),
            Motion::Static,
        );
        // One piece resting on the floor (its half-height is 0.05 m), the other beside
        // it 10 mm higher; the anchors where they are.
        let mut second = sprung_cube(k, 1.0, 0.06, 0);
        second.position.x = 0.1;
        if let Motion::Sprung(s) = &mut second.motion {
            s.anchor = second.position;
        }
        let mut bodies = vec![floor, sprung_cube(k, 1.0, 0.05, 0), second];
        let mut engine = MoreauJean::new(sprung_params(1.0, 9.81), exact_options());
        let friction = FrictionTable::uniform(1, 0.5);
        let mut force = 0.0;
        for step in 0..20_000 {
            for body in &mut bodies[1..] {
                if let Motion::Sprung(s) = &mut body.motion {
                    s.drive.velocity.z = if step < steps { -v } else { 0.0 };
                }
            }
            force = engine
                .step(&mut bodies, step as f64 * 1e-4, &friction)
                .max_contact_force;
        }
        let Motion::Sprung(s) = &bodies[1].motion else {
            unreachable!()
        };
        let overshoot = v * steps as f64 * 1e-4;
        assert!(
            (s.anchor.z - (0.05 - overshoot)).abs() < 1e-12,
            "{}",
            s.anchor.z
        );
        let expected = k * overshoot + (bodies[1].mass + bodies[2].mass) * 9.81;
        assert!(
            (force / expected - 1.0).abs() < 1e-9,
            "{force} N against {expected} N"
        );
        assert!(
            (bodies[1].position.z - 0.05).abs() < 1e-9,
            "{}",
            bodies[1].position.z
        );
        assert!(
            (bodies[2].position.z - 0.06).abs() < 1e-9,
            "{}",
            bodies[2].position.z
        );
        assert_eq!(bodies[2].velocity, bodies[1].velocity);
    }

    /// Two sprung pieces of one tool do not touch each other; of two tools they do.
    #[test]
    fn sprung_pieces_of_one_group_do_not_touch() {
        let touching = |group: u32| {
            let bodies = vec![
                sprung_cube(1e4, 0.0, 0.0, 0),
                sprung_cube(1e4, 0.0, 0.09, group),
            ];
            let mut engine = MoreauJean::new(sprung_params(1.0, 0.0), exact_options());
            engine.detect(&bodies).len()
        };
        assert_eq!(touching(0), 0);
        assert!(touching(1) > 0);
    }
}
