//! Post-processing: reports and metrics computed from meshes and results (mesh gallery,
//! stone-family statistics, the speed/accuracy chart, train loads for the track scene
//! the track sensors' spectra and the compactness of a packed bed).

mod chart;
pub mod compactness;
pub mod mesh_gallery;
pub mod speed_accuracy;
mod track_charts;
pub mod track_compare;
pub mod track_passages;
pub mod track_sensors;
pub mod track_spectra;
pub mod train_load;
