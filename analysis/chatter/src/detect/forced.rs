//! The forced lines of a milling cut and where a sampled log shows them.
//!
//! # Forced lines
//!
//! A cutter of N teeth turning at n rev/min makes a process of period T_r = 60/n s, one
//! revolution. The chip of a tooth depends on its radius: with run-out (the teeth at unequal
//! radii, [`vmt_model::cutting::EndMill::tooth_radius`]) each tooth cuts its own chip, and an
//! unbalanced spindle adds a force m·e·Ω² turning with it, so the cutting force repeats once per
//! revolution; on a tool without either it repeats once per tooth period T_r/N. A stable cut
//! is the periodic forced response to that force, so the housing acceleration holds only its
//! harmonics (Altintas, *Manufacturing Automation*, 2nd ed., §2.5 and §3.5; Schmitz & Smith,
//! *Machining Dynamics*, ch. 4):
//!
//!   f_k = k·f_r,   f_r = n/60 Hz,   k = 1, 2, …   (spindle-rotation harmonics),
//!
//! of which the orders k = m·N are the tooth-passing harmonics m·f_tp, f_tp = N·f_r. Without
//! run-out and unbalance only those carry power; with them every order does. Regenerative
//! chatter is self-excited near a mode at a frequency f_c that the spindle does not set, so in
//! general off this comb (its sidebands f_c + k·f_r are off it too). The comb itself is never
//! chatter, whatever its level.
//!
//! # Aliases
//!
//! A line of frequency f sampled at f_s reads x_j = cos(2π·f·j/f_s + φ). For every integer m,
//! e^{i2π·m·j} = 1, so f and f − m·f_s give the same samples; and cos is even, so f and −f do
//! too. The sampled line therefore shows at the distance from f to the nearest multiple of f_s:
//!
//!   f_a = |f − f_s·round(f/f_s)|,   0 ≤ f_a ≤ f_s/2
//!
//! (Shannon; Oppenheim & Schafer, *Discrete-Time Signal Processing*, 3rd ed., §4.2). A line
//! above the Nyquist frequency f_s/2 that the sensor's anti-alias filter lets through lands at
//! f_a, on the log's own band, and is as forced there as it was at f. Which orders can reach
//! the log is the sensor's business: a 4th-order Butterworth anti-alias filter at 0.45·f_s (the
//! simulator's, [`AliasBand`]) leaves a line at f_s 28 dB down and one at 1.5·f_s 42 dB down,
//! so by default the comb is taken up to the sample rate: every line of the log's band and
//! every line folded into it once.

/// Spindle-rotation frequency f_r = n/60 of a speed in rev/min, Hz.
pub fn spindle_hz(spindle_rpm: f64) -> f64 {
    spindle_rpm / 60.0
}

/// Tooth-passing frequency f_tp = N·n/60, Hz.
pub fn tooth_passing_hz(spindle_rpm: f64, teeth: u32) -> f64 {
    teeth as f64 * spindle_hz(spindle_rpm)
}

/// Where a line at `frequency_hz` shows in a log sampled at `sample_rate_hz`: its distance to
/// the nearest multiple of the sample rate, Hz, in [0, fs/2] (module doc).
pub fn alias_hz(frequency_hz: f64, sample_rate_hz: f64) -> f64 {
    let fs = sample_rate_hz;
    (frequency_hz - fs * (frequency_hz / fs).round()).abs()
}

/// The highest frequency of the forced lines considered, as a multiple of the sample rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AliasBand {
    /// Forced lines up to this many times the sample rate reach the log (1: the log's band and
    /// everything folded into it once; 0.5: no alias at all, an ideal anti-alias filter).
    pub sample_rates: f64,
}

impl Default for AliasBand {
    /// One sample rate: lines folded once. The simulator's accelerometer (4th-order
    /// Butterworth at 0.45·fs) passes a line at 0.55·fs (folded to 0.45·fs) 7 dB down and one
    /// at fs (folded to 0) 28 dB down.
    fn default() -> Self {
        Self { sample_rates: 1.0 }
    }
}

/// One line of the forced comb.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForcedLine {
    /// Spindle order k: the line is at k·f_r.
    pub order: u32,
    /// Its frequency, k·f_r, Hz.
    pub frequency_hz: f64,
    /// Where the log shows it ([`alias_hz`]), Hz.
    pub alias_hz: f64,
    /// k is a multiple of the teeth: a tooth-passing harmonic (else a spindle-rotation one,
    /// which run-out and unbalance make).
    pub tooth_passing: bool,
}

impl ForcedLine {
    /// Whether the log shows the line folded (its frequency above the Nyquist frequency).
    pub fn folded(&self, sample_rate_hz: f64) -> bool {
        self.frequency_hz > sample_rate_hz / 2.0
    }
}

/// The forced comb of a cut at `spindle_rpm` with `teeth` teeth as a log sampled at
/// `sample_rate_hz` shows it: every spindle order k ≥ 1 with k·f_r up to `band` sample rates,
/// in order. Empty for a speed or rate that is not positive.
pub fn forced_comb(
    spindle_rpm: f64,
    teeth: u32,
    sample_rate_hz: f64,
    band: AliasBand,
) -> Vec<ForcedLine> {
    let f_r = spindle_hz(spindle_rpm);
    if !(f_r > 0.0 && sample_rate_hz > 0.0 && band.sample_rates > 0.0) {
        return Vec::new();
    }
    let top = band.sample_rates * sample_rate_hz;
    (1..)
        .map(|k: u32| (k, k as f64 * f_r))
        .take_while(|&(_, f)| f <= top)
        .map(|(k, f)| ForcedLine {
            order: k,
            frequency_hz: f,
            alias_hz: alias_hz(f, sample_rate_hz),
            tooth_passing: teeth > 0 && k.is_multiple_of(teeth),
        })
        .collect()
}
