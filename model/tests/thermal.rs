//! Tests of the lumped thermal network (`vmt_model::thermal`): closed-form
//! responses, conservation, steady state, frequency response, stiffness and
//! input validation.

use nalgebra::Complex;
use proptest::prelude::*;
use vmt_model::thermal::{
    Ambient, Conductance, HeatSource, Operating, Segment, ThermalError, ThermalNetwork,
    ThermalNode, ThermalRun, ThermalSchedule, temperatures_at,
};

const AMBIENT_C: f64 = 20.0;

fn node(name: &str, capacity_j_per_k: f64, to_ambient_w_per_k: f64) -> ThermalNode {
    ThermalNode {
        name: name.to_owned(),
        capacity_j_per_k,
        to_ambient_w_per_k,
        initial_c: None,
    }
}

fn link(a: usize, b: usize, w_per_k: f64) -> Conductance {
    Conductance { a, b, w_per_k }
}

fn spindle(node: usize, w_per_rpm: f64, w_per_rpm2: f64) -> HeatSource {
    HeatSource::Spindle {
        node,
        w_per_rpm,
        w_per_rpm2,
    }
}

fn rpm(spindle_rpm: f64) -> Operating {
    Operating {
        spindle_rpm,
        axis_speed_m_s: [0.0; 3],
    }
}

fn constant_ambient() -> Ambient {
    Ambient::Constant { celsius: AMBIENT_C }
}

/// One segment at `op` until `until_s`, then stopped.
fn schedule(until_s: f64, op: Operating) -> ThermalSchedule {
    ThermalSchedule::new(vec![Segment { until_s, op }]).unwrap()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn energy_j(network: &ThermalNetwork, temps: &[f64]) -> f64 {
    network
        .nodes()
        .iter()
        .zip(temps)
        .map(|(n, t)| n.capacity_j_per_k * t)
        .sum()
}

fn error_of<T: std::fmt::Debug>(result: Result<T, ThermalError>) -> (ThermalError, String) {
    let err = result.expect_err("expected a validation error");
    let message = err.to_string();
    (err, message)
}

fn assert_mentions(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(
            message.contains(part),
            "error message {message:?} does not mention {part:?}"
        );
    }
}

// ---------------------------------------------------------------------------
// 1. single node: first-order step response, exact for any dt
// ---------------------------------------------------------------------------

#[test]
fn single_node_warm_up_and_cool_down_match_the_exponential_for_any_dt() {
    let (c, g) = (2.0e4, 10.0); // J/K, W/K
    let tau = c / g; // 2000 s
    let network = ThermalNetwork::new(
        vec![node("spindle", c, g)],
        vec![],
        vec![spindle(0, 0.01, 1.0e-6)],
        constant_ambient(),
    )
    .unwrap();
    let op = rpm(6000.0);
    let q = 0.01 * 6000.0 + 1.0e-6 * 6000.0 * 6000.0; // 96 W
    assert!((network.heat_input_w(&op)[0] - q).abs() < 1e-12);

    let taus = network.time_constants_s().unwrap();
    assert_eq!(taus.len(), 1);
    assert!((taus[0] - tau).abs() < 1e-12 * tau, "{taus:?}");

    // Warm-up for 10000 s (5 tau), then cool-down.
    let t_on = 10_000.0;
    let plan = schedule(t_on, op);
    let rise = |t: f64| q / g * (-(-t / tau).exp_m1());
    let expected = |t: f64| {
        if t <= t_on {
            AMBIENT_C + rise(t)
        } else {
            AMBIENT_C + rise(t_on) * (-(t - t_on) / tau).exp()
        }
    };

    // 63.2 % of the final rise after one time constant.
    let at_tau = temperatures_at(&network, &plan, 60.0, &[tau]).unwrap()[0][0];
    let fraction = (at_tau - AMBIENT_C) / (q / g);
    assert!((fraction - 0.632).abs() < 5e-4, "{fraction}");
    assert!((fraction - (1.0 - (-1.0_f64).exp())).abs() < 1e-12);

    // The whole curve, at times that are not multiples of dt, for steps from
    // far below to far above tau.
    let times: Vec<f64> = (0..=150).map(|k| f64::from(k) * 137.0).collect();
    for dt in [0.5, 7.3, 60.0, 1000.0, 3.0e4] {
        let temps = temperatures_at(&network, &plan, dt, &times).unwrap();
        for (t, temp) in times.iter().zip(&temps) {
            let err = (temp[0] - expected(*t)).abs();
            assert!(err < 1e-9, "dt = {dt} s, t = {t} s: error {err} K");
        }
    }
}

#[test]
fn node_without_path_to_ambient_integrates_its_heat() {
    let (c, q) = (5.0e3, 40.0);
    let network = ThermalNetwork::new(
        vec![node("isolated", c, 0.0)],
        vec![],
        vec![spindle(0, q / 1000.0, 0.0)],
        constant_ambient(),
    )
    .unwrap();
    assert!(network.time_constants_s().unwrap().is_empty());
    let plan = schedule(1000.0, rpm(1000.0));
    let temps = temperatures_at(&network, &plan, 30.0, &[500.0, 2000.0]).unwrap();
    assert!((temps[0][0] - (AMBIENT_C + q * 500.0 / c)).abs() < 1e-10);
    assert!((temps[1][0] - (AMBIENT_C + q * 1000.0 / c)).abs() < 1e-10);
    let (err, message) = error_of(network.steady_state_c(&rpm(1000.0), AMBIENT_C));
    assert!(matches!(
        err,
        ThermalError::NoPathToAmbient { index: 0, .. }
    ));
    assert_mentions(&message, &["`isolated`", "no path"]);
}

// ---------------------------------------------------------------------------
// Random networks for the property tests
// ---------------------------------------------------------------------------

/// A random network description: capacities (J/K), conductances to
/// ambient (W/K), links, and heat per node (W).
#[derive(Debug, Clone)]
struct RandomNet {
    capacities: Vec<f64>,
    to_ambient: Vec<f64>,
    links: Vec<(usize, usize, f64)>,
    heat_w: Vec<f64>,
}

impl RandomNet {
    /// The network with one spindle source per node delivering `heat_w` at
    /// 1000 rpm.
    fn build(&self) -> ThermalNetwork {
        let nodes = (0..self.capacities.len())
            .map(|i| node(&format!("n{i}"), self.capacities[i], self.to_ambient[i]))
            .collect();
        let links = self.links.iter().map(|&(a, b, w)| link(a, b, w)).collect();
        let sources = self
            .heat_w
            .iter()
            .enumerate()
            .map(|(i, q)| spindle(i, q / 1000.0, 0.0))
            .collect();
        ThermalNetwork::new(nodes, links, sources, constant_ambient()).unwrap()
    }
}

/// Log-uniform value in `[lo, hi]`.
fn log_uniform(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo.ln()..hi.ln()).prop_map(f64::exp)
}

/// Random links among `n` nodes: a spanning tree (so the network is
/// connected) plus extra links, possibly parallel.
fn links(n: usize) -> impl Strategy<Value = Vec<(usize, usize, f64)>> {
    let tree = (1..n)
        .map(|i| (0..i, log_uniform(1.0, 200.0)).prop_map(move |(p, w)| (p, i, w)))
        .collect::<Vec<_>>();
    let extra = prop::collection::vec((0..n, 0..n, log_uniform(0.5, 100.0)), 0..4)
        .prop_map(|v| v.into_iter().filter(|(a, b, _)| a != b).collect::<Vec<_>>());
    (tree, extra).prop_map(|(mut t, e)| {
        t.extend(e);
        t
    })
}

/// Connected networks of 1 to 6 nodes; with `ambient` some nodes (at least
/// one) are coupled to ambient, otherwise none.
fn random_net(ambient: bool) -> impl Strategy<Value = RandomNet> {
    (1usize..=6).prop_flat_map(move |n| {
        let to_ambient = (
            prop::collection::vec(prop_oneof![Just(0.0), log_uniform(0.5, 50.0)], n),
            0..n,
            log_uniform(0.5, 50.0),
        )
            .prop_map(move |(mut g, k, gk)| {
                if ambient {
                    g[k] = gk;
                } else {
                    g.iter_mut().for_each(|x| *x = 0.0);
                }
                g
            });
        (
            prop::collection::vec(log_uniform(10.0, 1.0e6), n),
            to_ambient,
            links(n),
            prop::collection::vec(0.0..500.0, n),
        )
            .prop_map(|(capacities, to_ambient, links, heat_w)| RandomNet {
                capacities,
                to_ambient,
                links,
                heat_w,
            })
    })
}

/// `C_i dT_i/dt` at steady state: `Σ_j G_ij (T_j − T_i) + g_i (T_amb − T_i) +
/// Q_i`, and the sum of the magnitudes of its terms (for a relative check).
fn net_heat_flow(net: &RandomNet, temps: &[f64]) -> Vec<(f64, f64)> {
    let mut flow: Vec<(f64, f64)> = (0..temps.len())
        .map(|i| {
            let to_ambient = net.to_ambient[i] * (AMBIENT_C - temps[i]);
            (to_ambient + net.heat_w[i], to_ambient.abs() + net.heat_w[i])
        })
        .collect();
    for &(a, b, w) in &net.links {
        let q = w * (temps[b] - temps[a]);
        flow[a].0 += q;
        flow[a].1 += q.abs();
        flow[b].0 -= q;
        flow[b].1 += q.abs();
    }
    flow
}

// ---------------------------------------------------------------------------
// 2. energy conservation without ambient coupling
// ---------------------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn without_ambient_coupling_stored_heat_rises_by_q_t(
        net in random_net(false),
        dt in log_uniform(0.1, 1.0e4),
        steps in 1usize..40,
        initial in prop::collection::vec(0.0..50.0f64, 6),
    ) {
        let network = net.build();
        let q_total: f64 = net.heat_w.iter().sum();

        // The stepper alone, from non-uniform temperatures.
        let stepper = network.discretize(dt).unwrap();
        let mut temps = initial[..network.node_count()].to_vec();
        let e0 = energy_j(&network, &temps);
        for _ in 0..steps {
            stepper.step(&mut temps, &net.heat_w, AMBIENT_C);
        }
        let gained = energy_j(&network, &temps) - e0;
        let expected = q_total * dt * steps as f64;
        let scale = expected.abs() + e0.abs();
        prop_assert!((gained - expected).abs() <= 1e-10 * scale,
            "stepper: gained {gained} J, expected {expected} J");

        // A run with heat until t_on (not a multiple of dt), sampled after
        // the cool-down started: the stored heat stays Q t_on.
        let t_on = dt * (steps as f64 + 0.37);
        let plan = schedule(t_on, rpm(1000.0));
        let mut run = ThermalRun::new(&network, &plan, dt).unwrap();
        let e0 = energy_j(&network, run.temperatures_c());
        run.advance_to(1.6 * t_on).unwrap();
        let gained = energy_j(&network, run.temperatures_c()) - e0;
        let expected = q_total * t_on;
        prop_assert!((gained - expected).abs() <= 1e-10 * (expected + e0.abs()),
            "run: gained {gained} J, expected {expected} J");
    }
}

// ---------------------------------------------------------------------------
// 3. steady state
// ---------------------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn long_run_converges_to_the_steady_state_which_solves_the_balance(
        net in random_net(true),
    ) {
        let network = net.build();
        let op = rpm(1000.0);
        let steady = network.steady_state_c(&op, AMBIENT_C).unwrap();

        // The steady state balances the heat flows of every node.
        for (i, (flow, scale)) in net_heat_flow(&net, &steady).into_iter().enumerate() {
            prop_assert!(flow.abs() <= 1e-9 * (scale + 1.0),
                "node {i}: residual {flow} W of {scale} W");
        }

        // A run of 40 of the slowest time constants reaches it (exp(-40) ~ 4e-18).
        let tau_max = *network.time_constants_s().unwrap().last().unwrap();
        let t_end = 40.0 * tau_max;
        let plan = schedule(2.0 * t_end, op);
        let mut run = ThermalRun::new(&network, &plan, tau_max / 8.0).unwrap();
        run.advance_to(t_end).unwrap();
        let max_rise = steady.iter().fold(0.0_f64, |m, t| m.max(t - AMBIENT_C));
        let err = max_abs_diff(run.temperatures_c(), &steady);
        prop_assert!(err <= 1e-7 * (1.0 + max_rise),
            "run ends {err} K from the steady state (rise {max_rise} K)");
    }
}

// ---------------------------------------------------------------------------
// 4. two nodes: closed-form time constants and transient
// ---------------------------------------------------------------------------

fn two_node_network() -> (ThermalNetwork, [f64; 5]) {
    let (c1, c2, g12, g1, g2) = (5.0e4, 2.0e5, 30.0, 4.0, 12.0);
    let network = ThermalNetwork::new(
        vec![node("spindle", c1, g1), node("column", c2, g2)],
        vec![link(0, 1, g12)],
        vec![spindle(0, 0.02, 0.0)],
        constant_ambient(),
    )
    .unwrap();
    (network, [c1, c2, g12, g1, g2])
}

#[test]
fn two_node_time_constants_match_the_closed_form_eigenvalues() {
    let (network, [c1, c2, g12, g1, g2]) = two_node_network();
    // det(K − λ C) = 0: C1 C2 λ² − (k11 C2 + k22 C1) λ + (k11 k22 − G12²) = 0.
    let (k11, k22) = (g1 + g12, g2 + g12);
    let a = c1 * c2;
    let b = k11 * c2 + k22 * c1;
    let c = k11 * k22 - g12 * g12;
    let root = (b * b - 4.0 * a * c).sqrt();
    let (lambda_fast, lambda_slow) = ((b + root) / (2.0 * a), 2.0 * c / (b + root));
    let expected = [1.0 / lambda_fast, 1.0 / lambda_slow];
    let taus = network.time_constants_s().unwrap();
    assert_eq!(taus.len(), 2);
    for (tau, want) in taus.iter().zip(expected) {
        assert!(
            (tau - want).abs() < 1e-12 * want,
            "{taus:?} vs {expected:?}"
        );
    }
}

/// Classical RK4 on the ODE, as an independent reference.
fn rk4_two_node(p: [f64; 5], q: f64, t_end: f64, h: f64) -> [f64; 2] {
    let [c1, c2, g12, g1, g2] = p;
    let f = |t: [f64; 2]| {
        [
            (g12 * (t[1] - t[0]) + g1 * (AMBIENT_C - t[0]) + q) / c1,
            (g12 * (t[0] - t[1]) + g2 * (AMBIENT_C - t[1])) / c2,
        ]
    };
    let add = |t: [f64; 2], k: [f64; 2], s: f64| [t[0] + s * k[0], t[1] + s * k[1]];
    let mut t = [AMBIENT_C; 2];
    let steps = (t_end / h).round() as usize;
    for _ in 0..steps {
        let k1 = f(t);
        let k2 = f(add(t, k1, h / 2.0));
        let k3 = f(add(t, k2, h / 2.0));
        let k4 = f(add(t, k3, h));
        for i in 0..2 {
            t[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    t
}

#[test]
fn two_node_warm_up_matches_an_independent_rk4_integration() {
    let (network, p) = two_node_network();
    let op = rpm(5000.0); // 100 W into the spindle node
    let q = network.heat_input_w(&op)[0];
    assert!((q - 100.0).abs() < 1e-12);
    let plan = schedule(1.0e6, op);
    for t_end in [1000.0, 7000.0, 30_000.0] {
        let exact = temperatures_at(&network, &plan, 450.0, &[t_end]).unwrap();
        let reference = rk4_two_node(p, q, t_end, 1.0);
        let err = max_abs_diff(&exact[0], &reference);
        assert!(err < 1e-9, "t = {t_end} s: {:?} vs {reference:?}", exact[0]);
    }
}

// ---------------------------------------------------------------------------
// 5. sinusoidal ambient: first-order frequency response
// ---------------------------------------------------------------------------

#[test]
fn sinusoidal_ambient_gives_the_first_order_amplitude_ratio_and_phase_lag() {
    let (c, g) = (1.0e5, 10.0);
    let tau = c / g; // 1e4 s
    let (period, amplitude, dt) = (86_400.0, 2.0, 60.0);
    let omega = std::f64::consts::TAU / period;
    let network = ThermalNetwork::new(
        vec![node("bed", c, g)],
        vec![],
        vec![],
        Ambient::Sinusoid {
            mean_c: AMBIENT_C,
            amplitude_k: amplitude,
            period_s: period,
            phase_s: 0.0,
        },
    )
    .unwrap();

    // One full period sampled every dt, after 4 periods (34 tau) of
    // transient: exp(-34) ~ 2e-15.
    let samples = (period / dt).round() as usize;
    let t0 = 4.0 * period;
    let times: Vec<f64> = (0..samples).map(|k| t0 + k as f64 * dt).collect();
    let temps = temperatures_at(&network, &ThermalSchedule::default(), dt, &times).unwrap();

    // Fourier coefficients of the fundamental: T − mean = R A sin(ω t − φ).
    let n = samples as f64;
    let mean = temps.iter().map(|t| t[0]).sum::<f64>() / n;
    let (mut s, mut co) = (0.0, 0.0);
    for (t, temp) in times.iter().zip(&temps) {
        s += (temp[0] - mean) * (omega * t).sin();
        co += (temp[0] - mean) * (omega * t).cos();
    }
    let (s, co) = (2.0 * s / n, 2.0 * co / n);
    let ratio = s.hypot(co) / amplitude;
    let lag = (-co).atan2(s);

    let wt = omega * tau;
    let expected_ratio = 1.0 / (1.0 + wt * wt).sqrt();
    let expected_lag = wt.atan();
    // Holding the midpoint ambient over each step makes the sampled system
    // the discrete filter T[k+1] = e T[k] + (1 − e) T_amb(t_k + dt/2),
    // e = exp(−dt/τ), whose response at ω is
    // H_d = (1 − e) exp(iω dt/2) / (exp(iω dt) − e). It differs from the
    // continuous response by O((ω dt)²): here 7.9e-7 in relative amplitude
    // and 2.2e-6 rad in phase. Tolerance against the continuous response:
    // 1e-5 (relative for the ratio, rad for the lag); against H_d, which
    // the exact discretisation must reproduce, 1e-9.
    let e = (-dt / tau).exp();
    let h_d = Complex::new(1.0 - e, 0.0) * Complex::from_polar(1.0, omega * dt / 2.0)
        / (Complex::from_polar(1.0, omega * dt) - e);
    assert!(
        (ratio - h_d.norm()).abs() < 1e-9,
        "ratio {ratio} vs {}",
        h_d.norm()
    );
    assert!(
        (lag + h_d.arg()).abs() < 1e-9,
        "lag {lag} vs {}",
        -h_d.arg()
    );
    assert!((mean - AMBIENT_C).abs() < 1e-5, "mean {mean}");
    assert!(
        (ratio / expected_ratio - 1.0).abs() < 1e-5,
        "ratio {ratio} vs {expected_ratio}"
    );
    assert!(
        (lag - expected_lag).abs() < 1e-5,
        "lag {lag} rad vs {expected_lag} rad"
    );
}

// ---------------------------------------------------------------------------
// 6. unconditional stability on a stiff network
// ---------------------------------------------------------------------------

fn stiff_network(tip_initial_c: Option<f64>) -> ThermalNetwork {
    let mut tip = node("tool tip", 1.0e-2, 0.0);
    tip.initial_c = tip_initial_c;
    ThermalNetwork::new(
        vec![
            tip,
            node("spindle", 2.0e5, 8.0),
            node("column", 1.0e6, 20.0),
        ],
        vec![link(0, 1, 50.0), link(1, 2, 15.0)],
        vec![spindle(0, 0.02, 0.0)],
        constant_ambient(),
    )
    .unwrap()
}

#[test]
fn stiff_network_with_a_huge_step_stays_bounded_and_reaches_the_steady_state() {
    let dt = 600.0;
    let warm = stiff_network(None);
    let taus = warm.time_constants_s().unwrap();
    assert_eq!(taus.len(), 3);
    // dt is more than a million times the fastest time constant: explicit
    // Euler would need dt < 2 tau_min.
    assert!(taus[0] < dt * 1e-6, "{taus:?}");
    let tau_max = taus[2];
    let op = rpm(10_000.0); // 200 W into the tool tip
    let steady = warm.steady_state_c(&op, AMBIENT_C).unwrap();

    // Warm-up from ambient: each node rises monotonically, never beyond its
    // steady state, and gets there.
    let plan = schedule(1.0e9, op);
    let mut run = ThermalRun::new(&warm, &plan, dt).unwrap();
    let mut previous = run.temperatures_c().to_vec();
    while run.time_s() < 30.0 * tau_max {
        run.advance_to(run.time_s() + dt).unwrap();
        for (i, &t) in run.temperatures_c().iter().enumerate() {
            assert!(t.is_finite() && t >= previous[i] - 1e-9 && t <= steady[i] + 1e-9);
        }
        previous = run.temperatures_c().to_vec();
    }
    let err = max_abs_diff(run.temperatures_c(), &steady);
    assert!(err < 1e-6, "{:?} vs {steady:?}", run.temperatures_c());

    // Cool-down of the hot tip: the maximum principle holds at every step.
    let hot = stiff_network(Some(80.0));
    let still = ThermalSchedule::default();
    let mut run = ThermalRun::new(&hot, &still, dt).unwrap();
    while run.time_s() < 30.0 * tau_max {
        run.advance_to(run.time_s() + dt).unwrap();
        for &t in run.temperatures_c() {
            assert!((AMBIENT_C - 1e-9..=80.0 + 1e-9).contains(&t), "{t}");
        }
    }
    let at_ambient = [AMBIENT_C; 3];
    assert!(max_abs_diff(run.temperatures_c(), &at_ambient) < 1e-6);
}

// ---------------------------------------------------------------------------
// Ambient, schedule and run behaviour
// ---------------------------------------------------------------------------

#[test]
fn ambient_models_evaluate_as_documented() {
    let table = Ambient::Table {
        times_s: vec![0.0, 100.0, 300.0],
        celsius: vec![20.0, 22.0, 18.0],
    };
    assert_eq!(table.celsius_at(-50.0), 20.0);
    assert!((table.celsius_at(50.0) - 21.0).abs() < 1e-12);
    assert!((table.celsius_at(200.0) - 20.0).abs() < 1e-12);
    assert_eq!(table.celsius_at(300.0), 18.0);
    assert_eq!(table.celsius_at(1.0e6), 18.0);

    let sine = Ambient::Sinusoid {
        mean_c: 20.0,
        amplitude_k: 1.5,
        period_s: 400.0,
        phase_s: 100.0,
    };
    assert!((sine.celsius_at(100.0) - 20.0).abs() < 1e-12);
    assert!((sine.celsius_at(200.0) - 21.5).abs() < 1e-12);
    assert!((sine.celsius_at(400.0) - 18.5).abs() < 1e-12);
}

#[test]
fn schedule_segments_are_half_open_and_stop_at_the_end() {
    let plan = ThermalSchedule::new(vec![
        Segment {
            until_s: 100.0,
            op: rpm(1000.0),
        },
        Segment {
            until_s: 250.0,
            op: Operating {
                spindle_rpm: 0.0,
                axis_speed_m_s: [0.1, 0.0, 0.05],
            },
        },
    ])
    .unwrap();
    assert_eq!(plan.duration_s(), 250.0);
    assert_eq!(plan.operating_at(-1.0), Operating::STOPPED);
    assert_eq!(plan.operating_at(0.0), rpm(1000.0));
    assert_eq!(plan.operating_at(99.999), rpm(1000.0));
    assert_eq!(plan.operating_at(100.0).axis_speed_m_s, [0.1, 0.0, 0.05]);
    assert_eq!(plan.operating_at(250.0), Operating::STOPPED);
}

#[test]
fn axis_heat_is_friction_force_times_speed() {
    let network = ThermalNetwork::new(
        vec![node("x nut", 1.0e3, 1.0), node("z nut", 1.0e3, 1.0)],
        vec![],
        vec![
            HeatSource::Axis {
                node: 0,
                axis: 0,
                w_per_m_per_s: 150.0,
            },
            HeatSource::Axis {
                node: 1,
                axis: 2,
                w_per_m_per_s: 80.0,
            },
            spindle(1, 0.001, 0.0),
        ],
        constant_ambient(),
    )
    .unwrap();
    let op = Operating {
        spindle_rpm: 2000.0,
        axis_speed_m_s: [0.2, 5.0, 0.5],
    };
    let heat = network.heat_input_w(&op);
    assert!((heat[0] - 30.0).abs() < 1e-12);
    assert!((heat[1] - (40.0 + 2.0)).abs() < 1e-12);
}

#[test]
fn temperatures_at_returns_results_in_the_callers_order() {
    let (network, _) = two_node_network();
    let network = ThermalNetwork::new(
        network.nodes().to_vec(),
        network.conductances().to_vec(),
        network.sources().to_vec(),
        Ambient::Table {
            times_s: vec![0.0, 3000.0, 9000.0],
            celsius: vec![20.0, 23.0, 19.0],
        },
    )
    .unwrap();
    let plan = schedule(4000.0, rpm(5000.0));
    let sorted = [0.0, 500.0, 2500.0, 2500.0, 7300.0];
    let shuffled = [7300.0, 2500.0, 0.0, 500.0, 2500.0];
    let a = temperatures_at(&network, &plan, 100.0, &sorted).unwrap();
    let b = temperatures_at(&network, &plan, 100.0, &shuffled).unwrap();
    for (k, t) in shuffled.iter().enumerate() {
        let j = sorted.iter().position(|s| s == t).unwrap();
        assert_eq!(b[k], a[j]);
    }
    assert_eq!(a[0], vec![20.0, 20.0]);
}

// ---------------------------------------------------------------------------
// 7. validation errors name the offending item
// ---------------------------------------------------------------------------

fn two_nodes() -> Vec<ThermalNode> {
    vec![node("spindle", 1.0e4, 5.0), node("column", 1.0e5, 10.0)]
}

#[test]
fn negative_capacity_is_rejected() {
    let mut nodes = two_nodes();
    nodes[1].capacity_j_per_k = -5.0;
    let (err, message) = error_of(ThermalNetwork::new(
        nodes,
        vec![],
        vec![],
        constant_ambient(),
    ));
    assert!(matches!(
        err,
        ThermalError::InvalidCapacity { index: 1, .. }
    ));
    assert_mentions(&message, &["`column`", "-5 J/K", "> 0"]);
}

#[test]
fn nan_conductance_is_rejected() {
    let links = vec![link(0, 1, 3.0), link(1, 0, f64::NAN)];
    let (err, message) = error_of(ThermalNetwork::new(
        two_nodes(),
        links,
        vec![],
        constant_ambient(),
    ));
    assert!(matches!(
        err,
        ThermalError::InvalidConductance { conductance: 1, .. }
    ));
    assert_mentions(
        &message,
        &["conductance #1", "`column`", "`spindle`", "NaN"],
    );
}

#[test]
fn nan_conductance_to_ambient_is_rejected() {
    let mut nodes = two_nodes();
    nodes[0].to_ambient_w_per_k = f64::NAN;
    let (_, message) = error_of(ThermalNetwork::new(
        nodes,
        vec![],
        vec![],
        constant_ambient(),
    ));
    assert_mentions(&message, &["`spindle`", "to ambient", "NaN"]);
}

#[test]
fn out_of_range_node_index_is_rejected() {
    let (err, message) = error_of(ThermalNetwork::new(
        two_nodes(),
        vec![link(0, 7, 1.0)],
        vec![],
        constant_ambient(),
    ));
    assert!(matches!(
        err,
        ThermalError::NodeIndexOutOfRange { index: 7, .. }
    ));
    assert_mentions(&message, &["conductance #0", "index 7", "2 node"]);

    let (_, message) = error_of(ThermalNetwork::new(
        two_nodes(),
        vec![],
        vec![spindle(2, 0.01, 0.0)],
        constant_ambient(),
    ));
    assert_mentions(&message, &["heat source #0", "index 2"]);
}

#[test]
fn self_conductance_is_rejected() {
    let (_, message) = error_of(ThermalNetwork::new(
        two_nodes(),
        vec![link(1, 1, 1.0)],
        vec![],
        constant_ambient(),
    ));
    assert_mentions(&message, &["conductance #0", "`column`", "itself"]);
}

#[test]
fn duplicate_node_names_and_empty_networks_are_rejected() {
    let mut nodes = two_nodes();
    nodes[1].name = "spindle".into();
    let (_, message) = error_of(ThermalNetwork::new(
        nodes,
        vec![],
        vec![],
        constant_ambient(),
    ));
    assert_mentions(&message, &["node #1", "`spindle`", "node #0"]);

    let (err, _) = error_of(ThermalNetwork::new(
        vec![],
        vec![],
        vec![],
        constant_ambient(),
    ));
    assert_eq!(err, ThermalError::NoNodes);
}

#[test]
fn bad_heat_sources_are_rejected() {
    let (_, message) = error_of(ThermalNetwork::new(
        two_nodes(),
        vec![],
        vec![spindle(0, 0.01, 0.0), spindle(1, 0.01, -1e-6)],
        constant_ambient(),
    ));
    assert_mentions(
        &message,
        &["heat source #1", "`column`", "w_per_rpm2", "-0.000001"],
    );

    let axis = HeatSource::Axis {
        node: 0,
        axis: 3,
        w_per_m_per_s: 10.0,
    };
    let (_, message) = error_of(ThermalNetwork::new(
        two_nodes(),
        vec![],
        vec![axis],
        constant_ambient(),
    ));
    assert_mentions(&message, &["heat source #0", "axis index 3", "2 (Z)"]);
}

#[test]
fn decreasing_ambient_table_is_rejected() {
    let table = Ambient::Table {
        times_s: vec![0.0, 100.0, 50.0],
        celsius: vec![20.0, 21.0, 22.0],
    };
    let (err, message) = error_of(ThermalNetwork::new(two_nodes(), vec![], vec![], table));
    assert!(matches!(
        err,
        ThermalError::AmbientTableNotIncreasing { index: 2, .. }
    ));
    assert_mentions(&message, &["point #2", "t = 50 s", "point #1", "t = 100 s"]);
}

#[test]
fn malformed_ambient_models_are_rejected() {
    let mismatched = Ambient::Table {
        times_s: vec![0.0, 100.0],
        celsius: vec![20.0],
    };
    let (_, message) = error_of(mismatched.validate());
    assert_mentions(&message, &["2 time(s)", "1 temperature(s)"]);

    let empty = Ambient::Table {
        times_s: vec![],
        celsius: vec![],
    };
    assert_eq!(empty.validate(), Err(ThermalError::AmbientTableEmpty));

    let flat = Ambient::Sinusoid {
        mean_c: 20.0,
        amplitude_k: 1.0,
        period_s: 0.0,
        phase_s: 0.0,
    };
    let (_, message) = error_of(ThermalNetwork::new(two_nodes(), vec![], vec![], flat));
    assert_mentions(&message, &["period_s", "= 0", "> 0 s"]);
}

#[test]
fn backwards_advance_is_rejected_and_leaves_the_run_unchanged() {
    let network = ThermalNetwork::new(
        two_nodes(),
        vec![link(0, 1, 2.0)],
        vec![],
        constant_ambient(),
    )
    .unwrap();
    let plan = ThermalSchedule::default();
    let mut run = ThermalRun::new(&network, &plan, 10.0).unwrap();
    run.advance_to(100.0).unwrap();
    let before = run.temperatures_c().to_vec();
    let (err, message) = error_of(run.advance_to(50.0));
    assert_eq!(
        err,
        ThermalError::BackwardsInTime {
            from_s: 100.0,
            to_s: 50.0
        }
    );
    assert_mentions(&message, &["t = 100 s", "t = 50 s"]);
    assert_eq!(run.time_s(), 100.0);
    assert_eq!(run.temperatures_c(), before.as_slice());

    let (_, message) = error_of(run.advance_to(f64::NAN));
    assert_mentions(&message, &["NaN"]);
    let (_, message) = error_of(temperatures_at(&network, &plan, 10.0, &[5.0, -1.0]));
    assert_mentions(&message, &["t = 0 s", "t = -1 s"]);
}

#[test]
fn bad_time_steps_and_schedules_are_rejected() {
    let network = ThermalNetwork::new(two_nodes(), vec![], vec![], constant_ambient()).unwrap();
    for dt in [0.0, -1.0, f64::INFINITY, f64::NAN] {
        let (err, _) = error_of(network.discretize(dt));
        assert!(matches!(err, ThermalError::InvalidTimeStep { .. }), "{dt}");
    }

    let segments = vec![
        Segment {
            until_s: 100.0,
            op: rpm(1000.0),
        },
        Segment {
            until_s: 100.0,
            op: rpm(2000.0),
        },
    ];
    let (_, message) = error_of(ThermalSchedule::new(segments));
    assert_mentions(&message, &["segment #1", "100 s", "> 100 s"]);

    let (_, message) = error_of(ThermalSchedule::new(vec![Segment {
        until_s: 100.0,
        op: Operating {
            spindle_rpm: 1000.0,
            axis_speed_m_s: [0.0, -0.2, 0.0],
        },
    }]));
    assert_mentions(&message, &["segment #0", "Y axis", "-0.2"]);
}
