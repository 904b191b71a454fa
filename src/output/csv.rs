//! CSV time series: a header of named columns (units in the names, time first), then one
//! row of numbers per record, each row written whole so a killed run loses at most the row
//! being written.

use std::fmt::Write as _;
use std::fs::{File, OpenOptions};
use std::io::Write as _;
use std::path::{Path, PathBuf};

use super::atomic::write_atomic;
use crate::{Error, Result};

/// An open CSV series; rows are appended and reach the file as each is pushed.
#[derive(Debug)]
pub struct CsvSeries {
    path: PathBuf,
    columns: Vec<String>,
    file: File,
}

impl CsvSeries {
    /// Creates (or replaces) `path` with a header of `columns`, e.g.
    /// `["time_s", "kinetic_energy_J"]`. The first column is the time by convention.
    pub fn create(path: impl AsRef<Path>, columns: &[&str]) -> Result<Self> {
        let path = path.as_ref();
        let columns = check_columns(path, columns)?;
        write_atomic(path, header(&columns).as_bytes())?;
        Self::append_to(path, columns)
    }

    /// Reopens a series written before (to resume a run): checks that its header is
    /// `columns`, keeps the rows up to the first whose time (first column) exceeds
    /// `keep_until_time`, drops an unfinished last line, and appends from there.
    pub fn open_existing(
        path: impl AsRef<Path>,
        columns: &[&str],
        keep_until_time: f64,
    ) -> Result<Self> {
        let path = path.as_ref();
        let columns = check_columns(path, columns)?;
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let expected = header(&columns);
        if !text.starts_with(&expected) {
            let found = text.lines().next().unwrap_or("");
            return Err(Error::invalid(
                path,
                format!(
                    "line 1: header \"{found}\" differs from \"{}\"",
                    expected.trim_end()
                ),
            ));
        }
        let mut kept = expected.clone();
        // Only lines that end in a newline were written whole.
        let body = &text[expected.len()..];
        let complete = &body[..body.rfind('\n').map_or(0, |end| end + 1)];
        for (index, line) in complete.lines().enumerate() {
            let first = line.split(',').next().unwrap_or("").trim();
            let time: f64 = first.parse().map_err(|_| {
                Error::invalid(
                    path,
                    format!("line {}: time \"{first}\" is not a number", index + 2),
                )
            })?;
            if time > keep_until_time {
                break;
            }
            kept.push_str(line);
            kept.push('\n');
        }
        write_atomic(path, kept.as_bytes())?;
        Self::append_to(path, columns)
    }

    fn append_to(path: &Path, columns: Vec<String>) -> Result<Self> {
        let file = OpenOptions::new()
            .append(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        Ok(CsvSeries {
            path: path.to_path_buf(),
            columns,
            file,
        })
    }

    /// Appends one row, one value per column, in shortest round-trip form.
    pub fn push(&mut self, row: &[f64]) -> Result<()> {
        if row.len() != self.columns.len() {
            return Err(Error::Message(format!(
                "{}: row of {} values for {} columns",
                self.path.display(),
                row.len(),
                self.columns.len()
            )));
        }
        let mut line = String::with_capacity(row.len() * 24);
        for (i, value) in row.iter().enumerate() {
            if i > 0 {
                line.push(',');
            }
            let _ = write!(line, "{value:?}");
        }
        line.push('\n');
        // One write per row: a reader never sees half of it unless the run dies mid-call.
        self.file
            .write_all(line.as_bytes())
            .map_err(|e| Error::io(&self.path, e))
    }

    /// The series' file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The column names.
    pub fn columns(&self) -> &[String] {
        &self.columns
    }
}

fn check_columns(path: &Path, columns: &[&str]) -> Result<Vec<String>> {
    if columns.is_empty() {
        return Err(Error::Message(format!("{}: no columns", path.display())));
    }
    if let Some(bad) = columns
        .iter()
        .find(|c| c.is_empty() || c.contains([',', '"', '\n', '\r']))
    {
        return Err(Error::Message(format!(
            "{}: column name \"{bad}\" is empty or holds a comma, quote or newline",
            path.display()
        )));
    }
    Ok(columns.iter().map(|c| c.to_string()).collect())
}

fn header(columns: &[String]) -> String {
    let mut text = columns.join(",");
    text.push('\n');
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    const COLUMNS: [&str; 2] = ["time_s", "kinetic_energy_J"];

    #[test]
    fn writes_rows_that_read_back_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("series").join("energy.csv");
        let mut series = CsvSeries::create(&path, &COLUMNS).unwrap();
        series.push(&[0.0, 0.1 + 0.2]).unwrap();
        series.push(&[1e-7, -1.5e300]).unwrap();
        assert!(series.push(&[1.0]).is_err());
        let text = std::fs::read_to_string(&path).unwrap();
        let rows: Vec<Vec<f64>> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect();
        assert_eq!(text.lines().next().unwrap(), "time_s,kinetic_energy_J");
        assert_eq!(rows, [vec![0.0, 0.1 + 0.2], vec![1e-7, -1.5e300]]);
    }

    #[test]
    fn reopens_truncating_later_rows_and_a_torn_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("energy.csv");
        let mut series = CsvSeries::create(&path, &COLUMNS).unwrap();
        for i in 0..5 {
            series.push(&[i as f64 * 0.5, i as f64]).unwrap();
        }
        drop(series);
        // A run killed mid-row.
        let mut file = OpenOptions::new().append(true).open(&path).unwrap();
        file.write_all(b"2.5,1").unwrap();
        drop(file);

        let mut series = CsvSeries::open_existing(&path, &COLUMNS, 1.0).unwrap();
        series.push(&[1.5, 9.0]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            "time_s,kinetic_energy_J\n0.0,0.0\n0.5,1.0\n1.0,2.0\n1.5,9.0\n"
        );
        let torn = CsvSeries::open_existing(&path, &COLUMNS, 10.0).unwrap();
        drop(torn);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
    }

    #[test]
    fn rejects_another_header() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("energy.csv");
        CsvSeries::create(&path, &["time_s", "other"]).unwrap();
        let error = CsvSeries::open_existing(&path, &COLUMNS, 1.0)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("energy.csv") && error.contains("header"),
            "{error}"
        );
        assert!(CsvSeries::create(&path, &["a,b"]).is_err());
    }
}
