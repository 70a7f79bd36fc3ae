//! Where the residual between measured and simulated traces sits.
//!
//! The residual energy of run j is its mean square `E_j = mean(r²)` (µm²), so runs weigh the
//! same whatever their sample rate; the total is `E = Σ_j E_j`. Each decomposition splits `E`
//! into shares that add up to one:
//!
//! - **run**: `E_j / E`;
//! - **quadrant** of the angle (0–90°, 90–180°, …) and **reversal windows**: the sum of `r²/n_j`
//!   over the samples within `±w` of each axis reversal (the first axis `p = R cos θ` turns at
//!   0° and 180°, the second at 90° and 270°), the rest "between reversals";
//! - **direction**: CW and CCW runs of the same test, averaged into 1° bins on their common arc,
//!   split into the common part `(a+b)/2` and the reversing part `(a-b)/2`
//!   (`a² + b² = 2(c² + d²)`, so the two shares are exact);
//! - **harmonic order** k = 0…K of the angle, from a least-squares Fourier fit `ŷ = Σ_k f_k`
//!   of each full circle (≥ 300°), and the rest `y − ŷ` above K. Order k holds
//!   `mean(f_k ŷ)`: its own mean square plus half its overlap `2 mean(f_k f_j)` with each other
//!   order. The orders then add up to the fit's mean square and, the fit's residual being
//!   orthogonal to the fit, with the rest to the circle's `mean(y²)` exactly. On a whole turn
//!   the Fourier columns are orthogonal and the overlaps vanish; on an arc short of it they are
//!   not, and the fitted parts' own mean squares do not add up (2.31 against 0.63 µm² on a
//!   300° arc). The split leaves an order that is absent from the residual at nothing (a
//!   rotation to an orthonormal basis would smear every order into its neighbours on an arc);
//!   on noise an order's share may come out slightly below zero, its fitted part opposing
//!   the others'. On white noise of variance σ² each column still holds σ²/n on average
//!   (`E[c_i (Aᵀy)_i] = σ² ((AᵀA)⁻¹AᵀA)_ii`, c the coefficients, A the columns);
//! - **time**: the straight-line trend of each run in time (drift) and the rest.
//!
//! - **peaks**: the angles where the residual concentrates within a few degrees, with their
//!   width, share and the axis positions they correspond to ([`crate::peaks`]).
//!
//! Beside each share stands the share the same place would hold if the residual were spread
//! evenly (white noise): the fraction of samples for angles, one half for direction, `2/n` per
//! harmonic order (`1/n` for order 0), `1/n`·(fit size) for a trend. Their ratio is the place's
//! concentration; the places with a large share and a concentration well above one are where
//! the gap sits.

use crate::align::{GapError, TracePair};
use crate::axis_change::AxisChange;
use crate::peaks::{AxisPlace, Circle, Peak, axis_places, peaks};
use crate::whiteness::{Whiteness, ljung_box};
use nalgebra::{DMatrix, DVector};
use vmt_ballbar::Sense;

/// Settings of the localisation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Half width of a window around an axis reversal, deg.
    pub reversal_window_deg: f64,
    /// Highest harmonic order fitted, K.
    pub max_order: usize,
    /// Lags of the whiteness test.
    pub whiteness_lags: usize,
    /// Width of the bins the leftover residual is averaged into for the whiteness test, deg.
    pub whiteness_bin_deg: f64,
    /// A place is reported as a concentration when its share is at least this…
    pub min_share: f64,
    /// …and its concentration at least this.
    pub min_concentration: f64,
    /// Least RMS of a peak of the high-passed residual, µm ([`crate::peaks`]).
    pub min_peak_um: f64,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            reversal_window_deg: 5.0,
            max_order: 8,
            whiteness_lags: 20,
            whiteness_bin_deg: 1.0,
            min_share: 0.15,
            min_concentration: 1.6,
            min_peak_um: 0.15,
        }
    }
}

/// One place of a decomposition.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Place {
    /// The decomposition: `run`, `quadrant`, `reversal`, `direction`, `harmonic`, `time`.
    pub kind: &'static str,
    /// What the place is, e.g. `X reversal at 90°`, `order 2`, `CW - CCW`.
    pub name: String,
    /// Its share of the residual energy, 0…1 (a harmonic order's may dip slightly below zero on
    /// an arc; see the module doc).
    pub share: f64,
    /// The share it would hold if the residual were white noise.
    pub expected: f64,
}

impl Place {
    /// Share over expected share.
    pub fn concentration(&self) -> f64 {
        if self.expected > 0.0 {
            self.share / self.expected
        } else {
            f64::INFINITY
        }
    }
}

/// The localised residual.
#[derive(Clone, Debug, PartialEq)]
pub struct Localisation {
    /// RMS of the residual over all runs (root of the mean of the runs' mean squares), µm.
    pub rms_um: f64,
    /// Per run.
    pub by_run: Vec<Place>,
    /// Per quadrant of the angle.
    pub by_quadrant: Vec<Place>,
    /// Per axis-reversal window, and between reversals.
    pub by_reversal: Vec<Place>,
    /// Common and reversing parts of CW/CCW pairs (empty without a pair).
    pub by_direction: Vec<Place>,
    /// Per harmonic order (empty without a full circle).
    pub by_harmonic: Vec<Place>,
    /// Drift within runs, and the rest.
    pub by_time: Vec<Place>,
    /// The places where the residual concentrates, largest share first.
    pub concentrations: Vec<Place>,
    /// Whiteness of what is left after the harmonic fit (full circles) or the trend (arcs).
    pub whiteness: Option<Whiteness>,
    /// The angles where the residual concentrates within a few degrees, largest share first.
    pub peaks: Vec<Peak>,
    /// Places on an axis the circle passes twice with a peak at both passes.
    pub axis_places: Vec<AxisPlace>,
    /// Where along an axis its error changes over a stretch of the travel, when the circles
    /// are known and such a change explains most of the residual ([`crate::axis_change`]).
    pub axis_change: Option<AxisChange>,
}

impl Localisation {
    /// Localises the residual of `pairs` (peaks without axis positions).
    pub fn of(pairs: &[TracePair], o: &Options) -> Result<Self, GapError> {
        Self::on_circles(pairs, &[], o)
    }

    /// Localises the residual of `pairs` whose circles (per pair, in axis coordinates) are
    /// `circles`: the peaks are also given as axis positions.
    pub fn on_circles(
        pairs: &[TracePair],
        circles: &[Option<Circle>],
        o: &Options,
    ) -> Result<Self, GapError> {
        if pairs.is_empty() {
            return Err(GapError::Empty);
        }
        let energies: Vec<f64> = pairs.iter().map(TracePair::mean_square).collect();
        let total: f64 = energies.iter().sum();
        let by_run = pairs
            .iter()
            .zip(&energies)
            .map(|(p, e)| Place {
                kind: "run",
                name: p.label.clone(),
                share: ratio(*e, total),
                expected: 1.0 / pairs.len() as f64,
            })
            .collect();
        let by_quadrant = angular(pairs, total, &quadrants());
        let by_reversal = angular(
            pairs,
            total,
            &reversal_windows(pairs, o.reversal_window_deg),
        );
        let by_direction = direction(pairs);
        let (by_harmonic, leftovers) = harmonics(pairs, o);
        let by_time = drift(pairs, total);
        let whiteness = ljung_box(
            &binned(pairs, &leftovers, o.whiteness_bin_deg),
            o.whiteness_lags,
        );
        let mut concentrations: Vec<Place> = [
            &by_quadrant,
            &by_reversal,
            &by_direction,
            &by_harmonic,
            &by_time,
        ]
        .into_iter()
        .flatten()
        .filter(|p| p.share >= o.min_share && p.concentration() >= o.min_concentration)
        .cloned()
        .collect();
        concentrations.sort_by(|a, b| b.share.total_cmp(&a.share));
        let peaks = peaks(pairs, circles, o.min_peak_um);
        let axis_places = axis_places(&peaks, pairs, circles);
        let axis_change = crate::axis_change::scan(pairs, circles, o.min_peak_um);
        Ok(Self {
            peaks,
            axis_places,
            axis_change,
            rms_um: (total / pairs.len() as f64).sqrt(),
            by_run,
            by_quadrant,
            by_reversal,
            by_direction,
            by_harmonic,
            by_time,
            concentrations,
            whiteness,
        })
    }
}

fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 { a / b } else { 0.0 }
}

/// A named set of angle windows `(name, [(from, to)] deg mod 360)`; samples in none of them
/// fall in the last, catch-all window `(name, [])`.
type Windows = Vec<(String, Vec<(f64, f64)>)>;

fn quadrants() -> Windows {
    (0..4)
        .map(|k| {
            let a = 90.0 * k as f64;
            (format!("{a:.0}-{:.0}°", a + 90.0), vec![(a, a + 90.0)])
        })
        .collect()
}

fn reversal_windows(pairs: &[TracePair], w: f64) -> Windows {
    let (p, q) = pairs[0].plane.axes();
    let mut windows: Windows = [(p, 0.0), (p, 180.0), (q, 90.0), (q, 270.0)]
        .into_iter()
        .map(|(axis, at)| {
            (
                format!("{axis} reversal at {at:.0}°"),
                vec![(at - w, at + w)],
            )
        })
        .collect();
    windows.push(("between reversals".into(), Vec::new()));
    windows
}

fn in_window(angle: f64, (from, to): (f64, f64)) -> bool {
    (angle - from).rem_euclid(360.0) < to - from
}

/// Shares of the energy and of the samples in each window.
fn angular(pairs: &[TracePair], total: f64, windows: &Windows) -> Vec<Place> {
    let mut energy = vec![0.0; windows.len()];
    let mut count = vec![0.0; windows.len()];
    for p in pairs {
        let n = p.residual_um.len() as f64;
        for (a, r) in p.angle_deg.iter().zip(&p.residual_um) {
            let k = windows
                .iter()
                .position(|(_, ws)| ws.iter().any(|w| in_window(*a, *w)))
                .unwrap_or(windows.len() - 1);
            energy[k] += r * r / n;
            count[k] += 1.0 / n;
        }
    }
    windows
        .iter()
        .enumerate()
        .map(|(k, (name, _))| Place {
            kind: if windows.len() == 4 {
                "quadrant"
            } else {
                "reversal"
            },
            name: name.clone(),
            share: ratio(energy[k], total),
            expected: count[k] / pairs.len() as f64,
        })
        .collect()
}

/// The residual of a run averaged into 1° bins, keyed by the bin's lower edge in 0…360°.
fn bins(p: &TracePair) -> std::collections::BTreeMap<i64, (f64, usize)> {
    let mut b = std::collections::BTreeMap::new();
    for (a, r) in p.angle_deg.iter().zip(&p.residual_um) {
        let e: &mut (f64, usize) = b.entry(a.rem_euclid(360.0).floor() as i64).or_default();
        e.0 += r;
        e.1 += 1;
    }
    b
}

fn direction(pairs: &[TracePair]) -> Vec<Place> {
    let (mut common, mut reversing) = (0.0, 0.0);
    let same = |p: &TracePair, q: &TracePair| {
        p.plane == q.plane && p.radius_mm == q.radius_mm && p.feed_mm_min == q.feed_mm_min
    };
    let cws: Vec<&TracePair> = pairs.iter().filter(|p| p.sense == Sense::Cw).collect();
    for (i, cw) in cws.iter().enumerate() {
        // The k-th CW run of a test with its k-th CCW run: the same test about the k-th of
        // several centres, in the order the job runs them.
        let k = cws[..i].iter().filter(|p| same(p, cw)).count();
        let Some(ccw) = pairs
            .iter()
            .filter(|p| p.sense == Sense::Ccw && same(p, cw))
            .nth(k)
        else {
            continue;
        };
        let (a, b) = (bins(cw), bins(ccw));
        let (mut c2, mut d2, mut n) = (0.0, 0.0, 0.0);
        for (k, (sa, na)) in &a {
            if let Some((sb, nb)) = b.get(k) {
                let (x, y) = (sa / *na as f64, sb / *nb as f64);
                c2 += ((x + y) / 2.0).powi(2);
                d2 += ((x - y) / 2.0).powi(2);
                n += 1.0;
            }
        }
        if n > 0.0 {
            common += c2 / n;
            reversing += d2 / n;
        }
    }
    let total = common + reversing;
    if total <= 0.0 {
        return Vec::new();
    }
    vec![
        Place {
            kind: "direction",
            name: "common to CW and CCW".into(),
            share: common / total,
            expected: 0.5,
        },
        Place {
            kind: "direction",
            name: "reversing with direction (CW - CCW)".into(),
            share: reversing / total,
            expected: 0.5,
        },
    ]
}

/// Whether a run covers a full circle (at least 300°).
fn full_circle(p: &TracePair) -> bool {
    let a = &p.angle_deg;
    (a[a.len() - 1] - a[0]).abs() >= 300.0
}

/// Least-squares fit of `columns` to `y`: the fitted values, or `None` if singular.
fn fit(columns: &[Vec<f64>], y: &[f64]) -> Option<Vec<Vec<f64>>> {
    let m = columns.len();
    let ata = DMatrix::from_fn(m, m, |i, j| {
        columns[i]
            .iter()
            .zip(&columns[j])
            .map(|(a, b)| a * b)
            .sum::<f64>()
    });
    let aty = DVector::from_fn(m, |i, _| {
        columns[i].iter().zip(y).map(|(a, b)| a * b).sum::<f64>()
    });
    let coef = ata.cholesky()?.solve(&aty);
    Some(
        columns
            .iter()
            .zip(coef.iter())
            .map(|(c, k)| c.iter().map(|v| v * k).collect())
            .collect(),
    )
}

fn mean_square(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64
}

/// Shares per harmonic order over the full circles, and each run's residual left after its
/// Fourier fit (full circles) or straight line in time (arcs).
fn harmonics(pairs: &[TracePair], o: &Options) -> (Vec<Place>, Vec<Vec<f64>>) {
    let k_max = o.max_order;
    let mut energy = vec![0.0; k_max + 2];
    let mut expected = vec![0.0; k_max + 2];
    let mut full = 0;
    // The full circles' residual energy, Σ mean(y²), which the orders and the rest add up to.
    let mut circles = 0.0;
    let mut leftovers = Vec::with_capacity(pairs.len());
    for p in pairs {
        let n = p.residual_um.len();
        if !full_circle(p) || n < 4 * (2 * k_max + 1) {
            leftovers.push(detrended(p));
            continue;
        }
        let mut columns = vec![vec![1.0; n]];
        for k in 1..=k_max {
            let (c, s): (Vec<f64>, Vec<f64>) = p
                .angle_deg
                .iter()
                .map(|a| (k as f64 * a.to_radians()).sin_cos())
                .map(|(s, c)| (c, s))
                .unzip();
            columns.push(c);
            columns.push(s);
        }
        let Some(parts) = fit(&columns, &p.residual_um) else {
            leftovers.push(detrended(p));
            continue;
        };
        full += 1;
        circles += mean_square(&p.residual_um);
        let mut fitted = vec![0.0; n];
        for part in &parts {
            fitted.iter_mut().zip(part).for_each(|(f, v)| *f += v);
        }
        // Each order's part times the whole fit: the overlaps of non-orthogonal columns (arcs)
        // shared out, so the orders add up to mean(ŷ²) (module doc).
        for (i, part) in parts.iter().enumerate() {
            let order = i.div_ceil(2);
            energy[order] += part.iter().zip(&fitted).map(|(a, b)| a * b).sum::<f64>() / n as f64;
        }
        let left: Vec<f64> = p
            .residual_um
            .iter()
            .zip(&fitted)
            .map(|(y, f)| y - f)
            .collect();
        energy[k_max + 1] += mean_square(&left);
        for (order, e) in expected.iter_mut().enumerate().take(k_max + 1) {
            *e += if order == 0 { 1.0 } else { 2.0 } / n as f64;
        }
        expected[k_max + 1] += 1.0 - (2 * k_max + 1) as f64 / n as f64;
        leftovers.push(left);
    }
    if full == 0 {
        return (Vec::new(), leftovers);
    }
    // Shares of the full circles' residual energy: they add up to one because the split is
    // exact, not because they are normalised to their sum.
    let places = (0..=k_max + 1)
        .map(|k| Place {
            kind: "harmonic",
            name: if k <= k_max {
                format!("order {k}")
            } else {
                format!("orders above {k_max}")
            },
            share: ratio(energy[k], circles),
            expected: expected[k] / full as f64,
        })
        .collect();
    (places, leftovers)
}

/// A run's residual less its straight line in time.
fn detrended(p: &TracePair) -> Vec<f64> {
    let columns = [vec![1.0; p.time_s.len()], p.time_s.clone()];
    match fit(&columns, &p.residual_um) {
        Some(parts) => p
            .residual_um
            .iter()
            .enumerate()
            .map(|(i, r)| r - parts[0][i] - parts[1][i])
            .collect(),
        None => p.residual_um.clone(),
    }
}

/// Drift within each run (the slope part of its straight line in time) and the rest.
fn drift(pairs: &[TracePair], total: f64) -> Vec<Place> {
    let mut trend = 0.0;
    let mut expected = 0.0;
    for p in pairs {
        let t_mean = p.time_s.iter().sum::<f64>() / p.time_s.len() as f64;
        let centred: Vec<f64> = p.time_s.iter().map(|t| t - t_mean).collect();
        if let Some(parts) = fit(&[centred], &p.residual_um) {
            trend += mean_square(&parts[0]);
        }
        expected += 1.0 / p.time_s.len() as f64;
    }
    let share = ratio(trend, total);
    let expected = expected / pairs.len() as f64;
    vec![
        Place {
            kind: "time",
            name: "drift within runs".into(),
            share,
            expected,
        },
        Place {
            kind: "time",
            name: "steady in time".into(),
            share: 1.0 - share,
            expected: 1.0 - expected,
        },
    ]
}

/// Each run's leftover averaged into bins of `width` deg, in the run's order.
fn binned(pairs: &[TracePair], leftovers: &[Vec<f64>], width: f64) -> Vec<Vec<f64>> {
    pairs
        .iter()
        .zip(leftovers)
        .map(|(p, left)| {
            let mut out = Vec::new();
            let (mut sum, mut n, mut bin) = (0.0, 0usize, None);
            for (a, r) in p.angle_deg.iter().zip(left) {
                let b = (a / width).floor() as i64;
                if bin.is_some_and(|x| x != b) {
                    out.push(sum / n as f64);
                    (sum, n) = (0.0, 0);
                }
                bin = Some(b);
                sum += r;
                n += 1;
            }
            if n > 0 {
                out.push(sum / n as f64);
            }
            out
        })
        .collect()
}
