//! What the withheld physics (`vmt_scenario::withheld`) costs when it is on: the built-in
//! scenario's ISO 230-4 circle (XY, 150 mm, 1000 mm/min, CW and CCW) on the reduced plant,
//! plain and with each effect at its typical size on X (a rail bump at X = 330 mm), as
//! `cargo bench -p vmt-sim --bench circle` measures the plain one. Throughput in simulated
//! milliseconds: criterion's `Kelem/s` is the real-time factor.
//! Run: `cargo bench -p vmt-sim --bench withheld`.

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use std::time::Duration;
use vmt_model::Axis;
use vmt_scenario::edit::Template;
use vmt_scenario::withheld::{WITHHELD, switch_on};
use vmt_sim::interpolator::Interpolator;
use vmt_sim::simulate::simulate;

fn bench(c: &mut Criterion) {
    let builtin = Template::parse(vmt_scenario::BUILTIN_DEFAULT, "vmc500.toml").expect("parses");
    let mut cases = vec![(
        "none".to_string(),
        vmt_scenario::BUILTIN_DEFAULT.to_string(),
    )];
    for e in &WITHHELD {
        let text =
            switch_on(&builtin, e.key, Axis::X, e.typical, Some(330.0)).expect("switches on");
        cases.push((e.key.to_string(), text));
    }
    let mut group = c.benchmark_group("withheld_physics");
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    group.warm_up_time(Duration::from_millis(1));
    group.measurement_time(Duration::from_secs(5));
    for (name, text) in &cases {
        let scenario = vmt_scenario::parse(text, "vmc500.toml", None).expect("loads");
        let exec = scenario.execution.expect("has a job");
        let ipo = Interpolator::new(&exec.job.program, &exec.controller).expect("plans");
        let simulated_ms = ipo.servo_ticks() as f64 * ipo.servo_period_s() * 1e3;
        group.throughput(Throughput::Elements(simulated_ms.round() as u64));
        group.bench_function(name.as_str(), |b| {
            b.iter(|| {
                simulate(
                    &scenario.machine,
                    &exec.axes,
                    &exec.controller,
                    &exec.job,
                    &exec.settings,
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
