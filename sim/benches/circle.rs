//! One ISO 230-4 circular test on one core, at both plant fidelities.
//!
//! The job is the built-in scenario's (`scenarios/vmc500.toml`): a 150 mm circle in XY at
//! 1000 mm/min, 360° CW and CCW with their feed-in and feed-out arcs, servo period 125 µs, one
//! plant step per period (converged: `sim/tests/plant_step.rs`), servo log at 1 kHz and the
//! ball bar at 1 kHz. The throughput is in simulated milliseconds, so criterion's `Kelem/s` is
//! simulated seconds per wall second (the real-time factor). Goals (issue 3): multibody ≥ 50,
//! reduced ≥ 2000; issue 28: the compliant multibody (carriages on their guide blocks) ≥ 20.
//! Run: `cargo bench -p vmt-sim --bench circle`.
//!
//! Measured 24 November 2026 on the idle 2-core machine: reduced 513–574× real time (about
//! 235 ns per servo tick; 445× with two plant steps per period), multibody 119–125×; peak RSS
//! 68 MB, 48 MB since the servo log is allocated for the settling wait too (reduced 589×, 25
//! November, another machine, where it had measured 564× before).
//!
//! 25 November, since the axes are fine-interpolated between IPO samples where the path allows
//! (`sim/src/interpolator/mod.rs`, stage 4): reduced 650–683× against 595–602× for the build
//! before (criterion medians, the two builds alternated), about 190 ns per tick; multibody
//! 125×. Where a reduced tick goes now (perf): the drive step 28 % (two LuGre contacts per
//! axis, each one division and one or two inline `exp`; the three axes stage by stage, see
//! `Drive::step_all`), the per-tick bookkeeping of `simulate` 15 %, the controllers 13 %, the
//! interpolator 16 % (11 % of it handing over the setpoint; `sincos` 2 %, was 11 %), the error
//! chain at the sample rate 5 %.
//! The reduced goal needs about 60 ns per servo tick for everything (README, "Benchmarks").
//!
//! 29 November 2026, on the 2-core machine shared with other jobs (load average 9–12):
//! compliant 10.2× (14.1 s a run), multibody 36.7× right after under the same load.
//! Later that day, load 1.1–1.4: compliant 29.6× (27.3–31.5×) with the refresh that no longer
//! writes the state back into rapier after its step, against 24.0× for the build before.

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use std::time::Duration;
use vmt_sim::interpolator::Interpolator;
use vmt_sim::plant::Fidelity;
use vmt_sim::simulate::simulate;

fn bench(c: &mut Criterion) {
    let scenario = vmt_scenario::builtin().expect("the built-in scenario loads");
    let exec = scenario.execution.expect("the built-in scenario has a job");
    let ipo = Interpolator::new(&exec.job.program, &exec.controller).expect("the job plans");
    let simulated_ms = ipo.servo_ticks() as f64 * ipo.servo_period_s() * 1e3;
    let mut group = c.benchmark_group("iso230_4_circle");
    group.throughput(Throughput::Elements(simulated_ms.round() as u64));
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    group.warm_up_time(Duration::from_millis(1));
    for fidelity in [Fidelity::Reduced, Fidelity::Multibody, Fidelity::Compliant] {
        let mut settings = exec.settings;
        settings.fidelity = fidelity;
        group.measurement_time(match fidelity {
            Fidelity::Reduced => Duration::from_secs(5),
            Fidelity::Multibody | Fidelity::Compliant => Duration::from_secs(20),
        });
        group.bench_function(fidelity.name(), |b| {
            b.iter(|| {
                simulate(
                    &scenario.machine,
                    &exec.axes,
                    &exec.controller,
                    &exec.job,
                    &settings,
                    "",
                    &mut |_| {},
                )
                .expect("the job runs")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
