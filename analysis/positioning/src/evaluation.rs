//! The evaluation of a checked positioning test.
//!
//! - The ISO 230-2 figures (`vmt_model::iso230_2`).
//! - The linear trend of the mean bidirectional deviations `x̄_i = a + k·P_i` by least squares:
//!   `k` (µm/m, i.e. ppm) is the axis' scale error as the laser sees it (pitch error of the
//!   screw, thermal expansion, or the laser's own compensation error), and the span of
//!   `x̄_i − (a + k·P_i)` is the part of M no scale correction removes.
//! - The pitch-error compensation table: at each target the correction a controller adds to its
//!   command so that the mean positions land on the target, `c_i = −x̄_i` (bidirectional), and
//!   per direction `−x̄_i↑`, `−x̄_i↓` for controllers with direction-dependent tables (their
//!   difference is the reversal B_i a backlash compensation takes).

use crate::run::PositioningRun;
use serde::Serialize;
use vmt_model::iso230_2::{Deviation, Iso230_2};

/// What ISO 230-2 asks for: runs per target and direction, targets in all and per metre.
const STANDARD_RUNS: usize = 5;
const STANDARD_TARGETS: usize = 5;
const STANDARD_TARGETS_PER_M: f64 = 5.0;
/// Beyond this travel (m) the standard has another procedure (ISO 230-2:2014, 6.2).
const LONG_AXIS_M: f64 = 2.0;
/// A laser is zeroed at a datum target: mean deviations all this far from zero (µm) say it
/// was not, or that the readings carry an offset.
const NO_DATUM_UM: f64 = 100.0;
/// A machine axis repeats to no better than some tens of nm: readings whose whole span is
/// under this (µm) are most likely millimetres written as micrometres.
const TOO_FLAT_UM: f64 = 0.01;

/// Least-squares line through the mean bidirectional deviations.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Trend {
    /// Slope, µm/m (ppm).
    pub slope_um_per_m: f64,
    /// Value of the line at the first target, µm.
    pub at_first_target_um: f64,
    /// Span (max − min) of the deviations from the line, µm.
    pub residual_span_um: f64,
}

/// One row of the compensation table.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Compensation {
    /// Target position, mm.
    pub target_mm: f64,
    /// `−x̄_i`, µm.
    pub bidirectional_um: f64,
    /// `−x̄_i↑`, µm.
    pub forward_um: f64,
    /// `−x̄_i↓`, µm.
    pub backward_um: f64,
}

/// The evaluation of a positioning test.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Evaluation {
    /// The axis.
    pub axis: String,
    /// Fewest readings at a target and direction.
    pub runs: usize,
    /// The ISO 230-2 figures.
    pub iso230_2: Iso230_2,
    /// Linear trend of the mean bidirectional deviations.
    pub trend: Trend,
    /// Pitch-error compensation table.
    pub compensation: Vec<Compensation>,
    /// Where the test falls short of the standard's procedure (the figures are still those of
    /// its formulas).
    pub notes: Vec<String>,
}

/// Evaluates a checked test.
pub fn evaluate(run: &PositioningRun) -> Evaluation {
    let deviations: Vec<Deviation> = run
        .readings
        .iter()
        .map(|r| Deviation {
            target: run.target_index(r),
            approach: r.approach,
            deviation_um: r.deviation_um,
        })
        .collect();
    let iso = Iso230_2::evaluate(&run.targets_mm, &deviations);
    let bidirectional: Vec<f64> = iso
        .mean_forward_um
        .iter()
        .zip(&iso.mean_backward_um)
        .map(|(u, d)| 0.5 * (u + d))
        .collect();
    let trend = trend(&run.targets_mm, &bidirectional);
    let compensation = (0..run.targets_mm.len())
        .map(|i| Compensation {
            target_mm: run.targets_mm[i],
            bidirectional_um: -bidirectional[i],
            forward_um: -iso.mean_forward_um[i],
            backward_um: -iso.mean_backward_um[i],
        })
        .collect();
    let (runs, most) = run.runs_range();
    Evaluation {
        axis: run.axis.clone(),
        runs,
        notes: [notes(run, runs, most), offset_notes(run, &bidirectional)].concat(),
        iso230_2: iso,
        trend,
        compensation,
    }
}

/// Least-squares line `y = a + k x` (x in mm, y in µm), reported per metre.
fn trend(x_mm: &[f64], y_um: &[f64]) -> Trend {
    let n = x_mm.len() as f64;
    let mx = x_mm.iter().sum::<f64>() / n;
    let my = y_um.iter().sum::<f64>() / n;
    let sxx: f64 = x_mm.iter().map(|x| (x - mx).powi(2)).sum();
    let sxy: f64 = x_mm
        .iter()
        .zip(y_um)
        .map(|(x, y)| (x - mx) * (y - my))
        .sum();
    // Two distinct targets at least (checked), so sxx > 0.
    let k = sxy / sxx;
    let line = |x: f64| my + k * (x - mx);
    let residuals = x_mm.iter().zip(y_um).map(|(x, y)| y - line(*x));
    let (lo, hi) = residuals.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
        (lo.min(r), hi.max(r))
    });
    Trend {
        slope_um_per_m: k * 1e3,
        at_first_target_um: line(x_mm[0]),
        residual_span_um: hi - lo,
    }
}

/// Where the test departs from the standard's procedure.
fn notes(run: &PositioningRun, runs: usize, most: usize) -> Vec<String> {
    let mut notes = Vec::new();
    if runs < STANDARD_RUNS {
        notes.push(format!(
            "ISO 230-2 asks for {STANDARD_RUNS} runs per target and direction; the fewest here are {runs}, so s, R and A rest on fewer values"
        ));
    }
    if runs != most {
        notes.push(format!(
            "targets have between {runs} and {most} readings per direction; each is evaluated on its own"
        ));
    }
    let n = run.targets_mm.len();
    let travel_m = (run.targets_mm[n - 1] - run.targets_mm[0]) * 1e-3;
    if travel_m > LONG_AXIS_M {
        notes.push(format!(
            "the tested travel is {:.0} mm: ISO 230-2 (6.2) evaluates axes over 2000 mm from one approach per target and direction and defines neither repeatability nor the accuracy A for them; the figures here apply the procedure for axes up to 2000 mm to the whole travel",
            travel_m * 1e3
        ));
        return notes;
    }
    let wanted = STANDARD_TARGETS.max((STANDARD_TARGETS_PER_M * travel_m).ceil() as usize);
    if n < wanted {
        notes.push(format!(
            "ISO 230-2 asks for at least {STANDARD_TARGETS} targets and {STANDARD_TARGETS_PER_M} per metre ({wanted} over {:.0} mm); this test has {n}",
            travel_m * 1e3
        ));
    }
    notes
}

/// Readings that look offset or in the wrong unit (`bidirectional`: the mean bidirectional
/// deviation at each target, µm).
fn offset_notes(run: &PositioningRun, bidirectional: &[f64]) -> Vec<String> {
    let mut notes = Vec::new();
    let nearest = bidirectional
        .iter()
        .copied()
        .min_by(|a, b| a.abs().total_cmp(&b.abs()))
        .unwrap_or(0.0);
    if nearest.abs() > NO_DATUM_UM {
        notes.push(format!(
            "no target's mean deviation is within ±{NO_DATUM_UM} µm (the nearest is {nearest:+.1} µm): a laser is zeroed at a datum target, so the readings look offset; an offset passes whole into the compensation table, though A, B, E, M and R do not depend on it"
        ));
    }
    let (lo, hi) = run
        .readings
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
            (lo.min(r.deviation_um), hi.max(r.deviation_um))
        });
    if hi - lo < TOO_FLAT_UM {
        notes.push(format!(
            "every deviation lies within {:.4} µm of the others, less than a machine axis repeats to: if the values are in mm, write them in µm (deviation_um) or give reading_mm",
            hi - lo
        ));
    }
    notes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trend_of_a_line_is_exact() {
        let t = trend(&[0.0, 100.0, 300.0], &[1.0, 3.0, 7.0]);
        assert!((t.slope_um_per_m - 20.0).abs() < 1e-12);
        assert!((t.at_first_target_um - 1.0).abs() < 1e-12);
        assert!(t.residual_span_um.abs() < 1e-12);
    }
}
