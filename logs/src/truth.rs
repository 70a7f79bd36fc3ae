//! A run's ground truth (the JSON object its log carries on `/ground_truth` and a dataset run
//! in `labels.json`) read for the figures a diagnosis is compared with.

use serde_json::{Map, Value};
use vmt_ballbar::Finding;

/// The truth figures of test `i` of a run, as the simulator wrote them.
pub fn truth_figures(truth: &Value, i: usize) -> Option<&Map<String, Value>> {
    truth["ballbar"]["tests"][i]["figures"].as_object()
}

/// The drift of test `i` of a run over its data (`radial_drift`, `pivot_drift_<axis>`, µm), as
/// the simulator wrote it: no finding reports it, but the findings of a partial arc or of a
/// circle run one way state their bias per µm of it.
pub fn truth_drift(truth: &Value, i: usize) -> Option<&Map<String, Value>> {
    truth["ballbar"]["tests"][i]["drift"].as_object()
}

/// The true values of every effect that a finding of test `i` may state a bias per unit of:
/// the test's truth figures and its drift.
pub fn truth_effects(truth: &Value, i: usize) -> Option<Map<String, Value>> {
    let mut effects = truth_figures(truth, i)?.clone();
    if let Some(drift) = truth_drift(truth, i) {
        effects.extend(drift.iter().map(|(k, v)| (k.clone(), v.clone())));
    }
    Some(effects)
}

/// [`Finding::left_out_bias`] from a run's truth of the effects the test leaves out (bows,
/// angular plays, drifts: [`truth_effects`]).
pub fn left_out_bias(f: &Finding, effects: &Map<String, Value>) -> Option<f64> {
    f.left_out_bias(|key| effects.get(key)?.as_f64())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_left_out_bias_sums_each_stated_rate_times_its_truth() {
        let f = Finding {
            key: "squareness_zx".into(),
            name: "Squareness ZX".into(),
            value: 11.7,
            unit: "µm/m",
            ci95: 0.2,
            contribution_um: 1.2,
            threshold: 5.0,
            present: true,
            details: vec![
                ("bias_per_um_of_straightness_z".into(), -6.0),
                ("bias_per_urad_of_angular_play_x".into(), 0.5),
                ("take_up_um".into(), 9.0),
            ],
        };
        let truth = json!({"straightness_z": -1.0, "angular_play_x": 2.0, "take_up": 1.0});
        let truth = truth.as_object().expect("an object");
        assert_eq!(left_out_bias(&f, truth), Some(6.0 + 1.0));
        let mut partial = truth.clone();
        partial.remove("angular_play_x");
        assert_eq!(left_out_bias(&f, &partial), None);
        let plain = Finding {
            details: vec![("take_up_um".into(), 9.0)],
            ..f
        };
        assert_eq!(left_out_bias(&plain, truth), None);
    }
}
