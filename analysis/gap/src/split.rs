//! Which data fit the candidates, which choose between them, and which judge the choice.
//!
//! The residual of every measured run is averaged into bins of its angle (1° by default), and
//! the bins are cut into segments of [`SEGMENT_DEG`] of the angle (0–40°, 40–80°, … of the
//! angle mod 360°). Segment `s` of run `t` (in the order the runs are given) plays the role
//! `(s + t) mod 3`:
//!
//! - **fit**: the parameters of the bar's set-up and of the candidates are fitted to these
//!   bins (least squares through the linearised model, then a Gauss–Newton step from a
//!   simulation);
//! - **select**: the candidates are ranked and gated on these (predicted RMS, BIC on the fit
//!   bins, shrink and least change here);
//! - **judge**: used by neither. The figures reported as held out, the confirmation that the
//!   chosen effects explain the gap, and the test of which rivals explain it as well are read
//!   from these bins only.
//!
//! Each role so holds every third segment of each run, and the roles turn by one from run to
//! run: the fit segments of a CW run are the select segments of its CCW partner. Every role
//! covers the circle's angles and both directions, and since 40° does not divide 90°, the
//! segments that hold the axis reversals (0°, 90°, 180°, 270°) fall in all three roles.
//! Neighbouring segments share the slow part of the residual (a drift, the nuisance's smooth
//! shapes) but not its noise; the judgement is of the effects' shapes on angles they were not
//! fitted or chosen on.
//!
//! A judgement needs [`MIN_JUDGE_SEGMENTS`] judge segments that each hold at least half a
//! segment of data (one direction of a full circle holds three); with fewer, no untouched
//! figure is given and the report says why.

use crate::align::GapError;
use vmt_ballbar::Trace;

/// Width of the segments the roles are dealt out in, deg.
pub const SEGMENT_DEG: f64 = 40.0;

/// Judge segments needed for an untouched judgement (and the paired test of rivals).
pub const MIN_JUDGE_SEGMENTS: usize = 3;

/// The part a bin of data plays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// Fits the parameters.
    Fit,
    /// Ranks and gates the candidates.
    Select,
    /// Judges the choice, untouched by both.
    Judge,
}

impl Role {
    /// The role of segment `segment` of run `run`.
    pub fn of(segment: i64, run: usize) -> Self {
        match (segment + run as i64).rem_euclid(3) {
            0 => Self::Fit,
            1 => Self::Select,
            _ => Self::Judge,
        }
    }
}

/// How the measured data are dealt out between fitting, selecting and judging.
#[derive(Clone, Debug, PartialEq)]
pub struct Split {
    /// Width of the segments, deg.
    pub segment_deg: f64,
    /// The protocol in words, for the report.
    pub rule: String,
}

impl Split {
    /// The protocol of the module doc, checked against the measured runs: an error when they
    /// hold too little to fit and to select at all.
    pub fn automatic(measured: &[Trace]) -> Result<Self, GapError> {
        let split = Self {
            segment_deg: SEGMENT_DEG,
            rule: format!(
                "segments of {SEGMENT_DEG:.0} deg of each run's angle, in turn fit, select and \
                 judge, turning by one from run to run; the judge segments are used neither to \
                 fit nor to choose"
            ),
        };
        let angles: Vec<Vec<f64>> = measured.iter().map(|t| t.angle_deg.clone()).collect();
        let counts = split.segments(&angles);
        if counts[0] == 0 || counts[1] == 0 {
            return Err(GapError::Model(format!(
                "the measured runs hold {} fit and {} select segments of {SEGMENT_DEG:.0} deg; \
                 the gap analysis needs data to fit and other data to choose with: give longer \
                 arcs, two directions or more tests",
                counts[0], counts[1]
            )));
        }
        Ok(split)
    }

    /// The segment of an angle, deg: its index in the turn (0 to 8 for 40°).
    pub fn segment(&self, angle_deg: f64) -> i64 {
        (angle_deg.rem_euclid(360.0) / self.segment_deg).floor() as i64
    }

    /// Segments per role (fit, select, judge) over runs of the given sample angles, counting
    /// only the segments a run covers for at least half their width.
    pub fn segments(&self, runs: &[Vec<f64>]) -> [usize; 3] {
        let mut counts = [0; 3];
        for (t, angles) in runs.iter().enumerate() {
            for (segment, span) in self.pieces(angles) {
                if span >= 0.5 * self.segment_deg {
                    counts[Role::of(segment, t) as usize] += 1;
                }
            }
        }
        counts
    }

    /// The consecutive pieces of a run in one segment each, with the angle each spans, deg.
    fn pieces(&self, angles: &[f64]) -> Vec<(i64, f64)> {
        let mut out: Vec<(i64, f64, f64)> = Vec::new();
        for &a in angles {
            let s = self.segment(a);
            match out.last_mut() {
                Some((seg, lo, hi)) if *seg == s => {
                    *lo = lo.min(a);
                    *hi = hi.max(a);
                }
                _ => out.push((s, a, a)),
            }
        }
        out.into_iter().map(|(s, lo, hi)| (s, hi - lo)).collect()
    }
}

/// The bins of each role, as (run, bin) pairs in run order, and the judge bins grouped by the
/// segment they lie in (for the paired test of rivals).
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Rows {
    pub fit: Vec<(usize, usize)>,
    pub select: Vec<(usize, usize)>,
    pub judge: Vec<(usize, usize)>,
    /// Per judge segment that holds at least half a segment of bins, the positions of its
    /// bins in `judge`.
    pub judge_segments: Vec<Vec<usize>>,
    /// Per select segment likewise, positions in `select` (the paired test when there is no
    /// judgement).
    pub select_segments: Vec<Vec<usize>>,
}

impl Rows {
    /// The roles of the bins of `grid` (per run, the bins' keys `⌊angle/bin_deg⌋`).
    pub fn new<T>(split: &Split, grid: &[Vec<(i64, T)>], bin_deg: f64) -> Self {
        let mut rows = Self::default();
        let least = (0.5 * split.segment_deg / bin_deg).ceil() as usize;
        for (t, bins) in grid.iter().enumerate() {
            let mut current: Option<(i64, Role, Vec<usize>)> = None;
            for (b, (key, _)) in bins.iter().enumerate() {
                let segment = split.segment((*key as f64 + 0.5) * bin_deg);
                let role = Role::of(segment, t);
                if current.as_ref().is_some_and(|(s, _, _)| *s != segment) {
                    rows.close(current.take(), least);
                }
                let list = rows.role_mut(role);
                list.push((t, b));
                let at = list.len() - 1;
                current
                    .get_or_insert_with(|| (segment, role, Vec::new()))
                    .2
                    .push(at);
            }
            rows.close(current, least);
        }
        rows
    }

    fn role_mut(&mut self, role: Role) -> &mut Vec<(usize, usize)> {
        match role {
            Role::Fit => &mut self.fit,
            Role::Select => &mut self.select,
            Role::Judge => &mut self.judge,
        }
    }

    fn close(&mut self, piece: Option<(i64, Role, Vec<usize>)>, least: usize) {
        match piece {
            Some((_, Role::Judge, at)) if at.len() >= least => self.judge_segments.push(at),
            Some((_, Role::Select, at)) if at.len() >= least => self.select_segments.push(at),
            _ => {}
        }
    }

    /// Whether the judge bins are enough for an untouched judgement.
    pub fn can_judge(&self) -> bool {
        self.judge_segments.len() >= MIN_JUDGE_SEGMENTS
    }

    /// The bins of `role`.
    pub fn of(&self, role: Role) -> &[(usize, usize)] {
        match role {
            Role::Fit => &self.fit,
            Role::Select => &self.select,
            Role::Judge => &self.judge,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys(from: i64, to: i64) -> Vec<(i64, ())> {
        (from..to).map(|k| (k, ())).collect()
    }

    #[test]
    fn every_bin_has_one_role_and_the_roles_turn_from_run_to_run() {
        let split = Split {
            segment_deg: SEGMENT_DEG,
            rule: String::new(),
        };
        // Two full circles of 1° bins: 9 segments each, 3 per role per run.
        let grid = vec![keys(0, 360), keys(0, 360)];
        let rows = Rows::new(&split, &grid, 1.0);
        assert_eq!(rows.fit.len() + rows.select.len() + rows.judge.len(), 720);
        assert_eq!(rows.fit.len(), 240);
        assert_eq!(rows.judge.len(), 240);
        assert_eq!(rows.judge_segments.len(), 6);
        assert!(rows.can_judge());
        // The bin at 10° fits in run 0 and selects in run 1; at 50° it selects, then judges.
        assert!(rows.fit.contains(&(0, 10)) && rows.select.contains(&(1, 10)));
        assert!(rows.select.contains(&(0, 50)) && rows.judge.contains(&(1, 50)));
        // Each axis reversal lies in a segment of each role over the two runs.
        for at in [0usize, 90, 180, 270] {
            let roles: Vec<Role> = (0..2)
                .map(|t| Role::of(split.segment(at as f64 + 0.5), t))
                .collect();
            assert_ne!(roles[0], roles[1], "reversal at {at}°");
        }
        let reversal_roles: std::collections::BTreeSet<u8> = [0.5, 90.5, 180.5, 270.5]
            .iter()
            .flat_map(|a| {
                let segment = split.segment(*a);
                (0..2).map(move |t| Role::of(segment, t) as u8)
            })
            .collect();
        assert_eq!(reversal_roles.len(), 3);
    }

    #[test]
    fn a_short_arc_is_too_few_to_judge() {
        let split = Split {
            segment_deg: SEGMENT_DEG,
            rule: String::new(),
        };
        // One run over 100°: segments 0, 1 and the half of 2: one judge segment of 20°.
        let rows = Rows::new(&split, &[keys(0, 100)], 1.0);
        assert!(!rows.can_judge());
        assert_eq!(rows.judge.len(), 20);
        assert_eq!(
            split.segments(&[(0..100).map(f64::from).collect()]),
            [1, 1, 0]
        );
    }
}
