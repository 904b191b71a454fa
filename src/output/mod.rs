//! Result files: VTK XML unstructured grids (`.vtu`) and collections (`.pvd`), JSON
//! summaries and CSV series, each written to a temporary name and renamed so a killed run
//! never leaves a truncated file.
//!
//! Solvers fill a [`Grid`] (points, tetra/triangle/line/vertex cells, named fields with
//! units in their names) and hand it to [`write_vtu`] or to a [`PvdWriter`]:
//!
//! ```no_run
//! # fn main() -> ballast::Result<()> {
//! use ballast::output::{Grid, PvdWriter};
//! let points = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
//! let mut grid = Grid::tetra(points, &[[0, 1, 2, 3]])?;
//! grid.add_point_field("displacement_m", 3, vec![0.0; 12])?;
//! grid.add_cell_field("von_mises_Pa", 1, vec![1.0e5])?;
//! let mut pvd = PvdWriter::create("results/cantilever/cantilever.pvd")?;
//! pvd.write_frame(0.0, "frames/step_000000.vtu", &grid)?;
//! # Ok(())
//! # }
//! ```

pub mod atomic;
pub mod checkpoint;
pub mod csv;
pub mod grid;
pub mod json;
pub mod progress;
pub mod pvd;
pub mod vtu;

pub use atomic::{write_atomic, AtomicFile};
pub use checkpoint::{
    default_checkpoint_wall_every, read_checkpoint, read_checkpoint_allowing,
    read_checkpoint_matching, write_checkpoint, Cadence, RunClocks, CHECKPOINT_FILE,
};
pub use csv::CsvSeries;
pub use grid::{points_from_nalgebra, CellKind, Field, FieldValues, Grid};
pub use json::write_json;
pub use progress::Progress;
pub use pvd::{PvdEntry, PvdWriter};
pub use vtu::{vtu_bytes, write_vtu};
