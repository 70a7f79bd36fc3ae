//! The carriages' sections (`[machine.axes.<axis>.carriage]`): bad values are refused naming the
//! file, the line, the key and what is accepted.

use vmt_scenario::{BUILTIN_DEFAULT, ScenarioError, parse};

/// The built-in scenario with the first `from` after X's carriage section replaced by `to`.
fn with_x_carriage(from: &str, to: &str) -> String {
    let at = BUILTIN_DEFAULT.find("[machine.axes.x.carriage]").unwrap();
    let (head, tail) = BUILTIN_DEFAULT.split_at(at);
    assert!(tail.contains(from), "{from}");
    format!("{head}{}", tail.replacen(from, to, 1))
}

fn error(text: &str) -> ScenarioError {
    match parse(text, "s.toml", None) {
        Err(e) => e,
        Ok(_) => panic!("accepted"),
    }
}

/// The line (1-based) of the first line of `text` starting with `start`.
fn line_of(text: &str, start: &str) -> usize {
    1 + text.lines().position(|l| l.starts_with(start)).unwrap()
}

#[test]
fn the_builtin_machine_has_its_three_carriages() {
    let s = parse(BUILTIN_DEFAULT, "b.toml", None).unwrap();
    let st = s.machine.structure.expect("a structure");
    // Own masses: X carries nothing (250 kg), Y its saddle alone (450 − 250), Z its head.
    let masses: Vec<f64> = st.carriages.iter().map(|c| c.mass_kg).collect();
    assert_eq!(masses, vec![250.0, 200.0, 180.0]);
    // The table's box inertia about Y: m (l² + h²)/12 with l = 0.8 m, h = 0.1 m.
    let i = st.carriages[0].inertia_kg_m2[(1, 1)];
    assert!((i - 250.0 * (0.64 + 0.01) / 12.0).abs() < 1e-9, "{i}");
}

#[test]
fn a_block_outside_its_carriage_is_refused_at_its_key() {
    let text = with_x_carriage("[50.0, 50.0, -250.0]", "[50.0, 50.0, -350.0]");
    let e = error(&text);
    assert_eq!(
        e.key.as_deref(),
        Some("machine.axes.x.carriage.blocks_mm[0]"),
        "{e}"
    );
    assert!(e.message.contains("lies outside the carriage's box"), "{e}");
    assert_eq!(e.position.map(|p| p.0), Some(line_of(&text, "blocks_mm")));
}

#[test]
fn a_stiffness_that_is_not_positive_is_refused_at_its_key() {
    for v in ["0.0", "-400.0"] {
        let text = with_x_carriage(
            "block_normal_n_per_um = 400.0",
            &format!("block_normal_n_per_um = {v}"),
        );
        let e = error(&text);
        assert_eq!(
            e.key.as_deref(),
            Some("machine.axes.x.carriage.block_normal_n_per_um"),
            "{e}"
        );
        assert!(
            e.message.contains("must be > 0") || e.message.contains("out of range"),
            "{e}"
        );
    }
}

#[test]
fn an_inertia_tensor_that_is_not_positive_definite_is_refused() {
    let text = with_x_carriage(
        "nut_mm = [250.0, 200.0, -290.0]",
        "nut_mm = [250.0, 200.0, -290.0]\ninertia_kg_m2 = [[5.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 5.0]]",
    );
    let e = error(&text);
    assert_eq!(
        e.key.as_deref(),
        Some("machine.axes.x.carriage.inertia_kg_m2"),
        "{e}"
    );
    assert!(e.message.contains("not positive definite"), "{e}");
    // An asymmetric one too.
    let text = with_x_carriage(
        "nut_mm = [250.0, 200.0, -290.0]",
        "nut_mm = [250.0, 200.0, -290.0]\ninertia_kg_m2 = [[5.0, 1.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, 5.0]]",
    );
    assert!(error(&text).message.contains("not positive definite"));
}

#[test]
fn blocks_on_one_line_leave_the_carriage_free_and_are_refused() {
    let text = with_x_carriage(
        "blocks_mm = [[50.0, 50.0, -250.0], [450.0, 50.0, -250.0], [50.0, 350.0, -250.0], [450.0, 350.0, -250.0]]",
        "blocks_mm = [[50.0, 200.0, -250.0], [450.0, 200.0, -250.0]]",
    );
    let e = error(&text);
    assert_eq!(
        e.key.as_deref(),
        Some("machine.axes.x.carriage.blocks_mm"),
        "{e}"
    );
    assert!(
        e.message.contains("do not hold it in all five directions"),
        "{e}"
    );
}

#[test]
fn the_compliant_fidelity_is_accepted_by_its_key() {
    let text = BUILTIN_DEFAULT.replace("fidelity = \"reduced\"", "fidelity = \"compliant\"");
    let s = parse(&text, "c.toml", None).unwrap();
    assert_eq!(
        s.execution.unwrap().settings.fidelity,
        vmt_sim::plant::Fidelity::Compliant
    );
}
