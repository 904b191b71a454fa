//! Result files: VTK XML unstructured grids (`.vtu`) and collections (`.pvd`), JSON
//! summaries and CSV series, each written to a temporary name and renamed so a killed run
//! never leaves a truncated file.
