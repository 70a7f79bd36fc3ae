//! The manifest of a dataset (`manifest.csv`, `manifest.parquet`): one row per complete run,
//! read from the runs' labels, which are checked on the way.

use crate::Error;
use crate::folder::{complete_runs, name_of, write_aside};
use parquet::basic::{LogicalType, Repetition, Type as Physical};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int64Type};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;
use serde_json::{Map, Value, json};
use std::collections::BTreeSet;
use std::path::Path;
use std::sync::Arc;

/// The manifest: column names and one row per run (id, seed, then numbers or gaps), and what
/// the Parquet file's key-value metadata says of the columns.
struct Manifest {
    numbers: Vec<String>,
    rows: Vec<(String, i64, Vec<Option<f64>>)>,
    metadata: Vec<(String, String)>,
}

/// The unit of the number at a scenario key path, from its name's unit tokens (the scenario's
/// convention: `backlash_um`, `kv_per_s`, `coulomb_n`, `feed_mm_min`, `stiffness_n_per_um`,
/// `capacity_j_per_k`, `alpha_per_k`); None when a token is not one listed here.
fn key_unit(key: &str) -> Option<String> {
    // The last name of the path, without an index (`center_mm[0]`) or quotes.
    let last = key.rsplit('.').next().unwrap_or(key);
    let name = last.split('[').next().unwrap_or(last).trim_matches('"');
    let unit = |t: &str| -> Option<&'static str> {
        Some(match t {
            "um" => "µm",
            "mm" => "mm",
            "m" => "m",
            "urad" => "µrad",
            "deg" => "deg",
            "n" => "N",
            "j" => "J",
            "w" => "W",
            "kg" => "kg",
            "hz" => "Hz",
            "c" => "°C",
            "k" => "K",
            "s" => "s",
            "ms" => "ms",
            "ppm" => "ppm",
            "us" => "µs",
            "min" => "min",
            _ => return None,
        })
    };
    let tokens: Vec<&str> = name.split('_').collect();
    if let Some(p) = tokens.iter().position(|t| *t == "per") {
        // `<quantity>_per_<unit>` is 1/unit; `<unit>_per_<unit>` a ratio of the two.
        let below = unit(tokens.get(p + 1)?)?;
        if p + 2 != tokens.len() {
            return None;
        }
        let above = |q: usize| p.checked_sub(q).and_then(|i| unit(tokens[i]));
        return Some(match (above(2), above(1)) {
            (Some(a), Some(b)) => format!("{a}·{b}/{below}"),
            (None, Some(b)) => format!("{b}/{below}"),
            _ => format!("1/{below}"),
        });
    }
    match tokens.as_slice() {
        // `feed_mm_min`, `stribeck_m_s`: a speed.
        [.., a, t @ ("min" | "s")] if unit(a).is_some_and(|u| u.ends_with('m')) => {
            Some(format!("{}/{}", unit(a)?, unit(t)?))
        }
        [_, .., last] => unit(last).map(str::to_string),
        _ => None,
    }
}

/// The manifest's column of ground-truth figure `key` (as sim's `truth::test_figures` computes
/// them): `truth.<key>_<unit>`, the unit in the scenario's tokens (`um`, `ppm`, `um_per_m`, `ms`,
/// `urad`).
fn truth_column(key: &str) -> String {
    let unit = if key.starts_with("scale_mismatch") {
        "ppm"
    } else if key.starts_with("squareness") {
        "um_per_m"
    } else if key.starts_with("servo_mismatch") {
        "ms"
    } else if key.starts_with("angular_play") {
        "urad"
    } else {
        "um"
    };
    format!("truth.{key}_{unit}")
}

/// The Parquet key-value metadata: `unit.<column>` for every column of a known unit and
/// `keys.<column>` (a JSON list) for a parameter of an entry with `keys`.
fn column_metadata(names: &BTreeSet<String>, keys: &Map<String, Value>) -> Vec<(String, String)> {
    let mut out = vec![(
        "seed".to_string(),
        "each run's seed (simulation.seed)".into(),
    )];
    for name in names {
        let listed: Vec<&str> = keys
            .get(name.as_str())
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
            .filter_map(Value::as_str)
            .collect();
        let units: BTreeSet<Option<String>> = listed.iter().map(|k| key_unit(k)).collect();
        match units.into_iter().collect::<Vec<_>>().as_slice() {
            [Some(unit)] => out.push((format!("unit.{name}"), unit.clone())),
            [] => out.extend(key_unit(name).map(|u| (format!("unit.{name}"), u))),
            _ => {}
        }
        if listed.len() > 1 || listed.first().is_some_and(|k| k != name) {
            out.push((format!("keys.{name}"), json!(listed).to_string()));
        }
    }
    out
}

/// Reads every complete run's labels into the manifest's rows; a run without a parameter the
/// others have is damaged.
fn manifest(dir: &Path) -> Result<Manifest, Error> {
    let runs = complete_runs(dir)?;
    let labels = runs
        .iter()
        .map(|p| read_run_labels(p))
        .collect::<Result<Vec<_>, _>>()?;
    let figures =
        |l: &Value| vmt_logs::truth::truth_effects(&l["ground_truth"], 0).unwrap_or_default();
    let mut names = BTreeSet::new();
    let mut truths = BTreeSet::new();
    for l in &labels {
        names.extend(
            l["parameters"]
                .as_object()
                .into_iter()
                .flatten()
                .map(|(k, _)| k.clone()),
        );
        truths.extend(figures(l).keys().cloned());
    }
    // Every run of a dataset draws the same parameters and has the same truth figures (a
    // trace's closing error is missing only from a trace with no reading, which no run
    // completes), so one that lacks one the others have was edited.
    for (run, l) in runs.iter().zip(&labels) {
        let lacks = names
            .iter()
            .find(|n| !l["parameters"][n].is_number())
            .map(|n| format!("parameters.{n}"))
            .or_else(|| {
                let f = figures(l);
                truths.iter().find(|k| !f.contains_key(*k)).map(|k| {
                    let section = if k.contains("drift") {
                        "drift"
                    } else {
                        "figures"
                    };
                    format!("ground_truth.ballbar.tests[0].{section}.{k}")
                })
            });
        if let Some(key) = lacks {
            return Err(Error::input(
                &run.join("labels.json").display().to_string(),
                None,
                format!(
                    "`{key}` is missing (other runs have it); the run is damaged: remove its \
                     folder and run `vmt dataset` again with the same arguments to simulate it \
                     anew"
                ),
            ));
        }
    }
    let rows = labels
        .iter()
        .map(|l| {
            let f = figures(l);
            let params = names.iter().map(|n| l["parameters"][n].as_f64());
            let truth = truths.iter().map(|k| f.get(k).and_then(Value::as_f64));
            (
                l["id"].as_str().unwrap_or_default().to_string(),
                l["seed"].as_i64().unwrap_or(-1),
                params.chain(truth).collect(),
            )
        })
        .collect();
    let keys = labels
        .first()
        .and_then(|l| l["keys"].as_object().cloned())
        .unwrap_or_default();
    let mut metadata = column_metadata(&names, &keys);
    let truth_columns: Vec<String> = truths.iter().map(|k| truth_column(k)).collect();
    metadata.extend(
        truth_columns
            .iter()
            .filter_map(|c| Some((format!("unit.{c}"), key_unit(c)?))),
    );
    let numbers = names.into_iter().chain(truth_columns).collect();
    Ok(Manifest {
        numbers,
        rows,
        metadata,
    })
}

/// Reads run folder `run`'s `labels.json`, checked to be what `vmt dataset` writes: an
/// object with the run's `id` (the folder's name), its `seed` and the `parameters`, `keys` and
/// `ground_truth` objects. A label that is not JSON (named with serde's line and column) or
/// lacks one of them is a damaged run, an error naming the file: not a run to leave out.
pub fn read_run_labels(run: &Path) -> Result<Value, Error> {
    let path = run.join("labels.json");
    let file = path.display().to_string();
    let damaged = |what: String| {
        format!(
            "{what}; the run is damaged: remove its folder and run `vmt dataset` again with the \
             same arguments to simulate it anew"
        )
    };
    let text =
        std::fs::read_to_string(&path).map_err(|e| Error::input(&file, None, e.to_string()))?;
    let v: Value = serde_json::from_str(&text)
        .map_err(|e| Error::input(&file, Some(e.line()), damaged(format!("not JSON ({e})"))))?;
    match label_problem(&v, &name_of(run)) {
        Some(what) => Err(Error::input(&file, None, damaged(what))),
        None => Ok(v),
    }
}

/// What makes `v` not the label of run `id`, if anything.
fn label_problem(v: &Value, id: &str) -> Option<String> {
    let holds = "a label holds id, seed, parameters, keys and ground_truth";
    if !v.is_object() {
        return Some(format!("not a JSON object ({holds})"));
    }
    if let Some(k) = ["id", "seed", "parameters", "keys", "ground_truth"]
        .into_iter()
        .find(|k| v.get(k).is_none())
    {
        return Some(format!("the key `{k}` is missing ({holds})"));
    }
    if v["id"].as_str() != Some(id) {
        return Some(format!(
            "`id` is {}, not the run's folder name \"{id}\"",
            v["id"]
        ));
    }
    if v["seed"].as_u64().is_none() {
        return Some(format!("`seed` is {}, not a whole number", v["seed"]));
    }
    if let Some(k) = ["parameters", "keys", "ground_truth"]
        .into_iter()
        .find(|k| !v[k].is_object())
    {
        return Some(format!("`{k}` is {}, not an object", v[k]));
    }
    missing_number(v)
}

/// The first parameter or truth figure run label `v` lacks: every entry `keys` lists has its
/// number in `parameters`, and the truth has figures of its first circular test, each a number
/// (the manifest would hold NaN or an empty cell instead).
fn missing_number(v: &Value) -> Option<String> {
    let names = v["keys"].as_object().into_iter().flatten().map(|(k, _)| k);
    if let Some(name) = names.into_iter().find(|n| !v["parameters"][n].is_number()) {
        return Some(format!(
            "`parameters.{name}` is missing or not a number (`keys` lists the entry)"
        ));
    }
    let truth = &v["ground_truth"];
    let ballbar = truth.get("ballbar");
    if ballbar.is_some_and(Value::is_null) || (ballbar.is_none() && truth.get("milling").is_some())
    {
        // A job without a circular test (a positioning test's truth has a null `ballbar`, a
        // milling run's none but its `milling`; a damaged label lacks the key): no figures.
        return None;
    }
    let Some(figures) = vmt_logs::truth::truth_figures(&v["ground_truth"], 0) else {
        return Some(
            "`ground_truth.ballbar.tests[0].figures` is missing (the truth of the run's \
             circular test)"
                .into(),
        );
    };
    let drift = vmt_logs::truth::truth_drift(truth, 0).into_iter().flatten();
    figures
        .iter()
        .map(|kv| ("figures", kv))
        .chain(drift.map(|kv| ("drift", kv)))
        .find(|(_, (_, f))| !f.is_number())
        .map(|(section, (k, f))| {
            format!("`ground_truth.ballbar.tests[0].{section}.{k}` is {f}, not a number")
        })
}

/// Rebuilds `manifest.csv` and `manifest.parquet` from the labels; returns the number of rows.
pub fn write_manifest(dir: &Path) -> Result<usize, Error> {
    let m = manifest(dir)?;
    write_aside(dir, "manifest.csv", "", |tmp| write_csv(&m, tmp))?;
    write_aside(dir, "manifest.parquet", "", |tmp| {
        write_parquet(&m, tmp).map_err(|e| Error::output(&dir.join("manifest.parquet"), e))
    })?;
    Ok(m.rows.len())
}

fn write_csv(m: &Manifest, path: &Path) -> Result<(), Error> {
    let err = |e: csv::Error| Error::output(path, e);
    let mut w = csv::Writer::from_path(path).map_err(err)?;
    let header = ["id", "seed"].into_iter().map(String::from);
    w.write_record(header.chain(m.numbers.iter().cloned()))
        .map_err(err)?;
    for (id, seed, values) in &m.rows {
        let cells = values
            .iter()
            .map(|v| v.map(|x| x.to_string()).unwrap_or_default());
        w.write_record([id.clone(), seed.to_string()].into_iter().chain(cells))
            .map_err(err)?;
    }
    w.flush().map_err(|e| Error::output(path, e))
}

/// One row group, written with parquet's column writers: `id` (string), `seed` (int64), and a
/// nullable double per number column (a run without that figure is a null).
fn column(
    name: &str,
    t: Physical,
    rep: Repetition,
) -> parquet::schema::types::PrimitiveTypeBuilder<'_> {
    Type::primitive_type_builder(name, t).with_repetition(rep)
}

fn write_parquet(m: &Manifest, path: &Path) -> parquet::errors::Result<()> {
    let mut fields = vec![
        Arc::new(
            column("id", Physical::BYTE_ARRAY, Repetition::REQUIRED)
                .with_logical_type(Some(LogicalType::String))
                .build()?,
        ),
        Arc::new(column("seed", Physical::INT64, Repetition::REQUIRED).build()?),
    ];
    for n in &m.numbers {
        fields.push(Arc::new(
            column(n, Physical::DOUBLE, Repetition::OPTIONAL).build()?,
        ));
    }
    let schema = Arc::new(
        Type::group_type_builder("manifest")
            .with_fields(fields)
            .build()?,
    );
    let file = std::fs::File::create(path)?;
    let metadata = m
        .metadata
        .iter()
        .map(|(k, v)| KeyValue::new(k.clone(), v.clone()))
        .collect();
    let props = Arc::new(
        WriterProperties::builder()
            .set_key_value_metadata(Some(metadata))
            .build(),
    );
    let mut writer = SerializedFileWriter::new(file, schema, props)?;
    let mut group = writer.next_row_group()?;
    let mut index = 0;
    while let Some(mut col) = group.next_column()? {
        match index {
            0 => {
                let ids: Vec<ByteArray> = m.rows.iter().map(|r| r.0.as_str().into()).collect();
                col.typed::<ByteArrayType>().write_batch(&ids, None, None)?;
            }
            1 => {
                let seeds: Vec<i64> = m.rows.iter().map(|r| r.1).collect();
                col.typed::<Int64Type>().write_batch(&seeds, None, None)?;
            }
            _ => {
                let cells = m.rows.iter().map(|r| r.2[index - 2]);
                let values: Vec<f64> = cells.clone().flatten().collect();
                let defined: Vec<i16> = cells.map(|c| i16::from(c.is_some())).collect();
                col.typed::<DoubleType>()
                    .write_batch(&values, Some(&defined), None)?;
            }
        }
        col.close()?;
        index += 1;
    }
    group.close()?;
    writer.close()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::key_unit;

    /// Units read from the scenario's key names, compound ones included (a suffix match had
    /// given `µm` for N/µm and `1/K` for J/K).
    #[test]
    fn units_follow_the_key_names() {
        for (key, unit) in [
            ("machine.axes.x.drive.backlash_um", Some("µm")),
            ("machine.axes.x.servo.kv_per_s", Some("1/s")),
            ("machine.axes.x.drive.guide_friction.coulomb_n", Some("N")),
            ("job.feed_mm_min", Some("mm/min")),
            (
                "machine.axes.x.drive.guide_friction.stribeck_m_s",
                Some("m/s"),
            ),
            ("instruments.ballbar.setup_drift_um_per_min", Some("µm/min")),
            (
                "machine.axes.x.drive.screw_stiffness_n_per_um",
                Some("N/µm"),
            ),
            (
                "machine.axes.x.drive.guide_friction.sigma1_n_s_per_m",
                Some("N·s/m"),
            ),
            ("machine.thermal.nodes[0].capacity_j_per_k", Some("J/K")),
            (
                "machine.thermal.links.\"G-Z\".translation_um_per_k",
                Some("µm/K"),
            ),
            ("instruments.ballbar.bar_alpha_per_k", Some("1/K")),
            ("machine.axes.x.drive.encoder_counts_per_rev", None),
            ("machine.errors.squareness.ec0y_urad", Some("µrad")),
            ("truth.backlash_x_um", Some("µm")),
            ("truth.scale_mismatch_xy_ppm", Some("ppm")),
            ("truth.squareness_xy_um_per_m", Some("µm/m")),
            ("truth.servo_mismatch_xy_ms", Some("ms")),
        ] {
            assert_eq!(key_unit(key).as_deref(), unit, "{key}");
        }
    }
}
