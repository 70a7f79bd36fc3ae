//! Where on the circle the residual concentrates, in the machine's own terms.
//!
//! The shares by quadrant and reversal say which part of the circle holds the residual; a
//! local defect (a bump on a rail, a joint between rail sections, a damaged stretch of a
//! screw) sits at a place along an axis, and the circle passes that place at one or two
//! angles. For each test (the runs of one plane, radius, feed and centre) this module finds
//! those angles:
//!
//! 1. each run's residual `r(θ)` (µm) is averaged into 1° bins of the angle mod 360°, and two
//!    local departures from the smooth run of the residual are read from it, both with
//!    medians, so that a narrow feature does not leak into its neighbours as a moving mean
//!    would make it:
//!    - a bump: `b(θ) = r(θ) − med_W(r)(θ)`, the median over [`HIGH_PASS_DEG`] about θ (a
//!      bump narrower than half the window leaves the median; a smooth shape and a step do
//!      not reach `b`);
//!    - a step: `s(θ) = med(r, θ…θ+w) − med(r, θ−w…θ)`, less the same difference of a line
//!      through the medians `3w` further out (what a smooth slope gives), `w` = [`STEP_DEG`];
//!      a step of height `a` reads about `3a/4`, since the outer medians straddle it too;
//! 2. the runs' `b² + (s/2)²` are averaged per bin and smoothed over [`SMOOTH_DEG`], `E(θ)`;
//! 3. a peak is a local maximum of `E` that stands [`MIN_RATIO`] times above its median and
//!    whose RMS, `√E`, reaches the least change an effect must make
//!    ([`crate::select::Options::min_effect_um`]); its width is where `E` stays above half its
//!    height over the median; its share is the part of the residual's energy `Σ r²` within
//!    that width, beside the share an even spread would give (width/360°);
//! 4. the peak's angles map to axis positions through the circle: `p = c_p + R cos θ`,
//!    `q = c_q + R sin θ` for the plane's axes `(p, q)` and the circle's centre `c` in axis
//!    coordinates (the tool point less the tool offset). Two peaks at the same `p`
//!    (`θ₂ ≈ −θ₁`) are a place on the `p` axis, at the same `q` (`θ₂ ≈ 180° − θ₁`) one on the
//!    `q` axis: the circle passes a place on an axis twice.

use crate::align::TracePair;
use crate::axis_change::axis_index;
use vmt_ballbar::Sense;

/// Width of the moving median a bump is read against, deg.
pub const HIGH_PASS_DEG: usize = 31;
/// Width of the medians on either side of a step, deg.
pub const STEP_DEG: usize = 5;
/// Smoothing of the energy profile, deg.
pub const SMOOTH_DEG: usize = 5;
/// Least ratio of a peak's energy to the median of the profile.
pub const MIN_RATIO: f64 = 8.0;
/// Two peaks within this many degrees of a mirror image of each other mark one place, deg.
pub const PAIR_TOLERANCE_DEG: f64 = 8.0;

/// The geometry of a test's circle in axis coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle {
    /// Centre, axis coordinates X, Y, Z, mm.
    pub centre_mm: [f64; 3],
    /// Radius, mm.
    pub radius_mm: f64,
}

impl Circle {
    /// The centre as `(250, 200, 200) mm`.
    pub fn centre_text(&self) -> String {
        centre_text(self.centre_mm)
    }
}

/// A centre as `(250, 200, 200) mm`.
pub fn centre_text([x, y, z]: [f64; 3]) -> String {
    format!("({x:.0}, {y:.0}, {z:.0}) mm")
}

/// The centres `circles` are about, each once, in the order they first come.
pub fn distinct_centres<'a>(circles: impl IntoIterator<Item = &'a Circle>) -> Vec<[f64; 3]> {
    once_each(circles.into_iter().map(|c| c.centre_mm))
}

/// Each of `items` once, in the order they first come.
pub(crate) fn once_each<T: PartialEq>(items: impl IntoIterator<Item = T>) -> Vec<T> {
    let mut out: Vec<T> = Vec::new();
    for x in items {
        if !out.contains(&x) {
            out.push(x);
        }
    }
    out
}

/// An angle difference, deg, wrapped into [−180, 180).
pub fn wrapped_deg(x: f64) -> f64 {
    (x + 180.0).rem_euclid(360.0) - 180.0
}

/// Each of `circles` once, in the order they first come (the runs of a test share one).
pub fn distinct<'a>(circles: impl IntoIterator<Item = &'a Circle>) -> Vec<Circle> {
    once_each(circles.into_iter().copied())
}

/// A place on the circle where the residual concentrates.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Peak {
    /// The test, e.g. `XY 150 mm 1000 mm/min`.
    pub test: String,
    /// The test's radius, mm.
    pub radius_mm: f64,
    /// The test's centre, axis coordinates X, Y, Z, mm, where known.
    pub centre_mm: Option<[f64; 3]>,
    /// Angle of the peak, deg in [0, 360).
    pub angle_deg: f64,
    /// Width where its energy stays above half its height, deg.
    pub width_deg: f64,
    /// The share of the test's residual energy within that width.
    pub share: f64,
    /// The share an even spread would put there (width / 360°).
    pub expected: f64,
    /// RMS of the high-passed residual at the peak, µm.
    pub rms_um: f64,
    /// Which runs show it: `both directions`, `CW only`, `CCW only`.
    pub directions: String,
    /// The axis positions the peak's width spans: (axis, from mm, to mm) for the plane's two
    /// axes, when the circle's centre is known.
    pub positions: Vec<(char, f64, f64)>,
}

/// A place on an axis the circle passes twice, with residual concentrated at both passes.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct AxisPlace {
    /// The test.
    pub test: String,
    /// The axis.
    pub axis: char,
    /// The position on it (mean of the two passes), mm.
    pub at_mm: f64,
    /// The angles of the two passes, deg.
    pub angles_deg: [f64; 2],
    /// The other axis when both passes are also its reversals (within
    /// [`PAIR_TOLERANCE_DEG`]): the place cannot be told from those reversals by angle alone.
    pub also_reversals_of: Option<char>,
}

impl std::fmt::Display for Peak {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let places: Vec<String> = self
            .positions
            .iter()
            .map(|(a, lo, hi)| format!("{a} {lo:.0}-{hi:.0} mm"))
            .collect();
        write!(
            f,
            "{:.0} deg (width {:.0} deg, {:.0} % of the energy where an even spread puts {:.0} %, {:.2} um RMS; {}){}",
            self.angle_deg,
            self.width_deg,
            100.0 * self.share,
            100.0 * self.expected,
            self.rms_um,
            self.directions,
            if places.is_empty() {
                String::new()
            } else {
                format!(": {}", places.join(", "))
            }
        )
    }
}

impl std::fmt::Display for AxisPlace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} at {:.0} mm (passed at {:.0} and {:.0} deg)",
            self.axis, self.at_mm, self.angles_deg[0], self.angles_deg[1]
        )?;
        if let Some(other) = self.also_reversals_of {
            write!(f, ", which are the {other} reversals too")?;
        }
        Ok(())
    }
}

/// The runs of one test: their indices into the pairs, and its circle.
fn tests(pairs: &[TracePair], circles: &[Option<Circle>]) -> Vec<(Vec<usize>, Option<Circle>)> {
    let mut out: Vec<(Vec<usize>, Option<Circle>)> = Vec::new();
    for (i, p) in pairs.iter().enumerate() {
        let c = circles.get(i).copied().flatten();
        let same = |j: &usize| {
            let q = &pairs[*j];
            q.plane == p.plane
                && q.radius_mm == p.radius_mm
                && q.feed_mm_min == p.feed_mm_min
                && circles.get(*j).copied().flatten() == c
        };
        match out.iter_mut().find(|(runs, _)| same(&runs[0])) {
            Some((runs, _)) => runs.push(i),
            None => out.push((vec![i], c)),
        }
    }
    out
}

/// Per 1° bin of the angle mod 360: the mean of `f` over the samples in it (`None` if empty).
fn per_degree(p: &TracePair, f: impl Fn(f64) -> f64) -> Vec<Option<f64>> {
    let mut sum = [0.0; 360];
    let mut n = [0usize; 360];
    for (a, r) in p.angle_deg.iter().zip(&p.residual_um) {
        let k = (a.rem_euclid(360.0).floor() as usize).min(359);
        sum[k] += f(*r);
        n[k] += 1;
    }
    (0..360)
        .map(|k| (n[k] > 0).then(|| sum[k] / n[k] as f64))
        .collect()
}

/// Circular moving mean over `w` bins of the bins present (absent bins stay absent).
fn moving_mean(x: &[Option<f64>], w: usize) -> Vec<Option<f64>> {
    let half = (w / 2) as isize;
    (0..x.len())
        .map(|i| {
            x[i]?;
            let (mut s, mut n) = (0.0, 0);
            for d in -half..=half {
                if let Some(v) = x[(i as isize + d).rem_euclid(x.len() as isize) as usize] {
                    s += v;
                    n += 1;
                }
            }
            Some(s / n as f64)
        })
        .collect()
}

/// The median of the bins present among `from..to` (circular indices, `to` exclusive).
fn median_over(x: &[Option<f64>], from: isize, to: isize) -> Option<f64> {
    let n = x.len() as isize;
    let v: Vec<f64> = (from..to)
        .filter_map(|i| x[i.rem_euclid(n) as usize])
        .collect();
    (!v.is_empty()).then(|| median(v))
}

/// The local departures of a run's residual per degree, `b² + (s/2)²` (step 1).
fn local_energy(p: &TracePair) -> Vec<Option<f64>> {
    let r = per_degree(p, |r| r);
    let (half, w) = ((HIGH_PASS_DEG / 2) as isize, STEP_DEG as isize);
    (0..r.len() as isize)
        .map(|i| {
            let here = r[i as usize]?;
            let bump = here - median_over(&r, i - half, i + half + 1)?;
            let step = |from: isize| -> Option<f64> {
                Some(median_over(&r, from, from + w)? - median_over(&r, from - w, from)?)
            };
            // A smooth slope's share: the same difference between medians 3w out, scaled to w.
            let slope =
                (median_over(&r, i + w, i + 3 * w)? - median_over(&r, i - 3 * w, i - w)?) / 4.0;
            let s = step(i)? - slope;
            Some(bump * bump + 0.25 * s * s)
        })
        .collect()
}

/// The mean over runs of per-degree profiles.
fn mean_profile(profiles: &[Vec<Option<f64>>]) -> Vec<Option<f64>> {
    (0..360)
        .map(|k| {
            let v: Vec<f64> = profiles.iter().filter_map(|p| p[k]).collect();
            (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The peaks of the residual of `pairs` (module doc), each test's circle given per pair
/// (`None` where unknown: no positions then); `min_rms_um` is the least RMS a peak must reach.
pub fn peaks(pairs: &[TracePair], circles: &[Option<Circle>], min_rms_um: f64) -> Vec<Peak> {
    let mut out = Vec::new();
    let tests = tests(pairs, circles);
    let centres = distinct_centres(tests.iter().filter_map(|(_, c)| c.as_ref())).len();
    for (runs, circle) in tests {
        let first = &pairs[runs[0]];
        let name = match circle {
            Some(c) if centres > 1 => format!(
                "{} {} mm {} mm/min about {}",
                first.plane,
                first.radius_mm,
                first.feed_mm_min,
                c.centre_text()
            ),
            _ => format!(
                "{} {} mm {} mm/min",
                first.plane, first.radius_mm, first.feed_mm_min
            ),
        };
        let profiles: Vec<Vec<Option<f64>>> =
            runs.iter().map(|i| local_energy(&pairs[*i])).collect();
        let e = moving_mean(&mean_profile(&profiles), SMOOTH_DEG);
        let floor = median(e.iter().flatten().copied().collect());
        let raw: Vec<Vec<Option<f64>>> = runs
            .iter()
            .map(|i| per_degree(&pairs[*i], |r| r * r))
            .collect();
        let raw = mean_profile(&raw);
        let total: f64 = raw.iter().flatten().sum();
        let present = raw.iter().flatten().count().max(1) as f64;
        for k in local_maxima(&e) {
            let height = e[k].unwrap_or(0.0);
            if height < MIN_RATIO * floor || height.sqrt() < min_rms_um {
                continue;
            }
            let (lo, hi) = half_width(&e, k, floor + 0.5 * (height - floor));
            let within: Vec<usize> = (lo..=hi).map(|d| d.rem_euclid(360) as usize).collect();
            let energy: f64 = within.iter().filter_map(|d| raw[*d]).sum();
            let count = within.iter().filter(|d| raw[**d].is_some()).count() as f64;
            let angle = k as f64 + 0.5;
            out.push(Peak {
                test: name.clone(),
                radius_mm: first.radius_mm,
                centre_mm: circle.map(|c| c.centre_mm),
                angle_deg: angle,
                width_deg: (hi - lo + 1) as f64,
                share: if total > 0.0 { energy / total } else { 0.0 },
                expected: count / present,
                rms_um: height.sqrt(),
                directions: directions(pairs, &runs, &profiles, k, floor),
                positions: circle.map_or_else(Vec::new, |c| {
                    positions(first, &c, lo as f64, hi as f64 + 1.0)
                }),
            });
        }
    }
    out.sort_by(|a, b| b.share.total_cmp(&a.share));
    out
}

/// Indices of the bins whose value is the largest within ±[`SMOOTH_DEG`] (circularly).
fn local_maxima(e: &[Option<f64>]) -> Vec<usize> {
    let n = e.len() as isize;
    let w = SMOOTH_DEG as isize;
    (0..e.len())
        .filter(|&k| {
            let Some(v) = e[k] else { return false };
            (-w..=w).filter(|d| *d != 0).all(|d| {
                let j = (k as isize + d).rem_euclid(n) as usize;
                // Ties go to the first of equal neighbours.
                e[j].is_none_or(|u| if d < 0 { u < v } else { u <= v })
            })
        })
        .collect()
}

/// The bins around `k` (as unwrapped indices `lo ≤ k ≤ hi`) where `e` stays above `level`.
fn half_width(e: &[Option<f64>], k: usize, level: f64) -> (isize, isize) {
    let n = e.len() as isize;
    let above = |j: isize| e[j.rem_euclid(n) as usize].is_some_and(|v| v > level);
    let (mut lo, mut hi) = (k as isize, k as isize);
    while lo > k as isize - 180 && above(lo - 1) {
        lo -= 1;
    }
    while hi < k as isize + 180 && above(hi + 1) {
        hi += 1;
    }
    (lo, hi)
}

/// Which directions hold the peak at bin `k`: a run holds it when its own energy there stands
/// above half of `MIN_RATIO` times the floor.
fn directions(
    pairs: &[TracePair],
    runs: &[usize],
    profiles: &[Vec<Option<f64>>],
    k: usize,
    floor: f64,
) -> String {
    let mut senses = Vec::new();
    for (i, profile) in runs.iter().zip(profiles) {
        let own = moving_mean(profile, SMOOTH_DEG)[k];
        if own.is_some_and(|v| v >= 0.5 * MIN_RATIO * floor) {
            senses.push(pairs[*i].sense);
        }
    }
    let (cw, ccw) = (senses.contains(&Sense::Cw), senses.contains(&Sense::Ccw));
    match (cw, ccw) {
        (true, true) => "both directions",
        (true, false) => "CW only",
        (false, true) => "CCW only",
        (false, false) => "the runs together",
    }
    .into()
}

/// The plane's axes' positions over the angles `from..to` (deg) of `circle`.
fn positions(p: &TracePair, circle: &Circle, from: f64, to: f64) -> Vec<(char, f64, f64)> {
    let (a, b) = p.plane.axes();
    let samples: Vec<f64> = (0..=20)
        .map(|i| (from + (to - from) * i as f64 / 20.0).to_radians())
        .collect();
    let span = |values: Vec<f64>| {
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    };
    let r = circle.radius_mm;
    let (p0, p1) = span(
        samples
            .iter()
            .map(|t| circle.centre_mm[axis_index(a)] + r * t.cos())
            .collect(),
    );
    let (q0, q1) = span(
        samples
            .iter()
            .map(|t| circle.centre_mm[axis_index(b)] + r * t.sin())
            .collect(),
    );
    vec![(a, p0, p1), (b, q0, q1)]
}

/// Pairs of peaks of one test that mark one place on an axis (module doc, step 4).
pub fn axis_places(
    peaks: &[Peak],
    pairs: &[TracePair],
    circles: &[Option<Circle>],
) -> Vec<AxisPlace> {
    let mut out = Vec::new();
    for (i, a) in peaks.iter().enumerate() {
        for b in &peaks[i + 1..] {
            if a.test != b.test {
                continue;
            }
            // A run of the test (its name) about the peak's centre, and its circle.
            let Some((run, circle)) = pairs.iter().zip(circles).find_map(|(p, c)| {
                let c = (*c)?;
                let name = format!("{} {} mm {} mm/min", p.plane, p.radius_mm, p.feed_mm_min);
                (a.test.starts_with(&name) && Some(c.centre_mm) == a.centre_mm).then_some((p, c))
            }) else {
                continue;
            };
            let (p, q) = run.plane.axes();
            let (ta, tb) = (a.angle_deg, b.angle_deg);
            let r = circle.radius_mm;
            // Both passes at the reversals of the other axis (p reverses at 0° and 180°, q
            // at 90° and 270°).
            let near = |t: f64, at: f64| wrapped_deg(t - at).abs() <= PAIR_TOLERANCE_DEG;
            let reversals = |axis: char, at: [f64; 2]| {
                [ta, tb]
                    .iter()
                    .all(|t| at.iter().any(|x| near(*t, *x)))
                    .then_some(axis)
            };
            if wrapped_deg(ta + tb).abs() <= PAIR_TOLERANCE_DEG {
                let at = 0.5 * (ta.to_radians().cos() + tb.to_radians().cos());
                out.push(AxisPlace {
                    test: a.test.clone(),
                    axis: p,
                    at_mm: circle.centre_mm[axis_index(p)] + r * at,
                    angles_deg: [ta, tb],
                    also_reversals_of: reversals(q, [90.0, 270.0]),
                });
            } else if wrapped_deg(ta + tb - 180.0).abs() <= PAIR_TOLERANCE_DEG {
                let at = 0.5 * (ta.to_radians().sin() + tb.to_radians().sin());
                out.push(AxisPlace {
                    test: a.test.clone(),
                    axis: q,
                    at_mm: circle.centre_mm[axis_index(q)] + r * at,
                    angles_deg: [ta, tb],
                    also_reversals_of: reversals(p, [0.0, 180.0]),
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use vmt_ballbar::Plane;

    /// A run of 0.25° samples with the residual `f(θ)` plus a small deterministic ripple.
    fn run(sense: Sense, f: impl Fn(f64) -> f64) -> TracePair {
        let angle_deg: Vec<f64> = (0..1440).map(|i| i as f64 * 0.25).collect();
        let residual_um = angle_deg
            .iter()
            .map(|a| f(*a) + 0.02 * (7.3 * a.to_radians()).sin() * (0.37 * a).cos())
            .collect();
        TracePair {
            label: format!("{sense:?}"),
            plane: Plane::Xy,
            sense,
            radius_mm: 150.0,
            feed_mm_min: 1000.0,
            time_s: (0..1440).map(|i| i as f64 * 0.01).collect(),
            angle_deg,
            residual_um,
        }
    }

    /// A raised-cosine bump of height `h` and full width `w` at `at` (deg).
    fn bump(a: f64, at: f64, h: f64, w: f64) -> f64 {
        let d = (a - at + 180.0).rem_euclid(360.0) - 180.0;
        if d.abs() < w / 2.0 {
            0.5 * h * (1.0 + (std::f64::consts::TAU * d / w).cos())
        } else {
            0.0
        }
    }

    const CIRCLE: Circle = Circle {
        centre_mm: [250.0, 200.0, 200.0],
        radius_mm: 150.0,
    };

    #[test]
    fn a_bump_is_found_at_its_angle_and_mapped_to_the_axes() {
        // A 2 µm bump 6° wide at 60° over a broad 1 µm second harmonic (which the medians
        // take away), in both directions.
        let f = |a: f64| bump(a, 60.0, 2.0, 6.0) + (2.0 * a.to_radians()).sin();
        let pairs = [run(Sense::Cw, f), run(Sense::Ccw, f)];
        let found = peaks(&pairs, &[Some(CIRCLE); 2], 0.15);
        assert_eq!(found.len(), 1, "{found:#?}");
        let p = &found[0];
        assert!((p.angle_deg - 60.0).abs() <= 1.0, "{p}");
        assert!(p.width_deg >= 2.0 && p.width_deg <= 8.0, "{p}");
        assert_eq!(p.directions, "both directions");
        // X = 250 + 150 cos θ, Y = 200 + 150 sin θ: 325 and 330 mm at 60° (closed form).
        let (x0, x1) = (p.positions[0].1, p.positions[0].2);
        let (y0, y1) = (p.positions[1].1, p.positions[1].2);
        assert!(x0 <= 325.0 && x1 >= 325.0 && x1 - x0 < 20.0, "{p}");
        assert!(y0 <= 330.0 && y1 >= 330.0 && y1 - y0 < 20.0, "{p}");
        // The share within the width (closed form over the bump's 6°): the bump's own
        // 3h²w/8 = 9 µm²·deg, the harmonic's sin²(120°)·6 = 4.5 and their overlap
        // 2·(hw/2)·sin 120° = 10.4, of the whole 180 + 9 µm²·deg: 12.6 %, where an even
        // spread puts 6/360 = 1.7 %.
        assert!((p.share - 0.126).abs() < 0.03, "{p}");
    }

    #[test]
    fn a_place_on_x_passed_twice_is_named_on_x() {
        // A rail bump at X = 325 mm is passed at ±60°.
        let f = |a: f64| bump(a, 60.0, 1.5, 6.0) + bump(a, 300.0, 1.5, 6.0);
        let pairs = [run(Sense::Cw, f), run(Sense::Ccw, f)];
        let circles = [Some(CIRCLE); 2];
        let found = peaks(&pairs, &circles, 0.15);
        assert_eq!(found.len(), 2, "{found:#?}");
        let places = axis_places(&found, &pairs, &circles);
        assert_eq!(places.len(), 1, "{places:#?}");
        assert_eq!(places[0].axis, 'X');
        assert!((places[0].at_mm - 325.0).abs() < 2.0, "{}", places[0]);
        assert_eq!(places[0].also_reversals_of, None);
        // Peaks at 0° and 180° are a place on Y at the centre's Y, and the X reversals too.
        let f = |a: f64| bump(a, 1.0, 1.5, 6.0) + bump(a, 181.0, 1.5, 6.0);
        let pairs = [run(Sense::Cw, f), run(Sense::Ccw, f)];
        let places = axis_places(&peaks(&pairs, &circles, 0.15), &pairs, &circles);
        assert_eq!(places.len(), 1, "{places:#?}");
        assert_eq!(
            (places[0].axis, places[0].also_reversals_of),
            ('Y', Some('X'))
        );
    }

    #[test]
    fn the_edges_of_a_step_are_found_where_they_are() {
        // A 1.5 µm plateau from 100° to 250° over a 2 µm first harmonic: two edges.
        let f = |a: f64| {
            2.0 * a.to_radians().cos()
                + if (100.0..250.0).contains(&a) {
                    1.5
                } else {
                    0.0
                }
        };
        let pairs = [run(Sense::Cw, f), run(Sense::Ccw, f)];
        let found = peaks(&pairs, &[None, None], 0.15);
        let mut angles: Vec<f64> = found.iter().map(|p| p.angle_deg).collect();
        angles.sort_by(f64::total_cmp);
        assert_eq!(angles.len(), 2, "{found:#?}");
        assert!(
            (angles[0] - 100.0).abs() <= 2.0 && (angles[1] - 250.0).abs() <= 2.0,
            "{angles:?}"
        );
    }

    #[test]
    fn a_smooth_residual_has_no_peak_and_one_direction_is_said() {
        let smooth = |a: f64| 2.0 * a.to_radians().cos() + 0.5 * (2.0 * a.to_radians()).sin();
        let pairs = [run(Sense::Cw, smooth), run(Sense::Ccw, smooth)];
        assert!(peaks(&pairs, &[None, None], 0.15).is_empty());
        let only_ccw = [
            run(Sense::Cw, smooth),
            run(Sense::Ccw, |a| smooth(a) + bump(a, 200.0, 2.0, 6.0)),
        ];
        let found = peaks(&only_ccw, &[None, None], 0.15);
        assert_eq!(found.len(), 1, "{found:#?}");
        assert_eq!(found[0].directions, "CCW only");
        assert!(found[0].positions.is_empty());
    }
}
