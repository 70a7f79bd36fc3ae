//! Where along an axis the residual changes: a scan for one axis' error changing over a
//! stretch of its travel.
//!
//! A defect under a carriage's guide blocks (a rail-joint step) or a worn stretch of a screw
//! changes an axis' error over a stretch of its travel: one value before, another beyond, the
//! change spread over the length of what rides over it (a block's 80–120 mm). The peaks of
//! [`crate::peaks`] find features a few degrees wide; seen through a block, such a change is a
//! ramp over 60–90° of a 100 mm circle, which shows as no local feature. This scan fits the
//! change itself. For each axis `a` of the plane, each direction `d` of the plane, each place
//! `x0` and each width `w`, the model of every run's residual (µm)
//!
//! ```text
//! r(θ) = H · S((a(θ) − x0) / w) · n_d(θ) + Σ c_j b_j(θ, R)
//! S(u) = clamp(u + 1/2, 0, 1)                      a ramp from 0 to 1 across the width
//! a(θ) = c_a + R cos θ  (the plane's first axis),  c_a + R sin θ  (its second)
//! n_d  = cos θ, sin θ   (the bar's reading of an error along the first, the second axis)
//! ```
//!
//! is fitted by least squares over 1° bins of every run (all tests together: circles of other
//! radii about the centre see the same place at other angles), with the baseline `b_j`: the
//! bar's set-up and length, and the smooth shapes that errors of the whole travel give
//! (linear and quadratic in the axis positions, each scaled with the radius as it is), shared
//! by the tests as one bar on one pivot and one machine share them. The change found is the
//! `(a, d, x0, w)` that removes the most of what the baseline leaves; it is reported when it
//! removes at least [`MIN_SHARE`] of it and its height reaches the least change an effect must
//! make. Places every [`PLACE_STEP_MM`] over the positions the circles reach; widths
//! [`WIDTHS_MM`]. It says where, not what: a change found this way is no library effect, and
//! the gap it sits in stays unexplained.

use crate::align::TracePair;
use crate::peaks::Circle;
use nalgebra::{DMatrix, DVector};

/// Spacing of the places scanned, mm.
pub const PLACE_STEP_MM: f64 = 5.0;
/// Widths scanned, mm: a short defect, a guide block's length. Wider ramps are the smooth
/// shapes of the baseline over a 100 mm circle.
pub const WIDTHS_MM: [f64; 2] = [30.0, 100.0];
/// Least share of the residual's sum of squares the change must remove.
pub const MIN_SHARE: f64 = 0.5;

/// A change of one axis' error over a stretch of its travel.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct AxisChange {
    /// The axis along which it sits, e.g. `X`.
    pub axis: char,
    /// The direction of the error it changes, e.g. `X` (positioning) or `Y` (straightness).
    pub direction: char,
    /// The middle of the stretch, mm (axis coordinates).
    pub at_mm: f64,
    /// The stretch's length, mm.
    pub width_mm: f64,
    /// The change across it, µm.
    pub height_um: f64,
    /// The share of the residual's sum of squares it removes.
    pub share: f64,
}

impl std::fmt::Display for AxisChange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the {} error of {} changes by {:+.2} µm between {} {:.0} and {:.0} mm ({:.0} % of the residual)",
            self.direction,
            self.axis,
            self.height_um,
            self.axis,
            self.at_mm - 0.5 * self.width_mm,
            self.at_mm + 0.5 * self.width_mm,
            100.0 * self.share
        )
    }
}

/// One 1° bin of a run: its angle (rad), radius (mm), circle and mean residual (µm).
struct Bin {
    theta: f64,
    radius_mm: f64,
    centre: [f64; 2],
    r: f64,
}

/// The bins of `pairs` whose circle is known, in the plane's axis coordinates.
fn bins(pairs: &[TracePair], circles: &[Option<Circle>]) -> Vec<Bin> {
    let mut out = Vec::new();
    for (p, c) in pairs.iter().zip(circles) {
        let Some(c) = c else { continue };
        let (a, b) = p.plane.axes();
        let centre = [c.centre_mm[axis_index(a)], c.centre_mm[axis_index(b)]];
        let mut sum = [0.0; 360];
        let mut n = [0usize; 360];
        for (deg, r) in p.angle_deg.iter().zip(&p.residual_um) {
            let k = (deg.rem_euclid(360.0).floor() as usize).min(359);
            sum[k] += r;
            n[k] += 1;
        }
        for k in (0..360).filter(|k| n[*k] > 0) {
            out.push(Bin {
                theta: (k as f64 + 0.5).to_radians(),
                radius_mm: c.radius_mm,
                centre,
                r: sum[k] / n[k] as f64,
            });
        }
    }
    out
}

/// The index (0, 1, 2) of axis letter `c` (either case) in X, Y, Z coordinates; Z for a
/// letter that names none, as a plane's axes always do.
pub(crate) fn axis_index(c: char) -> usize {
    vmt_model::Axis::from_letter(c).map_or(2, |a| a.index())
}

/// The residual sum of squares of `y` fitted by the columns `a` (least squares), and the
/// coefficients; `None` when the columns are degenerate.
fn fit(a: &DMatrix<f64>, y: &DVector<f64>) -> Option<(f64, DVector<f64>)> {
    let ata = a.transpose() * a;
    let aty = a.transpose() * y;
    let beta = ata.cholesky()?.solve(&aty);
    let rss = (y - a * &beta).norm_squared();
    Some((rss, beta))
}

/// The columns of what is no local change: the bar's set-up and length (`cos θ`, `sin θ`,
/// `R`), and the smooth shapes of the axes' errors across the whole circle, linear and
/// quadratic in the axis positions (`R cos 2θ`, `R sin 2θ`: a scale or a squareness; `R² cos θ`,
/// `R² sin θ`, `R² cos 3θ`, `R² sin 3θ`: a bow), with the radius each scales with.
fn baseline(bins: &[Bin]) -> DMatrix<f64> {
    DMatrix::from_fn(bins.len(), BASELINE, |i, j| {
        let (t, r) = (bins[i].theta, bins[i].radius_mm);
        match j {
            0 => t.cos(),
            1 => t.sin(),
            2 => r,
            3 => r * (2.0 * t).cos(),
            4 => r * (2.0 * t).sin(),
            5 => r * r * t.cos(),
            6 => r * r * t.sin(),
            7 => r * r * (3.0 * t).cos(),
            _ => r * r * (3.0 * t).sin(),
        }
    })
}

/// Columns of [`baseline`].
const BASELINE: usize = 9;

/// The change of one axis' error that best explains the residual of `pairs` (module doc), if
/// one removes [`MIN_SHARE`] of its sum of squares and changes by at least `min_um`; the
/// pairs' circles (axis coordinates) are `circles`, one per pair.
pub fn scan(pairs: &[TracePair], circles: &[Option<Circle>], min_um: f64) -> Option<AxisChange> {
    let bins = bins(pairs, circles);
    let plane = pairs.first()?.plane;
    if bins.len() < 8 {
        return None;
    }
    let y = DVector::from_iterator(bins.len(), bins.iter().map(|b| b.r));
    let base = baseline(&bins);
    let (rss0, _) = fit(&base, &y)?;
    if rss0 <= 0.0 {
        return None;
    }
    let (pa, qa) = plane.axes();
    let mut best: Option<(f64, AxisChange)> = None;
    for (side, axis) in [(0, pa), (1, qa)] {
        let along = |b: &Bin| {
            let t = if side == 0 {
                b.theta.cos()
            } else {
                b.theta.sin()
            };
            b.centre[side] + b.radius_mm * t
        };
        let lo = bins.iter().map(along).fold(f64::INFINITY, f64::min);
        let hi = bins.iter().map(along).fold(f64::NEG_INFINITY, f64::max);
        let places = ((hi - lo) / PLACE_STEP_MM).floor() as usize;
        for (dir, direction) in [(0, pa), (1, qa)] {
            for w in WIDTHS_MM {
                for k in 0..=places {
                    let x0 = lo + k as f64 * PLACE_STEP_MM;
                    let mut a = base.clone().insert_column(BASELINE, 0.0);
                    for (i, b) in bins.iter().enumerate() {
                        let s = ((along(b) - x0) / w + 0.5).clamp(0.0, 1.0);
                        let n = if dir == 0 {
                            b.theta.cos()
                        } else {
                            b.theta.sin()
                        };
                        a[(i, BASELINE)] = s * n;
                    }
                    let Some((rss, beta)) = fit(&a, &y) else {
                        continue;
                    };
                    let share = 1.0 - rss / rss0;
                    if best.as_ref().is_none_or(|(s, _)| share > *s) {
                        best = Some((
                            share,
                            AxisChange {
                                axis,
                                direction,
                                at_mm: x0,
                                width_mm: w,
                                height_um: beta[BASELINE],
                                share,
                            },
                        ));
                    }
                }
            }
        }
    }
    best.map(|(_, c)| c)
        .filter(|c| c.share >= MIN_SHARE && c.height_um.abs() >= min_um)
}

/// The circle's angles (deg) at which it passes axis position `at_mm` of `axis`, for a test in
/// `plane` about `circle`.
pub fn angles_at(plane: vmt_ballbar::Plane, circle: &Circle, axis: char, at_mm: f64) -> Vec<f64> {
    let (a, b) = plane.axes();
    let u = (at_mm - circle.centre_mm[axis_index(axis)]) / circle.radius_mm;
    if u.abs() > 1.0 || (axis != a && axis != b) {
        return Vec::new();
    }
    let both = if axis == a {
        let t = u.acos();
        [t, -t]
    } else {
        let t = u.asin();
        [t, std::f64::consts::PI - t]
    };
    both.iter()
        .map(|t| t.to_degrees().rem_euclid(360.0))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use vmt_ballbar::{Plane, Sense};

    /// A run of a circle about `c` (X, Y) mm of radius `r` whose residual is `f(θ)` plus a
    /// set-up offset and noise-like ripple (a deterministic sum of sines, 0.05 µm).
    fn run(r: f64, f: impl Fn(f64) -> f64) -> TracePair {
        let angle_deg: Vec<f64> = (0..3600).map(|i| i as f64 * 0.1).collect();
        let residual_um = angle_deg
            .iter()
            .map(|d| {
                let t = d.to_radians();
                f(t) + 0.8 * t.cos() - 0.3 * t.sin() + 0.05 * (37.0 * t).sin()
            })
            .collect();
        TracePair {
            label: format!("R{r}"),
            plane: Plane::Xy,
            sense: Sense::Ccw,
            radius_mm: r,
            feed_mm_min: 2000.0,
            time_s: angle_deg.clone(),
            angle_deg,
            residual_um,
        }
    }

    /// A positioning error of X that ramps by 3 µm over 100 mm about X = 300 mm, seen by
    /// circles of 100 and 50 mm about (250, 200) mm: the bar reads e(x)·cos θ (written here from
    /// the ramp, independently of the scan's columns). The scan finds X, direction X, the place
    /// within a step of the scan, the width and the height.
    #[test]
    fn a_ramp_of_the_x_positioning_error_is_found_at_its_place() {
        let centre = [250.0, 200.0, 0.0];
        let ramp = |x: f64| 3.0 * ((x - 300.0) / 100.0 + 0.5).clamp(0.0, 1.0);
        let pairs: Vec<TracePair> = [100.0, 50.0]
            .iter()
            .map(|&r| run(r, |t| ramp(250.0 + r * t.cos()) * t.cos()))
            .collect();
        let circles: Vec<Option<Circle>> = pairs
            .iter()
            .map(|p| {
                Some(Circle {
                    centre_mm: centre,
                    radius_mm: p.radius_mm,
                })
            })
            .collect();
        let c = scan(&pairs, &circles, 0.15).expect("a change");
        assert_eq!((c.axis, c.direction), ('X', 'X'), "{c}");
        assert!((c.at_mm - 300.0).abs() <= PLACE_STEP_MM, "{c}");
        assert_eq!(c.width_mm, 100.0, "{c}");
        assert!((c.height_um - 3.0).abs() < 0.1, "{c}");
        assert!(c.share >= MIN_SHARE, "{c}");
        // The circles pass its middle at 60° and 300° (R100) and 0° (R50).
        let at = angles_at(Plane::Xy, &circles[0].unwrap(), 'X', c.at_mm);
        assert!(at.iter().any(|a| (a - 60.0).abs() < 3.5), "{at:?}");
    }

    /// A smooth residual of the whole circle (a scale mismatch, cos 2θ, and a bow) is no change
    /// along an axis: the scan reports none.
    #[test]
    fn smooth_shapes_are_no_change() {
        let pairs: Vec<TracePair> = [100.0, 50.0]
            .iter()
            .map(|&r| {
                run(r, |t| {
                    0.01 * r * (2.0 * t).cos() + 0.5 * (r / 100.0).powi(2) * (3.0 * t).sin()
                })
            })
            .collect();
        let circles: Vec<Option<Circle>> = pairs
            .iter()
            .map(|p| {
                Some(Circle {
                    centre_mm: [250.0, 200.0, 0.0],
                    radius_mm: p.radius_mm,
                })
            })
            .collect();
        assert_eq!(scan(&pairs, &circles, 0.15), None);
    }
}
