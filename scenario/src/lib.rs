//! vmt-scenario: scenario files (TOML) describing a machine, its errors and its thermal
//! behaviour, loaded into the model's types.
//!
//! Every problem is reported once, with the file, line and column, the key, and what would be
//! accepted: unknown keys (including keys in a wrong unit), missing values, values out of range,
//! NaN, tables whose positions do not increase. See `scenarios/vmc500.toml` for the format.

mod build;
pub mod dataset;
mod dynamics;
pub mod edit;
mod effects;
mod error;
mod milling;
mod schema;
mod structure;
mod table;
pub mod withheld;

pub use build::{Execution, MAX_ANGLE_URAD, MAX_TRANSLATION_UM, Scenario, ThermalRunSpec};
pub use dynamics::{MAX_CENTRES, MAX_RADII};
pub use error::{KeyPath, ScenarioError};

use build::BuildError;
use std::path::Path;

/// The built-in default machine: a vertical machining centre of 500 x 400 x 400 mm.
pub const BUILTIN_DEFAULT: &str = include_str!("../../scenarios/vmc500.toml");

/// Name under which the built-in scenario is reported.
pub const BUILTIN_NAME: &str = "<built-in default: scenarios/vmc500.toml>";

/// Loads the scenario file at `path`; table files are resolved relative to its folder.
pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
    let text = std::fs::read_to_string(path).map_err(|e| ScenarioError {
        file: path.display().to_string(),
        position: None,
        key: None,
        message: format!("cannot read the scenario: {e}"),
    })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    parse(&text, &path.display().to_string(), Some(dir))
}

/// The built-in default scenario.
pub fn builtin() -> Result<Scenario, ScenarioError> {
    parse(BUILTIN_DEFAULT, BUILTIN_NAME, None)
}

/// Parses scenario `text` named `file` in error messages; `base_dir` resolves table files
/// (`None` refuses them).
pub fn parse(text: &str, file: &str, base_dir: Option<&Path>) -> Result<Scenario, ScenarioError> {
    let raw = read_toml(text, file)?;
    build::scenario(raw, base_dir).map_err(|e| match e {
        BuildError::External(e) => e,
        BuildError::Invalid(inv) => ScenarioError {
            file: file.to_string(),
            position: error::locate(text, &inv.path).map(|s| error::line_col(text, s.start)),
            key: Some(inv.path.to_string()),
            message: inv.message,
        },
    })
}

/// Deserialises the document, naming the key of a wrong or unknown value
/// (serde_path_to_error tracks the path the deserializer had reached).
pub(crate) fn read_toml(text: &str, file: &str) -> Result<schema::ScenarioFile, ScenarioError> {
    let toml_error = |e: toml::de::Error, key: Option<String>| ScenarioError {
        file: file.to_string(),
        position: e.span().map(|s| error::line_col(text, s.start)),
        key,
        message: e.message().trim().to_string(),
    };
    let de = toml::Deserializer::parse(text).map_err(|e| toml_error(e, None))?;
    dataset::check_entries(text, file)?;
    serde_path_to_error::deserialize(de).map_err(|e| {
        if let Some(field) = field_at_fault(text, e.path()) {
            let message = e.inner().message().trim().to_string();
            return ScenarioError {
                file: file.to_string(),
                position: error::locate(text, &field).map(|s| error::line_col(text, s.start)),
                key: Some(field.to_string()),
                message,
            };
        }
        let path = e.path().to_string();
        let key = (path != "." && !path.is_empty()).then_some(path);
        toml_error(e.into_inner(), key)
    })
}

/// The field at fault when an error is reported at a whole table. serde reads a table with a
/// `kind` tag (`[job]`, `[machine.thermal.ambient]`, `[[machine.thermal.sources]]`) into a
/// buffer first, which loses the path and the position of the field it then fails on: the
/// error names the table. The field is found by removing the table's fields one at a time and
/// reading the document again: the one whose removal changes the error is at fault (a wrong
/// type or an unknown key is met while the fields are read, before a missing field is checked
/// for, so removing a sound field leaves the error as it was). Errors that name their field
/// already (a missing field, an unknown `kind`) are left as they are.
fn field_at_fault(text: &str, at: &serde_path_to_error::Path) -> Option<KeyPath> {
    let doc: toml::Table = toml::from_str(text).ok()?;
    let path = key_path(at)?;
    let table = table_at(&doc, &path)?;
    let read = |doc: toml::Table| -> Option<(String, String)> {
        let value = toml::Value::Table(doc);
        serde_path_to_error::deserialize::<_, schema::ScenarioFile>(value)
            .err()
            .map(|e| (e.path().to_string(), e.inner().to_string()))
    };
    let baseline = read(doc.clone())?;
    if baseline.1.starts_with("missing field") || baseline.0 != at.to_string() {
        return None;
    }
    table.keys().filter(|k| k.as_str() != "kind").find_map(|k| {
        let mut without = doc.clone();
        table_at_mut(&mut without, &path)?.remove(k);
        (read(without).as_ref() != Some(&baseline)).then(|| path.key(k))
    })
}

/// serde_path_to_error's path as ours (`None` for steps that are not keys or indices).
fn key_path(at: &serde_path_to_error::Path) -> Option<KeyPath> {
    use serde_path_to_error::Segment;
    at.iter()
        .map(|s| match s {
            Segment::Map { key } => Some(error::Seg::Key(key.clone())),
            Segment::Seq { index } => Some(error::Seg::Index(*index)),
            _ => None,
        })
        .collect::<Option<Vec<_>>>()
        .map(KeyPath)
}

fn table_at<'a>(doc: &'a toml::Table, path: &KeyPath) -> Option<&'a toml::Table> {
    let mut value = doc.get(first_key(path)?)?;
    for seg in &path.0[1..] {
        value = match seg {
            error::Seg::Key(k) => value.as_table()?.get(k)?,
            error::Seg::Index(i) => value.as_array()?.get(*i)?,
        };
    }
    value.as_table()
}

fn table_at_mut<'a>(doc: &'a mut toml::Table, path: &KeyPath) -> Option<&'a mut toml::Table> {
    let mut value = doc.get_mut(first_key(path)?)?;
    for seg in &path.0[1..] {
        value = match seg {
            error::Seg::Key(k) => value.as_table_mut()?.get_mut(k)?,
            error::Seg::Index(i) => value.as_array_mut()?.get_mut(*i)?,
        };
    }
    value.as_table_mut()
}

fn first_key(path: &KeyPath) -> Option<&str> {
    match path.0.first()? {
        error::Seg::Key(k) => Some(k),
        error::Seg::Index(_) => None,
    }
}
