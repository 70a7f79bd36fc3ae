//! `[dataset]`: sampled machines are ordinary scenarios carrying the draws; bad entries are
//! refused with the key and what is accepted.

use vmt_scenario::dataset::{Dataset, from_text};
use vmt_scenario::{BUILTIN_DEFAULT, ScenarioError, parse};

/// The built-in machine with `entries` as its `[dataset.parameters]`.
fn with_dataset(entries: &str) -> String {
    format!("{BUILTIN_DEFAULT}\n[dataset.parameters]\n{entries}\n")
}

fn dataset(entries: &str) -> Dataset {
    from_text(&with_dataset(entries), "ds.toml")
        .expect("the dataset is accepted")
        .expect("a [dataset] section")
}

fn refusal(entries: &str) -> ScenarioError {
    from_text(&with_dataset(entries), "ds.toml").expect_err("the dataset should be refused")
}

fn value(v: &[(String, f64)], name: &str) -> f64 {
    v.iter().find(|(n, _)| n == name).expect("a drawn value").1
}

#[test]
fn a_scenario_with_a_dataset_section_still_runs_as_one() {
    let text = with_dataset(
        r#""machine.axes.x.drive.backlash_um" = { distribution = "uniform", min = 0.0, max = 6.0 }"#,
    );
    let s = parse(&text, "ds.toml", None).expect("vmt run accepts it");
    assert_eq!(s.machine.name, "VMC-500 (built-in default)");
    assert!(from_text(BUILTIN_DEFAULT, "vmc500.toml").unwrap().is_none());
}

#[test]
fn draws_are_written_into_the_scenario_and_shared_by_the_keys_of_an_entry() {
    let ds = dataset(
        r#""machine.axes.x.drive.backlash_um" = { distribution = "uniform", min = 2.0, max = 6.0 }
"machine.errors.squareness.EC0Y_urad" = { distribution = "normal", mean = 0.0, sd = 15.0 }
"instruments.ballbar.setup_eccentricity_um[0]" = { distribution = "constant", value = -7.5 }
"machine.errors.squareness.EA0Z_urad.backward" = { distribution = "lognormal", median = 9.0, sigma = 0.2 }
scale_x = { keys = ["machine.errors.x.forward.EXX_um[1]", "machine.errors.x.backward.EXX_um[1]"], distribution = "normal", mean = 0.0, sd = 5.0 }"#,
    );
    let s = ds.sample(42);
    let backlash = value(&s.values, "machine.axes.x.drive.backlash_um");
    assert!((2.0..=6.0).contains(&backlash));
    assert_eq!(
        value(&s.values, "instruments.ballbar.setup_eccentricity_um[0]"),
        -7.5
    );
    let scale = value(&s.values, "scale_x");
    let sc = parse(&s.text, "sample.toml", None).expect("a sample is an ordinary scenario");
    let doc: toml::Table = toml::from_str(&s.text).unwrap();
    let exx = |dir: &str| {
        doc["machine"]["errors"]["x"][dir]["EXX_um"][1]
            .as_float()
            .unwrap()
    };
    assert_eq!((exx("forward"), exx("backward")), (scale, scale));
    // Only c1 changed: the backward offset (c0 = 2 µm) and the higher terms stay.
    assert_eq!(
        doc["machine"]["errors"]["x"]["backward"]["EXX_um"][0].as_float(),
        Some(2.0)
    );
    assert_eq!(doc["simulation"]["seed"].as_integer(), Some(42));
    assert!(!doc.contains_key("dataset"));
    let exec = sc.execution.expect("a job");
    assert_eq!(exec.settings.seed, 42);
    let drive_backlash = exec.axes[0].drive.screw.backlash_m;
    assert!((drive_backlash * 1e6 - backlash).abs() < 1e-9);
    // The same seed draws the same machine; another seed another.
    assert_eq!(ds.sample(42), s);
    assert_ne!(value(&ds.sample(43).values, "scale_x"), scale);
}

#[test]
fn p_absent_sets_the_absent_value_in_that_share_of_the_draws() {
    let ds = dataset(
        r#""machine.axes.y.drive.backlash_um" = { distribution = "uniform", min = 1.0, max = 2.0, p_absent = 0.3 }
"machine.axes.x.servo.kv_per_s" = { distribution = "normal", mean = 33.0, sd = 2.0, p_absent = 1.0, absent = 30.0 }"#,
    );
    let n = 2000;
    let mut absent = 0;
    for seed in 0..n {
        let v = ds.sample(seed).values;
        assert_eq!(value(&v, "machine.axes.x.servo.kv_per_s"), 30.0);
        let b = value(&v, "machine.axes.y.drive.backlash_um");
        if b == 0.0 {
            absent += 1;
        } else {
            assert!((1.0..=2.0).contains(&b));
        }
    }
    // Binomial(2000, 0.3): sd 20.5, so 600 +- 80 is four sd.
    assert!((520..=680).contains(&absent), "{absent} absent of {n}");
}

#[test]
fn normal_draws_have_the_stated_mean_and_sd() {
    let ds = dataset(
        r#""machine.errors.squareness.EC0Y_urad" = { distribution = "normal", mean = 5.0, sd = 15.0 }"#,
    );
    let v: Vec<f64> = (0..4000)
        .map(|s| value(&ds.sample(s).values, "machine.errors.squareness.EC0Y_urad"))
        .collect();
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt();
    // Standard error of the mean 15/sqrt(4000) = 0.24; of the sd about 0.17.
    assert!((mean - 5.0).abs() < 1.0, "mean {mean}");
    assert!((sd - 15.0).abs() < 0.7, "sd {sd}");
}

/// `n` draws of the one parameter `key` of `entry`, one sample per seed.
fn draws(entry: &str, key: &str, n: u64) -> Vec<f64> {
    let ds = dataset(entry);
    (0..n).map(|s| value(&ds.sample(s).values, key)).collect()
}

/// Sample mean and standard deviation (n - 1).
fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

#[test]
fn lognormal_draws_have_the_stated_median_and_sigma() {
    // ln x ~ N(ln m, s²) with m = 9, s = 0.5: mean of ln x = ln 9 = 2.197225. Over 4000
    // draws its standard error is 0.5/√4000 = 0.0079 (4 se: 0.032); the sample sd of a normal
    // has standard error s/√(2(n-1)) = 0.0056 (4 se: 0.022). A generator taking the median
    // as the mean of ln x (9), sigma as the variance (sd 0.707 or 0.25), or the median as
    // the mean of x (ln x centred on ln 9 - s²/2 = 2.072) lies far outside.
    let key = "machine.errors.squareness.EA0Z_urad.backward";
    let v = draws(
        &format!(r#""{key}" = {{ distribution = "lognormal", median = 9.0, sigma = 0.5 }}"#),
        key,
        4000,
    );
    assert!(v.iter().all(|x| *x > 0.0));
    let ln: Vec<f64> = v.iter().map(|x| x.ln()).collect();
    let (mean, sd) = mean_sd(&ln);
    assert!((mean - 2.197_225).abs() < 0.032, "mean of ln x {mean}");
    assert!((sd - 0.5).abs() < 0.022, "sd of ln x {sd}");
}

#[test]
fn uniform_draws_cover_min_to_max_evenly() {
    // U(2, 6): mean 4, sd (6 - 2)/√12 = 1.1547. Over 4000 draws the mean's standard error is
    // 1.1547/√4000 = 0.018 (4 se: 0.073); the sample variance's is √((μ4 - σ⁴)/n) with
    // μ4 = 4⁴/80 = 3.2, σ⁴ = 1.778: 0.0189, so the sd's is 0.0189/(2·1.1547) = 0.0082
    // (4 se: 0.033). The smallest draw exceeds 2 + 0.01 with probability
    // (1 - 0.01/4)^4000 = e^-10, likewise the largest falls short of 6 - 0.01.
    let key = "machine.axes.x.drive.backlash_um";
    let v = draws(
        &format!(r#""{key}" = {{ distribution = "uniform", min = 2.0, max = 6.0 }}"#),
        key,
        4000,
    );
    let (mean, sd) = mean_sd(&v);
    assert!((mean - 4.0).abs() < 0.073, "mean {mean}");
    assert!((sd - 4.0 / 12f64.sqrt()).abs() < 0.033, "sd {sd}");
    let min = v.iter().copied().fold(f64::INFINITY, f64::min);
    let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert!((2.0..2.01).contains(&min), "min {min}");
    assert!(max > 5.99 && max <= 6.0, "max {max}");
}

#[test]
fn bad_entries_are_refused_naming_the_key_and_what_is_accepted() {
    let cases = [
        (
            r#""machine.axes.x.drive.backlash_mm" = { distribution = "uniform", min = 0.0, max = 1.0 }"#,
            "is not a number the scenario sets",
        ),
        (
            r#""machine.name" = { distribution = "uniform", min = 0.0, max = 1.0 }"#,
            "is not a number the scenario sets",
        ),
        (
            r#""instruments.ballbar.setup_eccentricity_um[7]" = { distribution = "uniform", min = 0.0, max = 1.0 }"#,
            "is not a number the scenario sets",
        ),
        (
            r#""machine.axes.x.drive.backlash_um" = { distribution = "uniform", min = 6.0, max = 1.0 }"#,
            "min <= max is accepted",
        ),
        (
            r#""machine.axes.x.drive.backlash_um" = { distribution = "normal", mean = 1.0, sd = -1.0 }"#,
            "a standard deviation >= 0 is accepted",
        ),
        (
            r#""machine.axes.x.drive.backlash_um" = { distribution = "uniform", min = 0.0, max = 1.0, p_absent = 1.5 }"#,
            "a probability from 0 to 1 is accepted",
        ),
        (
            r#""machine.axes.x.drive.backlash_um" = { distribution = "gamma", min = 0.0, max = 1.0 }"#,
            "accepted: uniform (min, max), normal (mean, sd), lognormal (median, sigma), constant (value)",
        ),
        (
            r#""machine.axes.x.drive.backlash_um" = { distribution = "uniform", min = 0.0, max = 1.0, sd = 1.0 }"#,
            "uniform does not take `sd`",
        ),
        (
            r#"both = { keys = ["machine.axes.x.drive.backlash_um", "machine.axes.x.drive.backlash_um"], distribution = "constant", value = 1.0 }"#,
            "drawn twice",
        ),
    ];
    for (entry, message) in cases {
        let e = refusal(entry);
        let name = entry.split(" = ").next().unwrap().trim_matches('"');
        let key = e.key.clone().unwrap_or_default();
        assert!(key.contains(name), "{entry}: key {key:?} in {e}");
        assert!(e.message.contains(message), "{entry}: {e}");
        assert!(e.position.is_some(), "{entry}: no line in {e}");
    }
    // A misspelt field is refused by the schema, so `vmt run` refuses it too.
    let text = with_dataset(
        r#""machine.axes.x.drive.backlash_um" = { distribution = "uniform", min = 0.0, maxi = 1.0 }"#,
    );
    let e = parse(&text, "ds.toml", None).expect_err("refused");
    assert!(e.to_string().contains("maxi"), "{e}");
}

#[test]
fn entries_that_would_mislead_are_refused_naming_the_key() {
    let cases = [
        // The column `machine.axes.x.drive.backlash_um` would hold the Y backlash.
        (
            r#""machine.axes.x.drive.backlash_um" = { keys = ["machine.axes.y.drive.backlash_um"], distribution = "uniform", min = 1.0, max = 6.0 }"#,
            "dataset.parameters.\"machine.axes.x.drive.backlash_um\".keys",
            "does not draw it",
        ),
        // An absent value that is never taken.
        (
            r#""machine.axes.x.drive.backlash_um" = { distribution = "uniform", min = 1.0, max = 6.0, absent = 2.0 }"#,
            "dataset.parameters.\"machine.axes.x.drive.backlash_um\".absent",
            "never taken without a `p_absent` above 0",
        ),
        // A plain number is no distribution.
        (
            r#""machine.axes.x.drive.backlash_um" = 3.0"#,
            "dataset.parameters.\"machine.axes.x.drive.backlash_um\"",
            "3.0: an entry is an inline table giving its distribution",
        ),
        // Unquoted, the key path is nested tables.
        (
            r#"machine.axes.x.drive.backlash_um = { distribution = "uniform", min = 0.0, max = 6.0 }"#,
            "dataset.parameters.machine",
            "`machine.axes.x.drive.backlash_um` is unquoted, so TOML reads it as nested tables: quote the key path",
        ),
    ];
    for (entry, key, message) in cases {
        let e = refusal(entry);
        assert_eq!(e.key.as_deref(), Some(key), "{entry}: {e}");
        assert!(e.message.contains(message), "{entry}: {e}");
        assert!(e.position.is_some(), "{entry}: no line in {e}");
    }
    // Named by one of its keys, or by a label, an entry with keys is accepted.
    dataset(
        r#""machine.axes.x.drive.backlash_um" = { keys = ["machine.axes.x.drive.backlash_um", "machine.axes.y.drive.backlash_um"], distribution = "uniform", min = 1.0, max = 6.0, p_absent = 0.5, absent = 0.5 }"#,
    );
}
