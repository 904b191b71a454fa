//! Scene files (TOML) and the run contract shared by every solver binary:
//! `ballast-X SCENE.toml [--preset NAME] [--out DIR] [--threads N]`.
