//! The scene file of `ballast-pack SCENE.toml`: the stones, the bed and its sleepers,
//! the deposition and compaction parameters. The only part of `pack` that knows TOML.
//!
//! ```toml
//! seed = 1                              # the packing is a function of this seed
//!
//! [stones]
//! directory = "../meshes/stones"        # the stone family (stone_*.msh), drawn at random
//! material = "granite"
//! scale = 1.0                           # factor on the family's size (grading shift)
//! count = 500                           # optional cap on the number of stones
//! spheres = "24 mm"                     # optional: contact spheres at the meshes'
//!                                       # surface nodes (the QDEM track's; needs
//!                                       # sleepers.mesh)
//!
//! [bed]
//! length = "1.8 m"                      # x, along the track
//! width = "1.2 m"                       # y, across
//! depth = "0.3 m"                       # ballast under the sleepers' underside
//! sides = "walls"                       # or "periodic": periodic along x, walls in y
//! shoulder_width = "0.4 m"              # optional track-bed profile (needs sleepers):
//! shoulder_slope = 1.5                  # flat beyond the sleeper ends, then 1 : slope
//! wall_material = "steel"
//!
//! [sleepers]                            # optional: none for a plain box
//! count = 3
//! spacing = "0.6 m"
//! size = ["0.26 m", "1.0 m", "0.2 m"]  # a cuboid ...
//! # mesh = "../meshes/sleeper_type3.msh" # ... or the convex hull of a mesh
//! embed = "0.1 m"                       # crib ballast height above the underside
//! material = "concrete"
//!
//! [deposit]
//! dt = "2 ms"
//! theta = 1.0
//! tolerance = 1e-4                      # NLGS
//! max_sweeps = 300
//! finish_sweeps = 500                   # cap once the drag is off (final settle)
//! held_warm_start = 0.9                 # share of last step's impulses carried while
//!                                       # sleepers are held (default 1)
//! alert_distance = "2 mm"
//! depenetration_speed = "2 mm/s"        # overlaps of unconverged steps pushed out
//! end_checks = 2                        # re-solve a step whose motion cuts unseen features
//! friction = 0.3                        # µ between stones while raining (then the table's)
//! settle_speed = "5 mm/s"               # rms speed below which the bed has settled
//! max_overlap = "20 µm"                 # final phases also need overlaps below this
//!                                       # (default 0.05 % of the family's d50)
//! max_phase_time = "4 s"                # a phase that has not settled by then is reported
//! drag_time = "0.1 s"                   # optional drag while raining (terminal 1 m/s)
//! sleeper_mass_ratio = 100              # a sleeper's inertia at most this × the mean
//!                                       # stone's mass while packing, its weight kept
//! hold_sleepers = false                 # free for the final settle, carrying 1/k of
//!                                       # their weight (default; true: held where
//!                                       # they rest)
//! release_sleepers = true               # then freed (carrying 1/k) and settled again
//! ddm = { driver = "synchronous" }      # DDM of the solve (crate::scene::DdmSpec;
//!                                       # default: one slab per sleeper)
//!
//! [compaction]                          # optional: the floor vibrates vertically
//! amplitude = "1 mm"
//! frequency = "30 Hz"
//! duration = "0.5 s"
//! stage = "bed"                         # "layer": the under-sleeper layer, before the
//!                                       # sleepers are laid; "bed" (default): the
//!                                       # finished bed
//!
//! [tile]                                # optional: the bed is this periodic bay,
//! bay = "../results/bed-bay/packing.toml" # repeated along x (super::tile), instead of
//!                                       # rained; then the final settle
//!
//! [[material]] / [[friction]]           # as in ballast-nscd scenes
//! [output]
//! frame_interval = "0.1 s"              # VTK frames of the deposition (0: none)
//! checkpoint_every = 200                # steps between checkpoints (0: none)
//! checkpoint_wall_every = "30 min"      # and after this much wall time ("0 s": off)
//! ```

use std::path::PathBuf;

use serde::Deserialize;

use super::packing::SIDES;
use crate::nscd::scene::{FrictionSpec, MaterialSpec};
use crate::scene::{DdmSpec, Frequency, Length, Time, Validate, Validator, Velocity};

/// A whole bed scene.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BedScene {
    /// Seed of every random draw (stone choice, plan position, orientation).
    #[serde(default = "one")]
    pub seed: u64,
    /// The stones.
    pub stones: StonesSpec,
    /// The container and the layer.
    pub bed: BedSpec,
    /// Sleepers (none for a plain box).
    #[serde(default)]
    pub sleepers: Option<SleepersSpec>,
    /// Time stepping and settling.
    pub deposit: DepositSpec,
    /// Optional vibration of the floor.
    #[serde(default)]
    pub compaction: Option<CompactionSpec>,
    /// Optional: the bed laid from a periodic bay's packing instead of rained.
    #[serde(default)]
    pub tile: Option<TileSpec>,
    /// Materials (densities of stones and sleepers).
    pub material: Vec<MaterialSpec>,
    /// Friction per pair of materials.
    #[serde(default)]
    pub friction: Vec<FrictionSpec>,
    /// VTK frames of the deposition.
    #[serde(default)]
    pub output: OutputSpec,
}

fn one() -> u64 {
    1
}

/// `[stones]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StonesSpec {
    /// Directory of `stone_*.msh` (relative to the scene file).
    pub directory: PathBuf,
    /// Material name.
    pub material: String,
    /// Factor on the family's coordinates.
    #[serde(default = "unit")]
    pub scale: f64,
    /// Experimental: the stones are packed as their hulls swept by a sphere of this
    /// radius (default 0: bare hulls), so that neighbours' hulls stay about twice it
    /// apart, as the contact spheres at the vertices of seed 004's stones keep them.
    /// The contact geometry is tested and the quick bed settles with it and free
    /// sleepers, not yet with held ones (docs/pack.md, "Rounded stones").
    #[serde(default)]
    pub round: Option<Length>,
    /// The stones and sleepers are packed with spheres of this diameter at every
    /// surface node of their meshes as their contact shape: the QDEM track scene's
    /// contact spheres (seed 004 §4, 24 mm), so that its bed starts at rest with
    /// them (docs/pack.md, "Vertex spheres"). Default: none (bare hulls). Needs a
    /// sleeper mesh, not a cuboid.
    #[serde(default)]
    pub spheres: Option<Length>,
    /// Cap on the number of stones.
    #[serde(default)]
    pub count: Option<usize>,
}

fn unit() -> f64 {
    1.0
}

/// `[bed]`: a box `[0, length] × [−width/2, width/2]`, floor at z = 0.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BedSpec {
    /// Extent along x (m).
    pub length: Length,
    /// Extent along y (m).
    pub width: Length,
    /// Ballast under the sleepers' underside, or the whole layer without sleepers (m).
    pub depth: Length,
    /// Side conditions: `walls` (four walls) or `periodic` (periodic along x, the track
    /// direction, over `length`, as seed 004 §4's bed; walls across y).
    #[serde(default = "walls")]
    pub sides: String,
    /// Material of the floor and walls.
    pub wall_material: String,
    /// Track-bed profile: flat crest this far beyond the sleeper ends (at the crib
    /// ballast's level), then the shoulder slope down to the walls ([`super::profile`]).
    #[serde(default)]
    pub shoulder_width: Option<Length>,
    /// Horizontal run per unit height of the shoulder slope (1.5 for 1 : 1.5).
    #[serde(default)]
    pub shoulder_slope: Option<f64>,
}

fn walls() -> String {
    "walls".to_string()
}

/// `[sleepers]`: `count` sleepers across the track, `spacing` apart along x, centred.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SleepersSpec {
    /// How many.
    pub count: usize,
    /// Centre-to-centre distance along x.
    pub spacing: Length,
    /// A cuboid sleeper: extents along x, y, z.
    #[serde(default)]
    pub size: Option<[Length; 3]>,
    /// Or a sleeper mesh (its convex hull), placed with its bounding box centred in x
    /// and y and its underside at the bed's depth.
    #[serde(default)]
    pub mesh: Option<PathBuf>,
    /// Crib ballast height above the sleepers' underside.
    pub embed: Length,
    /// Material name.
    pub material: String,
    /// Hold the sleepers level (no rotation at all, as if the rails held them) instead
    /// of only square to the track; a sleeper then rests on its highest supports
    /// without tilting (the `impact` beds: QDEM contact spheres round the stones'
    /// corners, and a tilted sleeper would first have to settle back down).
    #[serde(default)]
    pub level: bool,
}

/// `[deposit]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DepositSpec {
    /// Time step.
    pub dt: Time,
    /// θ of the θ-method (1 closes impacts at zero gap; see docs/nscd.md).
    #[serde(default = "unit")]
    pub theta: f64,
    /// NLGS tolerance.
    pub tolerance: f64,
    /// NLGS sweep cap.
    pub max_sweeps: usize,
    /// NLGS sweep cap of the finishing phases (compaction of the finished bed, final
    /// settle), which run without drag: there an unconverged solve feeds energy into
    /// the bed that the drag no longer takes out (docs/pack.md, "Final settle").
    #[serde(default = "default_finish_sweeps")]
    pub finish_sweeps: usize,
    /// Share of the last step's impulses that warm-starts the solve while the sleepers
    /// are held (`MoreauJean::set_warm_start`; default 1, all of it); all of it
    /// otherwise.
    #[serde(default = "unit")]
    pub held_warm_start: f64,
    /// Alert distance of the contact detection.
    pub alert_distance: Length,
    /// Speed at which the engine pushes existing overlaps out (unconverged steps under
    /// a deep heap leave some; see `StepParams::depenetration_speed`).
    #[serde(default)]
    pub depenetration_speed: Option<Velocity>,
    /// End-of-step checks per step (0, the default: none; see
    /// `StepParams::end_checks`).
    #[serde(default)]
    pub end_checks: usize,
    /// µ between stones while raining (the friction table applies afterwards).
    #[serde(default)]
    pub friction: Option<f64>,
    /// The bed has settled when the rms speed of the stones is below this.
    pub settle_speed: Velocity,
    /// The final phases also need every overlap below this (default 0.05 % of the
    /// family's d50).
    #[serde(default)]
    pub max_overlap: Option<Length>,
    /// A phase (raining, settling, compaction) stops after this simulated time.
    pub max_phase_time: Time,
    /// Relaxation time of a linear drag on the stones while raining and settling
    /// (terminal speed g τ; none by default). The final settle runs without it.
    #[serde(default)]
    pub drag_time: Option<Time>,
    /// While the bed is packed, a sleeper's inertia (mass and moments of inertia) is
    /// scaled down to at most this many times the mean stone's mass; its weight stays
    /// the true one (density scaling of a quasi-static deposit: the bed at rest carries
    /// the same loads). The NLGS does not converge on a sleeper hundreds of times
    /// heavier than the stones under it (docs/pack.md, "Heavy sleepers"). `inf` keeps
    /// the true inertia.
    #[serde(default = "default_sleeper_mass_ratio")]
    pub sleeper_mass_ratio: f64,
    /// The sleepers are held where they rest, as their rails hold them, for the final
    /// settle (docs/pack.md, "Heavy sleepers"); when not, they settle free with their
    /// scaled weight. Default: free. Held, stone columns between a sleeper and the
    /// floor carry a self-stress that the warm start grows, up to 1.7 × the bed's
    /// weight on one contact of the `impact` bed and 286 × on the periodic quick one,
    /// and a freed sleeper turns it into motion (docs/pack.md, "Held sleepers: the
    /// quick beds"); rounded stones jam against a held sleeper too (docs/pack.md,
    /// "Rounded stones").
    #[serde(default)]
    pub hold_sleepers: bool,
    /// After the final settle, held sleepers are freed and the bed settles again with
    /// them free, carrying their scaled weight (default true): the packing then ends
    /// at rest as the solvers restart it, with free sleepers (docs/pack.md, "Warm
    /// restart").
    #[serde(default = "crate::scene::yes")]
    pub release_sleepers: bool,
    /// Domain decomposition of the contact solve (default: synchronous, one slab per
    /// sleeper).
    #[serde(default)]
    pub ddm: DdmSpec,
}

/// `[compaction]`: the floor vibrates vertically, `A sin(2πft)`, whole cycles.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompactionSpec {
    /// Amplitude of the floor's displacement.
    pub amplitude: Length,
    /// Frequency.
    pub frequency: Frequency,
    /// Duration (rounded to whole cycles).
    pub duration: Time,
    /// When: the under-sleeper layer before the sleepers are laid, or the finished bed.
    #[serde(default)]
    pub stage: CompactionStage,
}

/// When the bed is compacted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CompactionStage {
    /// The under-sleeper layer, struck off and settled, before the sleepers are laid
    /// (as the bottom ballast is compacted in track construction); a bed without
    /// sleepers is compacted once filled.
    Layer,
    /// The finished bed, sleepers and crib included, before the final settle.
    #[default]
    Bed,
}

/// `[tile]`: the bed is a periodic bay's packing repeated along x ([`super::tile`]):
/// the stones and sleepers of one sleeper bay packed periodic along the track, laid
/// end to end so that its sleepers fall on the scene's, the copies that cross an end
/// wall left out; then the bed settles. A long bed (seed 000's 7-sleeper slice) costs
/// then one bay's deposition and the final settle instead of raining it all.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TileSpec {
    /// The bay's packing file (relative to the scene file), written by `ballast-pack`
    /// with `bed.sides = "periodic"`, the same stones, width, depth and sleepers.
    pub bay: PathBuf,
}

/// `[output]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Simulated time between VTK frames of the deposition; 0 for none (the final
    /// state is always written).
    #[serde(default = "default_frame_interval")]
    pub frame_interval: Time,
    /// A checkpoint every this many steps, from which `--resume` continues a killed run
    /// ([`super::resume`]); 0 for none.
    #[serde(default = "default_checkpoint_every")]
    pub checkpoint_every: u64,
    /// Also a checkpoint once this much wall time has passed since the last one ("0
    /// s": only by steps): a final settle's steps take a minute each
    /// ([`crate::output::Cadence`]).
    #[serde(default = "crate::output::default_checkpoint_wall_every")]
    pub checkpoint_wall_every: Time,
}

/// The seed's n_DDM for its Table 3 case (seed 000 §4.2).
fn default_finish_sweeps() -> usize {
    500
}

/// Sleepers' inertia at most 100 stones' (docs/pack.md, "Heavy sleepers").
fn default_sleeper_mass_ratio() -> f64 {
    100.0
}

fn default_checkpoint_every() -> u64 {
    200
}

fn default_frame_interval() -> Time {
    Time::parse("0.1 s").expect("a valid time")
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            frame_interval: default_frame_interval(),
            checkpoint_every: default_checkpoint_every(),
            checkpoint_wall_every: crate::output::default_checkpoint_wall_every(),
        }
    }
}

impl BedScene {
    /// Whether the bed is periodic along x (`bed.sides = "periodic"`).
    pub fn periodic(&self) -> bool {
        self.bed.sides == "periodic"
    }

    /// Index of material `name` (0 when unknown: validation rejects that).
    pub fn material_index(&self, name: &str) -> u32 {
        self.material
            .iter()
            .position(|m| m.name == name)
            .unwrap_or(0) as u32
    }

    /// Density of material `name` (kg/m³; 0 when not given: validation rejects that
    /// for stones and sleepers).
    pub fn density(&self, name: &str) -> f64 {
        self.material
            .iter()
            .find(|m| m.name == name)
            .and_then(|m| m.density)
            .map_or(0.0, |d| d.si())
    }
}

impl Validate for BedScene {
    fn validate(&self, v: &mut Validator) {
        v.non_negative(
            "output.checkpoint_wall_every",
            self.output.checkpoint_wall_every,
        );
        let names: Vec<&str> = self.material.iter().map(|m| m.name.as_str()).collect();
        let material = |v: &mut Validator, key: &str, name: &str, needs_density: bool| match self
            .material
            .iter()
            .find(|m| m.name == name)
        {
            None => v.fail(
                key,
                format!(
                    "unknown material \"{name}\" (defined: {})",
                    names.join(", ")
                ),
            ),
            Some(m) if needs_density && m.density.is_none() => v.fail(
                key,
                format!("material \"{name}\" needs a density (it moves)"),
            ),
            Some(_) => {}
        };
        material(v, "stones.material", &self.stones.material, true);
        material(v, "bed.wall_material", &self.bed.wall_material, false);
        if let Some(s) = &self.sleepers {
            material(v, "sleepers.material", &s.material, true);
        }
        for (i, m) in self.material.iter().enumerate() {
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
        for (i, f) in self.friction.iter().enumerate() {
            for (k, name) in f.pair.iter().enumerate() {
                material(v, &format!("friction[{i}].pair[{k}]"), name, false);
            }
            v.check(
                &format!("friction[{i}].mu"),
                f.mu.is_finite() && f.mu >= 0.0,
                "must be a finite number ≥ 0",
            );
        }
        v.check(
            "stones.scale",
            self.stones.scale.is_finite() && self.stones.scale > 0.0,
            "must be a positive number",
        );
        if let Some(r) = self.stones.round {
            v.non_negative("stones.round", r);
        }
        if let Some(d) = self.stones.spheres {
            v.non_negative("stones.spheres", d);
            v.check(
                "stones.spheres",
                self.stones.round.is_none_or(|r| r.si() == 0.0) || d.si() == 0.0,
                "cannot go with stones.round (one contact shape or the other)",
            );
            v.check(
                "stones.spheres",
                d.si() == 0.0 || self.sleepers.as_ref().is_none_or(|s| s.mesh.is_some()),
                "needs the sleepers as a mesh (sleepers.mesh): a cuboid has no surface nodes",
            );
        }
        if let Some(n) = self.stones.count {
            v.check("stones.count", n > 0, "must be at least 1");
        }
        v.nested("deposit.ddm", &self.deposit.ddm);
        v.positive("bed.length", self.bed.length);
        v.positive("bed.width", self.bed.width);
        v.positive("bed.depth", self.bed.depth);
        v.check(
            "bed.sides",
            SIDES.contains(&self.bed.sides.as_str()),
            format!(
                "\"{}\" is not one of \"walls\" or \"periodic\" (periodic along x, the track)",
                self.bed.sides
            ),
        );
        if let (true, Some(s)) = (self.periodic(), &self.sleepers) {
            let pitch = s.count as f64 * s.spacing.si();
            v.check(
                "bed.length",
                (pitch - self.bed.length.si()).abs() <= 1e-9 * pitch,
                format!(
                    "a periodic bed repeats its sleepers along x: must be sleepers.count × \
                     sleepers.spacing = {pitch} m"
                ),
            );
        }
        if self.bed.shoulder_width.is_some() || self.bed.shoulder_slope.is_some() {
            v.check(
                "bed.shoulder_width",
                self.bed.shoulder_width.is_some() && self.bed.shoulder_slope.is_some(),
                "give both shoulder_width and shoulder_slope, or neither",
            );
            v.check(
                "bed.shoulder_width",
                self.sleepers.is_some(),
                "a shoulder profile needs [sleepers] (its crest is the sleepers' length)",
            );
        }
        if let Some(w) = self.bed.shoulder_width {
            v.non_negative("bed.shoulder_width", w);
        }
        if let Some(slope) = self.bed.shoulder_slope {
            v.check(
                "bed.shoulder_slope",
                slope.is_finite() && slope > 0.0,
                "must be a positive number (horizontal run per unit height)",
            );
        }
        if let Some(s) = &self.sleepers {
            v.check("sleepers.count", s.count > 0, "must be at least 1");
            v.positive("sleepers.spacing", s.spacing);
            v.non_negative("sleepers.embed", s.embed);
            v.check(
                "sleepers",
                s.size.is_some() != s.mesh.is_some(),
                "give exactly one of size or mesh",
            );
            if let Some(size) = &s.size {
                for (k, l) in size.iter().enumerate() {
                    v.positive(&format!("sleepers.size[{k}]"), *l);
                }
                v.check(
                    "sleepers.spacing",
                    s.spacing.si() > size[0].si(),
                    "must exceed the sleeper's size along x (the cribs would be empty)",
                );
                v.check(
                    "sleepers.count",
                    s.count as f64 * s.spacing.si() <= self.bed.length.si() + 1e-12,
                    "count × spacing must fit in bed.length",
                );
                v.check(
                    "sleepers.size[1]",
                    size[1].si() < self.bed.width.si(),
                    "must be less than bed.width (the sleepers lie across the bed)",
                );
            }
        }
        let d = &self.deposit;
        v.positive("deposit.dt", d.dt);
        v.in_range("deposit.theta", d.theta, 0.5, 1.0);
        v.in_range("deposit.held_warm_start", d.held_warm_start, 0.0, 1.0);
        v.check(
            "deposit.tolerance",
            d.tolerance.is_finite() && d.tolerance > 0.0,
            "must be a positive number",
        );
        v.check("deposit.max_sweeps", d.max_sweeps > 0, "must be at least 1");
        v.check(
            "deposit.finish_sweeps",
            d.finish_sweeps > 0,
            "must be at least 1",
        );
        v.non_negative("deposit.alert_distance", d.alert_distance);
        if let Some(speed) = d.depenetration_speed {
            v.non_negative("deposit.depenetration_speed", speed);
        }
        if let Some(mu) = d.friction {
            v.check(
                "deposit.friction",
                mu.is_finite() && mu >= 0.0,
                "must be a finite number ≥ 0",
            );
        }
        v.positive("deposit.settle_speed", d.settle_speed);
        if let Some(l) = d.max_overlap {
            v.positive("deposit.max_overlap", l);
        }
        v.positive("deposit.max_phase_time", d.max_phase_time);
        if let Some(tau) = d.drag_time {
            v.positive("deposit.drag_time", tau);
        }
        v.check(
            "deposit.sleeper_mass_ratio",
            d.sleeper_mass_ratio >= 1.0,
            "must be at least 1 (inf keeps the true inertia)",
        );
        if let Some(c) = &self.compaction {
            v.check(
                "compaction.stage",
                self.tile.is_none() || c.stage == CompactionStage::Bed,
                "\"layer\" cannot go with [tile]: the bay's layer was compacted when the bay \
                 was packed (\"bed\" vibrates the tiled bed)",
            );
            v.positive("compaction.amplitude", c.amplitude);
            v.positive("compaction.frequency", c.frequency);
            v.positive("compaction.duration", c.duration);
        }
        v.non_negative("output.frame_interval", self.output.frame_interval);
    }
}
