//! The test that tells equally good explanations apart.
//!
//! When rivals explain the measured runs as well as the chosen effects
//! ([`crate::select::Alternative`]), the runs cannot decide between them; another test can.
//! Each explanation is a set of values written into the model (the chosen effects at their
//! fitted sizes, each rival at the sizes it would need). Over a grid of ball-bar tests the
//! machine can run ([`setups`]: plane, bar length, feed, both directions, full circles in XY
//! and the vertical planes' arcs where a circle leaves the strokes), the model is simulated
//! noise-free with each explanation, and per test and rival the predicted difference
//! `d(θ) = m_chosen(θ) − m_rival(θ)` is averaged into 1° bins per run. What a new set-up of the
//! bar would absorb is taken out: the least-squares fit of `1, cos θ, sin θ` common to the
//! test's runs (bar length and pivot offset). The test that discriminates best is the one
//! whose largest remaining `|d|` stands furthest above the instrument's noise `σ` (the
//! measured runs' sample-to-sample noise); the report names it, the difference and where on
//! the circle it lies (an axis reversal, or the angle).

use crate::align::GapError;
use crate::model::{Forward, ScenarioModel};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use vmt_ballbar::{Plane, Trace};

/// One ball-bar test of the grid.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Setup {
    /// Plane.
    pub plane: String,
    /// Bar length, mm.
    pub radius_mm: f64,
    /// Feed, mm/min.
    pub feed_mm_min: f64,
    /// Data arc, deg.
    pub arc_deg: f64,
}

impl std::fmt::Display for Setup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} R{:.0} at {:.0} mm/min",
            self.plane, self.radius_mm, self.feed_mm_min
        )?;
        if self.arc_deg < 360.0 {
            write!(f, " over {:.0} deg", self.arc_deg)?;
        }
        Ok(())
    }
}

/// The discriminating test for one rival.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Discrimination {
    /// The rival's effects.
    pub rival: String,
    /// The chosen effect it stands in for.
    pub instead_of: String,
    /// The test that tells them apart best.
    pub setup: Setup,
    /// The largest predicted difference there, µm (after the bar's set-up).
    pub difference_um: f64,
    /// Where: the angle, deg, and the run.
    pub at_deg: f64,
    /// The run it lies in, `cw` or `ccw`.
    pub run: String,
    /// What lies there: an axis reversal, or nothing in particular.
    pub place: String,
    /// The instrument's noise it is read against, µm.
    pub noise_um: f64,
    /// The difference over the noise.
    pub ratio: f64,
    /// The same difference on the measured test itself, µm (for comparison).
    pub on_measured_um: Option<f64>,
}

impl std::fmt::Display for Discrimination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "run {}: {} and {} differ by {:.2} um {} ({}, {:.0} deg), {:.0} times the bar's noise of {:.2} um",
            self.setup,
            self.instead_of,
            self.rival,
            self.difference_um,
            self.place,
            self.run,
            self.at_deg,
            self.ratio,
            self.noise_um
        )?;
        if let Some(m) = self.on_measured_um {
            write!(f, " (on the measured test: {m:.2} um)")?;
        }
        Ok(())
    }
}

/// The grid of tests: every plane, bar lengths of 50, 100 and 150 mm, feeds of 500, 1000,
/// 2000 and 4000 mm/min; full circles, or in ZX and YZ the 220° arc over the top where a
/// circle is refused (the model's strokes decide, when the tests are simulated).
pub fn setups() -> Vec<Setup> {
    let mut out = Vec::new();
    for plane in ["XY", "ZX", "YZ"] {
        for radius_mm in [50.0, 100.0, 150.0] {
            for feed_mm_min in [500.0, 1000.0, 2000.0, 4000.0] {
                out.push(Setup {
                    plane: plane.into(),
                    radius_mm,
                    feed_mm_min,
                    arc_deg: 360.0,
                });
            }
        }
    }
    out
}

fn job(s: &Setup) -> String {
    format!(
        "kind = \"ballbar\"\nplane = \"{}\"\nradius_mm = {:?}\nfeed_mm_min = {:?}\narc_deg = {:?}\ndirections = [\"cw\", \"ccw\"]\n",
        s.plane, s.radius_mm, s.feed_mm_min, s.arc_deg
    )
}

/// The model for a set-up: the full circle, or the 220° arc in a vertical plane when the
/// circle does not fit; `None` when neither fits the machine.
fn model_for(model: &ScenarioModel, s: &Setup) -> Option<(ScenarioModel, Setup)> {
    if let Ok(m) = model.for_job(&job(s)) {
        return Some((m, s.clone()));
    }
    if s.plane == "XY" {
        return None;
    }
    let arc = Setup {
        arc_deg: 220.0,
        ..s.clone()
    };
    model.for_job(&job(&arc)).ok().map(|m| (m, arc))
}

/// Per run, the binned difference of two sets of traces of one test, less the fit of
/// `1, cos θ, sin θ` common to the runs; with the runs' senses.
fn difference(a: &[Trace], b: &[Trace]) -> Vec<(String, Vec<(f64, f64)>)> {
    let runs: Vec<(String, Vec<(f64, f64)>)> = a
        .iter()
        .zip(b)
        .map(|(x, y)| {
            let mut bins: std::collections::BTreeMap<i64, (f64, usize)> = Default::default();
            for (i, angle) in x.angle_deg.iter().enumerate() {
                let Some(other) = y.deviation_um.get(i) else {
                    break;
                };
                let e = bins.entry(angle.floor() as i64).or_default();
                e.0 += x.deviation_um[i] - other;
                e.1 += 1;
            }
            let binned = bins
                .into_iter()
                .map(|(k, (s, n))| (k as f64 + 0.5, s / n as f64))
                .collect();
            (x.sense.name().to_string(), binned)
        })
        .collect();
    let all: Vec<(f64, f64)> = runs.iter().flat_map(|(_, r)| r.iter().copied()).collect();
    let shape = |t: f64| [1.0, t.to_radians().cos(), t.to_radians().sin()];
    let ata = DMatrix::from_fn(3, 3, |i, j| {
        all.iter()
            .map(|(t, _)| shape(*t)[i] * shape(*t)[j])
            .sum::<f64>()
    });
    let atb = DVector::from_fn(3, |i, _| {
        all.iter().map(|(t, d)| shape(*t)[i] * d).sum::<f64>()
    });
    let coef = ata
        .cholesky()
        .map_or_else(|| DVector::zeros(3), |c| c.solve(&atb));
    runs.into_iter()
        .map(|(sense, r)| {
            let left = r
                .into_iter()
                .map(|(t, d)| {
                    let s = shape(t);
                    (t, d - (0..3).map(|i| s[i] * coef[i]).sum::<f64>())
                })
                .collect();
            (sense, left)
        })
        .collect()
}

/// The largest |d| of a difference: its size (µm), angle (deg) and run.
#[derive(Clone, Debug, Default)]
struct Largest {
    size: f64,
    at: f64,
    run: String,
}

fn largest(d: &[(String, Vec<(f64, f64)>)]) -> Largest {
    let mut best = Largest::default();
    for (sense, run) in d {
        for (t, v) in run {
            if v.abs() > best.size {
                best = Largest {
                    size: v.abs(),
                    at: *t,
                    run: sense.clone(),
                };
            }
        }
    }
    best
}

/// What lies at angle `t` (deg) of a circle in `plane`: an axis reversal within 10°, or
/// nothing in particular.
fn place(plane: &str, t: f64) -> String {
    let Some(p) = Plane::parse(plane) else {
        return String::new();
    };
    let (a, b) = p.axes();
    let near = |at: f64| crate::peaks::wrapped_deg(t - at).abs() <= 10.0;
    if [0.0, 180.0].into_iter().any(near) {
        format!("at the {a} reversals")
    } else if [90.0, 270.0].into_iter().any(near) {
        format!("at the {b} reversals")
    } else {
        "between the reversals".into()
    }
}

/// An explanation: a label, the chosen effect it stands in for, and the values it writes into
/// the model (absolute, by key).
pub struct Explanation {
    /// Its effects, e.g. `friction_x`.
    pub label: String,
    /// The chosen effect it rivals (empty for the chosen explanation itself).
    pub instead_of: String,
    /// Its values.
    pub values: Vec<(String, f64)>,
}

/// The traces of `m` with `values`; `None` when the model refuses them (a value its checks
/// do not accept at this set-up).
fn traces_or_none(
    m: &ScenarioModel,
    values: &[(String, f64)],
) -> Result<Option<Vec<Trace>>, GapError> {
    match m.traces(values) {
        Ok(t) => Ok(Some(t)),
        Err(GapError::Model(_)) => Ok(None),
        Err(e) => Err(e),
    }
}

/// For each rival, the test of the grid that tells it from `chosen` best (module doc), with
/// the difference on the measured test (the model's own job) beside it; `noise_um` is the
/// instrument's noise. A rival the model refuses to simulate is left out. `progress` is
/// called once per test simulated.
pub fn discriminate(
    model: &ScenarioModel,
    chosen: &Explanation,
    rivals: &[Explanation],
    noise_um: f64,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<Discrimination>, GapError> {
    let largest_difference = |m: &ScenarioModel| -> Result<Vec<Option<Largest>>, GapError> {
        let base = m.traces(&chosen.values)?;
        rivals
            .iter()
            .map(|r| Ok(traces_or_none(m, &r.values)?.map(|t| largest(&difference(&base, &t)))))
            .collect()
    };
    let own = largest_difference(model)?;
    let grid: Vec<(ScenarioModel, Setup)> = setups()
        .par_iter()
        .filter_map(|s| model_for(model, s))
        .collect();
    // Per test: each rival's largest difference from the chosen explanation.
    let per_test: Vec<(Setup, Vec<Option<Largest>>)> = grid
        .par_iter()
        .map(|(m, s)| {
            let found = largest_difference(m)?;
            progress();
            Ok((s.clone(), found))
        })
        .collect::<Result<_, GapError>>()?;
    let noise = noise_um.max(1e-3);
    Ok(rivals
        .iter()
        .enumerate()
        .filter_map(|(k, r)| {
            let (setup, Largest { size, at, run }) = per_test
                .iter()
                .filter_map(|(s, found)| Some((s, found[k].clone()?)))
                .max_by(|a, b| a.1.size.total_cmp(&b.1.size))?;
            Some(Discrimination {
                rival: r.label.clone(),
                instead_of: r.instead_of.clone(),
                setup: setup.clone(),
                difference_um: size,
                at_deg: at.rem_euclid(360.0),
                run,
                place: place(&setup.plane, at),
                noise_um: noise,
                ratio: size / noise,
                on_measured_um: own[k].as_ref().map(|x| x.size),
            })
        })
        .collect())
}

/// The sample-to-sample noise of measured traces, µm: the median absolute first difference
/// over `0.6745·√2` (a robust σ of white noise; a smooth signal's differences are far smaller
/// at a bar's sample rate).
pub fn noise_of(measured: &[Trace]) -> f64 {
    let mut d: Vec<f64> = measured
        .iter()
        .flat_map(|t| t.deviation_um.windows(2).map(|w| (w[1] - w[0]).abs()))
        .collect();
    if d.is_empty() {
        return 0.0;
    }
    d.sort_by(f64::total_cmp);
    d[d.len() / 2] / (0.6745 * std::f64::consts::SQRT_2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_noise_of_white_noise_is_its_sigma() {
        // A deterministic uniform sequence (σ = 1/√12 of its unit width) is no Gaussian, so
        // the check is the Gaussian one: a Box–Muller sequence of σ = 0.3 µm.
        let mut state = 12345u64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let deviation_um: Vec<f64> = (0..20000)
            .map(|_| {
                let (u, v) = (uniform(), uniform());
                0.3 * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
            })
            .collect();
        let t = Trace {
            label: "t".into(),
            plane: Plane::Xy,
            sense: vmt_ballbar::Sense::Cw,
            radius_mm: 100.0,
            feed_mm_min: 1000.0,
            angle_deg: (0..20000).map(|i| i as f64 * 0.018).collect(),
            deviation_um,
            time_s: None,
        };
        let s = noise_of(&[t]);
        assert!((s - 0.3).abs() < 0.015, "{s}");
    }

    #[test]
    fn places_on_the_circle_are_named_by_their_reversals() {
        assert_eq!(place("XY", 3.0), "at the X reversals");
        assert_eq!(place("XY", 185.0), "at the X reversals");
        assert_eq!(place("ZX", 268.0), "at the X reversals");
        assert_eq!(place("ZX", 2.0), "at the Z reversals");
        assert_eq!(place("XY", 45.0), "between the reversals");
    }
}
