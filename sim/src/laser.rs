//! The laser interferometer and the ISO 230-2 linear positioning test.
//!
//! # The test (ISO 230-2:2014, standard test cycle)
//!
//! [`PositioningTest::gcode`] writes the linear test cycle: from `first target - overrun` the
//! axis moves to the *datum* half the overrun before the first target (approached in the
//! positive direction, where the laser is zeroed with its reading preset to the datum
//! coordinate), then, `runs` times, forward through every target (`G1`, then `G4` dwell), on to
//! `last + overrun`, back through every target in reverse order, on to `first - overrun`. Every
//! target is therefore approached from the same side in each direction, and every reversal lies
//! outside the measured range, as the standard requires. The other two coordinates stay on the
//! beam line.
//!
//! # The instrument
//!
//! The reflector is on the tool, the interferometer on the workpiece side. The laser samples at
//! its rate and, at the end of each measuring dwell, averages the last `averaging_s` (a real
//! system triggers on position stability). Per sample, with `p = P_tool · e_a` the tool point's
//! coordinate along the axis (m, relative to the workpiece, through the model's error chain):
//!
//! ```text
//! ε    = 0.925e-6 e_T − 0.2675e-6 e_p + 0.0085e-6 e_RH − α_m e_m    compensation scale error
//! r(t) = q · round(((1 + ε) p(t) − 0.925e-6 D ΔT(t) + σ n) / q),  n ~ N(0, 1)
//! L    = x_d + mean_window r − mean_datum r                          reading, m
//! x_ij = L_ij − P_i                                                  deviation (ISO 230-2)
//! ```
//!
//! `e_T`, `e_p`, `e_RH` are the weather station's errors (reading minus true air temperature K,
//! pressure hPa, humidity %RH) and `e_m` the material sensor's (K). The sensitivities are those
//! of the refractivity of standard air at 633 nm, 20 °C, 1013.25 hPa (Edlén 1966; Birch & Downs
//! 1993: `n − 1 = 2.71e-4`, `∂n/∂T = −(n − 1)/T`, `∂n/∂p = (n − 1)/p`, water vapour `−3.63e-10`
//! per Pa, 23.4 Pa per %RH at 20 °C): a station reading the air 1 K too warm assumes a lower
//! refractive index and reads 0.925 ppm long. The material compensation normalises to 20 °C
//! with `α_m`; a sensor reading `e_m` too warm over-corrects by `α_m e_m`. The dead path `D`
//! (interferometer to reflector at the datum) is not in the compensated length: when the air
//! warms by `ΔT(t) = drift · (t − t_datum)` after zeroing, its optical path shrinks by
//! `0.925e-6 D ΔT`. `q` is the resolution, `σ` the noise of one sample.

use crate::nc::parse::NcError;
use crate::nc::program::{Motion, Program};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;
use vmt_model::Axis;
pub use vmt_model::iso230_2::Approach;
use vmt_model::iso230_2::{Deviation, Iso230_2};

/// Refractivity change of air per kelvin at 20 °C, 1013.25 hPa, 633 nm (magnitude), 1/K.
pub const DN_DT_PER_K: f64 = 0.925e-6;
/// Refractivity change of air per hPa, 1/hPa.
pub const DN_DP_PER_HPA: f64 = 0.2675e-6;
/// Refractivity change of air per %RH at 20 °C (magnitude), 1/%RH.
pub const DN_DRH_PER_PERCENT: f64 = 0.0085e-6;

/// Laser interferometer settings, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaserSpec {
    /// Resolution of one sample, m (1 nm).
    pub resolution_m: f64,
    /// Standard deviation of the noise of one sample, m.
    pub noise_m: f64,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Averaging time at the end of each dwell, s.
    pub averaging_s: f64,
    /// Air temperature sensor error (reading minus true), K.
    pub air_temperature_error_k: f64,
    /// Air pressure sensor error, hPa.
    pub air_pressure_error_hpa: f64,
    /// Humidity sensor error, %RH.
    pub humidity_error_percent: f64,
    /// Material temperature sensor error, K.
    pub material_temperature_error_k: f64,
    /// Expansion coefficient used by the material compensation, 1/K.
    pub material_alpha_per_k: f64,
    /// Dead path: interferometer to reflector at the datum, m.
    pub dead_path_m: f64,
    /// Drift of the true air temperature after zeroing, K/s.
    pub air_drift_k_per_s: f64,
}

impl Default for LaserSpec {
    fn default() -> Self {
        Self {
            resolution_m: 1e-9,
            noise_m: 0.0,
            sample_rate_hz: 1000.0,
            averaging_s: 1.0,
            air_temperature_error_k: 0.0,
            air_pressure_error_hpa: 0.0,
            humidity_error_percent: 0.0,
            material_temperature_error_k: 0.0,
            material_alpha_per_k: 11.5e-6,
            dead_path_m: 0.0,
            air_drift_k_per_s: 0.0,
        }
    }
}

impl LaserSpec {
    /// The compensation scale error ε (dimensionless; ppm × 1e-6), see the module docs.
    pub fn scale_error(&self) -> f64 {
        DN_DT_PER_K * self.air_temperature_error_k - DN_DP_PER_HPA * self.air_pressure_error_hpa
            + DN_DRH_PER_PERCENT * self.humidity_error_percent
            - self.material_alpha_per_k * self.material_temperature_error_k
    }

    /// Servo ticks from one sample to the next: the laser is read at servo ticks, so its
    /// sample period is rounded to whole servo periods of `servo_period_s`.
    pub fn sample_every(&self, servo_period_s: f64) -> usize {
        ((1.0 / self.sample_rate_hz) / servo_period_s).round() as usize
    }
}

/// One measuring dwell of the program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement {
    /// Index of the dwell block in `program.blocks`.
    pub block: usize,
    /// Index of the target (0-based).
    pub target: usize,
    /// Direction of approach.
    pub approach: Approach,
    /// Run, 0-based.
    pub run: usize,
}

/// An ISO 230-2 linear positioning test of one axis (not validated: see
/// [`PositioningTest::validate`]).
#[derive(Clone, Debug, PartialEq)]
pub struct PositioningTest {
    /// The axis.
    pub axis: Axis,
    /// Target positions on the axis, m, increasing.
    pub targets_m: Vec<f64>,
    /// The beam line: the tool point's other coordinates (the axis' own entry is ignored), m.
    pub line_m: Vector3<f64>,
    /// Number of bidirectional runs (ISO: 5).
    pub runs: usize,
    /// Dwell at every target, s.
    pub dwell_s: f64,
    /// Feed of the moves, m/s.
    pub feed_m_s: f64,
    /// Overrun past the end targets, m.
    pub overrun_m: f64,
}

impl PositioningTest {
    /// Checks the test: at least two strictly increasing finite targets, at least two runs, a
    /// finite dwell > 0, a feed > 0 and an overrun > 0. The message names what is wrong.
    pub fn validate(&self) -> Result<(), String> {
        let t = &self.targets_m;
        if t.len() < 2 || t.iter().any(|v| !v.is_finite()) || t.windows(2).any(|w| w[1] <= w[0]) {
            return Err("at least two finite target positions in increasing order".into());
        }
        if self.runs < 2 {
            return Err(format!(
                "{} runs: at least 2 (ISO 230-2 asks for 5)",
                self.runs
            ));
        }
        for (v, what) in [
            (self.dwell_s, "the dwell"),
            (self.feed_m_s, "the feed"),
            (self.overrun_m, "the overrun"),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{what} {v} must be a finite number > 0"));
            }
        }
        Ok(())
    }

    /// The tool point at axis coordinate `a` on the beam line, m.
    pub fn point(&self, a: f64) -> Vector3<f64> {
        let mut p = self.line_m;
        p[self.axis.index()] = a;
        p
    }

    fn first(&self) -> f64 {
        self.targets_m.first().copied().unwrap_or(0.0)
    }

    fn last(&self) -> f64 {
        self.targets_m.last().copied().unwrap_or(0.0)
    }

    /// Where the program starts: the first target minus the overrun, m.
    pub fn start_point(&self) -> Vector3<f64> {
        self.point(self.first() - self.overrun_m)
    }

    /// The datum coordinate, where the laser is zeroed: half the overrun before the first
    /// target, m.
    pub fn datum_m(&self) -> f64 {
        self.first() - 0.5 * self.overrun_m
    }

    /// The program (see the module docs) and its dwell blocks: the datum's, then every
    /// measurement's.
    pub fn gcode(&self) -> (String, usize, Vec<Measurement>) {
        let mut w = Writer {
            text: String::new(),
            axis: self.axis.letter(),
            blocks: 0,
        };
        let mm = |v: f64| format!("{:.4}", v * 1e3);
        w.line(&format!(
            "(vmt ISO 230-2 linear positioning test of {}: {} targets, {} runs)",
            self.axis,
            self.targets_m.len(),
            self.runs
        ));
        w.line("G21 G90 G94 G17");
        w.line(&format!("F{:.1}", self.feed_m_s * 6e4));
        w.line("(to the datum, approached in the positive direction: zero the laser)");
        w.motion(&mm(self.datum_m()));
        let datum = w.dwell(self.dwell_s);
        let mut measurements = Vec::new();
        for run in 0..self.runs {
            for approach in [Approach::Forward, Approach::Backward] {
                w.line(&format!("(run {} {})", run + 1, approach.name()));
                let order: Vec<usize> = match approach {
                    Approach::Forward => (0..self.targets_m.len()).collect(),
                    Approach::Backward => (0..self.targets_m.len()).rev().collect(),
                };
                for target in order {
                    w.motion(&mm(self.targets_m[target]));
                    let block = w.dwell(self.dwell_s);
                    measurements.push(Measurement {
                        block,
                        target,
                        approach,
                        run,
                    });
                }
                let over = match approach {
                    Approach::Forward => self.last() + self.overrun_m,
                    Approach::Backward => self.first() - self.overrun_m,
                };
                w.line("(overrun)");
                w.motion(&mm(over));
            }
        }
        w.line("M30");
        (w.text, datum, measurements)
    }

    /// Checks that `program` (parsed from [`PositioningTest::gcode`]) has a dwell at every
    /// block the generator named.
    pub fn check_program(
        &self,
        program: &Program,
        datum: usize,
        measurements: &[Measurement],
    ) -> Result<(), NcError> {
        let dwell = |b: usize| {
            matches!(
                program.blocks.get(b).map(|b| &b.motion),
                Some(Motion::Dwell { .. })
            )
        };
        match std::iter::once(datum)
            .chain(measurements.iter().map(|m| m.block))
            .find(|&b| !dwell(b))
        {
            Some(b) => Err(NcError {
                line: program.blocks.get(b).map_or(0, |b| b.span.line),
                column: 1,
                message: format!("block {b} of the positioning program is not its dwell"),
            }),
            None => Ok(()),
        }
    }
}

/// Writes G-code and counts motion blocks.
struct Writer {
    text: String,
    axis: char,
    blocks: usize,
}

impl Writer {
    fn line(&mut self, s: &str) {
        self.text.push_str(s);
        self.text.push('\n');
    }

    fn motion(&mut self, coordinate_mm: &str) {
        self.line(&format!("G1 {}{coordinate_mm}", self.axis));
        self.blocks += 1;
    }

    fn dwell(&mut self, seconds: f64) -> usize {
        self.line(&format!("G4 P{seconds}"));
        self.blocks += 1;
        self.blocks - 1
    }
}

/// A laser set up for a positioning test.
#[derive(Clone, Debug)]
pub struct LaserSetup {
    /// The instrument.
    pub spec: LaserSpec,
    /// The test.
    pub test: PositioningTest,
    /// The dwell block where the laser is zeroed.
    pub datum_block: usize,
    /// The measuring dwells.
    pub measurements: Vec<Measurement>,
}

/// One averaged laser reading.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LaserReading {
    /// End of the averaging window, s.
    pub time_s: f64,
    /// Target index i, 1-based.
    pub target: usize,
    /// Target position P_i, mm.
    pub target_mm: f64,
    /// `forward` or `backward`.
    pub direction: String,
    /// Run j, 1-based.
    pub run: usize,
    /// Laser reading P_ij, mm.
    pub reading_mm: f64,
    /// Deviation x_ij = P_ij − P_i, µm.
    pub deviation_um: f64,
}

/// The laser record of a positioning test.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LaserRun {
    /// `X`, `Y` or `Z`.
    pub axis: String,
    /// Target positions, mm.
    pub targets_mm: Vec<f64>,
    /// Number of runs.
    pub runs: usize,
    /// The beam line (the tool point's coordinates, the axis' own entry 0), mm.
    pub line_mm: [f64; 3],
    /// Every reading, in time order.
    pub readings: Vec<LaserReading>,
}

impl LaserRun {
    /// The readings as ISO 230-2 deviations (targets 0-based).
    pub fn deviations(&self) -> Vec<Deviation> {
        self.readings
            .iter()
            .map(|r| Deviation {
                target: r.target.saturating_sub(1),
                approach: if r.direction == Approach::Forward.name() {
                    Approach::Forward
                } else {
                    Approach::Backward
                },
                deviation_um: r.deviation_um,
            })
            .collect()
    }

    /// The ISO 230-2 figures of the readings.
    pub fn iso230_2(&self) -> Iso230_2 {
        Iso230_2::evaluate(&self.targets_mm, &self.deviations())
    }
}

impl LaserSetup {
    /// The ISO 230-2 figures of deviations `x_um` (µm), one per measurement of the set-up.
    pub fn iso230_2(&self, x_um: &[f64]) -> Iso230_2 {
        let targets_mm: Vec<f64> = self.test.targets_m.iter().map(|t| t * 1e3).collect();
        let deviations: Vec<Deviation> = self
            .measurements
            .iter()
            .zip(x_um)
            .map(|(m, &deviation_um)| Deviation {
                target: m.target,
                approach: m.approach,
                deviation_um,
            })
            .collect();
        Iso230_2::evaluate(&targets_mm, &deviations)
    }
}

/// Sums over one averaging window: measured samples, noise-free samples, error-chain samples,
/// and the test axis' drive (see [`DriveSample`]).
#[derive(Clone, Copy, Debug, Default)]
struct Window {
    n: usize,
    measured: f64,
    exact: f64,
    chain: f64,
    holding: f64,
    servo: f64,
}

/// The state of the test axis' drive at a laser sample, for the truth.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DriveSample {
    /// The guideway friction force on the carriage, N (against forward motion).
    pub holding_n: f64,
    /// The position the loop closes on minus the axis command, m: the motor's (as carriage
    /// travel) in semi-closed loop, the carriage's on a linear scale. What the position loop
    /// leaves at a stop, within a count or so of its feedback.
    pub servo_residual_m: f64,
}

/// The laser during a run: samples the tool point in the averaging windows of the dwells.
#[derive(Debug)]
pub struct Laser {
    setup: LaserSetup,
    rng: StdRng,
    every: usize,
    /// Averaging window `[start, end)` of each measurement, s; index `measurements.len()` is the
    /// datum.
    windows: Vec<(f64, f64)>,
    sums: Vec<Window>,
    datum_time_s: f64,
}

/// Noise-free deviations and error-chain deviations of every measurement, µm, and the state of
/// the test axis' drive while it was read: the friction the carriage rested on and where the
/// servo left it.
#[derive(Clone, Debug, PartialEq)]
pub struct LaserTruth {
    /// What a perfect laser would read: x_ij of the tool point, µm, per measurement.
    pub exact_um: Vec<f64>,
    /// The geometric/thermal error chain alone at the commanded axis positions, µm.
    pub chain_um: Vec<f64>,
    /// The guideway friction force on the test axis' carriage, averaged over each
    /// measurement's window, N (the force the guideways exert against the carriage's forward
    /// motion: positive after a forward approach). At rest it is the force that holds the
    /// carriage against the screw; the truth's drive share of the deviations follows from it.
    pub holding_force_n: Vec<f64>,
    /// The servo's residual, averaged over each measurement's window, m
    /// ([`DriveSample::servo_residual_m`]).
    pub servo_residual_m: Vec<f64>,
    /// The datum window's averages: holding force (N) and servo residual (m).
    pub datum_drive: DriveSample,
}

impl Laser {
    /// A laser for `setup`; `block_times` are the interpolator's (block, enter s, leave s);
    /// `period_s` the servo period; `seed` drives the noise.
    pub fn new(
        setup: &LaserSetup,
        block_times: &[(usize, f64, f64)],
        period_s: f64,
        seed: u64,
    ) -> Self {
        let end_of = |b: usize| {
            block_times
                .iter()
                .find(|t| t.0 == b)
                .map_or(f64::INFINITY, |t| t.2)
        };
        let avg = setup.spec.averaging_s;
        let windows = setup
            .measurements
            .iter()
            .map(|m| m.block)
            .chain([setup.datum_block])
            .map(|b| (end_of(b) - avg, end_of(b)))
            .collect::<Vec<_>>();
        Self {
            rng: StdRng::seed_from_u64(seed),
            every: setup.spec.sample_every(period_s),
            sums: vec![Window::default(); windows.len()],
            datum_time_s: windows.last().map_or(0.0, |w| w.1),
            windows,
            setup: setup.clone(),
        }
    }

    /// The axis under test.
    pub fn axis(&self) -> Axis {
        self.setup.test.axis
    }

    /// The window being sampled at servo tick `k`, time `t_s`, block `block`, if any.
    pub fn window_at(&self, k: usize, t_s: f64, block: Option<usize>) -> Option<usize> {
        let block = block?;
        if !k.is_multiple_of(self.every) {
            return None;
        }
        let n = self.setup.measurements.len();
        let i = if block == self.setup.datum_block {
            n
        } else {
            self.setup
                .measurements
                .iter()
                .position(|m| m.block == block)?
        };
        let (a, b) = self.windows[i];
        (t_s >= a - 1e-9 && t_s < b).then_some(i)
    }

    /// Adds a sample to window `i` at `t_s`: `tool` the tool point, `chain` the error chain's
    /// tool point at the commanded axis positions (m, relative to the workpiece),
    /// `drive` the test axis' drive, for the truth.
    pub fn sample(
        &mut self,
        i: usize,
        t_s: f64,
        tool: &Vector3<f64>,
        chain: &Vector3<f64>,
        drive: DriveSample,
    ) {
        let s = &self.setup.spec;
        let a = self.setup.test.axis.index();
        let drift = s.air_drift_k_per_s * (t_s - self.datum_time_s).max(0.0);
        let n: f64 = StandardNormal.sample(&mut self.rng);
        let raw =
            (1.0 + s.scale_error()) * tool[a] - DN_DT_PER_K * s.dead_path_m * drift + s.noise_m * n;
        let q = s.resolution_m;
        let w = &mut self.sums[i];
        w.n += 1;
        w.measured += if q > 0.0 { (raw / q).round() * q } else { raw };
        w.exact += tool[a];
        w.chain += chain[a];
        w.holding += drive.holding_n;
        w.servo += drive.servo_residual_m;
    }

    fn mean(&self, i: usize, f: impl Fn(&Window) -> f64) -> f64 {
        let w = &self.sums[i];
        f(w) / w.n as f64
    }

    /// The readings and the truth of every measurement; refused if an averaging window holds
    /// no sample (a rate and averaging time that [`crate::simulate::simulate`] checks, or a
    /// dwell that never ran), which would read as nothing rather than 0.
    pub fn finish(self) -> Result<(LaserRun, LaserTruth), String> {
        if let Some(i) = self.sums.iter().position(|w| w.n == 0) {
            let (a, b) = self.windows[i];
            return Err(format!(
                "the laser's averaging window from {a:.4} to {b:.4} s holds no sample (a sample every {} servo ticks, averaging {} s)",
                self.every, self.setup.spec.averaging_s
            ));
        }
        let test = &self.setup.test;
        let d = self.sums.len() - 1;
        let datum = test.datum_m();
        let relative =
            |i: usize, f: &dyn Fn(&Window) -> f64| datum + self.mean(i, f) - self.mean(d, f);
        let mut readings = Vec::new();
        let mut truth = LaserTruth {
            exact_um: Vec::new(),
            chain_um: Vec::new(),
            holding_force_n: Vec::new(),
            servo_residual_m: Vec::new(),
            datum_drive: DriveSample {
                holding_n: self.mean(d, |w| w.holding),
                servo_residual_m: self.mean(d, |w| w.servo),
            },
        };
        for (i, m) in self.setup.measurements.iter().enumerate() {
            let target = test.targets_m[m.target];
            let reading = relative(i, &|w| w.measured);
            readings.push(LaserReading {
                time_s: self.windows[i].1,
                target: m.target + 1,
                target_mm: target * 1e3,
                direction: m.approach.name().into(),
                run: m.run + 1,
                reading_mm: reading * 1e3,
                deviation_um: (reading - target) * 1e6,
            });
            truth
                .exact_um
                .push((relative(i, &|w| w.exact) - target) * 1e6);
            truth
                .chain_um
                .push((relative(i, &|w| w.chain) - target) * 1e6);
            truth.holding_force_n.push(self.mean(i, |w| w.holding));
            truth.servo_residual_m.push(self.mean(i, |w| w.servo));
        }
        Ok((
            LaserRun {
                readings,
                ..self.header()
            },
            truth,
        ))
    }

    /// The test's run with no readings yet: axis, targets, runs and beam line.
    pub fn header(&self) -> LaserRun {
        let test = &self.setup.test;
        let mut line = test.line_m * 1e3;
        line[test.axis.index()] = 0.0;
        LaserRun {
            axis: test.axis.to_string(),
            targets_mm: test.targets_m.iter().map(|t| t * 1e3).collect(),
            runs: test.runs,
            line_mm: [line.x, line.y, line.z],
            readings: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nc::parse;

    fn test() -> PositioningTest {
        PositioningTest {
            axis: Axis::Y,
            targets_m: vec![0.1, 0.15, 0.2],
            line_m: Vector3::new(0.25, 0.0, 0.2),
            runs: 2,
            dwell_s: 0.5,
            feed_m_s: 0.05,
            overrun_m: 0.004,
        }
    }

    #[test]
    fn program_has_a_dwell_at_every_target_in_both_directions() {
        let t = test();
        assert_eq!(t.validate(), Ok(()));
        let (text, datum, ms) = t.gcode();
        let p = parse(&text, t.start_point()).unwrap();
        t.check_program(&p, datum, &ms).unwrap();
        assert_eq!(ms.len(), 2 * 2 * 3);
        // Backward run 1 visits the targets from the top; its dwell follows a move down.
        let order: Vec<(usize, Approach)> =
            ms[..6].iter().map(|m| (m.target, m.approach)).collect();
        assert_eq!(order[2], (2, Approach::Forward));
        assert_eq!(order[3], (2, Approach::Backward));
        assert_eq!(order[5], (0, Approach::Backward));
        let before = |b: usize| match &p.blocks[b - 1].motion {
            Motion::Linear { to, .. } => *to,
            other => panic!("{other:?}"),
        };
        for m in &ms {
            let to = before(m.block);
            assert!((to.y - t.targets_m[m.target]).abs() < 1e-12);
            assert!((to.x - 0.25).abs() < 1e-12 && (to.z - 0.2).abs() < 1e-12);
        }
        // The datum is half the overrun below the first target, approached upwards.
        assert!((before(datum).y - 0.098).abs() < 1e-12);
        let bad = PositioningTest {
            targets_m: vec![0.2, 0.1],
            ..t.clone()
        };
        assert!(bad.validate().is_err());
        assert!(PositioningTest { runs: 1, ..t }.validate().is_err());
    }

    /// An averaging window that got no sample is an error, not a reading of 0.
    #[test]
    fn an_averaging_window_without_a_sample_is_an_error() {
        let t = test();
        let (_, datum_block, measurements) = t.gcode();
        let last = measurements.iter().map(|m| m.block).max().unwrap();
        let times: Vec<(usize, f64, f64)> =
            (0..=last).map(|b| (b, b as f64, b as f64 + 1.0)).collect();
        let setup = LaserSetup {
            spec: LaserSpec::default(),
            test: t,
            datum_block,
            measurements,
        };
        let laser = |sample_datum: bool| {
            let mut laser = Laser::new(&setup, &times, 1e-3, 1);
            let p = Vector3::new(0.0, 0.1, 0.0);
            for (i, m) in setup.measurements.iter().enumerate() {
                laser.sample(i, m.block as f64 + 0.5, &p, &p, DriveSample::default());
            }
            if sample_datum {
                let n = setup.measurements.len();
                laser.sample(n, datum_block as f64 + 0.5, &p, &p, DriveSample::default());
            }
            laser
        };
        let e = laser(false).finish().unwrap_err();
        let (a, b) = (datum_block as f64, datum_block as f64 + 1.0);
        assert_eq!(
            e,
            format!(
                "the laser's averaging window from {a:.4} to {b:.4} s holds no sample (a sample every 1 servo ticks, averaging 1 s)"
            )
        );
        assert!(laser(true).finish().is_ok());
    }

    /// The refractive index of air at the He-Ne vacuum wavelength 632.9914 nm from the updated
    /// Edlén equation of Birch & Downs (Metrologia 30:155, 1993): `t` in °C, `p` in Pa, water
    /// vapour partial pressure `f` in Pa.
    fn birch_downs_n(t: f64, p: f64, f: f64) -> f64 {
        let s2 = (1.0 / 0.632_991_4f64).powi(2);
        let ns = (8342.54 + 2_406_147.0 / (130.0 - s2) + 15998.0 / (38.9 - s2)) * 1e-8;
        let ntp =
            p * ns / 96095.43 * (1.0 + 1e-8 * (0.601 - 0.00972 * t) * p) / (1.0 + 0.003_661 * t);
        1.0 + ntp - f * (3.7345 - 0.0401 * s2) * 1e-10
    }

    /// The weather station's sensitivities against a hand value each and against the full
    /// Birch & Downs (1993) equation for air at 20 °C, 1013.25 hPa, dry: a sensor reading `e`
    /// too high makes the laser assume `n(x + e)` for the true `n(x)` and scale every length by
    /// `n(x)/n(x + e)`, so `ε = n(x) − n(x + e)` to first order. +1 hPa: −0.2675 ppm;
    /// +10 %RH (233.9 Pa of water vapour at 20 °C, saturation 2339 Pa): +0.085 ppm; +1 K:
    /// +0.925 ppm. The implemented four-digit coefficients (from `n − 1 = 2.71e-4`) agree with
    /// the full equation (`n − 1 = 2.718e-4`: −0.2684, +0.0850 and +0.9267 ppm) to 0.4 %,
    /// checked to 1 %.
    ///
    /// Catches: a term of the wrong sign (the pressure and the humidity terms have opposite
    /// signs to the temperature term), a pressure in Pa (100 times too large) or a humidity as
    /// a fraction, the pressure and humidity coefficients swapped.
    #[test]
    fn weather_sensitivities_match_hand_values_and_birch_downs() {
        let ppm = |s: LaserSpec| s.scale_error() * 1e6;
        let pressure = ppm(LaserSpec {
            air_pressure_error_hpa: 1.0,
            ..LaserSpec::default()
        });
        let humidity = ppm(LaserSpec {
            humidity_error_percent: 10.0,
            ..LaserSpec::default()
        });
        let temperature = ppm(LaserSpec {
            air_temperature_error_k: 1.0,
            ..LaserSpec::default()
        });
        assert!((pressure + 0.2675).abs() < 1e-4, "{pressure} ppm");
        assert!((humidity - 0.085).abs() < 1e-4, "{humidity} ppm");
        assert!((temperature - 0.925).abs() < 1e-4, "{temperature} ppm");
        let (t, p) = (20.0, 101_325.0);
        let n = birch_downs_n(t, p, 0.0);
        assert!((n - 1.0 - 2.718e-4).abs() < 0.001e-4, "n - 1 = {}", n - 1.0);
        let eps = |dt: f64, dp: f64, df: f64| (n - birch_downs_n(t + dt, p + dp, df)) * 1e6;
        for (name, got, full) in [
            ("+1 hPa", pressure, eps(0.0, 100.0, 0.0)),
            ("+10 %RH", humidity, eps(0.0, 0.0, 233.9)),
            ("+1 K", temperature, eps(1.0, 0.0, 0.0)),
        ] {
            assert!(
                (got - full).abs() < 0.01 * full.abs(),
                "{name}: {got} ppm implemented, {full} ppm from Birch & Downs"
            );
        }
    }

    #[test]
    fn scale_error_signs() {
        let s = LaserSpec {
            air_temperature_error_k: 1.0,
            ..LaserSpec::default()
        };
        assert!((s.scale_error() - 0.925e-6).abs() < 1e-15);
        let s = LaserSpec {
            material_temperature_error_k: 1.0,
            ..LaserSpec::default()
        };
        assert!((s.scale_error() + 11.5e-6).abs() < 1e-15);
    }
}
