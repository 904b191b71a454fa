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
//! [solver]
//! tolerance = 1e-8                  # or: sweeps = 50 (fixed count, the seed's n_DDM)
//! max_sweeps = 2000
//! alert_distance = "1 mm"
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
//! ```

use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use serde::Deserialize;

use super::body::{Body, BodyShape, Motion, Prescribed};
use super::step::FrictionTable;
use crate::scene::{
    Acceleration, Angle, Density, Frequency, Length, Time, Validate, Validator, Velocity,
};
use crate::{Error, Result};

/// A whole NSCD scene.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NscdScene {
    /// Time stepping.
    pub time: TimeSpec,
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
    /// Stones from meshes.
    #[serde(default)]
    pub stones: Option<StonesSpec>,
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
    /// A fixed number of sweeps per step instead of a tolerance.
    #[serde(default)]
    pub sweeps: Option<usize>,
    /// Contacts within this gap enter the problem.
    pub alert_distance: Length,
}

fn default_max_sweeps() -> usize {
    1000
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
    /// Prescribed constant velocity (driven plane).
    #[serde(default)]
    pub velocity: Option<[Velocity; 3]>,
    /// Prescribed oscillation amplitude (driven plane).
    #[serde(default)]
    pub amplitude: Option<[Length; 3]>,
    /// Oscillation frequency.
    #[serde(default)]
    pub frequency: Option<Frequency>,
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

/// `[output]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// VTK frames over the run (besides the initial one); 0 for none.
    #[serde(default = "default_frames")]
    pub frames: usize,
}

fn default_frames() -> usize {
    20
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            frames: default_frames(),
        }
    }
}

/// `[analysis]`: what the scene checks.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalysisSpec {
    /// `incline` (a slider and a sticker), `rest` (nothing should move) or `deposit`.
    pub kind: String,
    /// The sliding block (incline).
    #[serde(default)]
    pub slider: Option<String>,
    /// The sticking block (incline).
    #[serde(default)]
    pub sticker: Option<String>,
    /// The acceleration is fitted after this time (incline).
    #[serde(default)]
    pub after: Option<Time>,
}

/// Analysis kinds.
pub const ANALYSIS_KINDS: [&str; 3] = ["incline", "rest", "deposit"];

impl Validate for NscdScene {
    fn validate(&self, v: &mut Validator) {
        v.positive("time.duration", self.time.duration);
        v.positive("time.dt", self.time.dt);
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
        v.check(
            "solver.max_sweeps",
            self.solver.max_sweeps > 0,
            "must be at least 1",
        );
        v.non_negative("solver.alert_distance", self.solver.alert_distance);
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
            if p.amplitude.is_some() {
                v.check(
                    &format!("plane[{i}].frequency"),
                    p.frequency.is_some_and(|f| f.si() > 0.0),
                    "an oscillating plane needs a positive frequency",
                );
            }
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
        }
    }
}

/// The bodies and tables a scene builds.
#[derive(Debug, Clone)]
pub struct Model {
    /// Every body: planes first, then blocks, then stones.
    pub bodies: Vec<Body>,
    /// µ per material pair.
    pub friction: FrictionTable,
    /// Equivalent-sphere diameters of the stones (m), in body order.
    pub stone_diameters: Vec<f64>,
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
        for p in &self.plane {
            let normal = Unit::new_normalize(Vector3::from(p.normal));
            let shape = Arc::new(BodyShape::half_space(normal));
            let velocity = p.velocity.map_or(Vector3::zeros(), |v| {
                Vector3::new(v[0].si(), v[1].si(), v[2].si())
            });
            let amplitude = p.amplitude.as_ref().map_or(Vector3::zeros(), vec3);
            let motion = if velocity == Vector3::zeros() && amplitude == Vector3::zeros() {
                Motion::Static
            } else {
                Motion::Driven(Prescribed {
                    velocity,
                    amplitude,
                    frequency: p.frequency.map_or(0.0, Frequency::si),
                })
            };
            bodies.push(Body::fixed(
                &p.name,
                shape,
                self.material_index(&p.material),
                Isometry3::translation(p.point[0].si(), p.point[1].si(), p.point[2].si()),
                motion,
            ));
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
        if let Some(s) = &self.stones {
            let (placed, diameters) = place_stones(self, s, scene_path)?;
            bodies.extend(placed);
            stone_diameters = diameters;
        }
        Ok(Model {
            bodies,
            friction,
            stone_diameters,
        })
    }
}

/// Reads the stone meshes of `spec.directory` (sorted `stone_*.msh`) as convex hulls.
pub fn read_stone_shapes(directory: &Path) -> Result<Vec<(PathBuf, Arc<BodyShape>)>> {
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
    let mut shapes = Vec::with_capacity(files.len());
    for file in files {
        let mesh = crate::mesh::read_msh(&file)?;
        let corners = crate::geometry::corner_vertices(&mesh.nodes, &mesh.boundary);
        let points: Vec<Point3<f64>> = if corners.len() >= 4 {
            corners.iter().map(|&i| mesh.nodes[i as usize]).collect()
        } else {
            let mut nodes: Vec<u32> = mesh.boundary.iter().flatten().copied().collect();
            nodes.sort_unstable();
            nodes.dedup();
            nodes.iter().map(|&i| mesh.nodes[i as usize]).collect()
        };
        let principal = BodyShape::convex_hull(&points, &file.display().to_string())?;
        shapes.push((file, Arc::new(principal.shape)));
    }
    Ok(shapes)
}

/// A small deterministic generator (SplitMix64) for the stones' orientations.
struct SplitMix(u64);

impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A uniformly random rotation (Shoemake).
    fn rotation(&mut self) -> UnitQuaternion<f64> {
        let (u1, u2, u3) = (self.next_f64(), self.next_f64(), self.next_f64());
        let tau = std::f64::consts::TAU;
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            b * (tau * u3).cos(),
            a * (tau * u2).sin(),
            a * (tau * u2).cos(),
            b * (tau * u3).sin(),
        ))
    }
}

fn place_stones(
    scene: &NscdScene,
    spec: &StonesSpec,
    scene_path: &Path,
) -> Result<(Vec<Body>, Vec<f64>)> {
    let directory = NscdScene::resolve(scene_path, &spec.directory);
    let shapes = read_stone_shapes(&directory)?;
    if shapes.is_empty() {
        return Err(Error::invalid(
            scene_path,
            format!(
                "key stones.directory: no stone_*.msh in {} (make meshes builds them)",
                directory.display()
            ),
        ));
    }
    let radius = shapes
        .iter()
        .map(|(_, s)| match &s.collider {
            crate::contact::Collider::Convex(c) => c.bounding_radius(),
            crate::contact::Collider::HalfSpace(_) => 0.0,
        })
        .fold(0.0, f64::max);
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
        let (file, shape) = &shapes[k % shapes.len()];
        let name = file.file_stem().and_then(|s| s.to_str()).unwrap_or("stone");
        diameters.push((6.0 * shape.volume / std::f64::consts::PI).cbrt());
        bodies.push(Body::dynamic(
            &format!("{name}#{k}"),
            shape.clone(),
            density,
            material,
            Isometry3::from_parts(Translation3::from(centre), random.rotation()),
        ));
    }
    Ok((bodies, diameters))
}
