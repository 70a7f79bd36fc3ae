//! Errors seen in the residual of the fitted model: local shapes at axis reversals, the start
//! of a run, oscillations and periodic errors along an axis.
//!
//! All of them work on the residual `r = Δr − model` of each trace at full sample rate, with
//! the sample noise σₙ estimated robustly from first differences,
//! `σₙ = 1.4826 · MAD(rᵢ − rᵢ₋₁) / √2` (white noise survives differencing with variance 2σₙ²,
//! while smooth unmodelled shapes do not).
//!
//! - Reversal spike (Kwon's "dynamic backlash"; a quadrant glitch): after an axis reverses, its
//!   friction changes sign and the velocity loop needs time to build the new torque, so the
//!   carriage lags and the path bulges. Height: the extreme of the residual, smoothed over
//!   [`SMOOTH_MS`], within [`SPIKE_ZONE_DEG`] after the reversal, above the level around it;
//!   width: its full width at half height, ms.
//! - Per-side backlash: the step of the partial residual (residual plus the axis' backlash term)
//!   across each reversal, from medians of the windows 2…12° before and after it.
//! - Stick-slip: at creep speed near its reversal an axis sticks and jumps; the residual's
//!   high-pass part (minus a moving mean over 2°) within 10° of the reversals of an axis against
//!   the same away from all reversals: RMS ratio and peak-to-peak.
//! - High servo gain vibration: the largest line of the residual's amplitude spectrum (against
//!   time) above 5 Hz, with its frequency and amplitude; significant when it stands above the
//!   spectrum's median.
//! - Start transient: the extreme of the smoothed residual within the first 5° of a run.
//! - Cyclic error of an axis, `δ = A sin(2π x/P + φ)` along its own coordinate x (screw lead,
//!   encoder): the periodogram of the residual regressed on `cos θ · {sin, cos}(2π k x)` (for the
//!   p axis; `sin θ` for q) over spatial frequencies k from 1/R to 1/[`MIN_PITCH_MM`].

use crate::moving_mean::PrefixSums;
use crate::signatures::Point;
use crate::trace::Sense;
use realfft::RealFftPlanner;
use realfft::num_complex::Complex;
use std::cell::RefCell;

/// Smoothing window for local shapes, ms: a centred moving mean over ±SMOOTH_MS/2 (5 samples
/// at 1 kHz; the diagnosis' noise floors count SMOOTH_MS/dt = 4 of them, which errs high).
pub const SMOOTH_MS: f64 = 4.0;
/// Zone after a reversal in which a spike is looked for, deg.
pub const SPIKE_ZONE_DEG: f64 = 3.0;
/// Width of the moving mean whose remainder is the high-pass residual, deg.
pub const HIGH_PASS_DEG: f64 = 2.0;
/// Shortest pitch searched for cyclic errors, mm.
pub const MIN_PITCH_MM: f64 = 4.0;

/// One trace's residual with what is needed to place its samples.
pub struct Residual<'a> {
    /// Unwrapped angles, deg.
    pub angle_deg: &'a [f64],
    /// cos θ of the samples.
    pub cos: &'a [f64],
    /// sin θ of the samples.
    pub sin: &'a [f64],
    /// Sense of travel.
    pub sense: Sense,
    /// Residual per sample, µm.
    pub r: Vec<f64>,
    /// Prefix sums of `r`, for the smoothed residual (see [`Residual::smooth`]).
    pub sums: PrefixSums,
    /// Half-width of the window of [`Residual::smooth`], samples.
    pub smooth_half: usize,
    /// The residual minus its moving mean over [`HIGH_PASS_DEG`] (the high-pass part
    /// stick-slip is measured on).
    pub high_pass: Vec<f64>,
    /// Σ of the squares of `high_pass` over the [`Residual::settled`] samples.
    pub high_pass_sq: f64,
    /// Sample period, ms.
    pub dt_ms: f64,
    /// Sample indices at which p (0) and q (1) reverse (see [`reversals`]).
    pub reversals: &'a [Vec<usize>; 2],
    /// The samples past the transients at the start and end of the run (all of them unless
    /// [`Residual::settled_within`] says otherwise): what local shapes are measured on.
    pub settled: std::ops::Range<usize>,
}

thread_local! {
    /// The buffer the medians select in, reused between calls on a thread: allocating (and the
    /// kernel zeroing) one anew for every trace costs more than the arithmetic.
    static SCRATCH: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
}

/// The fewest first differences [`noise_sigma`] takes the median of when the series has more.
const NOISE_DIFFERENCES: usize = 16_384;

/// Robust white-noise σ of a series from the median of its first differences: of every k-th
/// of them, k = ⌊(n − 1)/`NOISE_DIFFERENCES`⌋ (from k = 2 on, differences of disjoint pairs,
/// independent; the median of at least 16 384 estimates σ to about 1 %, well within the spread
/// of the noise between runs).
pub fn noise_sigma(r: &[f64]) -> f64 {
    if r.len() < 2 {
        return 0.0;
    }
    let k = ((r.len() - 1) / NOISE_DIFFERENCES).max(1);
    let n = (r.len() - 1).div_ceil(k);
    let m = select(n, n / 2, |i| (r[k * i + 1] - r[k * i]).abs());
    1.4826 * m / std::f64::consts::SQRT_2
}

/// Median (NaN-free input): the element of rank ⌊n/2⌋.
pub fn median(v: &[f64]) -> f64 {
    median_of(0..v.len(), |i| v[i])
}

/// The median of the values `f(i)` for i in `range`.
fn median_of(range: std::ops::Range<usize>, f: impl Fn(usize) -> f64) -> f64 {
    if range.is_empty() {
        return 0.0;
    }
    select(range.len(), range.len() / 2, |i| f(range.start + i))
}

/// The element of rank `k` (in `total_cmp` order) among the `n` values `f(0)…f(n − 1)`,
/// exactly: by [`select_in_band`] when there are more than [`SELECT_DIRECT`], else (or when
/// its bracket misses) among a copy of all of them. The values are never stored in place, so
/// the callers need no copy of their own.
fn select(n: usize, k: usize, f: impl Fn(usize) -> f64) -> f64 {
    SCRATCH.with(|cell| {
        let band = &mut *cell.borrow_mut();
        // Grown only (zeroing it at every call would cost as much as the pass).
        if band.len() < n {
            band.resize(n, 0.0);
        }
        if n > SELECT_DIRECT
            && let Some(x) = select_in_band(n, k, &f, band)
        {
            return x;
        }
        for (i, x) in band[..n].iter_mut().enumerate() {
            *x = f(i);
        }
        let (_, x, _) = band[..n].select_nth_unstable_by(k, f64::total_cmp);
        *x
    })
}

/// Up to this many values are selected among directly.
const SELECT_DIRECT: usize = 2048;

/// The element of rank `k` of the `n` values `f(i)` by Floyd and Rivest's sampling: two values
/// from a sorted sample of 256 bracket rank k with high probability; one branch-free pass
/// counts the values below the bracket and copies those inside it to `band` (of at least `n`
/// values), and only the band (about a tenth of the values) is selected among. None when the
/// bracket misses (rarely).
fn select_in_band(n: usize, k: usize, f: impl Fn(usize) -> f64, band: &mut [f64]) -> Option<f64> {
    const SAMPLE: usize = 256;
    let stride = n / SAMPLE;
    let mut sample = [0.0; SAMPLE];
    for (i, x) in sample.iter_mut().enumerate() {
        *x = f(i * stride + stride / 2);
    }
    sample.sort_unstable_by(f64::total_cmp);
    let at = k * SAMPLE / n;
    let (lo, hi) = (
        sample[at.saturating_sub(16)],
        sample[(at + 16).min(SAMPLE - 1)],
    );
    let (mut below, mut m) = (0usize, 0usize);
    for i in 0..n {
        let x = f(i);
        below += usize::from(x < lo);
        band[m] = x;
        m += usize::from(x >= lo && x <= hi);
    }
    (below <= k && k < below + m).then(|| {
        let (_, x, _) = band[..m].select_nth_unstable_by(k - below, f64::total_cmp);
        *x
    })
}

/// Σ v, in eight interleaved partial sums (which the compiler keeps in vector registers).
pub fn sum(v: &[f64]) -> f64 {
    lanes(v, |x| x)
}

/// Σ v², as [`sum`].
pub fn sum_sq(v: &[f64]) -> f64 {
    lanes(v, |x| x * x)
}

fn lanes(v: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    let mut acc = [0.0; 8];
    let chunks = v.chunks_exact(8);
    let rest: f64 = chunks.remainder().iter().map(|x| f(*x)).sum();
    for c in chunks {
        for (a, x) in acc.iter_mut().zip(c) {
            *a += f(*x);
        }
    }
    acc.iter().sum::<f64>() + rest
}

/// Sample indices at which an axis reverses: where sin θ (p axis, `axis` 0) or cos θ (q axis)
/// changes sign.
pub fn reversals(points: &[Point], axis: usize) -> Vec<usize> {
    let f = |p: &Point| p.turning(axis);
    (1..points.len())
        .filter(|&i| (f(&points[i]) > 0.0) != (f(&points[i - 1]) > 0.0))
        .collect()
}

/// [`reversals`] of both axes from sin θ and cos θ: the sign changes in blocks of samples
/// are counted by a loop without branches (which the compiler runs on vectors), and only the
/// blocks with one (nearly none) are searched.
pub fn reversals_cs(cos: &[f64], sin: &[f64]) -> [Vec<usize>; 2] {
    const BLOCK: usize = 256;
    let n = cos.len().min(sin.len());
    let flips = |v: &[f64], i: usize| (v[i] > 0.0) != (v[i - 1] > 0.0);
    let mut out = [Vec::new(), Vec::new()];
    for start in (1..n).step_by(BLOCK) {
        let end = (start + BLOCK).min(n);
        let (s, c) = (&sin[start - 1..end], &cos[start - 1..end]);
        let mut count = 0u64;
        for j in 1..s.len() {
            count += u64::from((s[j] > 0.0) != (s[j - 1] > 0.0));
            count += u64::from((c[j] > 0.0) != (c[j - 1] > 0.0));
        }
        if count == 0 {
            continue;
        }
        for i in start..end {
            if flips(sin, i) {
                out[0].push(i);
            }
            if flips(cos, i) {
                out[1].push(i);
            }
        }
    }
    out
}

impl<'a> Residual<'a> {
    /// The residual `r` of a trace with angles `angle_deg`, cos θ, sin θ, sense, sample
    /// period `dt_ms` and its [`reversals_cs`].
    pub fn new(
        angle_deg: &'a [f64],
        cos: &'a [f64],
        sin: &'a [f64],
        sense: Sense,
        r: Vec<f64>,
        dt_ms: f64,
        reversals: &'a [Vec<usize>; 2],
    ) -> Self {
        let w = ((SMOOTH_MS / dt_ms).round() as usize).max(1);
        let mut res = Self {
            angle_deg,
            cos,
            sin,
            sense,
            sums: PrefixSums::new(&r),
            smooth_half: w / 2,
            high_pass: Vec::new(),
            high_pass_sq: 0.0,
            settled: 0..r.len(),
            r,
            dt_ms,
            reversals,
        };
        let w = (HIGH_PASS_DEG * res.per_deg()).round().max(3.0) as usize;
        res.high_pass = res.sums.high_pass(&res.r, w / 2);
        res.high_pass_sq = sum_sq(&res.high_pass);
        res
    }

    /// The residual with its first and last `ends_deg` of travel left out of
    /// [`Residual::settled`]: the start and end transients of the servo loops, which a feed-in
    /// at an axis reversal would otherwise put into that axis' stick-slip window.
    pub fn settled_within(mut self, ends_deg: f64) -> Self {
        let n = self.r.len();
        let ends = ((ends_deg * self.per_deg()).round() as usize).min(n / 2);
        self.settled = ends..n - ends;
        self.high_pass_sq -= sum_sq(&self.high_pass[..ends]) + sum_sq(&self.high_pass[n - ends..]);
        self
    }

    /// The residual at sample `j` smoothed over [`SMOOTH_MS`]: its centred moving mean.
    #[inline]
    pub fn smooth(&self, j: usize) -> f64 {
        self.sums.mean(j, self.smooth_half)
    }

    /// Every how many samples the smoothed residual is independent of the last: its window.
    fn smooth_width(&self) -> usize {
        2 * self.smooth_half + 1
    }

    /// Sample `i` as a signature point (progress and set-up left at zero: only the place on
    /// the circle and the sense).
    pub fn point(&self, i: usize) -> Point {
        Point {
            cos: self.cos[i],
            sin: self.sin[i],
            sense: self.sense,
            progress: 0.0,
            radius_um: 0.0,
            feed_um_per_ms: 0.0,
        }
    }

    /// Samples per degree (mean).
    fn per_deg(&self) -> f64 {
        let n = self.angle_deg.len();
        (n - 1) as f64 / (self.angle_deg[n - 1] - self.angle_deg[0]).abs().max(1e-9)
    }

    /// Index range of the samples within `[from, to]` degrees of travel from sample `i`
    /// (negative: before it), clipped to the trace.
    fn window(&self, i: usize, from: f64, to: f64) -> std::ops::Range<usize> {
        let k = self.per_deg();
        let n = self.r.len() as f64;
        let a = (i as f64 + from * k).round().clamp(0.0, n) as usize;
        let b = (i as f64 + to * k).round().clamp(0.0, n) as usize;
        a..b
    }

    /// Whether the samples `from..to` degrees around `i` are all in the trace.
    fn has(&self, i: usize, from: f64, to: f64) -> bool {
        let k = self.per_deg();
        i as f64 + from * k >= 0.0 && i as f64 + to * k <= (self.r.len() - 1) as f64
    }
}

/// A reversal spike: height (µm, + outward) and full width at half height (ms).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spike {
    /// Height above the surrounding level, µm.
    pub height_um: f64,
    /// Full width at half height, ms.
    pub width_ms: f64,
}

/// The spike after the reversal at sample `i`, if the trace holds the zone around it. The
/// level around it is the median of one smoothed value per smoothing window (the values
/// between add nothing independent).
pub fn spike(res: &Residual, i: usize) -> Option<Spike> {
    if !res.has(i, -12.0, 12.0) {
        return None;
    }
    let smooth = |j: usize| res.smooth(j);
    let k = res.smooth_width();
    let around: Vec<f64> = res
        .window(i, -12.0, -2.0)
        .step_by(k)
        .chain(res.window(i, SPIKE_ZONE_DEG + 2.0, 12.0).step_by(k))
        .map(smooth)
        .collect();
    let level = median(&around);
    let zone = res.window(i, 0.0, SPIKE_ZONE_DEG);
    let peak = zone.clone().max_by(|&a, &b| {
        (smooth(a) - level)
            .abs()
            .total_cmp(&(smooth(b) - level).abs())
    })?;
    let h = smooth(peak) - level;
    let half = |j: usize| (smooth(j) - level) * h.signum() >= 0.5 * h.abs();
    let mut a = peak;
    while a > zone.start.saturating_sub(zone.len()) && half(a - 1) {
        a -= 1;
    }
    let mut b = peak;
    while b + 1 < res.r.len() && b < zone.end + zone.len() && half(b + 1) {
        b += 1;
    }
    Some(Spike {
        height_um: h,
        width_ms: (b - a + 1) as f64 * res.dt_ms,
    })
}

/// The step (after minus before, µm) across the reversal at sample `i` of the series whose
/// sample `j` is `partial(j)` (evaluated only in the two windows).
pub fn step(res: &Residual, partial: impl Fn(usize) -> f64, i: usize) -> Option<f64> {
    if !res.has(i, -12.0, 12.0) {
        return None;
    }
    let m = |r: std::ops::Range<usize>| median_of(r, &partial);
    Some(m(res.window(i, 2.0, 12.0)) - m(res.window(i, -12.0, -2.0)))
}

/// Stick-slip measure of one axis over the traces: (RMS of the high-pass residual near the
/// axis' reversals, the same away from all reversals, peak-to-peak near the reversals), µm.
///
/// Near: within 10° of a reversal of the axis but not in the [`SPIKE_ZONE_DEG`] after it (the
/// spike is a separate error) nor within [`HIGH_PASS_DEG`]/2 of that zone, where the high-pass
/// window reaches into it (a spike of 5 µm put 0.7 µm of "stick-slip" into the degree before
/// the reversal); away: not within 10° of any reversal. Both only among the
/// [`Residual::settled`] samples. Only the samples near reversals are visited; the sum over
/// those away is the settled total less theirs.
pub fn stick_slip(residuals: &[Residual], axis: usize) -> Option<(f64, f64, f64)> {
    let (mut near_n, mut near_sq) = (0usize, 0.0);
    let (mut far_n, mut far_sq) = (0usize, 0.0);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for res in residuals {
        // Windows tagged 1 (near this axis' reversal), 2 (near the other's), 4 (spike zone).
        let mut windows: Vec<(std::ops::Range<usize>, u8)> = Vec::new();
        for (ax, tag) in [(axis, 1u8), (1 - axis, 2u8)] {
            for &i in &res.reversals[ax] {
                windows.push((res.window(i, -10.0, 10.0), tag));
                if ax == axis {
                    let reach = HIGH_PASS_DEG / 2.0;
                    windows.push((res.window(i, -reach, SPIKE_ZONE_DEG + reach), 4));
                }
            }
        }
        let settled = res.settled.clone();
        for (r, _) in &mut windows {
            *r = r.start.clamp(settled.start, settled.end)..r.end.clamp(settled.start, settled.end);
        }
        let mut bounds: Vec<usize> = windows.iter().flat_map(|(r, _)| [r.start, r.end]).collect();
        bounds.sort_unstable();
        bounds.dedup();
        let (mut covered_n, mut covered_sq) = (0usize, 0.0);
        for seg in bounds.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            let tag = windows
                .iter()
                .filter(|(r, _)| r.contains(&a))
                .fold(0u8, |t, (_, g)| t | g);
            if tag == 0 {
                continue;
            }
            let hp = &res.high_pass[a..b];
            let sq: f64 = hp.iter().map(|x| x * x).sum();
            covered_n += b - a;
            covered_sq += sq;
            if tag == 1 || tag == 3 {
                near_n += b - a;
                near_sq += sq;
                for x in hp {
                    lo = lo.min(*x);
                    hi = hi.max(*x);
                }
            }
        }
        far_n += settled.len() - covered_n;
        far_sq += (res.high_pass_sq - covered_sq).max(0.0);
    }
    if near_n < 50 || far_n < 50 {
        return None;
    }
    let rms = |sq: f64, n: usize| (sq / n as f64).sqrt();
    Some((rms(near_sq, near_n), rms(far_sq, far_n), hi - lo))
}

/// FFT plans and buffers kept between diagnoses on a thread: the planner, the real input, the
/// spectrum, the scratch, the power per bin, and the power of the strongest line's spectrum.
struct FftCache {
    planner: RealFftPlanner<f64>,
    input: Vec<f64>,
    spectrum: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
    power: Vec<f64>,
    best: Vec<f64>,
}

thread_local! {
    static FFT: RefCell<FftCache> = RefCell::new(FftCache {
        planner: RealFftPlanner::new(),
        input: Vec::new(),
        spectrum: Vec::new(),
        scratch: Vec::new(),
        power: Vec::new(),
        best: Vec::new(),
    });
}

/// The strongest line of the residuals' spectra ([`vibration`]) and the noise about it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vibration {
    /// Frequency, Hz.
    pub hz: f64,
    /// Amplitude, µm.
    pub amplitude_um: f64,
    /// Median amplitude of the spectrum searched, µm.
    pub median_um: f64,
    /// Median amplitude of the bins within [`LOCAL_BINS`] of the line (the line's own three
    /// left out), µm: the noise at its frequency, which a residual correlated in time raises
    /// at the low frequencies.
    pub local_median_um: f64,
    /// Bins searched, over every residual's spectrum.
    pub bins: usize,
    /// The factor the amplitude was corrected by for the line's place between bins (1 to
    /// π/2; see [`vibration`]).
    pub scallop: f64,
    /// Index of the residual that holds it.
    pub residual: usize,
    /// The first sample of that residual the spectrum was taken from: the end of its start
    /// transient ([`transient_end`]).
    pub start: usize,
}

/// Bins each side of a line whose median is the noise at its frequency.
pub const LOCAL_BINS: usize = 32;

impl Vibration {
    /// The half-width of the amplitude's 95 % interval, µm: the bound that noise alone keeps
    /// the largest of the [`Vibration::bins`] amplitudes under in 95 % of tests, as for a
    /// cyclic error's pitches ([`Cyclic::ci95_um`]), times the line's own correction for its
    /// place between bins. The amplitude of a noise bin is Rayleigh-distributed, with σ the
    /// local median over `√(2 ln 2)`.
    pub fn ci95_um(&self) -> f64 {
        let sigma = self.local_median_um / (2.0 * std::f64::consts::LN_2).sqrt();
        self.scallop * largest_rayleigh_bound(sigma, self.bins)
    }
}

/// The bound (µm) that the largest of `k` independent Rayleigh amplitudes of scale `sigma`
/// (µm) stays under in 95 % of tests: `P(max ≤ x) = (1 − e^{−x²/2σ²})^K`, so
/// `x = σ √(−2 ln(1 − 0.95^{1/K}))`; 2.45 σ for one (K = 1), 3.9 σ for the largest of 100.
fn largest_rayleigh_bound(sigma: f64, k: usize) -> f64 {
    let k = k.max(1) as f64;
    sigma * (-2.0 * (1.0 - 0.95f64.powf(1.0 / k)).ln()).sqrt()
}

/// Length of the blocks whose mean squares tell a run's start transient from the rest, ms.
pub const TRANSIENT_BLOCK_MS: f64 = 100.0;

/// The first sample of `r` (sampled every `dt_ms`) past its start transient: the start of the
/// first block of [`TRANSIENT_BLOCK_MS`] whose mean square is at most four times the median
/// block's (its RMS at most twice the run's typical one), at most half the run.
///
/// A run that starts with the servo loops ringing down from a feed-in (Kwon's programs have no
/// overshoot: the carriages start lagging by F/Kv at the corner, 174 µm at 4000 mm/min, and
/// ring at the position loop's few hertz, decaying over a second or two) would otherwise put a
/// line into the spectrum as strong as a vibration's, and hide a real one at another frequency;
/// a sustained vibration raises every block alike and leaves the start where it is.
pub fn transient_end(r: &[f64], dt_ms: f64) -> usize {
    let b = ((TRANSIENT_BLOCK_MS / dt_ms).round() as usize).max(1);
    let blocks: Vec<f64> = r.chunks(b).map(|c| sum_sq(c) / c.len() as f64).collect();
    let typical = median(&blocks);
    let first = blocks
        .iter()
        .position(|&ms| ms <= 4.0 * typical)
        .unwrap_or(0);
    (first * b).min(r.len() / 2)
}

/// The strongest line above `min_hz` in the spectra of the residuals past their start
/// transients ([`transient_end`]), the last of equally strong lines; the medians only of the
/// spectrum that holds it.
pub fn vibration(residuals: &[Residual], min_hz: f64) -> Option<Vibration> {
    FFT.with(|cell| {
        let cache = &mut *cell.borrow_mut();
        let mut best: Option<(Line, usize, usize)> = None;
        let mut bins = 0;
        for (i, res) in residuals.iter().enumerate() {
            let start = transient_end(&res.r, res.dt_ms);
            let Some(line) = strongest_line(&res.r[start..], res.dt_ms, min_hz, cache) else {
                continue;
            };
            bins += line.bins.len();
            if best
                .as_ref()
                .is_none_or(|(b, _, _)| line.amplitude >= b.amplitude)
            {
                std::mem::swap(&mut cache.power, &mut cache.best);
                best = Some((line, i, start));
            }
        }
        let (line, i, start) = best?;
        let spectrum = &cache.best;
        let median_um = line.amplitude_of(median(&spectrum[line.bins.clone()]));
        let near = line.peak.saturating_sub(LOCAL_BINS).max(line.bins.start)
            ..(line.peak + LOCAL_BINS + 1).min(line.bins.end);
        let local: Vec<f64> = near
            .filter(|j| j.abs_diff(line.peak) > 1)
            .map(|j| spectrum[j])
            .collect();
        Some(Vibration {
            hz: line.hz,
            amplitude_um: line.amplitude,
            median_um,
            local_median_um: line.amplitude_of(median(&local)),
            bins,
            scallop: line.scallop,
            residual: i,
            start,
        })
    })
}

/// A line of a spectrum of `n` points: frequency, amplitude, its bin, the bins searched and
/// the correction of its amplitude for its place between bins.
#[derive(Clone, Debug)]
struct Line {
    hz: f64,
    amplitude: f64,
    n: usize,
    peak: usize,
    bins: std::ops::Range<usize>,
    scallop: f64,
}

impl Line {
    /// The amplitude (µm) of a bin of power `p`.
    fn amplitude_of(&self, p: f64) -> f64 {
        2.0 * p.sqrt() / self.n as f64
    }
}

/// The strongest line above `min_hz` of the spectrum of `residual` (sampled every `dt_ms`),
/// its power per bin left in `cache.power`.
///
/// The spectrum is unwindowed, so a line at `k + δ` bins (|δ| ≤ ½) has bins of magnitude
/// `(A N/2) |sinc δ|` at `k` and `(A N/2) |sinc(1 − |δ|)|` at its larger neighbour: the
/// neighbour's share `|X_j| / (|X_k| + |X_j|)` is `|δ|` exactly (Rife & Vincent, *Use of the
/// discrete Fourier transform in the measurement of frequencies and levels of tones*, Bell Syst.
/// Tech. J. 49, 1970), and `A = 2|X_k|/N · π|δ| / sin(π|δ|)` removes the scalloping loss (up to
/// 36 % at |δ| = ½). The negative-frequency image, at least `2 min_hz` away, is neglected.
fn strongest_line(residual: &[f64], dt_ms: f64, min_hz: f64, cache: &mut FftCache) -> Option<Line> {
    // The longest prefix whose length has only the factors 2 and 3 and at most one 5: a fast
    // FFT size (the full length can be a product of large primes, which costs an order of
    // magnitude more; 56 250 = 2·3²·5⁵ costs 30 % more than 55 296 = 2¹¹·3³).
    let n = fft_length(residual.len());
    if n < 64 {
        return None;
    }
    let FftCache {
        planner,
        input,
        spectrum,
        scratch,
        power,
        ..
    } = cache;
    let fft = planner.plan_fft_forward(n);
    let r = &residual[..n];
    let mean = sum(r) / n as f64;
    input.clear();
    input.extend(r.iter().map(|x| x - mean));
    spectrum.resize(n / 2 + 1, Complex::default());
    scratch.resize(fft.get_scratch_len(), Complex::default());
    fft.process_with_scratch(input, spectrum, scratch).ok()?;
    let df = 1000.0 / (dt_ms * n as f64);
    // The line and the median are found on the power |c|²: the amplitude is a non-decreasing
    // function of it, so only the bins reported need their square root.
    power.clear();
    power.extend(spectrum.iter().map(|c| c.re * c.re + c.im * c.im));
    let first = ((min_hz / df).ceil() as usize).max(1);
    if first + 8 >= power.len() {
        return None;
    }
    let last = power.len() - 1;
    let (k, p) = strongest(&power[first..last]).map(|(k, p)| (k + first, p))?;
    // 1 <= first <= k < last: both neighbours exist.
    let (side, neighbour) = if power[k + 1] >= power[k - 1] {
        (1.0, power[k + 1])
    } else {
        (-1.0, power[k - 1])
    };
    let (peak, next) = (p.sqrt(), neighbour.sqrt());
    let delta = if peak + next > 0.0 {
        next / (peak + next)
    } else {
        0.0
    };
    let line = Line {
        hz: (k as f64 + side * delta) * df,
        amplitude: 0.0,
        n,
        peak: k,
        bins: first..last,
        scallop: 1.0,
    };
    let scallop = if delta > 1e-9 {
        std::f64::consts::PI * delta / (std::f64::consts::PI * delta).sin()
    } else {
        1.0
    };
    Some(Line {
        amplitude: line.amplitude_of(p) * scallop,
        scallop,
        ..line
    })
}

/// The index and value of the largest of NaN-free values, the last of equal ones (as
/// `max_by` with `total_cmp`, the values being powers, never −0): the largest value by four
/// interleaved maxima (which the compiler keeps in vector registers), then its last place.
fn strongest(power: &[f64]) -> Option<(usize, f64)> {
    let chunks = power.chunks_exact(4);
    let mut top = chunks
        .remainder()
        .iter()
        .fold(f64::NEG_INFINITY, |a, &x| if x > a { x } else { a });
    let mut lanes = [f64::NEG_INFINITY; 4];
    for c in chunks {
        for (a, &x) in lanes.iter_mut().zip(c) {
            *a = if x > *a { x } else { *a };
        }
    }
    for a in lanes {
        top = if a > top { a } else { top };
    }
    let k = power.iter().rposition(|&x| x == top)?;
    Some((k, top))
}

/// The largest m ≤ n of the form 2^a 3^b or 5 · 2^a 3^b.
fn fft_length(n: usize) -> usize {
    let smooth = |mut m: usize| {
        if m.is_multiple_of(5) {
            m /= 5;
        }
        for f in [2, 3] {
            while m > 1 && m.is_multiple_of(f) {
                m /= f;
            }
        }
        m == 1
    };
    (1..=n).rev().find(|&m| smooth(m)).unwrap_or(1)
}

/// The start transient of a trace: extreme of the smoothed residual in its first 5° above its
/// median elsewhere (over one sample per smoothing window: the values between add nothing
/// independent), µm.
pub fn start_transient(res: &Residual) -> Option<f64> {
    let zone = res.window(0, 0.0, 5.0);
    let rest = res.window(0, 10.0, 360.0);
    if zone.is_empty() || rest.len() < 10 {
        return None;
    }
    let k = res.smooth_width().min(rest.len() / 10);
    let n = rest.len().div_ceil(k);
    let level = select(n, n / 2, |i| res.smooth(rest.start + k * i));
    zone.map(|j| res.smooth(j) - level)
        .max_by(|a, b| a.abs().total_cmp(&b.abs()))
}

/// Travel over which the smoothed residual must stay within its band for the run to count as
/// settled, deg (the fit's least end window, [`crate::samples::TRANSIENT_MIN_DEG`]).
pub const SETTLE_HOLD_DEG: f64 = crate::samples::TRANSIENT_MIN_DEG;

/// The least half-width of the settling band, µm: the resolution the ISO figures are given to.
pub const SETTLE_BAND_MIN_UM: f64 = 0.01;

/// The band the settled residual of a run occupies: its level (the median of the smoothed
/// residual over [`Residual::settled`], one value per smoothing window: the values between add
/// nothing independent) and half-width (five robust standard deviations, 1.4826 times the
/// median absolute deviation from that level, at least [`SETTLE_BAND_MIN_UM`]), µm. It holds the
/// noise and whatever the model leaves of the path, so a transient is over once the residual is
/// back inside it. Five standard deviations: a smoothed Gaussian noise leaves a band of 5σ
/// once in 1.7 million values, so that noise alone does not put off the settling within the
/// hold's few hundred values (at 3σ it did, 2.3° into a run whose transient had settled after
/// 0.4°).
pub fn settled_band(res: &Residual) -> (f64, f64) {
    let range = res.settled.clone();
    if range.is_empty() {
        return (0.0, SETTLE_BAND_MIN_UM);
    }
    let k = res.smooth_width().min(range.len());
    let n = range.len().div_ceil(k);
    let at = |i: usize| res.smooth(range.start + k * i);
    let level = select(n, n / 2, at);
    let mad = select(n, n / 2, |i| (at(i) - level).abs());
    (level, (5.0 * 1.4826 * mad).max(SETTLE_BAND_MIN_UM))
}

/// The first sample of `res` from which its smoothed residual stays within `band` of `level`
/// over [`SETTLE_HOLD_DEG`] of travel, looked for in the first half of the run (`None` when
/// it does not settle there). With `from_end`, the same from the end of the run backwards: the
/// end (exclusive) of the samples before the run's last excursion out of the band.
pub fn settles(res: &Residual, (level, band): (f64, f64), from_end: bool) -> Option<usize> {
    let n = res.r.len();
    let hold = (SETTLE_HOLD_DEG * res.per_deg()).ceil().max(1.0) as usize;
    let half = n / 2;
    let outside = |j: usize| (res.smooth(j) - level).abs() > band;
    let mut start = 0;
    for step in 0..n {
        let j = if from_end { n - 1 - step } else { step };
        if outside(j) {
            start = step + 1;
        } else if step + 1 - start >= hold {
            return Some(if from_end { n - start } else { start });
        }
        if start > half {
            return None;
        }
    }
    None
}

/// The transient at the end of a trace: the extreme of the smoothed residual in its last 5°
/// above its median elsewhere (as [`start_transient`] at the start), µm.
pub fn end_transient(res: &Residual) -> Option<f64> {
    let n = res.r.len();
    let zone = res.window(n.saturating_sub(1), -5.0, 1.0);
    let rest = res.window(n.saturating_sub(1), -360.0, -10.0);
    if zone.is_empty() || rest.len() < 10 {
        return None;
    }
    let k = res.smooth_width().min(rest.len() / 10);
    let m = rest.len().div_ceil(k);
    let level = select(m, m / 2, |i| res.smooth(rest.start + k * i));
    zone.map(|j| res.smooth(j) - level)
        .max_by(|a, b| a.abs().total_cmp(&b.abs()))
}

/// A cyclic error of one axis: pitch (mm), amplitude (µm), and the amplitude's standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cyclic {
    /// The axis: p (0) or q (1).
    pub axis: usize,
    /// Pitch, mm.
    pub pitch_mm: f64,
    /// Amplitude, µm.
    pub amplitude_um: f64,
    /// Standard error of the amplitude, µm.
    pub std_error_um: f64,
    /// Sine and cosine amplitudes of the axis error over its coordinate from the centre, µm.
    pub sin_cos_um: [f64; 2],
    /// The pitches whose largest amplitude this is: every pitch the search tried, or 1 once the
    /// amplitude is fitted again at its pitch.
    pub pitches: usize,
}

impl Cyclic {
    /// The half-width of the amplitude's 95 % interval, µm: the bound that noise alone keeps
    /// the largest of the [`Cyclic::pitches`] amplitudes under in 95 % of tests. Each is
    /// Rayleigh-distributed with the components' standard error σ (µm), so
    /// `P(max ≤ x) = (1 − e^{−x²/2σ²})^K` and `x = σ √(−2 ln(1 − 0.95^{1/K}))`: 2.45 σ at its
    /// pitch (K = 1), 3.9 σ for the largest of 100 pitches. Without it, the largest of a search
    /// on a machine without a cyclic error (the noise floor) lay outside its interval in every
    /// run of the XY accuracy study.
    pub fn ci95_um(&self) -> f64 {
        largest_rayleigh_bound(self.std_error_um, self.pitches)
    }

    /// Its radial deviation (µm) at the angle with cosine `c` and sine `s` on a circle of
    /// `radius_mm`: the axis error `a sin(2πx/P) + b cos(2πx/P)` at `x = R c` (p) or `R s` (q),
    /// projected on the bar.
    pub fn radial_um(&self, c: f64, s: f64, radius_mm: f64) -> f64 {
        let g = if self.axis == 0 { c } else { s };
        let (sin, cos) = (std::f64::consts::TAU * radius_mm * g / self.pitch_mm).sin_cos();
        g * (self.sin_cos_um[0] * sin + self.sin_cos_um[1] * cos)
    }
}

/// Searches a cyclic error of the p (`axis` 0) or q axis in the residuals evaluated at the
/// group points `points` (residual `r`, weight `w` each).
///
/// The spatial frequencies searched, k = 1/R + m/(8R), are the harmonics n = 8 + m of the
/// period L = 8R, so with t = 2πx/L the sums of the regression at every k come from two
/// Fourier sums over the rows, `Z_a(n) = Σ w r g e^{int}` and `Z_b(n) = Σ w g² e^{int}`:
/// `Σ w r g sin(nt) = Im Z_a(n)`, `Σ w r g cos(nt) = Re Z_a(n)`, `Σ w g² sin² = (Z_b(0) − Re
/// Z_b(2n))/2`, `Σ w g² cos² = (Z_b(0) + Re Z_b(2n))/2`, `Σ w g² sin cos = Im Z_b(2n)/2`. Both
/// are evaluated at every harmonic at once by [`nufft`] (to about 1e-7 of Σ|coefficients|)
/// instead of row by row at every frequency.
pub fn cyclic(
    points: &[Point],
    r: &[f64],
    w: &[f64],
    axis: usize,
    sigma_um: f64,
) -> Option<Cyclic> {
    let radius_mm = points.first()?.radius_um * 1e-3;
    let k_max = 1.0 / MIN_PITCH_MM;
    let k_min = 1.0 / radius_mm;
    let dk = 1.0 / (8.0 * radius_mm);
    let mut ks = Vec::new();
    let mut k = k_min;
    while k <= k_max {
        ks.push(k);
        k += dk;
    }
    if ks.is_empty() {
        return None;
    }
    let n0 = (k_min / dk).round() as usize;
    let n_max = 2 * (n0 + ks.len() - 1);
    let mut t = Vec::with_capacity(points.len());
    let mut a = Vec::with_capacity(points.len());
    let mut b = Vec::with_capacity(points.len());
    for (p, (r, w)) in points.iter().zip(r.iter().zip(w)) {
        let g = p.own(axis);
        t.push(std::f64::consts::TAU * dk * radius_mm * g);
        a.push(w * r * g);
        b.push(w * g * g);
    }
    let (za, zb) = nufft(&t, &a, &b, n_max);
    let total = zb[0].re;
    let mut best: Option<(f64, f64, [f64; 2], f64)> = None;
    for (m, k) in ks.iter().enumerate() {
        let n = n0 + m;
        let z2 = zb[2 * n];
        let (ss, cc, sc) = (0.5 * (total - z2.re), 0.5 * (total + z2.re), 0.5 * z2.im);
        let (rs, rc) = (za[n].im, za[n].re);
        let det = ss * cc - sc * sc;
        if det > 0.0 {
            let a = (cc * rs - sc * rc) / det;
            let b = (ss * rc - sc * rs) / det;
            let gain = a * rs + b * rc;
            if best.is_none_or(|x| gain > x.0) {
                best = Some((gain, *k, [a, b], (2.0 / (ss + cc)).sqrt()));
            }
        }
    }
    // The grid is four times finer than the resolution 1/(2R) of a coordinate spanning 2R, and
    // the largest over it lies above the largest over independent pitches: counting every
    // pitch tried is the conservative bound (the XY accuracy study's noise floors fall within
    // it in 86 to 88 % of the runs, with a quarter of them in 71 to 74 %).
    let pitches = ks.len();
    best.map(|(_, k, [a, b], se)| Cyclic {
        axis,
        pitch_mm: 1.0 / k,
        amplitude_um: a.hypot(b),
        std_error_um: sigma_um * se,
        sin_cos_um: [a, b],
        pitches,
    })
}

/// The standard error (µm) of the sine and cosine amplitudes of cyclic error `c`, at its
/// pitch, in the residuals `r` at `points` (weight `w` each), that holds when the residual is
/// correlated from group to group as the model's misfit is: the batch-means (long-run)
/// variance of the two amplitudes' scores, as [`crate::model::Normal::robust_std_errors`]
/// makes it for the fit's terms, and never below `c`'s own white-noise error.
pub fn robust_cyclic_error(points: &[Point], r: &[f64], w: &[f64], c: &Cyclic) -> f64 {
    let rows: Vec<[f64; 2]> = points
        .iter()
        .map(|pt| {
            let g = pt.own(c.axis);
            let radius_mm = pt.radius_um * 1e-3;
            let (sin, cos) = (std::f64::consts::TAU * radius_mm * g / c.pitch_mm).sin_cos();
            [g * sin, g * cos]
        })
        .collect();
    let [a, b] = c.sin_cos_um;
    let e: Vec<f64> = rows
        .iter()
        .zip(r)
        .map(|(f, r)| r - a * f[0] - b * f[1])
        .collect();
    let z: Vec<f64> = e.iter().zip(w).map(|(e, w)| w.sqrt() * e).collect();
    let (len, shortfall) = crate::model::block_length(&z, 2);
    let mut ata = nalgebra::Matrix2::<f64>::zeros();
    let mut meat = nalgebra::Matrix2::<f64>::zeros();
    let mut blocks = 0usize;
    for ((f, e), w) in rows.chunks(len).zip(e.chunks(len)).zip(w.chunks(len)) {
        let mut u = nalgebra::Vector2::<f64>::zeros();
        for ((f, e), &w) in f.iter().zip(e).zip(w) {
            let f = nalgebra::Vector2::new(f[0], f[1]);
            ata += w * f * f.transpose();
            u += w * e * f;
        }
        meat += u * u.transpose();
        blocks += 1;
    }
    let Some(inverse) = ata.try_inverse() else {
        return c.std_error_um;
    };
    let dof = blocks as f64 / (blocks as f64 - 2.0).max(1.0) / shortfall;
    let cov = inverse * meat * inverse * dof;
    c.std_error_um
        .max((0.5 * (cov[(0, 0)] + cov[(1, 1)])).max(0.0).sqrt())
}

/// The cyclic errors `found` with their amplitudes fitted again together, at their pitches, in
/// the residuals `r` at `points` (weight `w` each): a linear least-squares fit of the sine and
/// cosine amplitude of each (their radial shapes as in [`Cyclic::radial_um`]), the standard
/// errors from the fit's covariance `σ² (AᵀWA)⁻¹` with the sample noise `sigma_um`. A singular
/// fit leaves them as they were.
pub fn refit_cyclic(
    points: &[Point],
    r: &[f64],
    w: &[f64],
    found: &[Cyclic],
    sigma_um: f64,
) -> Vec<Cyclic> {
    let cols = 2 * found.len();
    let mut ata = nalgebra::DMatrix::<f64>::zeros(cols, cols);
    let mut atr = nalgebra::DVector::<f64>::zeros(cols);
    let mut row = vec![0.0; cols];
    for (pt, (r, w)) in points.iter().zip(r.iter().zip(w)) {
        let radius_mm = pt.radius_um * 1e-3;
        for (c, pair) in found.iter().zip(row.chunks_mut(2)) {
            let g = pt.own(c.axis);
            let (sin, cos) = (std::f64::consts::TAU * radius_mm * g / c.pitch_mm).sin_cos();
            pair.copy_from_slice(&[g * sin, g * cos]);
        }
        for i in 0..cols {
            atr[i] += w * row[i] * r;
            for j in 0..cols {
                ata[(i, j)] += w * row[i] * row[j];
            }
        }
    }
    let Some(inverse) = ata.try_inverse() else {
        return found.to_vec();
    };
    let x = &inverse * atr;
    found
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let (a, b) = (x[2 * k], x[2 * k + 1]);
            let variance = 0.5 * (inverse[(2 * k, 2 * k)] + inverse[(2 * k + 1, 2 * k + 1)]);
            Cyclic {
                amplitude_um: a.hypot(b),
                std_error_um: sigma_um * variance.sqrt(),
                sin_cos_um: [a, b],
                pitches: 1,
                ..*c
            }
        })
        .collect()
}

/// Points each side of a source that the Gaussian is spread to in [`nufft`]: six give sums
/// to about 1e-7 of Σ|coefficients|, far below what the noise leaves in a periodogram (twelve
/// would give 12 digits at twice the cost).
const SPREAD: i64 = 6;

/// `(Σ_j a_j e^{i n t_j}, Σ_j b_j e^{i n t_j})` for n = 0…`n_max`, points `t_j` anywhere: the
/// type-1 non-uniform FFT by Gaussian gridding (Greengard & Lee 2004, oversampling 2,
/// `SPREAD` points each side): the sources are spread with a Gaussian onto a regular grid of
/// the period 2π, the grid is transformed, and the Gaussian's transform divided out.
pub fn nufft(
    t: &[f64],
    a: &[f64],
    b: &[f64],
    n_max: usize,
) -> (Vec<Complex<f64>>, Vec<Complex<f64>>) {
    let m_r = smooth_length_up((4 * n_max + 4).max(8 * SPREAD as usize));
    let modes = m_r as f64 / 2.0;
    // τ = π M_sp / (N² R (R − ½)) with R = 2.
    let tau = std::f64::consts::PI * SPREAD as f64 / (modes * modes * 3.0);
    let h = std::f64::consts::TAU / m_r as f64;
    let e3: Vec<f64> = (0..=SPREAD)
        .map(|k| (-(k as f64 * h).powi(2) / (4.0 * tau)).exp())
        .collect();
    let mut ga = vec![0.0; m_r];
    let mut gb = vec![0.0; m_r];
    let m_i = m_r as i64;
    let mut weights = [0.0; 2 * SPREAD as usize + 1];
    for ((t, a), b) in t.iter().zip(a).zip(b) {
        let m0 = (t / h).floor();
        let xi = t - m0 * h;
        let e1 = (-xi * xi / (4.0 * tau)).exp();
        let e2 = (xi * h / (2.0 * tau)).exp();
        // The weights at m0 + k and m0 − k from e2^±k, by products (1/e2 once: a division
        // per step would be the loop's bottleneck).
        let (mut up, mut down, e2_inv) = (e1, e1, 1.0 / e2);
        let mid = SPREAD as usize;
        weights[mid] = e1 * e3[0];
        for k in 1..=mid {
            up *= e2;
            down *= e2_inv;
            weights[mid + k] = up * e3[k];
            weights[mid - k] = down * e3[k];
        }
        // The grid index of weights[0], and the stretch of the grid before it wraps round.
        let first = (m0 as i64 - SPREAD).rem_euclid(m_i) as usize;
        let (head, tail) = weights.split_at(weights.len().min(m_r - first));
        for (g, c) in [(&mut ga, a), (&mut gb, b)] {
            for (x, w) in g[first..].iter_mut().zip(head) {
                *x += c * w;
            }
            for (x, w) in g.iter_mut().zip(tail) {
                *x += c * w;
            }
        }
    }
    FFT.with(|cell| {
        let cache = &mut *cell.borrow_mut();
        let FftCache {
            planner, scratch, ..
        } = cache;
        let fft = planner.plan_fft_forward(m_r);
        scratch.resize(fft.get_scratch_len(), Complex::default());
        // The Gaussian's transform divided out, once for both sums.
        let root = (std::f64::consts::PI / tau).sqrt();
        let factor: Vec<f64> = (0..=n_max)
            .map(|n| root * (n as f64 * n as f64 * tau).exp() / m_r as f64)
            .collect();
        let mut out = |g: &mut Vec<f64>| {
            let mut spec = fft.make_output_vec();
            fft.process_with_scratch(g, &mut spec, scratch)
                .expect("buffers of the planned lengths");
            spec.truncate(n_max + 1);
            for (z, f) in spec.iter_mut().zip(&factor) {
                *z = z.conj() * *f;
            }
            spec
        };
        (out(&mut ga), out(&mut gb))
    })
}

/// The smallest m ≥ n of the form 2^a 3^b 5^c.
fn smooth_length_up(n: usize) -> usize {
    let smooth = |mut m: usize| {
        for f in [2, 3, 5] {
            while m > 1 && m.is_multiple_of(f) {
                m /= f;
            }
        }
        m == 1
    };
    (n.max(1)..).find(|&m| smooth(m)).unwrap_or(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    use proptest::prelude::*;

    /// `n` samples of a deterministic pseudo-random sequence of σ `sigma`: sums of twelve
    /// uniforms from an LCG seeded with `seed`, nearly Gaussian.
    fn noise(seed: u64, n: usize, sigma: f64) -> Vec<f64> {
        let mut x = seed;
        (0..n)
            .map(|_| {
                let mut g = 0.0;
                for _ in 0..12 {
                    x = x
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    g += (x >> 11) as f64 / (1u64 << 53) as f64;
                }
                sigma * (g - 6.0)
            })
            .collect()
    }

    #[test]
    fn noise_sigma_of_white_noise_ignores_a_slow_trend() {
        // σ = 0.3 on a large slow sine.
        let r: Vec<f64> = noise(12345, 20000, 0.3)
            .iter()
            .enumerate()
            .map(|(i, n)| n + 5.0 * (i as f64 * 1e-3).sin())
            .collect();
        let s = noise_sigma(&r);
        assert!((s - 0.3).abs() < 0.015, "{s}");
    }

    /// A ringing `A e^(−t/τ) cos ωt` on noise of σ ends where its blocks' mean square, about
    /// `σ² + 0.73 A² e^(−2t/τ)/2` over 100 ms at τ = 0.3 s, falls to `4σ²`: at
    /// `t = (τ/2) ln(0.73 A²/6σ²)`, 1.55 s for 150 µm on 0.3 µm, rounded up to its block.
    #[test]
    fn the_start_transient_ends_where_a_ringing_falls_to_twice_the_noise() {
        let (a, tau, sigma) = (150.0, 0.3, 0.3);
        let r: Vec<f64> = noise(7, 56_548, sigma)
            .iter()
            .enumerate()
            .map(|(i, n)| {
                let t = i as f64 * 1e-3;
                n + a * (-t / tau).exp() * (std::f64::consts::TAU * 5.5 * t).cos()
            })
            .collect();
        let expected = 0.5 * tau * (0.73 * a * a / (6.0 * sigma * sigma)).ln();
        let end = transient_end(&r, 1.0) as f64 * 1e-3;
        assert!(
            (expected..expected + 0.1 + 1e-9).contains(&end),
            "{end} s against {expected} s"
        );
    }

    proptest! {
        /// A run without a transient, a sustained line of any amplitude and frequency from 5 Hz
        /// on over noise, keeps its start: a 100 ms block holds at least half a period, so its
        /// mean square is within a factor 1.6 of any other's.
        #[test]
        fn a_stationary_run_keeps_its_start(
            amplitude in 0.0..5.0f64, hz in 5.0..450.0f64, phase in 0.0..6.3f64,
            sigma in 0.05..1.0f64, seed in any::<u64>(),
        ) {
            let r: Vec<f64> = noise(seed, 20_000, sigma)
                .iter()
                .enumerate()
                .map(|(i, n)| {
                    let t = i as f64 * 1e-3;
                    n + amplitude * (std::f64::consts::TAU * hz * t + phase).cos()
                })
                .collect();
            prop_assert_eq!(transient_end(&r, 1.0), 0);
        }
    }

    /// A tone between bins keeps its amplitude and frequency (no scalloping loss), for every
    /// offset from a bin.
    #[test]
    fn a_line_between_bins_has_its_amplitude_and_frequency() {
        let n = 18_432; // 2¹¹·3²: the spectrum's length is the signal's
        let df = 1000.0 / n as f64;
        for offset in [0.0, 0.1, 0.25, 0.4, 0.5, 0.6, 0.9] {
            let hz = (1234.0 + offset) * df;
            let r: Vec<f64> = (0..n)
                .map(|i| 0.6 * (std::f64::consts::TAU * hz * i as f64 * 1e-3 + 0.3).cos())
                .collect();
            let line = FFT
                .with(|c| strongest_line(&r, 1.0, 5.0, &mut c.borrow_mut()))
                .expect("a line");
            assert!(
                (line.amplitude - 0.6).abs() < 0.6e-3,
                "offset {offset}: {} µm",
                line.amplitude
            );
            assert!(
                (line.hz - hz).abs() < 1e-3 * df,
                "offset {offset}: {} Hz against {hz} Hz",
                line.hz
            );
        }
    }

    /// The non-uniform FFT agrees with the direct sums.
    #[test]
    fn nufft_matches_direct_sums() {
        let t: Vec<f64> = (0..500)
            .map(|i| -0.78 + 1.56 * ((i * 37 % 500) as f64 / 500.0))
            .collect();
        let a: Vec<f64> = (0..500)
            .map(|i| ((i * 7 % 13) as f64 - 6.0) * 0.3)
            .collect();
        let b: Vec<f64> = (0..500).map(|i| 1.0 + (i % 5) as f64).collect();
        let (za, zb) = nufft(&t, &a, &b, 600);
        let scale_a: f64 = a.iter().map(|x| x.abs()).sum();
        let scale_b: f64 = b.iter().sum();
        for n in [0usize, 1, 8, 99, 300, 599, 600] {
            let direct = |c: &[f64]| {
                t.iter().zip(c).fold(Complex::new(0.0, 0.0), |z, (t, c)| {
                    let (s, co) = (n as f64 * t).sin_cos();
                    z + Complex::new(c * co, c * s)
                })
            };
            assert!((za[n] - direct(&a)).norm() < 1e-7 * scale_a, "a, n = {n}");
            assert!((zb[n] - direct(&b)).norm() < 1e-7 * scale_b, "b, n = {n}");
        }
    }
}
