//! A scenario as an editable template: read the numbers it sets and write new ones by dotted
//! key path (`machine.axes.x.drive.backlash_um`, `machine.errors.x.forward.EXX_um[1]`), keeping
//! every other byte of the file. The sim-to-real gap analysis fits model parameters this way,
//! through the same parser and checks as any scenario.

use crate::dataset::{key_path, number, number_mut, value_at};
use crate::error::ScenarioError;
use toml_edit::{DocumentMut, Item, TableLike, Value};

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

    /// The scenario text with the TOML `fragment` merged into the table at the plain dotted
    /// key `table` (`""`: the document's root), the tables on its way created where the
    /// scenario has none. The fragment's tables are merged into the scenario's (inline tables
    /// too), its arrays of tables appended to the scenario's, and every other value set.
    /// This switches on what a scenario does not set: a table (`[machine.axes.x.drive.motor]`),
    /// an element of an array of tables (`[[machine.axes.x.guideway.defects]]`), a key of an
    /// inline table (`law = "gms"` in `machine.axes.x.drive.guide_friction`). The result is
    /// a scenario text for [`crate::parse`], which checks it.
    pub fn with_fragment(&self, table: &str, fragment: &str) -> Result<String, ScenarioError> {
        let mut doc = self.doc.clone();
        self.merge_fragment(&mut doc, table, fragment)?;
        Ok(doc.to_string())
    }

    /// The scenario text with each `(table, fragment)` merged in turn, as
    /// [`Template::with_fragment`] merges one.
    pub fn with_fragments(&self, fragments: &[(String, String)]) -> Result<String, ScenarioError> {
        let mut doc = self.doc.clone();
        for (table, fragment) in fragments {
            self.merge_fragment(&mut doc, table, fragment)?;
        }
        Ok(doc.to_string())
    }

    fn merge_fragment(
        &self,
        doc: &mut DocumentMut,
        table: &str,
        fragment: &str,
    ) -> Result<(), ScenarioError> {
        let key = if table.is_empty() { "<root>" } else { table };
        let part: DocumentMut = fragment.parse().map_err(|e: toml_edit::TomlError| {
            self.error(key, format!("the fragment is not TOML: {}", e.message()))
        })?;
        let mut at: &mut dyn TableLike = doc.as_table_mut();
        if !table.is_empty() {
            for t in table.split('.') {
                if at.get(t).is_none() {
                    // Into an inline table, insert converts the new table to its inline form.
                    at.insert(t, toml_edit::table());
                }
                at = at
                    .get_mut(t)
                    .and_then(Item::as_table_like_mut)
                    .ok_or_else(|| self.error(key, format!("`{t}` is not a table")))?;
            }
        }
        for (k, item) in part.as_table().iter() {
            merge(at, table, k, item).map_err(|m| self.error(key, m))?;
        }
        Ok(())
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

/// Merges `item` into `dst` at `key` (see [`Template::with_fragment`]); `path` is the dotted
/// key of `dst`, for the error that names where a table meets a value.
fn merge(dst: &mut dyn TableLike, path: &str, key: &str, item: &Item) -> Result<(), String> {
    let here = if path.is_empty() {
        key.to_string()
    } else {
        format!("{path}.{key}")
    };
    if let Some(existing) = dst.get_mut(key) {
        let entries: Option<Vec<(String, Item)>> = match item {
            Item::Table(t) => Some(t.iter().map(|(k, v)| (k.to_string(), v.clone())).collect()),
            Item::Value(Value::InlineTable(t)) => Some(
                t.iter()
                    .map(|(k, v)| (k.to_string(), Item::Value(v.clone())))
                    .collect(),
            ),
            _ => None,
        };
        if let (Item::ArrayOfTables(more), Item::ArrayOfTables(have)) = (item, &mut *existing) {
            for t in more.iter() {
                // The fragment's own document position would print it before the scenario's.
                let mut t = t.clone();
                t.set_position(None);
                have.push(t);
            }
            return Ok(());
        }
        match (entries, existing.as_table_like_mut()) {
            (Some(entries), Some(table)) => {
                for (k, v) in &entries {
                    merge(table, &here, k, v)?;
                }
                return Ok(());
            }
            (None, None) => {}
            _ => {
                return Err(format!(
                    "`{here}`: the fragment sets a table where the scenario has a value, or the reverse"
                ));
            }
        }
    }
    // An inline table takes a table or an array of tables as its inline form.
    if !item.is_none() {
        dst.insert(key, item.clone());
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
            .with_fragment(
                "",
                "[a]\ny = 2.0\n[a.f]\nd = 5.0\n[a.g]\nz = 3.0\n[[list]]\nn = 2\n",
            )
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
        let e = t.with_fragment("", "[a.x]\nq = 1.0\n").unwrap_err();
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

    #[test]
    fn fragments_add_tables_array_elements_and_inline_keys() {
        let text = "[a]\nx = 1.0\nf = { c = 4.0 }\n\n[[a.list]]\nn = 1\n";
        let t = Template::parse(text, "t.toml").unwrap();
        let out = t
            .with_fragment("a", "y = \"s\"\n[b]\nz = [1.0, 2.0]\n")
            .unwrap();
        let doc: toml::Table = toml::from_str(&out).unwrap();
        assert_eq!(doc["a"]["x"].as_float(), Some(1.0));
        assert_eq!(doc["a"]["y"].as_str(), Some("s"));
        assert_eq!(doc["a"]["b"]["z"][1].as_float(), Some(2.0));
        // Into an inline table, and a new nested table on the way.
        let out = t.with_fragment("a.f", "law = \"gms\"").unwrap();
        let doc: toml::Table = toml::from_str(&out).unwrap();
        assert_eq!(doc["a"]["f"]["c"].as_float(), Some(4.0), "{out}");
        assert_eq!(doc["a"]["f"]["law"].as_str(), Some("gms"), "{out}");
        let out = t.with_fragment("a.g.h", "k = 2").unwrap();
        let doc: toml::Table = toml::from_str(&out).unwrap();
        assert_eq!(doc["a"]["g"]["h"]["k"].as_integer(), Some(2));
        // An element appended to an array of tables, and one made where there is none.
        let out = t.with_fragment("a", "[[list]]\nn = 2\n").unwrap();
        let doc: toml::Table = toml::from_str(&out).unwrap();
        let list = doc["a"]["list"].as_array().unwrap();
        assert_eq!(list.len(), 2);
        assert_eq!(list[1]["n"].as_integer(), Some(2));
        let out = t.with_fragment("c", "[[d]]\nm = 1\n").unwrap();
        let doc: toml::Table = toml::from_str(&out).unwrap();
        assert_eq!(doc["c"]["d"][0]["m"].as_integer(), Some(1));
        // Errors name the key: a path through a value, a fragment that is not TOML.
        let e = t.with_fragment("a.x", "k = 1").unwrap_err();
        assert!(e.to_string().contains("a.x"), "{e}");
        assert!(t.with_fragment("a", "k = ").is_err());
    }
}
