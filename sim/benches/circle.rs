//! One ISO 230-4 circular test on one core, at both plant fidelities.
//!
//! The job is the built-in scenario's (`scenarios/vmc500.toml`): a 150 mm circle in XY at
//! 1000 mm/min, 360° CW and CCW with their feed-in and feed-out arcs, servo period 125 µs, two
//! plant steps per period, servo log at 1 kHz and the ball bar at 1 kHz. The throughput is in
//! simulated milliseconds, so criterion's `Kelem/s` is simulated seconds per wall second (the
//! real-time factor). Goals (issue 3): multibody ≥ 50, reduced ≥ 2000.
//! Run: `cargo bench -p vmt-sim --bench circle`.
//!
//! Measured (2-core machine shared with other builds, load 3-14, so ±30 % between runs):
//! multibody about 80-85× (was 6-8×: rapier now steps the links every 1 ms instead of every
//! 62.5 µs plant step, see `plant::multibody`); peak RSS of the benchmark 47 MB (reduced) and
//! 51 MB (multibody), of a whole `vmt run` of the scenario 136 MB and 127 MB.
//!
//! Reduced: about 440× real time, 282 ns per servo tick (was about 325×, 385 ns: best user time
//! of one run, 142.9 simulated s, alternated A/B under the same load; criterion at load 3.5 gave
//! 268 Kelem/s before and 360-430 after). Instructions (valgrind, robust to the load): 3180 per
//! tick, was 3790. Where the time goes now (perf): the drive step 42 % (two LuGre contacts per
//! axis and plant step, each one division and one or two inline `exp`, a third of these on the
//! short path of an axis at rest; the three axes stage by stage, see `Drive::step_all`), the
//! interpolator 20 % (`sin_cos` of the arc 6.5 %), the per-tick bookkeeping of `simulate` 11 %,
//! the controllers 7 %, the error chain at the sample rate 4 %, the page faults of the logs 5 %.
//! The reduced goal needs about 60 ns per servo tick for everything.

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
    for fidelity in [Fidelity::Reduced, Fidelity::Multibody] {
        let mut settings = exec.settings;
        settings.fidelity = fidelity;
        group.measurement_time(match fidelity {
            Fidelity::Reduced => Duration::from_secs(5),
            Fidelity::Multibody => Duration::from_secs(20),
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
