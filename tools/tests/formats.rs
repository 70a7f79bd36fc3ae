//! The run writers: MCAP read back with the Python `mcap` package, `.rrd` read back with the
//! Python `rerun-sdk` 0.36.3, byte-identical MCAP for the same run, and the ball-bar polar plot.
//!
//! The Python tests need `python3 -m pip install -r tools/tests/requirements.txt`; without the
//! packages they fail and say so.

#[path = "common/mcap_records.rs"]
mod mcap_records;
#[path = "common/python.rs"]
mod python;

use mcap_records::records;
use python::python;
use serde_json::{Value, json};
use std::f64::consts::PI;
use vmt_logs::{write_mcap, write_rrd};
use vmt_sim::run::{BallbarTrace, Channel, MachineSummary, Run, Stream};
use vmt_tools::plot::{Format, POLAR_SIZE, draw_polar};

/// Log rate of the servo stream, Hz.
const RATE_HZ: f64 = 1000.0;
/// Ball-bar length, mm.
const RADIUS_MM: f64 = 150.0;
/// Feed of the test circles, mm/min.
const FEED_MM_MIN: f64 = 6000.0;
/// Centre of the circle relative to the workpiece, m.
const CENTRE_M: [f64; 3] = [0.25, 0.2, 0.15];

/// The deviation of the test pattern at angle `theta` (rad) in direction `dir` (+1 CCW, -1 CW),
/// µm: eccentricity, squareness (same for both directions), servo mismatch (flips) and backlash
/// in X (a half-circle step).
fn deviation_um(theta: f64, dir: f64) -> f64 {
    let eccentricity = 2.0 * theta.cos() - 1.0 * theta.sin();
    let squareness = 3.0 * (2.0 * theta).sin();
    let mismatch = dir * 1.5 * (2.0 * theta).sin();
    let backlash = 1.0 * theta.sin().signum() * dir * 0.5;
    eccentricity + squareness + mismatch + backlash
}

/// One circle per direction, CCW then CW, one sample per servo period: (time s, angle deg
/// unwrapped, direction).
fn circle_samples() -> Vec<(f64, f64, f64)> {
    let period_s = 2.0 * PI * RADIUS_MM / (FEED_MM_MIN / 60.0);
    let n = (period_s * RATE_HZ).round() as usize;
    let mut out = Vec::with_capacity(2 * n);
    for (k, dir) in [1.0, -1.0].into_iter().enumerate() {
        for i in 0..n {
            let t = (k * n + i) as f64 / RATE_HZ;
            out.push((t, dir * 360.0 * i as f64 / n as f64, dir));
        }
    }
    out
}

fn channel(name: &str, unit: &str, values: Vec<f64>) -> Channel {
    Channel {
        name: name.into(),
        unit: unit.into(),
        values,
    }
}

/// The `servo` stream of the two circles, with every channel documented in `vmt_sim::run`.
fn servo_stream(samples: &[(f64, f64, f64)]) -> Stream {
    let r_m = RADIUS_MM * 1e-3;
    let speed = FEED_MM_MIN / 60.0 * 1e-3;
    let mut channels = Vec::new();
    let mut tool: [Vec<f64>; 3] = Default::default();
    for (k, a) in ["x", "y", "z"].into_iter().enumerate() {
        let mut cols: [Vec<f64>; 8] = Default::default();
        for &(_, deg, dir) in samples {
            let th = deg.to_radians();
            let (unit_pos, unit_vel) = match k {
                0 => (th.cos(), -th.sin() * dir),
                1 => (th.sin(), th.cos() * dir),
                _ => (0.0, 0.0),
            };
            let command = CENTRE_M[k] + r_m * unit_pos;
            let fe = unit_vel * speed / 30.0; // Kv = 30 1/s
            let position = command - fe;
            let radial = deviation_um(th, dir) * 1e-6 * unit_pos;
            let v = unit_vel * speed;
            let values = [
                command,
                position,
                (position / 1e-7).round() * 1e-7,
                fe,
                200.0 * v.signum() + 5000.0 * fe,
                0.05 * (200.0 * v.signum() + 5000.0 * fe),
                40.0 * v.signum(),
                25.0 * v.signum() + 100.0 * v,
            ];
            for (col, value) in cols.iter_mut().zip(values) {
                col.push(value);
            }
            tool[k].push(position + radial);
        }
        let names = [
            ("command", "m"),
            ("position", "m"),
            ("encoder", "m"),
            ("following_error", "m"),
            ("motor_force", "N"),
            ("motor_current", "A"),
            ("guide_friction", "N"),
            ("screw_friction", "N"),
        ];
        for ((name, unit), values) in names.into_iter().zip(cols) {
            channels.push(channel(&format!("{name}_{a}"), unit, values));
        }
    }
    for (a, values) in ["x", "y", "z"].into_iter().zip(tool) {
        channels.push(channel(&format!("tool_{a}"), "m", values));
    }
    Stream {
        name: "servo".into(),
        description: "servo loop signals at the log rate".into(),
        times_s: samples.iter().map(|s| s.0).collect(),
        channels,
    }
}

fn traces(samples: &[(f64, f64, f64)]) -> Vec<BallbarTrace> {
    [(1.0, "ccw"), (-1.0, "cw")]
        .into_iter()
        .map(|(dir, name)| {
            let mine: Vec<&(f64, f64, f64)> = samples.iter().filter(|s| s.2 == dir).collect();
            BallbarTrace {
                label: format!(
                    "XY {RADIUS_MM} mm {FEED_MM_MIN} mm/min {}",
                    name.to_uppercase()
                ),
                plane: "XY".into(),
                direction: name.into(),
                radius_mm: RADIUS_MM,
                feed_mm_min: FEED_MM_MIN,
                times_s: mine.iter().map(|s| s.0).collect(),
                angle_deg: mine.iter().map(|s| s.1).collect(),
                deviation_um: mine
                    .iter()
                    .map(|s| deviation_um(s.1.to_radians(), dir))
                    .collect(),
            }
        })
        .collect()
}

/// A run of two 150 mm ball-bar circles (CCW, CW) at 6000 mm/min logged at 1 kHz.
fn test_run() -> Run {
    let samples = circle_samples();
    Run {
        scenario_name: "vmc500 ball bar".into(),
        scenario_toml: "[machine]\nname = \"vmc500\"\ntopology = \"WXYGZT\"\n".into(),
        seed: 42,
        fidelity: "reduced".into(),
        machine: MachineSummary {
            name: "vmc500".into(),
            topology: "WXYGZT".into(),
            strokes_m: [[0.0, 0.5], [0.0, 0.4], [0.0, 0.4]],
            tool_length_m: 0.1,
        },
        streams: vec![servo_stream(&samples)],
        ballbar: traces(&samples),
        laser: None,
        ground_truth: json!({
            "squareness_xy_urad": 40.0,
            "backlash_um": {"x": 1.0, "y": 0.0},
            "servo_mismatch_ms": 0.54,
            "eccentricity_um": [2.0, -1.0],
            // An interval open at the end (a milling run's chatter) and a list of an integer
            // and a fraction: their schemas must hold them.
            "chatter_intervals_s": [[0.012, null]],
            "counts": [1, 1.5],
        }),
    }
}

fn ns(t_s: f64) -> u64 {
    (t_s * 1e9).round() as u64
}

/// The metadata that identify a run come before its first chunk of messages, so that a file cut short by
/// a killed job still names its scenario, seed and machine; the ground truth comes last.
#[test]
fn an_mcap_names_its_run_before_its_first_chunk() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("run.mcap");
    write_mcap(&test_run(), &path).expect("write mcap");
    let r: Vec<(u8, String)> = records(&std::fs::read(&path).unwrap())
        .into_iter()
        .map(|r| (r.opcode, r.name))
        .collect();
    // A chunk of messages is followed by its message indexes (the first chunk holds only the
    // schemas and channels).
    let index = |op: &u8| *op == 0x07;
    let first_messages = r.iter().position(|(op, _)| index(op)).expect("messages");
    let last_messages = r.iter().rposition(|(op, _)| index(op)).unwrap();
    let at = |name: &str| r.iter().position(|(op, n)| *op == 0x0C && n == name);
    for name in ["run", "machine", "scenario"] {
        assert!(at(name).expect(name) < first_messages, "{name}: {r:?}");
    }
    assert!(
        at("ground_truth").expect("ground_truth") > last_messages,
        "{r:?}"
    );
}

#[test]
fn mcap_reads_back_with_python_mcap() {
    let run = test_run();
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("run.mcap");
    write_mcap(&run, &path).expect("write mcap");
    let s = python("read_mcap.py", &path);

    let servo = &run.streams[0];
    let n = servo.times_s.len() as u64;
    let ccw = "/ballbar/xy_150_mm_6000_mm_min_ccw";
    let cw = "/ballbar/xy_150_mm_6000_mm_min_cw";
    let topics = s["topics"].as_object().expect("topics");
    let mut names: Vec<&str> = topics.keys().map(String::as_str).collect();
    names.sort_unstable();
    assert_eq!(names, [ccw, cw, "/ground_truth", "/servo"]);
    assert_eq!(
        s["schema_errors"],
        json!([]),
        "messages against their schemas"
    );
    assert_eq!(s["topics"]["/servo"]["count"], n);
    assert_eq!(s["topics"]["/servo"]["statistics_count"], n);
    assert_eq!(s["topics"][ccw]["count"], run.ballbar[0].times_s.len());
    assert_eq!(s["topics"][cw]["count"], run.ballbar[1].times_s.len());
    assert_eq!(s["topics"]["/ground_truth"]["count"], 1);
    for t in names {
        assert_eq!(s["topics"][t]["schema_encoding"], "jsonschema", "{t}");
        assert_eq!(s["topics"][t]["message_encoding"], "json", "{t}");
    }
    assert_eq!(s["topics"]["/servo"]["schema_name"], "vmt.stream.servo");
    let props = &s["topics"]["/servo"]["schema"]["properties"];
    assert_eq!(props.as_object().map(|p| p.len()), Some(27 + 1));
    assert_eq!(props["following_error_x"]["type"], "number");

    // The first servo message has every channel's first value, the last every channel's last
    // value, and each field summed over the messages in Python equals the sum of the channel
    // here. Equal exactly: serde_json writes the shortest decimal that reads back as the same
    // double, Python's float() and serde_json's float_roundtrip parse it correctly rounded, and
    // both sides add the same doubles one by one in sample order (the file is in time order).
    let first = &s["topics"]["/servo"]["first"];
    let last = &s["topics"]["/servo"]["last"];
    let sums = &s["topics"]["/servo"]["sums"];
    let mut fields: Vec<(&str, &[f64])> = vec![("time_s", &servo.times_s)];
    fields.extend(
        servo
            .channels
            .iter()
            .map(|c| (c.name.as_str(), c.values.as_slice())),
    );
    assert_eq!(sums.as_object().map(|m| m.len()), Some(fields.len()));
    for (name, values) in fields {
        assert_eq!(first[name].as_f64(), Some(values[0]), "{name}");
        assert_eq!(last[name].as_f64(), values.last().copied(), "{name}");
        let sum: f64 = values.iter().sum();
        assert_eq!(sums[name].as_f64(), Some(sum), "{name}");
    }
    for (topic, trace) in [(ccw, &run.ballbar[0]), (cw, &run.ballbar[1])] {
        let t = &s["topics"][topic];
        for (name, values) in [
            ("time_s", &trace.times_s),
            ("angle_deg", &trace.angle_deg),
            ("deviation_um", &trace.deviation_um),
        ] {
            assert_eq!(t["first"][name].as_f64(), Some(values[0]), "{topic} {name}");
            assert_eq!(
                t["last"][name].as_f64(),
                values.last().copied(),
                "{topic} {name}"
            );
            let sum: f64 = values.iter().sum();
            assert_eq!(t["sums"][name].as_f64(), Some(sum), "{topic} {name}");
        }
    }
    let units: Value = serde_json::from_str(
        s["topics"]["/servo"]["metadata"]["units"]
            .as_str()
            .expect("units"),
    )
    .expect("units JSON");
    assert_eq!(units["motor_current_x"], "A");
    assert_eq!(s["topics"][ccw]["metadata"]["direction"], "ccw");
    assert_eq!(
        s["topics"][ccw]["first"]["deviation_um"].as_f64(),
        Some(run.ballbar[0].deviation_um[0])
    );

    // Clock: simulation time in ns, the streams' and traces' messages in time order, then the
    // ground truth (known when the job ends); chunks zstd-compressed.
    assert_eq!(s["first_log_time_ns"], 0);
    assert_eq!(
        s["last_log_time_ns"],
        ns(*servo.times_s.last().expect("times"))
    );
    assert_eq!(s["statistics"]["message_end_time"], s["last_log_time_ns"]);
    assert_eq!(s["streams_in_time_order"], true);
    assert_eq!(s["topics_after_streams"], json!(["/ground_truth"]));
    assert_eq!(s["chunk_compressions"], json!(["zstd"]));

    // Metadata and ground truth.
    assert_eq!(
        s["metadata_names"],
        json!(["ground_truth", "machine", "run", "scenario"])
    );
    assert_eq!(s["metadata"]["run"]["seed"], "42");
    assert_eq!(s["metadata"]["run"]["fidelity"], "reduced");
    assert_eq!(s["metadata"]["machine"]["topology"], "WXYGZT");
    assert_eq!(s["metadata"]["scenario"]["toml"], run.scenario_toml);
    let truth: Value = serde_json::from_str(
        s["metadata"]["ground_truth"]["json"]
            .as_str()
            .expect("ground truth json"),
    )
    .expect("ground truth JSON");
    assert_eq!(truth, run.ground_truth);
    assert_eq!(s["ground_truth"]["squareness_xy_urad"].as_f64(), Some(40.0));
    assert_eq!(s["ground_truth"]["backlash_um"]["x"].as_f64(), Some(1.0));
    eprintln!(
        "mcap: {} bytes for {n} servo samples and {} ball-bar samples (python mcap {})",
        std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0),
        run.ballbar.iter().map(|t| t.times_s.len()).sum::<usize>(),
        s["mcap_version"]
    );
}

#[test]
fn mcap_is_byte_identical_for_the_same_run() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
    write_mcap(&test_run(), &a).expect("write a");
    write_mcap(&test_run().clone(), &b).expect("write b");
    let (a, b) = (std::fs::read(a).expect("a"), std::fs::read(b).expect("b"));
    assert!(a.len() > 1000);
    assert!(a == b, "two writes of the same run differ");
}

#[test]
fn writers_refuse_inconsistent_runs_without_panicking() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut run = test_run();
    run.streams[0].channels[2].values.pop(); // encoder_x
    let e = write_mcap(&run, &dir.path().join("x.mcap")).expect_err("short channel");
    assert!(e.to_string().contains("encoder_x"), "{e}");
    let e = write_rrd(&run, &dir.path().join("x.rrd")).expect_err("short channel");
    assert!(e.to_string().contains("encoder_x"), "{e}");

    let mut run = test_run();
    run.ballbar[0].times_s[5] = f64::NAN;
    let e = write_mcap(&run, &dir.path().join("y.mcap")).expect_err("NaN time");
    assert!(e.to_string().contains("sample 5"), "{e}");
    // Named as the file asked for, not the partial one it was being written as.
    assert!(
        e.to_string().contains("y.mcap") && !e.to_string().contains("partial"),
        "{e}"
    );
    let e = write_rrd(&run, &dir.path().join("y.rrd")).expect_err("NaN time");
    assert!(
        e.to_string().contains("y.rrd") && !e.to_string().contains("partial"),
        "{e}"
    );
    assert!(!dir.path().join("y.mcap.partial").exists());

    let mut run = test_run();
    run.machine.topology = "WXXGZT".into();
    let e = write_rrd(&run, &dir.path().join("z.rrd")).expect_err("bad topology");
    assert!(e.to_string().contains("WXXGZT"), "{e}");
}

/// The servo stream's rows `rows` alone, as a block of a run written while it runs.
fn rows_of(s: &Stream, rows: std::ops::Range<usize>) -> Stream {
    Stream {
        times_s: s.times_s[rows.clone()].to_vec(),
        channels: s
            .channels
            .iter()
            .map(|c| Channel {
                values: c.values[rows.clone()].to_vec(),
                ..c.clone()
            })
            .collect(),
        ..s.clone()
    }
}

/// Written block by block, a bad time is named by its row in the whole run, not in its block;
/// and the failed file is removed.
#[test]
fn files_written_in_blocks_name_a_bad_row_by_its_place_in_the_run() {
    use vmt_logs::{RunFile, mcap::McapFile, rerun::RrdFile};
    let dir = tempfile::tempdir().expect("temp dir");
    let mut run = test_run();
    run.streams[0].times_s[13] = f64::NAN;
    let servo = &run.streams[0];
    let blocks = [rows_of(servo, 0..10), rows_of(servo, 10..20)];
    let no_samples: Vec<BallbarTrace> = run.ballbar.iter().map(|t| t.samples(0..0)).collect();
    let path = dir.path().join("b.mcap");
    let mut mcap = McapFile::create(&path, &run).expect("create");
    mcap.block(std::slice::from_ref(&blocks[0]), &no_samples)
        .expect("first block");
    let e = mcap
        .block(std::slice::from_ref(&blocks[1]), &no_samples)
        .expect_err("a NaN time");
    assert!(e.to_string().contains("stream `servo`, sample 13"), "{e}");
    drop(mcap);
    let path = dir.path().join("b.rrd");
    let mut rrd = RrdFile::create(&path, &run).expect("create");
    rrd.block(std::slice::from_ref(&blocks[0]), &no_samples)
        .expect("first block");
    let e = rrd
        .block(std::slice::from_ref(&blocks[1]), &no_samples)
        .expect_err("a NaN time");
    assert!(e.to_string().contains("sample 13"), "{e}");
    drop(rrd);
    let left: Vec<_> = std::fs::read_dir(dir.path()).expect("dir").collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn files_appear_whole_or_not_at_all() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run = test_run();
    let names = |d: &std::path::Path| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .expect("read dir")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    // Written under `<name>.partial`, renamed when complete.
    write_mcap(&run, &dir.path().join("run.mcap")).expect("mcap");
    write_rrd(&run, &dir.path().join("run.rrd")).expect("rrd");
    assert_eq!(names(dir.path()), ["run.mcap", "run.rrd"]);

    // A write that fails at the end (the final name is taken by a folder) leaves the folder
    // as it was and no partial file behind.
    for name in ["busy.mcap", "busy.rrd"] {
        let busy = dir.path().join(name);
        std::fs::create_dir(&busy).expect("folder");
        let e = if name.ends_with("mcap") {
            write_mcap(&run, &busy)
        } else {
            write_rrd(&run, &busy)
        }
        .expect_err("a folder in the way");
        assert!(e.to_string().contains(name), "{e}");
        assert!(busy.is_dir());
    }
    assert_eq!(
        names(dir.path()),
        ["busy.mcap", "busy.rrd", "run.mcap", "run.rrd"]
    );
}

#[test]
fn rrd_reads_back_with_python_rerun() {
    let run = test_run();
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("run.rrd");
    write_rrd(&run, &path).expect("write rrd");
    let s = python("read_rrd.py", &path);
    assert_eq!(s["rerun_version"], "0.36.3");
    assert_eq!(s["recordings"].as_array().map(Vec::len), Some(1));
    assert_eq!(s["recordings"][0]["application_id"], "vmt");
    assert_eq!(s["blueprints"], 1);
    // Only simulation time: no wall-clock `log_time`, no `log_tick`.
    assert_eq!(s["timelines"], json!(["sim_time"]));

    let n = run.streams[0].times_s.len();
    let e = &s["entities"];
    for moving in [
        "/machine/y_axis",
        "/machine/y_axis/x_axis",
        "/machine/z_axis",
    ] {
        assert_eq!(e[moving]["rows"], n, "{moving}");
        assert!(
            e[moving]["components"]
                .as_array()
                .is_some_and(|c| c.contains(&json!("Transform3D:translation"))),
            "{moving}: {}",
            e[moving]
        );
        assert_eq!(e[moving]["static"], true, "{moving} has its box");
    }
    for fixed in [
        "/machine/base",
        "/machine/y_axis/x_axis/workpiece",
        "/machine/z_axis/tool",
    ] {
        assert!(
            e[fixed]["components"]
                .to_string()
                .contains("Boxes3D:half_sizes"),
            "{fixed}"
        );
    }
    assert!(
        e["/machine/y_axis/x_axis/workpiece/tool_path"]["components"]
            .to_string()
            .contains("LineStrips3D:strips")
    );
    for a in ["x", "y", "z"] {
        let fe = &e[format!("/series/following_error_um/{a}").as_str()];
        assert_eq!(fe["rows"], n, "following error {a}");
        for kind in ["guide", "screw"] {
            assert_eq!(
                e[format!("/series/friction_n/{kind}_{a}").as_str()]["rows"],
                n
            );
        }
    }
    let fe_x = &e["/series/following_error_um/x"];
    let fe = &run.streams[0]
        .channel("following_error_x")
        .expect("fe")
        .values;
    let (first, last) = (fe[0] * 1e6, fe[fe.len() - 1] * 1e6);
    assert!((fe_x["first_scalar"]["value"].as_f64().unwrap_or(f64::NAN) - first).abs() < 1e-9);
    assert!((fe_x["last_scalar"]["value"].as_f64().unwrap_or(f64::NAN) - last).abs() < 1e-9);
    assert_eq!(
        fe_x["last_scalar"]["time_ns"],
        ns(*run.streams[0].times_s.last().expect("times"))
    );
    for (t, slug) in run
        .ballbar
        .iter()
        .zip(["xy_150_mm_6000_mm_min_ccw", "xy_150_mm_6000_mm_min_cw"])
    {
        let series = &e[format!("/series/ballbar_deviation_um/{slug}").as_str()];
        assert_eq!(series["rows"], t.times_s.len(), "{slug}");
        let polar = &e[format!("/ballbar/xy_150_mm/{slug}").as_str()];
        assert!(
            polar["components"]
                .to_string()
                .contains("LineStrips2D:strips"),
            "{slug}"
        );
    }
    for info in [
        "/ballbar/xy_150_mm/nominal",
        "/ballbar/xy_150_mm/grid",
        "/info/run",
        "/info/ground_truth",
        "/info/scenario",
    ] {
        assert_eq!(e[info]["static"], true, "{info}");
    }
    eprintln!(
        "rrd: {} bytes for {n} servo samples and {} ball-bar samples",
        std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0),
        run.ballbar.iter().map(|t| t.times_s.len()).sum::<usize>()
    );
}

#[test]
fn polar_plot_png_is_written_with_its_size() {
    let run = test_run();
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("polar.png");
    let figures = "ISO 230-4 (XY, 150 mm, 6000 mm/min)\n\
                   circular deviation G  CCW  8.9 µm\n\
                   circular deviation G  CW   9.6 µm\n\
                   circular hysteresis H      3.1 µm";
    draw_polar(&run.ballbar, &path, Format::Png, Some(figures)).expect("draw");
    let bytes = std::fs::read(&path).expect("png");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    let be = |i: usize| u32::from_be_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    assert_eq!((be(16), be(20)), POLAR_SIZE);
    if let Ok(keep) = std::env::var("VMT_KEEP_PLOT") {
        let _ = std::fs::copy(&path, keep);
    }
    let svg = dir.path().join("polar.svg");
    draw_polar(&run.ballbar, &svg, Format::Svg, None).expect("svg");
    assert!(std::fs::read_to_string(&svg).is_ok_and(|s| s.contains("µm/div")));
    assert!(draw_polar(&[], &dir.path().join("none.png"), Format::Png, None).is_err());
}

/// The test run with an ISO 230-2 laser record: two targets, two runs, both directions.
fn laser_run() -> Run {
    use vmt_sim::run::{LaserReading, LaserRun};
    let mut run = test_run();
    let mut readings = Vec::new();
    let mut t = 0.5;
    for j in 1..=2 {
        for (dir, targets) in [("forward", [1, 2]), ("backward", [2, 1])] {
            for i in targets {
                let target_mm = 100.0 * i as f64;
                let deviation_um = 0.5 * i as f64 + if dir == "forward" { 0.0 } else { -2.0 };
                readings.push(LaserReading {
                    time_s: t,
                    target: i,
                    target_mm,
                    direction: dir.into(),
                    run: j,
                    reading_mm: target_mm + deviation_um * 1e-3,
                    deviation_um,
                });
                t += 1.0;
            }
        }
    }
    run.laser = Some(LaserRun {
        axis: "X".into(),
        targets_mm: vec![100.0, 200.0],
        runs: 2,
        line_mm: [0.0, 200.0, 200.0],
        readings,
    });
    run
}

#[test]
fn laser_readings_are_written_to_mcap_and_rrd() {
    let run = laser_run();
    let laser = run.laser.as_ref().expect("laser");
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("laser.mcap");
    write_mcap(&run, &path).expect("write mcap");
    let s = python("read_mcap.py", &path);
    assert_eq!(
        s["schema_errors"],
        json!([]),
        "messages against their schemas"
    );
    let topic = &s["topics"]["/laser"];
    assert_eq!(topic["schema_name"], "vmt.laser.Reading");
    assert_eq!(topic["count"], laser.readings.len());
    assert_eq!(topic["metadata"]["axis"], "X");
    let first = &topic["first"];
    assert_eq!(first["direction"], "forward");
    assert_eq!(first["target"], 1);
    assert_eq!(
        first["deviation_um"].as_f64(),
        Some(laser.readings[0].deviation_um)
    );
    assert_eq!(s["streams_in_time_order"], true);
    assert_eq!(
        s["topics_after_streams"],
        json!(["/laser", "/ground_truth"])
    );

    let rrd = dir.path().join("laser.rrd");
    write_rrd(&run, &rrd).expect("write rrd");
    let r = python("read_rrd.py", &rrd);
    for d in ["forward", "backward"] {
        let e = &r["entities"][format!("/series/laser_deviation_um/{d}").as_str()];
        assert_eq!(e["rows"], 4, "{d}");
    }
}

/// A compliant run's `structure` stream: the X table tilting about Y by a growing angle (0 to
/// 3 µrad) and sinking (0 to 2 µm), the other carriages still.
fn structure_stream(times_s: &[f64]) -> Stream {
    let n = times_s.len();
    let ramp = |to: f64| (0..n).map(|i| to * i as f64 / (n - 1) as f64).collect();
    let mut channels = Vec::new();
    for a in ["x", "y", "z"] {
        for (kind, unit) in [("tilt", "rad"), ("offset", "m")] {
            for c in ["x", "y", "z"] {
                let values = match (a, kind, c) {
                    ("x", "tilt", "y") => ramp(3e-6),
                    ("x", "offset", "z") => ramp(-2e-6),
                    _ => vec![0.0; n],
                };
                channels.push(Channel {
                    name: format!("{kind}_{a}_{c}"),
                    unit: unit.into(),
                    values,
                });
            }
        }
    }
    Stream {
        name: "structure".into(),
        description: "the carriages on their guide blocks".into(),
        times_s: times_s.to_vec(),
        channels,
    }
}

/// Rerun's own reader finds the magnified deflection of each carriage of a compliant run: the
/// copy of its box, and a transform per structure sample that turns it by 10 000 × the tilt
/// (the last X sample: 0.03 rad about +Y) and moves it by 10 000 × the offset (20 mm down over
/// the run).
#[test]
fn rrd_shows_the_carriages_tilt_and_offset_magnified() {
    let mut run = test_run();
    run.fidelity = "compliant".into();
    let times = run.streams[0].times_s.clone();
    run.streams.push(structure_stream(&times));
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("run.rrd");
    write_rrd(&run, &path).expect("write rrd");
    let s = python("read_rrd.py", &path);
    let e = &s["entities"];
    for carriage in [
        "/machine/y_axis",
        "/machine/y_axis/x_axis",
        "/machine/z_axis",
    ] {
        let d = &e[format!("{carriage}/deflection_x10000").as_str()];
        assert_eq!(d["rows"], times.len(), "{carriage}: {d}");
        assert_eq!(d["static"], true, "{carriage} has its box");
        assert!(d["components"].to_string().contains("Boxes3D:half_sizes"));
    }
    let x = &e["/machine/y_axis/x_axis/deflection_x10000"];
    let (first, last) = (&x["first_transform"], &x["last_transform"]);
    let turn = &last["rotation_axis_angle"];
    let axis: Vec<f64> = serde_json::from_value(turn["axis"].clone()).expect("an axis");
    let angle = turn["angle"].as_f64().expect("an angle");
    assert!((angle - 0.03).abs() < 1e-6, "{turn}");
    assert!((axis[1] - 1.0).abs() < 1e-6, "{turn}");
    let z = |t: &Value| t["translation"][2].as_f64().expect("a translation");
    assert!((z(last) - z(first) + 0.02).abs() < 1e-6, "{first} {last}");
    assert_eq!(first["rotation_axis_angle"]["angle"].as_f64(), Some(0.0));
}
