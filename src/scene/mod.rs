//! Scene files (TOML) and the run contract shared by every solver binary:
//! `ballast-X SCENE.toml [--preset NAME] [--out DIR] [--threads N]`.
//!
//! A solver defines its own scene struct (`#[serde(deny_unknown_fields)]`, quantity
//! types such as [`Length`] or [`Pressure`] for dimensional values, [`Material`] for
//! materials), implements [`Validate`] for its physical checks and calls
//! [`load_scene`] (or [`RunContext::load_scene`]). Every failure is one line naming the
//! file, the dotted key and the reason:
//!
//! ```text
//! scenes/cantilever.toml: key material.density: must be positive, got -2350 kg/m^3
//! scenes/cantilever.toml: unknown key material.densty (expected one of: name, density, …)
//! ```
//!
//! A preset is a table `[preset.NAME]` of the scene file deep-merged over the base
//! (`quick` for tests, `paper` for the published sizes).
//!
//! Avoid `#[serde(flatten)]` and untagged enums in scene structs: serde then buffers
//! the values, which loses both `deny_unknown_fields` and the key path of errors.

mod ddm;
mod load;
mod material;
mod quantity;
mod run;
mod summary;
pub mod units;
mod validate;

pub use ddm::DdmSpec;
pub use load::{
    apply_preset, deserialize_table, load_scene, load_scene_with_overrides, load_scene_with_source,
    merge_tables, parse_table, scene_from_str, PRESET_TABLE,
};
pub use material::Material;
pub use quantity::{
    format_si, Acceleration, Angle, Density, Force, Frequency, Length, Mass, Measure, Pressure,
    Stiffness, StiffnessPerArea, Time, Velocity, Viscosity,
};
pub use run::{default_out_dir, RunArgs, RunContext};
pub use summary::{toml_table_to_json, toml_to_json, PhaseTimer, Summary};
pub use validate::{Validate, Validator};

/// `true`: the serde default of a switch that is on unless the scene turns it off
/// (`#[serde(default = "crate::scene::yes")]`).
pub fn yes() -> bool {
    true
}
