//! Gravity deposition of polyhedral stones with the NSCD engine: rain, settle, strike
//! off, lower the sleepers, rain the crib ballast, compact.
//!
//! # Raining
//! A phase's stones enter at once as a column above the highest body, built by
//! ballistic deposition of their bounding spheres (each stone at the lowest of a few
//! random plan positions where its sphere rests on the column so far), so no two
//! inserted stones, nor a stone and anything below the column, overlap; plan positions
//! over a sleeper are refused. The column then falls under gravity: all its stones
//! start at rest and fall alike until the lowest land, so they meet only as the heap
//! builds up from the bottom. A column is a few times the layer it fills (bounding
//! spheres pack loosely), so the stones land at a few m/s at most. Stone shape (drawn
//! from the family), plan position and orientation (uniform, Shoemake) come from one
//! SplitMix64 stream seeded by the scene, in a fixed order: the packing is a function
//! of the seed.
//!
//! # How many stones
//! A phase fills a level: it rains the number of stones whose volume fills the free
//! volume below that level at a solid fraction of 0.62, above what a gravity deposit
//! of angular stones reaches (≈ 0.55–0.60), so the settled heap stands above the level;
//! the stones whose mass centre ends above the level are then removed (strike-off, as a
//! screed would) and the bed settles again.
//!
//! # Drag
//! Stones landing at a few m/s on a heap make deep transient overlaps and slow
//! settling. A linear drag (relaxation time τ, terminal speed g τ; as a packing
//! generator's numerical damping, not mechanics) may act while raining and settling;
//! the final settle runs without it, so the bed's last state is in equilibrium under
//! gravity and contact alone.
//!
//! # Settling
//! A phase ends when the rms speed of the dynamic bodies, √(2 KE / Σm), is below the
//! scene's `settle_speed` and no body point moves faster than four times that, or
//! after `max_phase_time` (then reported as capped). A finishing phase (compaction,
//! final settle, release) must also have met its speed and overlap tests on every
//! step of the last 0.1 s (at 5 mm/s; [`UNBALANCE_G`]). The bed is settled when its last
//! phase settled ([`Deposition::at_rest`]).
//!
//! # Stages and resuming
//! The run calls a fixed sequence of stages (each [`Deposition::fill`],
//! [`Deposition::lower_sleepers`], [`Deposition::compact`], [`Deposition::settle`] is
//! one), each made of parts: an instantaneous action (insert a column, place the
//! sleepers, start the floor) or a loop of steps. A [`Cursor`] says how many stages are
//! done, which part of the next one is under way and at which step its loop began. Its
//! figures so far are in the cursor too. Between two steps of a loop the observer may
//! save the bed ([`super::resume`]); a bed restored from it skips the stages done and
//! re-enters the part under way, so the resumed run takes the same steps as the
//! uninterrupted one.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Point3, Translation3, Vector3};
use serde::{Deserialize, Serialize};

use super::profile::Profile;
use super::tile::Laid;
use crate::contact::ContactPoint;
use crate::geometry::random::SplitMix;
use crate::nscd::body::{Body, BodyShape, Motion, Prescribed};
use crate::nscd::nlgs::{ErrorCheck, NlgsOptions, Stopping};
use crate::nscd::packed::container_planes;
use crate::nscd::scene::StoneShape;
use crate::nscd::step::{
    DdmSetup, FrictionTable, MoreauJean, SolvedContact, StepParams, StepReport,
};

/// Solid fraction assumed when counting the stones of a phase (above any gravity
/// deposit of angular grains, so the heap overfills the level before the strike-off).
pub const FILL_FRACTION: f64 = 0.62;

/// Plan positions clear of the sleepers tried for one stone of the column (the lowest
/// is kept).
pub const PLACEMENT_TRIES: usize = 8;

/// Random plan positions drawn for one stone at most (those over a sleeper are drawn
/// again); a stone that finds no clear one is not inserted.
pub const PLACEMENT_DRAWS: usize = 200;

/// A settled bed has no body point faster than this many times `settle_speed`.
pub const MAX_SPEED_FACTOR: f64 = 4.0;

/// The smallest unbalanced acceleration (in g) a finishing phase's settle test must be
/// able to see: such a phase settles only once its speed tests have held on every step
/// for the time a body starting from rest takes at `UNBALANCE_G` × g to pass
/// [`MAX_SPEED_FACTOR`] × `settle_speed` (0.1 s at 5 mm/s). What begins a phase
/// (sleepers held or released, the floor stopped) may leave a body unbalanced, and on
/// its first steps that body is still slow. The quick bed with its layer compacted
/// passed its release on the first step, and when `ballast-nscd` restarted the bed a
/// stone on the floor by the end wall slid 0.59 mm in 10 steps; held for 20 ms (0.1 g)
/// the release passed at 19 steps with that stone still sliding (0.57 mm); held for
/// 0.1 s it ran 52 steps, the stone slid and stopped within them, and the restart moved
/// no point more than 0.14 mm (docs/pack.md, "Settled: not on a phase's first steps").
/// The watch was first counted from the phase's start only; a stone tipping off a
/// ridge later in the phase then passed (docs/pack.md, "Settled: quiet for a whole
/// watch").
pub const UNBALANCE_G: f64 = 0.02;

/// The largest speed of any point of a dynamic body ([`Body::point_speed_bound`]; m/s,
/// 0 with none): what the finishing phases' settle test holds under
/// [`MAX_SPEED_FACTOR`] × `settle_speed`, and `deposit.csv`'s `fastest_point_m_s`.
pub fn fastest_point_speed(bodies: &[Body]) -> f64 {
    bodies
        .iter()
        .filter(|b| b.is_dynamic())
        .map(Body::point_speed_bound)
        .fold(0.0, f64::max)
}

/// The axis-aligned box of `points` (lower and upper corners; `points` not empty).
pub fn bounds(points: &[Point3<f64>]) -> (Point3<f64>, Point3<f64>) {
    let (mut lo, mut hi) = (points[0], points[0]);
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (lo, hi)
}

/// What a body of the bed is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Role {
    /// The floor (z = 0) or a wall.
    Boundary,
    /// A stone: index into the family.
    Stone(usize),
    /// A sleeper: its number.
    Sleeper(usize),
}

/// A sleeper to lower onto the bed: its shape (principal frame) and where that frame
/// sits in the sleeper's own frame (footprint centred on the origin, underside at z = 0,
/// level).
#[derive(Debug, Clone)]
pub struct SleeperModel {
    /// Hull in the principal frame.
    pub shape: Arc<BodyShape>,
    /// Principal frame in the sleeper's own frame.
    pub frame: Isometry3<f64>,
    /// x-extent and y-extent of the footprint (m).
    pub footprint: [f64; 2],
    /// Density (kg/m³).
    pub density: f64,
    /// Material index.
    pub material: u32,
    /// Held level (translation only) rather than only without yaw.
    pub level: bool,
}

/// Mean stone volume of a (non-empty) family (m³).
fn mean_volume(family: &[StoneShape]) -> f64 {
    family.iter().map(|s| s.shape.volume).sum::<f64>() / family.len() as f64
}

/// `body` held where it is: a static body of the same shape, material and pose.
pub(super) fn hold(body: &Body) -> Body {
    Body::fixed(
        &body.name,
        body.shape.clone(),
        body.material,
        body.pose(),
        Motion::Static,
    )
}

impl SleeperModel {
    /// A sleeper of this model at `pose` (of its own frame), released at rest, its
    /// inertia divided by `inertia_scale` ([`DepositSetup::sleeper_inertia_scale`]).
    pub fn body(&self, name: &str, pose: Isometry3<f64>, inertia_scale: f64) -> Body {
        let body = Body::dynamic(
            name,
            self.shape.clone(),
            self.density / inertia_scale,
            self.material,
            pose * self.frame,
        );
        if self.level {
            body.translation_only()
        } else {
            body.without_yaw()
        }
    }

    /// Its true mass (kg).
    pub fn mass(&self) -> f64 {
        self.density * self.shape.volume
    }
}

/// Everything fixed for the deposition.
#[derive(Debug, Clone)]
pub struct DepositSetup {
    /// The stone family.
    pub family: Vec<StoneShape>,
    /// Stone density and material index.
    pub stone_density: f64,
    /// Stone material index.
    pub stone_material: u32,
    /// Container: [0, L] × [−W/2, W/2] × [0, ∞); periodic along x over [0, L) when
    /// `params.period` is set.
    pub length: f64,
    /// Width (y).
    pub width: f64,
    /// Wall material index.
    pub wall_material: u32,
    /// Time stepping.
    pub params: StepParams,
    /// NLGS tolerance and sweep cap.
    pub tolerance: f64,
    /// Sweep cap.
    pub max_sweeps: usize,
    /// Sweep cap once finishing ([`Deposition::finish`]): without the drag an
    /// unconverged solve feeds the bed energy.
    pub finish_sweeps: usize,
    /// Share of the last step's impulses that warm-starts the solve while sleepers are
    /// held (`MoreauJean::set_warm_start`; 1 otherwise): a stone column between a held
    /// sleeper and the floor carries any compression, and fully warm-started, without
    /// the drag, that self-stress grew until it threw the bed up (docs/nscd.md, "Warm
    /// start and self-stress"). Not below 1 with free sleepers: a heavy free body is
    /// carried by its warm start within a sweep cap (with 0.9 here, the heavy test
    /// box's released sleeper was carried at 0.77 of its weight when the bed read as
    /// settled).
    pub held_warm_start: f64,
    /// Friction table after raining.
    pub friction: FrictionTable,
    /// Friction while raining (stone/stone pairs lowered).
    pub rain_friction: FrictionTable,
    /// Settling criterion: rms speed (m/s).
    pub settle_speed: f64,
    /// Finishing phases also need every overlap below this (m): pushed out at the
    /// depenetration speed, the deep overlaps of raining take a while to go.
    pub max_overlap: f64,
    /// Cap on a phase's simulated time (s).
    pub max_phase_time: f64,
    /// Cap on the number of stones.
    pub max_stones: usize,
    /// Relaxation time τ of a linear drag on the stones while raining and settling
    /// (terminal speed g τ); `None`: no drag. The final settle runs without it.
    pub drag_time: Option<f64>,
    /// Seed.
    pub seed: u64,
    /// Domain decomposition of the contact solve (`None`: sequential NLGS).
    pub ddm: Option<DdmSetup>,
    /// Track-bed profile the strike-offs follow (`None`: a flat fill to each level).
    pub profile: Option<Profile>,
    /// The sleepers' mass and moments of inertia are their true ones divided by this
    /// (≥ 1), and each step adds the missing part of their weight, `(k − 1) g dt`, to
    /// their velocity: the bed at rest carries their true weight, while the NLGS sees
    /// a mass ratio it converges on (docs/pack.md, "Heavy sleepers").
    pub sleeper_inertia_scale: f64,
    /// For the final settle the sleepers are held where they rest (as their rails hold
    /// them in track): its NLGS, without drag, then converges as on a bed of stones
    /// alone. Free, a sleeper hundreds of times heavier than the stones keeps it from
    /// converging (docs/pack.md, "Heavy sleepers"). When false, the free sleepers
    /// carry only their scaled weight in the final settle (see `light_sleepers`): the
    /// choice for rounded stones, which jam against a held sleeper (docs/pack.md,
    /// "Rounded stones").
    pub hold_sleepers: bool,
    /// After the final settle, held sleepers are freed and the bed settles again with
    /// them ([`Deposition::release_sleepers`]).
    pub release_sleepers: bool,
}

impl DepositSetup {
    /// The [`Self::sleeper_inertia_scale`] that brings a sleeper of `sleeper_mass`
    /// (kg) to at most `ratio` times the family's mean stone mass (1: no scaling).
    pub fn inertia_scale(
        family: &[StoneShape],
        stone_density: f64,
        sleeper_mass: f64,
        ratio: f64,
    ) -> f64 {
        (sleeper_mass / (ratio * stone_density * mean_volume(family))).max(1.0)
    }
}

/// How one phase ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhaseReport {
    /// Its name.
    pub name: String,
    /// Simulated time (s).
    pub time: f64,
    /// Steps.
    pub steps: u64,
    /// Whether the settling criterion was met (false: `max_phase_time` reached).
    pub settled: bool,
    /// Stones inserted in it.
    pub inserted: usize,
    /// Stones removed by its strike-off.
    pub removed: usize,
    /// Each free sleeper's support at the phase's end ([`Deposition::sleeper_support`];
    /// 1 when the bed carries its full weight); `None` when no sleeper is free.
    pub sleeper_support: Option<Vec<f64>>,
}

/// A step's record for the CSV and the progress display.
#[derive(Debug, Clone, Copy)]
pub struct StepRecord<'a> {
    /// Time at the end of the step (s).
    pub time: f64,
    /// The phase.
    pub phase: &'a str,
    /// Stones in the bed.
    pub stones: usize,
    /// Whether the step ran under the finishing rules ([`Deposition::finish`]: no
    /// drag, the bed on its way to rest), where no contact should carry more than the
    /// bed's weight.
    pub finishing: bool,
    /// The engine's report.
    pub report: &'a StepReport,
}

/// What sees the deposition run: every step's record with the bodies and their roles
/// (CSV rows, frames, progress), and the bed between two steps of a loop, where a
/// checkpoint may be taken.
pub trait Observer {
    /// After every step.
    fn step(&mut self, record: &StepRecord, bodies: &[Body], roles: &[Role]);

    /// Between two steps of a stage's loop: a bed restored from `bed`'s
    /// [`super::resume::DepositState`] continues from here.
    fn between_steps(&mut self, _bed: &Deposition) {}

    /// True once the run should stop (an output could not be written): the
    /// deposition takes no further step, and each stage left returns at once.
    fn stop(&self) -> bool {
        false
    }
}

impl<F: FnMut(&StepRecord, &[Body], &[Role])> Observer for F {
    fn step(&mut self, record: &StepRecord, bodies: &[Body], roles: &[Role]) {
        self(record, bodies, roles);
    }
}

/// Where the deposition stands in its sequence of stages (module doc, "Stages and
/// resuming").
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Cursor {
    /// Stages finished.
    pub stages_done: usize,
    /// The part of the next stage under way (0: its first).
    pub part: u8,
    /// The step at which that part began.
    pub start_step: u64,
    /// The stage's report so far.
    pub report: Option<PhaseReport>,
    /// The step after which every step so far has met the speed and overlap rules of
    /// [`Deposition::settled`] (`None`: the last step did not).
    pub quiet_since: Option<u64>,
}

impl Cursor {
    /// Records whether step `steps` (the count after it) was quiet, and returns how many
    /// steps of the current part, up to this one, have been quiet in a row (0 after a
    /// step that was not).
    pub fn quiet_run(&mut self, quiet: bool, steps: u64) -> u64 {
        if !quiet {
            self.quiet_since = None;
            return 0;
        }
        let since = *self.quiet_since.get_or_insert(steps - 1);
        steps - since.max(self.start_step)
    }
}

/// The deposition in progress: bodies, their roles, the engine and the clock.
pub struct Deposition {
    /// Fixed inputs.
    pub setup: DepositSetup,
    /// Bodies (boundaries first).
    pub bodies: Vec<Body>,
    /// The role of each body.
    pub roles: Vec<Role>,
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken.
    pub steps: u64,
    /// Σ over steps of the dynamic bodies (for grains·steps per second).
    pub body_steps: u64,
    /// Wall time per engine phase: detect, build, solve, update.
    pub phase_times: [Duration; 4],
    /// Of the solve, with a DDM: the parallel subdomain part, the sequential interface.
    pub solve_split: [Duration; 2],
    /// Wall time stepping.
    pub stepping: Duration,
    /// Phases done.
    pub phases: Vec<PhaseReport>,
    pub(super) engine: MoreauJean,
    /// Finishing (compaction, final settle): no drag, strict settling.
    pub(super) finishing: bool,
    /// The floor is vibrating: no drag (it would damp the shaking).
    pub(super) vibrating: bool,
    pub(super) random: SplitMix,
    cell: f64,
    /// Stones inserted so far (numbers the stones' names).
    pub(super) inserted: usize,
    /// Where the run stands.
    pub(super) cursor: Cursor,
    /// Stages called in this process (those up to `cursor.stages_done` were done
    /// before a resume and are skipped).
    calls: usize,
    /// The observer asked to stop ([`Observer::stop`]): no further step is taken.
    stopped: bool,
}

impl Deposition {
    /// An empty container (floor and four walls, or two with a period along x) ready
    /// for rain.
    pub fn new(setup: DepositSetup) -> Self {
        let (l, w) = (setup.length, setup.width);
        // Periodic along x: no end walls, the bed continues through the cell's ends.
        let bodies = container_planes(
            Vector3::zeros(),
            [0.0, l],
            [-0.5 * w, 0.5 * w],
            setup.params.period.is_some(),
            setup.wall_material,
        );
        let roles = vec![Role::Boundary; bodies.len()];
        let radius = setup
            .family
            .iter()
            .map(StoneShape::radius)
            .fold(0.0, f64::max);
        let engine = Self::engine(&setup, false);
        let random = SplitMix(setup.seed);
        Deposition {
            cell: 2.02 * radius,
            setup,
            bodies,
            roles,
            time: 0.0,
            steps: 0,
            body_steps: 0,
            phase_times: [Duration::ZERO; 4],
            solve_split: [Duration::ZERO; 2],
            stepping: Duration::ZERO,
            phases: Vec::new(),
            engine,
            finishing: false,
            vibrating: false,
            random,
            inserted: 0,
            cursor: Cursor::default(),
            calls: 0,
            stopped: false,
        }
    }

    /// The engine, with the sweep cap of the finishing phases if `finishing`.
    pub(super) fn engine(setup: &DepositSetup, finishing: bool) -> MoreauJean {
        let mut engine = MoreauJean::new(
            setup.params,
            NlgsOptions {
                stopping: Self::stopping(setup, finishing),
                // The full measure costs about a sweep: every tenth sweep, or when the
                // impulse change alone says converged.
                error_check: ErrorCheck::Light { every: 10 },
            },
        );
        engine.ddm = setup.ddm.clone();
        engine
    }

    /// The contact points of the current configuration (a detection without a step).
    pub fn detect(&mut self) -> Vec<ContactPoint> {
        self.engine.detect(&self.bodies)
    }

    /// Whether the bed ends at rest: its last phase (the final settle, or the release
    /// after a held one) met the finishing rules of [`Self::settled`] (rms speed, every
    /// body point, every overlap). A phase before it that ran to its cap
    /// ([`Self::capped_phases`]) shaped the bed, which its compactness measures, but
    /// leaves nothing moving: a stone wedged against a wall under a held sleeper in a
    /// final settle is pushed out once the sleeper is released (docs/pack.md, "Settled:
    /// the last phase").
    pub fn at_rest(&self) -> bool {
        self.phases.last().is_some_and(|p| p.settled)
    }

    /// The phases that ran to `max_phase_time` without settling, in order.
    pub fn capped_phases(&self) -> Vec<&str> {
        self.phases
            .iter()
            .filter(|p| !p.settled)
            .map(|p| p.name.as_str())
            .collect()
    }

    /// The contacts of the last step with their impulses.
    pub fn last_contacts(&self) -> &[SolvedContact] {
        self.engine.contacts()
    }

    /// Each free sleeper's support, in sleeper order: the upward resultant of the last
    /// step's contact impulses on it over its true weight's impulse `m g dt`. A sleeper
    /// at rest on the bed has 1, whatever its scaled inertia
    /// ([`DepositSetup::sleeper_inertia_scale`]). `None` when no sleeper is free (none
    /// laid yet, or held).
    pub fn sleeper_support(&self) -> Option<Vec<f64>> {
        let StepParams { dt, gravity, .. } = self.setup.params;
        let down = gravity.normalize();
        let mut up = vec![0.0; self.bodies.len()];
        for c in self.last_contacts() {
            let lift = -c.world_impulse().dot(&down);
            up[c.contact.key.body_b as usize] += lift;
            up[c.contact.key.body_a as usize] -= lift;
        }
        let support: Vec<f64> = self
            .bodies
            .iter()
            .zip(&self.roles)
            .zip(up)
            .filter(|((b, r), _)| matches!(r, Role::Sleeper(_)) && b.is_dynamic())
            .map(|((b, _), lift)| {
                let weight = b.mass * self.setup.sleeper_inertia_scale * gravity.norm() * dt;
                lift / weight
            })
            .collect();
        (!support.is_empty()).then_some(support)
    }

    /// Stones in the bed.
    pub fn stone_count(&self) -> usize {
        self.roles
            .iter()
            .filter(|r| matches!(r, Role::Stone(_)))
            .count()
    }

    /// The cell of the column's plan grid: 1.01 × the family's largest bounding
    /// diameter (m).
    pub fn cell(&self) -> f64 {
        self.cell
    }

    /// Mean stone volume of the family (m³).
    pub fn mean_stone_volume(&self) -> f64 {
        mean_volume(&self.setup.family)
    }

    fn step(
        &mut self,
        friction_while_raining: bool,
        phase: &str,
        observe: &mut dyn Observer,
    ) -> StepReport {
        let friction = if friction_while_raining {
            &self.setup.rain_friction
        } else {
            &self.setup.friction
        };
        if let (Some(tau), false) = (self.setup.drag_time, self.finishing || self.vibrating) {
            // Exact decay of a linear drag over the step, applied before it.
            let factor = (-self.setup.params.dt / tau).exp();
            for b in self.bodies.iter_mut().filter(|b| b.is_dynamic()) {
                b.velocity *= factor;
                b.angular_velocity *= factor;
            }
        }
        let scale = self.setup.sleeper_inertia_scale;
        if scale > 1.0 && !self.light_sleepers() {
            // The part of the sleepers' weight their scaled mass does not carry.
            let extra = (scale - 1.0) * self.setup.params.dt * self.setup.params.gravity;
            for (b, r) in self.bodies.iter_mut().zip(&self.roles) {
                if matches!(r, Role::Sleeper(_)) && b.is_dynamic() {
                    b.velocity += extra;
                }
            }
        }
        let held = self
            .bodies
            .iter()
            .zip(&self.roles)
            .any(|(b, r)| matches!(r, Role::Sleeper(_)) && !b.is_dynamic());
        self.engine.set_warm_start(if held {
            self.setup.held_warm_start
        } else {
            1.0
        });
        let clock = Instant::now();
        let report = self.engine.step(&mut self.bodies, self.time, friction);
        self.stepping += clock.elapsed();
        for (total, t) in self.phase_times.iter_mut().zip(report.phase_times) {
            *total += t;
        }
        for (total, t) in self.solve_split.iter_mut().zip(report.solve_split) {
            *total += t;
        }
        self.steps += 1;
        self.time = self.steps as f64 * self.setup.params.dt;
        self.body_steps += self.bodies.iter().filter(|b| b.is_dynamic()).count() as u64;
        let record = StepRecord {
            time: self.time,
            phase,
            stones: self.stone_count(),
            finishing: self.finishing && !self.vibrating,
            report: &report,
        };
        observe.step(&record, &self.bodies, &self.roles);
        self.stopped |= observe.stop();
        report
    }

    /// Whether the free sleepers carry only their scaled weight (1/k of the true one,
    /// k = [`DepositSetup::sleeper_inertia_scale`]) in this step: in the finishing
    /// phases with the floor still (the final settle when they are not held, the
    /// release). The bed's geometry is already made under their true weight; what these
    /// phases need is rest, which the solve reaches under a sleeper k times lighter
    /// (docs/pack.md, "Heavy sleepers", "Rounded stones").
    fn light_sleepers(&self) -> bool {
        self.finishing && !self.vibrating
    }

    /// Hands the bed to the observer between two steps of a loop; false when the run
    /// is to stop.
    fn between_steps(&mut self, observe: &mut dyn Observer) -> bool {
        if !self.stopped {
            observe.between_steps(self);
            self.stopped |= observe.stop();
        }
        !self.stopped
    }

    /// Whether the bed has settled: the rms speed below `settle_speed`, and once
    /// finishing ([`Self::finish`]) also no body point faster than [`MAX_SPEED_FACTOR`]
    /// times it (a lone stone still sliding down a sleeper's side hides in the rms of
    /// hundreds at rest; the intermediate phases only need a quiet heap) and no overlap
    /// deeper than `max_overlap` (one still being pushed out moves a stone slowly
    /// enough to pass the speed tests), on every step of the last
    /// [`Self::settle_watch`] of the phase: a body left unbalanced, by what began the
    /// phase or by a stone tipping off a ridge later in it, passes the speed limit
    /// within that time at [`UNBALANCE_G`] × g (docs/pack.md, "Settled: quiet for a
    /// whole watch").
    fn settled(&mut self, report: &StepReport) -> bool {
        let limit = self.setup.settle_speed;
        let quiet = self.rms_speed(report.kinetic_energy) < limit
            && (!self.finishing
                || (report.max_interpenetration < self.setup.max_overlap
                    && fastest_point_speed(&self.bodies) < MAX_SPEED_FACTOR * limit));
        let run = self.cursor.quiet_run(quiet, self.steps);
        quiet && (!self.finishing || run as f64 * self.setup.params.dt >= self.settle_watch())
    }

    /// The time over which a finishing phase's settle test must hold on every step (s):
    /// [`MAX_SPEED_FACTOR`] × `settle_speed` over [`UNBALANCE_G`] × g.
    fn settle_watch(&self) -> f64 {
        MAX_SPEED_FACTOR * self.setup.settle_speed
            / (UNBALANCE_G * self.setup.params.gravity.norm())
    }

    /// rms speed √(2 KE / Σm) of the dynamic bodies (m/s).
    fn rms_speed(&self, kinetic_energy: f64) -> f64 {
        let mass: f64 = self
            .bodies
            .iter()
            .filter(|b| b.is_dynamic())
            .map(|b| b.mass)
            .sum();
        if mass > 0.0 {
            (2.0 * kinetic_energy / mass).sqrt()
        } else {
            0.0
        }
    }

    /// Highest point of any bounded body (m: a hull vertex, plus the rounding); 0 for
    /// an empty container.
    fn top(&self) -> f64 {
        self.bodies
            .iter()
            .filter(|b| b.shape.collider.is_bounded())
            .flat_map(|b| {
                let pose = b.pose();
                let round = b.shape.collider.round();
                b.shape.vertices.iter().map(move |p| (pose * p).z + round)
            })
            .fold(0.0, f64::max)
    }

    /// The sleepers' axis-aligned boxes (lower and upper corners, world).
    pub fn sleeper_boxes(&self) -> Vec<(Point3<f64>, Point3<f64>)> {
        self.bodies
            .iter()
            .zip(&self.roles)
            .filter(|(_, r)| matches!(r, Role::Sleeper(_)))
            .map(|(b, _)| bounds(&b.world_vertices()))
            .collect()
    }

    /// xy footprints of the sleepers (min x, max x, min y, max y).
    fn sleeper_footprints(&self) -> Vec<[f64; 4]> {
        self.sleeper_boxes()
            .iter()
            .map(|(lo, hi)| [lo.x, hi.x, lo.y, hi.y])
            .collect()
    }

    /// Inserts a column of `wanted` stones above every body by ballistic deposition of
    /// their bounding spheres: each stone (shape drawn from the family) tries
    /// [`PLACEMENT_TRIES`] random plan positions clear of the walls and of the sleeper
    /// footprints (drawing at most [`PLACEMENT_DRAWS`]); at each, its sphere is lowered from above until it rests on the plane
    /// z = top or on a sphere already in the column; the lowest of the tries is kept.
    /// No two spheres overlap, so no two inserted stones do, nor a stone and anything
    /// below the column. Returns how many went in (a stone too large for the container,
    /// or whose tries all fell on sleepers, is skipped). Periodic along x, plan
    /// positions take the whole length and spheres near an end are also kept as their
    /// images one length away, so no stone overlaps another's image either.
    fn insert_column(&mut self, wanted: usize) -> usize {
        let (l, w) = (self.setup.length, self.setup.width);
        let periodic = self.setup.params.period.is_some();
        let base = self.top() + 1e-3;
        let blocked = self.sleeper_footprints();
        let cell = self.cell;
        let key = |x: f64, y: f64| ((x / cell).floor() as i64, (y / cell).floor() as i64);
        let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
        let mut placed: Vec<(Vector3<f64>, f64)> = Vec::new();
        let mut inserted = 0;
        for _ in 0..wanted {
            let family = self.random.below(self.setup.family.len());
            let r = self.setup.family[family].radius();
            let mut best: Option<Vector3<f64>> = None;
            let mut tries = 0;
            for _ in 0..PLACEMENT_DRAWS {
                if l < 2.0 * r || w < 2.0 * r || tries == PLACEMENT_TRIES {
                    break;
                }
                let x = if periodic {
                    l * self.random.next_f64()
                } else {
                    r + (l - 2.0 * r) * self.random.next_f64()
                };
                let y = -0.5 * w + r + (w - 2.0 * r) * self.random.next_f64();
                let on_sleeper = blocked.iter().any(|f| {
                    let gap_x = |x: f64| (f[0] - x).max(x - f[1]).max(0.0);
                    let dx = if periodic {
                        gap_x(x).min(gap_x(x - l)).min(gap_x(x + l))
                    } else {
                        gap_x(x)
                    };
                    let dy = (f[2] - y).max(y - f[3]).max(0.0);
                    dx * dx + dy * dy < r * r
                });
                if on_sleeper {
                    continue;
                }
                tries += 1;
                let (cx, cy) = key(x, y);
                let mut z = base + r;
                for i in cx - 1..=cx + 1 {
                    for j in cy - 1..=cy + 1 {
                        for &k in grid.get(&(i, j)).map_or(&[][..], Vec::as_slice) {
                            let (p, q) = placed[k];
                            let (dx, dy, reach) = (p.x - x, p.y - y, r + q);
                            let d2 = dx * dx + dy * dy;
                            if d2 < reach * reach {
                                z = z.max(p.z + (reach * reach - d2).sqrt() + 1e-6);
                            }
                        }
                    }
                }
                if best.is_none_or(|b| z < b.z) {
                    best = Some(Vector3::new(x, y, z));
                }
            }
            let Some(centre) = best else {
                continue;
            };
            // The sphere, and its images across the ends that come within a cell of
            // the bed (the largest sphere reaches 1.01 cells).
            let images: &[f64] = match (periodic, centre.x) {
                (true, x) if x < cell => &[0.0, 1.0],
                (true, x) if x > l - cell => &[0.0, -1.0],
                _ => &[0.0],
            };
            for k in images {
                let copy = centre + Vector3::new(k * l, 0.0, 0.0);
                grid.entry(key(copy.x, copy.y))
                    .or_default()
                    .push(placed.len());
                placed.push((copy, r));
            }
            let rotation = self.random.rotation();
            self.bodies.push(self.setup.family[family].body(
                self.inserted,
                self.setup.stone_density,
                self.setup.stone_material,
                Isometry3::from_parts(Translation3::from(centre), rotation),
            ));
            self.roles.push(Role::Stone(family));
            self.inserted += 1;
            inserted += 1;
        }
        inserted
    }

    /// Free volume between `bottom` and the fill's cap up to `level` (m³): the
    /// container's, under the profile if there is one, less the sleepers' footprints
    /// (which lie on the crest) times the layer.
    fn free_volume(&self, bottom: f64, level: f64) -> f64 {
        let (length, width) = (self.setup.length, self.setup.width);
        let sleepers: f64 = self
            .sleeper_footprints()
            .iter()
            .map(|f| (f[1] - f[0]) * (f[3] - f[2]))
            .sum();
        let layer = (level - bottom).max(0.0);
        match &self.setup.profile {
            Some(p) => {
                (length * p.section_area(bottom, level, 0.5 * width) - sleepers * layer).max(0.0)
            }
            None => (length * width - sleepers).max(0.0) * layer,
        }
    }

    /// Rains stones to fill the bed up to `level` (m) and lets them settle; then strikes
    /// off the stones whose centre is above `level` (or above the profile, where that is
    /// lower) and settles again. `bottom` is the level from which the new stones fill
    /// (the free volume between `bottom` and that cap). `low_friction`: the raining
    /// friction table while it settles (else the final one). One stage: insert (part
    /// 0), settle and strike off (1), settle again (2).
    pub fn fill(
        &mut self,
        name: &str,
        bottom: f64,
        level: f64,
        low_friction: bool,
        observe: &mut dyn Observer,
    ) {
        if !self.begin_stage() {
            return;
        }
        if self.cursor.part == 0 {
            let volume = self.free_volume(bottom, level);
            let room = self.setup.max_stones.saturating_sub(self.stone_count());
            let wanted =
                ((FILL_FRACTION * volume / self.mean_stone_volume()).ceil() as usize).min(room);
            let inserted = self.insert_column(wanted);
            self.cursor.report = Some(PhaseReport {
                name: name.to_string(),
                time: 0.0,
                steps: 0,
                settled: true,
                inserted,
                removed: 0,
                sleeper_support: None,
            });
            self.enter_part(1);
        }
        if self.cursor.part == 1 {
            let settled = self.settle_loop(name, low_friction, observe);
            let (time, steps) = self.part_span();
            let removed = self.strike_off(level);
            let report = self.cursor.report.as_mut().expect("set in part 0");
            (report.time, report.steps, report.settled) = (time, steps, settled);
            report.removed = removed;
            self.enter_part(if removed > 0 { 2 } else { 3 });
        }
        if self.cursor.part == 2 {
            // A profile's slopes are cut for the stones' own friction: at the raining
            // friction they would slump.
            let low = low_friction && self.setup.profile.is_none();
            let settled = self.settle_loop(&format!("{name} (after strike-off)"), low, observe);
            self.cursor.report.as_mut().expect("set in part 0").settled &= settled;
        }
        let support = self.sleeper_support();
        if let Some(report) = self.cursor.report.as_mut() {
            report.sleeper_support = support;
        }
        self.end_stage();
    }

    /// Whether the stage now called is still to run (else a resumed run did it before
    /// the checkpoint, or the run is stopping).
    fn begin_stage(&mut self) -> bool {
        self.calls += 1;
        self.calls > self.cursor.stages_done && !self.stopped
    }

    /// Starts part `part` of the stage at the current step.
    fn enter_part(&mut self, part: u8) {
        self.cursor.part = part;
        self.cursor.start_step = self.steps;
    }

    /// Simulated time and steps since the current part began.
    fn part_span(&self) -> (f64, u64) {
        let start = self.cursor.start_step as f64 * self.setup.params.dt;
        (self.time - start, self.steps - self.cursor.start_step)
    }

    /// Ends the stage: its report joins the phases, and the next stage begins here.
    fn end_stage(&mut self) {
        if let Some(report) = self.cursor.report.take() {
            self.phases.push(report);
        }
        self.cursor = Cursor {
            stages_done: self.cursor.stages_done + 1,
            part: 0,
            start_step: self.steps,
            report: None,
            quiet_since: None,
        };
    }

    /// Lays the bodies of a tiled bay into the empty container instead of raining
    /// ([`super::tile`]): a stage without steps, whose report counts the stones laid
    /// and, as `removed`, the copies left out at the end walls.
    pub fn lay(&mut self, name: &str, laid: Laid) {
        if !self.begin_stage() {
            return;
        }
        let stones = laid.bodies.len() - laid.sleepers();
        for (body, role) in laid.bodies {
            self.bodies.push(body);
            self.roles.push(role);
        }
        self.inserted += stones;
        self.cursor.report = Some(PhaseReport {
            name: name.to_string(),
            time: 0.0,
            steps: 0,
            settled: true,
            inserted: stones,
            removed: laid.dropped,
            sleeper_support: None,
        });
        self.end_stage();
    }

    /// Removes the stones whose mass centre is above `level`, or above the profile
    /// where that is lower; returns how many. The engine restarts cold (the contact
    /// memory is keyed by body index).
    pub fn strike_off(&mut self, level: f64) -> usize {
        let before = self.bodies.len();
        let cap = |y: f64| self.setup.profile.map_or(level, |p| p.cap(y, level));
        let keep: Vec<bool> = self
            .bodies
            .iter()
            .zip(&self.roles)
            .map(|(b, r)| !(matches!(r, Role::Stone(_)) && b.position.z > cap(b.position.y)))
            .collect();
        let mut k = 0;
        self.bodies.retain(|_| {
            k += 1;
            keep[k - 1]
        });
        let mut k = 0;
        self.roles.retain(|_| {
            k += 1;
            keep[k - 1]
        });
        let removed = before - self.bodies.len();
        if removed > 0 {
            self.engine = Self::engine(&self.setup, self.finishing);
        }
        removed
    }

    /// Steps until settled or `max_phase_time` after the current part began; true if
    /// settled. Between two steps the observer may take a checkpoint.
    fn settle_loop(
        &mut self,
        name: &str,
        raining_friction: bool,
        observe: &mut dyn Observer,
    ) -> bool {
        let start = self.cursor.start_step as f64 * self.setup.params.dt;
        while !self.stopped && self.time - start < self.setup.max_phase_time {
            let report = self.step(raining_friction, name, observe);
            if self.settled(&report) {
                return true;
            }
            if !self.between_steps(observe) {
                break;
            }
        }
        false
    }

    /// A part that lets the bed settle with the final friction table, as a phase of its
    /// own (the stage's report).
    fn settle_part(&mut self, name: &str, observe: &mut dyn Observer) {
        let settled = self.settle_loop(name, false, observe);
        let (time, steps) = self.part_span();
        self.cursor.report = Some(PhaseReport {
            name: name.to_string(),
            time,
            steps,
            settled,
            inserted: 0,
            removed: 0,
            sleeper_support: self.sleeper_support(),
        });
    }

    /// Switches to the finishing rules (compaction, final settle): no drag, the sweep
    /// cap `finish_sweeps`, and a phase settles only when no body point is fast either.
    pub fn finish(&mut self) {
        self.finishing = true;
        self.engine.options.stopping = Self::stopping(&self.setup, true);
    }

    /// The NLGS stopping rule: the tolerance, and the sweep cap of the phase.
    pub(super) fn stopping(setup: &DepositSetup, finishing: bool) -> Stopping {
        Stopping::Tolerance {
            tolerance: setup.tolerance,
            max_sweeps: if finishing {
                setup.finish_sweeps
            } else {
                setup.max_sweeps
            },
        }
    }

    /// Lets the bed settle with the final friction table (a stage and phase of its
    /// own).
    pub fn settle(&mut self, name: &str, observe: &mut dyn Observer) {
        if self.begin_stage() {
            self.settle_part(name, observe);
            self.end_stage();
        }
    }

    /// Lowers the sleepers onto the bed: each is placed at its nominal (x, y), level,
    /// 1 mm above the highest stone under its footprint, and released (a dynamic body
    /// under gravity); the bed then settles under their weight (part 1).
    pub fn lower_sleepers(
        &mut self,
        sleepers: &[(SleeperModel, [f64; 2])],
        observe: &mut dyn Observer,
    ) {
        if !self.begin_stage() {
            return;
        }
        if self.cursor.part == 0 {
            self.place_sleepers(sleepers);
            self.enter_part(1);
        }
        self.settle_part("lower sleepers", observe);
        self.end_stage();
    }

    /// Holds every sleeper where it rests, as a static body, if the scene says so
    /// ([`DepositSetup::hold_sleepers`]; before the final settle). A held sleeper
    /// cannot be pushed out of a stone under it, and a stone squeezed between it and
    /// the bed cannot go anywhere either, so each sleeper is first lifted clear of the
    /// stones it presses into (by the deepest overlap under it, measured along the
    /// vertical: a few µm on a settled bed). Idempotent: a resumed run calls it again.
    /// Returns each newly held sleeper's lift (m), in sleeper order.
    pub fn hold_sleepers(&mut self) -> Vec<f64> {
        // A bed resumed past the final settle may have released them again.
        if !self.setup.hold_sleepers || self.cursor.stages_done > self.calls {
            return Vec::new();
        }
        let free: Vec<usize> = (0..self.bodies.len())
            .filter(|&i| matches!(self.roles[i], Role::Sleeper(_)) && self.bodies[i].is_dynamic())
            .collect();
        if free.is_empty() {
            return Vec::new();
        }
        let mut lift = vec![0.0_f64; self.bodies.len()];
        for c in self.detect() {
            let (a, b) = (c.key.body_a as usize, c.key.body_b as usize);
            // The normal points from a to b: up into a sleeper b, down into a sleeper a.
            for (sleeper, up) in [(b, c.normal.z), (a, -c.normal.z)] {
                if up > 0.5 && c.gap < 0.0 && matches!(self.roles[sleeper], Role::Sleeper(_)) {
                    lift[sleeper] = lift[sleeper].max(-c.gap / up);
                }
            }
        }
        for &i in &free {
            let b = &mut self.bodies[i];
            b.position.z += lift[i];
            *b = hold(b);
        }
        free.iter().map(|&i| lift[i]).collect()
    }

    /// Frees the sleepers held for the final settle ([`Self::hold_sleepers`]) and lets
    /// the bed settle with them (the "release" phase; a stage of its own, without steps
    /// or phase when none is held or `release_sleepers` is off). A bed settled under
    /// held sleepers leans on them: restarted with free ones, as the track and tamping
    /// scenes use them, the stones against their sides moved by up to 1.7 mm in 10
    /// steps (docs/pack.md, "Warm restart"). Released, the sleepers keep their scaled
    /// inertia and carry their scaled weight, m g / k ([`Self::light_sleepers`]): with
    /// their true weight a heavy sleeper keeps the solve from converging, as in the
    /// final settle it was held for.
    pub fn release_sleepers(&mut self, models: &[SleeperModel], observe: &mut dyn Observer) {
        if !self.begin_stage() {
            return;
        }
        if self.cursor.part == 0 {
            let mut released = 0;
            if self.setup.release_sleepers {
                for i in 0..self.bodies.len() {
                    if let (Role::Sleeper(k), false) = (self.roles[i], self.bodies[i].is_dynamic())
                    {
                        let model = &models[k];
                        let own = self.bodies[i].pose() * model.frame.inverse();
                        let name = self.bodies[i].name.clone();
                        self.bodies[i] = model.body(&name, own, self.setup.sleeper_inertia_scale);
                        released += 1;
                    }
                }
            }
            if released == 0 {
                self.end_stage();
                return;
            }
            self.enter_part(1);
        }
        self.settle_part("release", observe);
        self.end_stage();
    }

    /// Places the sleepers (see [`Self::lower_sleepers`]).
    fn place_sleepers(&mut self, sleepers: &[(SleeperModel, [f64; 2])]) {
        for (k, (model, [x, y])) in sleepers.iter().enumerate() {
            let [fx, fy] = model.footprint;
            let mut highest: f64 = 0.0;
            for (b, r) in self.bodies.iter().zip(&self.roles) {
                if !matches!(r, Role::Stone(_)) {
                    continue;
                }
                let round = b.shape.collider.round();
                for p in b.world_vertices() {
                    if (p.x - x).abs() <= 0.5 * fx && (p.y - y).abs() <= 0.5 * fy {
                        highest = highest.max(p.z + round);
                    }
                }
            }
            // The sleeper's own frame is level, centred at (x, y), its underside at
            // `highest + 1 mm` (the highest point of a rounded stone under it), its
            // contact spheres (if any) clear of it by the same 1 mm.
            let under = highest + 1e-3 + model.shape.collider.round();
            let origin = Isometry3::translation(*x, *y, under);
            let body = model.body(
                &format!("sleeper_{}", k + 1),
                origin,
                self.setup.sleeper_inertia_scale,
            );
            self.bodies.push(body);
            self.roles.push(Role::Sleeper(k));
        }
    }

    /// Vibrates the floor vertically (`A sin 2πft`, whole cycles, the frequency
    /// adjusted so that they are whole steps too, so the floor ends where it started up
    /// to round-off), without drag and with the final friction table (part 1), then
    /// lets the bed settle with the floor at rest (part 2).
    pub fn compact(
        &mut self,
        amplitude: f64,
        frequency: f64,
        duration: f64,
        observe: &mut dyn Observer,
    ) {
        if !self.begin_stage() {
            return;
        }
        let cycles = (duration * frequency).round().max(1.0);
        let dt = self.setup.params.dt;
        let steps = (cycles / frequency / dt).round().max(1.0) as u64;
        // The frequency that makes those steps whole cycles (35 Hz with 2 ms steps: 18
        // cycles in 257 steps at 35.019 Hz). At the nominal frequency the floor would
        // stop a fraction of a step short of a cycle, up to 2π f dt / 2 × the
        // amplitude off its rest level (43 µm for 1 mm at 35 Hz), and a packing read
        // back with the floor at 0 would start with every stone above it.
        let frequency = cycles / (steps as f64 * dt);
        let motion = Prescribed {
            velocity: Vector3::zeros(),
            amplitude: Vector3::new(0.0, 0.0, amplitude),
            frequency,
            table: None,
        };
        if self.cursor.part == 0 {
            // Body 0 is the floor (see `new`); a resumed part 1 has its velocity.
            self.bodies[0].velocity = motion.velocity_at(self.time);
            self.enter_part(1);
        }
        if self.cursor.part == 1 {
            self.bodies[0].motion = Motion::Driven(motion);
            self.vibrating = true;
            while self.steps - self.cursor.start_step < steps {
                self.step(false, "compaction", observe);
                if !self.between_steps(observe) {
                    return;
                }
            }
            self.vibrating = false;
            self.bodies[0].motion = Motion::Static;
            self.bodies[0].velocity = Vector3::zeros();
            let (time, _) = self.part_span();
            self.phases.push(PhaseReport {
                name: "compaction".into(),
                time,
                steps,
                settled: true,
                inserted: 0,
                removed: 0,
                sleeper_support: self.sleeper_support(),
            });
            self.enter_part(2);
        }
        self.settle_part("settle after compaction", observe);
        self.end_stage();
    }

    /// The floor's height after compaction (m; 0 without it).
    pub fn floor_offset(&self) -> f64 {
        self.bodies[0].position.z
    }

    /// The stones' equivalent diameters (m), in body order.
    pub fn stone_diameters(&self) -> Vec<f64> {
        self.roles
            .iter()
            .filter_map(|r| match r {
                Role::Stone(f) => Some(self.setup.family[*f].diameter()),
                _ => None,
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::Cursor;

    #[test]
    fn a_quiet_run_restarts_after_a_loud_step_and_at_the_part_start() {
        // A part began after step 10; steps 11-13 quiet, 14 not, 15-16 quiet.
        let mut c = Cursor {
            start_step: 10,
            ..Cursor::default()
        };
        let runs: Vec<u64> = [
            (true, 11),
            (true, 12),
            (true, 13),
            (false, 14),
            (true, 15),
            (true, 16),
        ]
        .iter()
        .map(|&(quiet, step)| c.quiet_run(quiet, step))
        .collect();
        assert_eq!(runs, [1, 2, 3, 0, 1, 2]);
        // Quiet since step 15, but a new part begins after step 16: its first quiet
        // step counts one, not three.
        c.start_step = 16;
        assert_eq!(c.quiet_run(true, 17), 1);
        // Restored from a checkpoint, the cursor carries the run on.
        let bytes = bincode::serialize(&c).unwrap();
        let mut restored: Cursor = bincode::deserialize(&bytes).unwrap();
        assert_eq!(restored.quiet_run(true, 18), 2);
    }
}
