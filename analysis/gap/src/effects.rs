//! The library of candidate effects: each a switch of the model with its free parameters,
//! written as the scenario keys it changes. A parameter's value is an offset added to what the
//! model file sets at each of its keys, so a candidate at zero is the model unchanged.
//!
//! The keys follow the scenario format of `scenarios/vmc500.toml`; a candidate whose keys the
//! model file does not set is reported as unavailable rather than invented.

/// One free parameter of a candidate.
#[derive(Clone, Debug, PartialEq)]
pub struct Param {
    /// Name, e.g. `backlash X`.
    pub name: String,
    /// Unit of the offset (the keys' unit).
    pub unit: &'static str,
    /// The keys that take the offset (all the same).
    pub keys: Vec<String>,
    /// Finite-difference step for its sensitivity, in `unit`: large enough to stand above the
    /// simulator's round-off, small enough to stay linear.
    pub step: f64,
    /// A typical size on a real machine of the class, in `unit`: what `vmt gap-bench` injects
    /// times 1, 2 and 3, chosen so that the smallest stands clear (about 0.2 µm RMS or more) of
    /// the bench's nuisance on its 100 mm, 2000 mm/min test.
    pub typical: f64,
    /// Whether only increases are physical (a backlash, a friction force above the model's).
    pub increase_only: bool,
}

/// One candidate effect.
#[derive(Clone, Debug, PartialEq)]
pub struct Effect {
    /// Short key, e.g. `backlash_x`.
    pub key: String,
    /// What the physics is.
    pub description: String,
    /// Its free parameters.
    pub params: Vec<Param>,
    /// A property of the measurement rather than of the machine (the bar's set-up): fitted
    /// with every candidate and before any, never attributed.
    pub baseline: bool,
}

fn param(name: &str, unit: &'static str, keys: &[String], (step, typical): (f64, f64)) -> Param {
    Param {
        name: name.into(),
        unit,
        keys: keys.to_vec(),
        step,
        typical,
        increase_only: false,
    }
}

/// A parameter that can only grow (a negative gap or friction force is not physical).
fn growing(p: Param) -> Param {
    Param {
        increase_only: true,
        ..p
    }
}

fn effect(key: &str, description: &str, params: Vec<Param>) -> Effect {
    Effect {
        key: key.into(),
        description: description.into(),
        params,
        baseline: false,
    }
}

/// The built-in library for the axes of a test plane (`p`, `q` axis letters, lower case).
pub fn library(p: char, q: char) -> Vec<Effect> {
    let mut out = Vec::new();
    for a in [p, q] {
        let up = a.to_ascii_uppercase();
        let axis = format!("machine.axes.{a}");
        let errors = format!("machine.errors.{a}");
        out.push(effect(
            &format!("backlash_{a}"),
            &format!("lost motion in the {up} screw-nut (drive backlash)"),
            vec![growing(param(
                &format!("backlash {up}"),
                "um",
                &[format!("{axis}.drive.backlash_um")],
                (1.0, 2.0),
            ))],
        ));
        out.push(effect(
            &format!("friction_{a}"),
            &format!(
                "friction level of the {up} guides, Coulomb and static alike (reversal spikes)"
            ),
            vec![growing(param(
                &format!("Coulomb force {up}"),
                "N",
                &[
                    format!("{axis}.drive.guide_friction.coulomb_n"),
                    format!("{axis}.drive.guide_friction.static_n"),
                ],
                (20.0, 80.0),
            ))],
        ));
        out.push(effect(
            &format!("stick_slip_{a}"),
            &format!("static friction peak of the {up} guides over Coulomb (stick-slip)"),
            vec![growing(param(
                &format!("static force {up}"),
                "N",
                &[format!("{axis}.drive.guide_friction.static_n")],
                (50.0, 250.0),
            ))],
        ));
        let other = if a == p { q } else { p }.to_ascii_uppercase();
        out.push(effect(
            &format!("lateral_play_{a}"),
            &format!("lateral play of {up}: the {other} offset of the backward approach"),
            vec![param(
                &format!("E{other}{up} backward c0"),
                "um",
                &[format!("{errors}.backward.E{other}{up}_um[0]")],
                (1.0, 1.5),
            )],
        ));
        out.push(effect(
            &format!("cyclic_{a}"),
            &format!("periodic lead error of the {up} screw, once per revolution (cyclic error)"),
            ["cos", "sin"]
                .iter()
                .enumerate()
                .map(|(i, part)| {
                    param(
                        &format!("lead error {up} {part}"),
                        "um",
                        &[format!("{axis}.drive.screw_cyclic_um[{i}]")],
                        // Both parts at 0.7 µm: an amplitude of 1 µm (ISO 3408-3 v2π of
                        // 1-6 µm by accuracy class).
                        (0.5, 0.7),
                    )
                })
                .collect(),
        ));
        out.push(effect(
            &format!("straightness_{a}"),
            &format!("straightness of {up} in {other}: the bow (Legendre c2) of E{other}{up}"),
            vec![param(
                &format!("E{other}{up} c2"),
                "um",
                &[format!("{errors}.forward.E{other}{up}_um[2]")],
                (2.0, 6.0),
            )],
        ));
    }
    // A ball bar sees only the difference of the two lags, so one gain carries the mismatch.
    let (pu, qu) = (p.to_ascii_uppercase(), q.to_ascii_uppercase());
    // Likewise the scales: with the mean radius a baseline, only their difference shows.
    let e = format!("machine.errors.{p}");
    out.push(effect(
        "scale_mismatch",
        &format!(
            "scale mismatch: the linear positioning error (E{pu}{pu} slope) of {pu} against {qu}'s"
        ),
        vec![param(
            &format!("E{pu}{pu} c1 (half the change over the stroke)"),
            "um",
            &[
                format!("{e}.forward.E{pu}{pu}_um[1]"),
                format!("{e}.backward.E{pu}{pu}_um[1]"),
            ],
            (2.0, 3.0),
        )],
    ));
    out.push(effect(
        "servo_mismatch",
        &format!("servo mismatch: the position-loop gain of {pu} against {qu}'s"),
        vec![param(
            &format!("Kv {pu}"),
            "1/s",
            &[format!("machine.axes.{p}.servo.kv_per_s")],
            // 0.1/s at Kv = 33/s is a lag change of ΔKv/Kv² ≈ 0.09 ms.
            (0.1, 0.1),
        )],
    ));
    out.push(effect(
        "squareness",
        "out-of-squareness of the plane's axes",
        vec![param(
            "squareness",
            "urad",
            &[squareness_key(p, q)],
            (10.0, 15.0),
        )],
    ));
    out.push(Effect {
        baseline: true,
        ..effect(
            "setup",
            "ball-bar pivot set-up offset (eccentricity)",
            (0..2)
                .map(|i| {
                    let a = if i == 0 { p } else { q };
                    param(
                        &format!("pivot offset {}", a.to_ascii_uppercase()),
                        "um",
                        &[format!(
                            "instruments.ballbar.setup_eccentricity_um[{}]",
                            axis_index(a)
                        )],
                        (5.0, 8.0),
                    )
                })
                .collect(),
        )
    });
    // The mean radius is the bar's calibration as much as the machine's: a baseline, as in
    // ball-bar practice, where scale is judged by the difference between the axes.
    out.push(Effect {
        baseline: true,
        ..effect(
            "bar_length",
            "bar length error (bar temperature against its calibration)",
            vec![param(
                "bar temperature",
                "K",
                &["instruments.ballbar.bar_temperature_c".to_string()],
                (1.0, 1.5),
            )],
        )
    });
    out
}

/// The library for tests in several planes (`(p, q)` axis letters, lower case): the first
/// plane's library, the axis effects of the others' axes, their plane effects (squareness,
/// servo and scale mismatch) named with the plane (`squareness_zx`), and one baseline (set-up
/// of every axis involved, bar length).
pub fn library_for(planes: &[(char, char)]) -> Vec<Effect> {
    let Some((&(p, q), rest)) = planes.split_first() else {
        return Vec::new();
    };
    let mut out = library(p, q);
    for &(p, q) in rest {
        for mut e in library(p, q) {
            if let Some(have) = out.iter_mut().find(|x| x.key == e.key) {
                if e.baseline {
                    let new: Vec<Param> = e
                        .params
                        .into_iter()
                        .filter(|n| !have.params.iter().any(|h| h.keys == n.keys))
                        .collect();
                    have.params.extend(new);
                }
                continue;
            }
            if ["squareness", "servo_mismatch", "scale_mismatch"].contains(&e.key.as_str()) {
                e.key = format!("{}_{p}{q}", e.key);
            }
            if !out.iter().any(|x| x.key == e.key) {
                out.push(e);
            }
        }
    }
    out
}

/// Thermal drift: the spindle head starts warm (the spindle ran before the test) and cools
/// during the runs, so the tool moves as the head contracts (the thermal links of the model,
/// e.g. 0.8 µm/K in Y and −3.5 µm/K in Z on the built-in machine, with the node's time
/// constant C/G, about 21 min there). `node` is the thermal node the spindle's losses heat.
/// The static part at the start of a test is the bar's set-up; what is seen is the drift, so
/// it is strong in the vertical planes and in long jobs and weak in a short XY test.
pub fn thermal_drift(node: usize) -> Effect {
    effect(
        "thermal_drift",
        "thermal drift: the spindle head starts warm and cools during the runs",
        vec![param(
            "spindle head start excess",
            "K",
            &[format!("machine.thermal.nodes[{node}].initial_c")],
            // 8 K: the spindle node's steady excess after running at 8000 rpm on the built-in
            // machine (144 W over 18 W/K).
            (2.0, 8.0),
        )],
    )
}

fn axis_index(a: char) -> usize {
    match a {
        'x' => 0,
        'y' => 1,
        _ => 2,
    }
}

/// The ISO squareness key of a plane: EC0Y for XY, EB0Z for ZX, EA0Z for YZ.
fn squareness_key(p: char, q: char) -> String {
    match (p, q) {
        ('x', 'y') => "machine.errors.squareness.EC0Y_urad",
        ('z', 'x') => "machine.errors.squareness.EB0Z_urad",
        _ => "machine.errors.squareness.EA0Z_urad",
    }
    .to_string()
}
