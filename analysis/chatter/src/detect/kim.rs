//! Kim, Song & Koh's chatter detector: band-pass, block RMS, limit, feed override.
//!
//! Source: D.-H. Kim, J.-Y. Song, D.-Y. Koh, "Smart Compensation for Chatter Control of
//! Machine-Tool", J. Korean Soc. Precis. Eng. 32(2), 2015 (§2.2, §3.1.3, §4). Accelerometers on
//! the spindle housing sampled at 20 kHz; a Chebyshev I band-pass 6–7 kHz (0.1 dB ripple, 10 dB
//! at 5.5 and 7.5 kHz) isolates the band where chatter grew in their cuts; the DSP fills a buffer,
//! filters it and takes its RMS (block, not sliding: §3.1.2–3.1.3), and flags chatter when
//!
//!   RMS = √(1/W · Σ_{window} Σ_axes y²) > RMS_limit   (m/s²),
//!
//! where RMS_limit is set beforehand from cuts that chattered. The feed override sent to the CNC
//! is the ratio RMS_limit / RMS (§4), capped here at 1 (no speeding up below the limit).
//!
//! The paper states neither its buffer length nor its limit; [`KimSettings::with_limit`] uses a
//! 50 ms block (1000 samples at 20 kHz) and the limit must be given. The paper's DSP stops
//! sampling while it processes a buffer; here the filter runs continuously (its state carries
//! over from block to block). Several axes are combined by summing their squared filtered
//! samples (the RMS of the vector).

use super::{DetectError, Verdict, check_channels};
use crate::filter::{BandPassSpec, ChebyshevBandPass};

/// Settings of the detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KimSettings {
    /// Pass band (low, high), Hz; the stop edges are 0.5 kHz outside (as in the paper), with
    /// 0.1 dB ripple and 10 dB attenuation.
    pub band_hz: (f64, f64),
    /// RMS limit of the band-passed acceleration, m/s².
    pub limit: f64,
    /// Block length, s.
    pub window_s: f64,
}

impl KimSettings {
    /// The paper's band (6–7 kHz), a 50 ms block and the given limit (m/s²).
    pub fn with_limit(limit: f64) -> Self {
        Self {
            band_hz: (6000.0, 7000.0),
            limit,
            window_s: 0.05,
        }
    }

    /// The band-pass specification at sample rate `fs`.
    pub fn spec(&self, fs: f64) -> BandPassSpec {
        let (lo, hi) = self.band_hz;
        BandPassSpec {
            pass_hz: (lo, hi),
            stop_hz: (lo - 500.0, hi + 500.0),
            ..BandPassSpec::kim(fs)
        }
    }
}

/// One block of the detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KimWindow {
    /// End of the block, s.
    pub end_s: f64,
    /// RMS of the band-passed signal, m/s².
    pub rms: f64,
    /// RMS > limit.
    pub chatter: bool,
    /// min(1, limit / RMS).
    pub feed_override: f64,
}

/// The detector's output.
#[derive(Debug, Clone, PartialEq)]
pub struct KimResult {
    /// Per block.
    pub windows: Vec<KimWindow>,
    /// Verdict (no chatter frequency: the band is all it knows).
    pub verdict: Verdict,
}

/// Runs the detector on `channels` (m/s², equal lengths) sampled at `fs` Hz; the first sample
/// is at t = 0.
pub fn detect(channels: &[&[f64]], fs: f64, s: &KimSettings) -> Result<KimResult, DetectError> {
    if !(s.limit.is_finite() && s.limit > 0.0) {
        return Err(DetectError::Setting {
            name: "RMS limit (m/s²)",
            value: s.limit,
            accepted: "a positive number",
        });
    }
    let w = (s.window_s * fs).round();
    if !(w >= 16.0 && w.is_finite()) {
        return Err(DetectError::Setting {
            name: "window (s)",
            value: s.window_s,
            accepted: "at least 16 samples",
        });
    }
    let w = w as usize;
    let len = check_channels(channels, fs, w)?;
    let filter = ChebyshevBandPass::design(s.spec(fs))?;
    let mut sq = vec![0.0; len];
    for c in channels {
        let mut f = filter.runner();
        for (acc, &x) in sq.iter_mut().zip(c.iter()) {
            let y = f.step(x);
            *acc += y * y;
        }
    }
    let windows: Vec<KimWindow> = sq
        .chunks_exact(w)
        .enumerate()
        .map(|(i, block)| {
            let rms = (block.iter().sum::<f64>() / w as f64).sqrt();
            KimWindow {
                end_s: ((i + 1) * w) as f64 / fs,
                rms,
                chatter: rms > s.limit,
                feed_override: if rms > s.limit { s.limit / rms } else { 1.0 },
            }
        })
        .collect();
    let first = windows.iter().find(|w| w.chatter);
    Ok(KimResult {
        verdict: Verdict {
            chatter: first.is_some(),
            detection_time_s: first.map(|w| w.end_s),
            chatter_frequency_hz: None,
        },
        windows,
    })
}
