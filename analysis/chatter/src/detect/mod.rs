//! Chatter detection from accelerometer signals (m/s²) sampled at a constant rate.
//!
//! Two detectors:
//! - [`kim`]: Kim, Song & Koh's band-pass RMS detector (fixed 6–7 kHz band and an RMS limit).
//! - [`spectral`]: a spectral detector that takes the cut's forced lines out (spindle-rotation
//!   and tooth-passing harmonics, at their aliases) and needs no hand-set band.
//!
//! [`forced`] places the forced lines of a cut in a log of any sample rate.
//! [`eval`] scores detectors on labelled runs (accuracy, false-positive and false-negative rates,
//! detection latency).

pub mod eval;
pub mod forced;
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
    /// The spindle turns too slowly for this sample rate: telling a line from its
    /// spindle-rotation harmonics takes a longer frame than the detector takes.
    #[error(
        "a spindle at {spindle_rpm} rev/min ({teeth} teeth) logged at {sample_rate_hz:.0} Hz: its \
         spindle-rotation harmonics lie {spindle_hz:.3} Hz apart, and telling a chatter line from \
         them takes bins of a sixteenth of that, frames of {frame_needed:.0} samples, beyond the \
         longest frame of {max_frame} samples; a log sampled at {max_rate:.0} Hz or less tells \
         them apart",
        max_rate = *max_frame as f64 * spindle_hz / 16.0
    )]
    CombUnresolved {
        /// Spindle speed, rev/min.
        spindle_rpm: f64,
        /// Teeth.
        teeth: u32,
        /// Sample rate, Hz.
        sample_rate_hz: f64,
        /// Spindle frequency, Hz.
        spindle_hz: f64,
        /// The frame the resolution needs, samples.
        frame_needed: f64,
        /// The longest frame, samples.
        max_frame: usize,
    },
    /// The forced lines seen cover most of the spectrum even at the longest frame.
    #[error(
        "a spindle at {spindle_rpm} rev/min logged at {sample_rate_hz:.0} Hz: the {lines} forced \
         lines seen in the log (spindle-rotation harmonics and their aliases) cover {pct:.0} % \
         of its spectrum even with the longest frame ({max_frame} samples), so a chatter line \
         cannot be told from them (at most half of the spectrum may lie on them)",
        pct = masked_share * 100.0
    )]
    CombCrowded {
        /// Spindle speed, rev/min.
        spindle_rpm: f64,
        /// Sample rate, Hz.
        sample_rate_hz: f64,
        /// Comb lines masked.
        lines: usize,
        /// Share of the bins they cover at the longest frame.
        masked_share: f64,
        /// The longest frame, samples.
        max_frame: usize,
    },
    /// Kim's band does not fit below the Nyquist frequency.
    #[error(
        "Kim's band {pass_low:.0}–{pass_high:.0} Hz (stop edges {stop_low:.0}–{stop_high:.0} Hz) \
         does not fit below the Nyquist frequency {nyquist:.0} Hz of this {sample_rate:.0} Hz log"
    , sample_rate = 2.0 * nyquist)]
    BandAboveNyquist {
        /// Pass band, Hz.
        pass_low: f64,
        /// Pass band, Hz.
        pass_high: f64,
        /// Stop edges, Hz.
        stop_low: f64,
        /// Stop edges, Hz.
        stop_high: f64,
        /// Half the sample rate, Hz.
        nyquist: f64,
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
