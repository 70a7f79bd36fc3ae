//! Chatter detection from accelerometer signals (m/s²) sampled at a constant rate.
//!
//! Two detectors:
//! - [`kim`]: Kim, Song & Koh's band-pass RMS detector (fixed 6–7 kHz band and an RMS limit).
//! - [`spectral`]: a tooth-harmonic-aware spectral detector that needs no hand-set band.
//!
//! [`eval`] scores detectors on labelled runs (accuracy, false-positive and false-negative rates,
//! detection latency).

pub mod eval;
pub mod kim;
pub mod spectral;

use thiserror::Error;

/// Why a signal cannot be analysed.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum DetectError {
    /// No channel, channels of unequal length, or a signal shorter than one window.
    #[error("{0}")]
    Signal(String),
    /// A setting out of its accepted range.
    #[error("{name} = {value}: {accepted}")]
    Setting {
        /// Setting name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is accepted.
        accepted: &'static str,
    },
    /// The band-pass filter design failed.
    #[error("band-pass filter: {0}")]
    Filter(#[from] crate::filter::FilterError),
}

/// Checks that `channels` holds at least one channel, all of length `len` ≥ `min_len`, and
/// finite values, and that `fs` is a positive finite rate. Returns `len`.
pub(crate) fn check_channels(
    channels: &[&[f64]],
    fs: f64,
    min_len: usize,
) -> Result<usize, DetectError> {
    if !(fs.is_finite() && fs > 0.0) {
        return Err(DetectError::Setting {
            name: "sample rate (Hz)",
            value: fs,
            accepted: "a positive number",
        });
    }
    let Some(first) = channels.first() else {
        return Err(DetectError::Signal("no channel given".into()));
    };
    let len = first.len();
    if channels.iter().any(|c| c.len() != len) {
        return Err(DetectError::Signal("channels of different lengths".into()));
    }
    if len < min_len {
        return Err(DetectError::Signal(format!(
            "{len} samples: at least {min_len} (one analysis window) are needed"
        )));
    }
    if channels.iter().any(|c| c.iter().any(|v| !v.is_finite())) {
        return Err(DetectError::Signal("a sample that is not finite".into()));
    }
    Ok(len)
}

/// The verdict of a detector on a whole signal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Verdict {
    /// Chatter found anywhere in the signal.
    pub chatter: bool,
    /// Time of the first detection (end of the window that completed it), s from the first sample.
    pub detection_time_s: Option<f64>,
    /// Chatter frequency at the first detection, Hz, when the detector estimates one.
    pub chatter_frequency_hz: Option<f64>,
}
