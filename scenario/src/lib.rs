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
mod error;
mod milling;
mod schema;
mod table;

pub use build::{Execution, MAX_ANGLE_URAD, MAX_TRANSLATION_UM, Scenario, ThermalRunSpec};
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
    serde_path_to_error::deserialize(de).map_err(|e| {
        let path = e.path().to_string();
        let key = (path != "." && !path.is_empty()).then_some(path);
        toml_error(e.into_inner(), key)
    })
}
