//! Scoring detectors on labelled runs.
//!
//! A run is classified as a whole: correct when the detector's verdict equals the label.
//! Rates: false-positive rate = stable runs flagged / stable runs; false-negative rate = chatter
//! runs not flagged / chatter runs; accuracy = correct runs / all runs. Latency (s) =
//! detection time − labelled onset, over the chatter runs that were flagged (negative when the
//! detector fired before the onset: reported as is, since it is a false alarm in disguise);
//! the median and the 90th percentile (nearest rank) are given.

use super::{DetectError, Verdict};

/// A labelled run.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelledRun {
    /// Channels of acceleration, m/s², equal lengths, first sample at t = 0.
    pub channels: Vec<Vec<f64>>,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Spindle speed, rev/min.
    pub spindle_rpm: f64,
    /// Number of teeth.
    pub teeth: u32,
    /// Chatter onset, s, or `None` for a stable run.
    pub chatter_onset_s: Option<f64>,
}

impl LabelledRun {
    /// The channels as slices.
    pub fn slices(&self) -> Vec<&[f64]> {
        self.channels.iter().map(Vec::as_slice).collect()
    }
}

/// Scores of one detector over a set of runs.
#[derive(Debug, Clone, PartialEq)]
pub struct Scores {
    /// Runs scored.
    pub runs: usize,
    /// Correctly classified share.
    pub accuracy: f64,
    /// Flagged stable runs / stable runs (NaN without stable runs).
    pub false_positive_rate: f64,
    /// Missed chatter runs / chatter runs (NaN without chatter runs).
    pub false_negative_rate: f64,
    /// Median latency, s (NaN when no chatter run was flagged).
    pub median_latency_s: f64,
    /// 90th percentile latency (nearest rank), s.
    pub p90_latency_s: f64,
    /// Every latency, s, in run order.
    pub latencies_s: Vec<f64>,
}

/// Runs `detector` on every run and scores it.
pub fn evaluate<F>(runs: &[LabelledRun], mut detector: F) -> Result<Scores, DetectError>
where
    F: FnMut(&LabelledRun) -> Result<Verdict, DetectError>,
{
    let (mut correct, mut stable, mut fp, mut chatter, mut missed) = (0, 0, 0, 0, 0);
    let mut latencies = Vec::new();
    for run in runs {
        let v = detector(run)?;
        match run.chatter_onset_s {
            None => {
                stable += 1;
                fp += usize::from(v.chatter);
            }
            Some(onset) => {
                chatter += 1;
                missed += usize::from(!v.chatter);
                if let Some(t) = v.detection_time_s {
                    latencies.push(t - onset);
                }
            }
        }
        correct += usize::from(v.chatter == run.chatter_onset_s.is_some());
    }
    let ratio = |a: usize, b: usize| {
        if b == 0 {
            f64::NAN
        } else {
            a as f64 / b as f64
        }
    };
    Ok(Scores {
        runs: runs.len(),
        accuracy: ratio(correct, runs.len()),
        false_positive_rate: ratio(fp, stable),
        false_negative_rate: ratio(missed, chatter),
        median_latency_s: percentile(&latencies, 0.5),
        p90_latency_s: percentile(&latencies, 0.9),
        latencies_s: latencies,
    })
}

/// Nearest-rank percentile (q in 0..=1) of `x`; NaN for an empty slice.
pub fn percentile(x: &[f64], q: f64) -> f64 {
    if x.is_empty() {
        return f64::NAN;
    }
    let mut s = x.to_vec();
    s.sort_by(f64::total_cmp);
    let rank = (q * s.len() as f64).ceil().max(1.0) as usize;
    s[rank.min(s.len()) - 1]
}
