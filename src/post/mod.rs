//! Post-processing: reports and metrics computed from meshes and results (mesh gallery,
//! stone-family statistics, the speed/accuracy chart, train loads for the track scene,
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

/// Reads a JSON file (a run's `summary.json`); errors name the file.
pub(crate) fn read_json(path: &std::path::Path) -> crate::Result<serde_json::Value> {
    let text = std::fs::read_to_string(path).map_err(|e| crate::Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| crate::Error::invalid(path, format!("not JSON: {e}")))
}
