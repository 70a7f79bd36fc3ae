//! Lumped thermal network of the machine: ISO 230-3 warm-up, cool-down and
//! ambient drift.
//!
//! # Model
//!
//! The structure is divided into `n` lumped bodies (nodes: spindle housing,
//! headstock, column, bed, ...), each at one uniform temperature `T_i`. This
//! is the lumped-capacitance (thermal RC network) approximation used for
//! machine tools (Mayr et al. 2012, section 4); it is valid when each body's
//! internal conduction is fast compared with its exchange with the
//! surroundings (small Biot number). Node `i` stores heat in its capacity
//! `C_i`, exchanges heat with node `j` through the conductance `G_ij = G_ji`
//! (conduction through joints and contacts) and with the surrounding air
//! through `g_i` (convection and radiation, linearised), and receives the
//! heat `Q_i(t)` of the sources mounted on it:
//!
//! ```text
//! C_i dT_i/dt = Σ_j G_ij (T_j − T_i) + g_i (T_amb(t) − T_i) + Q_i(t)
//! ```
//!
//! In matrix form, with `C = diag(C_i)`, the conductance Laplacian `L`
//! (`L_ii = Σ_j G_ij`, `L_ij = −G_ij`) and `K = L + diag(g)`:
//!
//! ```text
//! dT/dt = A T + C⁻¹ Q + C⁻¹ g T_amb,        A = −C⁻¹ K
//! ```
//!
//! `A` is similar to `−S` with the symmetric positive semi-definite matrix
//! `S = C^-1/2 K C^-1/2`, so its eigenvalues are real and `≤ 0`: the network
//! relaxes without oscillation. With `S = V diag(μ) Vᵀ`, the time constants
//! of the network are `1/μ_k` for `μ_k > 0`. A zero eigenvalue belongs to a
//! group of nodes with no path of positive conductances to ambient; the
//! capacity-weighted sum of their temperatures just integrates their heat.
//!
//! # Heat sources
//!
//! See [`HeatSource`]: spindle loss `Q = a·|n| + b·n²` (`n` in rpm, `a` in
//! W/rpm, `b` in W/rpm²: speed-proportional friction plus the drag and
//! motor losses growing with the square of speed) and axis motion loss
//! `Q = c·|v|` (`v` the mean axis speed in m/s, `c` in W/(m/s), i.e. an
//! effective friction force in N of ball-screw nut, support bearings and
//! guideways).
//!
//! # Integrator
//!
//! Exact zero-order-hold discretisation (Van Loan 1978): over a step
//! `[t, t + h]` the inputs are held constant — the heat `Q` of the operating
//! point (a [`ThermalRun`] never lets a step straddle a change of the
//! [`ThermalSchedule`], so piecewise-constant heat is integrated exactly)
//! and the ambient temperature sampled **at the step's midpoint**
//! `t + h/2`. Then
//!
//! ```text
//! T(t+h) = Φ(h) T(t) + Γ(h) (Q + g T_amb)
//! Φ(h) = C^-1/2 V diag(exp(−μ h))   Vᵀ C^+1/2
//! Γ(h) = C^-1/2 V diag(φ₁(μ, h))    Vᵀ C^-1/2,   φ₁(μ, h) = (1 − exp(−μ h))/μ
//! ```
//!
//! `φ₁` is evaluated as `−expm1(−μ h)/μ`, which tends to `h` as `μ → 0`
//! (a node with no path to ambient integrates its heat). Because a uniform
//! temperature equal to the ambient is an equilibrium, `Φ 1 + Γ g = 1`, and
//! the update is evaluated in the algebraically identical form
//! `T(t+h) = T_amb + Φ (T − T_amb) + Γ Q`, in the modal coordinates of `S`
//! (products with `Vᵀ` and `V`, no explicit `Φ`, `Γ`), so that a step of any
//! length costs the same. Since `0 < exp(−μ h) ≤ 1` the scheme is
//! unconditionally stable: every `dt > 0` is accepted, and for constant
//! inputs the result does not depend on `dt` at all. The only time-step
//! error is that of holding a varying ambient over a step; for a sinusoid
//! of angular frequency `ω` sampled at the midpoint it is of relative order
//! `(ω dt)²`.
//!
//! The eigendecomposition of `S` uses nalgebra's
//! [`SymmetricEigen::try_new`](nalgebra::SymmetricEigen::try_new) with a
//! bounded number of iterations (non-convergence is an error, never a hang);
//! eigenvalues below `64 n ε max μ` (round-off level) are taken as exactly
//! zero, i.e. as infinite time constants.
//!
//! # Units
//!
//! SI throughout: time in s, temperature in °C (differences in K), heat
//! flow in W, capacity in J/K, conductance in W/K, speeds in m/s, except the
//! spindle speed in rpm.
//!
//! # The screws along their length
//!
//! [`screw`] gives a ball screw a temperature field along its length instead of one node:
//! conduction, convection, and the nut's heat where the nut runs, built as a network of this
//! module's kind (one node per finite volume) and stepped exactly as above. Its growth between
//! the fixed bearing and the nut replaces the lumped expansion of that axis in a simulated job.
//!
//! # References
//!
//! - ISO 230-3:2020, *Test code for machine tools — Part 3: Determination
//!   of thermal effects* (environmental temperature variation error,
//!   thermal distortion caused by rotating spindles and by moving linear
//!   axes: the warm-up and cool-down cycles this module simulates).
//! - J. Mayr et al. (2012), *Thermal issues in machine tools*, CIRP Annals
//!   — Manufacturing Technology 61(2), 771–791.
//! - C. F. Van Loan (1978), *Computing integrals involving the matrix
//!   exponential*, IEEE Transactions on Automatic Control 23(3), 395–404.

mod ambient;
mod network;
mod schedule;
pub mod screw;

pub use ambient::Ambient;
pub use network::{
    Conductance, HeatSource, Operating, ThermalNetwork, ThermalNode, ThermalStepper,
};
pub use schedule::{Segment, ThermalRun, ThermalSchedule, temperatures_at};

/// Range of structure temperatures the model accepts as input, °C: a machine in a shop or a
/// climate chamber, with a spindle housing that may run hot; outside it the linear expansion
/// coefficients of the deformation model no longer hold.
pub const NODE_TEMPERATURE_RANGE_C: (f64, f64) = (-50.0, 150.0);

/// Everything that can go wrong when building or running a thermal model.
///
/// Each variant names the offending node, conductance, heat source,
/// ambient point or schedule segment, the rejected value, and what is
/// accepted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ThermalError {
    /// The network has no node.
    #[error("the thermal network has no node; at least one node is required")]
    NoNodes,
    /// Two nodes have the same name.
    #[error(
        "node #{second} has the name `{name}` already used by node #{first}; node names must be unique"
    )]
    DuplicateNodeName {
        /// The repeated name.
        name: String,
        /// Index of the first node with this name.
        first: usize,
        /// Index of the repeated node.
        second: usize,
    },
    /// A node's heat capacity is not finite and positive.
    #[error(
        "node `{node}` (#{index}): heat capacity {value} J/K is not accepted; expected a finite value > 0"
    )]
    InvalidCapacity {
        /// Node name.
        node: String,
        /// Node index.
        index: usize,
        /// Rejected capacity in J/K.
        value: f64,
    },
    /// A node's conductance to ambient is not finite and non-negative.
    #[error(
        "node `{node}` (#{index}): conductance to ambient {value} W/K is not accepted; expected a finite value >= 0"
    )]
    InvalidAmbientConductance {
        /// Node name.
        node: String,
        /// Node index.
        index: usize,
        /// Rejected conductance in W/K.
        value: f64,
    },
    /// A node's initial temperature is not finite.
    #[error(
        "node `{node}` (#{index}): initial temperature {value} °C is not accepted; expected a finite value (or none for the ambient at t = 0)"
    )]
    InvalidInitialTemperature {
        /// Node name.
        node: String,
        /// Node index.
        index: usize,
        /// Rejected temperature in °C.
        value: f64,
    },
    /// A conductance or heat source refers to a node that does not exist.
    #[error(
        "{item} refers to node index {index}, but the network has {node_count} node(s); accepted indices are 0..{node_count}"
    )]
    NodeIndexOutOfRange {
        /// The referring item, e.g. `conductance #2` or `heat source #0`.
        item: String,
        /// The rejected node index.
        index: usize,
        /// Number of nodes in the network.
        node_count: usize,
    },
    /// A conductance connects a node to itself.
    #[error(
        "conductance #{conductance} connects node `{node}` (#{index}) to itself; a conductance must join two different nodes"
    )]
    SelfConductance {
        /// Conductance index.
        conductance: usize,
        /// Node name.
        node: String,
        /// Node index.
        index: usize,
    },
    /// A conductance value is not finite and non-negative.
    #[error(
        "conductance #{conductance} between `{a}` and `{b}`: {value} W/K is not accepted; expected a finite value >= 0"
    )]
    InvalidConductance {
        /// Conductance index.
        conductance: usize,
        /// Name of the first node.
        a: String,
        /// Name of the second node.
        b: String,
        /// Rejected value in W/K.
        value: f64,
    },
    /// A heat-source coefficient is not finite and non-negative.
    #[error(
        "heat source #{heat_source} on node `{node}`: {coefficient} = {value} is not accepted; expected a finite value >= 0"
    )]
    InvalidHeatCoefficient {
        /// Heat-source index.
        heat_source: usize,
        /// Name of the node the source heats.
        node: String,
        /// Name and unit of the coefficient, e.g. `w_per_rpm (W/rpm)`.
        coefficient: &'static str,
        /// Rejected value.
        value: f64,
    },
    /// An axis heat source names an axis other than X, Y, Z.
    #[error(
        "heat source #{heat_source} on node `{node}`: axis index {axis} is not accepted; expected 0 (X), 1 (Y) or 2 (Z)"
    )]
    InvalidAxis {
        /// Heat-source index.
        heat_source: usize,
        /// Name of the node the source heats.
        node: String,
        /// Rejected axis index.
        axis: usize,
    },
    /// A parameter of the ambient temperature model is out of range.
    #[error("ambient {what} = {value} is not accepted; expected {accepted}")]
    InvalidAmbient {
        /// The parameter, e.g. `sinusoid period_s` or `table celsius[3]`.
        what: String,
        /// Rejected value.
        value: f64,
        /// What is accepted.
        accepted: &'static str,
    },
    /// The ambient table has no point.
    #[error("the ambient table is empty; at least one (time, temperature) point is required")]
    AmbientTableEmpty,
    /// The ambient table's columns differ in length.
    #[error(
        "the ambient table has {times} time(s) but {temperatures} temperature(s); both columns must have the same length"
    )]
    AmbientTableLength {
        /// Number of times.
        times: usize,
        /// Number of temperatures.
        temperatures: usize,
    },
    /// The ambient table's times are not strictly increasing.
    #[error(
        "ambient table point #{index} at t = {value_s} s is not after point #{previous_index} at t = {previous_s} s; times must be strictly increasing"
    )]
    AmbientTableNotIncreasing {
        /// Index of the offending point.
        index: usize,
        /// Its time in s.
        value_s: f64,
        /// Index of the point before it.
        previous_index: usize,
        /// Time of the point before it, in s.
        previous_s: f64,
    },
    /// A time step is not finite and positive.
    #[error("time step {value} s is not accepted; expected a finite value > 0")]
    InvalidTimeStep {
        /// Rejected step in s.
        value: f64,
    },
    /// An operating point has a non-finite speed.
    #[error("operating point: {quantity} = {value} is not accepted; expected a finite value")]
    InvalidOperating {
        /// Name and unit of the speed.
        quantity: &'static str,
        /// Rejected value.
        value: f64,
    },
    /// An ambient temperature passed as argument is not finite.
    #[error("ambient temperature {value} °C is not accepted; expected a finite value")]
    InvalidAmbientTemperature {
        /// Rejected value in °C.
        value: f64,
    },
    /// A node has no path of positive conductances to ambient, so it has no
    /// steady state under heat input.
    #[error(
        "node `{node}` (#{index}) has no path of positive conductances to ambient, so the network has no steady state; give it (or a node connected to it) a conductance to ambient > 0"
    )]
    NoPathToAmbient {
        /// Node name.
        node: String,
        /// Node index.
        index: usize,
    },
    /// The scaled system matrix overflowed (extreme ratio of conductance to
    /// capacity).
    #[error(
        "the scaled conductance matrix C^-1/2 K C^-1/2 has the non-finite entry {value} at node `{node}`; capacities and conductances must have ratios representable in f64"
    )]
    NumericalRange {
        /// Name of a node in the offending row.
        node: String,
        /// The non-finite entry.
        value: f64,
    },
    /// The symmetric eigendecomposition did not converge.
    #[error(
        "the eigendecomposition of the {nodes}-node thermal network did not converge within {max_iterations} iterations"
    )]
    EigenNotConverged {
        /// Number of nodes.
        nodes: usize,
        /// The iteration bound used.
        max_iterations: usize,
    },
    /// The steady-state system could not be factorised.
    #[error(
        "the steady-state system of the thermal network is numerically singular (Cholesky factorisation failed); check for extreme conductance ratios"
    )]
    SingularSystem,
    /// A schedule segment's end time is not finite, not positive, or not
    /// after the previous segment's end.
    #[error(
        "schedule segment #{segment} ends at {value} s; expected a finite time > {previous_s} s (the previous segment's end, or the start at 0)"
    )]
    InvalidSegmentEnd {
        /// Segment index.
        segment: usize,
        /// Rejected end time in s.
        value: f64,
        /// The previous segment's end (0 for the first segment).
        previous_s: f64,
    },
    /// A schedule segment has a non-finite or negative speed.
    #[error(
        "schedule segment #{segment}: {quantity} = {value} is not accepted; expected a finite value >= 0"
    )]
    InvalidSegmentSpeed {
        /// Segment index.
        segment: usize,
        /// Name and unit of the speed.
        quantity: &'static str,
        /// Rejected value.
        value: f64,
    },
    /// A requested time is not finite.
    #[error("time {value} s is not accepted; expected a finite time")]
    InvalidTime {
        /// Rejected time in s.
        value: f64,
    },
    /// A run was asked to go back in time.
    #[error(
        "a thermal run cannot go backwards from t = {from_s} s to t = {to_s} s; expected a time >= {from_s} s"
    )]
    BackwardsInTime {
        /// Current time of the run in s.
        from_s: f64,
        /// Requested time in s.
        to_s: f64,
    },
}
