//! The scene file of `ballast-nscd SCENE.toml` and the bodies it builds.
//!
//! This file and [`super::run`] are the engine's edge: the only parts of `nscd` that
//! know TOML and files. The numerics ([`super::step`], [`super::body_nlgs`]) take the
//! plain structs built here.
//!
//! ```toml
//! [time]
//! duration = "1 s"
//! dt = "1 ms"
//! theta = 0.5                       # θ-method, 0.5 ≤ θ ≤ 1
//!
//! [ddm]                             # optional: domain decomposition of the solve
//! driver = "synchronous"            # crate::scene::DdmSpec (default: 2 slabs along x)
//!
//! [solver]
//! tolerance = 1e-8                  # or: sweeps = 50 (fixed count, the seed's n_DDM)
//! max_sweeps = 2000
//! check_every = 10                  # full error measure every 10 sweeps (default)
//! alert_distance = "1 mm"
//! depenetration_speed = "2 mm/s"    # optional: push existing overlaps out (packings)
//! end_checks = 2                    # optional: re-solve a step whose motion cuts unseen features
//! warm_start = 0.9                  # optional: share of last step's impulses carried (1)
//!
//! [gravity]
//! magnitude = "9.81 m/s^2"
//! incline = "20 deg"                # tilts gravity about y: bodies slide along +x
//!
//! [[material]]
//! name = "granite"
//! density = "2700 kg/m^3"
//!
//! [[friction]]
//! pair = ["granite", "steel"]
//! mu = 0.8
//!
//! [[plane]]                         # a half-space; static unless given a velocity
//! name = "floor"
//! point = [0, 0, 0]
//! normal = [0, 0, 1]
//! material = "steel"
//!
//! [[box]]                           # a driven (or fixed) cuboid, infinite mass
//! name = "pusher"
//! size = ["0.05 m", "0.2 m", "0.1 m"]
//! centre = ["-0.1 m", 0, "0.055 m"]
//! orientation = [0, 0, "30 deg"]    # about x, then y, then z (fixed axes)
//! material = "steel"
//! velocity = ["0.2 m/s", 0, 0]      # or a table, below; plus amplitude/frequency
//!
//! [[driven]]                        # a driven rigid body from a tetra mesh
//! name = "tine"
//! mesh = "../meshes/tine.msh"       # relative to the scene file
//! convex = ["blade", "shank"]       # or "volumes" (default) or "hull"
//! position = [0, "0.5 m", "0.005 m"]
//! velocity = { times = ["0 s", "0.1 s"], values = [[0, 0, 0], ["0.2 m/s", 0, 0]] }
//! # or: velocity = { file = "cycle.csv" }   (rows t, vx, vy, vz in s and m/s)
//!
//! [[block]]                         # boxes; `count` copies `step` apart
//! name = "cube"
//! size = ["0.1 m", "0.1 m", "0.1 m"]
//! position = [0, 0, "0.05 m"]
//! material = "granite"
//!
//! [stones]                          # convex hulls of meshes/stones/stone_*.msh
//! directory = "../meshes/stones"
//! count = 200
//! material = "granite"
//! region_min = [..]                 # placed on a lattice in this box, random turns
//! region_max = [..]
//!
//! [packing]                         # or: the bed that ballast-pack built
//! file = "../results/bed-quick/packing.toml"
//! stone_material = "granite"
//! sleeper_material = "concrete"     # optional: the sleepers as dynamic bodies
//! wall_material = "steel"           # optional: the container's floor and side walls
//!
//! [tamping]                         # optional, on a packing: super::tamping
//! tine_mesh = "../meshes/tine.msh"
//! tine_material = "steel"
//! ```

use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use serde::Deserialize;

use super::body::{Body, BodyShape, Motion, Prescribed, PrincipalShape};
use super::motion::{mesh_pieces, Pieces, VelocityTable};
use super::packed::PackedLayout;
use super::step::FrictionTable;
use crate::contact::{Collider, ConvexShape};
use crate::geometry::random::SplitMix;
use crate::geometry::Period;
use crate::pack::contacts::PackedContact;
use crate::scene::{
    Acceleration, Angle, DdmSpec, Density, Frequency, Length, Time, Validate, Validator, Velocity,
};
use crate::{Error, Result};

/// A whole NSCD scene.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NscdScene {
    /// Time stepping.
    pub time: TimeSpec,
    /// Domain decomposition of the contact solve (none: sequential NLGS).
    #[serde(default)]
    pub ddm: Option<DdmSpec>,
    /// NLGS and detection.
    pub solver: SolverSpec,
    /// Gravity.
    #[serde(default)]
    pub gravity: GravitySpec,
    /// Materials.
    pub material: Vec<MaterialSpec>,
    /// Friction per pair of materials.
    #[serde(default)]
    pub friction: Vec<FrictionSpec>,
    /// µ of pairs not listed in `friction`.
    #[serde(default)]
    pub default_friction: Option<f64>,
    /// Half-spaces (floors, walls).
    #[serde(default)]
    pub plane: Vec<PlaneSpec>,
    /// Boxes.
    #[serde(default)]
    pub block: Vec<BlockSpec>,
    /// Driven or fixed cuboids (infinite mass).
    #[serde(default, rename = "box")]
    pub boxes: Vec<BoxSpec>,
    /// Driven or fixed rigid bodies from tetra meshes (convex pieces).
    #[serde(default)]
    pub driven: Vec<DrivenSpec>,
    /// Stones from meshes.
    #[serde(default)]
    pub stones: Option<StonesSpec>,
    /// Stones, sleepers and container from a `ballast-pack` packing file.
    #[serde(default)]
    pub packing: Option<PackingSpec>,
    /// A tamping cycle on one of the packing's sleepers ([`super::tamping`]).
    #[serde(default)]
    pub tamping: Option<super::tamping::TampingSpec>,
    /// VTK output.
    #[serde(default)]
    pub output: OutputSpec,
    /// The figure the scene checks.
    #[serde(default)]
    pub analysis: Option<AnalysisSpec>,
}

/// `[time]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// Simulated time.
    pub duration: Time,
    /// Time step.
    pub dt: Time,
    /// θ of the θ-method.
    #[serde(default = "half")]
    pub theta: f64,
}

fn half() -> f64 {
    0.5
}

/// `[solver]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// Stop NLGS when the error measure is at most this.
    #[serde(default)]
    pub tolerance: Option<f64>,
    /// Cap on sweeps under a tolerance.
    #[serde(default = "default_max_sweeps")]
    pub max_sweeps: usize,
    /// Speed at which existing interpenetration is pushed out (0: never, the seed's
    /// law; see [`super::step::StepParams::depenetration_speed`]).
    #[serde(default)]
    pub depenetration_speed: Option<Velocity>,
    /// End-of-step checks per step (0, the default: none; see
    /// [`super::step::StepParams::end_checks`]).
    #[serde(default)]
    pub end_checks: usize,
    /// A fixed number of sweeps per step instead of a tolerance.
    #[serde(default)]
    pub sweeps: Option<usize>,
    /// Under a tolerance, the full error measure (as costly as a sweep) is taken after
    /// every this many sweeps, and after any sweep whose relative impulse change is
    /// already below the tolerance ([`super::nlgs::ErrorCheck::Light`]); 1 measures
    /// after every sweep. Stopping is always decided on the full measure.
    #[serde(default = "default_check_every")]
    pub check_every: usize,
    /// Contacts within this gap enter the problem.
    pub alert_distance: Length,
    /// Share of the last step's impulses each contact starts the solve from (1, the
    /// default; see [`super::step::MoreauJean::set_warm_start`]).
    #[serde(default = "unit_scale")]
    pub warm_start: f64,
}

fn default_max_sweeps() -> usize {
    1000
}

fn default_check_every() -> usize {
    10
}

/// `[gravity]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GravitySpec {
    /// |g|.
    #[serde(default = "standard_gravity")]
    pub magnitude: Acceleration,
    /// Tilt of gravity about y (an incline of this angle along +x).
    #[serde(default)]
    pub incline: Option<Angle>,
}

fn standard_gravity() -> Acceleration {
    Acceleration::from_si(9.81)
}

impl Default for GravitySpec {
    fn default() -> Self {
        GravitySpec {
            magnitude: standard_gravity(),
            incline: None,
        }
    }
}

impl GravitySpec {
    /// The gravity vector: |g| (sin α, 0, −cos α).
    pub fn vector(&self) -> Vector3<f64> {
        let alpha = self.incline.map_or(0.0, Angle::si);
        self.magnitude.si() * Vector3::new(alpha.sin(), 0.0, -alpha.cos())
    }
}

/// `[[material]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Name used by bodies and friction pairs.
    pub name: String,
    /// Density (needed by dynamic bodies).
    #[serde(default)]
    pub density: Option<Density>,
}

/// `[[friction]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionSpec {
    /// Two material names.
    pub pair: [String; 2],
    /// Coulomb coefficient.
    pub mu: f64,
}

/// `[[plane]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    /// Name.
    pub name: String,
    /// A point of the plane.
    pub point: [Length; 3],
    /// Outward normal (towards the grains), any length.
    pub normal: [f64; 3],
    /// Material name.
    pub material: String,
    /// Prescribed velocity: constant `[vx, vy, vz]` or a table (driven plane).
    #[serde(default)]
    pub velocity: Option<VelocitySpec>,
    /// Prescribed oscillation amplitude (driven plane).
    #[serde(default)]
    pub amplitude: Option<[Length; 3]>,
    /// Oscillation frequency.
    #[serde(default)]
    pub frequency: Option<Frequency>,
}

/// The `velocity` key of a driven body: a constant `[vx, vy, vz]`, or a
/// piecewise-linear table `{ times = [...], values = [[vx, vy, vz], ...] }`, or a CSV
/// file of such a table `{ file = "cycle.csv" }`.
#[derive(Debug, Clone, PartialEq)]
pub enum VelocitySpec {
    /// A constant velocity.
    Constant([Velocity; 3]),
    /// A piecewise-linear table.
    Table(TableSpec),
}

/// A velocity table in the scene.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableSpec {
    /// Breakpoint times (strictly increasing).
    #[serde(default)]
    pub times: Option<Vec<Time>>,
    /// One velocity per time.
    #[serde(default)]
    pub values: Option<Vec<[Velocity; 3]>>,
    /// A CSV file of rows `t, vx, vy, vz` (SI units), relative to the scene file.
    #[serde(default)]
    pub file: Option<PathBuf>,
}

impl<'de> Deserialize<'de> for VelocitySpec {
    fn deserialize<D: serde::Deserializer<'de>>(
        deserializer: D,
    ) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = VelocitySpec;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str(
                    "a velocity [vx, vy, vz] or a table { times = [...], values = [[vx, vy, vz], ...] } \
                     or { file = \"table.csv\" }",
                )
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                seq: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                let v = <[Velocity; 3]>::deserialize(
                    serde::de::value::SeqAccessDeserializer::new(seq),
                )?;
                Ok(VelocitySpec::Constant(v))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                let t = TableSpec::deserialize(serde::de::value::MapAccessDeserializer::new(map))?;
                Ok(VelocitySpec::Table(t))
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

impl<'de> Deserialize<'de> for Pieces {
    fn deserialize<D: serde::Deserializer<'de>>(
        deserializer: D,
    ) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = Pieces;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("\"volumes\", \"hull\" or a list of physical group names")
            }
            fn visit_str<E: serde::de::Error>(
                self,
                v: &str,
            ) -> std::result::Result<Self::Value, E> {
                match v {
                    "volumes" => Ok(Pieces::Volumes),
                    "hull" => Ok(Pieces::Hull),
                    other => Err(E::custom(format!(
                        "\"{other}\" is not \"volumes\" or \"hull\" (or give a list of physical groups)"
                    ))),
                }
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                seq: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                let names =
                    Vec::<String>::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))?;
                Ok(Pieces::Groups(names))
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

/// `[[box]]`: a cuboid that follows a prescribed motion (static without one).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// Name.
    pub name: String,
    /// Edge lengths along the box's own axes.
    pub size: [Length; 3],
    /// Centre at t = 0.
    pub centre: [Length; 3],
    /// Rotations about x, then y, then z (fixed axes).
    #[serde(default)]
    pub orientation: Option<[Angle; 3]>,
    /// Material name.
    pub material: String,
    /// Prescribed velocity (constant or table).
    #[serde(default)]
    pub velocity: Option<VelocitySpec>,
    /// Prescribed oscillation amplitude.
    #[serde(default)]
    pub amplitude: Option<[Length; 3]>,
    /// Oscillation frequency.
    #[serde(default)]
    pub frequency: Option<Frequency>,
}

/// `[[driven]]`: a rigid body from a tetra mesh, as infinite-mass convex pieces that
/// share one prescribed motion (static without one).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DrivenSpec {
    /// Name (pieces get `name/piece` when there are several).
    pub name: String,
    /// The `.msh` file, relative to the scene file.
    pub mesh: PathBuf,
    /// How the mesh is cut into convex pieces.
    #[serde(default)]
    pub convex: Pieces,
    /// Uniform scale applied to the mesh coordinates.
    #[serde(default = "unit_scale")]
    pub scale: f64,
    /// Rotations about x, then y, then z (fixed axes), applied after the scale.
    #[serde(default)]
    pub orientation: Option<[Angle; 3]>,
    /// Where the mesh's origin goes (applied last).
    #[serde(default)]
    pub position: Option<[Length; 3]>,
    /// Material name.
    pub material: String,
    /// Prescribed velocity (constant or table).
    #[serde(default)]
    pub velocity: Option<VelocitySpec>,
    /// Prescribed oscillation amplitude.
    #[serde(default)]
    pub amplitude: Option<[Length; 3]>,
    /// Oscillation frequency.
    #[serde(default)]
    pub frequency: Option<Frequency>,
}

fn unit_scale() -> f64 {
    1.0
}

/// `[[block]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlockSpec {
    /// Name (copies get `name_0`, `name_1` …).
    pub name: String,
    /// Edge lengths.
    pub size: [Length; 3],
    /// Centre of the first copy.
    pub position: [Length; 3],
    /// Material name.
    pub material: String,
    /// Copies.
    #[serde(default = "one")]
    pub count: usize,
    /// Offset between copies (default: stacked, the block height along z).
    #[serde(default)]
    pub step: Option<[Length; 3]>,
    /// Alternating offset ± (x, y) of odd and even copies.
    #[serde(default)]
    pub stagger: Option<[Length; 2]>,
    /// Initial velocity.
    #[serde(default)]
    pub velocity: Option<[Velocity; 3]>,
}

fn one() -> usize {
    1
}

/// `[stones]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StonesSpec {
    /// Directory of `stone_*.msh` (relative to the scene file).
    pub directory: PathBuf,
    /// How many stones (the meshes are used in turn).
    pub count: usize,
    /// Material name.
    pub material: String,
    /// Lower corner of the placement box.
    pub region_min: [Length; 3],
    /// Upper corner of the placement box.
    pub region_max: [Length; 3],
    /// Seed of the random orientations.
    #[serde(default = "one_u64")]
    pub seed: u64,
}

fn one_u64() -> u64 {
    1
}

/// `[packing]`: the bodies of a packing file written by `ballast-pack`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PackingSpec {
    /// The packing file (relative to the scene file).
    pub file: PathBuf,
    /// Material of the stones (needs a density).
    pub stone_material: String,
    /// Material of the sleepers (needs a density); without it they are left out.
    #[serde(default)]
    pub sleeper_material: Option<String>,
    /// Material of the container's floor and side walls; without it none is added.
    #[serde(default)]
    pub wall_material: Option<String>,
    /// Start the first step from the packing's contact impulses (its `contacts` file),
    /// when it has them (default true): a bed packed at rest then stays at rest, where
    /// a cold start lets it move by up to a millimetre in its first steps
    /// ([`crate::pack::contacts`]).
    #[serde(default = "crate::scene::yes")]
    pub warm_start: bool,
}

/// `[output]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// VTK frames over the run (besides the initial one); 0 for none.
    #[serde(default = "default_frames")]
    pub frames: usize,
    /// A checkpoint every this many steps, and at the end ([`super::checkpoint`]);
    /// 0 for none.
    #[serde(default = "default_checkpoint_every")]
    pub checkpoint_every: u64,
    /// Also a checkpoint once this much wall time has passed since the last one ("0
    /// s": only by steps; [`crate::output::Cadence`]).
    #[serde(default = "crate::output::default_checkpoint_wall_every")]
    pub checkpoint_wall_every: Time,
}

fn default_checkpoint_every() -> u64 {
    1000
}

fn default_frames() -> usize {
    20
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            frames: default_frames(),
            checkpoint_every: default_checkpoint_every(),
            checkpoint_wall_every: crate::output::default_checkpoint_wall_every(),
        }
    }
}

/// `[analysis]`: what the scene checks.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalysisSpec {
    /// `incline` (a slider and a sticker), `rest` (nothing should move), `deposit` or
    /// `push` (driven bodies push blocks along a floor at their prescribed speed).
    pub kind: String,
    /// The sliding block (incline).
    #[serde(default)]
    pub slider: Option<String>,
    /// The sticking block (incline).
    #[serde(default)]
    pub sticker: Option<String>,
    /// The acceleration is fitted (incline), the push measured (push) after this time.
    #[serde(default)]
    pub after: Option<Time>,
    /// Driven boxes or meshes that push (push), one per pushed block.
    #[serde(default)]
    pub pushers: Option<Vec<String>>,
    /// The pushed blocks (push), in the order of `pushers`.
    #[serde(default)]
    pub pushed: Option<Vec<String>>,
}

/// Analysis kinds.
pub const ANALYSIS_KINDS: [&str; 4] = ["incline", "rest", "deposit", "push"];

impl Validate for NscdScene {
    fn validate(&self, v: &mut Validator) {
        v.positive("time.duration", self.time.duration);
        v.positive("time.dt", self.time.dt);
        v.non_negative(
            "output.checkpoint_wall_every",
            self.output.checkpoint_wall_every,
        );
        v.nested("ddm", &self.ddm);
        v.in_range("time.theta", self.time.theta, 0.5, 1.0);
        if let Some(tol) = self.solver.tolerance {
            v.positive("solver.tolerance", tol);
        }
        v.check(
            "solver",
            self.solver.tolerance.is_some() != self.solver.sweeps.is_some(),
            "give exactly one of tolerance or sweeps",
        );
        if let Some(n) = self.solver.sweeps {
            v.check("solver.sweeps", n > 0, "must be at least 1");
        }
        v.in_range("solver.warm_start", self.solver.warm_start, 0.0, 1.0);
        v.check(
            "solver.max_sweeps",
            self.solver.max_sweeps > 0,
            "must be at least 1",
        );
        v.check(
            "solver.check_every",
            self.solver.check_every > 0,
            "must be at least 1",
        );
        v.non_negative("solver.alert_distance", self.solver.alert_distance);
        if let Some(speed) = self.solver.depenetration_speed {
            v.non_negative("solver.depenetration_speed", speed);
        }
        v.non_negative("gravity.magnitude", self.gravity.magnitude);
        if let Some(a) = self.gravity.incline {
            v.in_range(
                "gravity.incline",
                a,
                -std::f64::consts::FRAC_PI_2,
                std::f64::consts::FRAC_PI_2,
            );
        }
        v.check(
            "material",
            !self.material.is_empty(),
            "give at least one material",
        );
        for (i, m) in self.material.iter().enumerate() {
            v.check(
                &format!("material[{i}].name"),
                !m.name.trim().is_empty(),
                "must not be empty",
            );
            if let Some(d) = m.density {
                v.positive(&format!("material[{i}].density"), d);
            }
            if self.material[..i].iter().any(|o| o.name == m.name) {
                v.fail(
                    &format!("material[{i}].name"),
                    format!("\"{}\" is defined twice", m.name),
                );
            }
        }
        let known = |name: &str| self.material.iter().any(|m| m.name == name);
        let names: Vec<&str> = self.material.iter().map(|m| m.name.as_str()).collect();
        let unknown = |name: &str| {
            format!(
                "unknown material \"{name}\" (defined: {})",
                names.join(", ")
            )
        };
        for (i, f) in self.friction.iter().enumerate() {
            for (k, name) in f.pair.iter().enumerate() {
                v.check(
                    &format!("friction[{i}].pair[{k}]"),
                    known(name),
                    unknown(name),
                );
            }
            v.non_negative(&format!("friction[{i}].mu"), f.mu);
        }
        if let Some(mu) = self.default_friction {
            v.non_negative("default_friction", mu);
        }
        for (i, p) in self.plane.iter().enumerate() {
            v.check(
                &format!("plane[{i}].material"),
                known(&p.material),
                unknown(&p.material),
            );
            let n = Vector3::from(p.normal);
            v.check(
                &format!("plane[{i}].normal"),
                n.iter().all(|x| x.is_finite()) && n.norm() > 0.0,
                "must be a non-zero vector",
            );
            validate_motion(
                v,
                &format!("plane[{i}]"),
                &p.velocity,
                &p.amplitude,
                &p.frequency,
            );
        }
        let mut names: Vec<&str> = Vec::new();
        for (i, b) in self.boxes.iter().enumerate() {
            let key = format!("box[{i}]");
            check_name(v, &key, &b.name, &mut names);
            for k in 0..3 {
                v.positive(&format!("{key}.size[{k}]"), b.size[k]);
                v.finite(&format!("{key}.centre[{k}]"), b.centre[k]);
                if let Some(o) = &b.orientation {
                    v.finite(&format!("{key}.orientation[{k}]"), o[k]);
                }
            }
            v.check(
                &format!("{key}.material"),
                known(&b.material),
                unknown(&b.material),
            );
            validate_motion(v, &key, &b.velocity, &b.amplitude, &b.frequency);
        }
        for (i, d) in self.driven.iter().enumerate() {
            let key = format!("driven[{i}]");
            check_name(v, &key, &d.name, &mut names);
            v.positive(&format!("{key}.scale"), d.scale);
            for k in 0..3 {
                if let Some(p) = &d.position {
                    v.finite(&format!("{key}.position[{k}]"), p[k]);
                }
                if let Some(o) = &d.orientation {
                    v.finite(&format!("{key}.orientation[{k}]"), o[k]);
                }
            }
            if let Pieces::Groups(groups) = &d.convex {
                v.check(
                    &format!("{key}.convex"),
                    !groups.is_empty(),
                    "give at least one physical group (or \"volumes\" or \"hull\")",
                );
            }
            v.check(
                &format!("{key}.material"),
                known(&d.material),
                unknown(&d.material),
            );
            validate_motion(v, &key, &d.velocity, &d.amplitude, &d.frequency);
        }
        let dense = |name: &str| {
            self.material
                .iter()
                .any(|m| m.name == name && m.density.is_some())
        };
        for (i, b) in self.block.iter().enumerate() {
            for k in 0..3 {
                v.positive(&format!("block[{i}].size[{k}]"), b.size[k]);
            }
            v.check(
                &format!("block[{i}].count"),
                b.count > 0,
                "must be at least 1",
            );
            if known(&b.material) {
                v.check(
                    &format!("block[{i}].material"),
                    dense(&b.material),
                    format!("material \"{}\" needs a density for a block", b.material),
                );
            } else {
                v.fail(&format!("block[{i}].material"), unknown(&b.material));
            }
        }
        if let Some(s) = &self.stones {
            v.check("stones.count", s.count > 0, "must be at least 1");
            if known(&s.material) {
                v.check(
                    "stones.material",
                    dense(&s.material),
                    format!("material \"{}\" needs a density for stones", s.material),
                );
            } else {
                v.fail("stones.material", unknown(&s.material));
            }
            for k in 0..3 {
                v.check(
                    &format!("stones.region_max[{k}]"),
                    s.region_max[k].si() > s.region_min[k].si(),
                    "must be above region_min",
                );
            }
        }
        if let Some(p) = &self.packing {
            let with_density = [Some(&p.stone_material), p.sleeper_material.as_ref()];
            for (key, name) in ["packing.stone_material", "packing.sleeper_material"]
                .into_iter()
                .zip(with_density)
            {
                let Some(name) = name else { continue };
                if !known(name) {
                    v.fail(key, unknown(name));
                } else {
                    v.check(
                        key,
                        dense(name),
                        format!("material \"{name}\" needs a density"),
                    );
                }
            }
            if let Some(name) = &p.wall_material {
                v.check("packing.wall_material", known(name), unknown(name));
            }
        }
        if let Some(t) = &self.tamping {
            v.nested("tamping", t);
            v.check(
                "tamping",
                self.packing
                    .as_ref()
                    .is_some_and(|p| p.sleeper_material.is_some()),
                "needs a [packing] with a sleeper_material (the tamped sleeper is one of its sleepers)",
            );
            v.check(
                "tamping.tine_material",
                known(&t.tine_material),
                unknown(&t.tine_material),
            );
        }
        if let Some(a) = &self.analysis {
            v.check(
                "analysis.kind",
                ANALYSIS_KINDS.contains(&a.kind.as_str()),
                format!(
                    "\"{}\" is not one of: {}",
                    a.kind,
                    ANALYSIS_KINDS.join(", ")
                ),
            );
            if a.kind == "incline" {
                let block_name = |n: &Option<String>| {
                    n.as_ref()
                        .is_some_and(|n| self.block.iter().any(|b| &b.name == n && b.count == 1))
                };
                v.check(
                    "analysis.slider",
                    block_name(&a.slider),
                    "must name a single block",
                );
                v.check(
                    "analysis.sticker",
                    block_name(&a.sticker),
                    "must name a single block",
                );
                v.check(
                    "gravity.incline",
                    self.gravity.incline.is_some(),
                    "an incline analysis needs an inclined gravity",
                );
            }
            if a.kind == "push" {
                let pushers = a.pushers.as_deref().unwrap_or(&[]);
                let pushed = a.pushed.as_deref().unwrap_or(&[]);
                v.check(
                    "analysis.pushers",
                    !pushers.is_empty(),
                    "name at least one driven box or mesh",
                );
                v.check(
                    "analysis.pushed",
                    pushed.len() == pushers.len(),
                    format!(
                        "name one block per pusher ({} pushers, {} pushed)",
                        pushers.len(),
                        pushed.len()
                    ),
                );
                for (k, name) in pushers.iter().enumerate() {
                    let moving = |vel: &Option<VelocitySpec>| vel.is_some();
                    v.check(
                        &format!("analysis.pushers[{k}]"),
                        self.boxes
                            .iter()
                            .any(|b| &b.name == name && moving(&b.velocity))
                            || self
                                .driven
                                .iter()
                                .any(|d| &d.name == name && moving(&d.velocity)),
                        format!("\"{name}\" is not a [[box]] or [[driven]] with a velocity"),
                    );
                }
                for (k, name) in pushed.iter().enumerate() {
                    v.check(
                        &format!("analysis.pushed[{k}]"),
                        self.block.iter().any(|b| &b.name == name && b.count == 1),
                        format!("\"{name}\" is not a single [[block]]"),
                    );
                }
                v.check(
                    "gravity.incline",
                    self.gravity.incline.is_none(),
                    "a push analysis measures friction on a level floor (no incline)",
                );
            }
        }
    }
}

/// Records a duplicate or empty body name.
fn check_name<'a>(v: &mut Validator, key: &str, name: &'a str, names: &mut Vec<&'a str>) {
    v.check(
        &format!("{key}.name"),
        !name.trim().is_empty(),
        "must not be empty",
    );
    if names.contains(&name) {
        v.fail(&format!("{key}.name"), format!("\"{name}\" is used twice"));
    }
    names.push(name);
}

/// Checks the motion keys of a driven body `key` (`plane[0]`, `box[1]` …).
fn validate_motion(
    v: &mut Validator,
    key: &str,
    velocity: &Option<VelocitySpec>,
    amplitude: &Option<[Length; 3]>,
    frequency: &Option<Frequency>,
) {
    match velocity {
        None => {}
        Some(VelocitySpec::Constant(c)) => {
            for (k, x) in c.iter().enumerate() {
                v.finite(&format!("{key}.velocity[{k}]"), *x);
            }
        }
        Some(VelocitySpec::Table(t)) => match (&t.times, &t.values, &t.file) {
            (None, None, Some(_)) => {}
            (Some(times), Some(values), None) => {
                let table = VelocityTable::new(
                    times.iter().map(|t| t.si()).collect(),
                    values.iter().map(velocity_vector).collect(),
                );
                if let Err(reason) = table {
                    v.fail(&format!("{key}.velocity"), reason);
                }
            }
            _ => v.fail(
                &format!("{key}.velocity"),
                "a table needs both times and values, or a file (not both)",
            ),
        },
    }
    if let Some(a) = amplitude {
        for (k, x) in a.iter().enumerate() {
            v.finite(&format!("{key}.amplitude[{k}]"), *x);
        }
        v.check(
            &format!("{key}.frequency"),
            frequency.is_some_and(|f| f.si() > 0.0 && f.si().is_finite()),
            "an oscillation (amplitude) needs a positive frequency",
        );
    }
}

fn velocity_vector(v: &[Velocity; 3]) -> Vector3<f64> {
    Vector3::new(v[0].si(), v[1].si(), v[2].si())
}

/// The prescribed motion of a driven body `key` (reads a table's CSV file): static when
/// it has neither velocity nor oscillation.
fn prescribed_motion(
    scene_path: &Path,
    key: &str,
    velocity: &Option<VelocitySpec>,
    amplitude: &Option<[Length; 3]>,
    frequency: &Option<Frequency>,
) -> Result<Motion> {
    let mut prescribed = Prescribed {
        amplitude: amplitude.as_ref().map_or(Vector3::zeros(), vec3),
        frequency: frequency.map_or(0.0, Frequency::si),
        ..Prescribed::default()
    };
    match velocity {
        None => {}
        Some(VelocitySpec::Constant(c)) => prescribed.velocity = velocity_vector(c),
        Some(VelocitySpec::Table(t)) => {
            let table = match (&t.times, &t.values, &t.file) {
                (_, _, Some(file)) => {
                    VelocityTable::read_csv(&NscdScene::resolve(scene_path, file)).map_err(|e| {
                        Error::invalid(scene_path, format!("key {key}.velocity.file: {e}"))
                    })?
                }
                (Some(times), Some(values), None) => VelocityTable::new(
                    times.iter().map(|t| t.si()).collect(),
                    values.iter().map(velocity_vector).collect(),
                )
                .map_err(|e| Error::invalid(scene_path, format!("key {key}.velocity: {e}")))?,
                _ => {
                    return Err(Error::invalid(
                        scene_path,
                        format!("key {key}.velocity: a table needs both times and values"),
                    ))
                }
            };
            prescribed = prescribed.with_table(table);
        }
    }
    Ok(if prescribed.is_rest() {
        Motion::Static
    } else {
        Motion::Driven(prescribed)
    })
}

/// A rotation about x, then y, then z (fixed axes).
fn rotation(angles: &Option<[Angle; 3]>) -> UnitQuaternion<f64> {
    angles.map_or(UnitQuaternion::identity(), |a| {
        UnitQuaternion::from_euler_angles(a[0].si(), a[1].si(), a[2].si())
    })
}

/// The bodies and tables a scene builds.
#[derive(Debug, Clone)]
pub struct Model {
    /// Every body: planes first, then boxes, driven meshes' pieces, blocks, stones, and
    /// a packing's walls, sleepers and stones.
    pub bodies: Vec<Body>,
    /// µ per material pair.
    pub friction: FrictionTable,
    /// Equivalent-sphere diameters of the stones (m), in body order.
    pub stone_diameters: Vec<f64>,
    /// The boxes and driven meshes, each with its bodies (one per convex piece).
    pub driven: Vec<DrivenBody>,
    /// The tamping cycle's sleeper, tines, phases and control boxes.
    pub tamping: Option<super::tamping::TampingPlan>,
    /// Periodicity along the track, from a `"periodic"` packing.
    pub period: Option<Period>,
    /// A packing's contact impulses and where its bodies are, for a warm first step.
    pub warm_start: Option<(Vec<PackedContact>, PackedLayout)>,
}

/// A `[[box]]` or `[[driven]]` of the scene and the bodies it became.
#[derive(Debug, Clone, PartialEq)]
pub struct DrivenBody {
    /// The scene's name.
    pub name: String,
    /// Indices into [`Model::bodies`] of its pieces.
    pub pieces: Vec<usize>,
}

fn vec3(v: &[Length; 3]) -> Vector3<f64> {
    Vector3::new(v[0].si(), v[1].si(), v[2].si())
}

impl NscdScene {
    /// A path of the scene resolved against the scene file's directory.
    pub fn resolve(scene_path: &Path, path: &Path) -> PathBuf {
        if path.is_absolute() {
            path.to_path_buf()
        } else {
            scene_path.parent().unwrap_or(Path::new(".")).join(path)
        }
    }

    fn material_index(&self, name: &str) -> u32 {
        self.material
            .iter()
            .position(|m| m.name == name)
            .unwrap_or(0) as u32
    }

    fn density(&self, name: &str) -> f64 {
        self.material
            .iter()
            .find(|m| m.name == name)
            .and_then(|m| m.density)
            .map_or(0.0, Density::si)
    }

    /// Builds the bodies (reading stone meshes) and the friction table.
    pub fn build(&self, scene_path: &Path) -> Result<Model> {
        let mut friction =
            FrictionTable::uniform(self.material.len(), self.default_friction.unwrap_or(0.0));
        for f in &self.friction {
            friction.set(
                self.material_index(&f.pair[0]),
                self.material_index(&f.pair[1]),
                f.mu,
            );
        }
        let mut bodies = Vec::new();
        for (i, p) in self.plane.iter().enumerate() {
            let normal = Unit::new_normalize(Vector3::from(p.normal));
            let shape = Arc::new(BodyShape::half_space(normal));
            let motion = prescribed_motion(
                scene_path,
                &format!("plane[{i}]"),
                &p.velocity,
                &p.amplitude,
                &p.frequency,
            )?;
            bodies.push(Body::fixed(
                &p.name,
                shape,
                self.material_index(&p.material),
                Isometry3::translation(p.point[0].si(), p.point[1].si(), p.point[2].si()),
                motion,
            ));
        }
        let mut driven = Vec::new();
        for (i, b) in self.boxes.iter().enumerate() {
            let key = format!("box[{i}]");
            let motion =
                prescribed_motion(scene_path, &key, &b.velocity, &b.amplitude, &b.frequency)?;
            let shape = BodyShape::cuboid(vec3(&b.size))
                .map_err(|e| Error::invalid(scene_path, format!("key {key}.size: {e}")))?;
            driven.push(DrivenBody {
                name: b.name.clone(),
                pieces: vec![bodies.len()],
            });
            bodies.push(Body::fixed(
                &b.name,
                Arc::new(shape),
                self.material_index(&b.material),
                Isometry3::from_parts(
                    Translation3::from(vec3(&b.centre)),
                    rotation(&b.orientation),
                ),
                motion,
            ));
        }
        for (i, d) in self.driven.iter().enumerate() {
            let key = format!("driven[{i}]");
            let motion =
                prescribed_motion(scene_path, &key, &d.velocity, &d.amplitude, &d.frequency)?;
            let pieces = driven_pieces(scene_path, &key, d)?;
            let several = pieces.len() > 1;
            let mut indices = Vec::with_capacity(pieces.len());
            for (piece, principal) in pieces {
                let name = if several {
                    format!("{}/{piece}", d.name)
                } else {
                    d.name.clone()
                };
                indices.push(bodies.len());
                bodies.push(Body::fixed(
                    &name,
                    Arc::new(principal.shape),
                    self.material_index(&d.material),
                    principal.pose,
                    motion.clone(),
                ));
            }
            driven.push(DrivenBody {
                name: d.name.clone(),
                pieces: indices,
            });
        }
        // A driven body starts at its prescribed velocity: the step's position update
        // uses the velocity at the start of the step.
        for body in &mut bodies {
            if let Motion::Driven(prescribed) = &body.motion {
                body.velocity = prescribed.velocity_at(0.0);
            }
        }
        for b in &self.block {
            let size = vec3(&b.size);
            let shape = Arc::new(BodyShape::cuboid(size)?);
            let step = b.step.as_ref().map_or(Vector3::new(0.0, 0.0, size.z), vec3);
            let stagger = b.stagger.map_or(Vector3::zeros(), |s| {
                Vector3::new(s[0].si(), s[1].si(), 0.0)
            });
            for k in 0..b.count {
                let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                let centre = vec3(&b.position) + k as f64 * step + sign * stagger;
                let name = if b.count == 1 {
                    b.name.clone()
                } else {
                    format!("{}_{k}", b.name)
                };
                let mut body = Body::dynamic(
                    &name,
                    shape.clone(),
                    self.density(&b.material),
                    self.material_index(&b.material),
                    Isometry3::from_parts(Translation3::from(centre), UnitQuaternion::identity()),
                );
                if let Some(v) = b.velocity {
                    body.velocity = Vector3::new(v[0].si(), v[1].si(), v[2].si());
                }
                bodies.push(body);
            }
        }
        let mut stone_diameters = Vec::new();
        let mut tamping = None;
        let mut period = None;
        let mut warm_start = None;
        if let Some(s) = &self.stones {
            let (placed, diameters) = place_stones(self, s, scene_path)?;
            bodies.extend(placed);
            stone_diameters = diameters;
        }
        if let Some(p) = &self.packing {
            let file = Self::resolve(scene_path, &p.file);
            let packing = crate::pack::Packing::read(&file)?;
            if let Some(note) = packing.unsettled_note("ballast-nscd", &file) {
                println!("{note}");
            }
            period = packing.period();
            let stuff = |name: &str| super::packed::Stuff {
                material: self.material_index(name),
                density: self.density(name),
            };
            let packed = super::packed::packed_bodies(
                &file,
                &packing,
                &super::packed::PackedMaterials {
                    stones: stuff(&p.stone_material),
                    sleepers: p.sleeper_material.as_deref().map(stuff),
                    walls: p.wall_material.as_deref().map(|m| self.material_index(m)),
                },
            )?;
            let layout = PackedLayout {
                offset: bodies.len(),
                ..packed.layout
            };
            if let (true, Some(csv)) = (p.warm_start, &packing.contacts) {
                let contacts = crate::pack::contacts::read_contacts(csv)?;
                crate::pack::contacts::check_contacts(csv, &contacts, &packing)?;
                warm_start = Some((contacts, layout));
            }
            bodies.extend(packed.bodies);
            stone_diameters.extend(packed.stone_diameters);
            if let Some(t) = &self.tamping {
                let plan = super::tamping::build(
                    t,
                    scene_path,
                    &packing,
                    self.material_index(&t.tine_material),
                    &mut bodies,
                )?;
                tamping = Some(plan);
            }
        }
        Ok(Model {
            bodies,
            friction,
            stone_diameters,
            driven,
            tamping,
            period,
            warm_start,
        })
    }
}

/// The convex pieces of a `[[driven]]` mesh in world coordinates (scaled, rotated,
/// placed), each in its principal frame.
fn driven_pieces(
    scene_path: &Path,
    key: &str,
    spec: &DrivenSpec,
) -> Result<Vec<(String, PrincipalShape)>> {
    let file = NscdScene::resolve(scene_path, &spec.mesh);
    let mesh = crate::mesh::read_msh(&file)
        .map_err(|e| Error::invalid(scene_path, format!("key {key}.mesh: {e}")))?;
    let pieces = mesh_pieces(&mesh, &spec.convex)
        .map_err(|e| Error::invalid(scene_path, format!("key {key}.convex: {e}")))?;
    let rotation = rotation(&spec.orientation);
    let shift = spec.position.as_ref().map_or(Vector3::zeros(), vec3);
    let mut out = Vec::with_capacity(pieces.len());
    for (name, points) in pieces {
        let world: Vec<Point3<f64>> = points
            .iter()
            .map(|p| Point3::from(rotation * (spec.scale * p.coords) + shift))
            .collect();
        let what = format!("key {key}.convex: piece \"{name}\" of {}", file.display());
        let principal = BodyShape::convex_hull(&world, &what).map_err(|e| match e {
            Error::Message(m) => Error::invalid(scene_path, m),
            e => e,
        })?;
        out.push((name, principal));
    }
    Ok(out)
}

/// A stone of the family: its mesh file, its convex hull in the principal frame, and
/// where that frame lies in the mesh's coordinates (mesh point = `mesh_pose` · local).
#[derive(Debug, Clone)]
pub struct StoneShape {
    /// The mesh file.
    pub file: PathBuf,
    /// The hull in its principal frame.
    pub shape: Arc<BodyShape>,
    /// The principal frame in the (scaled) mesh coordinates.
    pub mesh_pose: Isometry3<f64>,
    /// The factor applied to the mesh coordinates.
    pub scale: f64,
    /// The mesh's surface nodes (scaled mesh coordinates): where
    /// [`StoneShape::with_vertex_spheres`] centres its spheres.
    pub surface: Arc<[Point3<f64>]>,
}

impl StoneShape {
    /// Equivalent-sphere diameter (6V/π)^(1/3) (m).
    pub fn diameter(&self) -> f64 {
        (6.0 * self.shape.volume / std::f64::consts::PI).cbrt()
    }

    /// The bounding radius about the mass centre (m), rounding included.
    pub fn radius(&self) -> f64 {
        self.shape.bounding_radius()
    }

    /// The rounding of its hull (m; 0 for the bare hull and for vertex spheres).
    pub fn round(&self) -> f64 {
        self.shape.collider.hull().map_or(0.0, ConvexShape::round)
    }

    /// The diameter of its vertex spheres (m; 0 without).
    pub fn spheres(&self) -> f64 {
        self.shape.collider.sphere_diameter()
    }

    /// The same stone with its collider swept by a sphere of radius `round` (m; see
    /// [`crate::contact::ConvexShape::rounded`]). Mass and inertia stay the hull's: the
    /// rounding stands for the contact spheres at the vertices of seed 004's stones,
    /// which add no mass.
    pub fn rounded(mut self, round: f64) -> Self {
        if let Collider::Convex(hull) = &self.shape.collider {
            let mut shape = (*self.shape).clone();
            shape.collider = Collider::Convex(hull.clone().rounded(round));
            self.shape = Arc::new(shape);
        }
        self
    }

    /// The same stone with spheres of `diameter` (m) at every surface node of its mesh
    /// as its contact shape (seed 004's QDEM contact spheres; 0 leaves it as it is).
    /// Mass and inertia stay the hull's.
    pub fn with_vertex_spheres(mut self, diameter: f64) -> Self {
        if diameter > 0.0 {
            let to_local = self.mesh_pose.inverse();
            let centres = self.surface.iter().map(|p| to_local * p).collect();
            let mut shape = (*self.shape).clone();
            if let Some(spheres) = shape.collider.with_spheres(centres, 0.5 * diameter) {
                shape.collider = spheres;
                self.shape = Arc::new(shape);
            }
        }
        self
    }

    /// Stone number `k` of this shape as a dynamic body, named `<mesh stem>#k`, its
    /// principal frame at `pose`.
    pub fn body(&self, k: usize, density: f64, material: u32, pose: Isometry3<f64>) -> Body {
        let name = self
            .file
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("stone");
        Body::dynamic(
            &format!("{name}#{k}"),
            self.shape.clone(),
            density,
            material,
            pose,
        )
    }
}

/// Reads the stone meshes of `directory` (sorted `stone_*.msh`) as convex hulls, their
/// coordinates multiplied by `scale`.
pub fn read_stone_shapes(directory: &Path, scale: f64) -> Result<Vec<StoneShape>> {
    let entries = std::fs::read_dir(directory).map_err(|e| Error::io(directory, e))?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("stone_") && n.ends_with(".msh"))
        })
        .collect();
    files.sort();
    files.iter().map(|f| read_stone_shape(f, scale)).collect()
}

/// Reads one stone mesh as the convex hull of its boundary corners (all boundary nodes
/// when it has fewer than four corners), coordinates multiplied by `scale`.
pub fn read_stone_shape(file: &Path, scale: f64) -> Result<StoneShape> {
    let mesh = crate::mesh::read_msh(file)?;
    let corners = crate::geometry::corner_vertices(&mesh.nodes, &mesh.boundary);
    let points: Vec<Point3<f64>> = if corners.len() >= 4 {
        corners
            .iter()
            .map(|&i| mesh.nodes[i as usize] * scale)
            .collect()
    } else {
        let mut nodes: Vec<u32> = mesh.boundary.iter().flatten().copied().collect();
        nodes.sort_unstable();
        nodes.dedup();
        nodes
            .iter()
            .map(|&i| mesh.nodes[i as usize] * scale)
            .collect()
    };
    let principal = BodyShape::convex_hull(&points, &file.display().to_string())?;
    let surface = mesh
        .surface_nodes()
        .iter()
        .map(|&i| mesh.nodes[i as usize] * scale)
        .collect();
    Ok(StoneShape {
        file: file.to_path_buf(),
        shape: Arc::new(principal.shape),
        mesh_pose: principal.pose,
        scale,
        surface,
    })
}

fn place_stones(
    scene: &NscdScene,
    spec: &StonesSpec,
    scene_path: &Path,
) -> Result<(Vec<Body>, Vec<f64>)> {
    let directory = NscdScene::resolve(scene_path, &spec.directory);
    let shapes = read_stone_shapes(&directory, 1.0)?;
    if shapes.is_empty() {
        return Err(Error::invalid(
            scene_path,
            format!(
                "key stones.directory: no stone_*.msh in {} (make meshes builds them)",
                directory.display()
            ),
        ));
    }
    let radius = shapes.iter().map(StoneShape::radius).fold(0.0, f64::max);
    let spacing = 2.0 * radius * 1.02;
    let lo = vec3(&spec.region_min);
    let hi = vec3(&spec.region_max);
    let cells = (hi - lo).map(|l| (l / spacing).floor().max(0.0) as usize);
    let capacity = cells.x * cells.y * cells.z;
    if capacity < spec.count {
        return Err(Error::invalid(
            scene_path,
            format!(
                "key stones.region_max: the region holds {capacity} stones on a {spacing:.4} m \
                 lattice, fewer than stones.count = {}",
                spec.count
            ),
        ));
    }
    let density = scene.density(&spec.material);
    let material = scene.material_index(&spec.material);
    let mut random = SplitMix(spec.seed);
    let mut bodies = Vec::with_capacity(spec.count);
    let mut diameters = Vec::with_capacity(spec.count);
    for k in 0..spec.count {
        let (ix, iy, iz) = (
            k % cells.x,
            (k / cells.x) % cells.y,
            k / (cells.x * cells.y),
        );
        let centre = lo + spacing * Vector3::new(ix as f64 + 0.5, iy as f64 + 0.5, iz as f64 + 0.5);
        let stone = &shapes[k % shapes.len()];
        diameters.push(stone.diameter());
        bodies.push(stone.body(
            k,
            density,
            material,
            Isometry3::from_parts(Translation3::from(centre), random.rotation()),
        ));
    }
    Ok((bodies, diameters))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::scene_from_str;

    /// A scene file path in the crate's `scenes/` (meshes resolve against it).
    fn scene_path() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/test.toml")
    }

    const BASE: &str = r#"
[time]
duration = "0.1 s"
dt = "1 ms"
[solver]
tolerance = 1e-8
alert_distance = "1 mm"
[[material]]
name = "steel"
[[plane]]
name = "floor"
point = [0, 0, 0]
normal = [0, 0, 1]
material = "steel"
"#;

    fn load(extra: &str) -> Result<NscdScene> {
        scene_from_str(&scene_path(), &format!("{BASE}{extra}"), None).map(|(s, _)| s)
    }

    fn build(extra: &str) -> Result<Model> {
        load(extra)?.build(&scene_path())
    }

    fn message(result: Result<impl std::fmt::Debug>) -> String {
        result.unwrap_err().to_string()
    }

    #[test]
    fn boxes_and_driven_meshes_become_infinite_mass_pieces() {
        let model = build(
            r#"
[[box]]
name = "pusher"
size = ["0.2 m", "0.1 m", "0.1 m"]
centre = [0, 0, "0.5 m"]
orientation = [0, 0, "90 deg"]
material = "steel"
velocity = { times = ["0 s", "0.1 s"], values = [["0.1 m/s", 0, 0], ["0.3 m/s", 0, 0]] }

[[box]]
name = "wall"
size = ["0.1 m", "1 m", "1 m"]
centre = ["2 m", 0, 0]
material = "steel"

[[driven]]
name = "cube"
mesh = "../tests/fixtures/cube_tet4_100.msh"
scale = 0.1
position = ["1 m", 0, 0]
material = "steel"
velocity = [0, 0, "-1 m/s"]
amplitude = [0, 0, "1 mm"]
frequency = "50 Hz"
"#,
        )
        .unwrap();
        assert_eq!(model.bodies.len(), 4);
        let names: Vec<&str> = model.driven.iter().map(|d| d.name.as_str()).collect();
        assert_eq!(names, ["pusher", "wall", "cube"]);
        assert_eq!(model.driven[2].pieces, [3]);
        // The rotated box: its long axis along y.
        let pusher = &model.bodies[1];
        let extent_y = pusher
            .world_vertices()
            .iter()
            .map(|p| p.y)
            .fold(0.0, f64::max);
        assert!((extent_y - 0.1).abs() < 1e-12, "{extent_y}");
        assert!(pusher.mass.is_infinite() && pusher.inverse_mass() == 0.0);
        // A table motion starts at its first value, interpolates, holds.
        let Motion::Driven(p) = &pusher.motion else {
            panic!("{:?}", pusher.motion)
        };
        assert_eq!(pusher.velocity, Vector3::new(0.1, 0.0, 0.0));
        assert!((p.velocity_at(0.05).x - 0.2).abs() < 1e-15);
        assert_eq!(p.velocity_at(1.0).x, 0.3);
        assert!((p.displacement(0.0, 0.2).x - (0.02 + 0.03)).abs() < 1e-15);
        // No motion keys: static.
        assert_eq!(model.bodies[2].motion, Motion::Static);
        // The mesh (unit cube) scaled by 0.1 and moved: one piece, its hull.
        let cube = &model.bodies[3];
        assert!((cube.shape.volume - 1e-3).abs() < 1e-15);
        assert!((cube.position - Vector3::new(1.05, 0.05, 0.05)).norm() < 1e-12);
        let Motion::Driven(p) = &cube.motion else {
            panic!()
        };
        let omega = std::f64::consts::TAU * 50.0;
        assert!((cube.velocity.z - (-1.0 + 1e-3 * omega)).abs() < 1e-12);
        assert!(p.table.is_none());
    }

    #[test]
    fn mesh_groups_give_pieces_and_bad_keys_name_themselves() {
        let driven = |convex: &str| {
            format!(
                "[[driven]]\nname = \"cube\"\nmesh = \"../tests/fixtures/cube_tet4_100.msh\"\n\
                 material = \"steel\"\nconvex = {convex}\n"
            )
        };
        // "hull" and the single volume group "cube" give the same unit cube.
        for convex in ["\"hull\"", "\"volumes\"", "[\"cube\"]"] {
            let model = build(&driven(convex)).unwrap();
            assert_eq!(model.bodies.len(), 2, "{convex}");
            assert!(
                (model.bodies[1].shape.volume - 1.0).abs() < 1e-12,
                "{convex}"
            );
        }
        let err = message(build(&driven("[\"tip\"]")));
        assert!(
            err.contains("test.toml: key driven[0].convex: physical group \"tip\""),
            "{err}"
        );
        // A surface group alone is flat: a degenerate hull, refused with the key.
        let err = message(build(&driven("[\"left\"]")));
        assert!(
            err.contains("key driven[0].convex: piece \"left\""),
            "{err}"
        );
        let err = message(build(&driven("\"halves\"")));
        assert!(err.contains("key driven[0].convex"), "{err}");
        let err = message(build(&driven("[]")));
        assert!(err.contains("key driven[0].convex"), "{err}");
        let missing = driven("\"hull\"").replace("cube_tet4_100", "nothing");
        let err = message(build(&missing));
        assert!(err.contains("test.toml: key driven[0].mesh: "), "{err}");
    }

    #[test]
    fn bad_motions_are_refused_with_their_key() {
        let with_box = |velocity: &str| {
            format!(
                "[[box]]\nname = \"b\"\nsize = [1, 1, 1]\ncentre = [0, 0, 2]\n\
                 material = \"steel\"\n{velocity}\n"
            )
        };
        for (velocity, key) in [
            (
                "velocity = { times = [0, 0], values = [[0, 0, 0], [1, 0, 0]] }",
                "key box[0].velocity: times must increase strictly",
            ),
            (
                "velocity = { times = [0, 1], values = [[0, 0, 0]] }",
                "key box[0].velocity: 2 times but 1 values",
            ),
            (
                "velocity = { times = [0, 1] }",
                "key box[0].velocity: a table needs both",
            ),
            (
                "velocity = { times = [0], values = [[0, 0, 0]], speed = 1 }",
                "unknown key box[0].velocity.speed",
            ),
            ("velocity = \"fast\"", "key box[0].velocity: invalid type"),
            (
                "velocity = [\"1 m\", 0, 0]",
                "key box[0].velocity[0]: unit \"m\" is not a velocity",
            ),
            (
                "amplitude = [0, 0, \"1 mm\"]",
                "key box[0].frequency: an oscillation",
            ),
        ] {
            let err = message(load(&with_box(velocity)));
            assert!(err.contains(key), "{velocity}: {err}");
            assert!(
                err.starts_with(&scene_path().display().to_string()),
                "{err}"
            );
        }
        let err = message(load(
            &with_box("").replace("size = [1, 1, 1]", "size = [1, -1, 1]"),
        ));
        assert!(
            err.contains("key box[0].size[1]: must be positive"),
            "{err}"
        );
        let twice = format!("{}{}", with_box(""), with_box(""));
        assert!(message(load(&twice)).contains("key box[1].name: \"b\" is used twice"));
        // A CSV table: read at build, its errors name the key and the line.
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("cycle.csv");
        std::fs::write(&csv, "t,vx,vy,vz\n0,0,0,0\n0.1,1,0\n").unwrap();
        let file = format!("velocity = {{ file = \"{}\" }}", csv.display());
        let err = message(build(&with_box(&file)));
        assert!(
            err.contains("key box[0].velocity.file: ") && err.contains("line 3: 3 numbers"),
            "{err}"
        );
        std::fs::write(&csv, "0,0,0,0\n0.1,1,0,0\n").unwrap();
        let model = build(&with_box(&file)).unwrap();
        let Motion::Driven(p) = &model.bodies[1].motion else {
            panic!()
        };
        assert!((p.velocity_at(0.05).x - 0.5).abs() < 1e-15);
    }
}
