//! The tamping cycle of seed 000 §3 (Figure 4) as prescribed motions: the `[tamping]`
//! table of an NSCD scene on a `ballast-pack` packing.
//!
//! A tamping unit lowers vibrating tines into the crib ballast on both sides of one
//! sleeper, to just below its underside, squeezes them towards the sleeper, and pulls
//! them out again, while the track (here: that sleeper) is held lifted by the planned
//! amount; the squeezed stones fill the void the lift opened. Per cycle:
//!
//! 1. **penetrate**: the tines' tips go from `clearance` above the sleeper's top to
//!    `tip_below` under its underside at `penetration_speed` (optionally only while
//!    the ballast resists less than `penetration_force`); during the first cycle the
//!    sleeper rises by `lift` over the same time (ramps of `ramp`);
//! 2. **squeeze**: for `squeeze_time`, each tine advances towards the sleeper at
//!    `squeeze / squeeze_time` while the ballast pushes back with less than
//!    `squeeze_force`, averaged over a vibration period (the squeezing cylinder's law,
//!    [`TampingMonitor::actuate`]), up to `squeeze` of travel;
//! 3. **withdraw**: the tines rise back and open by their travel, evenly over the time
//!    `withdraw_speed` gives the planned depth, ending where they started.
//!
//! After the last cycle, with `release`, the sleeper is let down (phase `release`): it
//! rests on the tamped ballast under its own weight, as the packing's other sleepers
//! do, and keeps what lift the ballast holds (`sleeper_rise_m` in the summary).
//!
//! All along, the tines vibrate along x, `amplitude · sin 2πft`, the two sides in
//! opposition (as the tine arms of a unit driven by one eccentric shaft).
//!
//! Defaults, from the tamping literature the issue collects: 35 Hz, 4 mm (amplitude
//! 4–5 mm), squeezing 1 s (0.8–1.2 s, never over 2 s), tips 15 mm under the sleeper
//! (15–20 mm), lift 20 mm. ASSUMED (no figure found): penetration and withdrawal at
//! 0.5 m/s, 20 mm of squeeze per tine, ramps of 10 ms. The squeeze speed is prescribed
//! and stopped by the 11 kN cylinder force (10–12 kN static squeezing force); the
//! forces that result are reported ([`TampingMonitor`]).
//!
//! By default the tines follow their drive exactly (infinite stiffness), so the
//! vibration's 4 mm goes through a jam whatever force that takes. With
//! `tine_stiffness` each tine (its pieces one body) hangs on its drive by a spring
//! ([`Spring`]): the drive moves as above, the tine follows with the compliance of its
//! arm. ASSUMED:
//! 10 MN/m is the order of a 0.5 m steel arm of 40 × 80 mm in bending (3EI/L³ = 8.6
//! MN/m); `tine_damping` 0.1 of critical; the tine's mass from its mesh at
//! `tine_density` (steel).
//!
//! ```toml
//! [tamping]
//! sleeper = 1                       # which sleeper of the packing (from 1; default: middle)
//! tine_mesh = "../meshes/tine.msh"
//! tine_convex = ["blade", "shank"]  # pieces, as in [[driven]]
//! tine_material = "steel"
//! tine_y = ["-0.08 m", "0.08 m"]    # tines on each side (default: ± a quarter sleeper)
//! gap = "50 mm"                     # tine to sleeper side at the start
//! tine_stiffness = "10 MN/m"        # optional: tines that give (default: rigid drive)
//! cycles = 1
//! release = "0.2 s"                 # optional: let the sleeper down after the last cycle
//! ```

use std::path::Path;
use std::sync::Arc;

use nalgebra::{Point3, UnitQuaternion, Vector3};
use serde::Deserialize;

use super::body::{Body, BodyShape, Motion, Prescribed, Spring};
use super::motion::{mesh_pieces, Pieces, VelocityTable};
use super::scene::DrivenBody;
use super::step::SolvedContact;
use crate::geometry::{ControlBox, Period};
use crate::pack::Packing;
use crate::scene::{Density, Frequency, Length, Stiffness, Time, Validate, Validator, Velocity};
use crate::{Error, Result};

/// `[tamping]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TampingSpec {
    /// The tamped sleeper, numbered from 1 along x (default: the middle one).
    #[serde(default)]
    pub sleeper: Option<usize>,
    /// The tine's `.msh` file (relative to the scene): tip at z = 0, paddle faces
    /// normal to x (geo/tine.geo).
    pub tine_mesh: std::path::PathBuf,
    /// Its convex pieces.
    #[serde(default = "tine_pieces")]
    pub tine_convex: Pieces,
    /// Factor on the tine mesh's coordinates.
    #[serde(default = "one")]
    pub tine_scale: f64,
    /// Material of the tines.
    pub tine_material: String,
    /// The stiffness of a tine's hold on its drive (its arm): the tine (its pieces
    /// moving as one body) hangs on the drive by a spring of this stiffness. None (the
    /// default): the tines follow the drive exactly.
    #[serde(default)]
    pub tine_stiffness: Option<Stiffness>,
    /// The damping of that hold as a fraction of critical, `C = 2ζ√(Km)`.
    #[serde(default = "tine_damping")]
    pub tine_damping: f64,
    /// The tines' density (their mass, for `tine_stiffness`).
    #[serde(default = "steel_density")]
    pub tine_density: Density,
    /// World y of the tines on each side (default: the sleeper's centre ± a quarter of
    /// its length).
    #[serde(default)]
    pub tine_y: Option<Vec<Length>>,
    /// Clearance between a tine and the sleeper's side at the start.
    #[serde(default = "gap")]
    pub gap: Length,
    /// Height of the tine tips above the sleeper's top at the start.
    #[serde(default = "clearance")]
    pub clearance: Length,
    /// Depth of the tips under the sleeper's underside at the end of penetration.
    #[serde(default = "tip_below")]
    pub tip_below: Length,
    /// Speed of penetration.
    #[serde(default = "half_metre_per_s")]
    pub penetration_speed: Velocity,
    /// A limit on the force that drives one tine down: it then descends only while
    /// the ballast pushes it up with less than this. Without it (the default) the
    /// tines go down as prescribed, as a real unit's do.
    #[serde(default)]
    pub penetration_force: Option<crate::scene::Force>,
    /// Largest travel of each tine towards the sleeper while squeezing.
    #[serde(default = "squeeze")]
    pub squeeze: Length,
    /// The squeezing force of one tine's cylinder: a tine advances while the ballast
    /// pushes back less than this.
    #[serde(default = "squeeze_force")]
    pub squeeze_force: crate::scene::Force,
    /// Duration of the squeeze.
    #[serde(default = "squeeze_time")]
    pub squeeze_time: Time,
    /// Speed of withdrawal.
    #[serde(default = "half_metre_per_s")]
    pub withdraw_speed: Velocity,
    /// Duration of each speed ramp.
    #[serde(default = "ramp")]
    pub ramp: Time,
    /// Vibration frequency.
    #[serde(default = "frequency")]
    pub frequency: Frequency,
    /// Vibration amplitude (displacement, along x).
    #[serde(default = "amplitude")]
    pub amplitude: Length,
    /// Lift of the sleeper during the first penetration.
    #[serde(default = "lift")]
    pub lift: Length,
    /// Tamping cycles.
    #[serde(default = "one_cycle")]
    pub cycles: usize,
    /// After the last cycle, the time the sleeper is let down onto the tamped ballast
    /// (phase `release`): the lifting clamps open and it rests under its own weight, a
    /// free body that does not yaw like the packing's other sleepers, and the box under
    /// it comes down with it. None (the default): it stays held at its lift, as in seed
    /// 000's cases. A before/after comparison with a published tamping study (Shi et
    /// al. 2020: +7.56 % in the top layer under the sleeper) needs it: held up, the
    /// layer it would rest on includes the void the lift opened.
    #[serde(default)]
    pub release: Option<Time>,
    /// Compactness and forces every this many steps.
    #[serde(default = "one_cycle")]
    pub sample_every: usize,
}

fn tine_pieces() -> Pieces {
    Pieces::Groups(vec!["blade".into(), "shank".into()])
}
fn one() -> f64 {
    1.0
}
fn tine_damping() -> f64 {
    0.1
}
fn steel_density() -> Density {
    Density::from_si(7850.0)
}
fn one_cycle() -> usize {
    1
}
fn gap() -> Length {
    Length::from_si(0.05)
}
fn clearance() -> Length {
    Length::from_si(0.01)
}
fn tip_below() -> Length {
    Length::from_si(0.015)
}
fn half_metre_per_s() -> Velocity {
    Velocity::from_si(0.5)
}
fn squeeze() -> Length {
    Length::from_si(0.02)
}
fn squeeze_force() -> crate::scene::Force {
    crate::scene::Force::from_si(11e3)
}
fn squeeze_time() -> Time {
    Time::from_si(1.0)
}
fn ramp() -> Time {
    Time::from_si(0.01)
}
fn frequency() -> Frequency {
    Frequency::from_si(35.0)
}
fn amplitude() -> Length {
    Length::from_si(0.004)
}
fn lift() -> Length {
    Length::from_si(0.02)
}

impl Validate for TampingSpec {
    fn validate(&self, v: &mut Validator) {
        if let Some(k) = self.sleeper {
            v.check("sleeper", k >= 1, "sleepers are numbered from 1");
        }
        v.check(
            "tine_scale",
            self.tine_scale > 0.0 && self.tine_scale.is_finite(),
            "must be positive",
        );
        if let Some(ys) = &self.tine_y {
            v.check("tine_y", !ys.is_empty(), "give at least one y");
        }
        v.positive("gap", self.gap);
        v.non_negative("clearance", self.clearance);
        v.non_negative("tip_below", self.tip_below);
        v.positive("penetration_speed", self.penetration_speed);
        v.positive("withdraw_speed", self.withdraw_speed);
        v.positive("squeeze_force", self.squeeze_force);
        if let Some(k) = self.tine_stiffness {
            v.positive("tine_stiffness", k);
        }
        v.check(
            "tine_damping",
            self.tine_damping >= 0.0 && self.tine_damping.is_finite(),
            "must be zero or positive (a fraction of critical damping)",
        );
        v.positive("tine_density", self.tine_density);
        if let Some(force) = self.penetration_force {
            v.positive("penetration_force", force);
        }
        v.non_negative("squeeze", self.squeeze);
        v.positive("ramp", self.ramp);
        v.non_negative("frequency", self.frequency);
        v.non_negative("amplitude", self.amplitude);
        v.non_negative("lift", self.lift);
        v.check("cycles", self.cycles >= 1, "must be at least 1");
        if let Some(release) = self.release {
            v.positive("release", release);
        }
        v.check("sample_every", self.sample_every >= 1, "must be at least 1");
        v.check(
            "squeeze_time",
            self.squeeze_time.si() > self.ramp.si(),
            "must be longer than tamping.ramp",
        );
        v.check(
            "squeeze",
            self.squeeze.si() + self.amplitude.si() < self.gap.si(),
            "the squeeze plus the vibration amplitude must stay below tamping.gap (a tine \
             never reaches the sleeper: two driven bodies do not interact)",
        );
    }
}

/// One phase of the cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct Phase {
    /// `penetrate`, `squeeze`, `withdraw`, or `release` (after the last cycle).
    pub name: &'static str,
    /// Cycle number, from 1.
    pub cycle: usize,
    /// Start and end times (s).
    pub start: f64,
    /// End time (s).
    pub end: f64,
}

/// What a `[tamping]` table built: which bodies are the sleeper and the tines, the
/// phases, and the control boxes in which the compactness is followed.
#[derive(Debug, Clone)]
pub struct TampingPlan {
    /// Periodicity of the packing (compactness counts stones' images across the ends).
    pub period: Option<Period>,
    /// The tamped sleeper's number (from 1) and body index.
    pub sleeper_number: usize,
    /// Body index of the tamped sleeper.
    pub sleeper: usize,
    /// The tamped sleeper as the packing built it (dynamic, no yaw), which it becomes
    /// again when the `release` phase begins; None without a release.
    pub released: Option<Body>,
    /// The tines (`tine_L1`, `tine_R1`, …: left/right of the sleeper), each with its
    /// pieces' body indices.
    pub tines: Vec<DrivenBody>,
    /// The phases, in time order.
    pub phases: Vec<Phase>,
    /// Control boxes (fixed, from the packing at t = 0): the packing's boxes, then
    /// `lift_gap` (the tamped sleeper's footprint between its underside before and
    /// after the lift) when the lift is not zero, then the upper and lower halves of
    /// the box under the tamped sleeper and of the cribs beside it (`…_top`,
    /// `…_bottom`; [`layer_halves`]).
    pub boxes: Vec<(String, ControlBox)>,
    /// Index into `boxes` of the box under the tamped sleeper. This one follows the
    /// sleeper up: it is the layer of the same height right under its underside, so
    /// "after" measures the ballast the lifted sleeper will rest on.
    pub tamped_box: usize,
    /// Indices into `boxes` of the boxes that follow the tamped sleeper up: its box
    /// and that box's two halves.
    pub following: Vec<usize>,
    /// The tamped sleeper's height at the start (m).
    pub sleeper_start_z: f64,
    /// Compactness every this many steps.
    pub sample_every: u64,
    /// +1 for a tine left of the sleeper (squeezing along +x), −1 right of it.
    pub sides: Vec<f64>,
    /// Squeeze speed while the ballast yields (m/s): the travel over the squeeze time.
    pub squeeze_speed: f64,
    /// Largest travel (m).
    pub squeeze_travel: f64,
    /// The cylinder's force (N).
    pub squeeze_force: f64,
    /// Penetration speed while the ballast yields (m/s).
    pub penetration_speed: f64,
    /// Depth the tips should reach, below their start (m).
    pub penetration_depth: f64,
    /// The limit on the force driving a tine down (N; infinite for none).
    pub penetration_force: f64,
    /// Time constant of the cylinders' response to the ballast's push (s): one
    /// vibration period (or the squeeze time without vibration).
    pub response_time: f64,
}

impl TampingPlan {
    /// The control boxes now: the tamped sleeper's box raised by its lift so far.
    pub fn boxes_now(&self, bodies: &[Body]) -> Vec<(String, ControlBox)> {
        let mut boxes = self.boxes.clone();
        let dz = Vector3::z() * (bodies[self.sleeper].position.z - self.sleeper_start_z);
        for &k in &self.following {
            let bx = &mut boxes[k].1;
            bx.min += dz;
            bx.max += dz;
        }
        boxes
    }

    /// When the last phase (the last cycle's withdrawal, or the release) ends (s).
    pub fn end(&self) -> f64 {
        self.phases.last().map_or(0.0, |p| p.end)
    }

    /// When the sleeper is let down (s; None: it is held to the end).
    pub fn release_start(&self) -> Option<f64> {
        self.phases
            .iter()
            .find(|p| p.name == "release")
            .map(|p| p.start)
    }

    /// The phase at time `t` (`None` outside every phase).
    pub fn phase_at(&self, t: f64) -> Option<&Phase> {
        self.phases.iter().find(|p| t > p.start && t <= p.end)
    }
}

/// Builds the `[tamping]` of a scene over the packing's bodies: turns the tamped
/// sleeper (a dynamic body named `sleeper_K` in `bodies`) into a driven body that
/// lifts, appends the tines (infinite-mass pieces of `tine_material`), and returns the
/// plan. `scene_path` resolves the tine mesh and names the file in errors.
pub fn build(
    spec: &TampingSpec,
    scene_path: &Path,
    packing: &Packing,
    tine_material: u32,
    bodies: &mut Vec<Body>,
) -> Result<TampingPlan> {
    let invalid =
        |key: &str, why: String| Error::invalid(scene_path, format!("key tamping.{key}: {why}"));
    let count = packing.sleepers.len();
    if count == 0 {
        return Err(invalid("sleeper", "the packing has no sleepers".into()));
    }
    let number = spec.sleeper.unwrap_or(count.div_ceil(2));
    if number > count {
        return Err(invalid(
            "sleeper",
            format!("{number} is past the packing's {count} sleepers"),
        ));
    }
    let sleeper_index = |k: usize| -> Result<usize> {
        let name = format!("sleeper_{k}");
        bodies.iter().position(|b| b.name == name).ok_or_else(|| {
            invalid(
                "sleeper",
                "the packing's sleepers are not in the scene (give packing.sleeper_material)"
                    .into(),
            )
        })
    };
    let indices: Vec<usize> = (1..=count).map(sleeper_index).collect::<Result<_>>()?;
    let sleepers: Vec<(Point3<f64>, Point3<f64>)> = indices
        .iter()
        .map(|&i| crate::pack::deposit::bounds(&bodies[i].world_vertices()))
        .collect();
    let (lo, hi) = sleepers[number - 1];
    let index = indices[number - 1];

    // Timeline.
    let ramp = spec.ramp.si();
    let z_start = hi.z + spec.clearance.si();
    let depth = z_start - (lo.z - spec.tip_below.si());
    let t_pen = depth / spec.penetration_speed.si() + ramp;
    let t_squeeze = spec.squeeze_time.si();
    let t_out = depth / spec.withdraw_speed.si() + ramp;
    let mut phases = Vec::new();
    let mut t = 0.0;
    for cycle in 1..=spec.cycles {
        for (name, length) in [
            ("penetrate", t_pen),
            ("squeeze", t_squeeze),
            ("withdraw", t_out),
        ] {
            phases.push(Phase {
                name,
                cycle,
                start: t,
                end: t + length,
            });
            t += length;
        }
    }
    if let Some(release) = spec.release {
        phases.push(Phase {
            name: "release",
            cycle: spec.cycles,
            start: t,
            end: t + release.si(),
        });
    }

    // Tines: the left ones (x < sleeper) squeeze along +x; the right ones are the same
    // mesh turned half a turn about z, squeezing along −x.
    let mesh_file = super::scene::NscdScene::resolve(scene_path, &spec.tine_mesh);
    let mesh = crate::mesh::read_msh(&mesh_file)
        .map_err(|e| invalid("tine_mesh", super::packed::one_line(&e)))?;
    let pieces = mesh_pieces(&mesh, &spec.tine_convex).map_err(|e| invalid("tine_convex", e))?;
    let all: Vec<Point3<f64>> = pieces
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q * spec.tine_scale))
        .collect();
    let (tine_lo, tine_hi) = crate::pack::deposit::bounds(&all);
    let centre_y = 0.5 * (lo.y + hi.y);
    let ys: Vec<f64> = match &spec.tine_y {
        Some(ys) => ys.iter().map(|y| y.si()).collect(),
        None => {
            let quarter = 0.25 * (hi.y - lo.y);
            vec![centre_y - quarter, centre_y + quarter]
        }
    };
    let (gap, squeeze, amplitude) = (spec.gap.si(), spec.squeeze.si(), spec.amplitude.si());
    let mut tines = Vec::new();
    let mut sides = Vec::new();
    for (side, sign) in [("L", 1.0), ("R", -1.0)] {
        // Turned tines: x ↦ −x, y ↦ −y in the mesh frame.
        let turn = if sign > 0.0 {
            UnitQuaternion::identity()
        } else {
            UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::PI)
        };
        // The face towards the sleeper is the mesh's max-x face on both sides.
        let x = if sign > 0.0 {
            lo.x - gap - tine_hi.x
        } else {
            hi.x + gap + tine_hi.x
        };
        // Furthest reach away from the sleeper, with the vibration.
        let far = if sign > 0.0 {
            x + tine_lo.x - amplitude
        } else {
            x - tine_lo.x + amplitude
        };
        // Down, across and up are set step by step (TampingMonitor::actuate).
        let prescribed = Prescribed {
            amplitude: Vector3::new(sign * amplitude, 0.0, 0.0),
            frequency: spec.frequency.si(),
            ..Prescribed::default()
        };
        // Room on the far side: the container's wall or the neighbouring sleeper.
        let neighbour = if sign > 0.0 {
            number.checked_sub(2)
        } else {
            (number < count).then_some(number)
        };
        let wall = if sign > 0.0 {
            packing.container_min[0]
        } else {
            packing.container_max[0]
        };
        let limit = neighbour.map_or(wall, |k| {
            if sign > 0.0 {
                sleepers[k].1.x
            } else {
                sleepers[k].0.x
            }
        });
        if (far - limit) * sign < 0.0 {
            return Err(invalid(
                "gap",
                format!(
                    "a tine {} of sleeper {number} would reach x = {far:.4} m, past the {} at x = {limit:.4} m \
                     (make tamping.gap smaller or the tine thinner)",
                    if sign > 0.0 { "left" } else { "right" },
                    if neighbour.is_some() { "next sleeper" } else { "container wall" },
                ),
            ));
        }
        for (k, &y) in ys.iter().enumerate() {
            let name = format!("tine_{side}{}", k + 1);
            let shift = Vector3::new(x, y, z_start);
            let mut indices = Vec::new();
            let mut shapes = Vec::new();
            for (piece, points) in &pieces {
                let world: Vec<Point3<f64>> = points
                    .iter()
                    .map(|p| Point3::from(turn * (spec.tine_scale * p.coords) + shift))
                    .collect();
                let principal = BodyShape::convex_hull(
                    &world,
                    &format!("key tamping.tine_convex: piece \"{piece}\""),
                )
                .map_err(|e| Error::invalid(scene_path, super::packed::one_line(&e)))?;
                shapes.push((piece, principal));
            }
            let tine_mass =
                spec.tine_density.si() * shapes.iter().map(|(_, p)| p.shape.volume).sum::<f64>();
            for (piece, principal) in shapes {
                indices.push(bodies.len());
                let body_name = format!("{name}/{piece}");
                let Some(stiffness) = spec.tine_stiffness else {
                    bodies.push(Body::fixed(
                        &body_name,
                        Arc::new(principal.shape),
                        tine_material,
                        principal.pose,
                        Motion::Driven(prescribed.clone()),
                    ));
                    continue;
                };
                // The pieces move as one tine (one group), held by one spring.
                let mut body = Body::dynamic(
                    &body_name,
                    Arc::new(principal.shape),
                    spec.tine_density.si(),
                    tine_material,
                    principal.pose,
                )
                .translation_only();
                let k = stiffness.si();
                body.motion = Motion::Sprung(Spring {
                    drive: prescribed.clone(),
                    anchor: body.position,
                    rest: body.position,
                    stiffness: k,
                    damping: 2.0 * spec.tine_damping * (k * tine_mass).sqrt(),
                    group: tines.len() as u32,
                });
                bodies.push(body);
            }
            tines.push(DrivenBody {
                name,
                pieces: indices,
            });
            sides.push(sign);
        }
    }

    // The sleeper: held, lifted during the first penetration (and let go, as the
    // packing built it, when the release begins).
    let lift = spec.lift.si();
    let old = &bodies[index];
    let released = spec.release.map(|_| old.clone());
    let motion = if lift > 0.0 {
        // A trapezoid: from rest, up at v between the ramps, rest at the end; it rises
        // by v (t_pen − ramp) = lift.
        let (t0, t1) = (phases[0].start, phases[0].end);
        let v = Vector3::new(0.0, 0.0, lift / (t_pen - ramp));
        let times = vec![t0, t0 + ramp, t1 - ramp, t1];
        let values = vec![Vector3::zeros(), v, v, Vector3::zeros()];
        Motion::Driven(
            Prescribed::default()
                .with_table(VelocityTable::new(times, values).map_err(|e| invalid("lift", e))?),
        )
    } else {
        Motion::Static
    };
    bodies[index] = Body::fixed(
        &old.name,
        old.shape.clone(),
        old.material,
        old.pose(),
        motion,
    );

    // Control boxes, as ballast-pack measures them.
    let [x0, y0, z0] = packing.container_min;
    let [x1, y1, _] = packing.container_max;
    if x0 != 0.0 || y0 != -y1 {
        return Err(invalid(
            "sleeper",
            "the packing's container is not [0, L] × [−W/2, W/2] as ballast-pack writes it".into(),
        ));
    }
    let crib_top = packing.crib_top_m.unwrap_or(hi.z);
    let mut boxes = crate::pack::report::control_boxes(
        x1,
        y1 - y0,
        lo.z - z0,
        &sleepers,
        crib_top,
        packing.d50_m,
        packing.period().is_some(),
    );
    let tamped_box = boxes
        .iter()
        .position(|(n, _)| *n == format!("under_sleeper_{number}"))
        .expect("one box per sleeper");
    if lift > 0.0 {
        let under = boxes[tamped_box].1;
        boxes.push((
            "lift_gap".to_string(),
            ControlBox {
                min: Point3::new(under.min.x, under.min.y, lo.z),
                max: Point3::new(under.max.x, under.max.y, lo.z + lift),
            },
        ));
    }
    let halved = layer_halves(&mut boxes, number);
    let following = std::iter::once(tamped_box)
        .chain(
            halved
                .into_iter()
                .filter(|&k| boxes[k].0.starts_with(&format!("under_sleeper_{number}_"))),
        )
        .collect();
    Ok(TampingPlan {
        period: packing.period(),
        sleeper_number: number,
        sleeper: index,
        released,
        tines,
        phases,
        boxes,
        tamped_box,
        following,
        sleeper_start_z: bodies[index].position.z,
        sample_every: spec.sample_every as u64,
        sides,
        squeeze_speed: squeeze / t_squeeze,
        squeeze_travel: squeeze,
        squeeze_force: spec.squeeze_force.si(),
        penetration_speed: spec.penetration_speed.si(),
        penetration_depth: depth,
        penetration_force: spec.penetration_force.map_or(f64::INFINITY, |f| f.si()),
        response_time: if spec.frequency.si() > 0.0 {
            1.0 / spec.frequency.si()
        } else {
            t_squeeze
        },
    })
}

/// Appends the upper and lower halves (`<name>_top`, `<name>_bottom`, split at
/// mid-height) of the box under sleeper `number` and of the cribs on either side of
/// it, and returns their indices. The tines work in the top of the layer (their tips
/// 15 mm under the sleeper's underside), and the published figures are by layer: Shi
/// et al. (2020, Computers and Geotechnics 124, 103574) report +7.56 % in the top
/// layer under the sleeper and −34.77 % in the crib. A whole-depth box mixes the
/// tamped layer with the untouched one below. The halves have equal volumes, so the
/// whole box's compactness is their mean.
pub fn layer_halves(boxes: &mut Vec<(String, ControlBox)>, number: usize) -> Vec<usize> {
    let under = format!("under_sleeper_{number}");
    let (left, right) = (format!("crib_{number}_"), format!("_{number}"));
    let chosen: Vec<(String, ControlBox)> = boxes
        .iter()
        .filter(|(n, _)| {
            *n == under || (n.starts_with("crib_") && (n.starts_with(&left) || n.ends_with(&right)))
        })
        .cloned()
        .collect();
    let mut added = Vec::new();
    for (name, bx) in chosen {
        let mid = 0.5 * (bx.min.z + bx.max.z);
        for (half, lo, hi) in [("top", mid, bx.max.z), ("bottom", bx.min.z, mid)] {
            added.push(boxes.len());
            boxes.push((
                format!("{name}_{half}"),
                ControlBox {
                    min: Point3::new(bx.min.x, bx.min.y, lo),
                    max: Point3::new(bx.max.x, bx.max.y, hi),
                },
            ));
        }
    }
    added
}

/// Σ volume(stone ∩ box) / volume(box) for every box, over the dynamic bodies that are
/// not sleepers (exact clipping, [`convex_volume_in_box`]; images across a `period`'s
/// ends too).
pub fn stone_compactness(
    bodies: &[Body],
    boxes: &[(String, ControlBox)],
    period: Option<&Period>,
) -> Vec<f64> {
    let stones: Vec<&Body> = bodies
        .iter()
        .filter(|b| b.is_dynamic() && !b.name.starts_with("sleeper_"))
        .collect();
    boxes
        .iter()
        .map(|(_, bx)| crate::pack::report::solid_fraction(&stones, bx, period))
        .collect()
}

/// The force (N, world) that the contacts of a step put on the bodies `pieces`: their
/// impulses over `dt`.
pub fn force_on(pieces: &[usize], contacts: &[SolvedContact], dt: f64) -> Vector3<f64> {
    let mut impulse = Vector3::zeros();
    for c in contacts {
        let (a, b) = (c.contact.key.body_a as usize, c.contact.key.body_b as usize);
        let world = c.world_impulse();
        if pieces.contains(&b) {
            impulse += world;
        }
        if pieces.contains(&a) {
            impulse -= world;
        }
    }
    impulse / dt
}

/// The per-step record of a tamping run and its summary figures.
#[derive(Debug, Clone)]
pub struct TampingMonitor {
    /// The plan.
    pub plan: TampingPlan,
    /// What changes from step to step (saved in checkpoints).
    pub state: TampingState,
}

/// The running part of a [`TampingMonitor`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TampingState {
    /// Compactness in every box at t = 0.
    pub before: Vec<f64>,
    /// The latest sample.
    pub latest: Vec<f64>,
    /// Compactness of the tamped box at the start and end of each squeeze.
    pub squeeze: Vec<[f64; 2]>,
    /// Largest |force| on the sleeper (N).
    pub max_sleeper_force: f64,
    /// Largest squeezing force (along the squeeze, N) on one tine.
    pub max_tine_force: f64,
    /// Σ over squeeze steps of the tines' mean squeezing force (N).
    pub squeeze_force_sum: f64,
    /// Steps in the sum.
    pub squeeze_samples: usize,
    /// Each tine's travel towards the sleeper so far (m).
    pub travel: Vec<f64>,
    /// Each tine's squeezing force, averaged over the response time (N).
    pub last_force: Vec<f64>,
    /// Each tine's descent so far (m).
    pub descent: Vec<f64>,
    /// The upward force of the ballast on each tine, averaged likewise (N).
    pub last_lift: Vec<f64>,
    /// Each tine's largest descent and largest travel so far (m).
    pub reached: Vec<[f64; 2]>,
    /// The largest distance of a sprung tine piece from its drive so far (m; zero for
    /// tines that follow their drive).
    pub max_deflection: f64,
    /// The tamped sleeper's height above its start at the latest step (m).
    pub rise: f64,
    /// Compactness in every box and the sleeper's rise when it was let down (None
    /// before a release and without one).
    pub withdrawn: Option<Withdrawn>,
}

/// The state of a tamping run when its sleeper is let down ([`TampingSpec::release`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Withdrawn {
    /// Compactness in every box.
    pub compactness: Vec<f64>,
    /// The sleeper's height above its start (m): the lift.
    pub rise: f64,
}

impl TampingMonitor {
    /// A monitor with the compactness of `bodies` at t = 0.
    pub fn new(plan: TampingPlan, bodies: &[Body]) -> Self {
        let before = stone_compactness(bodies, &plan.boxes_now(bodies), plan.period.as_ref());
        let tines = plan.tines.len();
        TampingMonitor {
            plan,
            state: TampingState {
                latest: before.clone(),
                before,
                squeeze: Vec::new(),
                max_sleeper_force: 0.0,
                max_tine_force: 0.0,
                squeeze_force_sum: 0.0,
                squeeze_samples: 0,
                travel: vec![0.0; tines],
                last_force: vec![0.0; tines],
                descent: vec![0.0; tines],
                last_lift: vec![0.0; tines],
                reached: vec![[0.0; 2]; tines],
                max_deflection: 0.0,
                rise: 0.0,
                withdrawn: None,
            },
        }
    }

    /// Sets the tines' velocity for the step from `time` to `time + dt`, the laws of
    /// the unit's cylinders: while penetrating, a tine goes down at the penetration
    /// speed as long as the ballast pushes it up with less than the penetration force
    /// (averaged over the response time), until its tip is at the planned depth; while squeezing, it
    /// advances at the squeeze speed as long as the ballast pushes back with less than
    /// the squeezing force (averaged likewise), up to the largest travel; while withdrawing it goes back to
    /// its start, up and across, evenly over the phase's remaining steps; otherwise it
    /// holds. The velocity is the constant part of the tine's prescribed motion (the
    /// vibration is added to it), so with θ = 1 the travel recorded here is exactly the
    /// one the step makes.
    ///
    /// When the release begins the held sleeper becomes the free body the packing
    /// built, where it is and as fast as it goes (at rest: its lift ended long before),
    /// so a run resumed during the release rebuilds it with the checkpoint's state
    /// (its turning too, which a held sleeper does not have).
    pub fn actuate(&mut self, time: f64, dt: f64, bodies: &mut [Body]) {
        let plan = &self.plan;
        let phase = plan.phase_at(time + 0.5 * dt);
        if let (Some(free), Some(start)) = (&plan.released, plan.release_start()) {
            let held = &bodies[plan.sleeper];
            if time + 0.5 * dt > start && !held.is_dynamic() {
                let mut body = free.clone();
                body.position = held.position;
                body.orientation = held.orientation;
                body.velocity = held.velocity;
                body.angular_velocity = held.angular_velocity;
                bodies[plan.sleeper] = body;
            }
        }
        let st = &mut self.state;
        for (k, tine) in plan.tines.iter().enumerate() {
            let (across, down) = match phase {
                Some(p) if p.name == "penetrate" && st.last_lift[k] < plan.penetration_force => (
                    0.0,
                    plan.penetration_speed
                        .min((plan.penetration_depth - st.descent[k]) / dt)
                        .max(0.0),
                ),
                Some(p) if p.name == "squeeze" && st.last_force[k] < plan.squeeze_force => (
                    plan.squeeze_speed
                        .min((plan.squeeze_travel - st.travel[k]) / dt)
                        .max(0.0),
                    0.0,
                ),
                Some(p) if p.name == "withdraw" => {
                    let left = ((p.end - time) / dt).round().max(1.0) * dt;
                    (-st.travel[k] / left, -st.descent[k] / left)
                }
                _ => (0.0, 0.0),
            };
            // Where the drive is at the start of the step (the rest of the vibration
            // is in the prescribed motion's oscillation).
            let offset = Vector3::new(plan.sides[k] * st.travel[k], 0.0, -st.descent[k]);
            st.travel[k] += across * dt;
            st.descent[k] += down * dt;
            st.reached[k][0] = st.reached[k][0].max(st.descent[k]);
            st.reached[k][1] = st.reached[k][1].max(st.travel[k]);
            for &piece in &tine.pieces {
                let drive = match &mut bodies[piece].motion {
                    Motion::Driven(p) => p,
                    Motion::Sprung(spring) => {
                        spring.anchor = spring.rest + offset + spring.drive.oscillation_at(time);
                        &mut spring.drive
                    }
                    _ => continue,
                };
                drive.velocity.x = plan.sides[k] * across;
                drive.velocity.z = -down;
            }
        }
    }

    /// Column names of the tamping CSV.
    pub fn columns(&self) -> Vec<String> {
        let mut columns = vec!["time_s".to_string(), "cycle".into(), "phase".into()];
        columns.extend(
            self.plan
                .boxes
                .iter()
                .map(|(n, _)| format!("compactness_{n}")),
        );
        columns.extend(
            [
                "sleeper_fx_N",
                "sleeper_fy_N",
                "sleeper_fz_N",
                "sleeper_rise_m",
            ]
            .map(String::from),
        );
        for t in &self.plan.tines {
            columns.extend(
                [
                    "fx_N",
                    "fy_N",
                    "fz_N",
                    "travel_m",
                    "descent_m",
                    "deflection_m",
                ]
                .map(|c| format!("{}_{c}", t.name)),
            );
        }
        columns
    }

    /// Records the step that ended at `time` (`sample`: measure the compactness; the
    /// step that ends as the release begins is always measured) and returns the CSV
    /// row: time, cycle, phase (1 penetrate, 2 squeeze, 3 withdraw, 4 release, 0 after
    /// the last phase), compactness per box, the forces on the sleeper and its height
    /// above its start, the tines' forces and travel.
    pub fn record(
        &mut self,
        time: f64,
        sample: bool,
        bodies: &[Body],
        contacts: &[SolvedContact],
        dt: f64,
    ) -> Vec<f64> {
        let phase = self.plan.phase_at(time).cloned();
        let letting_go = self.state.withdrawn.is_none()
            && self
                .plan
                .release_start()
                .is_some_and(|start| time > start - 0.5 * dt);
        if sample || letting_go {
            self.state.latest = stone_compactness(
                bodies,
                &self.plan.boxes_now(bodies),
                self.plan.period.as_ref(),
            );
        }
        self.state.rise = bodies[self.plan.sleeper].position.z - self.plan.sleeper_start_z;
        if letting_go {
            self.state.withdrawn = Some(Withdrawn {
                compactness: self.state.latest.clone(),
                rise: self.state.rise,
            });
        }
        let tamped = self.state.latest[self.plan.tamped_box];
        if let Some(p) = &phase {
            if p.name == "squeeze" {
                let k = p.cycle - 1;
                if self.state.squeeze.len() <= k {
                    self.state.squeeze.push([tamped, tamped]);
                }
                self.state.squeeze[k][1] = tamped;
            }
        }
        let sleeper = force_on(&[self.plan.sleeper], contacts, dt);
        self.state.max_sleeper_force = self.state.max_sleeper_force.max(sleeper.norm());
        let mut row = vec![
            time,
            phase.as_ref().map_or(0.0, |p| p.cycle as f64),
            phase.as_ref().map_or(0.0, |p| match p.name {
                "penetrate" => 1.0,
                "squeeze" => 2.0,
                "withdraw" => 3.0,
                _ => 4.0,
            }),
        ];
        row.extend(&self.state.latest);
        row.extend([sleeper.x, sleeper.y, sleeper.z, self.state.rise]);
        let mut squeezing = 0.0;
        for (k, t) in self.plan.tines.iter().enumerate() {
            let f = force_on(&t.pieces, contacts, dt);
            // The ballast resists the squeeze: along −x on the left tines, +x on the right.
            let along = -self.plan.sides[k] * f.x;
            // The cylinders follow the push averaged over about a vibration period
            // (hydraulics do not answer each impact of a 35 Hz vibration).
            let w = (dt / self.plan.response_time).min(1.0);
            self.state.last_force[k] += w * (along - self.state.last_force[k]);
            self.state.max_tine_force = self.state.max_tine_force.max(along);
            squeezing += along / self.plan.tines.len() as f64;
            self.state.last_lift[k] += w * (f.z - self.state.last_lift[k]);
            let deflection = t
                .pieces
                .iter()
                .map(|&p| match &bodies[p].motion {
                    Motion::Sprung(spring) => (bodies[p].position - spring.anchor).norm(),
                    _ => 0.0,
                })
                .fold(0.0, f64::max);
            self.state.max_deflection = self.state.max_deflection.max(deflection);
            row.extend([
                f.x,
                f.y,
                f.z,
                self.state.travel[k],
                self.state.descent[k],
                deflection,
            ]);
        }
        if phase.as_ref().is_some_and(|p| p.name == "squeeze") {
            self.state.squeeze_force_sum += squeezing;
            self.state.squeeze_samples += 1;
        }
        row
    }

    /// The summary's tamping figures: `compactness_before` and `compactness_after`
    /// under the tamped sleeper (and their relative change), every box before and
    /// after (and `withdrawn`, when the sleeper was let down; null otherwise), the
    /// compactness at the start and end of each squeeze, the phases, the sleeper's
    /// height above its start at the end (`sleeper_rise_m`: the lift the tamped
    /// ballast kept, once released) and when it was let down, and the largest forces.
    pub fn figures(&self, summary: crate::scene::Summary) -> crate::scene::Summary {
        let k = self.plan.tamped_box;
        let (before, after) = (self.state.before[k], self.state.latest[k]);
        let boxes: Vec<serde_json::Value> = self
            .plan
            .boxes
            .iter()
            .enumerate()
            .map(|(i, (name, bx))| {
                serde_json::json!({
                    "box": name,
                    "min_m": [bx.min.x, bx.min.y, bx.min.z],
                    "max_m": [bx.max.x, bx.max.y, bx.max.z],
                    "before": self.state.before[i],
                    "after": self.state.latest[i],
                    "withdrawn": self.state.withdrawn.as_ref().map(|w| w.compactness[i]),
                })
            })
            .collect();
        let squeezes: Vec<serde_json::Value> = self
            .state
            .squeeze
            .iter()
            .enumerate()
            .map(
                |(c, [start, end])| serde_json::json!({"cycle": c + 1, "start": start, "end": end}),
            )
            .collect();
        let phases: Vec<serde_json::Value> = self
            .plan
            .phases
            .iter()
            .map(|p| serde_json::json!({"cycle": p.cycle, "name": p.name, "start_s": p.start, "end_s": p.end}))
            .collect();
        summary
            .figure("tamped_sleeper", self.plan.sleeper_number)
            .figure("planned_descent_m", self.plan.penetration_depth)
            .figure(
                "tine_descent_m",
                self.state
                    .reached
                    .iter()
                    .map(|r| r[0])
                    .collect::<Vec<f64>>(),
            )
            .figure(
                "tine_travel_m",
                self.state
                    .reached
                    .iter()
                    .map(|r| r[1])
                    .collect::<Vec<f64>>(),
            )
            .figure("tines", self.plan.tines.len())
            .figure("compactness_before", before)
            .figure("compactness_after", after)
            .figure("compactness_change_relative", (after - before) / before)
            .figure(
                "compactness_withdrawn",
                self.state.withdrawn.as_ref().map(|w| w.compactness[k]),
            )
            .figure("sleeper_rise_m", self.state.rise)
            .figure(
                "sleeper_rise_withdrawn_m",
                self.state.withdrawn.as_ref().map(|w| w.rise),
            )
            .figure("compactness", boxes)
            .figure("compactness_squeeze", squeezes)
            .figure("tamping_phases", phases)
            .figure("tamping_end_s", self.plan.end())
            .figure("max_sleeper_force_N", self.state.max_sleeper_force)
            .figure("max_tine_squeeze_force_N", self.state.max_tine_force)
            .figure("max_tine_deflection_m", self.state.max_deflection)
            .figure(
                "mean_tine_squeeze_force_N",
                if self.state.squeeze_samples > 0 {
                    self.state.squeeze_force_sum / self.state.squeeze_samples as f64
                } else {
                    f64::NAN
                },
            )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed(name: &str, x: [f64; 2], z: [f64; 2]) -> (String, ControlBox) {
        let bx = ControlBox {
            min: Point3::new(x[0], -0.4, z[0]),
            max: Point3::new(x[1], 0.4, z[1]),
        };
        (name.to_string(), bx)
    }

    /// Sleeper 1 of a periodic strip of twelve: the halves are of its own box and of
    /// the cribs on both sides (the one across the ends included), split at mid-height,
    /// and of nothing else (not sleeper 11's or 12's boxes, whose names share digits).
    #[test]
    fn layer_halves_split_the_tamped_sleepers_box_and_the_cribs_beside_it() {
        let mut boxes = vec![
            boxed("bed", [0.0, 7.2], [0.04, 0.25]),
            boxed("under_sleeper_1", [0.17, 0.43], [0.04, 0.25]),
            boxed("under_sleeper_11", [6.17, 6.43], [0.04, 0.25]),
            boxed("crib_1_2", [0.43, 0.77], [0.04, 0.31]),
            boxed("crib_10_11", [5.83, 6.17], [0.04, 0.31]),
            boxed("crib_11_12", [6.43, 6.77], [0.04, 0.31]),
            boxed("crib_12_1", [7.03, 7.37], [0.04, 0.31]),
        ];
        let added = layer_halves(&mut boxes, 1);
        let names: Vec<&str> = added.iter().map(|&k| boxes[k].0.as_str()).collect();
        assert_eq!(
            names,
            [
                "under_sleeper_1_top",
                "under_sleeper_1_bottom",
                "crib_1_2_top",
                "crib_1_2_bottom",
                "crib_12_1_top",
                "crib_12_1_bottom",
            ]
        );
        let crib = &boxes[added[2]].1;
        assert_eq!((crib.min.z, crib.max.z), (0.175, 0.31));
        assert_eq!((crib.min.x, crib.max.x), (0.43, 0.77));
        let bottom = &boxes[added[5]].1;
        assert_eq!((bottom.min.z, bottom.max.z), (0.04, 0.175));
        assert_eq!((bottom.min.x, bottom.max.x), (7.03, 7.37));
    }
}
