//! JSON result files (`summary.json`, `run.json`), pretty-printed and written atomically.

use std::path::Path;

use serde::Serialize;

use super::atomic::write_atomic;
use crate::{Error, Result};

/// Writes `value` (a `serde_json::Value` or any serialisable struct) to `path` as
/// pretty-printed JSON with a final newline, atomically.
pub fn write_json(path: impl AsRef<Path>, value: &impl Serialize) -> Result<()> {
    let path = path.as_ref();
    let mut bytes = serde_json::to_vec_pretty(value)
        .map_err(|e| Error::invalid(path, format!("cannot encode JSON: {e}")))?;
    bytes.push(b'\n');
    write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_pretty_json_that_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("summary.json");
        let value = serde_json::json!({"scene": "tamping", "wall_time_s": 1.5, "threads": 4});
        write_json(&path, &value).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.ends_with("}\n") && text.contains("\n  \"scene\""),
            "{text}"
        );
        let back: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back, value);
    }
}
