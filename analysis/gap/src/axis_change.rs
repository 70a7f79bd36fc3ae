//! Where along an axis the residual changes: a scan for one axis' error changing over a
//! stretch of its travel.
//!
//! A defect under a carriage's guide blocks (a rail-joint step) or a worn stretch of a screw
//! changes an axis' error over a stretch of its travel: one value before, another beyond, the
//! change spread over the length of what rides over it (a block's 80–120 mm). The peaks of
//! [`crate::peaks`] find features a few degrees wide; seen through a block, such a change is a
//! ramp over 60–90° of a 100 mm circle, which shows as no local feature. A short defect (a
//! bump) seen through a block changes the error and brings it back: up while the block rides
//! onto it, level while the block is over it, down as it leaves. This scan fits the change
//! itself. For each axis `a` of the plane, each direction `d` of the plane, each place
//! `x0` and each width `w`, the model of every run's residual (µm)
//!
//! ```text
//! r(θ) = H · S((a(θ) − x0) / w) · n_d(θ) + Σ c_j b_j(θ, R)
//! S(u) = clamp(u + 1/2, 0, 1)                      a ramp from 0 to 1 across the width
//!        (or a bump: up over 30 mm, level, down over 30 mm, 130 mm in all; `BLOCK_MM`)
//! a(θ) = c_a + R cos θ  (the plane's first axis),  c_a + R sin θ  (its second)
//! n_d  = cos θ, sin θ   (the bar's reading of an error along the first, the second axis)
//! ```
//!
//! is fitted by least squares over 1° bins of every run (all tests together: circles of other
//! radii, or about other centres, see the same place at other angles), with the baseline
//! `b_j`: the bar's set-up on each centre's pivot, its length, and the smooth shapes that
//! errors of the whole travel give (linear and quadratic in the axis positions), one function
//! of the position for every circle as one machine has them, and, where the caller gives them,
//! the shapes of the other effects the model can have ([`scan_beyond`]). The change found is the
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
/// The length of what rides over a defect, mm: a guide block's. A short defect (a bump
/// [`WIDTHS_MM`]`[0]` wide) seen through a block changes the error over the block's length
/// plus its own and back: a trapezoid, up over the defect's width, level while the block is
/// over it, down over its width again ([`AxisChange::comes_back`]).
pub const BLOCK_MM: f64 = 100.0;
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
    /// Whether the error comes back beyond the stretch (a bump under a block: its height is
    /// the change while the block is over it), or keeps the change (a step).
    pub comes_back: bool,
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
        )?;
        if self.comes_back {
            write!(f, ", and back")?;
        }
        Ok(())
    }
}

/// One 1° bin of a run: its angle (rad), radius (mm), circle and mean residual (µm); the run's
/// index and the bin's degree, `⌊angle⌋ mod 360`.
struct Bin {
    theta: f64,
    radius_mm: f64,
    centre: [f64; 2],
    r: f64,
    run: usize,
    degree: usize,
}

/// The bins of `pairs` whose circle is known, in the plane's axis coordinates.
fn bins(pairs: &[TracePair], circles: &[Option<Circle>]) -> Vec<Bin> {
    let mut out = Vec::new();
    for (run, (p, c)) in pairs.iter().zip(circles).enumerate() {
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
                run,
                degree: k,
            });
        }
    }
    out
}

/// The positions along the plane's first (`side` 0) or second axis that the runs of `pairs`
/// with a known circle reach, lowest and highest, mm; none without such a run.
pub fn reach(pairs: &[TracePair], circles: &[Option<Circle>], side: usize) -> Option<(f64, f64)> {
    let along: Vec<f64> = bins(pairs, circles)
        .iter()
        .map(|b| position(b, side))
        .collect();
    let lo = along.iter().copied().reduce(f64::min)?;
    let hi = along.iter().copied().reduce(f64::max)?;
    Some((lo, hi))
}

/// The change's profile at `x` mm from its middle, over `width` mm: a ramp from 0 to 1, or
/// (`comes_back`) up over [`WIDTHS_MM`]`[0]`, level, and down again over as much.
fn profile(x: f64, width: f64, comes_back: bool) -> f64 {
    let ramp = |x: f64, w: f64| (x / w + 0.5).clamp(0.0, 1.0);
    if comes_back {
        let (w, half) = (WIDTHS_MM[0], 0.5 * (width - WIDTHS_MM[0]));
        ramp(x + half, w) - ramp(x - half, w)
    } else {
        ramp(x, width)
    }
}

/// The orthonormal columns `q` (a basis of the baseline) with the part of each of `shapes` on
/// `bins` they leave, normalised, added in turn: Gram–Schmidt, twice for rounding. A shape
/// whose part left is under 10⁻⁶ of its norm (one the columns already span, or none on these
/// bins) is left out.
fn with_shapes(q: DMatrix<f64>, bins: &[Bin], shapes: &[Shape]) -> DMatrix<f64> {
    let mut columns: Vec<DVector<f64>> = q.column_iter().map(|c| c.into_owned()).collect();
    for shape in shapes {
        let v = DVector::from_iterator(
            bins.len(),
            bins.iter()
                .map(|b| shape.get(b.run).map_or(0.0, |d| d[b.degree])),
        );
        let norm = v.norm();
        let mut left = v;
        for _ in 0..2 {
            for c in &columns {
                left -= c * c.dot(&left);
            }
        }
        if norm > 0.0 && left.norm() > 1e-6 * norm {
            let unit = left.normalize();
            columns.push(unit);
        }
    }
    DMatrix::from_columns(&columns)
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

/// The columns of what is no local change: the bar's set-up on each centre's pivot (`cos θ`,
/// `sin θ` of that centre's runs), its length (`R`), and the smooth shapes of the axes' errors
/// over the whole travel, linear and quadratic in the axis positions, the same function of the
/// position for every circle: linear, `R cos 2θ` and `R sin 2θ` (a scale or a squareness; the
/// rest of a linear error is the set-up); quadratic (a bow), `u_a(θ)² n_d(θ)` for each axis `a`
/// and direction `d` of the plane, `u_a` the axis position from the circles' mean, in 100 mm.
/// About one centre these span `R² cos θ`, `R² sin θ`, `R² cos 3θ`, `R² sin 3θ` beside the
/// set-up and the linear shapes; about several, a bow also tilts each circle by its own
/// offset from the middle, which the quadratic columns carry as one error of the machine.
/// `degree` 3 adds the cubic shapes, `u_a(θ)³ n_d(θ)` (a positioning error's S).
fn baseline(bins: &[Bin], degree: i32) -> DMatrix<f64> {
    let centres = crate::peaks::once_each(bins.iter().map(|b| b.centre));
    let n = bins.len().max(1) as f64;
    let mean = |side: usize| bins.iter().map(|b| position(b, side)).sum::<f64>() / n;
    let middle = [mean(0), mean(1)];
    let own = 2 * centres.len();
    let powers = (degree.max(1) - 1) as usize;
    DMatrix::from_fn(bins.len(), own + 3 + 4 * powers, |i, j| {
        let b = &bins[i];
        let (t, r) = (b.theta, b.radius_mm);
        let n_d = |d: usize| if d == 0 { t.cos() } else { t.sin() };
        let u = |a: usize| (position(b, a) - middle[a]) / 100.0;
        match j {
            j if j < own => {
                let here = centres[j / 2] == b.centre;
                if here { n_d(j % 2) } else { 0.0 }
            }
            j if j == own => r,
            j if j == own + 1 => r * (2.0 * t).cos(),
            j if j == own + 2 => r * (2.0 * t).sin(),
            j => {
                let k = j - own - 3;
                let power = 2 + (k / 4) as i32;
                u((k % 4) / 2).powi(power) * n_d(k % 2)
            }
        }
    })
}

/// Bin `b`'s position along the plane's first (`side` 0) or second axis, mm.
fn position(b: &Bin, side: usize) -> f64 {
    let t = if side == 0 {
        b.theta.cos()
    } else {
        b.theta.sin()
    };
    b.centre[side] + b.radius_mm * t
}

/// The change of one axis' error that best explains the residual of `pairs` (module doc), if
/// one removes [`MIN_SHARE`] of its sum of squares and changes by at least `min_um`; the
/// pairs' circles (axis coordinates) are `circles`, one per pair.
pub fn scan(pairs: &[TracePair], circles: &[Option<Circle>], min_um: f64) -> Option<AxisChange> {
    scan_beyond(pairs, circles, min_um, 2, &[])
}

/// A shape the baseline of [`scan_beyond`] holds besides its own: per run of its pairs, the
/// value at each degree of the angle (`⌊angle⌋ mod 360`), µm per unit of its parameter.
pub type Shape = Vec<[f64; 360]>;

/// [`scan`] against smooth shapes up to power `degree` of the axis positions (2: a bow; 3: a
/// positioning error's S too, as the library's `positioning_{a}` has it) and the `other`
/// shapes beside them (the other effects a model can have, whose mismatch is in the residual
/// too): the change's share is then of what all of them leave. A shape the others already
/// span adds nothing.
pub fn scan_beyond(
    pairs: &[TracePair],
    circles: &[Option<Circle>],
    min_um: f64,
    degree: i32,
    other: &[Shape],
) -> Option<AxisChange> {
    let bins = bins(pairs, circles);
    let plane = pairs.first()?.plane;
    if bins.len() < 8 {
        return None;
    }
    let y = DVector::from_iterator(bins.len(), bins.iter().map(|b| b.r));
    let base = baseline(&bins, degree);
    // Degenerate circles (too few, or all alike) leave the baseline without a fit.
    fit(&base, &y)?;
    // What the baseline leaves of the residual, and of each ramp's column: a ramp's least
    // squares height beside the baseline is `(s⊥·r₀)/(s⊥·s⊥)` and it removes `(s⊥·r₀)²/(s⊥·s⊥)`
    // of the sum of squares, the same as refitting the baseline with the column added.
    let q = with_shapes(base.qr().q(), &bins, other);
    let leave = |v: &DVector<f64>| v - &q * (q.transpose() * v);
    let r0 = leave(&y);
    let rss0 = r0.norm_squared();
    if rss0 <= 0.0 {
        return None;
    }
    let (pa, qa) = plane.axes();
    let mut best: Option<(f64, AxisChange)> = None;
    for (side, axis) in [(0, pa), (1, qa)] {
        let along = |b: &Bin| position(b, side);
        let lo = bins.iter().map(along).fold(f64::INFINITY, f64::min);
        let hi = bins.iter().map(along).fold(f64::NEG_INFINITY, f64::max);
        let places = ((hi - lo) / PLACE_STEP_MM).floor() as usize;
        for (dir, direction) in [(0, pa), (1, qa)] {
            // Steps of each width, and a short defect's bump seen through a block.
            let profiles = WIDTHS_MM
                .map(|w| (w, false))
                .into_iter()
                .chain([(BLOCK_MM + WIDTHS_MM[0], true)]);
            for (w, comes_back) in profiles {
                for k in 0..=places {
                    let x0 = lo + k as f64 * PLACE_STEP_MM;
                    let ramp = DVector::from_iterator(
                        bins.len(),
                        bins.iter().map(|b| {
                            let n = if dir == 0 {
                                b.theta.cos()
                            } else {
                                b.theta.sin()
                            };
                            profile(along(b) - x0, w, comes_back) * n
                        }),
                    );
                    let own = leave(&ramp);
                    let (ss, sr) = (own.norm_squared(), own.dot(&r0));
                    // A ramp the baseline already holds changes nothing.
                    if ss <= 1e-12 * ramp.norm_squared() {
                        continue;
                    }
                    let share = sr * sr / ss / rss0;
                    if best.as_ref().is_none_or(|(s, _)| share > *s) {
                        best = Some((
                            share,
                            AxisChange {
                                axis,
                                direction,
                                at_mm: x0,
                                width_mm: w,
                                height_um: sr / ss,
                                share,
                                comes_back,
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

    /// Circles of `radii` about each of `centres` (X, Y mm), each run's residual `f(x, θ)` of
    /// the X position and the angle, with its circle.
    fn runs_about(
        centres: &[[f64; 2]],
        radii: &[f64],
        f: impl Fn(f64, f64) -> f64,
    ) -> (Vec<TracePair>, Vec<Option<Circle>>) {
        let mut pairs = Vec::new();
        let mut circles = Vec::new();
        for &[cx, cy] in centres {
            for &r in radii {
                pairs.push(run(r, |t| f(cx + r * t.cos(), t)));
                circles.push(Some(Circle {
                    centre_mm: [cx, cy, 0.0],
                    radius_mm: r,
                }));
            }
        }
        (pairs, circles)
    }

    /// A positioning error of X that ramps by 3 µm over 100 mm about X = 300 mm: the bar reads
    /// e(x)·cos θ (written here from the ramp, independently of the scan's columns).
    fn ramp(x: f64, t: f64) -> f64 {
        3.0 * ((x - 300.0) / 100.0 + 0.5).clamp(0.0, 1.0) * t.cos()
    }

    /// The ramp seen by circles of 100 and 50 mm about (250, 200) mm and about (330, 240) mm,
    /// each centre with its own set-up: the scan finds X, direction X, the place within a step
    /// of the scan, the width and the height.
    #[test]
    fn a_ramp_of_the_x_positioning_error_is_found_at_its_place() {
        let (pairs, circles) = runs_about(&[[250.0, 200.0], [330.0, 240.0]], &[100.0, 50.0], ramp);
        let c = scan(&pairs, &circles, 0.15).expect("a change");
        assert_eq!((c.axis, c.direction), ('X', 'X'), "{c}");
        assert!((c.at_mm - 300.0).abs() <= PLACE_STEP_MM, "{c}");
        assert_eq!(c.width_mm, 100.0, "{c}");
        assert!((c.height_um - 3.0).abs() < 0.1, "{c}");
        assert!(c.share >= MIN_SHARE, "{c}");
        // The first circles pass its middle at 60° and 300° (R100) and 0° (R50).
        let at = angles_at(Plane::Xy, &circles[0].unwrap(), 'X', c.at_mm);
        assert!(at.iter().any(|a| (a - 60.0).abs() < 3.5), "{at:?}");
    }

    /// About one centre the ramp, which starts at the centre (X = 250 mm), cannot be told from
    /// its mirror image through the centre (a ramp about X = 200 mm, ending there). On a circle
    /// of `R` ≤ 100 mm about X = 250 mm the ramp reads `max(0, R cos θ/100) cos θ`, which is
    /// `(R/200) cos² θ` (a scale, in the baseline) plus `(R/200)|cos θ| cos θ`; the mirror reads
    /// `cos θ − (R/100)|cos θ| cos θ` more, so beside the baseline both are multiples of the one
    /// column `R|cos θ| cos θ` and remove the same share, to rounding. About a second centre the
    /// identity fails and the right place removes more.
    #[test]
    fn about_one_centre_a_ramp_and_its_mirror_fit_alike() {
        let share = |centres: &[[f64; 2]], x0: f64, h: f64| {
            let (pairs, circles) = runs_about(centres, &[100.0, 50.0], ramp);
            let bins = bins(&pairs, &circles);
            let y = DVector::from_iterator(bins.len(), bins.iter().map(|b| b.r));
            let base = baseline(&bins, 2);
            let (rss0, _) = fit(&base, &y).unwrap();
            let n = base.ncols();
            let mut a = base.insert_column(n, 0.0);
            for (i, b) in bins.iter().enumerate() {
                a[(i, n)] =
                    h * ((position(b, 0) - x0) / 100.0 + 0.5).clamp(0.0, 1.0) * b.theta.cos();
            }
            1.0 - fit(&a, &y).unwrap().0 / rss0
        };
        let one = [[250.0, 200.0]];
        assert!((share(&one, 300.0, 3.0) - share(&one, 200.0, -3.0)).abs() < 1e-9);
        let two = [[250.0, 200.0], [330.0, 240.0]];
        let (right, mirror) = (share(&two, 300.0, 3.0), share(&two, 200.0, -3.0));
        assert!(
            right > 0.95 && mirror < right - 0.05,
            "{right} against {mirror}"
        );
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

    /// A lost motion of 4 µm at X's reversals (the bar reads `±2 sign(−sin θ) cos θ` µm for
    /// a CCW run, written here from the mechanism, not from the scan's columns) beside the
    /// 3 µm ramp: against the smooth shapes alone the ramp leaves most of the residual to the
    /// lost motion and falls under the scan's share; with the lost motion's shape beside them
    /// (the other effects a model can have) the share is of what those leave, and the ramp is
    /// found at its place and height.
    #[test]
    fn another_effects_mismatch_is_left_to_its_shape() {
        let lost = |t: f64| 2.0 * (-t.sin()).signum() * t.cos();
        let both = |x: f64, t: f64| ramp(x, t) + lost(t);
        let (pairs, circles) = runs_about(&[[250.0, 200.0], [330.0, 240.0]], &[100.0, 50.0], both);
        let alone = scan_beyond(&pairs, &circles, 0.15, 3, &[]);
        assert!(alone.is_none(), "{alone:?}");
        let shape: Shape = pairs
            .iter()
            .map(|_| std::array::from_fn(|d| lost((d as f64 + 0.5).to_radians())))
            .collect();
        let c = scan_beyond(&pairs, &circles, 0.15, 3, &[shape]).expect("a change");
        assert_eq!((c.axis, c.direction), ('X', 'X'), "{c}");
        assert!((c.at_mm - 300.0).abs() <= PLACE_STEP_MM, "{c}");
        assert!((c.height_um - 3.0).abs() < 0.15, "{c}");
        // A shape the baseline already spans (the set-up's cos θ) adds nothing.
        let setup: Shape = pairs
            .iter()
            .map(|_| std::array::from_fn(|d| (d as f64 + 0.5).to_radians().cos()))
            .collect();
        assert_eq!(scan_beyond(&pairs, &circles, 0.15, 3, &[setup]), alone);
    }

    /// A 30 mm raised-cosine bump of 2 µm on X's rail seen through a 100 mm block: the block's
    /// lift is the bump's mean over its length (written here as that average, by quadrature,
    /// apart from the scan's trapezoid), a change that comes back. The scan finds it as such,
    /// with its middle where the block is over the bump.
    #[test]
    fn a_bump_seen_through_a_block_comes_back_at_its_place() {
        let bump = |x: f64| {
            let u = (x - 300.0) / 30.0;
            if u.abs() < 0.5 {
                1.0 + (2.0 * std::f64::consts::PI * u).cos()
            } else {
                0.0
            }
        };
        let lift = |x: f64| {
            (0..200)
                .map(|i| bump(x - 50.0 + (i as f64 + 0.5) * 0.5))
                .sum::<f64>()
                / 200.0
        };
        let (pairs, circles) =
            runs_about(&[[250.0, 200.0], [330.0, 240.0]], &[100.0, 50.0], |x, t| {
                2.0 * lift(x) * t.cos()
            });
        let c = scan(&pairs, &circles, 0.15).expect("a change");
        assert!(c.comes_back, "{c}");
        assert_eq!((c.axis, c.direction), ('X', 'X'), "{c}");
        assert!((c.at_mm - 300.0).abs() <= PLACE_STEP_MM, "{c}");
        assert!(c.share > 0.9, "{c}");
        // The step of the first test is no bump.
        let (pairs, circles) = runs_about(&[[250.0, 200.0], [330.0, 240.0]], &[100.0, 50.0], ramp);
        assert!(!scan(&pairs, &circles, 0.15).unwrap().comes_back);
    }
}
