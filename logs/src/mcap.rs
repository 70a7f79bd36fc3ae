//! A run as an [MCAP](https://mcap.dev) file: JSON messages described by JSON Schemas.
//!
//! # Why JSON with `jsonschema` schemas
//!
//! - Foxglove decodes `json` messages with `jsonschema` schemas natively: it lists the fields of
//!   every topic and plots any of them against time without a plugin.
//! - The Python `mcap` package (and the C++, Go, Rust and TypeScript readers) reads them with a
//!   JSON parser; no generated code, no `.proto` or `.msg` files to ship.
//! - Rerun imports only ROS 2 and Foxglove-protobuf MCAP channels (JSON channels stay opaque
//!   blobs there), so for Rerun the run is written natively as an `.rrd` by
//!   [`write_rrd`](super::rerun::write_rrd) instead.
//!
//! The price is size (about 20–30 bytes per value before compression) and decimal text; for
//! bulk numeric work the Rerun or CSV outputs are the better fit. Chunks are **zstd-compressed**
//! (level 1, on one thread, so that a run gives the same bytes every time), which every MCAP
//! reader supports: the built-in ball-bar run takes 39 MB instead of 156 MB.
//!
//! # Clock
//!
//! `log_time` and `publish_time` of every message are the **simulation time** of its sample in
//! nanoseconds from the start of the job (`round(t_s · 1e9)`), never the wall clock. A file is a
//! pure function of the run: the same run gives a byte-identical file, whether it is written
//! from the finished run ([`write_mcap`]) or block by block while the job runs ([`McapFile`]).
//! The streams' and ball-bar traces' messages are written in the order of their log time (ties:
//! the streams in run order, then the traces in run order). The laser readings (relative to a
//! datum read at the end of the test) and the ground truth (at log time 0) are known only when
//! the job ends and follow them; readers that use the file's chunk index (Foxglove, the Python
//! reader's `iter_messages()`) give every topic in log-time order.
//!
//! # Topics
//!
//! | topic | schema (`jsonschema`) | messages | fields (unit) |
//! |---|---|---|---|
//! | `/ground_truth` | `vmt.GroundTruth` | one, at log time 0 (written last) | the run's ground-truth object as it is; its schema lists its fields |
//! | `/<stream>`, e.g. `/servo` | `vmt.stream.<stream>` | one per sample of the stream | `time_s` (s) and one number per channel, named as the channel, in the channel's unit |
//! | `/ballbar/<trace>` | `vmt.ballbar.Sample` | one per sample of the trace | `time_s` (s), `angle_deg` (deg, unwrapped, from the plane's first axis), `deviation_um` (µm, measured minus nominal bar length) |
//! | `/laser` | `vmt.laser.Reading` | one per laser reading of an ISO 230-2 test, at the end of its averaging window | `time_s` (s), `target` (i, 1-based), `target_mm` (P_i, mm), `direction` (`forward`, `backward`), `run` (j, 1-based), `reading_mm` (P_ij, mm), `deviation_um` (x_ij = P_ij − P_i, µm) |
//!
//! `<stream>` and `<trace>` are the stream name and the trace label made into lower-case names of
//! ASCII letters, digits and `_` (`XY 150 mm 1000 mm/min CCW` -> `xy_150_mm_1000_mm_min_ccw`; a
//! repeated label gets `_2`, `_3`, ...). The `/servo` stream has, for each axis `a` in `x`, `y`,
//! `z`: `command_a`, `position_a`, `encoder_a`, `following_error_a` (m), `motor_force_a` (N),
//! `motor_current_a` (A), `guide_friction_a`, `screw_friction_a` (N), and `tool_x`, `tool_y`,
//! `tool_z` (m); see `vmt_sim::run`. The unit of each field is in its schema `description` and in
//! the channel metadata `units` (a JSON object field -> unit). A value that is not finite (which
//! the simulator never produces) is written as `null`.
//!
//! Channel metadata: streams carry `description` and `units`; ball-bar channels carry `label`,
//! `plane` (`XY`, `ZX`, `YZ`), `direction` (`cw`, `ccw`), `radius_mm` and `feed_mm_min`; the
//! laser channel carries `axis`, `targets_mm` (JSON list), `runs` and `line_mm` (JSON, the
//! beam line's coordinates, the axis' own entry 0).
//!
//! # Metadata records
//!
//! | name | keys |
//! |---|---|
//! | `run` | `format` (`vmt-mcap/1`), `scenario_name`, `seed`, `fidelity` (`reduced` or `multibody`), `clock` |
//! | `machine` | `name`, `topology` (e.g. `WXYGZT`), `strokes_m` (JSON `[[min, max]; 3]`, m), `tool_length_m` (m) |
//! | `scenario` | `name`, `toml` (the scenario file that made the run) |
//! | `ground_truth` | `json` (the ground truth as compact JSON, as on `/ground_truth`) |

use super::{Partial, RunFile, check_stream, check_trace, time_ns, unique_slugs, write_whole};
use crate::error::FileError;
use ::mcap::records::{MessageHeader, Metadata};
use ::mcap::{Compression, WriteOptions, Writer};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use vmt_sim::run::{BallbarTrace, LaserRun, Run, Stream};

/// Name and version of the file layout, in the `run` metadata record.
pub const FORMAT: &str = "vmt-mcap/1";

/// The `library` string of the MCAP header: `vmt-tools`, the crate that wrote these files
/// before the writers had a crate of their own, so that a run's file keeps its bytes.
const LIBRARY: &str = concat!(
    "vmt-tools/",
    env!("CARGO_PKG_VERSION"),
    " ",
    "(mcap-rust/0.26)"
);

/// JSON Schema dialect of every schema.
const DIALECT: &str = "https://json-schema.org/draft/2020-12/schema";

type McapWriter = Writer<BufWriter<File>>;

/// Writes `run` to the MCAP file `path` (written as `<path>.partial`
/// and renamed when complete): the topics and metadata listed in
/// the [module documentation](self), log and publish times in simulation nanoseconds.
///
/// Fails when a stream or trace is inconsistent (a channel with more or fewer values than sample
/// times), when a sample time is negative or not finite, or when the file cannot be written.
/// The file is the one [`McapFile`] writes block by block while the job runs, byte for byte.
pub fn write_mcap(run: &Run, path: &Path) -> Result<(), FileError> {
    write_whole::<McapFile>(run, path)
}

/// An MCAP file of a run written while its job runs: the streams' and traces' channels and
/// the metadata that identify the run (`run`, `machine`, `scenario`) when it is created, their
/// messages block by block, the laser readings and the ground truth (message and metadata) at
/// the end. Written as `<path>.partial` and renamed when finished; removed if
/// dropped unfinished (an error), left as it is if the process is killed, when the chunks
/// written so far are readable (`mcap recover`).
pub struct McapFile {
    // Declared before `partial`: dropped (and so closed) before the partial file is removed.
    writer: McapWriter,
    partial: Partial,
    streams: Vec<u16>,
    ballbar: Vec<u16>,
    sequence: BTreeMap<u16, u32>,
    data: Vec<u8>,
}

impl RunFile for McapFile {
    /// Creates the file and adds the channels of the streams and traces of `opening`.
    fn create(path: &Path, opening: &Run) -> Result<Self, FileError> {
        let partial = Partial::new(path);
        let err = |e: ::mcap::McapError| FileError::output(path, e);
        let file = File::create(partial.path()).map_err(|e| FileError::output(path, e))?;
        let mut writer = WriteOptions::new()
            .compression(Some(Compression::Zstd))
            // One thread: zstd's multithreaded frames differ from single-threaded ones, and a
            // dataset already runs one job per core. Level 1: level 3 took longer and was no
            // smaller on our decimal text.
            .compression_threads(0)
            .compression_level(1)
            .profile("")
            .library(LIBRARY)
            .create(BufWriter::new(file))
            .map_err(err)?;
        let (streams, ballbar) = add_channels(&mut writer, opening).map_err(err)?;
        // What identifies the run goes first, so that a file cut short by a killed job still
        // names its scenario, seed and machine.
        write_identity(&mut writer, opening).map_err(err)?;
        Ok(Self {
            writer,
            partial,
            streams,
            ballbar,
            sequence: BTreeMap::new(),
            data: Vec::with_capacity(4096),
        })
    }

    /// Writes the messages of the block merged in time order.
    fn block(&mut self, streams: &[Stream], traces: &[BallbarTrace]) -> Result<(), FileError> {
        let path = self.partial.target().to_path_buf();
        let path = path.as_path();
        streams.iter().try_for_each(|s| check_stream(s, path))?;
        traces.iter().try_for_each(|t| check_trace(t, path))?;
        // Messages written so far on a channel: the index in its stream of a block's first row.
        let written = |ids: &[u16]| -> Vec<usize> {
            ids.iter()
                .map(|id| self.sequence.get(id).map_or(0, |&n| n as usize))
                .collect()
        };
        let first = [written(&self.streams), written(&self.ballbar)];
        let stream_rows: Vec<RowFormat> = streams
            .iter()
            .map(|s| RowFormat::new(s.channels.iter().map(|c| c.name.as_str())))
            .collect();
        let trace_rows = RowFormat::new(["angle_deg", "deviation_um"].into_iter());
        for (time, source) in message_order(streams, traces, &first, path)? {
            let channel_id = match source {
                Source::Stream(k, i) => {
                    let s = &streams[k];
                    let values = s.channels.iter().map(|c| c.values[i]);
                    stream_rows[k].write(&mut self.data, s.times_s[i], values);
                    self.streams[k]
                }
                Source::Ballbar(k, i) => {
                    let t = &traces[k];
                    let values = [t.angle_deg[i], t.deviation_um[i]].into_iter();
                    trace_rows.write(&mut self.data, t.times_s[i], values);
                    self.ballbar[k]
                }
            };
            self.message(channel_id, time)?;
        }
        Ok(())
    }

    /// Writes the laser readings and the ground truth of the finished `run` and the metadata
    /// records and completes the file.
    fn complete(mut self, run: &Run) -> Result<Partial, FileError> {
        let path = self.partial.target().to_path_buf();
        let err = |e: ::mcap::McapError| FileError::output(&path, e);
        if let Some(l) = &run.laser {
            let id = self
                .writer
                .add_schema("vmt.laser.Reading", "jsonschema", &pretty(&laser_schema()))
                .map_err(err)?;
            let channel = self
                .writer
                .add_channel(id, "/laser", "json", &laser_metadata(l))
                .map_err(err)?;
            for (i, r) in l.readings.iter().enumerate() {
                let time = time_ns(r.time_s, &|| format!("laser reading {i}"), &path)?;
                serde_json::to_writer(&mut self.data, r)
                    .map_err(|e| FileError::output(&path, e))?;
                self.message(channel, time)?;
            }
        }
        let schema = pretty(&ground_truth_schema(&run.ground_truth));
        let id = self
            .writer
            .add_schema("vmt.GroundTruth", "jsonschema", &schema)
            .map_err(err)?;
        let meta = BTreeMap::from([(
            "description".to_string(),
            "every injected parameter and derived figure of the run".to_string(),
        )]);
        let channel = self
            .writer
            .add_channel(id, "/ground_truth", "json", &meta)
            .map_err(err)?;
        serde_json::to_writer(&mut self.data, &run.ground_truth)
            .map_err(|e| FileError::output(&path, e))?;
        self.message(channel, 0)?;
        let truth = metadata("ground_truth", vec![("json", run.ground_truth.to_string())]);
        self.writer.write_metadata(&truth).map_err(err)?;
        self.writer.finish().map_err(err)?;
        let Self {
            writer, partial, ..
        } = self;
        writer
            .into_inner()
            .into_inner()
            .map_err(|e| FileError::output(&path, e.error()))?;
        Ok(partial)
    }
}

impl McapFile {
    /// Writes the message in the data buffer on `channel_id` at `time` (ns) and empties it.
    fn message(&mut self, channel_id: u16, time: u64) -> Result<(), FileError> {
        let seq = self.sequence.entry(channel_id).or_insert(0);
        let header = MessageHeader {
            channel_id,
            sequence: *seq,
            log_time: time,
            publish_time: time,
        };
        *seq = seq.wrapping_add(1);
        self.writer
            .write_to_known_channel(&header, &self.data)
            .map_err(|e| FileError::output(self.partial.target(), e))?;
        self.data.clear();
        Ok(())
    }
}

/// Unique topic names for `names` under `prefix`: `/servo`, `/ballbar/xy_150_mm_ccw`, ...
fn topics<'a>(prefix: &str, names: impl Iterator<Item = &'a str>) -> Vec<String> {
    unique_slugs(names)
        .into_iter()
        .map(|n| format!("{prefix}/{n}"))
        .collect()
}

/// Adds the channels of `run`'s streams and ball-bar traces: their ids, in run order.
fn add_channels(w: &mut McapWriter, run: &Run) -> Result<(Vec<u16>, Vec<u16>), ::mcap::McapError> {
    let stream_topics = topics("", run.streams.iter().map(|s| s.name.as_str()));
    let mut streams = Vec::with_capacity(run.streams.len());
    for (stream, topic) in run.streams.iter().zip(&stream_topics) {
        let name = format!("vmt.stream.{}", &topic[1..]);
        let id = w.add_schema(&name, "jsonschema", &pretty(&stream_schema(stream)))?;
        streams.push(w.add_channel(id, topic, "json", &stream_metadata(stream))?);
    }
    if run.ballbar.is_empty() {
        // No schema without a channel of it (a milling or laser run had listed one).
        return Ok((streams, Vec::new()));
    }
    let id = w.add_schema(
        "vmt.ballbar.Sample",
        "jsonschema",
        &pretty(&ballbar_schema()),
    )?;
    let trace_topics = topics("/ballbar", run.ballbar.iter().map(|t| t.label.as_str()));
    let mut ballbar = Vec::with_capacity(run.ballbar.len());
    for (trace, topic) in run.ballbar.iter().zip(&trace_topics) {
        ballbar.push(w.add_channel(id, topic, "json", &trace_metadata(trace))?);
    }
    Ok((streams, ballbar))
}

fn pretty(v: &Value) -> Vec<u8> {
    // Serialising a `Value` cannot fail (its map keys are strings).
    serde_json::to_vec_pretty(v).unwrap_or_default()
}

fn number(description: String) -> Value {
    json!({ "type": "number", "description": description })
}

fn stream_schema(stream: &Stream) -> Value {
    let mut props = serde_json::Map::new();
    props.insert(
        "time_s".into(),
        number("simulation time from the start of the job, s".into()),
    );
    for c in &stream.channels {
        props.insert(c.name.clone(), number(format!("{}, {}", c.name, c.unit)));
    }
    let required: Vec<&str> = std::iter::once("time_s")
        .chain(stream.channels.iter().map(|c| c.name.as_str()))
        .collect();
    json!({
        "$schema": DIALECT,
        "title": format!("vmt stream {}", stream.name),
        "description": stream.description,
        "type": "object",
        "properties": props,
        "required": required,
    })
}

fn stream_metadata(stream: &Stream) -> BTreeMap<String, String> {
    let units: serde_json::Map<String, Value> = std::iter::once(("time_s".into(), json!("s")))
        .chain(
            stream
                .channels
                .iter()
                .map(|c| (c.name.clone(), json!(c.unit))),
        )
        .collect();
    BTreeMap::from([
        ("description".into(), stream.description.clone()),
        ("units".into(), Value::Object(units).to_string()),
    ])
}

fn ballbar_schema() -> Value {
    json!({
        "$schema": DIALECT,
        "title": "vmt ball-bar sample",
        "description": "one sample of a ball-bar trace (one direction of one circular test)",
        "type": "object",
        "properties": {
            "time_s": number("simulation time from the start of the job, s".into()),
            "angle_deg": number(
                "angle of the bar in its plane from the plane's first axis, deg (unwrapped, \
                 increasing for CCW)".into()),
            "deviation_um": number("measured minus nominal bar length, µm".into()),
        },
        "required": ["time_s", "angle_deg", "deviation_um"],
    })
}

fn laser_schema() -> Value {
    let integer = |d: &str| json!({ "type": "integer", "description": d });
    json!({
        "$schema": DIALECT,
        "title": "vmt laser reading",
        "description": "one averaged laser interferometer reading of an ISO 230-2 positioning test",
        "type": "object",
        "properties": {
            "time_s": number("end of the averaging window, simulation time, s".into()),
            "target": integer("target index i, 1-based"),
            "target_mm": number("target position P_i, mm".into()),
            "direction": {
                "type": "string",
                "enum": ["forward", "backward"],
                "description": "direction of approach (ISO 230-2 up / down)",
            },
            "run": integer("run j, 1-based"),
            "reading_mm": number("laser reading P_ij, mm".into()),
            "deviation_um": number("deviation x_ij = P_ij - P_i, µm".into()),
        },
        "required": ["time_s", "target", "target_mm", "direction", "run", "reading_mm", "deviation_um"],
    })
}

fn laser_metadata(l: &LaserRun) -> BTreeMap<String, String> {
    BTreeMap::from([
        ("axis".into(), l.axis.clone()),
        ("targets_mm".into(), json!(l.targets_mm).to_string()),
        ("runs".into(), l.runs.to_string()),
        ("line_mm".into(), json!(l.line_mm).to_string()),
    ])
}

fn trace_metadata(t: &BallbarTrace) -> BTreeMap<String, String> {
    BTreeMap::from([
        ("label".into(), t.label.clone()),
        ("plane".into(), t.plane.clone()),
        ("direction".into(), t.direction.clone()),
        ("radius_mm".into(), json!(t.radius_mm).to_string()),
        ("feed_mm_min".into(), json!(t.feed_mm_min).to_string()),
    ])
}

/// A JSON Schema describing `v` (its fields, recursively), so that viewers list the fields.
fn ground_truth_schema(v: &Value) -> Value {
    let mut schema = infer_schema(v);
    if let Value::Object(m) = &mut schema {
        m.insert("$schema".into(), json!(DIALECT));
        m.insert("title".into(), json!("vmt ground truth"));
        m.insert(
            "description".into(),
            json!("every injected parameter and derived figure of the run; units in the names"),
        );
    }
    schema
}

/// The schema of one JSON value; `null` members are left out (viewers reject a `null` type).
fn infer_schema(v: &Value) -> Value {
    match v {
        Value::Object(m) => {
            let props: serde_json::Map<String, Value> = m
                .iter()
                .filter(|(_, x)| !x.is_null())
                .map(|(k, x)| (k.clone(), infer_schema(x)))
                .collect();
            json!({ "type": "object", "properties": props })
        }
        Value::Array(a) => {
            // Items are typed only when every item has the same schema: an open interval
            // `[0.012, null]` or a list of mixed values stays an untyped array, which its
            // messages then satisfy.
            let first = a.first().map(infer_schema);
            match first {
                Some(f) if !a[0].is_null() && a[1..].iter().all(|x| infer_schema(x) == f) => {
                    json!({ "type": "array", "items": f })
                }
                _ => json!({ "type": "array" }),
            }
        }
        Value::Number(n) if n.is_i64() || n.is_u64() => json!({ "type": "integer" }),
        Value::Number(_) => json!({ "type": "number" }),
        Value::String(_) => json!({ "type": "string" }),
        Value::Bool(_) => json!({ "type": "boolean" }),
        Value::Null => json!({}),
    }
}

/// Where a message comes from: sample `i` of stream `k` or sample `i` of trace `k`. The
/// derived order (time, source, index) is the order of the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Source {
    Stream(usize, usize),
    Ballbar(usize, usize),
}

/// Every message of `streams` and `traces` as (log time ns, source), sorted by time then
/// source. `first` holds, for the streams and for the traces, the index of each one's first
/// sample here in the whole run (for errors).
fn message_order(
    streams: &[Stream],
    traces: &[BallbarTrace],
    first: &[Vec<usize>; 2],
    path: &Path,
) -> Result<Vec<(u64, Source)>, FileError> {
    let total = streams.iter().map(|s| s.times_s.len()).sum::<usize>()
        + traces.iter().map(|t| t.times_s.len()).sum::<usize>();
    let mut events = Vec::with_capacity(total);
    for (k, s) in streams.iter().enumerate() {
        for (i, &t) in s.times_s.iter().enumerate() {
            let what = || format!("stream `{}`, sample {}", s.name, first[0][k] + i);
            events.push((time_ns(t, &what, path)?, Source::Stream(k, i)));
        }
    }
    for (k, tr) in traces.iter().enumerate() {
        for (i, &t) in tr.times_s.iter().enumerate() {
            let what = || format!("ball-bar trace `{}`, sample {}", tr.label, first[1][k] + i);
            events.push((time_ns(t, &what, path)?, Source::Ballbar(k, i)));
        }
    }
    events.sort_unstable();
    Ok(events)
}

/// One sample as a JSON object, `time_s` then one number per field, byte for byte what
/// serde_json writes for the map of them in that order: each key encoded (and escaped) once,
/// each number by serde_json's own formatter, a value that is not finite as `null` (serde_json's
/// rule for floats). A million servo rows of 27 fields spend much of their writing here.
struct RowFormat {
    /// `{"time_s":`, then `,"<field>":` for each field.
    keys: Vec<Vec<u8>>,
}

impl RowFormat {
    fn new<'a>(fields: impl Iterator<Item = &'a str>) -> Self {
        let key = |prefix: &[u8], name: &str| {
            let mut k = prefix.to_vec();
            // Writing a string into a Vec cannot fail.
            let _ = serde_json::to_writer(&mut k, name);
            k.push(b':');
            k
        };
        let keys = std::iter::once(key(b"{", "time_s"))
            .chain(fields.map(|f| key(b",", f)))
            .collect();
        Self { keys }
    }

    /// Appends the row to `out`; `values` has one value per field.
    fn write(&self, out: &mut Vec<u8>, time_s: f64, values: impl Iterator<Item = f64>) {
        for (key, v) in self.keys.iter().zip(std::iter::once(time_s).chain(values)) {
            out.extend_from_slice(key);
            if v.is_finite() {
                // Writing into a Vec cannot fail.
                let _ = serde_json::ser::Formatter::write_f64(
                    &mut serde_json::ser::CompactFormatter,
                    out,
                    v,
                );
            } else {
                out.extend_from_slice(b"null");
            }
        }
        out.push(b'}');
    }
}

fn metadata(name: &str, pairs: Vec<(&str, String)>) -> Metadata {
    Metadata {
        name: name.to_string(),
        metadata: pairs.into_iter().map(|(k, v)| (k.to_string(), v)).collect(),
    }
}

/// The metadata records `run`, `machine` and `scenario`, known when the job starts.
fn write_identity(w: &mut McapWriter, run: &Run) -> Result<(), ::mcap::McapError> {
    let m = &run.machine;
    let records = [
        metadata(
            "run",
            vec![
                ("format", FORMAT.to_string()),
                ("scenario_name", run.scenario_name.clone()),
                ("seed", run.seed.to_string()),
                ("fidelity", run.fidelity.clone()),
                (
                    "clock",
                    "log_time = publish_time = simulation time in ns from the start of the job"
                        .to_string(),
                ),
            ],
        ),
        metadata(
            "machine",
            vec![
                ("name", m.name.clone()),
                ("topology", m.topology.clone()),
                ("strokes_m", json!(m.strokes_m).to_string()),
                ("tool_length_m", json!(m.tool_length_m).to_string()),
            ],
        ),
        metadata(
            "scenario",
            vec![
                ("name", run.scenario_name.clone()),
                ("toml", run.scenario_toml.clone()),
            ],
        ),
    ];
    records.iter().try_for_each(|r| w.write_metadata(r))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schema_of_ground_truth_lists_fields() {
        let v = json!({"backlash_um": {"x": 2.0}, "seed": 3, "note": null, "list": [1.5]});
        let s = ground_truth_schema(&v);
        assert_eq!(
            s["properties"]["backlash_um"]["properties"]["x"]["type"],
            "number"
        );
        assert_eq!(s["properties"]["seed"]["type"], "integer");
        assert!(s["properties"].get("note").is_none());
        assert_eq!(s["properties"]["list"]["items"]["type"], "number");
        // A milling run's chatter interval still open at the end: `[[0.012, null]]` had been
        // declared an array of arrays of numbers, which its own message failed.
        let open = infer_schema(&json!({"intervals": [[0.012, null]], "mixed": [1.5, "a"]}));
        assert_eq!(
            open["properties"]["intervals"]["items"],
            json!({ "type": "array" })
        );
        assert_eq!(open["properties"]["mixed"], json!({ "type": "array" }));
    }

    /// A row is what serde_json writes for the same map, for numbers of every kind, and a
    /// value that is not finite is `null`.
    #[test]
    fn rows_are_serde_json_s_maps_byte_for_byte() {
        let values = [
            1.0,
            -0.0,
            0.1,
            -2.5e-7,
            1e-300,
            5e-324,
            1.7976931348623157e308,
            123456789.0,
            1e16,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        let names: Vec<String> = (0..values.len()).map(|i| format!("f{i}")).collect();
        let format = RowFormat::new(names.iter().map(String::as_str).chain(["q\"u"]));
        let mut out = Vec::new();
        format.write(&mut out, 0.5, values.iter().copied().chain([3.0]));
        let mut expected = String::from(r#"{"time_s":0.5"#);
        for (n, v) in names.iter().zip(values) {
            let number = serde_json::to_string(&v).unwrap_or_default();
            expected.push_str(&format!(r#","{n}":{number}"#));
        }
        expected.push_str(r#","q\"u":3.0}"#);
        assert_eq!(String::from_utf8_lossy(&out), expected);
        assert!(expected.contains(r#""f9":null,"f10":null,"f11":null"#));
    }

    #[test]
    fn topic_names_are_unique() {
        let t = topics("/ballbar", ["XY 150 CW", "xy 150 cw", "YZ"].into_iter());
        assert_eq!(
            t,
            ["/ballbar/xy_150_cw", "/ballbar/xy_150_cw_2", "/ballbar/yz"]
        );
    }
}
