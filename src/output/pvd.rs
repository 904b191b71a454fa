//! ParaView collections (`.pvd`): a list of (time, frame file) rewritten atomically after
//! each frame, so a killed run leaves a `.pvd` that lists only complete frames.

use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use super::atomic::write_atomic;
use super::grid::Grid;
use super::vtu::write_vtu;
use crate::{Error, Result};

/// One frame of a collection.
#[derive(Clone, Debug, PartialEq)]
pub struct PvdEntry {
    /// Simulation time of the frame, in seconds.
    pub time: f64,
    /// The frame file, relative to the `.pvd`'s directory, with `/` separators.
    pub file: String,
}

/// Writes a `.pvd` collection frame by frame.
#[derive(Debug)]
pub struct PvdWriter {
    path: PathBuf,
    entries: Vec<PvdEntry>,
}

impl PvdWriter {
    /// Starts an empty collection at `path` and writes it (replacing any old one).
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        let writer = PvdWriter {
            path: path.as_ref().to_path_buf(),
            entries: Vec::new(),
        };
        writer.write()?;
        Ok(writer)
    }

    /// Reopens a collection this writer wrote before (to resume a run), keeping only the
    /// frames with `time <= keep_until_time`, and rewrites it. The frame files of dropped
    /// entries are left on disk; the resumed run overwrites them.
    pub fn open_existing(path: impl AsRef<Path>, keep_until_time: f64) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let mut entries = parse_entries(&text).map_err(|what| Error::invalid(path, what))?;
        entries.retain(|entry| entry.time <= keep_until_time);
        let writer = PvdWriter {
            path: path.to_path_buf(),
            entries,
        };
        writer.write()?;
        Ok(writer)
    }

    /// The `.pvd` file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The frames listed so far, in order.
    pub fn entries(&self) -> &[PvdEntry] {
        &self.entries
    }

    /// The directory that frame paths are relative to.
    pub fn base_dir(&self) -> &Path {
        match self.path.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent,
            _ => Path::new("."),
        }
    }

    /// Writes `grid` to `relative_file` (relative to the `.pvd`'s directory, e.g.
    /// `frames/step_000010.vtu`), then lists it at `time`.
    pub fn write_frame(
        &mut self,
        time: f64,
        relative_file: impl AsRef<Path>,
        grid: &Grid,
    ) -> Result<()> {
        let relative_file = relative_file.as_ref();
        let file = self.relative_name(relative_file)?;
        self.check_time(time)?;
        write_vtu(self.base_dir().join(relative_file), grid)?;
        self.push(time, file)
    }

    /// Lists an already written frame file at `time` and rewrites the `.pvd`. `file` is
    /// relative to the `.pvd`'s directory, or an absolute path inside it.
    pub fn add_frame(&mut self, time: f64, file: impl AsRef<Path>) -> Result<()> {
        let file = self.relative_name(file.as_ref())?;
        self.check_time(time)?;
        self.push(time, file)
    }

    fn push(&mut self, time: f64, file: String) -> Result<()> {
        self.entries.push(PvdEntry { time, file });
        if let Err(error) = self.write() {
            self.entries.pop();
            return Err(error);
        }
        Ok(())
    }

    fn check_time(&self, time: f64) -> Result<()> {
        if !time.is_finite() {
            return Err(Error::Message(format!(
                "{}: frame time {time} is not finite",
                self.path.display()
            )));
        }
        if let Some(last) = self.entries.last() {
            if time < last.time {
                return Err(Error::Message(format!(
                    "{}: frame time {time} s is before the previous frame's {} s",
                    self.path.display(),
                    last.time
                )));
            }
        }
        Ok(())
    }

    /// `file` as the `/`-separated path relative to the base directory.
    fn relative_name(&self, file: &Path) -> Result<String> {
        let relative = if file.is_absolute() {
            let base =
                std::path::absolute(self.base_dir()).map_err(|e| Error::io(&self.path, e))?;
            file.strip_prefix(&base).map_err(|_| {
                Error::Message(format!(
                    "{}: frame {} is not inside {}",
                    self.path.display(),
                    file.display(),
                    base.display()
                ))
            })?
        } else {
            file
        };
        let mut parts = Vec::new();
        for component in relative.components() {
            match component {
                Component::Normal(part) => parts.push(part.to_str().ok_or_else(|| {
                    Error::Message(format!("frame path {} is not UTF-8", file.display()))
                })?),
                Component::CurDir => {}
                _ => {
                    return Err(Error::Message(format!(
                        "{}: frame path {} must stay inside the collection's directory",
                        self.path.display(),
                        file.display()
                    )))
                }
            }
        }
        if parts.is_empty() {
            return Err(Error::Message(format!(
                "{}: empty frame path",
                self.path.display()
            )));
        }
        Ok(parts.join("/"))
    }

    fn write(&self) -> Result<()> {
        write_atomic(&self.path, render(&self.entries).as_bytes())
    }
}

/// The `.pvd` text for `entries`. Times are written in Rust's shortest round-trip form,
/// so they read back bit for bit.
fn render(entries: &[PvdEntry]) -> String {
    let mut text = String::from(
        "<?xml version=\"1.0\"?>\n\
         <VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n",
    );
    for entry in entries {
        let _ = writeln!(
            text,
            "    <DataSet timestep=\"{}\" group=\"\" part=\"0\" file=\"{}\"/>",
            entry.time,
            escape(&entry.file)
        );
    }
    text.push_str("  </Collection>\n</VTKFile>\n");
    text
}

/// Reads the entries of a `.pvd` written by [`render`] (or one like it: `DataSet`
/// elements with `timestep` and `file` attributes).
fn parse_entries(text: &str) -> std::result::Result<Vec<PvdEntry>, String> {
    if !text.contains("type=\"Collection\"") {
        return Err("not a VTK collection (no type=\"Collection\")".into());
    }
    let mut entries = Vec::new();
    let mut rest = text;
    while let Some(start) = rest.find("<DataSet") {
        let line = 1 + text[..text.len() - rest.len() + start]
            .matches('\n')
            .count();
        let after = &rest[start + "<DataSet".len()..];
        let end = after
            .find('>')
            .ok_or_else(|| format!("line {line}: unterminated DataSet element"))?;
        let tag = &after[..end];
        let time_text = attribute(tag, "timestep")
            .ok_or_else(|| format!("line {line}: DataSet without timestep"))?;
        let time: f64 = time_text
            .trim()
            .parse()
            .map_err(|_| format!("line {line}: timestep \"{time_text}\" is not a number"))?;
        let file =
            attribute(tag, "file").ok_or_else(|| format!("line {line}: DataSet without file"))?;
        entries.push(PvdEntry { time, file });
        rest = &after[end..];
    }
    Ok(entries)
}

/// The unescaped value of attribute `name` in the inside of a tag.
fn attribute(tag: &str, name: &str) -> Option<String> {
    let mut search = tag;
    loop {
        let at = search.find(name)?;
        let preceded_by_space = at == 0 || search[..at].ends_with(char::is_whitespace);
        let after = search[at + name.len()..].trim_start();
        if preceded_by_space {
            if let Some(value) = after.strip_prefix('=') {
                let value = value.trim_start();
                let quote = value.chars().next()?;
                if quote == '"' || quote == '\'' {
                    let inner = &value[1..];
                    let close = inner.find(quote)?;
                    return Some(unescape(&inner[..close]));
                }
            }
        }
        search = &search[at + name.len()..];
    }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
}

fn unescape(text: &str) -> String {
    text.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&apos;", "'")
        .replace("&amp;", "&")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rewrites_after_each_frame_and_reopens() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("impact.pvd");
        let mut pvd = PvdWriter::create(&path).unwrap();
        assert!(std::fs::read_to_string(&path)
            .unwrap()
            .contains("<Collection>"));
        let times = [0.0, 1e-7, 0.1 + 0.2, 2.5];
        for (i, &time) in times.iter().enumerate() {
            pvd.add_frame(time, format!("frames/step_{i:06}.vtu"))
                .unwrap();
            let listed = parse_entries(&std::fs::read_to_string(&path).unwrap()).unwrap();
            assert_eq!(listed.len(), i + 1);
        }
        let absolute = std::path::absolute(dir.path().join("frames/a&b.vtu")).unwrap();
        pvd.add_frame(3.0, &absolute).unwrap();
        assert_eq!(pvd.entries().last().unwrap().file, "frames/a&b.vtu");

        let reopened = PvdWriter::open_existing(&path, 0.1 + 0.2).unwrap();
        let kept: Vec<f64> = reopened.entries().iter().map(|e| e.time).collect();
        assert_eq!(kept, [0.0, 1e-7, 0.1 + 0.2]);
        assert_eq!(reopened.entries()[2].file, "frames/step_000002.vtu");
        let on_disk = parse_entries(&std::fs::read_to_string(&path).unwrap()).unwrap();
        assert_eq!(on_disk, reopened.entries());
    }

    #[test]
    fn rejects_bad_times_and_paths() {
        let dir = tempfile::tempdir().unwrap();
        let mut pvd = PvdWriter::create(dir.path().join("run.pvd")).unwrap();
        pvd.add_frame(1.0, "a.vtu").unwrap();
        assert!(pvd.add_frame(0.5, "b.vtu").is_err());
        assert!(pvd.add_frame(f64::NAN, "b.vtu").is_err());
        assert!(pvd.add_frame(2.0, "../b.vtu").is_err());
        assert!(pvd.add_frame(2.0, "/elsewhere/b.vtu").is_err());
        assert_eq!(pvd.entries().len(), 1);
    }

    #[test]
    fn reports_a_broken_collection() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("broken.pvd");
        std::fs::write(
            &path,
            "<VTKFile type=\"Collection\">\n<Collection>\n<DataSet timestep=\"x\" file=\"a.vtu\"/>",
        )
        .unwrap();
        let error = PvdWriter::open_existing(&path, 1.0)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("broken.pvd") && error.contains("line 3"),
            "{error}"
        );
        let missing = PvdWriter::open_existing(dir.path().join("none.pvd"), 1.0).unwrap_err();
        assert!(matches!(missing, Error::Io { .. }));
    }
}
