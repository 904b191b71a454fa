//! The track-impact scene of `ballast-qdem` (seed 004 §4): a `ballast-pack` packing
//! (stones and one sleeper) turned into QDEM and rigid bodies with vertex spheres,
//! settled under gravity, then loaded through the rail seats by a `time_s,Rp1,Rp2` CSV.
//!
//! ```toml
//! [track]
//! packing = "../results/bed-impact/packing.toml"
//! loads = "../results/train_load.csv"   # time_s,Rp1,Rp2 (N), t = 0 at the end of settling
//! stones = "rigid"                      # rigid | deformable | near
//! deformable_within = "0.15 m"          # near: stones this close to the sleeper deform
//! periodic = "x"                        # along the track (the packing's x), or "none"
//! settle = "20 ms"                      # gravity, damped; the loads ramp to their first row
//! duration = "0.2 s"                    # loaded time
//! dt = "auto"                           # or a time; auto = dt_factor × stable
//! dt_factor = 0.5
//! sphere_diameter = "24 mm"
//! skin = "0.5 mm"                     # Verlet skin: a cost setting (docs/track.md)
//! rigid_damping_ratio = 0.02
//! sample_rate = "10 kHz"
//! frames = 4
//! checkpoint_every = 50000              # steps; 0 for none (resume: --resume DIR)
//! checkpoint_wall_every = "30 min"      # and after this much wall time ("0 s": off)
//!
//! [ballast]            # material + DEM springs (seed 004 Table 1)
//! [sleeper]
//! [rail]               # longitudinal, lateral: the rails' hold per rail seat (N/m)
//! [[sensor]]           # name, on = "sleeper" | "stone", at = sleeper-mesh coordinates
//! ```

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::scene::{Frequency, Length, Material, Stiffness, Time, Validate, Validator};

/// A whole track-impact scene.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackScene {
    /// The run.
    pub track: TrackSpec,
    /// Ballast stones: material and springs.
    pub ballast: BodyMaterial,
    /// The sleeper: material and springs.
    pub sleeper: BodyMaterial,
    /// The rigid base and walls: springs.
    pub base: Springs,
    /// Friction coefficients.
    #[serde(default)]
    pub friction: FrictionSpec,
    /// The rails' hold on the sleeper's rail seats along and across the track.
    #[serde(default)]
    pub rail: RailSpec,
    /// Acceleration and displacement sensors (seed 004 Figure 6).
    #[serde(default)]
    pub sensor: Vec<SensorSpec>,
}

/// How stones are modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StoneModel {
    /// Every stone a 6-DOF rigid body with vertex spheres.
    Rigid,
    /// Every stone a QDEM tetra body.
    Deformable,
    /// QDEM within `deformable_within` of the sleeper, rigid beyond.
    Near,
}

/// Periodicity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Periodic {
    /// Walls of the packing's container on every side.
    None,
    /// Periodic along x (the track direction of a packing), walls across.
    X,
    /// Periodic along y.
    Y,
}

/// The `[track]` table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackSpec {
    /// The packing file (relative to the scene).
    pub packing: PathBuf,
    /// Rail-seat loads `time_s,Rp1,Rp2` (N, compressive positive), relative to the scene;
    /// none: gravity only.
    #[serde(default)]
    pub loads: Option<PathBuf>,
    /// Stone model.
    #[serde(default = "default_stones")]
    pub stones: StoneModel,
    /// For `near`: stones whose centre lies within this distance of the sleeper's
    /// bounding box deform.
    #[serde(default)]
    pub deformable_within: Option<Length>,
    /// Periodic direction.
    #[serde(default = "default_periodic")]
    pub periodic: Periodic,
    /// Settling time before the load record's t = 0: gravity, damped, with the loads
    /// ramping from 0 to the record's first row.
    pub settle: Time,
    /// Mass-proportional damping rate α during settling (1/s; none after): the
    /// spheres round the polyhedra's corners off, so the bed first closes mm gaps.
    #[serde(default = "default_settle_damping")]
    pub settle_damping: Frequency,
    /// Loaded time after settling.
    pub duration: Time,
    /// Time step: "auto" or a time.
    #[serde(default)]
    pub dt: Option<DtSpec>,
    /// Safety factor on the stable step for `dt = "auto"`.
    #[serde(default = "default_dt_factor")]
    pub dt_factor: f64,
    /// Where the spheres sit: on the vertices (seed 004; the default) or inset into
    /// the polyhedron so that their envelope is the polyhedron with rounded corners.
    #[serde(default = "default_centres")]
    pub sphere_centres: SphereCentres,
    /// How the sphere pairs that overlap when the packing is read carry load:
    /// `each` (the default: every pair a full spring) or `shared` (the pairs of one
    /// touching pair of bodies, or of a body and a plane, share one spring's stiffness).
    #[serde(default = "default_rest_pairs")]
    pub rest_pairs: RestPairs,
    /// Diameter of the vertex spheres (seed 004: 24 mm).
    #[serde(default = "default_sphere")]
    pub sphere_diameter: Length,
    /// Verlet skin: sphere pairs closer than r_i + r_j + skin are candidates, and the
    /// list is rebuilt when a sphere has moved half of it. It sets the cost, not the
    /// result (the time step counts the pairs within [`crate::dem::system::STABLE_STEP_GAP`]
    /// whatever the skin); 0.5 mm halves the candidates of 2 mm on the paper bed.
    #[serde(default = "default_skin")]
    pub skin: Length,
    /// Dashpot ratio of contacts involving a rigid body.
    #[serde(default = "default_rigid_damping")]
    pub rigid_damping_ratio: f64,
    /// Sensor sampling rate (seed 004: 10 kHz).
    #[serde(default = "default_rate")]
    pub sample_rate: Frequency,
    /// VTK frames over the run (settling included).
    #[serde(default = "default_frames")]
    pub frames: usize,
    /// A checkpoint (`checkpoint.bin`, for `--resume`) every this many steps and at the
    /// end; 0 for none.
    #[serde(default = "default_checkpoint_every")]
    pub checkpoint_every: u64,
    /// Also a checkpoint once this much wall time has passed since the last one ("0
    /// s": only by steps; [`crate::output::Cadence`]).
    #[serde(default = "crate::output::default_checkpoint_wall_every")]
    pub checkpoint_wall_every: Time,
}

/// Where a body's contact spheres are centred.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SphereCentres {
    /// On the surface vertices (seed 004 §4): the contact shape is the polyhedron
    /// dilated by r. Pairs overlapping when the packing is read (it was made with the
    /// polyhedra) rest at that overlap.
    Vertices,
    /// Inset along the vertex normal so that each sphere lies inside the polyhedron:
    /// the contact shape is the polyhedron with its corners rounded off (by up to 2r),
    /// so the bed first sinks into the gaps this leaves.
    Inset,
}

/// How the sphere pairs resting at their import overlap carry load (`track.rest_pairs`).
///
/// A packing made with the polyhedra puts touching stones closer than their vertex
/// spheres would rest: each touching pair of stones meets through a cluster of
/// overlapping sphere pairs (≈ 57 per stone on the quick bed), every one a full
/// contact spring, so the bed is far stiffer than seed 004's, whose stones met through
/// the one or few sphere pairs a free fall with the spheres leaves (docs/track.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RestPairs {
    /// Every resting pair is a full spring.
    Each,
    /// The n resting pairs of one pair of bodies (or of a body and a plane) each
    /// carry 1/n of their force: together one spring's stiffness per touching pair.
    /// Pairs that meet later are full springs.
    Shared,
}

/// `dt = "auto"` or a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DtSpec {
    /// dt_factor × the stable step.
    Auto,
    /// A given step.
    Fixed(Time),
}

impl<'de> Deserialize<'de> for DtSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        if s.trim() == "auto" {
            Ok(DtSpec::Auto)
        } else {
            Time::parse(&s)
                .map(DtSpec::Fixed)
                .map_err(serde::de::Error::custom)
        }
    }
}

/// A body material and its sphere springs.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyMaterial {
    /// Density, moduli, viscosities.
    pub material: Material,
    /// The vertex spheres' springs.
    pub springs: Springs,
}

/// Normal and tangential spring constants of a material's spheres.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Springs {
    /// k_n.
    pub normal: Stiffness,
    /// k_t.
    pub tangential: Stiffness,
}

/// Friction coefficients per pair of materials (seed 004 Table 1: 0.577 everywhere).
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionSpec {
    /// Stone on stone.
    #[serde(default = "default_mu")]
    pub ballast_ballast: f64,
    /// Stone on sleeper.
    #[serde(default = "default_mu")]
    pub ballast_sleeper: f64,
    /// Stone or sleeper on the base and walls.
    #[serde(default = "default_mu")]
    pub base: f64,
}

impl Default for FrictionSpec {
    fn default() -> Self {
        FrictionSpec {
            ballast_ballast: default_mu(),
            ballast_sleeper: default_mu(),
            base: default_mu(),
        }
    }
}

/// The rails' hold on the sleeper (`[rail]`): at each rail seat, a spring on the seat's
/// mean horizontal displacement along the track (`longitudinal`) and along the sleeper
/// (`lateral`), anchored where the packing left the seat ([`crate::qdem::GroupSpring`]).
///
/// Seed 004 loads the rail seats with measured pressures and models no rail; a sleeper
/// without one slides off the slopes of the stones under it (4.7 mm along the track in
/// the quick run's 0.07 s, docs/track.md). In track the rails, fastened to every
/// sleeper, tie it to its neighbours, so the hold is the fastening's stiffness in series
/// with the rest of the track's, which is far stiffer; 0 frees a direction.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RailSpec {
    /// Along the track, per rail seat.
    #[serde(default = "default_rail_stiffness")]
    pub longitudinal: Stiffness,
    /// Along the sleeper (across the track), per rail seat.
    #[serde(default = "default_rail_stiffness")]
    pub lateral: Stiffness,
}

impl Default for RailSpec {
    fn default() -> Self {
        RailSpec {
            longitudinal: default_rail_stiffness(),
            lateral: default_rail_stiffness(),
        }
    }
}

/// Where a sensor sits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorOn {
    /// The sleeper node nearest `at`.
    Sleeper,
    /// The stone whose centre is nearest `at` (its centre of mass).
    Stone,
}

/// One sensor.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorSpec {
    /// Name (CSV column prefix).
    pub name: String,
    /// Sleeper or stone.
    pub on: SensorOn,
    /// Position in the sleeper mesh's coordinates (m).
    pub at: [Length; 3],
}

fn default_rest_pairs() -> RestPairs {
    RestPairs::Each
}
fn default_centres() -> SphereCentres {
    SphereCentres::Vertices
}
fn default_stones() -> StoneModel {
    StoneModel::Rigid
}
fn default_periodic() -> Periodic {
    Periodic::X
}
fn default_dt_factor() -> f64 {
    0.5
}
fn default_sphere() -> Length {
    Length::from_si(0.024)
}
fn default_skin() -> Length {
    Length::from_si(0.0005)
}
fn default_rigid_damping() -> f64 {
    0.02
}
fn default_rate() -> Frequency {
    Frequency::from_si(10e3)
}
fn default_settle_damping() -> Frequency {
    Frequency::from_si(200.0)
}
fn default_frames() -> usize {
    4
}
fn default_checkpoint_every() -> u64 {
    50_000
}
fn default_rail_stiffness() -> Stiffness {
    Stiffness::from_si(20e6)
}
fn default_mu() -> f64 {
    0.577
}

impl TrackScene {
    /// A path of the scene resolved against the scene file's directory.
    pub fn resolve(scene_path: &Path, file: &Path) -> PathBuf {
        crate::solid::scene::SolidScene::resolve(scene_path, file)
    }
}

impl Validate for TrackScene {
    fn validate(&self, v: &mut Validator) {
        let t = &self.track;
        v.non_negative("track.settle", t.settle);
        v.non_negative("track.settle_damping", t.settle_damping);
        v.non_negative("track.checkpoint_wall_every", t.checkpoint_wall_every);
        v.positive("track.duration", t.duration);
        if let Some(DtSpec::Fixed(dt)) = t.dt {
            v.positive("track.dt", dt);
        }
        v.check(
            "track.dt_factor",
            t.dt_factor > 0.0 && t.dt_factor <= 1.0,
            "must be in (0, 1]",
        );
        v.positive("track.sphere_diameter", t.sphere_diameter);
        v.positive("track.skin", t.skin);
        v.check(
            "track.rigid_damping_ratio",
            (0.0..1.0).contains(&t.rigid_damping_ratio),
            "must be in [0, 1)",
        );
        v.positive("track.sample_rate", t.sample_rate);
        v.check(
            "track.deformable_within",
            (t.stones == StoneModel::Near) == t.deformable_within.is_some(),
            "give it exactly when stones = \"near\"",
        );
        for (key, m) in [("ballast", &self.ballast), ("sleeper", &self.sleeper)] {
            v.nested(&format!("{key}.material"), &m.material);
            v.positive(&format!("{key}.springs.normal"), m.springs.normal);
            v.non_negative(&format!("{key}.springs.tangential"), m.springs.tangential);
        }
        v.positive("base.normal", self.base.normal);
        v.non_negative("base.tangential", self.base.tangential);
        for (key, mu) in [
            ("friction.ballast_ballast", self.friction.ballast_ballast),
            ("friction.ballast_sleeper", self.friction.ballast_sleeper),
            ("friction.base", self.friction.base),
        ] {
            v.check(key, mu.is_finite() && mu >= 0.0, "must be ≥ 0");
        }
        v.non_negative("rail.longitudinal", self.rail.longitudinal);
        v.non_negative("rail.lateral", self.rail.lateral);
        for (i, s) in self.sensor.iter().enumerate() {
            v.check(
                &format!("sensor[{i}].name"),
                !s.name.is_empty()
                    && s.name
                        .chars()
                        .all(|c| c.is_ascii_alphanumeric() || c == '_'),
                "must be letters, digits or _",
            );
        }
    }
}
