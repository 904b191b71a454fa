//! Checkpoint files shared by the solvers that resume a killed run (`ballast-nscd`,
//! `ballast-qdem` track scenes).
//!
//! A checkpoint is one bincode record (f64 kept bit for bit) whose first two fields are
//! a format tag and the merged scene text (after preset and `--set`), followed by
//! whatever the solver needs to continue. It is written whole to a temporary file and
//! renamed over the previous one, so a run killed at any moment leaves the previous
//! checkpoint or the new one, never half of one. Reading checks the tag and the scene
//! before decoding the rest, so a damaged file, another tool's file and a checkpoint
//! of another scene each give one line naming the file.

use std::path::Path;

use serde::{de::DeserializeOwned, Deserialize, Serialize};

use crate::{Error, Result};

/// The file name in a run's output directory.
pub const CHECKPOINT_FILE: &str = "checkpoint.bin";

/// The leading fields every checkpoint record starts with.
#[derive(Deserialize)]
struct Header {
    format: String,
    scene: String,
}

/// Writes `record` (a struct whose first fields are `format: String, scene: String`)
/// atomically to `path`.
pub fn write_checkpoint<T: Serialize>(path: &Path, record: &T) -> Result<()> {
    let bytes = bincode::serialize(record)
        .map_err(|e| Error::invalid(path, format!("cannot encode the checkpoint: {e}")))?;
    crate::output::write_atomic(path, &bytes)
}

/// Reads a checkpoint written by [`write_checkpoint`], checking that its tag is
/// `format` and that it was written for `scene` (the merged scene text).
pub fn read_checkpoint<T: DeserializeOwned>(path: &Path, format: &str, scene: &str) -> Result<T> {
    read_checkpoint_matching(path, format, |saved| saved == scene)
}

/// [`read_checkpoint`] with the scene test given: `matches(saved)` says whether the
/// saved merged scene text is one the current run may continue (a tool that lets a
/// resumed run change a run-control key compares the scenes without it).
pub fn read_checkpoint_matching<T: DeserializeOwned>(
    path: &Path,
    format: &str,
    matches: impl Fn(&str) -> bool,
) -> Result<T> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let not_ours = |e: &dyn std::fmt::Display| {
        Error::invalid(path, format!("not a {format} file of this version ({e})"))
    };
    // bincode's default decoding stops after the header and ignores the rest.
    let header: Header = bincode::deserialize(&bytes).map_err(|e| not_ours(&e))?;
    if header.format != format {
        return Err(Error::invalid(
            path,
            format!("format \"{}\", expected \"{format}\"", header.format),
        ));
    }
    if !matches(&header.scene) {
        return Err(Error::invalid(
            path,
            "was written for another scene, preset or --set (resume with the same \
             arguments as the killed run)",
        ));
    }
    bincode::deserialize(&bytes).map_err(|e| not_ours(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Record {
        format: String,
        scene: String,
        x: Vec<f64>,
    }

    #[test]
    fn a_checkpoint_reads_back_and_refuses_other_tags_scenes_and_junk() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(CHECKPOINT_FILE);
        let record = Record {
            format: "tool checkpoint 1".into(),
            scene: "a = 1\n".into(),
            x: vec![0.1, f64::MIN_POSITIVE, -3.0e300],
        };
        write_checkpoint(&path, &record).unwrap();
        let back: Record = read_checkpoint(&path, "tool checkpoint 1", "a = 1\n").unwrap();
        assert_eq!(back, record);
        let err = |format: &str, scene: &str| {
            read_checkpoint::<Record>(&path, format, scene)
                .unwrap_err()
                .to_string()
        };
        assert!(err("other checkpoint 1", "a = 1\n").contains("expected \"other"));
        assert!(err("tool checkpoint 1", "a = 2\n").contains("another scene"));
        std::fs::write(&path, b"junk").unwrap();
        let junk = err("tool checkpoint 1", "a = 1\n");
        assert!(junk.contains("not a tool checkpoint 1 file"), "{junk}");
        assert!(
            junk.contains(CHECKPOINT_FILE) && !junk.contains('\n'),
            "{junk}"
        );
    }
}
