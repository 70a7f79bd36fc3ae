//! The ambient (workshop air) temperature as a function of time.

use super::ThermalError;

/// Ambient air temperature `T_amb(t)` in °C, `t` in s from the start of the
/// run (ISO 230-3 environmental temperature variation).
#[derive(Debug, Clone, PartialEq)]
pub enum Ambient {
    /// A constant temperature.
    Constant {
        /// Temperature in °C.
        celsius: f64,
    },
    /// A sinusoidal drift, e.g. the day/night cycle of a workshop:
    /// `T(t) = mean_c + amplitude_k · sin(2π (t − phase_s) / period_s)`,
    /// i.e. the temperature crosses the mean upwards at `t = phase_s`.
    Sinusoid {
        /// Mean temperature in °C.
        mean_c: f64,
        /// Amplitude in K (half the peak-to-peak swing), `>= 0`.
        amplitude_k: f64,
        /// Period in s, `> 0`.
        period_s: f64,
        /// Time shift in s of the upward mean crossing.
        phase_s: f64,
    },
    /// A measured record: linear interpolation between the points, held at
    /// the first value before the first point and at the last value after
    /// the last point.
    Table {
        /// Times in s, strictly increasing.
        times_s: Vec<f64>,
        /// Temperatures in °C, one per time.
        celsius: Vec<f64>,
    },
}

impl Default for Ambient {
    /// A constant 20 °C, the ISO 1 reference temperature.
    fn default() -> Self {
        Ambient::Constant { celsius: 20.0 }
    }
}

impl Ambient {
    /// The ambient temperature in °C at time `t_s` (s).
    ///
    /// Never panics. For a model that [`validate`](Self::validate) rejects
    /// (e.g. an empty table) the result is unspecified, possibly NaN.
    pub fn celsius_at(&self, t_s: f64) -> f64 {
        match self {
            Ambient::Constant { celsius } => *celsius,
            Ambient::Sinusoid {
                mean_c,
                amplitude_k,
                period_s,
                phase_s,
            } => {
                let angle = std::f64::consts::TAU * (t_s - phase_s) / period_s;
                mean_c + amplitude_k * angle.sin()
            }
            Ambient::Table { times_s, celsius } => interpolate(times_s, celsius, t_s),
        }
    }

    /// Checks the model: all values finite, sinusoid amplitude `>= 0` and
    /// period `> 0`, table non-empty with columns of equal length and
    /// strictly increasing times.
    pub fn validate(&self) -> Result<(), ThermalError> {
        match self {
            Ambient::Constant { celsius } => finite("constant celsius", *celsius),
            Ambient::Sinusoid {
                mean_c,
                amplitude_k,
                period_s,
                phase_s,
            } => validate_sinusoid(*mean_c, *amplitude_k, *period_s, *phase_s),
            Ambient::Table { times_s, celsius } => validate_table(times_s, celsius),
        }
    }
}

/// Linear interpolation in a table, clamped at both ends.
fn interpolate(times_s: &[f64], celsius: &[f64], t_s: f64) -> f64 {
    let len = times_s.len().min(celsius.len());
    let (times_s, celsius) = (&times_s[..len], &celsius[..len]);
    // Index of the first point strictly after t (NaN t gives 0).
    let after = times_s.partition_point(|&x| x <= t_s);
    match (after.checked_sub(1), celsius.get(after)) {
        (None, _) => celsius.first().copied().unwrap_or(f64::NAN),
        (Some(before), None) => celsius[before],
        (Some(before), Some(&c1)) => {
            let (t0, t1, c0) = (times_s[before], times_s[after], celsius[before]);
            let w = (t_s - t0) / (t1 - t0);
            c0 + w * (c1 - c0)
        }
    }
}

fn finite(what: &str, value: f64) -> Result<(), ThermalError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(invalid(what, value, "a finite value"))
    }
}

fn invalid(what: &str, value: f64, accepted: &'static str) -> ThermalError {
    ThermalError::InvalidAmbient {
        what: what.to_owned(),
        value,
        accepted,
    }
}

fn validate_sinusoid(
    mean_c: f64,
    amplitude_k: f64,
    period_s: f64,
    phase_s: f64,
) -> Result<(), ThermalError> {
    finite("sinusoid mean_c", mean_c)?;
    finite("sinusoid phase_s", phase_s)?;
    if !(amplitude_k.is_finite() && amplitude_k >= 0.0) {
        return Err(invalid(
            "sinusoid amplitude_k",
            amplitude_k,
            "a finite value >= 0 K",
        ));
    }
    if !(period_s.is_finite() && period_s > 0.0) {
        return Err(invalid(
            "sinusoid period_s",
            period_s,
            "a finite value > 0 s",
        ));
    }
    Ok(())
}

fn validate_table(times_s: &[f64], celsius: &[f64]) -> Result<(), ThermalError> {
    if times_s.len() != celsius.len() {
        return Err(ThermalError::AmbientTableLength {
            times: times_s.len(),
            temperatures: celsius.len(),
        });
    }
    if times_s.is_empty() {
        return Err(ThermalError::AmbientTableEmpty);
    }
    for (i, (&t, &c)) in times_s.iter().zip(celsius).enumerate() {
        finite(&format!("table times_s[{i}]"), t)?;
        finite(&format!("table celsius[{i}]"), c)?;
    }
    for (i, pair) in times_s.windows(2).enumerate() {
        if pair[1] <= pair[0] {
            return Err(ThermalError::AmbientTableNotIncreasing {
                index: i + 1,
                value_s: pair[1],
                previous_index: i,
                previous_s: pair[0],
            });
        }
    }
    Ok(())
}
