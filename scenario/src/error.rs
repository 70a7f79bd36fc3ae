//! Errors that name the file, line, column and key, and say what is accepted.

use std::fmt;
use std::ops::Range;

/// One step of a key path: a table key or an array index.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Seg {
    /// A table key.
    Key(String),
    /// An array element.
    Index(usize),
}

/// A dotted key path such as `machine.axes.x.stroke_mm[1]`.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct KeyPath(pub Vec<Seg>);

impl KeyPath {
    /// The path of the given keys.
    pub fn of(keys: &[&str]) -> Self {
        KeyPath(keys.iter().map(|k| Seg::Key((*k).to_string())).collect())
    }

    /// This path extended by a key.
    pub fn key(&self, k: &str) -> Self {
        let mut p = self.clone();
        p.0.push(Seg::Key(k.to_string()));
        p
    }

    /// This path extended by an index.
    pub fn index(&self, i: usize) -> Self {
        let mut p = self.clone();
        p.0.push(Seg::Index(i));
        p
    }
}

impl fmt::Display for KeyPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, s) in self.0.iter().enumerate() {
            match s {
                Seg::Key(k) if i == 0 => write!(f, "{k}")?,
                Seg::Key(k) if k.contains(['.', '-', ' ']) => write!(f, ".\"{k}\"")?,
                Seg::Key(k) => write!(f, ".{k}")?,
                Seg::Index(n) => write!(f, "[{n}]")?,
            }
        }
        Ok(())
    }
}

/// A problem with a scenario, located as precisely as known.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioError {
    /// The file (or `<built-in default>`).
    pub file: String,
    /// 1-based line and column, when known.
    pub position: Option<(usize, usize)>,
    /// The key, when the problem is with one value.
    pub key: Option<String>,
    /// What is wrong and what would be accepted.
    pub message: String,
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some((line, col)) = self.position {
            write!(f, ":{line}:{col}")?;
        }
        write!(f, ": ")?;
        if let Some(k) = &self.key {
            write!(f, "key `{k}`: ")?;
        }
        write!(f, "{}", self.message)
    }
}

impl std::error::Error for ScenarioError {}

/// A validation problem found after parsing: the key path and the message.
#[derive(Debug, Clone, PartialEq)]
pub struct Invalid {
    /// Where in the document.
    pub path: KeyPath,
    /// What is wrong and what is accepted.
    pub message: String,
}

impl Invalid {
    /// A problem at `path`.
    pub fn new(path: KeyPath, message: impl Into<String>) -> Self {
        Self {
            path,
            message: message.into(),
        }
    }
}

/// 1-based line and column of byte `offset` in `text`.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before
        .rfind('\n')
        .map_or(before.len(), |n| before.len() - n - 1)
        + 1;
    (line, col)
}

/// The byte span of the value at `path` in the TOML `text`, or of the deepest part of the path
/// that exists (so a missing key points at the table that lacks it).
pub fn locate(text: &str, path: &KeyPath) -> Option<Range<usize>> {
    let doc = toml_edit::Document::parse(text).ok()?;
    let mut node = Node::Item(doc.as_item());
    let mut span = None;
    for seg in &path.0 {
        match node.child(seg) {
            Some((next, s)) => {
                span = s.or(span);
                node = next;
            }
            None => break,
        }
    }
    span
}

/// A place in a parsed TOML document.
enum Node<'a> {
    Item(&'a toml_edit::Item),
    Table(&'a toml_edit::Table),
    Value(&'a toml_edit::Value),
}

impl<'a> Node<'a> {
    fn child(&self, seg: &Seg) -> Option<(Node<'a>, Option<Range<usize>>)> {
        use toml_edit::{Item, Value};
        let keyed = |kv: Option<(&'a toml_edit::Key, &'a Item)>| {
            kv.map(|(k, v)| (Node::Item(v), v.span().or_else(|| k.span())))
        };
        match (self, seg) {
            (Node::Item(Item::ArrayOfTables(a)), Seg::Index(i)) => {
                a.get(*i).map(|t| (Node::Table(t), t.span()))
            }
            (Node::Item(Item::Value(v)), _) => Node::Value(v).child(seg),
            (Node::Item(item), Seg::Key(k)) => {
                keyed(item.as_table_like().and_then(|t| t.get_key_value(k)))
            }
            (Node::Table(t), Seg::Key(k)) => keyed(t.get_key_value(k)),
            (Node::Value(Value::InlineTable(t)), Seg::Key(k)) => keyed(t.get_key_value(k)),
            (Node::Value(Value::Array(a)), Seg::Index(i)) => {
                a.get(*i).map(|v| (Node::Value(v), v.span()))
            }
            _ => None,
        }
    }
}
