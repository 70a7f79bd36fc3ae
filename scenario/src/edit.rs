//! A scenario as an editable template: read the numbers it sets and write new ones by dotted
//! key path (`machine.axes.x.drive.backlash_um`, `machine.errors.x.forward.EXX_um[1]`), keeping
//! every other byte of the file. The sim-to-real gap analysis fits model parameters this way,
//! through the same parser and checks as any scenario.

use crate::dataset::{key_path, number, number_mut, value_at};
use crate::error::ScenarioError;
use toml_edit::{DocumentMut, Value};

/// A parsed scenario text that can be edited by key path.
#[derive(Debug, Clone)]
pub struct Template {
    doc: DocumentMut,
    file: String,
}

impl Template {
    /// Parses `text` (named `file` in errors).
    pub fn parse(text: &str, file: &str) -> Result<Self, ScenarioError> {
        let doc: DocumentMut = text
            .parse()
            .map_err(|e: toml_edit::TomlError| ScenarioError {
                file: file.to_string(),
                position: e.span().map(|s| crate::error::line_col(text, s.start)),
                key: None,
                message: e.message().to_string(),
            })?;
        Ok(Self {
            doc,
            file: file.to_string(),
        })
    }

    /// The number the scenario sets at `key`, if any; an error for a malformed key.
    pub fn value(&self, key: &str) -> Result<Option<f64>, ScenarioError> {
        let path = key_path(key).map_err(|m| self.error(key, m))?;
        Ok(
            number(&self.doc, &path)
                .and_then(|v| v.as_float().or(v.as_integer().map(|i| i as f64))),
        )
    }

    /// The string the scenario sets at `key`, if any (a job's tool name, say).
    pub fn text(&self, key: &str) -> Result<Option<String>, ScenarioError> {
        let path = key_path(key).map_err(|m| self.error(key, m))?;
        Ok(value_at(&self.doc, &path).and_then(|v| v.as_str().map(str::to_string)))
    }

    /// The scenario text with each `(key, value)` written in. Every key must already hold a
    /// number (a template does not invent structure): an error names the first that does not.
    pub fn with(&self, values: &[(&str, f64)]) -> Result<String, ScenarioError> {
        let mut doc = self.doc.clone();
        for (key, v) in values {
            let path = key_path(key).map_err(|m| self.error(key, m))?;
            let slot = number_mut(&mut doc, &path)
                .filter(|v| v.is_float() || v.is_integer())
                .ok_or_else(|| self.error(key, "the scenario sets no number at this key".into()))?;
            let decor = slot.decor().clone();
            // An integer key (a seed, a count) stays an integer when the value is whole.
            *slot = if slot.is_integer() && v.fract() == 0.0 && v.abs() < 9e15 {
                Value::from(*v as i64)
            } else {
                Value::from(*v)
            };
            *slot.decor_mut() = decor;
        }
        Ok(doc.to_string())
    }

    /// The scenario text with each `(key, text)` written in as a string (a job's plane, say).
    /// Every key must already hold a string: an error names the first that does not.
    pub fn with_text(&self, values: &[(&str, &str)]) -> Result<String, ScenarioError> {
        let mut doc = self.doc.clone();
        for (key, v) in values {
            let path = key_path(key).map_err(|m| self.error(key, m))?;
            let slot = number_mut(&mut doc, &path)
                .filter(|v| v.is_str())
                .ok_or_else(|| self.error(key, "the scenario sets no string at this key".into()))?;
            let decor = slot.decor().clone();
            *slot = Value::from(*v);
            *slot.decor_mut() = decor;
        }
        Ok(doc.to_string())
    }

    /// The scenario text with each plain dotted `(key, value)` (no `[i]` elements) set,
    /// creating the tables on its way when the scenario has none (e.g. an instrument setting the
    /// file leaves at its default).
    pub fn with_inserted(&self, values: &[(&str, f64)]) -> Result<String, ScenarioError> {
        let mut doc = self.doc.clone();
        for (key, v) in values {
            let parts: Vec<&str> = key.split('.').collect();
            let Some((last, tables)) = parts.split_last() else {
                return Err(self.error(key, "an empty key".into()));
            };
            let mut table = doc.as_table_mut();
            for t in tables {
                let item = table.entry(t).or_insert_with(toml_edit::table);
                table = item
                    .as_table_mut()
                    .ok_or_else(|| self.error(key, format!("`{t}` is not a table")))?;
            }
            table[*last] = toml_edit::value(*v);
        }
        Ok(doc.to_string())
    }

    /// The scenario text with the TOML `fragment` merged in: its tables into the scenario's
    /// tables of the same path (inline or not), its values over the scenario's, its arrays of
    /// tables after the scenario's own entries. Withheld physics is written into a measured
    /// machine this way, as tables no model parameter edit reaches.
    pub fn with_merged(&self, fragment: &str) -> Result<String, ScenarioError> {
        let add = Self::parse(fragment, &format!("{} (merged fragment)", self.file))?;
        let mut doc = self.doc.clone();
        merge_table(doc.as_table_mut(), add.doc.as_table(), "")
            .map_err(|(key, m)| self.error(&key, m))?;
        Ok(doc.to_string())
    }

    /// The scenario text with its top-level table `name` replaced by the table `fragment` (the
    /// table's body: `kind = "ballbar"\nplane = "XY"\n…`); a job is swapped this way.
    pub fn with_table(&self, name: &str, fragment: &str) -> Result<String, ScenarioError> {
        let body = Self::parse(fragment, &format!("{} (table {name})", self.file))?;
        let mut doc = self.doc.clone();
        let mut table = body.doc.as_table().clone();
        table.set_implicit(false);
        doc.insert(name, toml_edit::Item::Table(table));
        Ok(doc.to_string())
    }

    fn error(&self, key: &str, message: String) -> ScenarioError {
        ScenarioError {
            file: self.file.clone(),
            position: None,
            key: Some(key.to_string()),
            message,
        }
    }
}

/// Merges `add` into `into` (see [`Template::with_merged`]); an error names the key where a
/// table meets a value.
fn merge_table(
    into: &mut toml_edit::Table,
    add: &toml_edit::Table,
    path: &str,
) -> Result<(), (String, String)> {
    use toml_edit::Item;
    for (key, item) in add.iter() {
        let here = if path.is_empty() {
            key.to_string()
        } else {
            format!("{path}.{key}")
        };
        let clash = || {
            (
                here.clone(),
                "the fragment sets a table where the scenario has a value, or the reverse".into(),
            )
        };
        match (into.get_mut(key), item) {
            (None, _) => {
                into.insert(key, item.clone());
            }
            (Some(Item::Table(t)), Item::Table(a)) => merge_table(t, a, &here)?,
            (Some(Item::Value(Value::InlineTable(t))), Item::Table(a)) => {
                for (k, v) in a.iter() {
                    let v = v.as_value().ok_or_else(clash)?;
                    t.insert(k, v.clone());
                }
            }
            (Some(Item::ArrayOfTables(list)), Item::ArrayOfTables(a)) => {
                for t in a.iter() {
                    list.push(t.clone());
                }
            }
            (Some(Item::Value(_)), Item::Value(v)) => {
                into[key] = Item::Value(v.clone());
            }
            _ => return Err(clash()),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fragment_merges_into_tables_inline_tables_and_arrays_of_tables() {
        let text = "[a]\nx = 1.0\nf = { c = 4.0 }\n\n[[list]]\nn = 1\n";
        let t = Template::parse(text, "t.toml").unwrap();
        let out = t
            .with_merged("[a]\ny = 2.0\n[a.f]\nd = 5.0\n[a.g]\nz = 3.0\n[[list]]\nn = 2\n")
            .unwrap();
        let merged = Template::parse(&out, "out.toml").unwrap();
        for (key, v) in [
            ("a.x", 1.0),
            ("a.y", 2.0),
            ("a.f.c", 4.0),
            ("a.f.d", 5.0),
            ("a.g.z", 3.0),
            ("list[0].n", 1.0),
            ("list[1].n", 2.0),
        ] {
            assert_eq!(merged.value(key).unwrap(), Some(v), "{key} in\n{out}");
        }
        let e = t.with_merged("[a.x]\nq = 1.0\n").unwrap_err();
        assert!(e.to_string().contains("a.x"), "{e}");
        let swapped = t.with_table("a", "z = 9.0\n").unwrap();
        let swapped = Template::parse(&swapped, "swapped.toml").unwrap();
        assert_eq!(swapped.value("a.z").unwrap(), Some(9.0));
        assert_eq!(swapped.value("a.x").unwrap(), None);
        assert_eq!(swapped.value("list[0].n").unwrap(), Some(1.0));
    }

    #[test]
    fn values_are_read_and_written_by_key_path_keeping_the_rest() {
        let text = "[a]\nx = 1.5 # comment\ny = [1, 2.0, 3]\nf = { c = 4.0 }\n";
        let t = Template::parse(text, "t.toml").unwrap();
        assert_eq!(t.value("a.y[1]").unwrap(), Some(2.0));
        assert_eq!(t.value("a.f.c").unwrap(), Some(4.0));
        let out = t
            .with(&[("a.x", 2.5), ("a.y[0]", -1.0), ("a.f.c", 5.0)])
            .unwrap();
        // An integer stays an integer when the new value is whole.
        assert_eq!(
            out,
            "[a]\nx = 2.5 # comment\ny = [-1, 2.0, 3]\nf = { c = 5.0 }\n"
        );
        let e = t.with(&[("a.z", 1.0)]).unwrap_err();
        assert!(e.to_string().contains("a.z"), "{e}");
        let s = Template::parse("[job]\nplane = \"XY\" # the test\n", "t.toml").unwrap();
        assert_eq!(s.text("job.plane").unwrap().as_deref(), Some("XY"));
        let out = s.with_text(&[("job.plane", "ZX")]).unwrap();
        assert_eq!(out, "[job]\nplane = \"ZX\" # the test\n");
        let e = s.with_text(&[("job.radius", "1")]).unwrap_err();
        assert!(e.to_string().contains("job.radius"), "{e}");
    }
}
