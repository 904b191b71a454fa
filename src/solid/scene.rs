//! The scene file of one deformable solid (seed 004 §3): a tetra mesh, its material,
//! fixed and loaded physical groups, probes, and the sections that `ballast-qdem`
//! (`[qdem]`) and `ballast-fem` (`[fem]`) read. The same file drives both solvers, so
//! a comparison is made on the same mesh, groups and loads by construction.
//!
//! ```toml
//! [mesh]
//! file = "../meshes/cantilever_h0.05.msh"     # relative to the scene file
//!
//! [material]
//! name = "concrete"
//! density = "2350 kg/m^3"
//! young_modulus = "45 GPa"
//! poisson = 0.167
//!
//! [[fix]]
//! group = "fixed"
//! directions = "xyz"
//!
//! [[load]]
//! group = "tip"
//! force = ["0 N", "0 N", "-200 N"]            # total over the group's nodes
//! time = { kind = "ramp", duration = "1 s" }  # constant | ramp | switch_off | table
//!
//! [[probe]]
//! name = "tip_centre"
//! group = "tip_centre"                        # or point = ["2.4 m", "0.125 m", "0.11 m"]
//! ```

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::qdem::Directions;
use crate::scene::{
    Acceleration, Force, Frequency, Length, Material, StiffnessPerArea, Time, Validate, Validator,
    Viscosity,
};

/// A whole solid scene.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolidScene {
    /// The tetra mesh.
    pub mesh: MeshSpec,
    /// The body's material (one per scene).
    pub material: Material,
    /// Fixed directions on physical groups.
    #[serde(default)]
    pub fix: Vec<FixSpec>,
    /// Total forces spread over physical groups.
    #[serde(default)]
    pub load: Vec<LoadSpec>,
    /// Gravitational acceleration (three components); none by default.
    #[serde(default)]
    pub gravity: Option<[Acceleration; 3]>,
    /// Displacement probes written as CSV time series.
    #[serde(default)]
    pub probe: Vec<ProbeSpec>,
    /// Variants run one after the other (e.g. several shear viscosities).
    #[serde(default)]
    pub case: Vec<CaseSpec>,
    /// The explicit QDEM run (`ballast-qdem`).
    #[serde(default)]
    pub qdem: Option<QdemSpec>,
    /// The reference FEM run (`ballast-fem`).
    #[serde(default)]
    pub fem: Option<FemSpec>,
    /// The headline figure the scene is about.
    #[serde(default)]
    pub analysis: Option<AnalysisSpec>,
}

/// `[mesh]`: the gmsh file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// The `.msh` file, relative to the scene file.
    pub file: PathBuf,
}

/// `[[fix]]`: directions of a physical group's nodes held at zero displacement.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FixSpec {
    /// Physical group name.
    pub group: String,
    /// Any of `x`, `y`, `z` (e.g. `"xyz"`, `"xy"`, `"z"`).
    #[serde(default = "all_directions")]
    pub directions: String,
}

fn all_directions() -> String {
    "xyz".to_string()
}

impl FixSpec {
    /// The directions as a mask; `None` if the text is not made of x, y and z.
    pub fn mask(&self) -> Option<Directions> {
        parse_directions(&self.directions)
    }
}

/// Parses `"xyz"`-style direction sets (at least one letter, no repeats).
pub fn parse_directions(text: &str) -> Option<Directions> {
    let mut mask = Directions::NONE;
    for c in text.chars() {
        let d = match c {
            'x' | 'X' => Directions::X,
            'y' | 'Y' => Directions::Y,
            'z' | 'Z' => Directions::Z,
            _ => return None,
        };
        if mask.0 & d.0 != 0 {
            return None;
        }
        mask = mask.union(d);
    }
    (mask != Directions::NONE).then_some(mask)
}

impl Validate for FixSpec {
    fn validate(&self, v: &mut Validator) {
        v.check(
            "group",
            !self.group.is_empty(),
            "must name a physical group",
        );
        v.check(
            "directions",
            self.mask().is_some(),
            format!(
                "\"{}\" is not a set of directions (use letters x, y, z, e.g. \"xyz\" or \"z\")",
                self.directions
            ),
        );
    }
}

/// `[[load]]`: a total force spread equally over a group's nodes, times φ(t).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    /// Physical group name.
    pub group: String,
    /// Total force (x, y, z) over all the group's nodes.
    pub force: [Force; 3],
    /// Time factor; constant if absent.
    #[serde(default)]
    pub time: Option<TimeSpec>,
}

impl Validate for LoadSpec {
    fn validate(&self, v: &mut Validator) {
        v.check(
            "group",
            !self.group.is_empty(),
            "must name a physical group",
        );
        for (i, f) in self.force.iter().enumerate() {
            v.finite(&format!("force[{i}]"), *f);
        }
        if let Some(time) = &self.time {
            v.nested("time", time);
        }
    }
}

/// How a load varies in time.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// `constant`, `ramp` (0 → 1 over `duration`), `switch_off` (1 until `t0`, then 0)
    /// or `table` (a CSV `time_s,factor`, linear between rows).
    pub kind: String,
    /// Ramp duration.
    #[serde(default)]
    pub duration: Option<Time>,
    /// Switch-off time.
    #[serde(default)]
    pub t0: Option<Time>,
    /// The table file (relative to the scene file).
    #[serde(default)]
    pub file: Option<PathBuf>,
}

/// The time-function kinds a scene may name.
pub const TIME_KINDS: [&str; 4] = ["constant", "ramp", "switch_off", "table"];

impl Validate for TimeSpec {
    fn validate(&self, v: &mut Validator) {
        let ok = v.check(
            "kind",
            TIME_KINDS.contains(&self.kind.as_str()),
            format!(
                "\"{}\" is not a time function (use one of: {})",
                self.kind,
                TIME_KINDS.join(", ")
            ),
        );
        if !ok {
            return;
        }
        let needs = |name: &str| match self.kind.as_str() {
            "ramp" => name == "duration",
            "switch_off" => name == "t0",
            "table" => name == "file",
            _ => false,
        };
        for (name, given) in [
            ("duration", self.duration.is_some()),
            ("t0", self.t0.is_some()),
            ("file", self.file.is_some()),
        ] {
            if needs(name) {
                v.check(
                    name,
                    given,
                    format!("is required by kind = \"{}\"", self.kind),
                );
            } else {
                v.check(
                    name,
                    !given,
                    format!("is not used by kind = \"{}\"", self.kind),
                );
            }
        }
        if let Some(d) = self.duration {
            v.positive("duration", d);
        }
        if let Some(t0) = self.t0 {
            v.non_negative("t0", t0);
        }
    }
}

/// `[[probe]]`: a displacement time series — one node (a point group, or the node
/// nearest `point`) or the average over a group's nodes.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    /// Column prefix in `probes.csv`.
    pub name: String,
    /// Physical group: its node, or the average of its nodes.
    #[serde(default)]
    pub group: Option<String>,
    /// A point: the node nearest to it.
    #[serde(default)]
    pub point: Option<[Length; 3]>,
}

impl Validate for ProbeSpec {
    fn validate(&self, v: &mut Validator) {
        v.check(
            "name",
            !self.name.is_empty()
                && self
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_'),
            format!(
                "\"{}\" must be letters, digits and _ (it names CSV columns)",
                self.name
            ),
        );
        v.check(
            "group",
            self.group.is_some() != self.point.is_some(),
            "give exactly one of group or point",
        );
    }
}

/// `[[case]]`: a variant of the scene run on its own (results in a sub-directory named
/// after it).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaseSpec {
    /// Sub-directory and label.
    pub name: String,
    /// Replaces the material's shear viscosity µ_D.
    #[serde(default)]
    pub shear_viscosity: Option<Viscosity>,
    /// Replaces the material's bulk viscosity κ_D.
    #[serde(default)]
    pub bulk_viscosity: Option<Viscosity>,
    /// Fixes added to the scene's.
    #[serde(default)]
    pub fix: Vec<FixSpec>,
}

impl Validate for CaseSpec {
    fn validate(&self, v: &mut Validator) {
        v.check(
            "name",
            !self.name.is_empty()
                && self
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c)),
            format!(
                "\"{}\" must be letters, digits, _, - and . (it names a directory)",
                self.name
            ),
        );
        if let Some(mu) = self.shear_viscosity {
            v.non_negative("shear_viscosity", mu);
        }
        if let Some(kappa) = self.bulk_viscosity {
            v.non_negative("bulk_viscosity", kappa);
        }
        v.each("fix", &self.fix);
    }
}

/// The time step of an explicit run: `"auto"` (a fraction of the stable step) or a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TimeStep {
    /// `dt_factor` × the stable step.
    Auto,
    /// A given step.
    Given(Time),
}

impl<'de> Deserialize<'de> for TimeStep {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let text = String::deserialize(deserializer)?;
        if text.trim() == "auto" {
            Ok(TimeStep::Auto)
        } else {
            Time::parse(&text)
                .map(TimeStep::Given)
                .map_err(|e| serde::de::Error::custom(format!("{e}, or \"auto\"")))
        }
    }
}

/// `[qdem]`: the explicit run.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QdemSpec {
    /// Simulated time.
    pub duration: Time,
    /// Time step: `"auto"` or a time such as `"1e-6 s"`.
    #[serde(default = "auto_step")]
    pub dt: TimeStep,
    /// With `dt = "auto"`: the fraction of the stable step (default 0.8). Above 1 the
    /// run is refused unless `--force`.
    #[serde(default = "default_dt_factor")]
    pub dt_factor: f64,
    /// Numerical damping to reach a steady state sooner.
    #[serde(default)]
    pub damping: Option<DampingSpec>,
    /// VTK frames written over the run (plus the initial state).
    #[serde(default = "default_frames")]
    pub frames: usize,
    /// Probe and energy sampling interval; default: every step, or duration / 20 000
    /// when that is coarser.
    #[serde(default)]
    pub sample_interval: Option<Time>,
}

fn auto_step() -> TimeStep {
    TimeStep::Auto
}
fn default_dt_factor() -> f64 {
    crate::qdem::RECOMMENDED_FRACTION
}
fn default_frames() -> usize {
    20
}

impl Validate for QdemSpec {
    fn validate(&self, v: &mut Validator) {
        v.positive("duration", self.duration);
        if let TimeStep::Given(dt) = self.dt {
            v.positive("dt", dt);
        }
        v.check(
            "dt_factor",
            self.dt_factor.is_finite() && self.dt_factor > 0.0,
            format!("must be positive, got {}", self.dt_factor),
        );
        if let Some(d) = &self.damping {
            v.nested("damping", d);
        }
        if let Some(s) = self.sample_interval {
            v.positive("sample_interval", s);
        }
    }
}

/// `[qdem.damping]`: dynamic relaxation (numerical, vanishes at rest).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DampingSpec {
    /// `none`, `mass_proportional` (force −α m v) or `kinetic` (velocities zeroed at
    /// each peak of the kinetic energy).
    pub kind: String,
    /// α for `mass_proportional`, as a rate in 1/s (critical for a mode ω is α = 2ω).
    #[serde(default)]
    pub rate: Option<Frequency>,
    /// Damping is switched off from this time on (e.g. when a load is released).
    #[serde(default)]
    pub until: Option<Time>,
}

impl Validate for DampingSpec {
    fn validate(&self, v: &mut Validator) {
        let kinds = ["none", "mass_proportional", "kinetic"];
        v.check(
            "kind",
            kinds.contains(&self.kind.as_str()),
            format!(
                "\"{}\" is not a damping (use one of: {})",
                self.kind,
                kinds.join(", ")
            ),
        );
        let needs_rate = self.kind == "mass_proportional";
        v.check(
            "rate",
            self.rate.is_some() == needs_rate,
            if needs_rate {
                "is required by kind = \"mass_proportional\""
            } else {
                "is only used by kind = \"mass_proportional\""
            },
        );
        if let Some(rate) = self.rate {
            v.positive("rate", rate);
        }
        if let Some(until) = self.until {
            v.positive("until", until);
        }
    }
}

/// `[fem]`: the reference FEM run.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FemSpec {
    /// Lowest modes to compute (`ballast-fem modes`).
    #[serde(default = "default_modes")]
    pub modes: usize,
    /// Winkler springs (normal stiffness per area) on physical groups.
    #[serde(default)]
    pub winkler: Vec<WinklerSpec>,
}

fn default_modes() -> usize {
    4
}

impl Validate for FemSpec {
    fn validate(&self, v: &mut Validator) {
        v.check(
            "modes",
            (1..=200).contains(&self.modes),
            format!("must be between 1 and 200, got {}", self.modes),
        );
        v.each("winkler", &self.winkler);
    }
}

/// `[[fem.winkler]]`: an elastic foundation on a group's faces.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WinklerSpec {
    /// Physical surface group.
    pub group: String,
    /// Stiffness per area (e.g. `"100 MN/m^3"`).
    pub stiffness: StiffnessPerArea,
}

impl Validate for WinklerSpec {
    fn validate(&self, v: &mut Validator) {
        v.check(
            "group",
            !self.group.is_empty(),
            "must name a physical group",
        );
        v.positive("stiffness", self.stiffness);
    }
}

/// The analyses a scene can ask for.
pub const ANALYSIS_KINDS: [&str; 4] = ["static_deflection", "frequency", "creep", "decay"];

/// `[analysis]`: which headline figure the scene reports, from which probe.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalysisSpec {
    /// `static_deflection` (final |u| at the probe), `frequency` (FFT of the probe after
    /// `after`), `creep` (strain u_z/height against eq. 14 and its correction) or
    /// `decay` (peak envelope of the strain oscillation).
    pub kind: String,
    /// The probe analysed.
    pub probe: String,
    /// Only samples from this time on.
    #[serde(default)]
    pub after: Option<Time>,
    /// Layer height for strains (creep, decay).
    #[serde(default)]
    pub height: Option<Length>,
    /// A published value to compare with (deflection in m or frequency in Hz).
    #[serde(default)]
    pub reference: Option<f64>,
    /// Where the reference comes from.
    #[serde(default)]
    pub reference_source: Option<String>,
}

impl Validate for AnalysisSpec {
    fn validate(&self, v: &mut Validator) {
        v.check(
            "kind",
            ANALYSIS_KINDS.contains(&self.kind.as_str()),
            format!(
                "\"{}\" is not an analysis (use one of: {})",
                self.kind,
                ANALYSIS_KINDS.join(", ")
            ),
        );
        if matches!(self.kind.as_str(), "creep" | "decay") {
            v.check("height", self.height.is_some(), "is required for strains");
        }
        if let Some(h) = self.height {
            v.positive("height", h);
        }
    }
}

impl Validate for SolidScene {
    fn validate(&self, v: &mut Validator) {
        v.nested("material", &self.material);
        v.each("fix", &self.fix);
        v.each("load", &self.load);
        v.each("probe", &self.probe);
        v.each("case", &self.case);
        if let Some(g) = &self.gravity {
            for (i, a) in g.iter().enumerate() {
                v.finite(&format!("gravity[{i}]"), *a);
            }
        }
        if let Some(q) = &self.qdem {
            v.nested("qdem", q);
        }
        if let Some(f) = &self.fem {
            v.nested("fem", f);
        }
        if let Some(a) = &self.analysis {
            v.nested("analysis", a);
            v.check(
                "analysis.probe",
                self.probe.iter().any(|p| p.name == a.probe),
                format!("no [[probe]] named \"{}\"", a.probe),
            );
        }
        let mut names: Vec<&str> = self.probe.iter().map(|p| p.name.as_str()).collect();
        names.sort_unstable();
        if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
            v.fail("probe", format!("two probes are named \"{}\"", w[0]));
        }
        let mut cases: Vec<&str> = self.case.iter().map(|c| c.name.as_str()).collect();
        cases.sort_unstable();
        if let Some(w) = cases.windows(2).find(|w| w[0] == w[1]) {
            v.fail("case", format!("two cases are named \"{}\"", w[0]));
        }
    }
}

impl SolidScene {
    /// A path of the scene resolved against the scene file's directory.
    pub fn resolve(scene_path: &Path, file: &Path) -> PathBuf {
        match scene_path.parent() {
            Some(dir) if file.is_relative() => dir.join(file),
            _ => file.to_path_buf(),
        }
    }

    /// The scene's variants: its `[[case]]` list, or one unnamed case.
    pub fn cases(&self) -> Vec<CaseSpec> {
        if self.case.is_empty() {
            vec![CaseSpec {
                name: String::new(),
                shear_viscosity: None,
                bulk_viscosity: None,
                fix: Vec::new(),
            }]
        } else {
            self.case.clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directions_parse() {
        assert_eq!(parse_directions("xyz"), Some(Directions::ALL));
        assert_eq!(parse_directions("z"), Some(Directions::Z));
        assert_eq!(parse_directions("xx"), None);
        assert_eq!(parse_directions(""), None);
        assert_eq!(parse_directions("xw"), None);
    }
}
