//! The packing file that `ballast-pack` writes and the solvers read: every stone's mesh
//! and rigid placement, the sleepers, the container.
//!
//! A TOML file; a placement maps the mesh file's coordinates (times `scale`) to the
//! world: `x_world = position + orientation · (scale · x_mesh)`, with the orientation a
//! unit quaternion `[w, x, y, z]`. Numbers are written in Rust's shortest round-trip
//! form, so a packing read back is the packing written, bit for bit.
//!
//! ```toml
//! format = "ballast-packing 1"
//! seed = 1
//! d50_m = 0.0416
//! container_min = [0.0, -0.6, 0.0]
//! container_max = [1.8, 0.6, 0.9]
//! sides = "walls"          # or "periodic": periodic along x (the track), walls in y
//! crib_top_m = 0.3         # the crib ballast's surface (optional)
//! settled = true           # whether the last build phase settled (optional)
//! capped_phases = ["final settle"] # phases run to their time cap (optional)
//! contacts = "contacts.csv" # the last step's contact impulses (optional; relative to
//!                           # the packing file; crate::pack::contacts)
//!
//! [[mesh]]                 # mesh files, relative to the packing file
//! file = "../../meshes/stones/stone_001.msh"
//! scale = 1.0
//! round_m = 0.012          # optional: the stone is its hull swept by this sphere
//! spheres_m = 0.024        # optional: contact spheres of this diameter at every
//!                          # surface node of the mesh (ballast-pack's stones.spheres)
//!
//! [[stone]]
//! mesh = 0                 # index into [[mesh]]
//! position = [0.1, 0.2, 0.05]
//! orientation = [1.0, 0.0, 0.0, 0.0]
//!
//! [[sleeper]]
//! size = [0.26, 1.0, 0.2]  # a cuboid centred on its position, or: mesh = <index>
//! position = [0.9, 0.0, 0.4]
//! orientation = [1.0, 0.0, 0.0, 0.0]
//! ```

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::Deserialize;

use crate::geometry::Period;
use crate::{Error, Result};

/// The side conditions a packing may have (see [`Packing::sides`]).
pub const SIDES: [&str; 2] = ["walls", "periodic"];

/// The format tag on the first line.
pub const PACKING_FORMAT: &str = "ballast-packing 1";

/// A mesh used by stones or sleepers.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PackedMesh {
    /// The file (relative to the packing file when read; as given when written).
    pub file: PathBuf,
    /// Factor on the mesh coordinates.
    pub scale: f64,
    /// The stone is its hull swept by a sphere of this radius (m; 0, the default: the
    /// bare hull), as `ballast-pack`'s `stones.round` packed it.
    #[serde(default)]
    pub round_m: f64,
    /// The body's contact shape is spheres of this diameter at every surface node of
    /// the mesh (m; 0, the default: none), as `ballast-pack`'s `stones.spheres` packed
    /// it.
    #[serde(default)]
    pub spheres_m: f64,
}

/// A rigid placement of a mesh (or a cuboid).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Placement {
    /// Index into [`Packing::meshes`] (absent for a cuboid).
    #[serde(default)]
    pub mesh: Option<usize>,
    /// Extents of a cuboid centred on `position` (absent for a mesh).
    #[serde(default)]
    pub size: Option<[f64; 3]>,
    /// Translation (m).
    pub position: [f64; 3],
    /// Rotation as a unit quaternion `[w, x, y, z]`.
    pub orientation: [f64; 4],
}

impl Placement {
    /// The rigid transform from the (scaled) mesh coordinates to the world.
    pub fn pose(&self) -> Isometry3<f64> {
        let [w, x, y, z] = self.orientation;
        Isometry3::from_parts(
            Translation3::from(Vector3::from(self.position)),
            UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z)),
        )
    }

    /// The placement of `pose`.
    pub fn from_pose(mesh: Option<usize>, size: Option<[f64; 3]>, pose: &Isometry3<f64>) -> Self {
        let t = pose.translation.vector;
        let q = pose.rotation.quaternion();
        Placement {
            mesh,
            size,
            position: [t.x, t.y, t.z],
            orientation: [q.w, q.i, q.j, q.k],
        }
    }
}

/// A packing: what `ballast-pack` builds.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Packing {
    /// Always [`PACKING_FORMAT`].
    pub format: String,
    /// The seed that built it.
    pub seed: u64,
    /// Median equivalent-sphere diameter of the stones (m).
    pub d50_m: f64,
    /// Lower corner of the container (m).
    pub container_min: [f64; 3],
    /// Upper corner of the container (m).
    pub container_max: [f64; 3],
    /// Side conditions: `"walls"` (four walls) or `"periodic"` (periodic along x, the
    /// track direction, over the container's length; walls across y).
    pub sides: String,
    /// Level of the crib ballast's struck-off surface (m); absent in older files.
    #[serde(default)]
    pub crib_top_m: Option<f64>,
    /// Whether the last phase of the build passed its settle test, so that the bed
    /// is at rest (ballast-pack's `summary.json` `settled`; files written before
    /// 2026-12-05 asked it of every phase); absent in older files. A bed written NOT
    /// SETTLED (its last phase stopped at its time cap) is still a bed, but the
    /// solvers that read it say that it does not start at rest
    /// ([`Packing::unsettled_note`]).
    #[serde(default)]
    pub settled: Option<bool>,
    /// The build's phases that ran to their time cap without settling (ballast-pack's
    /// `summary.json` `capped_phases`); empty when none did, and in older files. A bed
    /// whose last phase settled after an earlier one was capped is at rest under
    /// ballast-pack's test, yet it may still creep in a solver with another contact
    /// law (docs/pack.md, "A third impact bed"): the solvers say so.
    #[serde(default)]
    pub capped_phases: Vec<String>,
    /// The contact impulses of the packing's last step (a CSV, relative to the packing
    /// file when read; [`super::contacts`]), from which a restart starts warm.
    #[serde(default)]
    pub contacts: Option<PathBuf>,
    /// Meshes.
    #[serde(rename = "mesh")]
    pub meshes: Vec<PackedMesh>,
    /// Stones.
    #[serde(rename = "stone")]
    pub stones: Vec<Placement>,
    /// Sleepers.
    #[serde(default, rename = "sleeper")]
    pub sleepers: Vec<Placement>,
}

fn numbers(values: &[f64]) -> String {
    let parts: Vec<String> = values.iter().map(|v| format!("{v:?}")).collect();
    format!("[{}]", parts.join(", "))
}

fn quoted(path: &Path) -> String {
    quoted_text(&path.to_string_lossy())
}

/// A TOML basic string.
fn quoted_text(text: &str) -> String {
    format!("\"{}\"", text.replace('\\', "\\\\").replace('"', "\\\""))
}

impl Packing {
    /// The TOML text (round-trip exact).
    pub fn to_toml(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "format = \"{}\"", self.format);
        let _ = writeln!(out, "seed = {}", self.seed);
        let _ = writeln!(out, "d50_m = {:?}", self.d50_m);
        let _ = writeln!(out, "container_min = {}", numbers(&self.container_min));
        let _ = writeln!(out, "container_max = {}", numbers(&self.container_max));
        let _ = writeln!(out, "sides = \"{}\"", self.sides);
        if let Some(top) = self.crib_top_m {
            let _ = writeln!(out, "crib_top_m = {top:?}");
        }
        if let Some(settled) = self.settled {
            let _ = writeln!(out, "settled = {settled}");
        }
        if !self.capped_phases.is_empty() {
            let names: Vec<String> = self
                .capped_phases
                .iter()
                .map(|name| quoted_text(name))
                .collect();
            let _ = writeln!(out, "capped_phases = [{}]", names.join(", "));
        }
        if let Some(contacts) = &self.contacts {
            let _ = writeln!(out, "contacts = {}", quoted(contacts));
        }
        for m in &self.meshes {
            let _ = writeln!(
                out,
                "\n[[mesh]]\nfile = {}\nscale = {:?}",
                quoted(&m.file),
                m.scale
            );
            if m.round_m != 0.0 {
                let _ = writeln!(out, "round_m = {:?}", m.round_m);
            }
            if m.spheres_m != 0.0 {
                let _ = writeln!(out, "spheres_m = {:?}", m.spheres_m);
            }
        }
        for (table, list) in [("stone", &self.stones), ("sleeper", &self.sleepers)] {
            for p in list {
                let _ = writeln!(out, "\n[[{table}]]");
                if let Some(mesh) = p.mesh {
                    let _ = writeln!(out, "mesh = {mesh}");
                }
                if let Some(size) = p.size {
                    let _ = writeln!(out, "size = {}", numbers(&size));
                }
                let _ = writeln!(out, "position = {}", numbers(&p.position));
                let _ = writeln!(out, "orientation = {}", numbers(&p.orientation));
            }
        }
        out
    }

    /// Writes the packing atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::output::write_atomic(path, self.to_toml().as_bytes())
    }

    /// A one-line note for a solver (`tool`) reading the packing at `path` when the
    /// packing says it did not settle (`settled = false`), or that some phase of its
    /// build ran to its time cap; `None` otherwise.
    pub fn unsettled_note(&self, tool: &str, path: &Path) -> Option<String> {
        if self.settled == Some(false) {
            return Some(format!(
                "{tool}: note: {} was written NOT SETTLED (its last build phase stopped \
                 at its time cap; its summary.json gives the phases and the deepest \
                 overlap): the bed does not start at rest",
                path.display()
            ));
        }
        (!self.capped_phases.is_empty()).then(|| {
            format!(
                "{tool}: note: {} was built with phases run to their time cap ({}); its \
                 last phase settled, but such a bed may still creep (docs/pack.md, \
                 \"A third impact bed\")",
                path.display(),
                self.capped_phases.join(", ")
            )
        })
    }

    /// The periodicity of a `"periodic"` packing: along x over the container's length.
    pub fn period(&self) -> Option<Period> {
        (self.sides == "periodic").then(|| Period {
            axis: 0,
            low: self.container_min[0],
            length: self.container_max[0] - self.container_min[0],
        })
    }

    /// Reads and checks a packing file; mesh paths come back resolved against the
    /// packing file's directory. Errors are one line naming the file and the key.
    pub fn read(path: &Path) -> Result<Packing> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let mut packing = Self::parse(path, &text)?;
        let base = path.parent().unwrap_or(Path::new("."));
        for m in &mut packing.meshes {
            if m.file.is_relative() {
                m.file = base.join(&m.file);
            }
        }
        if let Some(c) = &mut packing.contacts {
            if c.is_relative() {
                *c = base.join(&*c);
            }
        }
        Ok(packing)
    }

    /// Parses and checks packing text (`path` names it in errors; paths unresolved).
    pub fn parse(path: &Path, text: &str) -> Result<Packing> {
        let table = crate::scene::parse_table(path, text)?;
        let packing: Packing =
            crate::scene::deserialize_table(&table).map_err(|m| Error::invalid(path, m))?;
        packing.check().map_err(|m| Error::invalid(path, m))?;
        Ok(packing)
    }

    /// The checks that serde cannot make: format tag, indices, unit quaternions, sizes.
    fn check(&self) -> std::result::Result<(), String> {
        if self.format != PACKING_FORMAT {
            return Err(format!(
                "key format: \"{}\" is not \"{PACKING_FORMAT}\"",
                self.format
            ));
        }
        if !SIDES.contains(&self.sides.as_str()) {
            return Err(format!(
                "key sides: \"{}\" is not one of \"walls\" or \"periodic\"",
                self.sides
            ));
        }
        for (i, m) in self.meshes.iter().enumerate() {
            if !(m.scale.is_finite() && m.scale > 0.0) {
                return Err(format!("key mesh[{i}].scale: must be a positive number"));
            }
            for (key, value) in [("round_m", m.round_m), ("spheres_m", m.spheres_m)] {
                if !(value.is_finite() && value >= 0.0) {
                    return Err(format!("key mesh[{i}].{key}: must be a number ≥ 0"));
                }
            }
        }
        for (table, list) in [("stone", &self.stones), ("sleeper", &self.sleepers)] {
            for (i, p) in list.iter().enumerate() {
                let key = format!("{table}[{i}]");
                match (p.mesh, p.size) {
                    (Some(m), None) if m >= self.meshes.len() => {
                        return Err(format!(
                            "key {key}.mesh: index {m} but the file lists {} meshes",
                            self.meshes.len()
                        ))
                    }
                    (Some(_), None) => {}
                    (None, Some(size)) => {
                        if !size.iter().all(|s| s.is_finite() && *s > 0.0) {
                            return Err(format!("key {key}.size: must be positive numbers"));
                        }
                    }
                    _ => return Err(format!("key {key}: give exactly one of mesh or size")),
                }
                if !p.position.iter().all(|x| x.is_finite()) {
                    return Err(format!("key {key}.position: must be finite numbers"));
                }
                let norm = p.orientation.iter().map(|q| q * q).sum::<f64>().sqrt();
                let unit = (norm - 1.0).abs() < 1e-9;
                if !unit {
                    return Err(format!(
                        "key {key}.orientation: not a unit quaternion [w, x, y, z] (norm {norm})"
                    ));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Packing {
        Packing {
            format: PACKING_FORMAT.to_string(),
            seed: 3,
            d50_m: 0.1 + 0.2,
            container_min: [0.0, -0.5, 0.0],
            container_max: [1.0, 0.5, 1.0 / 3.0],
            sides: "walls".into(),
            crib_top_m: Some(0.25),
            settled: Some(false),
            capped_phases: vec!["final settle".into()],
            contacts: Some("contacts.csv".into()),
            meshes: vec![
                PackedMesh {
                    file: "stones/stone_001.msh".into(),
                    scale: 1.0,
                    round_m: 0.012,
                    spheres_m: 0.0,
                },
                PackedMesh {
                    file: "stones/stone_002.msh".into(),
                    scale: 1.5,
                    round_m: 0.0,
                    spheres_m: 0.024,
                },
            ],
            stones: vec![Placement::from_pose(
                Some(0),
                None,
                &Isometry3::new(Vector3::new(0.1, 0.2, 0.3), Vector3::new(0.3, -0.2, 0.7)),
            )],
            sleepers: vec![Placement {
                mesh: None,
                size: Some([0.26, 1.0, 0.2]),
                position: [0.5, 0.0, 0.4],
                orientation: [1.0, 0.0, 0.0, 0.0],
            }],
        }
    }

    #[test]
    fn a_packing_reads_back_bit_for_bit() {
        let packing = sample();
        let text = packing.to_toml();
        let back = Packing::parse(Path::new("p.toml"), &text).unwrap();
        assert_eq!(back, packing);
        assert_eq!(back.to_toml(), text);
    }

    #[test]
    fn an_unsettled_packing_gets_a_note_naming_its_file() {
        let mut packing = sample();
        let note = packing.unsettled_note("tool", Path::new("beds/p.toml"));
        assert!(note.is_some_and(|n| n.starts_with("tool: note: beds/p.toml")));
        // Settled at the end, but an earlier phase capped: a note naming the phase.
        packing.settled = Some(true);
        let note = packing.unsettled_note("tool", Path::new("p.toml"));
        assert!(
            note.as_ref()
                .is_some_and(|n| n.starts_with("tool: note: p.toml") && n.contains("final settle")),
            "{note:?}"
        );
        packing.capped_phases.clear();
        for settled in [Some(true), None] {
            packing.settled = settled;
            assert_eq!(packing.unsettled_note("tool", Path::new("p.toml")), None);
        }
    }

    #[test]
    fn malformed_packings_name_the_key() {
        let text = sample().to_toml();
        let cases = [
            (text.replace("mesh = 0", "mesh = 4"), "stone[0].mesh"),
            (
                text.replace("round_m = 0.012", "round_m = -0.01"),
                "mesh[0].round_m",
            ),
            (
                text.replace("spheres_m = 0.024", "spheres_m = nan"),
                "mesh[1].spheres_m",
            ),
            (
                text.replace(
                    "orientation = [1.0, 0.0, 0.0, 0.0]",
                    "orientation = [2.0, 0.0, 0.0, 0.0]",
                ),
                "sleeper[0].orientation",
            ),
            (
                text.replace("ballast-packing 1", "ballast-packing 9"),
                "format",
            ),
            (
                text.replace("position = [0.5", "position = [\"x\""),
                "sleeper",
            ),
            (text.replace("seed = 3", "seed = 3\ncolour = 1"), "colour"),
        ];
        for (bad, key) in cases {
            let err = Packing::parse(Path::new("p.toml"), &bad)
                .unwrap_err()
                .to_string();
            assert!(err.contains("p.toml") && err.contains(key), "{err}");
            assert_eq!(err.lines().count(), 1, "{err}");
        }
    }
}
