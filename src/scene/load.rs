//! Reading a scene file: TOML syntax, presets merged over the base, typed
//! deserialization with the dotted key path of any failure, then [`Validate`].
//!
//! Every error is one line: `FILE: key a.b: reason` (or `FILE: line N, column M: …`
//! for a syntax error).

use std::path::Path;

use serde::de::DeserializeOwned;

use super::validate::{Validate, Validator};
use crate::{Error, Result};

/// The top-level table that holds the presets: `[preset.quick]`, `[preset.paper]` ….
pub const PRESET_TABLE: &str = "preset";

/// Loads a scene of type `T` from `path`, with the preset `preset` applied, and
/// validates it.
///
/// ```no_run
/// use serde::Deserialize;
/// use ballast::scene::{load_scene, Material, Time, Validate, Validator};
///
/// #[derive(Deserialize)]
/// #[serde(deny_unknown_fields)]
/// struct CantileverScene { material: Material, dt: Time, steps: usize }
///
/// impl Validate for CantileverScene {
///     fn validate(&self, v: &mut Validator) {
///         v.nested("material", &self.material);
///         v.positive("dt", self.dt);
///         v.check("steps", self.steps > 0, "must be at least 1");
///     }
/// }
///
/// let scene: CantileverScene =
///     load_scene("scenes/cantilever.toml".as_ref(), Some("quick"))?;
/// # Ok::<(), ballast::Error>(())
/// ```
pub fn load_scene<T: DeserializeOwned + Validate>(path: &Path, preset: Option<&str>) -> Result<T> {
    load_scene_with_source(path, preset).map(|(scene, _)| scene)
}

/// Like [`load_scene`], and also returns the merged TOML table (preset applied, the
/// `preset` table removed): the inputs to record in a run summary.
pub fn load_scene_with_source<T: DeserializeOwned + Validate>(
    path: &Path,
    preset: Option<&str>,
) -> Result<(T, toml::Table)> {
    let text = std::fs::read_to_string(path).map_err(|err| Error::io(path, err))?;
    scene_from_str(path, &text, preset)
}

/// Like [`load_scene_with_source`], then applies command-line overrides
/// `KEY.PATH=VALUE` (`--set qdem.dt_factor=0.5`) over the preset: VALUE is read as a
/// TOML value (`0.5`, `"1 ms"`, `[1, 2]`), or as a string when it is not one.
pub fn load_scene_with_overrides<T: DeserializeOwned + Validate>(
    path: &Path,
    preset: Option<&str>,
    overrides: &[String],
) -> Result<(T, toml::Table)> {
    let text = std::fs::read_to_string(path).map_err(|err| Error::io(path, err))?;
    scene_from_str_with_overrides(path, &text, preset, overrides)
}

/// Reads a scene from TOML `text`; `path` is used only to name the file in messages.
pub fn scene_from_str<T: DeserializeOwned + Validate>(
    path: &Path,
    text: &str,
    preset: Option<&str>,
) -> Result<(T, toml::Table)> {
    scene_from_str_with_overrides(path, text, preset, &[])
}

/// One `KEY.PATH=VALUE` override as a nested table.
fn override_table(text: &str) -> std::result::Result<toml::Table, String> {
    let (key, value) = text
        .split_once('=')
        .ok_or_else(|| format!("--set {text}: expected KEY=VALUE (e.g. qdem.dt_factor=0.5)"))?;
    let key = key.trim();
    if key.is_empty() || key.split('.').any(str::is_empty) {
        return Err(format!("--set {text}: \"{key}\" is not a dotted key"));
    }
    let value = value.trim();
    let value = match format!("v = {value}").parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").expect("parsed"),
        Err(_) => toml::Value::String(value.to_string()),
    };
    let mut table = toml::Table::new();
    let mut parts: Vec<&str> = key.split('.').collect();
    let last = parts.pop().expect("non-empty");
    table.insert(last.to_string(), value);
    for part in parts.into_iter().rev() {
        let mut outer = toml::Table::new();
        outer.insert(part.to_string(), toml::Value::Table(table));
        table = outer;
    }
    Ok(table)
}

fn scene_from_str_with_overrides<T: DeserializeOwned + Validate>(
    path: &Path,
    text: &str,
    preset: Option<&str>,
    overrides: &[String],
) -> Result<(T, toml::Table)> {
    let table = parse_table(path, text)?;
    let mut merged = apply_preset(table, preset).map_err(|what| Error::invalid(path, what))?;
    for text in overrides {
        let over = override_table(text).map_err(Error::Message)?;
        merge_tables(&mut merged, over);
    }
    let with_preset = |what: String| match preset {
        Some(name) => Error::invalid(path, format!("{what} (with preset {name})")),
        None if !overrides.is_empty() => Error::invalid(
            path,
            format!("{what} (with --set {})", overrides.join(" --set ")),
        ),
        None => Error::invalid(path, what),
    };
    let scene: T = deserialize_table(&merged).map_err(with_preset)?;
    let mut validator = Validator::new();
    scene.validate(&mut validator);
    validator.finish().map_err(with_preset)?;
    Ok((scene, merged))
}

/// Parses TOML text into a table; a syntax error gives its line and column.
pub fn parse_table(path: &Path, text: &str) -> Result<toml::Table> {
    text.parse::<toml::Table>().map_err(|err| {
        let message = one_line(err.message());
        let what = match err.span() {
            Some(span) => {
                let (line, column) = line_and_column(text, span.start);
                format!("line {line}, column {column}: {message}")
            }
            None => message,
        };
        Error::invalid(path, what)
    })
}

/// Takes `[preset.NAME]` (if a name is given) and merges it over the base table, then
/// drops the `preset` table. The error lists the presets the file defines.
pub fn apply_preset(
    mut table: toml::Table,
    preset: Option<&str>,
) -> std::result::Result<toml::Table, String> {
    let presets = match table.remove(PRESET_TABLE) {
        None => toml::Table::new(),
        Some(toml::Value::Table(presets)) => presets,
        Some(other) => {
            return Err(format!(
                "key {PRESET_TABLE}: must be a table of presets ([{PRESET_TABLE}.NAME]), found {}",
                other.type_str()
            ))
        }
    };
    let Some(name) = preset else {
        return Ok(table);
    };
    match presets.get(name) {
        Some(toml::Value::Table(overrides)) => {
            merge_tables(&mut table, overrides.clone());
            Ok(table)
        }
        Some(other) => Err(format!(
            "key {PRESET_TABLE}.{name}: a preset must be a table, found {}",
            other.type_str()
        )),
        None if presets.is_empty() => Err(format!(
            "unknown preset \"{name}\" (this file defines no [{PRESET_TABLE}.NAME] tables)"
        )),
        None => {
            let names: Vec<&str> = presets.keys().map(String::as_str).collect();
            Err(format!(
                "unknown preset \"{name}\" (available: {})",
                names.join(", ")
            ))
        }
    }
}

/// Deep merge: tables merge key by key, recursively; any other value of `over`
/// replaces the one in `base` (arrays are replaced whole). An empty table `{ }` over a
/// value that is not a table removes the key: how a preset unsets a base value (e.g.
/// `sleepers.size = { }` where the preset gives `sleepers.mesh` instead).
pub fn merge_tables(base: &mut toml::Table, over: toml::Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(base_table)), toml::Value::Table(over_table)) => {
                merge_tables(base_table, over_table)
            }
            (Some(_), toml::Value::Table(over_table)) if over_table.is_empty() => {
                base.remove(&key);
            }
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

/// Deserializes `table` into `T`; the error names the dotted key path and the reason.
pub fn deserialize_table<T: DeserializeOwned>(
    table: &toml::Table,
) -> std::result::Result<T, String> {
    serde_path_to_error::deserialize(table.clone()).map_err(|err| {
        let path = key_path(err.path());
        describe(&path, err.inner().message())
    })
}

/// The dotted key path of a serde path: `material.density`, `bodies[2].mesh`.
fn key_path(path: &serde_path_to_error::Path) -> String {
    use serde_path_to_error::Segment;
    let mut out = String::new();
    for segment in path.iter() {
        match segment {
            Segment::Seq { index } => out.push_str(&format!("[{index}]")),
            Segment::Map { key } | Segment::Enum { variant: key } => {
                if !out.is_empty() {
                    out.push('.');
                }
                out.push_str(key);
            }
            Segment::Unknown => {
                if !out.is_empty() {
                    out.push('.');
                }
                out.push('?');
            }
        }
    }
    out
}

/// Rewrites serde's messages into the scene-file vocabulary of keys.
fn describe(path: &str, message: &str) -> String {
    let message = one_line(message);
    let join = |parent: &str, name: &str| {
        if parent.is_empty() {
            name.to_string()
        } else if parent == name || parent.ends_with(&format!(".{name}")) {
            parent.to_string()
        } else {
            format!("{parent}.{name}")
        }
    };
    if let Some(rest) = message.strip_prefix("unknown field ") {
        let (name, expected) = split_name(rest);
        let expected = expected_list(expected);
        return format!("unknown key {}{expected}", join(path, name));
    }
    if let Some(rest) = message.strip_prefix("missing field ") {
        let (name, _) = split_name(rest);
        return format!("missing key {}", join(path, name));
    }
    if let Some(rest) = message.strip_prefix("unknown variant ") {
        let (name, expected) = split_name(rest);
        let expected = expected_list(expected);
        return format!("key {path}: unknown value \"{name}\"{expected}");
    }
    if path.is_empty() {
        message
    } else {
        format!("key {path}: {message}")
    }
}

/// Splits "`name`, expected …" into the name and the rest.
fn split_name(text: &str) -> (&str, &str) {
    let text = text.trim_start_matches('`');
    match text.split_once('`') {
        Some((name, rest)) => (name, rest.trim_start_matches(',').trim()),
        None => (text, ""),
    }
}

/// Turns "expected one of `a`, `b`" into " (expected one of: a, b)".
fn expected_list(text: &str) -> String {
    let names: Vec<&str> = text
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|name| !name.is_empty())
        .collect();
    if names.is_empty() {
        if text.contains("no fields") {
            " (this table takes no keys)".to_string()
        } else {
            String::new()
        }
    } else {
        format!(" (expected one of: {})", names.join(", "))
    }
}

/// Collapses a possibly multi-line message into one line.
fn one_line(message: &str) -> String {
    message
        .lines()
        .map(str::trim)
        .filter(|line| !line.is_empty())
        .collect::<Vec<_>>()
        .join("; ")
}

/// 1-based line and column (in characters) of byte offset `offset` in `text`.
fn line_and_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before
        .rsplit('\n')
        .next()
        .map_or(0, |last| last.chars().count())
        + 1;
    (line, column)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    fn table(text: &str) -> toml::Table {
        text.parse().unwrap()
    }

    #[test]
    fn merge_is_deep_and_replaces_leaves() {
        let mut base = table("a = 1\n[t]\nx = 1\ny = [1, 2]\n[t.u]\nz = 1\nw = 2\n");
        merge_tables(
            &mut base,
            table("b = 2\n[t]\ny = [3]\n[t.u]\nz = 5\n[new]\nk = 1\n"),
        );
        assert_eq!(
            base,
            table("a = 1\nb = 2\n[t]\nx = 1\ny = [3]\n[t.u]\nz = 5\nw = 2\n[new]\nk = 1\n")
        );
    }

    #[test]
    fn an_empty_table_unsets_a_value() {
        let mut base = table("a = 1\nb = [1, 2]\n[t]\nx = 1\n");
        merge_tables(&mut base, table("a = {}\nb = {}\nc = {}\n[t]\n"));
        // a and b removed; an empty table where there was nothing (c) or a table (t) stays.
        assert_eq!(base, table("c = {}\n[t]\nx = 1\n"));
    }

    #[test]
    fn presets_are_applied_and_removed() {
        let base = table("n = 1\n[preset.quick]\nn = 2\n[preset.paper]\nn = 3\n");
        assert_eq!(apply_preset(base.clone(), None).unwrap(), table("n = 1"));
        assert_eq!(
            apply_preset(base.clone(), Some("paper")).unwrap(),
            table("n = 3")
        );
        assert_eq!(
            apply_preset(base, Some("fast")).unwrap_err(),
            "unknown preset \"fast\" (available: paper, quick)"
        );
        assert_eq!(
            apply_preset(table("n = 1"), Some("quick")).unwrap_err(),
            "unknown preset \"quick\" (this file defines no [preset.NAME] tables)"
        );
        assert!(apply_preset(table("preset = 1"), None)
            .unwrap_err()
            .starts_with("key preset: must be a table"));
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Inner {
        #[allow(dead_code)]
        x: f64,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Outer {
        #[allow(dead_code)]
        inner: Inner,
        #[allow(dead_code)]
        #[serde(default)]
        list: Vec<Inner>,
    }

    #[test]
    fn deserialization_errors_name_the_key() {
        let err = |text: &str| deserialize_table::<Outer>(&table(text)).unwrap_err();
        assert_eq!(
            err("[inner]\nx = 1\ny = 2"),
            "unknown key inner.y (expected one of: x)"
        );
        assert_eq!(
            err("top = 1\n[inner]\nx = 1"),
            "unknown key top (expected one of: inner, list)"
        );
        assert_eq!(err("[inner]\n"), "missing key inner.x");
        assert_eq!(err("list = []"), "missing key inner");
        assert_eq!(
            err("[inner]\nx = \"a\""),
            "key inner.x: invalid type: string \"a\", expected f64"
        );
        assert_eq!(
            err("[inner]\nx = 1\n[[list]]\nx = 1\n[[list]]\nz = 1"),
            "unknown key list[1].z (expected one of: x)"
        );
    }

    #[test]
    fn syntax_errors_give_line_and_column() {
        let err = parse_table(Path::new("s.toml"), "a = 1\nb = = 2\n").unwrap_err();
        let text = err.to_string();
        assert!(text.starts_with("s.toml: line 2, column "), "{text}");
        assert!(!text.contains('\n'));
    }

    #[test]
    fn line_and_column_count_characters() {
        assert_eq!(line_and_column("ab\ncµd", 0), (1, 1));
        assert_eq!(line_and_column("ab\ncµd", 3), (2, 1));
        assert_eq!(line_and_column("ab\ncµd", 6), (2, 3));
    }
}

#[cfg(test)]
mod override_tests {
    use super::*;

    #[test]
    fn overrides_build_nested_tables_and_fall_back_to_strings() {
        let t = override_table("qdem.dt_factor=0.5").unwrap();
        assert_eq!(t["qdem"]["dt_factor"].as_float(), Some(0.5));
        let t = override_table("mesh.file=../meshes/a.msh").unwrap();
        assert_eq!(t["mesh"]["file"].as_str(), Some("../meshes/a.msh"));
        let t = override_table("qdem.duration=\"1 ms\"").unwrap();
        assert_eq!(t["qdem"]["duration"].as_str(), Some("1 ms"));
        assert!(override_table("qdem.dt_factor")
            .unwrap_err()
            .contains("KEY=VALUE"));
        assert!(override_table("qdem..x=1")
            .unwrap_err()
            .contains("dotted key"));
    }
}
