//! The error model of a circular test and its least-squares fit.
//!
//! The deviation of every sample of every trace of a test is modelled as the sum of the
//! signatures of [`crate::signatures`], each scaled by one unknown physical parameter:
//!
//! ```text
//! Δr = r₀ + Σ_terms x_k f_k(θ, σ, s) + ε,      ε ~ N(0, σ_ε²) per sample
//! ```
//!
//! with s the progress over the whole test (time when the traces carry it), so that a drift of
//! the pivot or the bar is one continuous law across the CW and CCW runs. Samples are averaged
//! in groups (see [`crate::samples`]; the groups of the start and end transients, and in a
//! diagnosis those of the reversal spikes, are left out) and the groups weighted by their size,
//! which is the generalised least-squares estimate for white sample noise; the covariance of the
//! estimate is `σ̂² (AᵀWA)⁻¹` with `σ̂² = Σ w r² / (n_groups − n_terms)`, and a diagnosis states
//! the larger of that and a long-run estimate that holds when the residual is correlated
//! ([`Normal::robust_std_errors`]).
//!
//! A term enters only where the test can tell it from the others (see [`Terms::for_test`]):
//! backlash needs a reversal of its axis inside the arc or both senses, lateral play a reversal
//! in both senses, angular play that on an arc of at least 270°, servo mismatch both senses,
//! drift full circles run both ways; on a half circle or less the terms that the axes' unfitted bows move
//! most are fitted but not reported ([`Terms::unresolved`]).

use crate::samples::Samples;
use crate::signatures::{self, Point};
use crate::trace::{Plane, Trace};
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;
use thiserror::Error;

/// One unknown of the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Term {
    /// Radius offset r₀, µm.
    Radius,
    /// Pivot offset along p (0) or q (1) at the start of the test, µm.
    Pivot(usize),
    /// Radial growth over the test, µm.
    RadialDrift,
    /// Pivot drift over the test along p (0) or q (1), µm.
    PivotDrift(usize),
    /// Scale mismatch ε_p − ε_q, ppm.
    ScaleMismatch,
    /// The plane's ISO squareness, µrad (µm/m).
    Squareness,
    /// Servo mismatch τ_p − τ_q, ms.
    ServoMismatch,
    /// Backlash of p (0) or q (1), µm.
    Backlash(usize),
    /// Lateral play of p (0) or q (1), µm.
    LateralPlay(usize),
    /// Angular play of p (0) or q (1) about the plane's normal, µrad.
    AngularPlay(usize),
    /// Straightness (bow over the diameter) of p (0) or q (1), µm.
    Straightness(usize),
}

/// Number of shape functions of [`Compiled`].
pub const SHAPES: usize = 17;

/// The model as weights of 17 shape functions of a sample, so that the deviation of a sample
/// is one dot product:
/// `[1, c, s, c²−s², sc, σ sgn(s) c, σ sgn(c) s, σ|s|, σ|c|, c²s, s²c, u, u c, u s, σ sc,
/// σ|s|c, σ|c|s]`
/// with c = cos θ, s = sin θ, σ the sense and u the progress. [`Term::basis`] is the reference;
/// a test checks that both agree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Compiled {
    w: [f64; SHAPES],
}

impl Compiled {
    /// `out[i] = deviation[i] − model(i)` for the samples of one trace of sense sign `g` (the
    /// residual): the dot product of the weights with [`shapes`], the sense folded into the
    /// weights and the terms regrouped (`w₉c²s + w₁₀s²c = sc (w₉c + w₁₀s)`,
    /// `|s| = sign(s) s`), the signs applied by `signed`, so that the loop has no branch or
    /// select and runs on vectors.
    pub fn residuals(
        &self,
        g: f64,
        cos: &[f64],
        sin: &[f64],
        progress: &[f64],
        deviation: &[f64],
        out: &mut [f64],
    ) {
        let w = &self.w;
        let k4 = w[4] + g * w[14];
        let (ps, pc) = (
            [g * w[5], g * w[7], g * w[15]],
            [g * w[8], g * w[6], g * w[16]],
        );
        let n = out.len();
        let (cos, sin, progress, deviation) =
            (&cos[..n], &sin[..n], &progress[..n], &deviation[..n]);
        for i in 0..n {
            let (c, s, u) = (cos[i], sin[i], progress[i]);
            let sc = s * c;
            let model = w[0]
                + w[1] * c
                + w[2] * s
                + w[3] * (c * c - s * s)
                + sc * (k4 + w[9] * c + w[10] * s)
                + signed(s, ps[0] * c + ps[1] * s + ps[2] * sc)
                + signed(c, pc[0] * c + pc[1] * s + pc[2] * sc)
                + u * (w[11] + w[12] * c + w[13] * s);
            out[i] = deviation[i] - model;
        }
    }
}

/// `sign(x) · y` (0 where x is ±0) by bit operations: y with the sign bit of x flipped in,
/// masked by x ≠ 0.
#[inline]
fn signed(x: f64, y: f64) -> f64 {
    const SIGN: u64 = 1 << 63;
    let nonzero = u64::from(x != 0.0).wrapping_neg();
    f64::from_bits((y.to_bits() ^ (x.to_bits() & SIGN)) & nonzero)
}

/// The [`SHAPES`] shape functions of [`Compiled`] at `pt`.
#[inline]
pub fn shapes(pt: &Point) -> [f64; SHAPES] {
    let (c, s, g, u) = (pt.cos, pt.sin, pt.sense.sign(), pt.progress);
    let sgn = signatures::sign;
    [
        1.0,
        c,
        s,
        c * c - s * s,
        s * c,
        g * sgn(s) * c,
        g * sgn(c) * s,
        g * s.abs(),
        g * c.abs(),
        c * c * s,
        s * s * c,
        u,
        u * c,
        u * s,
        g * s * c,
        g * s.abs() * c,
        g * c.abs() * s,
    ]
}

impl Term {
    /// The shape function (index in [`Compiled`]) and its weight per unit of this term.
    pub fn shape(self, plane: Plane, radius_um: f64, feed_um_per_ms: f64) -> (usize, f64) {
        match self {
            Term::Radius => (0, 1.0),
            Term::Pivot(i) => (1 + i, -1.0),
            Term::ScaleMismatch => (3, 0.5 * radius_um * 1e-6),
            Term::Squareness => (4, signatures::squareness_sign(plane) * radius_um * 1e-6),
            Term::Backlash(i) => (5 + i, if i == 0 { 0.5 } else { -0.5 }),
            Term::LateralPlay(i) => (7 + i, if i == 0 { 0.5 } else { -0.5 }),
            Term::AngularPlay(i) => (15 + i, [0.5, -0.5][i] * radius_um * 1e-6),
            Term::Straightness(i) => (9 + i, -1.0),
            Term::RadialDrift => (11, 1.0),
            Term::PivotDrift(i) => (12 + i, -1.0),
            Term::ServoMismatch => (14, feed_um_per_ms),
        }
    }

    /// Δr per unit of this term at `pt` in `plane`, µm (inlined: called per sample in the
    /// windows around reversals, where the term is known).
    #[inline]
    pub fn basis(self, pt: &Point, plane: Plane) -> f64 {
        match self {
            Term::Radius => 1.0,
            Term::Pivot(i) => signatures::pivot_offset(pt)[i],
            Term::RadialDrift => signatures::drift(pt)[0],
            Term::PivotDrift(i) => signatures::drift(pt)[1 + i],
            Term::ScaleMismatch => signatures::scale_mismatch(pt),
            Term::Squareness => signatures::squareness(pt, plane),
            Term::ServoMismatch => signatures::servo_mismatch(pt),
            Term::Backlash(i) => signatures::backlash(pt)[i],
            Term::LateralPlay(i) => signatures::lateral_play(pt)[i],
            Term::AngularPlay(i) => signatures::angular_play(pt)[i],
            Term::Straightness(i) => signatures::straightness(pt)[i],
        }
    }
}

/// Whether an axis reversal at `theta_deg` (mod 360) lies inside the trace with `margin` degrees
/// on both sides.
pub fn covers(t: &Trace, theta_deg: f64, margin: f64) -> bool {
    let (a, b) = (t.angle_deg[0], t.angle_deg[t.angle_deg.len() - 1]);
    let (lo, hi) = (a.min(b) + margin, a.max(b) - margin);
    let k = ((lo - theta_deg) / 360.0).ceil();
    theta_deg + 360.0 * k <= hi
}

/// Angles (deg) at which the plane's p (index 0) or q (index 1) axis reverses.
pub const fn reversal_angles(axis: usize) -> [f64; 2] {
    if axis == 0 {
        [0.0, 180.0]
    } else {
        [90.0, 270.0]
    }
}

/// The terms a test can determine, and why the others are left out.
#[derive(Clone, Debug, PartialEq)]
pub struct Terms {
    /// Terms in the model.
    pub terms: Vec<Term>,
    /// Terms left out, with the reason.
    pub left_out: Vec<(Term, &'static str)>,
    /// Terms in the model (so that the shapes they stand for do not leak into the others) whose
    /// values the test cannot tell from an effect left out, with the reason: not reported.
    pub unresolved: Vec<(Term, &'static str)>,
}

/// The sweep (deg) a trace needs for drift terms: a closed circle.
pub const FULL_CIRCLE_DEG: f64 = 355.0;
/// Margin (deg) a reversal needs inside the arc for its steps to be seen.
pub const REVERSAL_MARGIN_DEG: f64 = 5.0;
/// The sweep (deg) from which the axes' bows (straightness) are fitted.
pub const STRAIGHTNESS_SWEEP_DEG: f64 = 270.0;
/// The sweep (deg) below which the terms an unfitted bow moves most are not reported (a half
/// circle and less; see [`Terms::unresolved`]).
pub const HALF_CIRCLE_DEG: f64 = 200.0;

impl Terms {
    /// The terms for a test made of `traces` (one or two senses, full or partial arcs).
    pub fn for_test(traces: &[&Trace]) -> Self {
        let both = traces.iter().any(|t| t.sense != traces[0].sense);
        let full = traces.iter().all(|t| t.sweep_deg() >= FULL_CIRCLE_DEG);
        let sweep = traces.iter().map(|t| t.sweep_deg()).fold(0.0, f64::max);
        let reverses = |axis: usize| {
            reversal_angles(axis)
                .iter()
                .any(|&a| traces.iter().all(|t| covers(t, a, REVERSAL_MARGIN_DEG)))
        };
        let mut terms = vec![Term::Radius, Term::Pivot(0), Term::Pivot(1)];
        let mut left_out = Vec::new();
        let mut add = |term: Term, ok: bool, why: &'static str| {
            if ok {
                terms.push(term);
            } else {
                left_out.push((term, why));
            }
        };
        // Run one way, the progress follows the angle: a drift is the circle's own shapes but
        // for the jump where the circle closes, which the start's transient and the reversal
        // there hide (on the built-in machine run CCW only, the fitted drift moved the
        // eccentricity of Y by 1.4 µm and the squareness by 3.6 µm/m).
        let why = if full {
            "needs full circles run both ways (one way, a drift follows the angle)"
        } else {
            "needs full circles (start and end at the same angle)"
        };
        add(Term::RadialDrift, full && both, why);
        add(Term::PivotDrift(0), full && both, why);
        add(Term::PivotDrift(1), full && both, why);
        // A 90° data arc's samples span a little less: the traces' own least sweep.
        const NEEDS_90: &str = "needs an arc of at least 90 deg";
        let quarter = sweep >= crate::trace::MIN_SWEEP_DEG;
        add(Term::ScaleMismatch, quarter, NEEDS_90);
        add(Term::Squareness, quarter, NEEDS_90);
        const NEEDS_BOTH: &str = "needs both a CW and a CCW run of the same circle";
        let why = if both { NEEDS_90 } else { NEEDS_BOTH };
        add(Term::ServoMismatch, both && quarter, why);
        // An axis that does not reverse inside the arc still travels one way in the CW run and
        // the other way in the CCW run: its lost motion is the same law, a shift of the run by
        // ±b/2 along the axis (sign v constant over the arc).
        const NEEDS_270: &str = "needs an arc of at least 270 deg";
        const NEEDS_REVERSAL: &str =
            "needs a reversal of the axis inside the arc, or a CW and a CCW run";
        const NEEDS_REVERSAL_BOTH: &str =
            "needs a reversal of the axis inside the arc in both a CW and a CCW run";
        for axis in 0..2 {
            add(Term::Backlash(axis), reverses(axis) || both, NEEDS_REVERSAL);
            add(
                Term::LateralPlay(axis),
                both && reverses(axis),
                NEEDS_REVERSAL_BOTH,
            );
            // On a shorter arc its shape leans on the backlash's (a 220° arc in ZX moved X's
            // backlash by 0.05 µm and read 3 µrad of angular play that was not there).
            let (ok, why) = match (both && reverses(axis), sweep >= STRAIGHTNESS_SWEEP_DEG) {
                (false, _) => (false, NEEDS_REVERSAL_BOTH),
                (true, long) => (long, NEEDS_270),
            };
            add(Term::AngularPlay(axis), ok, why);
        }
        for axis in 0..2 {
            add(
                Term::Straightness(axis),
                sweep >= STRAIGHTNESS_SWEEP_DEG,
                NEEDS_270,
            );
        }
        let unresolved = if sweep < HALF_CIRCLE_DEG {
            unresolved_on_partial_arc(traces[0], &terms)
        } else {
            Vec::new()
        };
        Self {
            terms,
            left_out,
            unresolved,
        }
    }
}

/// The terms of `terms` that an arc of a half circle or less (shorter than
/// [`HALF_CIRCLE_DEG`], such as `trace`'s) cannot tell from the bows of its axes, which it
/// leaves out: over a half circle 1 µm of bow moves the scale mismatch by about 11 ppm, the
/// squareness by about 6 µrad, the radius by about 0.9 µm and the pivot offset along the arc's
/// middle direction by about 1.8 µm (least-squares projections of the bow's shape on theirs).
/// The pivot offset across the middle direction moves by about 0.17 µm per µm of bow and stays
/// reported. Over the usual 220° vertical arc of 150 mm the squareness still moves by 4 µrad
/// per µm of bow, the scale mismatch by 8 ppm: reported, as the standard's practice is, each
/// finding stating its bias per µm of bow (the diagnosis' `bias_per_um_of_straightness_*`).
fn unresolved_on_partial_arc(trace: &Trace, terms: &[Term]) -> Vec<(Term, &'static str)> {
    const WHY: &str = "a half circle cannot tell it from the bow (straightness) of the axes: \
                       needs an arc of at least 270 deg";
    let (a, b) = (
        trace.angle_deg[0],
        trace.angle_deg[trace.angle_deg.len() - 1],
    );
    let middle = (0.5 * (a + b)).to_radians();
    let along = usize::from(middle.sin().abs() > middle.cos().abs());
    [
        Term::Radius,
        Term::Pivot(along),
        Term::ScaleMismatch,
        Term::Squareness,
    ]
    .into_iter()
    .filter(|t| terms.contains(t))
    .map(|t| (t, WHY))
    .collect()
}

/// Why a fit failed.
#[derive(Debug, Error, PartialEq)]
pub enum FitError {
    /// The normal equations are singular.
    #[error(
        "the error terms cannot be told apart on this test (singular normal equations); a longer arc or both directions are needed"
    )]
    Singular,
    /// Fewer groups than unknowns.
    #[error("{groups} sample groups for {terms} unknowns; the trace is too short")]
    TooFewSamples {
        /// Groups.
        groups: usize,
        /// Unknowns.
        terms: usize,
    },
}

/// The fitted model.
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// The test plane.
    pub plane: Plane,
    /// The terms, in the order of `values`.
    pub terms: Vec<Term>,
    /// Estimates, in the units of each term.
    pub values: Vec<f64>,
    /// Standard errors of the estimates.
    pub std_errors: Vec<f64>,
    /// Estimated per-sample noise σ̂, µm.
    pub sample_sigma_um: f64,
}

/// The weighted normal equations of a fit, `AᵀWA x = AᵀWy`, factored, with `yᵀWy`: kept so
/// that the fit can be made again when a few groups' means move ([`Normal::shift`]) without a
/// pass over all the groups. The residual sum of squares at the solution is
/// `yᵀWy − xᵀAᵀWy`.
#[derive(Clone, Debug)]
pub struct Normal {
    plane: Plane,
    terms: Vec<Term>,
    chol: nalgebra::Cholesky<f64, nalgebra::Dyn>,
    inv: DMatrix<f64>,
    aty: DVector<f64>,
    yy: f64,
    groups: usize,
    /// Per trace: each term's shape function and factor.
    maps: Vec<Vec<(usize, f64)>>,
    /// Per trace: the sums of the shape functions' products, which the terms' normal equations
    /// were made from (shared by the clones of a search; see [`Normal::alias`]).
    grams: Arc<Vec<Gram>>,
}

/// The weighted sums `Σ w fᵢ fⱼ` of the products of the [`SHAPES`] shape functions over the
/// fitted groups of one trace (upper triangle, `i ≤ j`), with the trace's set-up that turns
/// shapes into terms.
#[derive(Debug)]
struct Gram {
    sum: [[f64; SHAPES]; SHAPES],
    radius_um: f64,
    feed_um_per_ms: f64,
}

impl Gram {
    /// `Σ w fₐ f_b` for shapes `a` and `b` in either order.
    fn get(&self, a: usize, b: usize) -> f64 {
        self.sum[a.min(b)][a.max(b)]
    }
}

impl Normal {
    /// The normal equations of `terms` on the prepared traces of a test, accumulated group by
    /// group from the [`SHAPES`] shape functions (each term is one of them times a factor of
    /// the trace's set-up), without a design matrix.
    pub fn new(plane: Plane, terms: &[Term], traces: &[&Samples]) -> Result<Self, FitError> {
        let m: usize = traces.iter().map(|s| s.fit_groups().count()).sum();
        let n = terms.len();
        if m <= n {
            return Err(FitError::TooFewSamples {
                groups: m,
                terms: n,
            });
        }
        let mut ata = DMatrix::<f64>::zeros(n, n);
        let mut aty = DVector::<f64>::zeros(n);
        let mut yy = 0.0;
        let mut maps: Vec<Vec<(usize, f64)>> = Vec::new();
        let mut grams = Vec::new();
        for s in traces {
            let map: Vec<(usize, f64)> = terms
                .iter()
                .map(|t| t.shape(plane, s.radius_um, s.feed_um_per_ms))
                .collect();
            let mut sum = [[0.0; SHAPES]; SHAPES];
            let mut sum_y = [0.0; SHAPES];
            for (pt, y, w) in s.fit_groups() {
                let f = shapes(pt);
                let w = *w as f64;
                yy += w * y * y;
                for i in 0..SHAPES {
                    let wf = w * f[i];
                    sum_y[i] += wf * y;
                    for j in i..SHAPES {
                        sum[i][j] += wf * f[j];
                    }
                }
            }
            let gram = Gram {
                sum,
                radius_um: s.radius_um,
                feed_um_per_ms: s.feed_um_per_ms,
            };
            for (i, (si, ki)) in map.iter().enumerate() {
                aty[i] += ki * sum_y[*si];
                for (j, (sj, kj)) in map.iter().enumerate() {
                    ata[(i, j)] += ki * kj * gram.get(*si, *sj);
                }
            }
            maps.push(map);
            grams.push(gram);
        }
        let chol = ata.cholesky().ok_or(FitError::Singular)?;
        let inv = chol.inverse();
        Ok(Self {
            plane,
            terms: terms.to_vec(),
            chol,
            inv,
            aty,
            yy,
            groups: m,
            maps,
            grams: Arc::new(grams),
        })
    }

    /// Moves the mean of a fitted group of trace `trace` (point `pt`, `w` samples) from `from`
    /// to `to` µm.
    pub fn shift(&mut self, trace: usize, pt: &Point, w: usize, from: f64, to: f64) {
        let (f, w) = (shapes(pt), w as f64);
        for (i, (si, ki)) in self.maps[trace].iter().enumerate() {
            self.aty[i] += ki * w * f[*si] * (to - from);
        }
        self.yy += w * (to * to - from * from);
    }

    /// The test plane.
    pub fn plane(&self) -> Plane {
        self.plane
    }

    /// How much each fitted term's estimate moves per unit of `other`, a term left out of the
    /// fit, in the order of the fit's terms: the regression's alias matrix
    /// `(AᵀWA)⁻¹AᵀW b`, with `b` the signature of one unit of `other` over the fitted groups of
    /// the traces (`AᵀW b` from the sums the normal equations were made from). An effect the
    /// test cannot fit biases the reported terms by exactly this much per unit of it, whatever
    /// the noise.
    pub fn alias(&self, other: Term) -> Vec<f64> {
        let mut atb = DVector::<f64>::zeros(self.terms.len());
        for (gram, map) in self.grams.iter().zip(&self.maps) {
            let (sb, kb) = other.shape(self.plane, gram.radius_um, gram.feed_um_per_ms);
            for (i, (si, ki)) in map.iter().enumerate() {
                atb[i] += ki * kb * gram.get(*si, sb);
            }
        }
        self.chol.solve(&atb).iter().copied().collect()
    }

    /// Standard errors of `fit` (the solution of these equations) that hold when the residual
    /// is correlated from group to group, as the model's misfit is (an unmodelled effect, a
    /// transient's tail): batch means of the groups' scores (a long-run, HAC, variance
    /// estimate). `residuals` are, per trace in the order the equations were made from, the
    /// fitted groups' points, mean residuals (µm) and sizes, in sample order.
    ///
    /// ```text
    /// u_g = w_g r̄_g a_g                   score of group g (a_g its row of A)
    /// U_b = Σ_{g ∈ block b} u_g           B consecutive groups per block
    /// V   = c (AᵀWA)⁻¹ (Σ_b U_b U_bᵀ) (AᵀWA)⁻¹,   c = n_b/(n_b − n)
    /// ```
    ///
    /// over the n_b blocks of all traces, n terms. The block length comes from the groups'
    /// lag-one autocorrelation ρ of `√w r̄` by Andrews' (1991) AR(1) rule for the Bartlett
    /// kernel, `B = ⌈1.1447 (α m_k)^⅓⌉`, `α = 4ρ²/((1−ρ)²(1+ρ)²)`, for a trace of m_k groups
    /// (B = 1, the heteroskedasticity-robust estimate, for white noise), at most `m_k/(2n)` so
    /// that the blocks outnumber the terms. The residual is orthogonal to the terms' signatures,
    /// which are smooth over a block, so the blocks' scores hold about n of their n_b degrees
    /// of freedom less than the noise: c restores them (`m/(m − n)` for white noise, as in
    /// σ̂²). A block misses the covariance with its neighbours, `2ρ(1 − ρ^B)/(B(1 − ρ²))` of
    /// the long-run variance of an AR(1) residual; each trace's share is restored with its ρ.
    /// Each error is at least the white-noise one of [`Normal::solve`]: a correlated
    /// residual widens the interval, never narrows it.
    pub fn robust_std_errors(&self, fit: &Fit, residuals: &[Vec<(Point, f64, usize)>]) -> Vec<f64> {
        let n = self.terms.len();
        let mut meat = DMatrix::<f64>::zeros(n, n);
        let mut blocks = 0usize;
        for (groups, map) in residuals.iter().zip(&self.maps) {
            // The blocks' scores in shape space, one column each; their Gram matrix Z Zᵀ maps
            // to the terms' as the normal equations do.
            let z: Vec<f64> = groups
                .iter()
                .map(|(_, r, w)| (*w as f64).sqrt() * r)
                .collect();
            let (len, shortfall) = block_length(&z, n);
            let blocks_here = groups.len().div_ceil(len);
            let mut z = DMatrix::<f64>::zeros(SHAPES, blocks_here);
            for (mut column, block) in z.column_iter_mut().zip(groups.chunks(len)) {
                for (pt, r, w) in block {
                    let wr = *w as f64 * r;
                    for (zj, fj) in column.iter_mut().zip(shapes(pt)) {
                        *zj += wr * fj;
                    }
                }
            }
            let gram = &z * z.transpose();
            for (i, (si, ki)) in map.iter().enumerate() {
                for (j, (sj, kj)) in map.iter().enumerate() {
                    meat[(i, j)] += ki * kj * gram[(*si, *sj)] / shortfall;
                }
            }
            blocks += blocks_here;
        }
        let dof = blocks as f64 / (blocks as f64 - n as f64).max(1.0);
        let cov = &self.inv * meat * &self.inv;
        fit.std_errors
            .iter()
            .enumerate()
            .map(|(i, se)| se.max((dof * cov[(i, i)]).max(0.0).sqrt()))
            .collect()
    }

    /// The least-squares estimates and their standard errors.
    pub fn solve(&self) -> Fit {
        let x = self.chol.solve(&self.aty);
        let rss = (self.yy - x.dot(&self.aty)).max(0.0);
        let sigma = (rss / (self.groups - self.terms.len()) as f64).sqrt();
        Fit {
            plane: self.plane,
            terms: self.terms.clone(),
            values: x.iter().copied().collect(),
            std_errors: (0..self.terms.len())
                .map(|i| sigma * self.inv[(i, i)].max(0.0).sqrt())
                .collect(),
            sample_sigma_um: sigma,
        }
    }
}

impl Fit {
    /// Peak-to-valley (µm) of one unit of each term's signature over the groups of the traces
    /// (in the order of `terms`).
    pub fn unit_contributions(&self, traces: &[&Samples]) -> Vec<f64> {
        unit_contributions(self.plane, &self.terms, traces)
    }

    /// Estimate and standard error of `term`, if it is in the model.
    pub fn get(&self, term: Term) -> Option<(f64, f64)> {
        let i = self.terms.iter().position(|t| *t == term)?;
        Some((self.values[i], self.std_errors[i]))
    }

    /// The model's deviation at `pt`, µm, leaving out the terms `except` returns true for.
    pub fn model(&self, pt: &Point, except: impl Fn(Term) -> bool) -> f64 {
        self.terms
            .iter()
            .zip(&self.values)
            .filter(|(t, _)| !except(**t))
            .map(|(t, v)| v * t.basis(pt, self.plane))
            .sum()
    }

    /// The fitted model folded into one weight per shape function, for evaluation at every
    /// sample (see [`Compiled`]).
    pub fn compiled(&self, radius_um: f64, feed_um_per_ms: f64) -> Compiled {
        let mut w = [0.0; SHAPES];
        for (term, v) in self.terms.iter().zip(&self.values) {
            let (i, k) = term.shape(self.plane, radius_um, feed_um_per_ms);
            w[i] += v * k;
        }
        Compiled { w }
    }
}

/// The block length of a batch-means (long-run) variance of the scores of a fit of `terms`
/// terms ([`Normal::robust_std_errors`]) over m groups whose weighted residuals `√w r̄` are
/// `z`, in order: Andrews' AR(1) plug-in bandwidth for the Bartlett kernel from the lag-one
/// autocorrelation ρ of `z`, between 1 and `m/(2·terms)`; and the share of the long-run
/// variance that blocks of that length hold for an AR(1) residual,
/// `1 − 2ρ(1 − ρ^B)/(B(1 − ρ²))` (1 for white noise), which the estimate is divided by.
pub(crate) fn block_length(z: &[f64], terms: usize) -> (usize, f64) {
    let var: f64 = z.iter().map(|v| v * v).sum();
    let lag: f64 = z.windows(2).map(|p| p[0] * p[1]).sum();
    let m = z.len();
    if var <= 0.0 || m < 16 {
        return (1, 1.0);
    }
    let rho = (lag / var).clamp(-0.99, 0.99);
    let alpha = 4.0 * rho * rho / ((1.0 - rho).powi(2) * (1.0 + rho).powi(2));
    let b = (1.1447 * (alpha * m as f64).cbrt()).ceil() as usize;
    let b = b.clamp(1, (m / (2 * terms)).max(1));
    let shortfall = 1.0 - 2.0 * rho * (1.0 - rho.powi(b as i32)) / (b as f64 * (1.0 - rho * rho));
    (b, shortfall)
}

/// Peak-to-valley (µm) of one unit of the signature of each of `terms` over the groups of the
/// traces (in the order of `terms`).
pub fn unit_contributions(plane: Plane, terms: &[Term], traces: &[&Samples]) -> Vec<f64> {
    let mut ranges = vec![(f64::INFINITY, f64::NEG_INFINITY); terms.len()];
    for s in traces {
        let (mut lo, mut hi) = ([f64::INFINITY; SHAPES], [f64::NEG_INFINITY; SHAPES]);
        for (pt, _, _) in &s.groups {
            let f = shapes(pt);
            // By comparisons, which the compiler runs on vectors (the shapes are finite).
            for i in 0..SHAPES {
                lo[i] = if f[i] < lo[i] { f[i] } else { lo[i] };
                hi[i] = if f[i] > hi[i] { f[i] } else { hi[i] };
            }
        }
        for (term, range) in terms.iter().zip(&mut ranges) {
            let (i, k) = term.shape(plane, s.radius_um, s.feed_um_per_ms);
            if lo[i] > hi[i] {
                continue;
            }
            let (a, b) = (k * lo[i], k * hi[i]);
            range.0 = range.0.min(a.min(b));
            range.1 = range.1.max(a.max(b));
        }
    }
    ranges
        .iter()
        .map(|(lo, hi)| if hi >= lo { hi - lo } else { 0.0 })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::samples::Placement;
    use crate::trace::Sense;
    use proptest::prelude::*;

    const ALL: [Term; 17] = [
        Term::Radius,
        Term::Pivot(0),
        Term::Pivot(1),
        Term::RadialDrift,
        Term::PivotDrift(0),
        Term::PivotDrift(1),
        Term::ScaleMismatch,
        Term::Squareness,
        Term::ServoMismatch,
        Term::Backlash(0),
        Term::Backlash(1),
        Term::LateralPlay(0),
        Term::LateralPlay(1),
        Term::AngularPlay(0),
        Term::AngularPlay(1),
        Term::Straightness(0),
        Term::Straightness(1),
    ];

    /// A 90° data arc, the shortest a test may have, records a little less (89.9° at 1 kHz):
    /// its CW and CCW runs still give scale, squareness and servo mismatch; 87° does not.
    #[test]
    fn a_quarter_circle_run_both_ways_fits_scale_squareness_and_servo_mismatch() {
        let run = |sense: Sense, sweep: f64| {
            let n = 900;
            let s = sense.sign();
            Trace {
                label: "q".into(),
                plane: Plane::Xy,
                sense,
                radius_mm: 50.0,
                feed_mm_min: 3000.0,
                angle_deg: (0..n)
                    .map(|i| s * sweep * i as f64 / (n - 1) as f64)
                    .collect(),
                deviation_um: vec![0.0; n],
                time_s: None,
            }
        };
        for (sweep, fitted) in [(89.9, true), (87.0, false)] {
            let (ccw, cw) = (run(Sense::Ccw, sweep), run(Sense::Cw, sweep));
            let terms = Terms::for_test(&[&ccw, &cw]);
            for t in [Term::ScaleMismatch, Term::Squareness, Term::ServoMismatch] {
                assert_eq!(terms.terms.contains(&t), fitted, "{sweep}: {t:?}");
            }
            if !fitted {
                let why = terms
                    .left_out
                    .iter()
                    .find(|(t, _)| *t == Term::ServoMismatch);
                assert_eq!(why.map(|w| w.1), Some("needs an arc of at least 90 deg"));
            }
        }
    }

    /// The alias of a term the fit holds is that term alone (one unit of itself, nothing of
    /// the others); that of a term left out is the fit of its signature, to rounding. Both for
    /// terms whose factor is the radius (squareness) or the feed (servo mismatch), and for the
    /// drifts, which follow the test's progress.
    #[test]
    fn the_alias_of_a_term_is_the_fit_of_its_signature() {
        let run = |sense: Sense, start: f64| {
            let none = crate::synthetic::Errors::default();
            let p = (0.0, 1.0);
            crate::synthetic::trace(Plane::Zx, sense, 100.0, 1000.0, start, 220.0, &none, p, 1)
        };
        let traces = [run(Sense::Ccw, -110.0), run(Sense::Cw, 110.0)];
        let terms = Terms::for_test(&traces.iter().collect::<Vec<_>>());
        // The CCW run the first half of the test, the CW run the second.
        let places: Vec<Placement> = traces
            .iter()
            .zip([-0.5, 0.0])
            .map(|(t, from)| {
                let n = t.angle_deg.len();
                let u = (0..n).map(|i| from + 0.5 * i as f64 / n as f64).collect();
                Placement::new(t, u)
            })
            .collect();
        let left_out = [
            Term::Straightness(0),
            Term::Straightness(1),
            Term::PivotDrift(1),
        ];
        let held = [Term::Squareness, Term::ServoMismatch];
        let fit_of = |effect: Option<Term>| {
            let samples: Vec<Samples> = traces
                .iter()
                .zip(&places)
                .map(|(t, p)| {
                    // With one unit of the effect as the deviation, the fit is its alias.
                    let mut s = Samples::new(t, p, &t.deviation_um);
                    for (pt, y, _) in &mut s.groups {
                        *y = effect.map_or(0.0, |b| b.basis(pt, Plane::Zx));
                    }
                    s
                })
                .collect();
            let refs: Vec<&Samples> = samples.iter().collect();
            let normal = Normal::new(Plane::Zx, &terms.terms, &refs).expect("fits");
            let alias = |t: Term| normal.alias(t);
            (
                normal.solve(),
                alias(effect.unwrap_or(held[0])),
                held.map(alias),
            )
        };
        let (_, _, own) = fit_of(None);
        for (term, alias) in held.iter().zip(own) {
            let at = terms.terms.iter().position(|t| t == term);
            for (k, a) in alias.iter().enumerate() {
                let expected = f64::from(u8::from(Some(k) == at));
                assert!((a - expected).abs() < 1e-9, "{term:?} on {k}: {a}");
            }
        }
        for effect in left_out {
            assert!(!terms.terms.contains(&effect), "{effect:?} is fitted");
            let (fit, alias, _) = fit_of(Some(effect));
            for (v, a) in fit.values.iter().zip(&alias) {
                let close = (v - a).abs() < 1e-9 * (1.0 + a.abs());
                assert!(close, "{effect:?}: {v} against {a}");
            }
            assert!(
                alias.iter().any(|a| a.abs() > 0.1),
                "{effect:?} aliases nothing"
            );
        }
    }

    /// Angular play is fitted on full circles run both ways, and left out of a 220° arc (the
    /// usual vertical test), where its shape leans on the backlash's, with the reason.
    #[test]
    fn angular_play_needs_an_arc_of_270_degrees() {
        let run = |sense: Sense, sweep: f64| {
            let none = crate::synthetic::Errors::default();
            crate::synthetic::trace(
                Plane::Zx,
                sense,
                100.0,
                1000.0,
                -20.0,
                sweep,
                &none,
                (0.0, 1.0),
                1,
            )
        };
        for (sweep, fitted) in [(360.0, true), (220.0, false)] {
            let (ccw, cw) = (run(Sense::Ccw, sweep), run(Sense::Cw, sweep));
            let terms = Terms::for_test(&[&ccw, &cw]);
            assert!(terms.terms.contains(&Term::LateralPlay(0)), "{sweep}");
            assert_eq!(
                terms.terms.contains(&Term::AngularPlay(0)),
                fitted,
                "{sweep}"
            );
            let why = terms
                .left_out
                .iter()
                .find(|(t, _)| *t == Term::AngularPlay(0));
            let expected = (!fitted).then_some("needs an arc of at least 270 deg");
            assert_eq!(why.map(|w| w.1), expected, "{sweep}");
        }
    }

    /// The robust standard errors of a fit whose group means are noise with lag-one
    /// correlation `rho` (stationary, unit variance per sample), over a full XY circle run
    /// both ways at 150 mm and 1000 mm/min: their ratios to the white-noise ones, per term.
    fn robust_over_white(rho: f64, seed: u64) -> Vec<f64> {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let none = crate::synthetic::Errors::default();
        let traces: Vec<Trace> = [(Sense::Cw, (0.0, 0.5)), (Sense::Ccw, (0.5, 1.0))]
            .into_iter()
            .map(|(sense, p)| {
                crate::synthetic::trace(Plane::Xy, sense, 150.0, 1000.0, 0.0, 360.0, &none, p, 1)
            })
            .collect();
        let refs: Vec<&Trace> = traces.iter().collect();
        let terms = Terms::for_test(&refs);
        let places: Vec<Placement> = traces
            .iter()
            .zip([-0.5, 0.0])
            .map(|(t, from)| {
                let n = t.angle_deg.len();
                Placement::new(
                    t,
                    (0..n).map(|i| from + 0.5 * i as f64 / n as f64).collect(),
                )
            })
            .collect();
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let samples: Vec<Samples> = traces
            .iter()
            .zip(&places)
            .map(|(t, p)| {
                let mut s = Samples::new(t, p, &t.deviation_um);
                let mut x = 0.0;
                for (_, y, w) in &mut s.groups {
                    let e: f64 = StandardNormal.sample(&mut rng);
                    x = rho * x + (1.0 - rho * rho).sqrt() * e;
                    *y = x / (*w as f64).sqrt();
                }
                s
            })
            .collect();
        let sample_refs: Vec<&Samples> = samples.iter().collect();
        let normal = Normal::new(Plane::Xy, &terms.terms, &sample_refs).expect("fits");
        let fit = normal.solve();
        let residuals: Vec<Vec<(Point, f64, usize)>> = samples
            .iter()
            .map(|s| {
                s.fit_groups()
                    .map(|(pt, y, w)| (*pt, y - fit.model(pt, |_| false), *w))
                    .collect()
            })
            .collect();
        let robust = normal.robust_std_errors(&fit, &residuals);
        robust
            .iter()
            .zip(&fit.std_errors)
            .map(|(r, w)| r / w)
            .collect()
    }

    /// On white noise the robust errors are the white-noise ones within their own scatter
    /// (never below them); on noise correlated from group to group (ρ = 0.9, which multiplies
    /// the error of a smooth term by about √((1+ρ)/(1−ρ)) = 4.4) they grow by about that much
    /// (3.8 to 4.1 on average over the terms; 3.2 to 3.6 without the blocks' AR(1) shortfall).
    #[test]
    fn robust_errors_widen_with_the_residuals_correlation_only() {
        for seed in 0..3 {
            let white = robust_over_white(0.0, seed);
            assert!(white.iter().all(|r| (1.0..1.25).contains(r)), "{white:?}");
            let correlated = robust_over_white(0.9, seed);
            let mean = correlated.iter().sum::<f64>() / correlated.len() as f64;
            assert!((3.3..5.5).contains(&mean), "{correlated:?}");
        }
    }

    proptest! {
        /// The compiled model's residual and the sum of the terms' signatures agree at every
        /// point.
        #[test]
        fn compiled_model_equals_the_sum_of_signatures(
            theta in -7.0..7.0f64, u in 0.0..1.0f64, ccw: bool, plane in 0usize..3,
            values in proptest::collection::vec(-50.0..50.0f64, 17),
        ) {
            let plane = Plane::ALL[plane];
            let pt = Point {
                cos: theta.cos(), sin: theta.sin(),
                sense: if ccw { Sense::Ccw } else { Sense::Cw },
                progress: u, radius_um: 123e3, feed_um_per_ms: 25.0,
            };
            let fit = Fit {
                plane,
                terms: ALL.to_vec(),
                values: values.clone(),
                std_errors: vec![0.0; 17],
                sample_sigma_um: 0.0,
            };
            let direct: f64 = ALL.iter().zip(&values).map(|(t, v)| v * t.basis(&pt, plane)).sum();
            let compiled = fit.compiled(123e3, 25.0);
            let mut r = [0.0];
            compiled.residuals(pt.sense.sign(), &[pt.cos], &[pt.sin], &[u], &[1.0], &mut r);
            prop_assert!((1.0 - r[0] - direct).abs() < 1e-9 * (1.0 + direct.abs()));
        }
    }
}
