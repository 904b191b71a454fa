//! Post-processing: reports and metrics computed from meshes and results (mesh gallery,
//! stone-family statistics, the speed/accuracy chart, train loads for the track scene
//! and the track sensors' spectra; later compactness).

mod chart;
pub mod mesh_gallery;
pub mod speed_accuracy;
mod track_charts;
pub mod track_compare;
pub mod track_sensors;
pub mod track_spectra;
pub mod train_load;
