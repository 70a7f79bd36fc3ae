//! A run's ball-bar traces read back from its MCAP file, grouped into circular tests as the
//! diagnosis takes them, and the grouping of a simulated run's traces, which the writers and
//! the polar plots number the same way.

use crate::error::FileError;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use vmt_ballbar::Trace;
use vmt_ballbar::samples::transient_deg;
use vmt_sim::run::BallbarTrace;

/// The traces of a run, grouped by test (the traces of one circular test share plane, radius,
/// feed and set-up), and the run's ground truth if it carries one.
pub struct Recorded {
    /// Tests, each one or two traces.
    pub tests: Vec<Vec<Trace>>,
    /// Ground truth of a simulated run.
    pub ground_truth: Option<Value>,
}

/// Groups consecutive traces into tests: a new test starts when the plane, radius or feed
/// changes or a direction repeats (the next test of a multi-step procedure).
pub fn group_tests(traces: Vec<Trace>) -> Vec<Vec<Trace>> {
    let sizes = test_sizes(&traces, |a, b| {
        a.plane == b.plane
            && a.radius_mm == b.radius_mm
            && a.feed_mm_min == b.feed_mm_min
            && a.sense != b.sense
    });
    let mut rest = traces.into_iter();
    sizes
        .into_iter()
        .map(|n| rest.by_ref().take(n).collect())
        .collect()
}

/// The tests of a run's traces, as [`group_tests`] makes them of the traces read back.
pub fn run_tests(traces: &[BallbarTrace]) -> Vec<&[BallbarTrace]> {
    let sizes = test_sizes(traces, |a, b| {
        a.plane.eq_ignore_ascii_case(&b.plane)
            && a.radius_mm == b.radius_mm
            && a.feed_mm_min == b.feed_mm_min
            && !a.direction.eq_ignore_ascii_case(&b.direction)
    });
    let mut rest = traces;
    sizes
        .into_iter()
        .map(|n| {
            let (test, tail) = rest.split_at(n);
            rest = tail;
            test
        })
        .collect()
}

/// The number of traces of each test, in order: a trace joins the one before it when that one
/// is alone in its test and `pair` says the two are its directions.
fn test_sizes<T>(traces: &[T], pair: impl Fn(&T, &T) -> bool) -> Vec<usize> {
    let mut sizes: Vec<usize> = Vec::new();
    for (i, t) in traces.iter().enumerate() {
        match sizes.last_mut() {
            Some(n) if *n == 1 && pair(&traces[i - 1], t) => *n = 2,
            _ => sizes.push(1),
        }
    }
    sizes
}

/// One ball-bar channel being read: its metadata and samples.
#[derive(Default)]
struct Channel {
    meta: BTreeMap<String, String>,
    time: Vec<f64>,
    angle: Vec<f64>,
    deviation: Vec<f64>,
}

/// The ball-bar traces of the MCAP run `path`, grouped into tests, and its ground truth;
/// errors name `file`. A run without `/ballbar/` topics is refused.
pub fn read(path: &Path, file: &str) -> Result<Recorded, FileError> {
    let bad = |m: String| FileError::input(file, None, m);
    let mut channels: BTreeMap<u16, Channel> = BTreeMap::new();
    let mut truth = None;
    for message in crate::input::messages(path, file)? {
        let m = message?;
        let topic = m.channel.topic.as_str();
        if topic == "/ground_truth" {
            truth = serde_json::from_slice(&m.data).ok();
            continue;
        }
        if !topic.starts_with("/ballbar/") {
            continue;
        }
        let c = channels.entry(m.channel.id).or_insert_with(|| Channel {
            meta: m.channel.metadata.clone(),
            ..Default::default()
        });
        let v: Value = serde_json::from_slice(&m.data)
            .map_err(|e| bad(format!("{topic}: a message that is not JSON: {e}")))?;
        let num = |k: &str| {
            v[k].as_f64()
                .ok_or_else(|| bad(format!("{topic}: a message without a number `{k}`")))
        };
        c.time.push(num("time_s")?);
        c.angle.push(num("angle_deg")?);
        c.deviation.push(num("deviation_um")?);
    }
    if channels.is_empty() {
        return Err(bad(
            "no /ballbar/ topics: not a ball-bar run (a run of a ballbar or kwon_seven_step job is needed)".into(),
        ));
    }
    let traces = channels
        .into_values()
        .map(|c| {
            let meta = |k: &str| {
                c.meta
                    .get(k)
                    .cloned()
                    .ok_or_else(|| bad(format!("a ball-bar channel without `{k}` metadata")))
            };
            let number = |k: &str| -> Result<f64, FileError> {
                meta(k)?
                    .parse()
                    .map_err(|_| bad(format!("ball-bar channel metadata `{k}` is not a number")))
            };
            Trace::new(
                &meta("label")?,
                &meta("plane")?,
                &meta("direction")?,
                number("radius_mm")?,
                number("feed_mm_min")?,
                c.angle,
                c.deviation,
                Some(c.time),
            )
            .map_err(|e| bad(e.to_string()))
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Recorded {
        tests: group_tests(traces),
        ground_truth: truth,
    })
}

/// The largest |deviation| of the finite samples of `traces` (µm), and of those more than
/// [`transient_deg`] from either end of their trace; `None` without a finite sample. The
/// polar plots of the PNGs and of the Rerun recording take their scales from it.
pub fn largest_deviations<'a>(
    traces: impl IntoIterator<Item = &'a BallbarTrace>,
) -> Option<(f64, Option<f64>)> {
    let mut all: Option<f64> = None;
    let mut inner: Option<f64> = None;
    for t in traces {
        let finite: Vec<(f64, f64)> = t
            .angle_deg
            .iter()
            .zip(&t.deviation_um)
            .filter(|(a, d)| a.is_finite() && d.is_finite())
            .map(|(a, d)| (*a, d.abs()))
            .collect();
        let (Some(first), Some(last)) = (finite.first(), finite.last()) else {
            continue;
        };
        let ends = transient_deg(t.feed_mm_min, t.radius_mm);
        for &(a, d) in &finite {
            all = Some(all.map_or(d, |m| m.max(d)));
            if (a - first.0).abs() >= ends && (last.0 - a).abs() >= ends {
                inner = Some(inner.map_or(d, |m| m.max(d)));
            }
        }
    }
    all.map(|a| (a, inner))
}
