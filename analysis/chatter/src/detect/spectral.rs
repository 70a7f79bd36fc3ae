//! A chatter detector that needs no hand-set band: the share of the short-time spectrum held by
//! the strongest peak that is not a forced line of the cut, at any sample rate.
//!
//! # Why
//!
//! A stable milling cut is periodic at the spindle's rotation: its vibration lies on the comb of
//! spindle-rotation harmonics k·f_r, the tooth-passing harmonics among them, and a log sampled at
//! f_s shows each of those lines at its alias ([`super::forced`]). Chatter is a self-excited
//! vibration near a structural mode at a frequency the spindle does not set (Altintas,
//! *Manufacturing Automation*, 2nd ed., §3.5; Schmitz & Smith, *Machining Dynamics*, ch. 4).
//! Energy in a fixed band (Kim et al.) rises with chatter but also with a forced line that falls
//! in the band or with a heavier stable cut, so its limit has to be re-tuned for each tool,
//! speed and machine. Taking the forced comb out first and measuring what is left as a share of
//! the total gives a dimensionless figure that is near zero for any stable cut, whatever its
//! level and run-out, and that goes to one when chatter dominates, at any frequency.
//!
//! # Method
//!
//! Frames of L samples (Hann window w, hop L/4); L is the smallest power of two from
//! [`MIN_FRAME`] with f_s/L ≤ f_r/[`BINS_PER_SPINDLE_ORDER`] (16 bins between two spindle orders:
//! a forced line masks ±2 bins, the Hann main lobe, so a line off the comb stays visible
//! unless it lies within an eighth of f_r of a forced one). A spindle so slow against the rate
//! that this takes more than [`MAX_FRAME`] samples is refused ([`DetectError::CombUnresolved`]):
//! at that rate the comb cannot be told from a chatter line. Per frame,
//! P_j = Σ_axes |Σ_i w_i x_i e^{−2πi·ij/L}|² (realfft).
//!
//! The comb's lines are those of [`forced_comb`] (spindle orders up to the alias band, one
//! sample rate by default), each at its alias a_k, covering the bins within ±2 of it. Bins below
//! f_r/2 are ignored (the feed motion, the mean). A comb line is masked (its bins taken out of
//! the search) when it is a tooth-passing harmonic below the Nyquist frequency (always there
//! in a cut), or when the log shows it as a forced line: it stands [`SEEN_DB`] above the noise
//! floor of the mean spectrum and keeps its share of the comb's power (a forced line scales
//! with the cut; one whose share of the comb grows by `growth` over the log is self-excited,
//! not forced, and stays in the search). So the lines run-out, unbalance and the folding of
//! lines above the Nyquist frequency put into the log are masked where they are, and the
//! places where the comb carries nothing stay open. A seen line is that line only where the
//! peak of the mean spectrum in its bins lies within [`ON_LINE_BINS`] of its alias (a forced
//! line is on k·f_r exactly; chatter a few Hz off it, or on a folded order's alias, is not
//! masked with it), and it is not taken for forced where the cut cannot force it more than
//! every direct tooth-passing line: a folded line (through the anti-alias filter's stop band)
//! or, for an even tooth count of 4 or more, a line at a period-doubling order N/2, 3N/2, …
//! that also stands 10 dB above both neighbouring orders (flip chatter, exactly on the comb;
//! run-out and unbalance lines are of like size from order to order). Should the masked lines cover more than
//! [`MAX_MASKED_SHARE`] of the bins, L is doubled, up to [`MAX_FRAME`]
//! ([`DetectError::CombCrowded`] beyond). With j* the largest free bin,
//!
//!   share = Σ_{|j−j*|≤2, j free} P_j / Σ_{j not ignored} P_j   (dimensionless, 0..1),
//!
//! and the frame is chattering when share > threshold (default 0.05) and P_j* is a spectral
//! line (over 30 times the median free bin, so that a noise-only frame, e.g. an air cut, never
//! qualifies however small its total); chatter is declared at the end of a frame that closes at
//! least `persistence` consecutive chattering frames (default 3) and whose peak power is at
//! least 0.9 times that of the frame `persistence − 1` hops earlier. Chatter is self-excited:
//! its amplitude grows or holds. A free vibration (tool entry, an impact) also sits at the mode,
//! off the comb, but decays as e^{−ζωt}; the milling simulator's stable cuts start with one
//! that lasts ~50 ms, which the share alone flags. The chatter frequency is j*·Δf refined by a
//! parabola through log P at j*−1, j*, j*+1: the frequency as the log shows it (an alias when
//! the chatter lies above f_s/2).
//!
//! Growth. A held peak above the threshold is not yet chatter: near the stability boundary a
//! stable cut's closed-loop mode is lightly damped, and the cut's own broad-band excitation
//! keeps it ringing as a stationary (or beating) line off the comb — in the benchmark's
//! stable cuts next to the boundary, shares of 0.03–0.09 held for the whole 0.4 s at the
//! 6.5 kHz mode while the tool's once-per-tooth deviation stayed under 2 % of the feed. Chatter
//! is self-excited: its amplitude grows exponentially until the tool leaves the cut, and then
//! either the chatter line dominates the spectrum or, near the boundary, it settles as a
//! limit cycle of moderate size (in down milling the chip thins to zero at the exit, so a few
//! µm of vibration already lift the tooth out there). So a held peak is chatter when either
//! - its share exceeds `developed_share` (default 0.12: developed chatter), or
//! - its power is at least `growth` (default 4, twice the amplitude) times the smallest peak
//!   power of the frames in the last `growth_window_s` (default 0.15 s) and one frame more
//!   (four hops: frames that overlap share their samples, so growth within one frame shows
//!   only against the frame before it): growing chatter.
//!
//! A level alone cannot tell a saturated moderate chatter from the ringing of a stable cut:
//! the cut of `vmt chatter compensate` (20 000 rpm, 0.3 mm, spectral radius 1.011 per tooth
//! period by semi-discretization) grows from the entry transient for 0.3 s and then holds a
//! share of 0.083 at 2.29 kHz, while a stable cut of the old 20 kHz evaluation set (22 105 rpm,
//! 0.16 mm) held 0.094 at 6.5 kHz from its first frame. What separates them is the growth: in
//! the stable cuts of the 20 kHz sets the peak power of a held line never rose by more than
//! 1.95 over any look-back up to 0.2 s, while a cut just past the boundary rises by 4 within
//! 0.15 s before it saturates (ρ = 1.011 per 0.75 ms tooth period makes the linear power grow
//! by 4 in 50 ms). The 0.12 and the 0.15 s were chosen on a calibration set apart from the
//! evaluation set (`docs/chatter.md`).
//!
//! # A line on the comb
//!
//! A chatter line whose alias falls on a tooth-passing harmonic's is masked with it. Its
//! growth still shows: a forced line keeps its share of the comb's power (a cut's entry raises
//! the whole comb alike), so a masked line whose share of the spectrum passes the threshold and
//! whose share of the comb grows by `growth` within the look-back, held over `persistence`
//! frames, is reported as [`HiddenLine`]: something grew there, and at this rate and speed it
//! cannot be told from the forced line. It is not a chatter verdict.
//!
//! # What the comb says
//!
//! Over the mean spectrum of all frames each comb line's level above the local noise floor (the
//! median of the free bins within [`FLOOR_BINS`] of it) is measured: the lines 10 dB or more
//! above it are the forced lines seen. The tooth count they support is the N' from 2 to 16
//! whose multiples stand highest above the other orders (mean level in dB of the orders that
//! are multiples of N' minus that of the rest, over the orders below the Nyquist frequency
//! whose bins no other order shares: a folded line's level depends on the sensor's
//! anti-alias filter): a 4-tooth cutter with run-out has every order, its multiples of 4 highest, so
//! N' = 2 or 8 scores lower than 4 (half of 2's multiples and one in eight of the rest are
//! tooth lines). When the stated teeth score 3 dB below the supported count the survey warns.
//!
//! Latency is about L + (persistence − 1)·L/4 samples after the chatter has grown to a
//! detectable share: L = 16·f_s/f_r rounded up to a power of two is 0.2–0.4 s at 3000 rev/min
//! (f_r = 50 Hz) and a quarter of that at 12 000 rev/min, whatever the rate: the resolution
//! the spindle's comb needs, not the sample rate, sets the wait.

use super::forced::{AliasBand, ForcedLine, forced_comb, spindle_hz};
use super::{DetectError, Verdict, check_channels};
use realfft::RealFftPlanner;
use std::f64::consts::PI;

/// Settings of the detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpectralSettings {
    /// Spindle speed, rev/min.
    pub spindle_rpm: f64,
    /// Teeth of the cutter.
    pub teeth: u32,
    /// How far above the sample rate forced lines reach the log.
    pub alias_band: AliasBand,
    /// Share of the spectrum in the strongest free peak above which a frame chatters.
    pub threshold: f64,
    /// Consecutive chattering frames needed.
    pub persistence: usize,
    /// Share above which a persistent, non-decaying peak is developed chatter without further
    /// evidence of growth (the tool leaves the cut and the chatter line dominates).
    pub developed_share: f64,
    /// Growth of the peak power (over its smallest value in the last `growth_window_s`) that
    /// makes a peak between `threshold` and `developed_share` chatter.
    pub growth: f64,
    /// Look-back of the growth test, s.
    pub growth_window_s: f64,
}

impl SpectralSettings {
    /// The default settings for a cut at `spindle_rpm` with `teeth` teeth.
    pub fn new(spindle_rpm: f64, teeth: u32) -> Self {
        Self {
            spindle_rpm,
            teeth,
            alias_band: AliasBand::default(),
            threshold: 0.05,
            persistence: 3,
            developed_share: 0.12,
            growth: 4.0,
            growth_window_s: 0.15,
        }
    }
}

/// One analysis frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// End of the frame, s.
    pub end_s: f64,
    /// Share of the strongest free peak (dimensionless).
    pub share: f64,
    /// Energy of all free bins over the total (dimensionless).
    pub free_ratio: f64,
    /// Frequency of the strongest free peak, Hz.
    pub peak_hz: f64,
    /// Power in that peak (the numerator of `share`), (m/s²)²·(Σw)² (FFT units).
    pub peak_power: f64,
    /// share > threshold and the peak is a spectral line.
    pub chatter: bool,
}

/// A comb line seen in the mean spectrum.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeenLine {
    /// The line.
    pub line: ForcedLine,
    /// Its level above the local noise floor, dB (power).
    pub level_db: f64,
}

/// What the comb says about the stated teeth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TeethCheck {
    /// No comb line stands 10 dB above the noise, or too few orders are told apart: nothing
    /// to check against.
    NotSeen,
    /// The comb does not pick out any tooth count (every spindle order about as strong: run-out
    /// or unbalance dominates), by less than 6 dB.
    Undecided,
    /// The stated teeth are the count the comb supports, or within 3 dB of it.
    Consistent {
        /// The count the comb supports.
        supported: u32,
        /// Its contrast, dB.
        contrast_db: f64,
    },
    /// The comb supports another count.
    Mismatch {
        /// The stated teeth.
        stated: u32,
        /// Their contrast, dB.
        stated_contrast_db: f64,
        /// The count the comb supports.
        supported: u32,
        /// Its contrast, dB.
        contrast_db: f64,
    },
}

/// A line on the comb that grew as chatter would, where it cannot be told from the forced line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HiddenLine {
    /// The forced line it sits on.
    pub line: ForcedLine,
    /// End of the frame where it was seen, s.
    pub end_s: f64,
    /// Growth of its share of the comb's power over the look-back.
    pub growth: f64,
}

/// The detector's output.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectralResult {
    /// Spindle frequency f_r, Hz.
    pub spindle_hz: f64,
    /// Tooth-passing frequency f_tp, Hz.
    pub tooth_passing_hz: f64,
    /// Frame length L, samples.
    pub frame_len: usize,
    /// Share of the bins from f_r/2 to f_s/2 the comb masks at this frame.
    pub masked_share: f64,
    /// The forced comb (every order within the alias band).
    pub comb: Vec<ForcedLine>,
    /// Per frame.
    pub frames: Vec<Frame>,
    /// The comb lines 10 dB or more above the noise, strongest first.
    pub seen: Vec<SeenLine>,
    /// The stated teeth against the comb.
    pub teeth_check: TeethCheck,
    /// A line on the comb that grew, when the verdict is no chatter.
    pub hidden: Option<HiddenLine>,
    /// Verdict.
    pub verdict: Verdict,
}

/// Shortest frame, samples.
pub const MIN_FRAME: usize = 256;
/// Longest frame, samples (0.82 s at 20 kHz, 10 s at 1.6 kHz).
pub const MAX_FRAME: usize = 16_384;
/// Bins per spindle-rotation interval f_r at least: a comb line masks ±2 bins, so a line off
/// the comb is seen unless it lies within an eighth of f_r of a forced one.
pub const BINS_PER_SPINDLE_ORDER: f64 = 16.0;
/// Largest share of the bins the masked lines may cover.
pub const MAX_MASKED_SHARE: f64 = 0.5;
/// Free bins each side of a comb line whose median is its noise floor.
pub const FLOOR_BINS: usize = 32;
/// Level above the noise floor from which a comb line counts as seen (and is masked), dB.
pub const SEEN_DB: f64 = 10.0;

/// Per bin of a frame of L samples: ignored, masked (a forced line), or free.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Bin {
    Ignored,
    Forced,
    Free,
}

/// Per comb line, the bins within ±2 of its alias (first, last) in a frame of `l` samples.
fn line_bins(l: usize, fs: f64, comb: &[ForcedLine]) -> Vec<(usize, usize)> {
    let df = fs / l as f64;
    let half = l / 2;
    comb.iter()
        .map(|c| {
            let lo = ((c.alias_hz / df - 2.0).ceil().max(0.0) as usize).min(half);
            let hi = ((c.alias_hz / df + 2.0).floor().max(0.0) as usize).min(half);
            (lo, hi)
        })
        .collect()
}

/// Largest distance, bins, between a comb line's alias and the peak of the mean spectrum in its
/// bins for that peak to be the line: a forced line lies on k·f_r exactly (the Hann window's
/// parabolic peak estimate is within a few hundredths of a bin at the levels that count), so a
/// peak a quarter of a bin or more off it is something else, chatter near the comb. A quarter
/// bin is a spindle speed within 0.4 % at the fourth order (16 bins per order), so a stated
/// speed that close still masks its tooth-passing lines' neighbours.
pub const ON_LINE_BINS: f64 = 0.25;

/// The largest power of `mean` within bins `lo..=hi`.
fn peak_power(mean: &[f64], lo: usize, hi: usize) -> f64 {
    mean[lo..=hi].iter().copied().fold(0.0, f64::max)
}

/// Whether the peak of `mean` within bins `lo..=hi` lies within [`ON_LINE_BINS`] of bin
/// position `at` (parabola through the log powers around the largest bin; a peak on the edge
/// of the range rises beyond it and is off the line).
fn on_line(mean: &[f64], lo: usize, hi: usize, at: f64) -> bool {
    let Some(j) = (lo..=hi).max_by(|&a, &b| mean[a].total_cmp(&mean[b])) else {
        return false;
    };
    if j == 0 || j + 1 >= mean.len() || (lo < hi && (j == lo || j == hi)) {
        return false;
    }
    let [a, b, c] = [mean[j - 1], mean[j], mean[j + 1]].map(|p| p.max(f64::MIN_POSITIVE).ln());
    let d = a - 2.0 * b + c;
    let offset = if d < 0.0 { 0.5 * (a - c) / d } else { 0.0 };
    (j as f64 + offset - at).abs() < ON_LINE_BINS
}

/// Comb lines that the cut cannot force more strongly than every tooth-passing line shown
/// unfolded, so that a line there which is stronger is chatter on the comb.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Unlikely {
    /// Any other line.
    No,
    /// A line shown folded: it came through the anti-alias filter's stop band (7 dB down at
    /// 0.55·f_s, 28 dB at f_s for a 4th-order filter at 0.45·f_s) from a higher harmonic of
    /// the tooth pulses or of run-out, which the cut excites less than the direct tooth lines.
    Folded,
    /// For an even tooth count N of 4 or more, an odd multiple of half the tooth-passing
    /// frequency (orders N/2, 3N/2, …), where period-doubling (flip) chatter of an interrupted
    /// cut lies (the tool alternating tooth by tooth; Insperger, Stépán et al., flip lobes of
    /// low-immersion milling). Run-out, unbalance and misalignment put lines at every order,
    /// of like size from one order to the next, so such a line is taken for chatter only when
    /// it also stands [`FLIP_OVER_NEIGHBOURS`] above both neighbouring orders (with 2 teeth
    /// those orders are run-out's own, and the rule is not applied).
    Flip,
}

/// Power ratio by which a line at a period-doubling order stands above both neighbouring
/// spindle orders to be taken for flip chatter (10 dB).
pub const FLIP_OVER_NEIGHBOURS: f64 = 10.0;

fn unlikely_forced(line: &ForcedLine, teeth: u32, fs: f64) -> Unlikely {
    if line.folded(fs) {
        Unlikely::Folded
    } else if teeth >= 4 && teeth.is_multiple_of(2) && line.order % teeth == teeth / 2 {
        Unlikely::Flip
    } else {
        Unlikely::No
    }
}

/// The bins of a frame: what each is, and which comb lines are masked.
struct Mask {
    bins: Vec<Bin>,
    /// Per comb line, its bins and whether it is masked.
    lines: Vec<((usize, usize), bool)>,
    /// Masked bins over the bins not ignored.
    masked_share: f64,
}

impl Mask {
    /// Bins below f_r/2 ignored, those of the `masked` comb lines (`ranges`) forced, the rest
    /// free.
    fn new(l: usize, fs: f64, f_r: f64, ranges: &[(usize, usize)], masked: &[bool]) -> Self {
        let df = fs / l as f64;
        let mut bins: Vec<Bin> = (0..=l / 2)
            .map(|j| {
                if (j as f64) * df < f_r / 2.0 {
                    Bin::Ignored
                } else {
                    Bin::Free
                }
            })
            .collect();
        for (&(lo, hi), _) in ranges.iter().zip(masked).filter(|(_, m)| **m) {
            for b in &mut bins[lo..=hi] {
                if *b == Bin::Free {
                    *b = Bin::Forced;
                }
            }
        }
        let counted = bins.iter().filter(|b| **b != Bin::Ignored).count();
        let forced = bins.iter().filter(|b| **b == Bin::Forced).count();
        Self {
            bins,
            lines: ranges.iter().copied().zip(masked.iter().copied()).collect(),
            masked_share: forced as f64 / counted.max(1) as f64,
        }
    }
}

/// The frame the spindle's resolution needs at `fs`: the smallest power of two from
/// [`MIN_FRAME`] with f_s/L ≤ f_r/[`BINS_PER_SPINDLE_ORDER`], refused beyond [`MAX_FRAME`].
pub fn frame_len(fs: f64, s: &SpectralSettings) -> Result<usize, DetectError> {
    let f_r = spindle_hz(s.spindle_rpm);
    let need = (BINS_PER_SPINDLE_ORDER * fs / f_r).ceil();
    if need > MAX_FRAME as f64 {
        return Err(DetectError::CombUnresolved {
            spindle_rpm: s.spindle_rpm,
            teeth: s.teeth,
            sample_rate_hz: fs,
            spindle_hz: f_r,
            frame_needed: need,
            max_frame: MAX_FRAME,
        });
    }
    Ok((need as usize).max(MIN_FRAME).next_power_of_two())
}

/// Runs the detector on `channels` (m/s², equal lengths) sampled at `fs` Hz.
pub fn detect(
    channels: &[&[f64]],
    fs: f64,
    s: &SpectralSettings,
) -> Result<SpectralResult, DetectError> {
    check_settings(s, fs)?;
    let f_r = spindle_hz(s.spindle_rpm);
    let comb = forced_comb(s.spindle_rpm, s.teeth, fs, s.alias_band);
    let mut l = frame_len(fs, s)?;
    let (spectra, line_share, masked_power, mask, levels) = loop {
        let spectra = frame_spectra(channels, fs, l)?;
        let ranges = line_bins(l, fs, &comb);
        let mut mean = vec![0.0; l / 2 + 1];
        for p in &spectra {
            for (m, v) in mean.iter_mut().zip(p) {
                *m += v;
            }
        }
        let levels = levels(&mean, &ranges);
        let first = ((f_r / 2.0) / (fs / l as f64)).ceil() as usize;
        let shares: Vec<Vec<f64>> = spectra
            .iter()
            .map(|p| line_shares(p, &ranges, first))
            .collect();
        // The direct tooth-passing lines always; every other comb line where the log shows it
        // as a forced line does, stationary against the comb (not growing as chatter does).
        let df = fs / l as f64;
        let tooth_peak = comb
            .iter()
            .zip(&ranges)
            .filter(|(c, _)| c.tooth_passing && !c.folded(fs))
            .map(|(_, &(lo, hi))| peak_power(&mean, lo, hi))
            .fold(0.0, f64::max);
        // With every tooth-passing line folded there is no direct line to compare with.
        let tooth_peak = if tooth_peak > 0.0 {
            tooth_peak
        } else {
            f64::INFINITY
        };
        let order_power = |order: u32| {
            comb.iter()
                .zip(&ranges)
                .find(|(c, _)| c.order == order)
                .map_or(0.0, |(_, &(lo, hi))| peak_power(&mean, lo, hi))
        };
        let seen: Vec<bool> = comb
            .iter()
            .zip(&ranges)
            .zip(&levels)
            .map(|((c, &(lo, hi)), db)| {
                let p = peak_power(&mean, lo, hi);
                let not_forced = match unlikely_forced(c, s.teeth, fs) {
                    Unlikely::No => false,
                    Unlikely::Folded => p > tooth_peak,
                    Unlikely::Flip => {
                        p > tooth_peak
                            && p > FLIP_OVER_NEIGHBOURS * order_power(c.order - 1)
                            && p > FLIP_OVER_NEIGHBOURS * order_power(c.order + 1)
                    }
                };
                *db >= SEEN_DB && on_line(&mean, lo, hi, c.alias_hz / df) && !not_forced
            })
            .collect();
        let seen_power = comb_shares(&spectra, &ranges, &seen, first);
        let masked: Vec<bool> = comb
            .iter()
            .enumerate()
            .map(|(k, c)| {
                (c.tooth_passing && !c.folded(fs))
                    || (seen[k] && grows(&shares, k, &seen_power, s, 0.0, None).is_none())
            })
            .collect();
        let mask = Mask::new(l, fs, f_r, &ranges, &masked);
        if mask.masked_share <= MAX_MASKED_SHARE {
            let masked_power = comb_shares(&spectra, &ranges, &masked, first);
            break (spectra, shares, masked_power, mask, levels);
        }
        if 2 * l > MAX_FRAME {
            return Err(DetectError::CombCrowded {
                spindle_rpm: s.spindle_rpm,
                sample_rate_hz: fs,
                lines: masked.iter().filter(|m| **m).count(),
                masked_share: mask.masked_share,
                max_frame: MAX_FRAME,
            });
        }
        l *= 2;
    };
    let hop = l / 4;
    let df = fs / l as f64;
    let frames: Vec<Frame> = spectra
        .iter()
        .enumerate()
        .map(|(i, p)| frame(p, &mask, df, (i * hop + l) as f64 / fs, s.threshold))
        .collect();
    // A frame holds L samples: a line's growth shows between frames that do not overlap, so the
    // look-back reaches back one frame (four hops) beyond the growth window.
    let lookback = (s.growth_window_s * fs / hop as f64).round() as usize + 4;
    let verdict = verdict(&frames, s, lookback);
    let hidden = if verdict.chatter {
        None
    } else {
        hidden_line(
            &frames,
            &line_share,
            &masked_power,
            &comb,
            &mask,
            s,
            lookback,
        )
    };
    let teeth_check = teeth_check(&comb, &levels, &mask, s.teeth, fs);
    let mut seen: Vec<SeenLine> = comb
        .iter()
        .zip(&levels)
        .filter(|(_, db)| **db >= SEEN_DB)
        .map(|(line, db)| SeenLine {
            line: *line,
            level_db: *db,
        })
        .collect();
    seen.sort_by(|a, b| b.level_db.total_cmp(&a.level_db));
    Ok(SpectralResult {
        spindle_hz: f_r,
        tooth_passing_hz: f_r * s.teeth as f64,
        frame_len: l,
        masked_share: mask.masked_share,
        comb,
        frames,
        seen,
        teeth_check,
        hidden,
        verdict,
    })
}

/// The power spectra of every frame of `l` samples (hop l/4) of `channels`.
fn frame_spectra(channels: &[&[f64]], fs: f64, l: usize) -> Result<Vec<Vec<f64>>, DetectError> {
    let len = check_channels(channels, fs, l)?;
    let mut spectra = Spectra::new(l);
    Ok((0..=(len - l) / (l / 4))
        .map(|k| spectra.power(channels, k * (l / 4)))
        .collect())
}

fn check_settings(s: &SpectralSettings, fs: f64) -> Result<(), DetectError> {
    if !(s.spindle_rpm.is_finite() && s.spindle_rpm > 0.0) {
        return Err(DetectError::Setting {
            name: "spindle speed (rev/min)",
            value: s.spindle_rpm,
            accepted: "a positive number",
        });
    }
    if s.teeth == 0 {
        return Err(DetectError::Setting {
            name: "teeth",
            value: 0.0,
            accepted: "a cutter has at least one tooth",
        });
    }
    let band = s.alias_band.sample_rates;
    if !(band.is_finite() && (0.5..=10.0).contains(&band)) {
        return Err(DetectError::Setting {
            name: "alias band (sample rates)",
            value: band,
            accepted: "from 0.5 (no alias: an ideal anti-alias filter) to 10 sample rates",
        });
    }
    if !(s.threshold > 0.0 && s.threshold < 1.0) {
        return Err(DetectError::Setting {
            name: "share threshold",
            value: s.threshold,
            accepted: "between 0 and 1",
        });
    }
    if !(s.developed_share >= s.threshold && s.developed_share <= 1.0) {
        return Err(DetectError::Setting {
            name: "developed share",
            value: s.developed_share,
            accepted: "between the share threshold and 1",
        });
    }
    if !(s.growth >= 1.0 && s.growth.is_finite()) {
        return Err(DetectError::Setting {
            name: "growth (power ratio)",
            value: s.growth,
            accepted: "a finite number of at least 1",
        });
    }
    if !(s.growth_window_s >= 0.0 && s.growth_window_s.is_finite()) {
        return Err(DetectError::Setting {
            name: "growth window (s)",
            value: s.growth_window_s,
            accepted: "a finite number of seconds, at least 0",
        });
    }
    if s.persistence == 0 {
        return Err(DetectError::Setting {
            name: "persistence (frames)",
            value: 0.0,
            accepted: "at least 1",
        });
    }
    if !(fs.is_finite() && fs > 0.0) {
        return Err(DetectError::Setting {
            name: "sample rate (Hz)",
            value: fs,
            accepted: "a positive number",
        });
    }
    Ok(())
}

/// Hann-windowed power spectra summed over channels.
struct Spectra {
    window: Vec<f64>,
    fft: std::sync::Arc<dyn realfft::RealToComplex<f64>>,
    input: Vec<f64>,
    output: Vec<realfft::num_complex::Complex<f64>>,
}

impl Spectra {
    fn new(l: usize) -> Self {
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(l);
        let window = (0..l)
            .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / l as f64).cos())
            .collect();
        Self {
            window,
            input: fft.make_input_vec(),
            output: fft.make_output_vec(),
            fft,
        }
    }

    fn power(&mut self, channels: &[&[f64]], start: usize) -> Vec<f64> {
        let mut p = vec![0.0; self.output.len()];
        for c in channels {
            let seg = &c[start..start + self.window.len()];
            let mean = seg.iter().sum::<f64>() / seg.len() as f64;
            for ((d, &x), w) in self.input.iter_mut().zip(seg).zip(&self.window) {
                *d = (x - mean) * w;
            }
            // Lengths come from the plan itself, so the transform cannot fail.
            if self.fft.process(&mut self.input, &mut self.output).is_ok() {
                for (acc, v) in p.iter_mut().zip(&self.output) {
                    *acc += v.norm_sqr();
                }
            }
        }
        p
    }
}

fn frame(p: &[f64], mask: &Mask, df: f64, end_s: f64, threshold: f64) -> Frame {
    let (mut total, mut free) = (0.0, 0.0);
    let mut best: Option<usize> = None;
    for (j, (&pj, b)) in p.iter().zip(&mask.bins).enumerate() {
        match b {
            Bin::Ignored => continue,
            Bin::Forced => total += pj,
            Bin::Free => {
                total += pj;
                free += pj;
                if best.is_none_or(|k| pj > p[k]) {
                    best = Some(j);
                }
            }
        }
    }
    let (share, peak_hz, peak_power) = match best {
        Some(b) if total > 0.0 => {
            // Only free bins: the ±2 neighbours of a peak next to the comb would otherwise take
            // in a forced line's own main lobe.
            let lo = b.saturating_sub(2);
            let hi = (b + 2).min(p.len() - 1);
            let peak: f64 = (lo..=hi)
                .filter(|&j| mask.bins[j] == Bin::Free)
                .map(|j| p[j])
                .sum();
            (peak / total, refine(p, b) * df, peak)
        }
        _ => (0.0, 0.0, 0.0),
    };
    let is_line = best.is_some_and(|b| p[b] > LINE_OVER_MEDIAN * free_median(p, mask));
    Frame {
        end_s,
        share,
        free_ratio: if total > 0.0 { free / total } else { 0.0 },
        peak_hz,
        peak_power,
        chatter: share > threshold && is_line,
    }
}

/// Per comb line (its bins `ranges`), its power over the frame's total from bin `first` on
/// (the bins not ignored).
fn line_shares(p: &[f64], ranges: &[(usize, usize)], first: usize) -> Vec<f64> {
    let total: f64 = p[first.min(p.len())..].iter().sum();
    ranges
        .iter()
        .map(|&(lo, hi)| {
            if total > 0.0 {
                p[lo..=hi].iter().sum::<f64>() / total
            } else {
                0.0
            }
        })
        .collect()
}

/// Per frame, the share of its power in the bins of the comb lines `members` (each bin once).
fn comb_shares(
    spectra: &[Vec<f64>],
    ranges: &[(usize, usize)],
    members: &[bool],
    first: usize,
) -> Vec<f64> {
    let n = spectra.first().map_or(0, Vec::len);
    let mut on = vec![false; n];
    for (&(lo, hi), _) in ranges.iter().zip(members).filter(|(_, m)| **m) {
        for b in on.iter_mut().take(hi + 1).skip(lo.max(first)) {
            *b = true;
        }
    }
    spectra
        .iter()
        .map(|p| {
            let total: f64 = p[first.min(p.len())..].iter().sum();
            let comb: f64 = p.iter().zip(&on).filter(|(_, o)| **o).map(|(v, _)| v).sum();
            if total > 0.0 { comb / total } else { 0.0 }
        })
        .collect()
}

/// The first frame at which comb line `k` grows as chatter would, held over `persistence`
/// frames: its share of the spectrum (`shares`, per frame and line) above `min_share` while its
/// share of the comb's power (`comb`, per frame: the share of the spectrum the comb holds) is
/// at least `growth` times its smallest over the frames before (the last `lookback` of them;
/// all with `None`) in which the comb is active (its power at least a tenth of its median: a
/// cut's entry after an air cut raises every forced line from the noise, and is no growth of
/// one). Returns (frame, growth).
fn grows(
    shares: &[Vec<f64>],
    k: usize,
    comb: &[f64],
    s: &SpectralSettings,
    min_share: f64,
    lookback: Option<usize>,
) -> Option<(usize, f64)> {
    let active = 0.1 * median_of(comb.to_vec());
    let of_comb = |i: usize| {
        if comb[i] > 0.0 {
            shares[i][k] / comb[i]
        } else {
            0.0
        }
    };
    let mut run = 0;
    // The smallest over all active frames so far (without a look-back).
    let mut lowest_yet = f64::INFINITY;
    for (i, share) in shares.iter().enumerate() {
        let lowest = match lookback {
            Some(b) => (i.saturating_sub(b)..=i)
                .filter(|&j| comb[j] >= active)
                .map(of_comb)
                .fold(f64::INFINITY, f64::min),
            None => {
                if comb[i] >= active {
                    lowest_yet = lowest_yet.min(of_comb(i));
                }
                lowest_yet
            }
        };
        let g = of_comb(i) / lowest;
        let grew = lowest > 0.0 && lowest.is_finite() && g >= s.growth;
        run = if grew && share[k] > min_share {
            run + 1
        } else {
            0
        };
        if run >= s.persistence {
            return Some((i, g));
        }
    }
    None
}

/// A peak counts as a spectral line when it exceeds the median free bin by this factor
/// (≈ 15 dB). The bins of white noise are exponentially distributed: the largest of 256 exceeds
/// 30 medians (20.8 means) with probability 256·e^{−20.8} ≈ 2·10⁻⁷.
const LINE_OVER_MEDIAN: f64 = 30.0;

fn free_median(p: &[f64], mask: &Mask) -> f64 {
    let mut v: Vec<f64> = p
        .iter()
        .zip(&mask.bins)
        .filter(|(_, b)| **b == Bin::Free)
        .map(|(x, _)| *x)
        .collect();
    if v.is_empty() {
        return f64::INFINITY;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Bin position of the peak at `b` refined by a parabola through ln P at b−1, b, b+1.
fn refine(p: &[f64], b: usize) -> f64 {
    if b == 0 || b + 1 >= p.len() || p[b - 1] <= 0.0 || p[b + 1] <= 0.0 {
        return b as f64;
    }
    let (l, c, r) = (p[b - 1].ln(), p[b].ln(), p[b + 1].ln());
    let den = l - 2.0 * c + r;
    if den >= 0.0 {
        return b as f64;
    }
    b as f64 + 0.5 * (l - r) / den
}

/// A decaying peak is a transient, not chatter: over the persistence run the peak power may
/// fall to no less than this share of its first value.
const HOLD: f64 = 0.9;

fn verdict(frames: &[Frame], s: &SpectralSettings, lookback: usize) -> Verdict {
    let persistence = s.persistence;
    let mut run = 0;
    for (i, f) in frames.iter().enumerate() {
        run = if f.chatter { run + 1 } else { 0 };
        if run < persistence || f.peak_power < HOLD * frames[i + 1 - persistence].peak_power {
            continue;
        }
        let lowest = frames[i.saturating_sub(lookback)..=i]
            .iter()
            .map(|g| g.peak_power)
            .fold(f64::INFINITY, f64::min);
        if f.share > s.developed_share || f.peak_power >= s.growth * lowest {
            return Verdict {
                chatter: true,
                detection_time_s: Some(f.end_s),
                chatter_frequency_hz: Some(f.peak_hz),
            };
        }
    }
    Verdict {
        chatter: false,
        detection_time_s: None,
        chatter_frequency_hz: None,
    }
}

/// The first masked comb line that grows as chatter would within the look-back ([`grows`],
/// against the masked lines' power): something self-excited on a forced line's alias.
fn hidden_line(
    frames: &[Frame],
    shares: &[Vec<f64>],
    masked_power: &[f64],
    comb: &[ForcedLine],
    mask: &Mask,
    s: &SpectralSettings,
    lookback: usize,
) -> Option<HiddenLine> {
    comb.iter()
        .enumerate()
        .filter(|(k, _)| mask.lines[*k].1)
        .filter_map(|(k, line)| {
            let (i, growth) = grows(shares, k, masked_power, s, s.threshold, Some(lookback))?;
            Some(HiddenLine {
                line: *line,
                end_s: frames[i].end_s,
                growth,
            })
        })
        .min_by(|a, b| a.end_s.total_cmp(&b.end_s))
}

/// Per comb line (its bins `ranges`), its level in the mean spectrum `mean` above the noise
/// floor: the median of the bins of no comb line within [`FLOOR_BINS`] of it (of all such bins
/// when fewer than 8 are that near), dB.
fn levels(mean: &[f64], ranges: &[(usize, usize)]) -> Vec<f64> {
    let mut on_comb = vec![false; mean.len()];
    for &(lo, hi) in ranges {
        for b in &mut on_comb[lo..=hi] {
            *b = true;
        }
    }
    // Not the mean's first bins: the window's leakage of the mean removed per frame.
    let off: Vec<usize> = (3..mean.len()).filter(|&j| !on_comb[j]).collect();
    let global = median_of(off.iter().map(|&j| mean[j]).collect());
    ranges
        .iter()
        .map(|&(lo, hi)| {
            let peak = mean[lo..=hi].iter().copied().fold(0.0, f64::max);
            let centre = (lo + hi) / 2;
            let near: Vec<f64> = off
                .iter()
                .filter(|&&j| j.abs_diff(centre) <= FLOOR_BINS)
                .map(|&j| mean[j])
                .collect();
            let floor = if near.len() >= 8 {
                median_of(near)
            } else {
                global
            };
            if floor > 0.0 && peak > 0.0 {
                10.0 * (peak / floor).log10()
            } else {
                0.0
            }
        })
        .collect()
}

fn median_of(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Largest tooth count the comb is asked about.
pub const MAX_TEETH_CHECKED: u32 = 16;
/// Contrast below which the comb supports no tooth count, dB.
const CONTRAST_DB: f64 = 6.0;
/// How far the stated teeth may score below the supported count, dB.
const MISMATCH_DB: f64 = 3.0;

/// The stated `teeth` against the comb (module doc), over the orders below the Nyquist
/// frequency (`fs`): a folded line comes through the sensor's anti-alias filter weakened by an
/// amount the log does not say, so its level tells nothing of the tooth count. Orders whose
/// alias shares its bins with another order's are left out: their level cannot be given to
/// either.
fn teeth_check(
    comb: &[ForcedLine],
    levels: &[f64],
    mask: &Mask,
    teeth: u32,
    fs: f64,
) -> TeethCheck {
    if !levels.iter().any(|&db| db >= SEEN_DB) {
        return TeethCheck::NotSeen;
    }
    let alone: Vec<(u32, f64)> = comb
        .iter()
        .zip(levels)
        .zip(&mask.lines)
        .enumerate()
        .filter(|(_, ((c, _), _))| !c.folded(fs))
        .filter(|(i, (_, ((lo, hi), _)))| {
            mask.lines
                .iter()
                .enumerate()
                .all(|(j, ((a, b), _))| j == *i || *b + 2 < *lo || *a > *hi + 2)
        })
        .map(|(_, ((c, db), _))| (c.order, db.max(0.0)))
        .collect();
    let contrast = |n: u32| -> Option<f64> {
        let (mut on, mut off) = ((0.0, 0), (0.0, 0));
        for &(k, db) in &alone {
            let side = if k.is_multiple_of(n) {
                &mut on
            } else {
                &mut off
            };
            side.0 += db;
            side.1 += 1;
        }
        (on.1 > 0 && off.1 > 0).then(|| on.0 / on.1 as f64 - off.0 / off.1 as f64)
    };
    let best = (2..=MAX_TEETH_CHECKED)
        .filter_map(|n| contrast(n).map(|c| (n, c)))
        .fold(None, |acc: Option<(u32, f64)>, (n, c)| match acc {
            Some((_, b)) if b >= c => acc,
            _ => Some((n, c)),
        });
    let Some((supported, contrast_db)) = best else {
        return TeethCheck::NotSeen;
    };
    if contrast_db < CONTRAST_DB {
        return TeethCheck::Undecided;
    }
    let stated_contrast_db = if teeth == 1 {
        0.0
    } else {
        contrast(teeth).unwrap_or(f64::NEG_INFINITY)
    };
    if supported == teeth || stated_contrast_db >= contrast_db - MISMATCH_DB {
        TeethCheck::Consistent {
            supported,
            contrast_db,
        }
    } else {
        TeethCheck::Mismatch {
            stated: teeth,
            stated_contrast_db,
            supported,
            contrast_db,
        }
    }
}
