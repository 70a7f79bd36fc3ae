//! Volumetric error evaluation on one core: points per second through the exact HTM chain.
//!
//! The machine has every one of the 18 axis error functions (Legendre series of degree 4, or
//! 21-row PCHIP tables), direction-dependent squareness, and a warm thermal state that deforms
//! all five structural links and the three joints: the full reference path, nothing skipped.
//! Run: `cargo bench -p vmt-model --bench volumetric`; the figure is the throughput in elem/s.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;
use std::hint::black_box;
use vmt_model::geometric::{
    Component, Directional, ErrorFunction, ErrorTable, GeometricErrors, Interpolation,
    LegendreSeries, SquarenessError, SquarenessValue,
};
use vmt_model::kinematics::{AxisState, Kinematics, VolumetricModel};
use vmt_model::thermal_deformation::ThermalDeformation;
use vmt_model::{Axis, Direction};

const POINTS: usize = 10_000;
const STROKE: f64 = 0.5;

/// A deterministic pseudo-random value in [-1, 1) (a splitmix-style hash of `i`).
fn unit(i: u64) -> f64 {
    let mut z = i.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) as f64 / u64::MAX as f64 * 2.0 - 1.0
}

fn function(seed: u64, amp: f64, table: bool) -> ErrorFunction {
    if table {
        let q: Vec<f64> = (0..21).map(|i| STROKE * i as f64 / 20.0).collect();
        let v = (0..21).map(|i| amp * unit(seed * 100 + i)).collect();
        ErrorFunction::Table(ErrorTable::new(q, v, Interpolation::Pchip).unwrap())
    } else {
        let c = (0..5).map(|i| amp * unit(seed * 100 + i) / 3.0).collect();
        ErrorFunction::Legendre(LegendreSeries::new(c, 0.0, STROKE).unwrap())
    }
}

fn machine(table: bool) -> VolumetricModel {
    let mut e = GeometricErrors::zero();
    let mut seed = 1;
    for axis in Axis::ALL {
        for c in Component::ALL {
            let amp = if c.is_angular() { 10e-6 } else { 5e-6 };
            let forward = function(seed, amp, table);
            let backward = function(seed + 1, amp, table);
            e.axis_mut(axis).set(c, Directional { forward, backward });
            seed += 2;
        }
    }
    for s in SquarenessError::ALL {
        let v = SquarenessValue {
            values: [[10e-6, 11e-6], [12e-6, 13e-6]],
        };
        e.set_squareness(s, v);
    }
    let mut k = Kinematics::new("WXYGZT".parse().unwrap());
    k.tool_offset = Vector3::new(0.0, 0.0, -0.1);
    k.link_pivots[3] = Vector3::new(0.25, 0.55, -0.35);
    VolumetricModel::new(k, e)
}

fn warm() -> ThermalDeformation {
    let mut d = ThermalDeformation::default();
    for (i, l) in d.links.iter_mut().enumerate() {
        l.translation = Vector3::new(1e-6, 2e-6, -3e-6) * (i + 1) as f64;
        l.rotation = Vector3::new(-1e-6, 0.5e-6, 0.2e-6) * (i + 1) as f64;
    }
    for j in &mut d.joints {
        j.strain = 20e-6;
        j.rotation = Vector3::new(0.0, 0.0, 0.8e-6);
    }
    d
}

fn states() -> Vec<AxisState> {
    (0..POINTS as u64)
        .map(|i| {
            let p = Vector3::new(unit(3 * i), unit(3 * i + 1), unit(3 * i + 2))
                .map(|u| (u + 1.0) * STROKE / 2.0);
            let d = if i % 2 == 0 {
                Direction::Forward
            } else {
                Direction::Backward
            };
            AxisState::new(p, d)
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let states = states();
    let thermal = warm();
    let mut group = c.benchmark_group("volumetric_error");
    group.throughput(Throughput::Elements(POINTS as u64));
    for (name, table) in [("legendre_deg4", false), ("pchip_table_21", true)] {
        let model = machine(table);
        let evaluator = model.evaluator(&thermal);
        group.bench_function(name, |b| {
            b.iter(|| {
                let mut acc = Vector3::zeros();
                for s in &states {
                    acc += evaluator.volumetric_error(black_box(s));
                }
                acc
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
