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
//! 50 ms block (1000 samples at 20 kHz) and the limit must be given. Its band is its machine's
//! chatter band; for another tool [`KimSettings::for_mode`] designs one from the tool-point
//! mode that chatters first ([`weakest_mode`]). A band whose stop edges do not lie below the
//! Nyquist frequency cannot be run on that log ([`KimSettings::fits`]). The paper's DSP stops
//! sampling while it processes a buffer; here the filter runs continuously (its state carries
//! over from block to block). Several axes are combined by summing their squared filtered
//! samples (the RMS of the vector).

use super::{DetectError, Verdict, check_channels};
use crate::filter::{BandPassSpec, ChebyshevBandPass};
use vmt_model::cutting::Mode;

/// Settings of the detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KimSettings {
    /// Pass band (low, high), Hz; the stop edges lie half the band's width outside it (the
    /// paper's 500 Hz outside its 1 kHz band), with 0.1 dB ripple and 10 dB attenuation.
    pub band_hz: (f64, f64),
    /// RMS limit of the band-passed acceleration, m/s².
    pub limit: f64,
    /// Block length, s.
    pub window_s: f64,
}

/// The paper's pass band, Hz (their machine's chatter, §2.1–2.2).
pub const PAPER_BAND_HZ: (f64, f64) = (6000.0, 7000.0);

/// The pass band designed from a tool-point mode, as fractions of its natural frequency:
/// regenerative chatter sets in above the mode it grows from (where the real part of the
/// frequency response is negative, ω_n to about ω_n·(1 + 2ζ) for a single mode, further on a
/// lobe's flank; Altintas §3.3), so the band reaches from 10 % below the mode to 20 % above,
/// 0.3·f_n wide: the paper's 6–7 kHz is 0.15 of its centre, here wider because the chatter
/// frequency moves along the lobes with the spindle speed.
pub const MODE_BAND: (f64, f64) = (0.9, 1.2);

impl KimSettings {
    /// The paper's band (6–7 kHz), a 50 ms block and the given limit (m/s²).
    pub fn with_limit(limit: f64) -> Self {
        Self {
            band_hz: PAPER_BAND_HZ,
            limit,
            window_s: 0.05,
        }
    }

    /// The band of [`MODE_BAND`] about a tool-point mode at `mode_hz`, a 50 ms block and the
    /// given limit (m/s²).
    pub fn for_mode(mode_hz: f64, limit: f64) -> Self {
        Self {
            band_hz: (MODE_BAND.0 * mode_hz, MODE_BAND.1 * mode_hz),
            ..Self::with_limit(limit)
        }
    }

    /// The stop edges, Hz: half the pass band's width outside it.
    pub fn stop_hz(&self) -> (f64, f64) {
        let (lo, hi) = self.band_hz;
        let margin = 0.5 * (hi - lo);
        (lo - margin, hi + margin)
    }

    /// The band-pass specification at sample rate `fs`.
    pub fn spec(&self, fs: f64) -> BandPassSpec {
        BandPassSpec {
            pass_hz: self.band_hz,
            stop_hz: self.stop_hz(),
            ..BandPassSpec::kim(fs)
        }
    }

    /// Whether the band and its stop edges lie below the Nyquist frequency of `fs`:
    /// [`DetectError::BandAboveNyquist`] if not.
    pub fn fits(&self, fs: f64) -> Result<(), DetectError> {
        let (stop_low, stop_high) = self.stop_hz();
        let nyquist = fs / 2.0;
        if stop_high < nyquist && stop_low > 0.0 {
            return Ok(());
        }
        Err(DetectError::BandAboveNyquist {
            pass_low: self.band_hz.0,
            pass_high: self.band_hz.1,
            stop_low,
            stop_high,
            nyquist,
        })
    }
}

/// The natural frequency (Hz) of the tool-point mode a regenerative chatter grows from first:
/// the one of least k·ζ·(1 + ζ). The zero-order critical depth is a_lim = −1/(2·K_t·N·α·Re G)
/// (Altintas, *Manufacturing Automation*, §3.3), and a single mode's most negative real part
/// is Re G_min = −1/(2kζ(1 + ζ)), so the lowest lobe of a mode is proportional to k·ζ·(1 + ζ).
pub fn weakest_mode(modes: &[Mode]) -> Option<f64> {
    modes
        .iter()
        .filter(|m| m.natural_frequency_hz > 0.0 && m.stiffness > 0.0)
        .min_by(|a, b| {
            let w = |m: &Mode| m.stiffness * m.damping_ratio * (1.0 + m.damping_ratio);
            w(a).total_cmp(&w(b))
        })
        .map(|m| m.natural_frequency_hz)
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
    s.fits(fs)?;
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
