//! The ball screw warming along its length: one-dimensional heat conduction with the nut's
//! friction heat where the nut is, and the thermal growth that moves the nut.
//!
//! The lumped network gives a screw one temperature and its expansion `α (T − 20 °C)(q − q_f)`.
//! A screw warms where its nut runs, and the nut's position error is the growth of the part of
//! the screw between the fixed (thrust) bearing and the nut (ISO 230-3, thermal distortion
//! caused by moving linear axes; Min & Chung's linear expansion term, here with its
//! temperature field):
//!
//! ```text
//! ρc A ∂T/∂t = k A ∂²T/∂s² − h P (T − T_amb) + q'(s, t)          W/m, s along the screw (m)
//! e(q)       = α ∫ from q_f to q of (T(s) − 20 °C) ds              m, the nut at axis position q
//! ```
//!
//! with A = πd²/4 and P = πd the section and perimeter of a screw of (root) diameter d, k the
//! conductivity, ρc the volumetric heat capacity, h the convection coefficient to the air,
//! α the expansion coefficient and q_f the axis position of the fixed bearing. Sources: the
//! nut's friction power `c_n |v|` spread evenly over its length around its position, and the
//! fixed-end bearings' `c_b |v|` into the end cell there (the lumped source of `kind = "axis"`,
//! `c |v|`, split between nut and bearings). Both ends conduct to the structure, taken at the
//! ambient temperature, through the bearings' conductances `G_e` (W/K).
//!
//! Discretisation: `N` equal finite volumes over the screw's span between its bearings (cell
//! centres `s_i`, width Δs): capacity `ρc A Δs`, conductance `k A/Δs` between neighbours,
//! `h P Δs` to the air, and at each end `G_e` in series with the half cell's `2 k A/Δs`. This is
//! a lumped network of the `thermal` module and is stepped the same way: exactly, with the
//! heat and ambient held over each step (zero-order hold, Van Loan), unconditionally stable;
//! the simulator steps it every second with the heat the nut left in each cell during that
//! second. The growth integrates the piecewise-constant cell temperatures exactly, so `e` is
//! piecewise linear in q; a uniform rise ΔT gives `α ΔT (q − q_f)`, the lumped model's.
//!
//! Plausible values for the 32 mm screws of a 500 × 400 × 400 mm machining centre: d of
//! 26–32 mm (root to nominal), steel (k ≈ 46 W/(m·K), ρc ≈ 3.6 MJ/(m³·K), α ≈ 11.5e-6 /K),
//! h of 10–40 W/(m²·K) (still to moving air about a turning screw), bearing conductances of
//! 0.5–5 W/K, and a split of the lumped 0.5 W/(mm/s) into about 0.3 for the nut and 0.2 for
//! the bearings; a screw warms by a few kelvin over minutes of motion at 1–2 m/min and by up
//! to 10–20 K in hours of rapid traverse.

use super::network::{Conductance, ThermalNetwork, ThermalNode, ThermalStepper};
use super::{Ambient, ThermalError};
use crate::thermal_deformation::REFERENCE_TEMPERATURE_C;
use std::f64::consts::PI;

/// Most cells of a screw's conduction model.
pub const MAX_SCREW_CELLS: usize = 64;

/// A warm section of the screw at the start (where it ran before the job).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WarmSection {
    /// Temperature rise over the ambient at the start, K.
    pub rise_k: f64,
    /// Axis positions between which the screw is that warm, m.
    pub from_to_m: [f64; 2],
}

/// A ball screw's thermal parameters, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScrewThermalParams {
    /// Axis positions of the screw's two bearing ends, m (low, high).
    pub span_m: [f64; 2],
    /// Whether the fixed (thrust) bearing is at the high end; else at the low end.
    pub fixed_at_high_end: bool,
    /// Diameter d of the conducting section, m.
    pub diameter_m: f64,
    /// Thermal conductivity k, W/(m·K).
    pub conductivity_w_per_m_k: f64,
    /// Volumetric heat capacity ρc, J/(m³·K).
    pub heat_capacity_j_per_m3_k: f64,
    /// Convection coefficient h to the air, W/(m²·K).
    pub convection_w_per_m2_k: f64,
    /// Conductance of each end's bearings to the structure (low, high end), W/K.
    pub end_conductance_w_per_k: [f64; 2],
    /// The nut's friction heat per speed c_n, W/(m/s).
    pub nut_w_per_m_s: f64,
    /// Length of the nut over which its heat enters the screw, m.
    pub nut_length_m: f64,
    /// The fixed-end bearings' heat per speed c_b, W/(m/s).
    pub bearing_w_per_m_s: f64,
    /// Expansion coefficient α, 1/K.
    pub alpha_per_k: f64,
    /// Number of cells N (2 to [`MAX_SCREW_CELLS`]).
    pub cells: usize,
    /// A warm section at the start, if any (else the whole screw is at the ambient).
    pub warm: Option<WarmSection>,
}

impl ScrewThermalParams {
    /// Cell width Δs, m.
    pub fn cell_m(&self) -> f64 {
        (self.span_m[1] - self.span_m[0]) / self.cells as f64
    }

    /// The axis position of the fixed bearing, m.
    pub fn fixed_m(&self) -> f64 {
        self.span_m[usize::from(self.fixed_at_high_end)]
    }

    /// The centre of cell `i`, m.
    pub fn centre_m(&self, i: usize) -> f64 {
        self.span_m[0] + (i as f64 + 0.5) * self.cell_m()
    }

    /// A description of the first value that is not a ball screw's, if any.
    pub fn check(&self) -> Result<(), String> {
        let [lo, hi] = self.span_m;
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(format!(
                "the span [{lo}, {hi}] must be an increasing pair of finite positions"
            ));
        }
        let positive = [
            ("diameter", self.diameter_m),
            ("conductivity", self.conductivity_w_per_m_k),
            ("heat capacity", self.heat_capacity_j_per_m3_k),
        ];
        for (what, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("the {what} {v} must be a finite number > 0"));
            }
        }
        let non_negative = [
            ("convection coefficient", self.convection_w_per_m2_k),
            ("low end's conductance", self.end_conductance_w_per_k[0]),
            ("high end's conductance", self.end_conductance_w_per_k[1]),
            ("nut heat", self.nut_w_per_m_s),
            ("nut length", self.nut_length_m),
            ("bearing heat", self.bearing_w_per_m_s),
        ];
        for (what, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("the {what} {v} must be a finite number >= 0"));
            }
        }
        if !self.alpha_per_k.is_finite() {
            return Err("the expansion coefficient must be a finite number".into());
        }
        if !(2..=MAX_SCREW_CELLS).contains(&self.cells) {
            return Err(format!(
                "{} cells: 2 to {MAX_SCREW_CELLS} are accepted",
                self.cells
            ));
        }
        if self.convection_w_per_m2_k == 0.0 && self.end_conductance_w_per_k == [0.0, 0.0] {
            return Err(
                "the screw loses no heat: give a convection coefficient or an end conductance > 0"
                    .into(),
            );
        }
        if let Some(w) = &self.warm {
            let [a, b] = w.from_to_m;
            if !(w.rise_k.is_finite() && a.is_finite() && b.is_finite() && b > a) {
                return Err(
                    "the warm section needs a finite rise and an increasing pair of positions"
                        .into(),
                );
            }
        }
        Ok(())
    }
}

/// A screw's conduction model discretised for a fixed step.
#[derive(Clone, Debug, PartialEq)]
pub struct ScrewThermal {
    params: ScrewThermalParams,
    stepper: ThermalStepper,
    /// Cell width, m.
    cell_m: f64,
}

impl ScrewThermal {
    /// The model of `p` stepped every `dt_s` seconds.
    pub fn new(p: &ScrewThermalParams, dt_s: f64) -> Result<Self, String> {
        p.check()?;
        let network = Self::network(p).map_err(|e| e.to_string())?;
        let stepper = network.discretize(dt_s).map_err(|e| e.to_string())?;
        Ok(Self {
            params: *p,
            stepper,
            cell_m: p.cell_m(),
        })
    }

    /// The cells as a lumped network (module docs).
    fn network(p: &ScrewThermalParams) -> Result<ThermalNetwork, ThermalError> {
        let (n, ds) = (p.cells, p.cell_m());
        let area = PI * p.diameter_m * p.diameter_m / 4.0;
        let axial = p.conductivity_w_per_m_k * area / ds;
        let air = p.convection_w_per_m2_k * PI * p.diameter_m * ds;
        // An end's bearings in series with the half cell between the end and the centre.
        let end = |g: f64| {
            if g > 0.0 {
                1.0 / (1.0 / g + 0.5 / axial)
            } else {
                0.0
            }
        };
        let nodes = (0..n)
            .map(|i| {
                let low = if i == 0 {
                    end(p.end_conductance_w_per_k[0])
                } else {
                    0.0
                };
                let high = if i + 1 == n {
                    end(p.end_conductance_w_per_k[1])
                } else {
                    0.0
                };
                ThermalNode {
                    name: format!("cell {i}"),
                    capacity_j_per_k: p.heat_capacity_j_per_m3_k * area * ds,
                    to_ambient_w_per_k: air + low + high,
                    initial_c: None,
                }
            })
            .collect();
        let conductances = (1..n)
            .map(|i| Conductance {
                a: i - 1,
                b: i,
                w_per_k: axial,
            })
            .collect();
        ThermalNetwork::new(nodes, conductances, Vec::new(), Ambient::default())
    }

    /// The parameters.
    pub fn params(&self) -> &ScrewThermalParams {
        &self.params
    }

    /// The cell temperatures at the start with the ambient at `ambient_c` (°C): the ambient,
    /// and the warm section above it.
    pub fn initial_temperatures(&self, ambient_c: f64) -> Vec<f64> {
        (0..self.params.cells)
            .map(|i| {
                let s = self.params.centre_m(i);
                match &self.params.warm {
                    Some(w) if (w.from_to_m[0]..=w.from_to_m[1]).contains(&s) => {
                        ambient_c + w.rise_k
                    }
                    _ => ambient_c,
                }
            })
            .collect()
    }

    /// Adds to `heat_j` (J per cell) the heat of the nut at axis position `q` (m) moving at
    /// speed `v` (m/s) for `dt` seconds, spread over its length, and of the fixed bearings.
    pub fn deposit(&self, heat_j: &mut [f64], q: f64, v: f64, dt: f64) {
        let p = &self.params;
        let speed = v.abs();
        if speed == 0.0 {
            return;
        }
        let fixed = if p.fixed_at_high_end { p.cells - 1 } else { 0 };
        heat_j[fixed] += p.bearing_w_per_m_s * speed * dt;
        let energy = p.nut_w_per_m_s * speed * dt;
        if energy == 0.0 {
            return;
        }
        let [lo, hi] = p.span_m;
        let half = 0.5 * p.nut_length_m;
        let (a, b) = ((q - half).clamp(lo, hi), (q + half).clamp(lo, hi));
        if b <= a {
            // A point nut (or one at the end of the span): its cell takes all.
            let i = (((q - lo) / self.cell_m) as usize).min(p.cells - 1);
            heat_j[i] += energy;
            return;
        }
        let first = ((a - lo) / self.cell_m) as usize;
        let last = (((b - lo) / self.cell_m) as usize).min(p.cells - 1);
        for (i, h) in heat_j.iter_mut().enumerate().take(last + 1).skip(first) {
            let c0 = lo + i as f64 * self.cell_m;
            let overlap = (b.min(c0 + self.cell_m) - a.max(c0)).max(0.0);
            *h += energy * overlap / (b - a);
        }
    }

    /// Advances `temps_c` by the step with the heat `heat_w` (W per cell) and the ambient
    /// `ambient_c` (°C) held over it.
    pub fn step(&self, temps_c: &mut [f64], heat_w: &[f64], ambient_c: f64) {
        self.stepper.step(temps_c, heat_w, ambient_c);
    }

    /// The step, s.
    pub fn dt_s(&self) -> f64 {
        self.stepper.dt_s()
    }

    /// The growth of the screw at cell temperatures `temps_c` (°C).
    pub fn growth(&self, temps_c: &[f64]) -> ScrewGrowth {
        let p = &self.params;
        let mut cumulative = [0.0; MAX_SCREW_CELLS + 1];
        for (i, t) in temps_c.iter().enumerate().take(p.cells) {
            cumulative[i + 1] =
                cumulative[i] + p.alpha_per_k * (t - REFERENCE_TEMPERATURE_C) * self.cell_m;
        }
        let mut g = ScrewGrowth {
            low_m: p.span_m[0],
            cell_m: self.cell_m,
            cells: p.cells,
            cumulative,
            at_fixed_m: 0.0,
        };
        g.at_fixed_m = g.integral(p.fixed_m());
        g
    }
}

/// The growth of a screw at one thermal state: how far the nut at axis position q is from
/// where the cold screw would put it, `α ∫ from q_f to q of (T − 20 °C) ds` (m), piecewise
/// linear in q.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScrewGrowth {
    low_m: f64,
    cell_m: f64,
    cells: usize,
    /// The growth from the low end to each cell boundary, m.
    cumulative: [f64; MAX_SCREW_CELLS + 1],
    /// The growth from the low end to the fixed bearing, m.
    at_fixed_m: f64,
}

impl ScrewGrowth {
    /// The growth from the low end to `q` (m), held beyond the span.
    #[inline]
    fn integral(&self, q: f64) -> f64 {
        let u = ((q - self.low_m) / self.cell_m).clamp(0.0, self.cells as f64);
        let i = (u as usize).min(self.cells - 1);
        let f = u - i as f64;
        self.cumulative[i] + f * (self.cumulative[i + 1] - self.cumulative[i])
    }

    /// The nut's displacement at axis position `q` (m) from the screw's growth, m.
    #[inline]
    pub fn at(&self, q: f64) -> f64 {
        self.integral(q) - self.at_fixed_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn screw(cells: usize) -> ScrewThermalParams {
        ScrewThermalParams {
            span_m: [-0.1, 0.6],
            fixed_at_high_end: false,
            diameter_m: 0.028,
            conductivity_w_per_m_k: 46.0,
            heat_capacity_j_per_m3_k: 3.6e6,
            convection_w_per_m2_k: 0.0,
            end_conductance_w_per_k: [1e9, 0.0],
            nut_w_per_m_s: 300.0,
            nut_length_m: 0.1,
            bearing_w_per_m_s: 200.0,
            alpha_per_k: 11.5e-6,
            cells,
            warm: None,
        }
    }

    /// Against the closed form of a rod with a uniform source q' (W/m), held at the ambient at
    /// the fixed end and insulated at the other: `T − T_a = q'/(kA) (L s − s²/2)`. The finite
    /// volumes are exact for this parabola inside; the half cell at the held end puts every
    /// cell `q' Δs²/(8kA)` above it (the scheme's known boundary error, shrinking as Δs²).
    #[test]
    fn steady_state_with_a_uniform_source_is_the_parabola() {
        for cells in [8, 32, 64] {
            let p = screw(cells);
            let model = ScrewThermal::new(&p, 1e9).unwrap();
            let q_per_m = 2.0;
            let heat = vec![q_per_m * p.cell_m(); cells];
            let mut t = model.initial_temperatures(20.0);
            // One exact step far longer than every time constant: the steady state.
            model.step(&mut t, &heat, 20.0);
            let ka = 46.0 * PI * 0.028 * 0.028 / 4.0;
            let length = 0.7;
            let shift = q_per_m * p.cell_m().powi(2) / (8.0 * ka);
            for (i, ti) in t.iter().enumerate() {
                let s = p.centre_m(i) + 0.1;
                let expected = 20.0 + q_per_m / ka * (length * s - s * s / 2.0) + shift;
                assert!(
                    (ti - expected).abs() < 1e-9 * expected,
                    "{cells} {i}: {ti} {expected}"
                );
            }
        }
    }

    /// Against `T − T_a = q'/(h π d)`: with a uniform source and insulated ends every cell
    /// loses its heat to the air only.
    #[test]
    fn steady_state_with_convection_alone() {
        let p = ScrewThermalParams {
            convection_w_per_m2_k: 15.0,
            end_conductance_w_per_k: [0.0, 0.0],
            ..screw(20)
        };
        let model = ScrewThermal::new(&p, 1e9).unwrap();
        let heat = vec![1.5 * p.cell_m(); 20];
        let mut t = model.initial_temperatures(21.0);
        model.step(&mut t, &heat, 21.0);
        let expected = 21.0 + 1.5 / (15.0 * PI * 0.028);
        for ti in t {
            assert!((ti - expected).abs() < 1e-9, "{ti} {expected}");
        }
    }

    /// Against `α ΔT (q − q_f)`: a uniform rise grows the screw as the lumped expansion does,
    /// from either fixed end.
    #[test]
    fn a_uniform_rise_grows_the_screw_linearly_from_the_fixed_end() {
        for high in [false, true] {
            let p = ScrewThermalParams {
                fixed_at_high_end: high,
                ..screw(50)
            };
            let model = ScrewThermal::new(&p, 1.0).unwrap();
            let g = model.growth(&vec![23.5; 50]);
            for i in 0..=70 {
                let q = -0.1 + i as f64 * 0.01;
                let expected = 11.5e-6 * 3.5 * (q - p.fixed_m());
                assert!(
                    (g.at(q) - expected).abs() < 1e-15,
                    "{q}: {} {expected}",
                    g.at(q)
                );
            }
        }
    }

    /// The nut's heat lands where the nut is, all of it, and the bearings' at the fixed end.
    #[test]
    fn the_heat_goes_where_the_nut_and_bearings_are() {
        let p = screw(56);
        let model = ScrewThermal::new(&p, 1.0).unwrap();
        let mut heat = vec![0.0; 56];
        model.deposit(&mut heat, 0.2534, 0.02, 0.5);
        let total: f64 = heat.iter().sum();
        assert!((total - (300.0 + 200.0) * 0.02 * 0.5).abs() < 1e-12);
        assert!((heat[0] - 200.0 * 0.02 * 0.5).abs() < 1e-12);
        let nut: Vec<usize> = (1..56).filter(|&i| heat[i] > 0.0).collect();
        let (a, b) = (p.centre_m(nut[0]), p.centre_m(*nut.last().unwrap()));
        assert!(a > 0.2534 - 0.06 && b < 0.2534 + 0.06, "{a} {b}");
        // Mean position of the nut's heat: the nut's position.
        let mean: f64 = nut.iter().map(|&i| heat[i] * p.centre_m(i)).sum::<f64>()
            / nut.iter().map(|&i| heat[i]).sum::<f64>();
        assert!((mean - 0.2534).abs() < 1e-3, "{mean}");
    }
}
