//! Time-domain milling on one core: simulated seconds per wall second.
//!
//! A 12 mm end mill with 4 teeth and a 30° helix, 2 mm deep, 3 mm radial (25 %), down milling
//! at 8000 rpm and 0.08 mm per tooth; two modes per direction (650 Hz and 2400 Hz), the
//! cut step 50/3 µs (20 steps per period of 2400 Hz, 3 per output sample), accelerometers at
//! 20 kHz, 6 axial disks. The throughput is in simulated milliseconds, so criterion's
//! `Kelem/s` is simulated seconds per wall second (the real-time factor). Goal (issue 5): ≥ 20.
//! Run: `cargo bench -p vmt-sim --bench milling`.

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use std::time::Duration;
use vmt_model::cutting::{
    CutGeometry, CuttingCoefficients, EndMill, MillingDirection, Mode, ToolDynamics,
};
use vmt_sim::milling::{AccelerometerParams, Feed, MillingDrive, MillingSetup, simulate_milling};

fn setup() -> MillingSetup {
    let modes = vec![
        Mode {
            natural_frequency_hz: 650.0,
            damping_ratio: 0.03,
            stiffness: 2e7,
        },
        Mode {
            natural_frequency_hz: 2400.0,
            damping_ratio: 0.02,
            stiffness: 6e7,
        },
    ];
    MillingSetup {
        tool: EndMill {
            diameter: 0.012,
            teeth: 4,
            helix: 30f64.to_radians(),
            flute_length: 0.03,
            runout: 5e-6,
            runout_angle: 0.0,
        },
        coefficients: CuttingCoefficients {
            tangential: 7e8,
            radial: 2.5e8,
            axial: 1.5e8,
            tangential_edge: 2e4,
            radial_edge: 1.5e4,
            axial_edge: 5e3,
        },
        dynamics: ToolDynamics::symmetric(modes),
        axial_mode: Some(Mode {
            natural_frequency_hz: 1500.0,
            damping_ratio: 0.04,
            stiffness: 2e8,
        }),
        cut: CutGeometry {
            axial_depth: 2e-3,
            radial_depth: 3e-3,
            direction: MillingDirection::Down,
        },
        feed_per_tooth: 8e-5,
        accelerometer: AccelerometerParams::default(),
        step_s: 5e-5 / 3.0,
        seed: 1,
    }
}

fn bench(c: &mut Criterion) {
    let setup = setup();
    let drive = MillingDrive {
        spindle_rpm: 8000.0,
        feed: Feed::PerTooth(8e-5),
        duration_s: 1.0,
        supervisor_window_s: 0.01,
    };
    let mut group = c.benchmark_group("milling");
    group.throughput(Throughput::Elements(1000));
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    group.warm_up_time(Duration::from_millis(1));
    group.measurement_time(Duration::from_secs(5));
    group.bench_function("4_teeth_helix_2_modes_20kHz", |b| {
        b.iter(|| simulate_milling(&setup, &drive).expect("the cut runs"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
