//! Instrument CSV exports read as they are exported: a mapping from our column names to the
//! export's own headers, and the export's units converted to ours.
//!
//! An instrument's software names its columns and picks its units (`Time (s),Accel X (m/s^2),
//! Accel Y (m/s^2),Accel Z (m/s^2),CI Value` from a spindle-housing accelerometer; g or ms from
//! another). A reader declares the columns it takes ([`Column`]: our name, its quantity, its
//! unit, whether it is required); the user maps them onto the file's headers
//! ([`ColumnMap::parse`]: `time_s=Time (s),ax=Accel X (m/s^2)`) and states units where they
//! differ from ours ([`Units::parse`]: `ax=g,time_s=ms`). [`resolve`] matches them against a
//! header and says which column holds each of ours and the factor that converts it; a
//! column not mapped is looked for under our own name. A unit written in the mapped header
//! (`Accel X (g)`, `Time [ms]`) is taken when none is stated, and a stated unit that contradicts
//! the header's is refused: a unit read wrong is an error of 9.81 or 1000 in every figure.
//!
//! Every refusal names what was given, the header it was looked for in and what is accepted.

use std::fmt;
use thiserror::Error;

/// What a column measures, which sets the units it is accepted in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// Time, s.
    Time,
    /// Acceleration, m/s².
    Acceleration,
    /// A length in µm (deviations).
    Micrometres,
    /// A length in mm (positions).
    Millimetres,
    /// An angle, deg.
    Angle,
    /// Words or counts (a direction, a run number): no unit.
    Label,
}

/// A unit a column can be given in, with its factor to the column's own unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    /// The unit's name as written.
    pub name: &'static str,
    /// Value in our unit = value in this unit × factor.
    pub factor: f64,
}

/// Standard gravity, m/s² (ISO 80000-3; the g of accelerometer data sheets).
pub const STANDARD_GRAVITY: f64 = 9.806_65;

impl Quantity {
    /// The units accepted, ours first, each with the spellings that name it.
    fn units(self) -> &'static [(Unit, &'static [&'static str])] {
        const S: Unit = Unit {
            name: "s",
            factor: 1.0,
        };
        const MS: Unit = Unit {
            name: "ms",
            factor: 1e-3,
        };
        const MPS2: Unit = Unit {
            name: "m/s²",
            factor: 1.0,
        };
        const G: Unit = Unit {
            name: "g",
            factor: STANDARD_GRAVITY,
        };
        const DEG: Unit = Unit {
            name: "deg",
            factor: 1.0,
        };
        const RAD: Unit = Unit {
            name: "rad",
            factor: 180.0 / std::f64::consts::PI,
        };
        match self {
            Quantity::Time => &[(S, &["s", "sec"]), (MS, &["ms", "msec"])],
            Quantity::Acceleration => &[
                (MPS2, &["m/s^2", "m/s²", "m/s2", "m s^-2", "m*s^-2"]),
                (G, &["g", "g0", "gn"]),
            ],
            Quantity::Micrometres => &[
                (
                    Unit {
                        name: "µm",
                        factor: 1.0,
                    },
                    &["um", "µm", "μm", "micron", "microns"],
                ),
                (
                    Unit {
                        name: "mm",
                        factor: 1e3,
                    },
                    &["mm"],
                ),
            ],
            Quantity::Millimetres => &[
                (
                    Unit {
                        name: "mm",
                        factor: 1.0,
                    },
                    &["mm"],
                ),
                (
                    Unit {
                        name: "µm",
                        factor: 1e-3,
                    },
                    &["um", "µm", "μm", "micron", "microns"],
                ),
            ],
            Quantity::Angle => &[(DEG, &["deg", "°", "degree", "degrees"]), (RAD, &["rad"])],
            Quantity::Label => &[],
        }
    }

    /// Our unit for this quantity (`None` for a label).
    pub fn own_unit(self) -> Option<Unit> {
        self.units().first().map(|(u, _)| *u)
    }

    /// The unit named `text` (case-insensitive for the letters, as written otherwise).
    pub fn unit(self, text: &str) -> Option<Unit> {
        let t = text.trim();
        self.units()
            .iter()
            .find(|(_, names)| names.iter().any(|n| n.eq_ignore_ascii_case(t) || *n == t))
            .map(|(u, _)| *u)
    }

    /// The accepted units' names, for messages.
    pub fn accepted(self) -> String {
        self.units()
            .iter()
            .map(|(u, _)| u.name)
            .collect::<Vec<_>>()
            .join(" or ")
    }
}

/// One column a reader takes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Column {
    /// Our name, e.g. `ax`.
    pub name: &'static str,
    /// What it measures.
    pub quantity: Quantity,
    /// Whether a file must have it.
    pub required: bool,
}

/// The columns of an accelerometer log: its time (s) and one or more of the accelerations
/// along X, Y and Z (m/s²).
pub const ACCELEROMETER_COLUMNS: [Column; 4] = [
    Column {
        name: "time_s",
        quantity: Quantity::Time,
        required: true,
    },
    Column {
        name: "ax",
        quantity: Quantity::Acceleration,
        required: false,
    },
    Column {
        name: "ay",
        quantity: Quantity::Acceleration,
        required: false,
    },
    Column {
        name: "az",
        quantity: Quantity::Acceleration,
        required: false,
    },
];

/// Why an export cannot be read as mapped.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ImportError {
    /// `--columns` or `--units` that does not parse.
    #[error("{option} `{text}`: {why}")]
    Syntax {
        /// The option.
        option: &'static str,
        /// The entry.
        text: String,
        /// What is wrong and what is accepted.
        why: String,
    },
    /// A mapping or unit for a column the reader does not take.
    #[error("{option} names `{name}`, which is not a column of {what}; accepted: {accepted}")]
    UnknownColumn {
        /// The option.
        option: &'static str,
        /// The name given.
        name: String,
        /// What the file is.
        what: &'static str,
        /// Our column names.
        accepted: String,
    },
    /// A mapping naming a header the file does not have.
    #[error(
        "--columns maps `{name}` to `{header}`, but the header has no such column (found: {found})"
    )]
    MissingHeader {
        /// Our column name.
        name: String,
        /// The header it was mapped to.
        header: String,
        /// The file's headers.
        found: String,
    },
    /// A required column neither mapped nor present under our name.
    #[error(
        "no `{name}` column (found: {found}); {what} has {accepted}: map it to the export's \
         header with --columns {name}=HEADER"
    )]
    MissingColumn {
        /// Our column name.
        name: &'static str,
        /// The file's headers.
        found: String,
        /// What the file is.
        what: &'static str,
        /// Our column names.
        accepted: String,
    },
    /// A unit this column is not accepted in.
    #[error("--units {name}={unit}: not a unit of {name}; accepted: {accepted}")]
    UnknownUnit {
        /// Our column name.
        name: String,
        /// The unit given.
        unit: String,
        /// The units accepted.
        accepted: String,
    },
    /// A unit stated against the one written in the column's header.
    #[error(
        "--units {name}={given}, but its column `{header}` says {in_header}; state the unit the \
         export uses"
    )]
    UnitConflict {
        /// Our column name.
        name: &'static str,
        /// The header.
        header: String,
        /// The unit in the header.
        in_header: &'static str,
        /// The unit stated.
        given: &'static str,
    },
    /// Two of our columns mapped to one header, or one mapped twice.
    #[error("--columns: {0}")]
    Ambiguous(String),
}

/// `--columns`: our column names mapped to the export's headers, in the order given.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ColumnMap {
    /// (our name, the export's header).
    pub pairs: Vec<(String, String)>,
}

/// Splits `text` into `key=value` entries at the commas that are followed by a key and `=`, so
/// that a header holding a comma (`Accel (x, m/s^2)`) stays whole.
fn entries(option: &'static str, text: &str) -> Result<Vec<(String, String)>, ImportError> {
    let bytes = text.as_bytes();
    let is_key_start = |i: usize| {
        let rest = &text[i..];
        let key: String = rest
            .trim_start()
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect();
        !key.is_empty()
            && rest.trim_start()[key.len()..].trim_start().starts_with('=')
            && key.chars().next().is_some_and(|c| !c.is_ascii_digit())
    };
    let mut cuts = vec![0];
    for (i, &b) in bytes.iter().enumerate() {
        if b == b',' && is_key_start(i + 1) {
            cuts.push(i + 1);
        }
    }
    cuts.push(text.len() + 1);
    let mut out = Vec::new();
    for w in cuts.windows(2) {
        let entry = &text[w[0]..(w[1] - 1).min(text.len())];
        if entry.trim().is_empty() {
            continue;
        }
        let Some((k, v)) = entry.split_once('=') else {
            return Err(ImportError::Syntax {
                option,
                text: entry.to_string(),
                why: "an entry is NAME=VALUE, entries separated by commas".into(),
            });
        };
        let (k, v) = (k.trim(), v.trim());
        if k.is_empty() || v.is_empty() {
            return Err(ImportError::Syntax {
                option,
                text: entry.to_string(),
                why: "an entry is NAME=VALUE with neither empty".into(),
            });
        }
        out.push((k.to_string(), v.to_string()));
    }
    Ok(out)
}

impl ColumnMap {
    /// Parses `name=Header,name=Header,…` (headers as written in the file, spaces kept inside,
    /// commas allowed where not followed by `name=`).
    pub fn parse(text: &str) -> Result<Self, ImportError> {
        let pairs = entries("--columns", text)?;
        for (i, (k, _)) in pairs.iter().enumerate() {
            if pairs[..i].iter().any(|(j, _)| j == k) {
                return Err(ImportError::Ambiguous(format!("`{k}` is mapped twice")));
            }
        }
        Ok(Self { pairs })
    }
}

/// `--units`: our column names with the unit the export gives them in.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Units {
    /// (our name, the unit as written).
    pub pairs: Vec<(String, String)>,
}

impl Units {
    /// Parses `name=unit,name=unit,…`.
    pub fn parse(text: &str) -> Result<Self, ImportError> {
        let pairs = entries("--units", text)?;
        for (i, (k, _)) in pairs.iter().enumerate() {
            if pairs[..i].iter().any(|(j, _)| j == k) {
                return Err(ImportError::Syntax {
                    option: "--units",
                    text: text.to_string(),
                    why: format!("`{k}` is given twice"),
                });
            }
        }
        Ok(Self { pairs })
    }
}

/// Where a column's unit came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnitSource {
    /// Ours, nothing said otherwise.
    Default,
    /// Written in the export's header.
    Header,
    /// Stated with `--units`.
    Stated,
}

/// One of our columns found in the file.
#[derive(Debug, Clone, PartialEq)]
pub struct Found {
    /// Our name.
    pub name: &'static str,
    /// The export's header.
    pub header: String,
    /// Its index in the header (0-based).
    pub index: usize,
    /// The unit it is read in (`None` for a label).
    pub unit: Option<Unit>,
    /// Where that unit came from.
    pub source: UnitSource,
}

/// The columns of a reader found in one file's header.
#[derive(Debug, Clone, PartialEq)]
pub struct Resolved {
    /// The columns found, in the reader's order (a column that is not required and absent is
    /// left out).
    pub columns: Vec<Found>,
}

impl Resolved {
    /// Our column `name`, if found.
    pub fn get(&self, name: &str) -> Option<&Found> {
        self.columns.iter().find(|c| c.name == name)
    }

    /// Its index in the header.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.get(name).map(|c| c.index)
    }

    /// The factor that converts its values to our unit (1 for a label or an absent column).
    pub fn factor(&self, name: &str) -> f64 {
        self.get(name)
            .and_then(|c| c.unit)
            .map_or(1.0, |u| u.factor)
    }
}

impl fmt::Display for Resolved {
    /// `time_s = "Time (s)" in s (from the header), ax = "Accel X (m/s^2)" in m/s² …`: what
    /// was read where and in which unit, for the report.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self
            .columns
            .iter()
            .map(|c| {
                let unit = match (c.unit, c.source) {
                    (None, _) => String::new(),
                    (Some(u), UnitSource::Default) => format!(" in {}", u.name),
                    (Some(u), UnitSource::Header) => format!(" in {} (from the header)", u.name),
                    (Some(u), UnitSource::Stated) => format!(" in {} (--units)", u.name),
                };
                format!("{} = \"{}\"{unit}", c.name, c.header)
            })
            .collect();
        f.write_str(&parts.join(", "))
    }
}

/// The unit written in a header, `Name (unit)` or `Name [unit]`, if it names a unit of `q`.
fn header_unit(header: &str, q: Quantity) -> Option<Unit> {
    let h = header.trim_end();
    let (open, close) = match h.chars().last()? {
        ')' => ('(', ')'),
        ']' => ('[', ']'),
        _ => return None,
    };
    let start = h.rfind(open)?;
    let inner = &h[start + open.len_utf8()..h.len() - close.len_utf8()];
    q.unit(inner)
}

/// Finds the `columns` of a reader of `what` in `header` with the mapping and units given.
pub fn resolve(
    header: &[&str],
    columns: &[Column],
    map: &ColumnMap,
    units: &Units,
    what: &'static str,
) -> Result<Resolved, ImportError> {
    let names = || {
        columns
            .iter()
            .map(|c| c.name)
            .collect::<Vec<_>>()
            .join(", ")
    };
    let found = || header.join(", ");
    for (option, keys) in [
        (
            "--columns",
            map.pairs.iter().map(|p| &p.0).collect::<Vec<_>>(),
        ),
        ("--units", units.pairs.iter().map(|p| &p.0).collect()),
    ] {
        if let Some(k) = keys
            .iter()
            .find(|k| !columns.iter().any(|c| c.name == k.as_str()))
        {
            return Err(ImportError::UnknownColumn {
                option,
                name: (*k).clone(),
                what,
                accepted: names(),
            });
        }
    }
    let mut out = Vec::new();
    for c in columns {
        let mapped = map.pairs.iter().find(|(k, _)| k == c.name).map(|p| &p.1);
        let index = match mapped {
            Some(h) => Some(
                header
                    .iter()
                    .position(|x| x.trim() == h.trim())
                    .ok_or_else(|| ImportError::MissingHeader {
                        name: c.name.to_string(),
                        header: h.clone(),
                        found: found(),
                    })?,
            ),
            None => header.iter().position(|x| x.trim() == c.name),
        };
        let Some(index) = index else {
            if c.required {
                return Err(ImportError::MissingColumn {
                    name: c.name,
                    found: found(),
                    what,
                    accepted: names(),
                });
            }
            continue;
        };
        let stated = units.pairs.iter().find(|(k, _)| k == c.name).map(|p| &p.1);
        let (unit, source) = match (c.quantity.own_unit(), stated) {
            (None, Some(u)) => {
                return Err(ImportError::UnknownUnit {
                    name: c.name.to_string(),
                    unit: u.clone(),
                    accepted: "none: the column has no unit".into(),
                });
            }
            (None, None) => (None, UnitSource::Default),
            (Some(own), stated) => {
                let in_header = header_unit(header[index], c.quantity);
                match stated {
                    Some(text) => {
                        let u = c
                            .quantity
                            .unit(text)
                            .ok_or_else(|| ImportError::UnknownUnit {
                                name: c.name.to_string(),
                                unit: text.clone(),
                                accepted: c.quantity.accepted(),
                            })?;
                        if let Some(h) = in_header.filter(|h| h.name != u.name) {
                            return Err(ImportError::UnitConflict {
                                name: c.name,
                                header: header[index].to_string(),
                                in_header: h.name,
                                given: u.name,
                            });
                        }
                        (Some(u), UnitSource::Stated)
                    }
                    None => match in_header {
                        Some(h) => (Some(h), UnitSource::Header),
                        None => (Some(own), UnitSource::Default),
                    },
                }
            }
        };
        out.push(Found {
            name: c.name,
            header: header[index].to_string(),
            index,
            unit,
            source,
        });
    }
    for (i, a) in out.iter().enumerate() {
        if let Some(b) = out[..i].iter().find(|b| b.index == a.index) {
            return Err(ImportError::Ambiguous(format!(
                "`{}` and `{}` both read the column `{}`",
                b.name, a.name, a.header
            )));
        }
    }
    Ok(Resolved { columns: out })
}

#[cfg(test)]
mod tests {
    use super::*;

    const EXPORT: [&str; 5] = [
        "Time (s)",
        "Accel X (m/s^2)",
        "Accel Y (m/s^2)",
        "Accel Z (m/s^2)",
        "CI Value",
    ];

    fn map() -> ColumnMap {
        ColumnMap::parse("time_s=Time (s),ax=Accel X (m/s^2),ay=Accel Y (m/s^2),az=Accel Z (m/s^2)")
            .unwrap()
    }

    #[test]
    fn the_exported_header_is_read_through_the_mapping() {
        let r = resolve(
            &EXPORT,
            &ACCELEROMETER_COLUMNS,
            &map(),
            &Units::default(),
            "an accelerometer log",
        )
        .unwrap();
        assert_eq!(r.index("time_s"), Some(0));
        assert_eq!(r.index("az"), Some(3));
        assert_eq!(r.factor("ax"), 1.0);
        assert_eq!(r.get("ax").unwrap().source, UnitSource::Header);
        let echo = r.to_string();
        assert!(
            echo.contains("ax = \"Accel X (m/s^2)\" in m/s² (from the header)"),
            "{echo}"
        );
    }

    #[test]
    fn units_are_taken_from_the_header_or_stated() {
        let header = ["t [ms]", "x (g)", "y"];
        let map = ColumnMap::parse("time_s=t [ms],ax=x (g),ay=y").unwrap();
        let units = Units::parse("ay=g").unwrap();
        let r = resolve(
            &header,
            &ACCELEROMETER_COLUMNS,
            &map,
            &units,
            "an accelerometer log",
        )
        .unwrap();
        assert_eq!(r.factor("time_s"), 1e-3);
        assert_eq!(r.factor("ax"), STANDARD_GRAVITY);
        assert_eq!(r.factor("ay"), STANDARD_GRAVITY);
        assert_eq!(r.get("ay").unwrap().source, UnitSource::Stated);
        assert!(r.get("az").is_none());
    }

    #[test]
    fn a_comma_inside_a_header_stays_in_it() {
        let m = ColumnMap::parse("time_s=Time, s,ax=Accel (x, g)").unwrap();
        assert_eq!(
            m.pairs,
            vec![
                ("time_s".to_string(), "Time, s".to_string()),
                ("ax".to_string(), "Accel (x, g)".to_string())
            ]
        );
    }

    #[test]
    fn bad_mappings_and_units_are_refused_naming_them() {
        let e = resolve(
            &EXPORT,
            &ACCELEROMETER_COLUMNS,
            &ColumnMap::parse("time_s=Time (s),ax=Accel Q (m/s^2)").unwrap(),
            &Units::default(),
            "an accelerometer log",
        )
        .unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("`Accel Q (m/s^2)`") && text.contains("Accel X (m/s^2)"),
            "{text}"
        );
        let e = resolve(
            &EXPORT,
            &ACCELEROMETER_COLUMNS,
            &map(),
            &Units::parse("ax=furlong").unwrap(),
            "an accelerometer log",
        )
        .unwrap_err();
        assert!(matches!(&e, ImportError::UnknownUnit { .. }), "{e}");
        assert!(e.to_string().contains("m/s² or g"), "{e}");
        let e = resolve(
            &EXPORT,
            &ACCELEROMETER_COLUMNS,
            &map(),
            &Units::parse("ax=g").unwrap(),
            "an accelerometer log",
        )
        .unwrap_err();
        assert!(matches!(e, ImportError::UnitConflict { .. }), "{e}");
        let e = resolve(
            &EXPORT,
            &ACCELEROMETER_COLUMNS,
            &ColumnMap::parse("bx=Accel X (m/s^2)").unwrap(),
            &Units::default(),
            "an accelerometer log",
        )
        .unwrap_err();
        assert!(e.to_string().contains("time_s, ax, ay, az"), "{e}");
        let e = resolve(
            &EXPORT,
            &ACCELEROMETER_COLUMNS,
            &ColumnMap::default(),
            &Units::default(),
            "an accelerometer log",
        )
        .unwrap_err();
        assert!(e.to_string().contains("--columns time_s=HEADER"), "{e}");
        assert!(ColumnMap::parse("time_s").is_err());
        assert!(ColumnMap::parse("ax=a,ax=b").is_err());
        let e = resolve(
            &EXPORT,
            &ACCELEROMETER_COLUMNS,
            &ColumnMap::parse("time_s=Time (s),ax=Time (s)").unwrap(),
            &Units::default(),
            "an accelerometer log",
        );
        assert!(e.is_err());
    }
}
