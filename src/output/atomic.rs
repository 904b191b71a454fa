//! Atomic file replacement: write to a temporary name beside the target, flush it to disk,
//! then rename it over the target. A reader (or a resumed run) sees either the old file or
//! the complete new one, never a truncated frame.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// Writes `bytes` to `path` atomically, creating missing parent directories.
///
/// The data go to `<dir>/.<name>.tmp.<pid>` first, are synced to disk, and the temporary
/// file is renamed over `path`. On failure the temporary file is removed and the error
/// names `path`.
pub fn write_atomic(path: impl AsRef<Path>, bytes: &[u8]) -> Result<()> {
    let mut file = AtomicFile::create(path)?;
    file.write_all(bytes)
        .map_err(|e| Error::io(file.target(), e))?;
    file.commit()
}

/// A file being written under a temporary name; [`AtomicFile::commit`] renames it over
/// the target. Dropped without a commit, it removes its temporary file and leaves the
/// target untouched.
#[derive(Debug)]
pub struct AtomicFile {
    target: PathBuf,
    temporary: PathBuf,
    // `None` once committed (or after a failed commit).
    file: Option<io::BufWriter<File>>,
}

impl AtomicFile {
    /// Opens a temporary file beside `path` (creating missing parent directories).
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        let target = path.as_ref().to_path_buf();
        let name = target.file_name().ok_or_else(|| {
            Error::io(
                &target,
                io::Error::new(io::ErrorKind::InvalidInput, "not a file name"),
            )
        })?;
        let parent = parent_dir(&target);
        fs::create_dir_all(parent).map_err(|e| Error::io(&target, e))?;
        let mut temporary_name = std::ffi::OsString::from(".");
        temporary_name.push(name);
        temporary_name.push(format!(".tmp.{}", std::process::id()));
        let temporary = parent.join(temporary_name);
        let file = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&temporary)
            .map_err(|e| Error::io(&target, e))?;
        Ok(AtomicFile {
            target,
            temporary,
            file: Some(io::BufWriter::new(file)),
        })
    }

    /// The path that [`AtomicFile::commit`] will replace.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Flushes and syncs the data, then renames the temporary file over the target.
    pub fn commit(mut self) -> Result<()> {
        let Some(writer) = self.file.take() else {
            return Err(Error::Message(format!(
                "{}: atomic file already committed",
                self.target.display()
            )));
        };
        let result = (|| -> io::Result<()> {
            let file = writer.into_inner().map_err(|e| e.into_error())?;
            file.sync_all()?;
            drop(file);
            fs::rename(&self.temporary, &self.target)
        })();
        if let Err(e) = result {
            let _ = fs::remove_file(&self.temporary);
            return Err(Error::io(&self.target, e));
        }
        sync_dir(parent_dir(&self.target));
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match &mut self.file {
            Some(file) => file.write(buf),
            None => Err(io::Error::other("atomic file already committed")),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match &mut self.file {
            Some(file) => file.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            let _ = fs::remove_file(&self.temporary);
        }
    }
}

/// The directory holding `path` (`.` for a bare file name).
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    }
}

/// Makes a rename durable where the platform allows it; a failure here loses nothing that
/// the rename has not already made visible, so it is ignored.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(handle) = File::open(dir) {
        let _ = handle.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn writes_and_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frames").join("step_000001.vtu");
        write_atomic(&path, b"first").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"first");
        assert_eq!(entries(&dir.path().join("frames")), ["step_000001.vtu"]);
    }

    #[test]
    fn replaces_an_existing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("summary.json");
        fs::write(&path, b"old content that is longer").unwrap();
        write_atomic(&path, b"new").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"new");
        assert_eq!(entries(dir.path()), ["summary.json"]);
    }

    #[test]
    fn failing_write_names_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("not_a_dir");
        fs::write(&blocker, b"a file").unwrap();
        let path = blocker.join("frame.vtu");
        let error = write_atomic(&path, b"data").unwrap_err();
        assert!(matches!(error, Error::Io { .. }), "{error:?}");
        let message = error.to_string();
        assert!(
            message.contains(&path.display().to_string()),
            "error should name {}: {message}",
            path.display()
        );
        assert_eq!(entries(dir.path()), ["not_a_dir"]);
    }

    #[test]
    fn dropped_without_commit_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("series.csv");
        fs::write(&path, b"old").unwrap();
        {
            let mut file = AtomicFile::create(&path).unwrap();
            file.write_all(b"half a fr").unwrap();
        }
        assert_eq!(fs::read(&path).unwrap(), b"old");
        assert_eq!(entries(dir.path()), ["series.csv"]);
    }

    #[test]
    fn bare_file_name_is_in_the_current_directory() {
        assert_eq!(parent_dir(Path::new("run.json")), Path::new("."));
        assert_eq!(parent_dir(Path::new("a/run.json")), Path::new("a"));
    }
}
