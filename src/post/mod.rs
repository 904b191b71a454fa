//! Post-processing: reports and metrics computed from meshes and results (mesh gallery,
//! stone-family statistics; later spectra, compactness and charts).

pub mod mesh_gallery;
pub mod speed_accuracy;
