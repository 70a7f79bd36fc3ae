//! Accelerometers on the spindle housing, X, Y and Z.
//!
//! Housing acceleration: each mode k of the tool point moves the housing by a fraction κ_k of
//! its modal acceleration, a_h = Σ_k κ_k·q̈_k per direction (the participation of the housing
//! in the mode shape relative to the tool point; the tool and holder carry the rest). Default
//! κ = [`DEFAULT_PARTICIPATION`] for every mode: an assumed value, not from a source; κ is a
//! property of the machine's mode shapes, found by tapping the tool tip with the sensor on the
//! housing (the ratio of the two frequency response functions at the mode). Z: the optional axial mode driven by the axial
//! force, same rule; without it the Z sensor reads noise only.
//!
//! Signal chain, per cut step h then per output sample:
//! 1. Mounted resonance (the stud-mounted sensor's contact resonance, ISO 5348): a 2nd-order low-pass ÿ + 2ζω·ẏ + ω²·y = ω²·a_h (default 30 kHz,
//!    ζ = 0.05), integrated exactly with the input held over the step (as the modes).
//! 2. Anti-alias: a 4th-order Butterworth low-pass (two bilinear biquads, pre-warped, at the
//!    cut step rate), default corner 0.45 of the output rate; skipped when the step equals the
//!    output period (there is nothing to decimate then).
//! 3. Decimation to the output rate (20 kHz by default), white Gaussian noise (seeded), and an
//!    ADC of `adc_bits` over ±`adc_range` (rounding to the LSB 2·range/2^bits, clipping at the
//!    range).

use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};
use vmt_model::cutting::Mode;
use vmt_model::cutting::integrator::DiscreteMode;

use super::{MillingError, check};

/// Housing participation κ of a mode when none is given.
pub const DEFAULT_PARTICIPATION: f64 = 0.2;

/// The sensors and the output rate.
#[derive(Clone, Debug, PartialEq)]
pub struct AccelerometerParams {
    /// Output rate of the `accelerometer` and `cutting` streams, Hz.
    pub sample_rate_hz: f64,
    /// κ per mode: the X modes, then the Y modes, then the axial mode; empty for the default.
    pub participation: Vec<f64>,
    /// Mounted resonance, Hz.
    pub resonance_hz: f64,
    /// Damping ratio of the mounted resonance.
    pub resonance_damping: f64,
    /// Anti-alias corner, Hz.
    pub anti_alias_hz: f64,
    /// RMS of the white noise, m/s².
    pub noise_rms: f64,
    /// ADC resolution, bits (1–32).
    pub adc_bits: u32,
    /// ADC full scale ±range, m/s².
    pub adc_range: f64,
}

impl Default for AccelerometerParams {
    /// 20 kHz, κ = 0.2, 30 kHz / ζ 0.05 mounted resonance, 9 kHz anti-alias, 0.05 m/s² noise,
    /// 16-bit ADC over ±50 g.
    fn default() -> Self {
        Self {
            sample_rate_hz: 20_000.0,
            participation: Vec::new(),
            resonance_hz: 30_000.0,
            resonance_damping: 0.05,
            anti_alias_hz: 9_000.0,
            noise_rms: 0.05,
            adc_bits: 16,
            adc_range: 50.0 * 9.80665,
        }
    }
}

/// The anti-alias corner of [`AccelerometerParams::at_rate`], as a fraction of the sample rate
/// (the default's 9 kHz at 20 kHz: a 4th-order Butterworth there leaves a line at the Nyquist
/// frequency 3.5 dB down and one at the sample rate 28 dB down).
pub const ANTI_ALIAS_FRACTION: f64 = 0.45;

impl AccelerometerParams {
    /// The default sensors sampled at `sample_rate_hz`, with the anti-alias corner at
    /// [`ANTI_ALIAS_FRACTION`] of it: the signal chain a data acquisition system gives a sensor
    /// logged at that rate.
    pub fn at_rate(sample_rate_hz: f64) -> Self {
        Self {
            sample_rate_hz,
            anti_alias_hz: ANTI_ALIAS_FRACTION * sample_rate_hz,
            ..Self::default()
        }
    }

    pub(crate) fn validate(&self, modes: usize) -> Result<(), MillingError> {
        let fs = self.sample_rate_hz;
        check("accelerometer sample rate (Hz)", fs, fs > 0.0, "> 0")?;
        let n = self.participation.len();
        check(
            "number of accelerometer participation factors",
            n as f64,
            n == 0 || n == modes,
            "none (default) or one per mode: X modes, Y modes, axial mode",
        )?;
        for &k in &self.participation {
            check("accelerometer participation", k, true, "a finite number")?;
        }
        let r = self.resonance_hz;
        check("accelerometer resonance (Hz)", r, r > 0.0, "> 0")?;
        let z = self.resonance_damping;
        check(
            "accelerometer resonance damping",
            z,
            z > 0.0 && z < 1.0,
            "0 < ζ < 1",
        )?;
        let aa = self.anti_alias_hz;
        check(
            "anti-alias corner (Hz)",
            aa,
            aa > 0.0 && aa < fs / 2.0,
            "0 < corner < half the sample rate",
        )?;
        check(
            "accelerometer noise RMS (m/s²)",
            self.noise_rms,
            self.noise_rms >= 0.0,
            "≥ 0",
        )?;
        let b = self.adc_bits;
        check("ADC bits", b as f64, (1..=32).contains(&b), "1 to 32")?;
        check(
            "ADC range (m/s²)",
            self.adc_range,
            self.adc_range > 0.0,
            "> 0",
        )
    }

    /// κ of mode i (numbered X, Y, axial).
    pub(crate) fn participation(&self, i: usize) -> f64 {
        self.participation
            .get(i)
            .copied()
            .unwrap_or(DEFAULT_PARTICIPATION)
    }
}

/// A direct-form-II-transposed biquad.
#[derive(Clone, Copy)]
struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
    z: [f64; 2],
}

impl Biquad {
    /// Bilinear low-pass of corner `fc` and quality `q` at sample rate `fs` (pre-warped).
    fn low_pass(fc: f64, q: f64, fs: f64) -> Self {
        let k = (std::f64::consts::PI * fc / fs).tan();
        let norm = 1.0 / (1.0 + k / q + k * k);
        let b0 = k * k * norm;
        Self {
            b: [b0, 2.0 * b0, b0],
            a: [2.0 * (k * k - 1.0) * norm, (1.0 - k / q + k * k) * norm],
            z: [0.0; 2],
        }
    }

    #[inline]
    fn process(&mut self, x: f64) -> f64 {
        let y = self.b[0] * x + self.z[0];
        self.z[0] = self.b[1] * x - self.a[0] * y + self.z[1];
        self.z[1] = self.b[2] * x - self.a[1] * y;
        y
    }
}

/// One channel: mounted resonance then anti-alias.
#[derive(Clone)]
struct Channel {
    sensor: [f64; 2],
    anti_alias: Option<[Biquad; 2]>,
}

/// The three sensors of a cut.
pub(crate) struct Accelerometers {
    resonance: DiscreteMode,
    channels: [Channel; 3],
    rng: StdRng,
    noise_rms: f64,
    lsb: f64,
    range: f64,
}

impl Accelerometers {
    pub(crate) fn new(p: &AccelerometerParams, step_s: f64, seed: u64) -> Self {
        let fs = 1.0 / step_s;
        // Butterworth 4th order: two sections with Q = 1/(2 cos(π/8)) and 1/(2 cos(3π/8)).
        let decimating = fs > p.sample_rate_hz * (1.0 + 1e-9);
        let anti_alias = decimating.then(|| {
            [0.541_196_100_146_197, 1.306_562_964_876_376_6]
                .map(|q| Biquad::low_pass(p.anti_alias_hz, q, fs))
        });
        let resonance = Mode {
            natural_frequency_hz: p.resonance_hz,
            damping_ratio: p.resonance_damping,
            stiffness: 1.0,
        };
        Self {
            // With k = 1 the oscillator's force is ω²·a·m = a: unit gain at rest.
            resonance: DiscreteMode::new(&resonance, step_s),
            channels: std::array::from_fn(|_| Channel {
                sensor: [0.0; 2],
                anti_alias,
            }),
            rng: StdRng::seed_from_u64(seed),
            noise_rms: p.noise_rms,
            lsb: 2.0 * p.adc_range / 2f64.powi(p.adc_bits as i32),
            range: p.adc_range,
        }
    }

    /// Filters the housing accelerations at this step (m/s²) and returns the anti-aliased
    /// sensor outputs; the sensors then advance one step under this input.
    pub(crate) fn filter(&mut self, housing: [f64; 3]) -> [f64; 3] {
        let res = &self.resonance;
        std::array::from_fn(|i| {
            let ch = &mut self.channels[i];
            let mut y = ch.sensor[0];
            res.step(&mut ch.sensor, housing[i]);
            if let Some(aa) = &mut ch.anti_alias {
                let first = aa[0].process(y);
                y = aa[1].process(first);
            }
            y
        })
    }

    /// An output sample: noise and ADC on the filtered signals, m/s².
    pub(crate) fn read(&mut self, filtered: [f64; 3]) -> [f64; 3] {
        filtered.map(|y| {
            let n: f64 = StandardNormal.sample(&mut self.rng);
            let v = (y + self.noise_rms * n).clamp(-self.range, self.range);
            (v / self.lsb).round() * self.lsb
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_chain_passes_a_slow_tone_and_stops_a_fast_one() {
        let p = AccelerometerParams {
            noise_rms: 0.0,
            ..AccelerometerParams::default()
        };
        let h = 1.0 / 60_000.0;
        let amplitude_after = |f: f64| {
            let mut acc = Accelerometers::new(&p, h, 1);
            let mut peak: f64 = 0.0;
            for n in 0..60_000 {
                let a = (std::f64::consts::TAU * f * n as f64 * h).sin();
                let y = acc.filter([a, 0.0, 0.0])[0];
                if n > 30_000 {
                    peak = peak.max(y.abs());
                }
            }
            peak
        };
        // 1 kHz passes (within the resonance's +0.1 % and Butterworth's flat band).
        assert!((amplitude_after(1_000.0) - 1.0).abs() < 0.01);
        // 9 kHz is the corner: -3 dB (the resonance adds ~9 %).
        assert!((amplitude_after(9_000.0) - 0.707 * 1.099).abs() < 0.03);
        // 20 kHz is 4th order and 1.2 octaves above: below 4 %.
        assert!(amplitude_after(20_000.0) < 0.04);
    }
}
