//! The library of candidate effects: each a switch of the model with its free parameters,
//! written as the scenario keys it changes. A parameter's value is an offset added to what the
//! model file sets at each of its keys, so a candidate at zero is the model unchanged; a
//! parameter whose signature is linear in the reciprocal of its key (a heat capacity) is that
//! reciprocal instead ([`Scale`]).
//!
//! The keys follow the scenario format of `scenarios/vmc500.toml`; a candidate whose keys the
//! model file does not set is reported as unavailable rather than invented.
//!
//! Every parameter states the values a machine of the model's class (a vertical machining
//! centre of about 500 mm travel with ball-screw drives and rolling guides) can have
//! ([`Plausible`]): absolute bounds on the value the machine would then have (the model's
//! value plus the offset), and, where the model sets a non-zero value, bounds relative to it;
//! each with the catalogue, standard or physics it comes from. A fit outside them is not an
//! explanation: the selection reports it as one that would need an implausible value.

use crate::axis_change::axis_index;

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
    /// times 1, 2 and 3; three times it stays within [`Param::plausible`] (a bench that
    /// injected what no machine has would test nothing), whether or not the smallest stands
    /// clear of the bench's nuisance (the bench sets apart what its test cannot see).
    pub typical: f64,
    /// Whether only increases are physical (a backlash, a friction force above the model's).
    pub increase_only: bool,
    /// The values a machine of the model's class can have, in the parameter's own terms.
    pub plausible: Plausible,
    /// How the parameter maps to its keys.
    pub scale: Scale,
}

/// How a parameter's value maps to its keys' values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scale {
    /// The keys take the parameter itself.
    Same,
    /// The parameter is `factor / key`: a heat capacity `C` is fitted as `1/C`, in which the
    /// warming `Q t / C` of a node heated for a time short against its time constant is linear
    /// (so the Gauss–Newton steps of the selection reach it from a value several times off).
    Reciprocal(f64),
}

impl Scale {
    /// The parameter's value where its key holds `key`.
    pub fn of_key(self, key: f64) -> f64 {
        match self {
            Scale::Same => key,
            Scale::Reciprocal(f) => f / key,
        }
    }

    /// The key's value where the parameter holds `value` (each map is its own inverse).
    pub fn to_key(self, value: f64) -> f64 {
        self.of_key(value)
    }
}

/// The values a parameter can take on a machine of the model's class, and why.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plausible {
    /// Least and greatest value the machine can have (the model's value plus the offset), in
    /// the parameter's unit.
    pub absolute: (f64, f64),
    /// Least and greatest value as multiples of the model's own value, where the model sets a
    /// non-zero one (a friction force, a gain); `None` where only the absolute bounds mean
    /// something (a gap, an offset, a bow).
    pub relative: Option<(f64, f64)>,
    /// The catalogue, standard or physics the bounds come from.
    pub reason: &'static str,
}

/// Why a value is not plausible: what was fitted against what the class allows.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Implausible {
    /// The parameter.
    pub name: String,
    /// The value the machine would have, in `unit`.
    pub value: f64,
    /// The model's value, in `unit`.
    pub model: f64,
    /// Unit.
    pub unit: String,
    /// The plausible range of the value, in `unit` (the absolute and relative bounds together).
    pub range: (f64, f64),
    /// Why that range.
    pub reason: String,
}

impl Plausible {
    /// The range of values allowed for a parameter whose model value is `model`: the absolute
    /// bounds, narrowed by the relative ones when the model's value is not zero.
    pub fn range(&self, model: f64) -> (f64, f64) {
        let (mut lo, mut hi) = self.absolute;
        if let (Some((a, b)), true) = (self.relative, model != 0.0) {
            let (r0, r1) = (a * model, b * model);
            lo = lo.max(r0.min(r1));
            hi = hi.min(r0.max(r1));
        }
        (lo, hi)
    }
}

impl Param {
    /// The value a key whose model value is `model` takes at the parameter's `offset`.
    pub fn key_value(&self, model: f64, offset: f64) -> f64 {
        self.scale.to_key(self.scale.of_key(model) + offset)
    }

    /// Whether the machine can have this parameter at the model's value plus `offset`, the
    /// keys' model values being `models` (every key of the parameter shares the offset, each
    /// from its own model value); the first key outside its range is named.
    pub fn check(&self, models: &[f64], offset: f64) -> Result<(), Implausible> {
        for (key, model) in self.keys.iter().zip(models) {
            let model = self.scale.of_key(*model);
            let value = model + offset;
            let (lo, hi) = self.plausible.range(model);
            if !(lo..=hi).contains(&value) {
                let name = match self.keys.len() {
                    1 => self.name.clone(),
                    _ => format!("{} (`{key}`)", self.name),
                };
                return Err(Implausible {
                    name,
                    value,
                    model,
                    unit: self.unit.to_string(),
                    range: (lo, hi),
                    reason: self.plausible.reason.to_string(),
                });
            }
        }
        Ok(())
    }
}

impl std::fmt::Display for Implausible {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let times = if self.model != 0.0 {
            format!(
                ", {:.1} x the model's {:.4} {}",
                self.value / self.model,
                self.model,
                self.unit
            )
        } else {
            String::new()
        };
        write!(
            f,
            "would need an implausible {} of {:.4} {}{times}; a machine of this class has {:.4} to {:.4} {} ({})",
            self.name, self.value, self.unit, self.range.0, self.range.1, self.unit, self.reason
        )
    }
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
    /// The axis and the direction (upper case, `('X', 'X')`) of the error of the whole travel
    /// whose smooth shape this effect is (a positioning error's curve, a straightness's bow),
    /// if it is one: a change over a stretch that the circles see begin and end is no such
    /// shape, and the selection sets the effect aside then.
    pub whole_travel: Option<(char, char)>,
}

fn param(
    name: &str,
    unit: &'static str,
    keys: &[String],
    (step, typical): (f64, f64),
    plausible: Plausible,
) -> Param {
    Param {
        name: name.into(),
        unit,
        keys: keys.to_vec(),
        step,
        typical,
        increase_only: false,
        plausible,
        scale: Scale::Same,
    }
}

/// A range of absolute values only.
const fn absolute(lo: f64, hi: f64, reason: &'static str) -> Plausible {
    Plausible {
        absolute: (lo, hi),
        relative: None,
        reason,
    }
}

/// Absolute bounds narrowed by bounds relative to the model's value.
const fn relative(abs: (f64, f64), rel: (f64, f64), reason: &'static str) -> Plausible {
    Plausible {
        absolute: abs,
        relative: Some(rel),
        reason,
    }
}

/// Drive backlash, µm.
const BACKLASH: Plausible = absolute(
    0.0,
    25.0,
    "lost motion of ball-screw drives: 0-5 um with a preloaded nut, 10-25 um worn \
     (reversal values of ISO 230-2 tests of machining centres)",
);
/// Coulomb (and with it static) friction of the guides, N.
const GUIDE_FRICTION: Plausible = relative(
    (5.0, 400.0),
    (0.25, 4.0),
    "rolling guides: 0.002-0.005 of the carried load plus 2-15 N of seal drag per block \
     (THK, Bosch Rexroth catalogues), 20-100 N for carriages of this class; preload class, \
     lubrication and wipers change it by up to 4 times either way",
);
/// Static friction of the guides, N.
const STATIC_FRICTION: Plausible = relative(
    (5.0, 500.0),
    (0.5, 2.5),
    "static friction exceeds the sliding level by 10-30 % on rolling guides and by up to \
     100 % on lubricated sliding ones (Armstrong-Helouvry, Dupont & Canudas de Wit, \
     Automatica 30(7), 1994): up to 2.5 times the model's static level",
);
/// Lateral play (backward offset), µm.
const LATERAL_PLAY: Plausible = absolute(
    -10.0,
    10.0,
    "lateral play of preloaded rolling guides is below 1-2 um; 10 um is a loose or worn guide",
);
/// Cosine or sine part of a screw's periodic lead error, µm.
const CYCLIC: Plausible = absolute(
    -8.0,
    8.0,
    "periodic lead error v_2pi of ball screws: 3-8 um for ISO 3408-3 classes 3 to 7",
);
/// Legendre c2 of a straightness, µm.
const STRAIGHTNESS: Plausible = absolute(
    -15.0,
    15.0,
    "straightness of machining-centre axes: ISO 10791-2 tolerances of 10-20 um over 500 mm \
     (the bow's sagitta is 1.5 c2)",
);
/// Legendre c2 or c3 of a positioning error (its bow, its S over the stroke), µm.
const POSITIONING: Plausible = absolute(
    -15.0,
    15.0,
    "non-linear positioning error of uncompensated ball-screw axes: lead deviations of \
     8-23 um over 300 mm by class (ISO 3408-3, C3-C7), and a screw warmed unevenly along its \
     length (a few K over part of it at 11.5 ppm/K)",
);
/// Legendre c1 of a linear positioning error (half its change over the stroke), µm.
const SCALE: Plausible = absolute(
    -25.0,
    25.0,
    "linear positioning error of uncompensated ball-screw axes: up to 50 um over 500 mm \
     (about 100 ppm: lead tolerance and a few K of screw warming at 11.5 ppm/K)",
);
/// Position-loop gain, 1/s.
const SERVO_GAIN: Plausible = relative(
    (5.0, 200.0),
    (0.85, 1.15),
    "position-loop gains of interpolating axes are matched at commissioning to within a few \
     per cent; 15 % (about 5 ms of lag at Kv = 33/s) is a gross error",
);
/// Squareness, µrad.
const SQUARENESS: Plausible = absolute(
    -100.0,
    100.0,
    "squareness of machining-centre axes: ISO 10791-2 tolerances of 20 um over 500 mm \
     (40 urad); 100 urad is a crashed or badly rebuilt machine",
);
/// Start temperature of the spindle head, °C.
const SPINDLE_START: Plausible = absolute(
    10.0,
    60.0,
    "a spindle head runs 5-30 K above the shop's 20 degC (ISO 230-3 warm-up tests), 40 K \
     after hard running",
);
/// The bar's set-up offset, µm.
const PIVOT_OFFSET: Plausible = absolute(
    -1000.0,
    1000.0,
    "a ball bar's measuring range: a pivot set further off cannot be read",
);
/// The bar's temperature, °C.
const BAR_TEMPERATURE: Plausible = absolute(
    5.0,
    40.0,
    "a bar in a workshop; the standard asks for 20 degC and a stated temperature",
);

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
        whole_travel: None,
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
                BACKLASH,
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
                // 40 N: a preload class or a lubrication state apart (3 x 40 N on 50 N is
                // 3.4 times the model's force, within the class's range).
                (20.0, 40.0),
                GUIDE_FRICTION,
            ))],
        ));
        out.push(effect(
            &format!("stick_slip_{a}"),
            &format!("static friction peak of the {up} guides over Coulomb (stick-slip)"),
            vec![growing(param(
                &format!("static force {up}"),
                "N",
                &[format!("{axis}.drive.guide_friction.static_n")],
                // 25 N: a static level 80 % over the sliding one (90 N on 50 N on X).
                (20.0, 25.0),
                STATIC_FRICTION,
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
                LATERAL_PLAY,
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
                        CYCLIC,
                    )
                })
                .collect(),
        ));
        out.push(straightness(up, other, &errors));
        out.push(positioning(up, &errors));
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
            SCALE,
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
            SERVO_GAIN,
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
            SQUARENESS,
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
                        &[format!("{PIVOT_OFFSET_KEY}[{}]", axis_index(a))],
                        (5.0, 8.0),
                        PIVOT_OFFSET,
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
                BAR_TEMPERATURE,
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

/// Straightness of axis `a` in direction `d` (upper case), `errors` its error tables' key.
fn straightness(a: char, d: char, errors: &str) -> Effect {
    Effect {
        whole_travel: Some((a, d)),
        ..effect(
            &format!("straightness_{}", a.to_ascii_lowercase()),
            &format!("straightness of {a} in {d}: the bow (Legendre c2) of E{d}{a}"),
            vec![param(
                &format!("E{d}{a} c2"),
                "um",
                &[format!("{errors}.forward.E{d}{a}_um[2]")],
                // 4 um of c2: a 6 um bow over the stroke.
                (2.0, 4.0),
                STRAIGHTNESS,
            )],
        )
    }
}

/// The non-linear positioning error of axis `a` (upper case): the bow and S of its curve over
/// the stroke, the same for both approaches (a screw's lead deviation, or a screw warmed
/// unevenly along its length).
fn positioning(a: char, errors: &str) -> Effect {
    Effect {
        whole_travel: Some((a, a)),
        ..effect(
            &format!("positioning_{}", a.to_ascii_lowercase()),
            &format!(
                "non-linear positioning error of {a}: the bow and S (Legendre c2, c3) of E{a}{a}, both approaches"
            ),
            [2, 3]
                .iter()
                .map(|k| {
                    param(
                        &format!("E{a}{a} c{k}"),
                        "um",
                        &["forward", "backward"].map(|d| format!("{errors}.{d}.E{a}{a}_um[{k}]")),
                        // 2 um of c2: a 3 um bow of the positioning error over the stroke.
                        (1.0, 2.0),
                        POSITIONING,
                    )
                })
                .collect(),
        )
    }
}

/// The key prefix of the bar's pivot offset, one `[x, y, z]` or one per centre.
pub(crate) const PIVOT_OFFSET_KEY: &str = "instruments.ballbar.setup_eccentricity_um";

/// `library` for a job whose circles run about `centres` centres, the bar set up anew at each:
/// every pivot-offset parameter of the set-up split into one per centre, on that centre's
/// element of the offsets' list (`setup_eccentricity_um[c][i]`). One centre keeps the library.
pub fn per_centre(mut library: Vec<Effect>, centres: usize) -> Vec<Effect> {
    if centres < 2 {
        return library;
    }
    for e in library.iter_mut().filter(|e| e.baseline) {
        e.params = std::mem::take(&mut e.params)
            .into_iter()
            .flat_map(|p| {
                let pivot = p.keys.iter().all(|k| k.starts_with(PIVOT_OFFSET_KEY));
                let split = |c: usize| Param {
                    name: format!("{} (centre {})", p.name, c + 1),
                    keys: p
                        .keys
                        .iter()
                        .map(|k| {
                            k.replacen(PIVOT_OFFSET_KEY, &format!("{PIVOT_OFFSET_KEY}[{c}]"), 1)
                        })
                        .collect(),
                    ..p.clone()
                };
                match pivot {
                    true => (0..centres).map(split).collect(),
                    false => vec![p],
                }
            })
            .collect();
    }
    library
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
        // A head starts warm from running; colder than the shop it does not start.
        vec![growing(param(
            "spindle head start excess",
            "K",
            &[format!("machine.thermal.nodes[{node}].initial_c")],
            // 8 K: the spindle node's steady excess after running at 8000 rpm on the built-in
            // machine (144 W over 18 W/K).
            (2.0, 8.0),
            SPINDLE_START,
        ))],
    )
}

/// The reciprocal of a screw's effective heat capacity, K/kJ.
const SCREW_WARMING: Plausible = absolute(
    0.1,
    3.0,
    "a ball screw of 25-40 mm on a 500 mm axis warms 0.35-10 kJ/K of steel (volumetric heat \
     capacity 3.6 MJ/(m3 K)): in a test of minutes only the section its nut runs over and a \
     few cm beyond (heat spreads sqrt(a t), 3 cm in a minute), up to the whole screw with its \
     nut and bearings after hours",
);

/// Screw heating during the runs: the nut's and bearings' friction heat `c |v|` warms the
/// axis' screw, whose growth `α ΔT (q − q_f)` stretches the axis as the test goes on. The
/// lumped node of the model (`node`, its capacity `C`) holds the screw with its nut and
/// bearings; in a test of minutes the heat stays in the screw's running section (Fourier's
/// penetration depth `√(a t)`, 3 cm in a minute for steel), so the effective capacity is a few
/// times smaller and the warming `c |v| t / C` a few times faster. The parameter is `1/C` in
/// K per kJ ([`Scale::Reciprocal`]): the warming is linear in it. The bench injects it growing
/// (less steel warming than the node holds); a fit may find more, up to the 10 kJ/K of its
/// plausible range.
pub fn screw_heating(axis: char, node: usize) -> Effect {
    let up = axis.to_ascii_uppercase();
    effect(
        &format!("screw_heating_{axis}"),
        &format!(
            "{up} screw heating during the runs: less of the screw warms than the model's node (its effective heat capacity)"
        ),
        vec![growing(Param {
            scale: Scale::Reciprocal(1000.0),
            ..param(
                &format!("{up} screw warming per kJ (1/effective heat capacity)"),
                "K/kJ",
                &[format!("machine.thermal.nodes[{node}].capacity_j_per_k")],
                // 0.25 K/kJ over the built-in 6.9 kJ/K (0.145 K/kJ): 2.5 kJ/K; three times
                // it, 1.1 kJ/K, is about a 28 mm screw's 0.7 m of bare steel.
                (0.1, 0.25),
                SCREW_WARMING,
            )
        })],
    )
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// A reciprocal parameter maps back to the key it came from, and at zero offset
        /// leaves the key as the model has it.
        #[test]
        fn a_reciprocal_scale_round_trips(key in 1.0e2..1.0e6_f64, factor in 1.0..1.0e4_f64) {
            let s = Scale::Reciprocal(factor);
            prop_assert!((s.to_key(s.of_key(key)) - key).abs() <= 1e-9 * key);
            let p = Param { scale: s, ..screw_heating('x', 3).params[0].clone() };
            prop_assert!((p.key_value(key, 0.0) - key).abs() <= 1e-9 * key);
        }
    }

    /// The screw heating's offset is of `1/C` in K/kJ: +0.5 K/kJ on 6.9 kJ/K is
    /// 1000 / (1000/6900 + 0.5) = 1550 J/K, a 28 mm screw's 0.7 m of steel (plausible); a
    /// capacity of 200 J/K, less than 100 mm of such a screw, is not.
    #[test]
    fn screw_heating_is_judged_on_the_capacity_it_implies() {
        let p = &screw_heating('x', 3).params[0];
        assert!((p.key_value(6900.0, 0.5) - 1550.0).abs() < 1.0);
        assert!(p.check(&[6900.0], 0.5).is_ok());
        let e = p
            .check(&[6900.0], 1000.0 / 200.0 - 1000.0 / 6900.0)
            .unwrap_err();
        assert!((e.value - 5.0).abs() < 1e-9 && e.unit == "K/kJ", "{e}");
        assert!((e.model - 1000.0 / 6900.0).abs() < 1e-12);
    }
}
