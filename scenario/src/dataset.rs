//! `[dataset]`: distributions of a scenario's parameters, from which random machines are drawn.
//!
//! ```toml
//! [dataset.parameters]
//! "machine.axes.x.drive.backlash_um" = { distribution = "uniform", min = 0.0, max = 6.0, p_absent = 0.3 }
//! "machine.errors.squareness.EC0Y_urad" = { distribution = "normal", mean = 0.0, sd = 15.0 }
//! scale_x = { keys = ["machine.errors.x.forward.EXX_um[1]", "machine.errors.x.backward.EXX_um[1]"], distribution = "normal", mean = 0.0, sd = 5.0 }
//! ```
//!
//! An entry is named by the dotted key path of a number the scenario sets (an array element as
//! `key[i]`), or carries `keys`, every one of which takes the same draw (a scale error alike for
//! both approach directions). Distributions (rand_distr): `uniform` (min, max), `normal` (mean,
//! sd), `lognormal` (median, sigma: ln x ~ N(ln median, sigma²)), `constant` (value). With
//! probability `p_absent` (default 0) the parameter takes its `absent` value (default 0) instead,
//! so a dataset holds machines without each error. A sample is the scenario text with the drawn
//! numbers written in (toml_edit keeps everything else), `simulation.seed` set and `[dataset]`
//! removed: an ordinary scenario.

use crate::error::{self, KeyPath, ScenarioError, Seg};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, LogNormal, Normal, Uniform};
use serde::Deserialize;
use std::collections::{BTreeMap, BTreeSet};
use toml_edit::{DocumentMut, Item, Value};

/// The `[dataset]` section as written.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct DatasetToml {
    #[serde(default)]
    parameters: BTreeMap<String, ParameterToml>,
}

/// One entry of `[dataset.parameters]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ParameterToml {
    distribution: String,
    keys: Option<Vec<String>>,
    min: Option<f64>,
    max: Option<f64>,
    mean: Option<f64>,
    sd: Option<f64>,
    median: Option<f64>,
    sigma: Option<f64>,
    value: Option<f64>,
    p_absent: Option<f64>,
    absent: Option<f64>,
}

const ACCEPTED: &str = "accepted: uniform (min, max), normal (mean, sd), \
                        lognormal (median, sigma), constant (value)";

/// A drawn value's distribution.
#[derive(Debug, Clone)]
enum Dist {
    Uniform(Uniform<f64>),
    Normal(Normal<f64>),
    LogNormal(LogNormal<f64>),
    Constant(f64),
}

impl Dist {
    fn draw(&self, rng: &mut StdRng) -> f64 {
        match self {
            Dist::Uniform(d) => d.sample(rng),
            Dist::Normal(d) => d.sample(rng),
            Dist::LogNormal(d) => d.sample(rng),
            Dist::Constant(v) => *v,
        }
    }
}

/// One parameter of a dataset: its name, the keys it sets, and its distribution.
#[derive(Debug, Clone)]
pub struct Parameter {
    /// The entry's name: its key path, or a label for an entry with `keys`.
    pub name: String,
    /// The key paths that take the drawn value.
    pub keys: Vec<String>,
    /// Line and column of the entry in the scenario file.
    pub position: Option<(usize, usize)>,
    paths: Vec<KeyPath>,
    dist: Dist,
    p_absent: f64,
    absent: f64,
}

/// A scenario with a `[dataset]` section: the template and its parameters.
#[derive(Debug, Clone)]
pub struct Dataset {
    doc: DocumentMut,
    /// The parameters, in the order of their names.
    pub parameters: Vec<Parameter>,
}

/// One random machine: the scenario text and the drawn values, by parameter name.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// The scenario with the draws written in, `simulation.seed` set, no `[dataset]`.
    pub text: String,
    /// `(parameter name, value)` in the order of [`Dataset::parameters`].
    pub values: Vec<(String, f64)>,
}

/// The `[dataset]` of scenario `text` (named `file` in errors), or `None` when it has none.
pub fn from_text(text: &str, file: &str) -> Result<Option<Dataset>, ScenarioError> {
    let raw = crate::read_toml(text, file)?;
    let Some(section) = raw.dataset else {
        return Ok(None);
    };
    let located = |path: KeyPath, message: String| ScenarioError {
        file: file.to_string(),
        position: error::locate(text, &path).map(|s| error::line_col(text, s.start)),
        key: Some(path.to_string()),
        message,
    };
    let mut doc: DocumentMut = text
        .parse()
        .map_err(|e| located(KeyPath::default(), format!("{e}")))?;
    doc.remove("dataset");
    let mut seen = BTreeSet::new();
    let mut parameters = Vec::new();
    for (name, p) in section.parameters {
        let at = KeyPath::of(&["dataset", "parameters", &name]);
        let mut param =
            parameter(&doc, &name, p, &mut seen).map_err(|(field, m)| located(at.key(field), m))?;
        param.position = error::locate(text, &at).map(|s| error::line_col(text, s.start));
        parameters.push(param);
    }
    Ok(Some(Dataset { doc, parameters }))
}

/// Refuses `[dataset.parameters]` entries that are no inline table of a distribution, before
/// serde reads them (its words, `unknown field axes` or `expected struct ParameterToml`, do not
/// say what is accepted): a plain number, or an unquoted dotted key path, which TOML reads as
/// nested tables.
pub(crate) fn check_entries(text: &str, file: &str) -> Result<(), ScenarioError> {
    let Ok(doc) = toml_edit::Document::parse(text) else {
        return Ok(());
    };
    let Some(entries) = doc
        .get("dataset")
        .and_then(|d| d.get("parameters"))
        .and_then(Item::as_table_like)
    else {
        return Ok(());
    };
    for (name, item) in entries.iter() {
        let Some(message) = entry_shape(name, item) else {
            continue;
        };
        let span = entries.get_key_value(name).and_then(|(k, _)| k.span());
        return Err(ScenarioError {
            file: file.to_string(),
            position: span.map(|s| error::line_col(text, s.start)),
            key: Some(KeyPath::of(&["dataset", "parameters", name]).to_string()),
            message,
        });
    }
    Ok(())
}

/// What is wrong with the shape of entry `name`, if anything.
fn entry_shape(name: &str, item: &Item) -> Option<String> {
    let example = "\"machine.axes.x.drive.backlash_um\" = { distribution = \"uniform\", min = 0.0, \
                   max = 6.0 }";
    let Some(table) = item.as_table_like() else {
        return Some(format!(
            "{}: an entry is an inline table giving its distribution, e.g. {example}; {ACCEPTED}",
            item.as_value()
                .map_or("a table".into(), |v| v.to_string().trim().to_string())
        ));
    };
    if table.contains_key("distribution") || table.contains_key("keys") {
        return None;
    }
    let path = dotted(name, item)?;
    Some(format!(
        "`{path}` is unquoted, so TOML reads it as nested tables: quote the key path, \
         \"{path}\" = {{ distribution = ... }}"
    ))
}

/// The dotted path from `name` down to the first table giving a distribution, if any.
fn dotted(name: &str, item: &Item) -> Option<String> {
    let table = item.as_table_like()?;
    if table.contains_key("distribution") {
        return Some(name.to_string());
    }
    table
        .iter()
        .find_map(|(k, v)| dotted(&format!("{name}.{k}"), v))
}

type Refusal = (&'static str, String);

fn parameter(
    doc: &DocumentMut,
    name: &str,
    p: ParameterToml,
    seen: &mut BTreeSet<String>,
) -> Result<Parameter, Refusal> {
    let dist = distribution(&p)?;
    let (p_absent, absent) = absence(&p)?;
    let (keys, field) = match p.keys {
        Some(keys) if keys.is_empty() => {
            return Err((
                "keys",
                "an empty list: one key path or more is accepted".into(),
            ));
        }
        Some(keys) => {
            mislabelled(doc, name, &keys)?;
            (keys, "keys")
        }
        None => (vec![name.to_string()], "distribution"),
    };
    let mut paths = Vec::new();
    for key in &keys {
        let path = key_path(key).map_err(|m| (field, m))?;
        if number(doc, &path).is_none() {
            return Err((
                field,
                format!(
                    "`{key}` is not a number the scenario sets: the dotted key path of one is \
                     accepted, e.g. machine.axes.x.drive.backlash_um or \
                     instruments.ballbar.setup_eccentricity_um[0]"
                ),
            ));
        }
        if key == "simulation.seed" || !seen.insert(path.to_string()) {
            return Err((
                field,
                format!("`{key}` is drawn twice or is the seed: each key once is accepted"),
            ));
        }
        paths.push(path);
    }
    Ok(Parameter {
        name: name.to_string(),
        keys,
        position: None,
        paths,
        dist,
        p_absent,
        absent,
    })
}

/// `p_absent` (default 0) and `absent` (default 0) of an entry. An `absent` value with no
/// chance of being taken is refused: it would look like it has an effect.
fn absence(p: &ParameterToml) -> Result<(f64, f64), Refusal> {
    let p_absent = p.p_absent.unwrap_or(0.0);
    if !(0.0..=1.0).contains(&p_absent) {
        return Err((
            "p_absent",
            format!("{p_absent}: a probability from 0 to 1 is accepted"),
        ));
    }
    match p.absent {
        Some(a) if !a.is_finite() => Err(("absent", "a finite number is accepted".into())),
        Some(a) if p_absent == 0.0 => Err((
            "absent",
            format!(
                "{a} is never taken without a `p_absent` above 0: give p_absent (the chance of \
                 the absent value), or leave `absent` out"
            ),
        )),
        a => Ok((p_absent, a.unwrap_or(0.0))),
    }
}

/// Refuses an entry with `keys` that is named by another number's key path: the manifest's
/// column of that name would hold the draw of other keys.
fn mislabelled(doc: &DocumentMut, name: &str, keys: &[String]) -> Result<(), Refusal> {
    let Ok(path) = key_path(name) else {
        return Ok(());
    };
    let among = keys.iter().any(|k| key_path(k).is_ok_and(|p| p == path));
    if number(doc, &path).is_none() || among {
        return Ok(());
    }
    Err((
        "keys",
        format!(
            "the entry is named by the key path of `{name}`, a number the scenario sets, but \
             does not draw it: the manifest column `{name}` would hold the draw of {}; name \
             the entry by a label that is no key path (e.g. scale_x), or add `{name}` to keys",
            keys.join(", ")
        ),
    ))
}
/// The distribution of an entry, refusing fields that belong to another one.
fn distribution(p: &ParameterToml) -> Result<Dist, Refusal> {
    let given = [
        ("min", p.min),
        ("max", p.max),
        ("mean", p.mean),
        ("sd", p.sd),
        ("median", p.median),
        ("sigma", p.sigma),
        ("value", p.value),
    ];
    let wants: &[&str] = match p.distribution.as_str() {
        "uniform" => &["min", "max"],
        "normal" => &["mean", "sd"],
        "lognormal" => &["median", "sigma"],
        "constant" => &["value"],
        other => {
            return Err((
                "distribution",
                format!("unknown distribution `{other}`: {ACCEPTED}"),
            ));
        }
    };
    let mut v = Vec::new();
    for (field, value) in given {
        match (wants.contains(&field), value) {
            (true, Some(x)) if x.is_finite() => v.push(x),
            (true, _) => {
                return Err((
                    "distribution",
                    format!("{} needs a finite `{field}`; {ACCEPTED}", p.distribution),
                ));
            }
            (false, Some(_)) => {
                return Err((
                    "distribution",
                    format!("{} does not take `{field}`; {ACCEPTED}", p.distribution),
                ));
            }
            (false, None) => {}
        }
    }
    let bad = |field, m: String| Err((field, m));
    match (p.distribution.as_str(), v.as_slice()) {
        ("uniform", &[min, max]) if min > max => bad(
            "min",
            format!("min {min} > max {max}: min <= max is accepted"),
        ),
        ("uniform", &[min, max]) => Ok(Dist::Uniform(
            Uniform::new_inclusive(min, max).map_err(|e| ("min", e.to_string()))?,
        )),
        ("normal", &[_, sd]) if sd < 0.0 => {
            bad("sd", format!("{sd}: a standard deviation >= 0 is accepted"))
        }
        ("normal", &[mean, sd]) => Ok(Dist::Normal(
            Normal::new(mean, sd).map_err(|e| ("sd", e.to_string()))?,
        )),
        ("lognormal", &[median, _]) if median <= 0.0 => {
            bad("median", format!("{median}: a median > 0 is accepted"))
        }
        ("lognormal", &[_, sigma]) if sigma < 0.0 => {
            bad("sigma", format!("{sigma}: a sigma >= 0 is accepted"))
        }
        ("lognormal", &[median, sigma]) => Ok(Dist::LogNormal(
            LogNormal::new(median.ln(), sigma).map_err(|e| ("sigma", e.to_string()))?,
        )),
        (_, &[value]) => Ok(Dist::Constant(value)),
        _ => bad("distribution", ACCEPTED.to_string()),
    }
}

/// Parses `a.b."c-d".e[2]` into its segments.
pub(crate) fn key_path(key: &str) -> Result<KeyPath, String> {
    let bad =
        || format!("`{key}`: a dotted key path is accepted, with quoted keys and [index] elements");
    let mut segs = Vec::new();
    let mut rest = key;
    while !rest.is_empty() {
        let (name, tail) = if let Some(q) = rest.strip_prefix('"') {
            let end = q.find('"').ok_or_else(bad)?;
            (&q[..end], &q[end + 1..])
        } else {
            let end = rest.find(['.', '[']).unwrap_or(rest.len());
            (&rest[..end], &rest[end..])
        };
        if name.is_empty() {
            return Err(bad());
        }
        segs.push(Seg::Key(name.to_string()));
        rest = tail;
        while let Some(r) = rest.strip_prefix('[') {
            let end = r.find(']').ok_or_else(bad)?;
            segs.push(Seg::Index(r[..end].parse().map_err(|_| bad())?));
            rest = &r[end + 1..];
        }
        rest = match rest.strip_prefix('.') {
            Some(r) if !r.is_empty() => r,
            None if rest.is_empty() => rest,
            _ => return Err(bad()),
        };
    }
    Ok(KeyPath(segs))
}

/// The number at `path`, if the document sets one there.
pub(crate) fn number<'a>(doc: &'a DocumentMut, path: &KeyPath) -> Option<&'a Value> {
    value_at(doc, path).filter(|v| v.is_float() || v.is_integer())
}

/// The value at `path`, whatever its type.
pub(crate) fn value_at<'a>(doc: &'a DocumentMut, path: &KeyPath) -> Option<&'a Value> {
    let mut item: &Item = doc.as_item();
    for seg in &path.0 {
        item = match seg {
            Seg::Key(k) => item.get(k.as_str())?,
            Seg::Index(i) => item.get(*i)?,
        };
    }
    item.as_value()
}

pub(crate) fn number_mut<'a>(doc: &'a mut DocumentMut, path: &KeyPath) -> Option<&'a mut Value> {
    let mut item: &mut Item = doc.as_item_mut();
    for seg in &path.0 {
        item = match seg {
            Seg::Key(k) => item.get_mut(k.as_str())?,
            Seg::Index(i) => item.get_mut(*i)?,
        };
    }
    item.as_value_mut()
}

impl Dataset {
    /// The entry that draws the number at key path `key` (as a [`KeyPath`] displays it).
    pub fn entry_of(&self, key: &str) -> Option<&Parameter> {
        let path = key_path(key).ok()?;
        self.parameters.iter().find(|p| p.paths.contains(&path))
    }

    /// The entries that draw a key of the table that holds `key` (its siblings and their
    /// members): a check of the table's consistency, such as a circle against the strokes at
    /// `job.center_mm`, refuses one key for the value drawn for another.
    pub fn entries_beside(&self, key: &str) -> Vec<&Parameter> {
        let Ok(path) = key_path(key) else {
            return Vec::new();
        };
        let table = &path.0[..path.0.len().saturating_sub(1)];
        self.parameters
            .iter()
            .filter(|p| {
                p.paths
                    .iter()
                    .any(|q| q.0.len() > table.len() && q.0.starts_with(table))
            })
            .collect()
    }

    /// Draws machine `seed`: every parameter from its distribution (a generator seeded with
    /// `seed`, parameters in name order), written into the scenario with `simulation.seed = seed`.
    /// `seed` must fit a TOML integer (below 2^63).
    pub fn sample(&self, seed: u64) -> Sample {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut doc = self.doc.clone();
        let mut values = Vec::with_capacity(self.parameters.len());
        for p in &self.parameters {
            // Both draws always happen, so one entry's p_absent does not shift the others.
            let absent = rng.random::<f64>() < p.p_absent;
            let drawn = p.dist.draw(&mut rng);
            let v = if absent { p.absent } else { drawn };
            for path in &p.paths {
                if let Some(slot) = number_mut(&mut doc, path) {
                    let decor = slot.decor().clone();
                    *slot = Value::from(v);
                    *slot.decor_mut() = decor;
                }
            }
            values.push((p.name.clone(), v));
        }
        let seed = i64::try_from(seed).unwrap_or(i64::MAX);
        if !doc.contains_table("simulation") {
            doc["simulation"] = toml_edit::table();
        }
        doc["simulation"]["seed"] = toml_edit::value(seed);
        Sample {
            text: doc.to_string(),
            values,
        }
    }
}
