//! The optional physics through a whole run of the built-in machine's ball-bar test: a rail
//! bump reaches the bar as the rigid-body tilt of the table written out here, every withheld
//! effect changes what the bar reads, and tables that switch nothing on change nothing.

use nalgebra::Vector3;
use vmt_model::Axis;
use vmt_scenario::edit::Template;
use vmt_scenario::withheld::{WITHHELD, switch_on};

/// The built-in XY test at 2000 mm/min on a 100 mm circle (the gap bench's), the bar without
/// noise or rounding, the log at 10 Hz.
fn quiet() -> Template {
    let t = Template::parse(vmt_scenario::BUILTIN_DEFAULT, "vmc500.toml").unwrap();
    let text = t
        .with(&[("job.radius_mm", 100.0), ("job.feed_mm_min", 2000.0)])
        .unwrap();
    let text = Template::parse(&text, "vmc500.toml")
        .unwrap()
        .with_inserted(&[
            ("instruments.ballbar.noise_um", 0.0),
            ("instruments.ballbar.resolution_um", 0.0),
            ("simulation.log_rate_hz", 10.0),
        ])
        .unwrap();
    Template::parse(&text, "vmc500.toml").unwrap()
}

/// Each trace's (angle in degrees, reading in µm).
fn traces(text: &str) -> Vec<Vec<(f64, f64)>> {
    let s = vmt_scenario::parse(text, "s.toml", None).unwrap();
    let exec = s.execution.as_ref().unwrap();
    let run = exec.simulate(&s.machine, text, &mut |_| {}).unwrap();
    run.ballbar
        .iter()
        .map(|t| {
            t.angle_deg
                .iter()
                .copied()
                .zip(t.deviation_um.iter().copied())
                .collect()
        })
        .collect()
}

/// Against the rigid-body motion of the table about its blocks' centre, written here: a bump
/// of height H and width w (raised cosine) on X's rails, point blocks L apart, lifts the table
/// by the mean of its blocks' heights and pitches it by their difference over L; the tool,
/// fixed in X and Y, reads `−t − θ × (P_T − c)` relative to the workpiece (c the blocks'
/// centre where the table has taken it). The defect is kinematic (the motion is the same
/// with and without it), so the bar's reading changes by that error along the bar.
#[test]
fn a_rail_bump_reaches_the_bar_as_the_tilt_of_the_table() {
    let (h, w, l, at) = (2e-6, 0.03, 0.3, 0.33);
    let c0 = Vector3::new(0.25, 0.2, -0.25);
    let t = quiet();
    let base = traces(&t.with(&[]).unwrap());
    let fragment = format!(
        "[guideway]\nblock_spacing_mm = {}\nblocks_centre_mm = [{}, {}, {}]\n[[guideway.defects]]\nshape = \"bump\"\ndirection = \"z\"\nat_mm = {}\nheight_um = {}\nwidth_mm = {}\n",
        l * 1e3,
        c0.x * 1e3,
        c0.y * 1e3,
        c0.z * 1e3,
        at * 1e3,
        h * 1e6,
        w * 1e3
    );
    let bumped = traces(&t.with_fragment("machine.axes.x", &fragment).unwrap());
    let rail = |s: f64| {
        if s.abs() <= w / 2.0 {
            h / 2.0 * (1.0 + (std::f64::consts::TAU * s / w).cos())
        } else {
            0.0
        }
    };
    // The circle's centre (tool point) and the tool offset of the built-in machine.
    let (centre, tool) = (Vector3::new(0.25, 0.2, 0.2), Vector3::new(0.0, 0.0, -0.1));
    let (mut worst, mut peak) = (0.0_f64, 0.0_f64);
    for (b, m) in base.iter().zip(&bumped) {
        assert_eq!(b.len(), m.len());
        for ((deg, r0), (_, r1)) in b.iter().zip(m) {
            let (s, c) = deg.to_radians().sin_cos();
            let radial = Vector3::new(c, s, 0.0);
            let q = centre + radial * 0.1 - tool;
            // The table moves −q: its blocks' centre is at rail coordinate −(q_x − at).
            let centre_on_rail = -(q.x - at);
            let (front, rear) = (
                rail(centre_on_rail + l / 2.0),
                rail(centre_on_rail - l / 2.0),
            );
            let lift = Vector3::z() * 0.5 * (front + rear);
            let pitch = Vector3::x().cross(&Vector3::z()) * ((front - rear) / l);
            let tool_point = Vector3::new(0.0, 0.0, q.z) + tool;
            let blocks = c0 + Vector3::new(-q.x, -q.y, 0.0);
            let error = -lift - pitch.cross(&(tool_point - blocks));
            let expected = error.dot(&radial) * 1e6;
            worst = worst.max((r1 - r0 - expected).abs());
            peak = peak.max(expected.abs());
        }
    }
    // The pitch of 6.7 µrad over the 350 mm from the blocks to the tool: about 2.3 µm.
    assert!(peak > 1.5, "{peak}");
    // The bar's angle is the measured one, not the commanded (a µm shifts the bump by
    // nothing that shows): within 1 % of the peak.
    assert!(worst < 0.01 * peak, "{worst} µm off a {peak} µm change");
}

/// Every withheld effect at its typical size on X changes the bar's reading; written with
/// nothing switched on (the explicit default law, a guideway without defects) the run is the
/// built-in one to the bit.
#[test]
fn withheld_effects_change_the_bar_and_empty_tables_change_nothing() {
    let t = quiet();
    let base = traces(&t.with(&[]).unwrap());
    for e in &WITHHELD {
        let text = switch_on(&t, e.key, Axis::X, e.typical, Some(330.0)).unwrap();
        let with = traces(&text);
        let change = base
            .iter()
            .zip(&with)
            .flat_map(|(b, w)| b.iter().zip(w).map(|((_, x), (_, y))| (y - x).abs()))
            .fold(0.0, f64::max);
        assert!(change > 1e-4, "{}: the bar changed by {change} µm", e.key);
    }
    let text = t
        .with_fragment("machine.axes.x.drive.guide_friction", "law = \"lugre\"\n")
        .unwrap();
    let text = Template::parse(&text, "s.toml")
        .unwrap()
        .with_fragment(
            "machine.axes.x",
            "[guideway]\nblock_spacing_mm = 300.0\nblocks_centre_mm = [250.0, 200.0, -250.0]\n",
        )
        .unwrap();
    assert_eq!(traces(&text), base);
}
