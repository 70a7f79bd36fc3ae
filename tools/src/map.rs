//! Volumetric error maps over a plane, for forward and backward approach (Ahn & Cho's Figs 7–9).

use crate::error::CliError;
use nalgebra::Vector3;
use std::io::Write;
use std::str::FromStr;
use vmt_model::kinematics::AxisState;
use vmt_model::machine::Machine;
use vmt_model::{Axis, Direction};

/// A coordinate plane: the two axes spanning it and the one held fixed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plane {
    /// Horizontal axis of the map.
    pub u: Axis,
    /// Vertical axis of the map.
    pub v: Axis,
    /// The axis held at `--at-mm`.
    pub normal: Axis,
}

impl FromStr for Plane {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        use crate::plane::Plane as Name;
        let (u, v, normal) = match crate::plane::parse(s)? {
            Name::Xy => (Axis::X, Axis::Y, Axis::Z),
            Name::Zx => (Axis::X, Axis::Z, Axis::Y),
            Name::Yz => (Axis::Y, Axis::Z, Axis::X),
        };
        Ok(Plane { u, v, normal })
    }
}

impl std::fmt::Display for Plane {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}{}",
            self.u.letter().to_ascii_lowercase(),
            self.v.letter().to_ascii_lowercase()
        )
    }
}

/// The error map: a grid over the plane, for both approach directions.
#[derive(Clone, Debug)]
pub struct VolumetricMap {
    /// The plane.
    pub plane: Plane,
    /// Coordinate of the fixed axis, m.
    pub at_m: f64,
    /// Grid coordinates along `u` and `v`, m.
    pub u_m: Vec<f64>,
    /// Grid coordinates along `v`, m.
    pub v_m: Vec<f64>,
    /// Errors (m) for forward and backward approach, indexed `[iv * u.len() + iu]`.
    pub errors: [Vec<Vector3<f64>>; 2],
}

/// The approach directions of the map, with their names.
pub const APPROACHES: [(Direction, &str); 2] = [
    (Direction::Forward, "forward"),
    (Direction::Backward, "backward"),
];

/// Computes the map over the full strokes of the plane's axes on an `n` x `n` grid, with the
/// machine at node temperatures `temps_c`.
pub fn compute(
    machine: &Machine,
    plane: Plane,
    at_m: f64,
    n: usize,
    temps_c: &[f64],
) -> Result<VolumetricMap, CliError> {
    let spec = machine.axis(plane.normal);
    if !spec.contains(at_m) {
        return Err(CliError::Argument(format!(
            "--at-mm {} is outside the {} stroke {} to {} mm",
            at_m * 1e3,
            plane.normal,
            spec.min_m * 1e3,
            spec.max_m * 1e3
        )));
    }
    if !(2..=2001).contains(&n) {
        return Err(CliError::Argument(format!(
            "--grid {n}: from 2 to 2001 points per side are accepted"
        )));
    }
    let grid = |a: Axis| {
        let s = machine.axis(a);
        (0..n)
            .map(|i| s.min_m + (s.max_m - s.min_m) * i as f64 / (n - 1) as f64)
            .collect::<Vec<_>>()
    };
    let (u_m, v_m) = (grid(plane.u), grid(plane.v));
    let deformation = machine
        .thermal_deformation(temps_c)
        .map_err(|e| CliError::Model(e.to_string()))?;
    let evaluator = machine.volumetric.evaluator(&deformation);
    let errors = APPROACHES.map(|(direction, _)| {
        let mut out = Vec::with_capacity(n * n);
        for v in &v_m {
            for u in &u_m {
                let mut p = Vector3::zeros();
                p[plane.u.index()] = *u;
                p[plane.v.index()] = *v;
                p[plane.normal.index()] = at_m;
                out.push(evaluator.volumetric_error(&AxisState::new(p, direction)));
            }
        }
        out
    });
    Ok(VolumetricMap {
        plane,
        at_m,
        u_m,
        v_m,
        errors,
    })
}

impl VolumetricMap {
    /// Writes `approach,x_mm,y_mm,z_mm,dx_um,dy_um,dz_um`, one row per grid point and approach.
    pub fn write_csv(&self, out: &mut dyn Write) -> std::io::Result<()> {
        writeln!(out, "approach,x_mm,y_mm,z_mm,dx_um,dy_um,dz_um")?;
        for ((_, name), errors) in APPROACHES.iter().zip(&self.errors) {
            for (iv, v) in self.v_m.iter().enumerate() {
                for (iu, u) in self.u_m.iter().enumerate() {
                    let mut p = Vector3::zeros();
                    p[self.plane.u.index()] = *u;
                    p[self.plane.v.index()] = *v;
                    p[self.plane.normal.index()] = self.at_m;
                    let e = errors[iv * self.u_m.len() + iu] * 1e6;
                    writeln!(
                        out,
                        "{name},{:.3},{:.3},{:.3},{:.6},{:.6},{:.6}",
                        p.x * 1e3,
                        p.y * 1e3,
                        p.z * 1e3,
                        e.x,
                        e.y,
                        e.z
                    )?;
                }
            }
        }
        Ok(())
    }

    /// Largest magnitude of component `k` over both approaches, m.
    pub fn max_abs(&self, k: usize) -> f64 {
        self.errors
            .iter()
            .flatten()
            .map(|e| e[k].abs())
            .fold(0.0, f64::max)
    }
}
