//! Nodes, conductances, heat sources, and the exact discretisation of the
//! network (see the [module documentation](super) for the equations).

use std::collections::HashMap;

use nalgebra::{Cholesky, DMatrix, DVector, SymmetricEigen};

use super::{Ambient, ThermalError};

/// Eigenvalues of `S` below `EIGEN_ZERO_FACTOR · n · ε · max μ` are
/// round-off and taken as exactly zero.
const EIGEN_ZERO_FACTOR: f64 = 64.0;
/// Fixed part of the iteration bound of the symmetric QR algorithm.
const EIGEN_BASE_ITERATIONS: usize = 1000;
/// Per-node part of the iteration bound of the symmetric QR algorithm.
const EIGEN_ITERATIONS_PER_NODE: usize = 100;

/// One lumped body of the structure at a uniform temperature.
#[derive(Debug, Clone, PartialEq)]
pub struct ThermalNode {
    /// Unique name, e.g. `"spindle housing"`.
    pub name: String,
    /// Heat capacity `C_i = m c_p` in J/K, finite and `> 0`.
    pub capacity_j_per_k: f64,
    /// Conductance to the ambient air `g_i` in W/K (convection `h A` plus
    /// linearised radiation), finite and `>= 0`.
    pub to_ambient_w_per_k: f64,
    /// Temperature at `t = 0` in °C; `None` means the ambient temperature at
    /// `t = 0`.
    pub initial_c: Option<f64>,
}

/// A thermal conductance `G_ab` in W/K between nodes `a` and `b`
/// (conduction through a joint). Several conductances between the same
/// pair add up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conductance {
    /// Index of the first node.
    pub a: usize,
    /// Index of the second node, different from `a`.
    pub b: usize,
    /// Conductance in W/K, finite and `>= 0`.
    pub w_per_k: f64,
}

/// A heat source: a loss model feeding heat into one node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HeatSource {
    /// Spindle bearing and motor loss `Q = w_per_rpm·|n| + w_per_rpm2·n²`
    /// in W, with `n` the spindle speed in rpm (direction does not matter).
    Spindle {
        /// Index of the heated node.
        node: usize,
        /// Speed-proportional coefficient in W/rpm, `>= 0`.
        w_per_rpm: f64,
        /// Coefficient of the square of speed in W/rpm², `>= 0`.
        w_per_rpm2: f64,
    },
    /// Axis motion loss (ball-screw nut, support bearings, guideways)
    /// `Q = w_per_m_per_s·|v|` in W, with `v` the mean speed of the axis in
    /// m/s; the coefficient is an effective friction force in N.
    Axis {
        /// Index of the heated node.
        node: usize,
        /// Axis: 0 = X, 1 = Y, 2 = Z.
        axis: usize,
        /// Coefficient in W/(m/s), `>= 0`.
        w_per_m_per_s: f64,
    },
}

impl HeatSource {
    /// Index of the node this source heats.
    pub fn node(&self) -> usize {
        match *self {
            HeatSource::Spindle { node, .. } | HeatSource::Axis { node, .. } => node,
        }
    }

    /// Heat flow in W at the operating point `op`.
    ///
    /// Non-finite speeds give a non-finite result; an axis index `>= 3`
    /// (rejected by [`ThermalNetwork::new`]) gives 0.
    pub fn heat_w(&self, op: &Operating) -> f64 {
        match *self {
            HeatSource::Spindle {
                w_per_rpm,
                w_per_rpm2,
                ..
            } => {
                let n = op.spindle_rpm.abs();
                w_per_rpm * n + w_per_rpm2 * n * n
            }
            HeatSource::Axis {
                axis,
                w_per_m_per_s,
                ..
            } => op
                .axis_speed_m_s
                .get(axis)
                .map_or(0.0, |v| w_per_m_per_s * v.abs()),
        }
    }
}

/// An operating point of the machine: what drives the heat sources.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Operating {
    /// Spindle speed in rpm.
    pub spindle_rpm: f64,
    /// Mean speed of the X, Y, Z axes in m/s (e.g. the mean of `|v|` over
    /// the ISO 230-3 axis motion cycle).
    pub axis_speed_m_s: [f64; 3],
}

impl Operating {
    /// Everything stopped: no heat from any source.
    pub const STOPPED: Operating = Operating {
        spindle_rpm: 0.0,
        axis_speed_m_s: [0.0; 3],
    };

    /// Names and units of the speeds, in the order of [`Self::speeds`].
    pub(crate) const SPEED_NAMES: [&'static str; 4] = [
        "spindle speed (rpm)",
        "X axis speed (m/s)",
        "Y axis speed (m/s)",
        "Z axis speed (m/s)",
    ];

    /// All speeds: spindle (rpm), then X, Y, Z (m/s).
    pub(crate) fn speeds(&self) -> [f64; 4] {
        let [x, y, z] = self.axis_speed_m_s;
        [self.spindle_rpm, x, y, z]
    }

    fn check_finite(&self) -> Result<(), ThermalError> {
        for (quantity, value) in Self::SPEED_NAMES.into_iter().zip(self.speeds()) {
            if !value.is_finite() {
                return Err(ThermalError::InvalidOperating { quantity, value });
            }
        }
        Ok(())
    }
}

/// A validated lumped thermal network: nodes, conductances, heat sources and
/// ambient model.
#[derive(Debug, Clone, PartialEq)]
pub struct ThermalNetwork {
    nodes: Vec<ThermalNode>,
    conductances: Vec<Conductance>,
    sources: Vec<HeatSource>,
    ambient: Ambient,
}

impl ThermalNetwork {
    /// Builds and validates a network.
    ///
    /// Rejected (never a panic): no node; duplicate node names; capacities
    /// not finite and `> 0`; conductances (to ambient or between nodes) not
    /// finite and `>= 0`; non-finite initial temperatures; node indices out
    /// of range; a conductance joining a node to itself; heat-source
    /// coefficients not finite and `>= 0`; axis index `>= 3`; an invalid
    /// ambient model (see [`Ambient::validate`]).
    pub fn new(
        nodes: Vec<ThermalNode>,
        conductances: Vec<Conductance>,
        sources: Vec<HeatSource>,
        ambient: Ambient,
    ) -> Result<Self, ThermalError> {
        validate_nodes(&nodes)?;
        validate_conductances(&nodes, &conductances)?;
        validate_sources(&nodes, &sources)?;
        ambient.validate()?;
        Ok(Self {
            nodes,
            conductances,
            sources,
            ambient,
        })
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Node names in index order.
    pub fn node_names(&self) -> impl Iterator<Item = &str> {
        self.nodes.iter().map(|n| n.name.as_str())
    }

    /// Index of the node called `name`.
    pub fn node_index(&self, name: &str) -> Option<usize> {
        self.nodes.iter().position(|n| n.name == name)
    }

    /// The nodes, in index order.
    pub fn nodes(&self) -> &[ThermalNode] {
        &self.nodes
    }

    /// The conductances between nodes.
    pub fn conductances(&self) -> &[Conductance] {
        &self.conductances
    }

    /// The heat sources.
    pub fn sources(&self) -> &[HeatSource] {
        &self.sources
    }

    /// The ambient temperature model.
    pub fn ambient(&self) -> &Ambient {
        &self.ambient
    }

    /// Node temperatures at `t = 0` in °C (the ambient at `t = 0` for nodes
    /// without an initial temperature).
    pub fn initial_temperatures(&self) -> Vec<f64> {
        let ambient = self.ambient.celsius_at(0.0);
        self.nodes
            .iter()
            .map(|n| n.initial_c.unwrap_or(ambient))
            .collect()
    }

    /// Heat flow into each node in W at the operating point `op`.
    pub fn heat_input_w(&self, op: &Operating) -> Vec<f64> {
        let mut heat = vec![0.0; self.nodes.len()];
        for source in &self.sources {
            if let Some(q) = heat.get_mut(source.node()) {
                *q += source.heat_w(op);
            }
        }
        heat
    }

    /// Time constants `1/μ_k` of the network in s, ascending. Infinite time
    /// constants (groups of nodes without a path to ambient) are omitted.
    pub fn time_constants_s(&self) -> Result<Vec<f64>, ThermalError> {
        let modal = self.modal()?;
        let mut taus: Vec<f64> = modal
            .mu
            .iter()
            .filter(|&&mu| mu > 0.0)
            .map(|mu| 1.0 / mu)
            .filter(|tau| tau.is_finite())
            .collect();
        taus.sort_by(f64::total_cmp);
        Ok(taus)
    }

    /// Steady-state node temperatures in °C at the operating point `op` and
    /// the constant ambient `ambient_c`: the solution of
    /// `(L + diag g) (T − T_amb) = Q`.
    ///
    /// Errors if a speed of `op` or `ambient_c` is not finite, or if some
    /// node has no path of positive conductances to ambient (its temperature
    /// would grow without bound).
    pub fn steady_state_c(&self, op: &Operating, ambient_c: f64) -> Result<Vec<f64>, ThermalError> {
        op.check_finite()?;
        if !ambient_c.is_finite() {
            return Err(ThermalError::InvalidAmbientTemperature { value: ambient_c });
        }
        self.check_path_to_ambient()?;
        let k = self.stiffness();
        let cholesky = Cholesky::new(k).ok_or(ThermalError::SingularSystem)?;
        let rise = cholesky.solve(&DVector::from_vec(self.heat_input_w(op)));
        Ok(rise.iter().map(|dt| ambient_c + dt).collect())
    }

    /// The exact zero-order-hold discretisation of the network over the
    /// step `dt_s` (s). Any finite `dt_s > 0` is accepted: the scheme is
    /// unconditionally stable.
    pub fn discretize(&self, dt_s: f64) -> Result<ThermalStepper, ThermalError> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(ThermalError::InvalidTimeStep { value: dt_s });
        }
        let modal = self.modal()?;
        let (decay, gain) = modal.factors(dt_s);
        Ok(ThermalStepper {
            dt_s,
            modal,
            decay,
            gain,
        })
    }

    /// `K = L + diag(g)`: the conductance Laplacian plus the conductances to
    /// ambient (W/K).
    fn stiffness(&self) -> DMatrix<f64> {
        let n = self.nodes.len();
        let mut k = DMatrix::from_diagonal(&DVector::from_iterator(
            n,
            self.nodes.iter().map(|node| node.to_ambient_w_per_k),
        ));
        for c in &self.conductances {
            k[(c.a, c.a)] += c.w_per_k;
            k[(c.b, c.b)] += c.w_per_k;
            k[(c.a, c.b)] -= c.w_per_k;
            k[(c.b, c.a)] -= c.w_per_k;
        }
        k
    }

    /// Eigendecomposition of `S = C^-1/2 K C^-1/2`.
    fn modal(&self) -> Result<Modal, ThermalError> {
        let capacities: Vec<f64> = self.nodes.iter().map(|n| n.capacity_j_per_k).collect();
        Modal::new(&capacities, &self.stiffness()).map_err(|err| match err {
            ModalError::NonFinite { row, value } => ThermalError::NumericalRange {
                node: self.nodes[row].name.clone(),
                value,
            },
            ModalError::NotConverged { max_iterations } => ThermalError::EigenNotConverged {
                nodes: self.nodes.len(),
                max_iterations,
            },
        })
    }

    /// Errors with the first node that has no path of positive conductances
    /// to a node coupled to ambient.
    fn check_path_to_ambient(&self) -> Result<(), ThermalError> {
        let n = self.nodes.len();
        let mut neighbours = vec![Vec::new(); n];
        for c in self.conductances.iter().filter(|c| c.w_per_k > 0.0) {
            neighbours[c.a].push(c.b);
            neighbours[c.b].push(c.a);
        }
        let mut reached: Vec<bool> = self
            .nodes
            .iter()
            .map(|node| node.to_ambient_w_per_k > 0.0)
            .collect();
        let mut stack: Vec<usize> = (0..n).filter(|&i| reached[i]).collect();
        while let Some(i) = stack.pop() {
            for &j in &neighbours[i] {
                if !reached[j] {
                    reached[j] = true;
                    stack.push(j);
                }
            }
        }
        match reached.iter().position(|&r| !r) {
            None => Ok(()),
            Some(index) => Err(ThermalError::NoPathToAmbient {
                node: self.nodes[index].name.clone(),
                index,
            }),
        }
    }
}

fn validate_nodes(nodes: &[ThermalNode]) -> Result<(), ThermalError> {
    if nodes.is_empty() {
        return Err(ThermalError::NoNodes);
    }
    let mut seen: HashMap<&str, usize> = HashMap::new();
    for (index, node) in nodes.iter().enumerate() {
        validate_node(index, node)?;
        if let Some(&first) = seen.get(node.name.as_str()) {
            return Err(ThermalError::DuplicateNodeName {
                name: node.name.clone(),
                first,
                second: index,
            });
        }
        seen.insert(&node.name, index);
    }
    Ok(())
}

fn validate_node(index: usize, node: &ThermalNode) -> Result<(), ThermalError> {
    let name = || node.name.clone();
    let c = node.capacity_j_per_k;
    if !(c.is_finite() && c > 0.0) {
        return Err(ThermalError::InvalidCapacity {
            node: name(),
            index,
            value: c,
        });
    }
    let g = node.to_ambient_w_per_k;
    if !(g.is_finite() && g >= 0.0) {
        return Err(ThermalError::InvalidAmbientConductance {
            node: name(),
            index,
            value: g,
        });
    }
    match node.initial_c {
        Some(value) if !value.is_finite() => Err(ThermalError::InvalidInitialTemperature {
            node: name(),
            index,
            value,
        }),
        _ => Ok(()),
    }
}

fn check_index(item: impl FnOnce() -> String, index: usize, n: usize) -> Result<(), ThermalError> {
    if index < n {
        Ok(())
    } else {
        Err(ThermalError::NodeIndexOutOfRange {
            item: item(),
            index,
            node_count: n,
        })
    }
}

fn validate_conductances(
    nodes: &[ThermalNode],
    conductances: &[Conductance],
) -> Result<(), ThermalError> {
    let n = nodes.len();
    for (k, c) in conductances.iter().enumerate() {
        check_index(|| format!("conductance #{k} (end a)"), c.a, n)?;
        check_index(|| format!("conductance #{k} (end b)"), c.b, n)?;
        if c.a == c.b {
            return Err(ThermalError::SelfConductance {
                conductance: k,
                node: nodes[c.a].name.clone(),
                index: c.a,
            });
        }
        if !(c.w_per_k.is_finite() && c.w_per_k >= 0.0) {
            return Err(ThermalError::InvalidConductance {
                conductance: k,
                a: nodes[c.a].name.clone(),
                b: nodes[c.b].name.clone(),
                value: c.w_per_k,
            });
        }
    }
    Ok(())
}

fn validate_sources(nodes: &[ThermalNode], sources: &[HeatSource]) -> Result<(), ThermalError> {
    for (k, source) in sources.iter().enumerate() {
        check_index(|| format!("heat source #{k}"), source.node(), nodes.len())?;
        let node = || nodes[source.node()].name.clone();
        let coefficient_error = |coefficient, value| ThermalError::InvalidHeatCoefficient {
            heat_source: k,
            node: node(),
            coefficient,
            value,
        };
        let coefficients: &[(&'static str, f64)] = match *source {
            HeatSource::Spindle {
                w_per_rpm,
                w_per_rpm2,
                ..
            } => &[
                ("w_per_rpm (W/rpm)", w_per_rpm),
                ("w_per_rpm2 (W/rpm²)", w_per_rpm2),
            ],
            HeatSource::Axis {
                axis,
                w_per_m_per_s,
                ..
            } => {
                if axis >= 3 {
                    return Err(ThermalError::InvalidAxis {
                        heat_source: k,
                        node: node(),
                        axis,
                    });
                }
                &[("w_per_m_per_s (W/(m/s))", w_per_m_per_s)]
            }
        };
        for &(name, value) in coefficients {
            if !(value.is_finite() && value >= 0.0) {
                return Err(coefficient_error(name, value));
            }
        }
    }
    Ok(())
}

/// Failure of the modal decomposition, before node names are attached.
enum ModalError {
    NonFinite { row: usize, value: f64 },
    NotConverged { max_iterations: usize },
}

/// `S = C^-1/2 K C^-1/2 = V diag(μ) Vᵀ` with the scalings `C^±1/2`.
#[derive(Debug, Clone, PartialEq)]
struct Modal {
    c_sqrt: DVector<f64>,
    c_inv_sqrt: DVector<f64>,
    v: DMatrix<f64>,
    mu: DVector<f64>,
}

impl Modal {
    fn new(capacities: &[f64], k: &DMatrix<f64>) -> Result<Self, ModalError> {
        let n = capacities.len();
        let c_sqrt = DVector::from_iterator(n, capacities.iter().map(|c| c.sqrt()));
        let c_inv_sqrt = c_sqrt.map(|s| 1.0 / s);
        let s = DMatrix::from_fn(n, n, |i, j| c_inv_sqrt[i] * k[(i, j)] * c_inv_sqrt[j]);
        if let Some((index, &value)) = s.iter().enumerate().find(|(_, x)| !x.is_finite()) {
            // Column-major storage: the row is the index modulo n.
            return Err(ModalError::NonFinite {
                row: index % n,
                value,
            });
        }
        let max_iterations = EIGEN_BASE_ITERATIONS + EIGEN_ITERATIONS_PER_NODE * n;
        let eigen = SymmetricEigen::try_new(s, f64::EPSILON, max_iterations)
            .ok_or(ModalError::NotConverged { max_iterations })?;
        Ok(Self {
            c_sqrt,
            c_inv_sqrt,
            v: eigen.eigenvectors,
            mu: clamp_round_off(eigen.eigenvalues),
        })
    }

    /// `exp(−μ h)` and `φ₁(μ, h) = (1 − exp(−μ h))/μ` for each mode.
    fn factors(&self, h: f64) -> (Vec<f64>, Vec<f64>) {
        self.mu
            .iter()
            .map(|&mu| {
                if mu > 0.0 {
                    let em1 = (-mu * h).exp_m1();
                    (1.0 + em1, -em1 / mu)
                } else {
                    (1.0, h)
                }
            })
            .unzip()
    }

    /// One step: `T ← T_amb + Φ (T − T_amb) + Γ Q`, evaluated in modal
    /// coordinates with the given factors.
    fn apply(
        &self,
        temps_c: &mut [f64],
        heat_w: &[f64],
        ambient_c: f64,
        factors: (&[f64], &[f64]),
    ) {
        let n = self.mu.len();
        let y = DVector::from_iterator(
            n,
            temps_c
                .iter()
                .zip(self.c_sqrt.iter())
                .map(|(t, s)| s * (t - ambient_c)),
        );
        let q = DVector::from_iterator(
            n,
            heat_w
                .iter()
                .zip(self.c_inv_sqrt.iter())
                .map(|(p, s)| s * p),
        );
        let mut z = self.v.tr_mul(&y);
        let zq = self.v.tr_mul(&q);
        let (decay, gain) = factors;
        for (((zk, qk), e), p) in z.iter_mut().zip(zq.iter()).zip(decay).zip(gain) {
            *zk = e * *zk + p * qk;
        }
        let y_new = &self.v * z;
        for ((t, s), yk) in temps_c
            .iter_mut()
            .zip(self.c_inv_sqrt.iter())
            .zip(y_new.iter())
        {
            *t = ambient_c + s * yk;
        }
    }
}

/// Sets eigenvalues at round-off level (and the negative ones, which `S`
/// being positive semi-definite cannot have) to exactly zero.
fn clamp_round_off(mut mu: DVector<f64>) -> DVector<f64> {
    let n = mu.len() as f64;
    let scale = mu.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let tolerance = EIGEN_ZERO_FACTOR * n * f64::EPSILON * scale;
    mu.iter_mut()
        .filter(|x| **x <= tolerance)
        .for_each(|x| *x = 0.0);
    mu
}

/// The network discretised exactly over a fixed step (zero-order hold on
/// the heat and the ambient temperature), from
/// [`ThermalNetwork::discretize`].
#[derive(Debug, Clone, PartialEq)]
pub struct ThermalStepper {
    dt_s: f64,
    modal: Modal,
    decay: Vec<f64>,
    gain: Vec<f64>,
}

impl ThermalStepper {
    /// The step in s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.decay.len()
    }

    /// Advances `temps_c` (°C) by one step `dt_s` with the heat `heat_w`
    /// (W per node) and the ambient `ambient_c` (°C) held constant over the
    /// step. The caller chooses the ambient value; [`super::ThermalRun`]
    /// uses the value at the step's midpoint.
    ///
    /// # Panics
    ///
    /// If `temps_c` or `heat_w` does not have one entry per node (a
    /// programming error, not bad input data).
    pub fn step(&self, temps_c: &mut [f64], heat_w: &[f64], ambient_c: f64) {
        self.check_lengths(temps_c, heat_w);
        self.modal
            .apply(temps_c, heat_w, ambient_c, (&self.decay, &self.gain));
    }

    /// Like [`Self::step`] but over the step `h_s` (exactly discretised; `h_s`
    /// equal to `dt_s` reuses the precomputed factors).
    pub(crate) fn step_by(&self, temps_c: &mut [f64], heat_w: &[f64], ambient_c: f64, h_s: f64) {
        if h_s == self.dt_s {
            return self.step(temps_c, heat_w, ambient_c);
        }
        self.check_lengths(temps_c, heat_w);
        let (decay, gain) = self.modal.factors(h_s);
        self.modal
            .apply(temps_c, heat_w, ambient_c, (&decay, &gain));
    }

    fn check_lengths(&self, temps_c: &[f64], heat_w: &[f64]) {
        let n = self.node_count();
        assert!(
            temps_c.len() == n && heat_w.len() == n,
            "ThermalStepper::step: expected {n} temperatures and heat flows, got {} and {}",
            temps_c.len(),
            heat_w.len()
        );
    }
}
