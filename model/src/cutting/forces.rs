//! The mechanistic cutting force on one axial element of one tooth, its projection on the
//! machine axes, and Altintas' closed-form average forces.
//!
//! Altintas, "Manufacturing Automation", 2nd ed., §2.3 (eqs. 2.39–2.41 for the element forces,
//! 2.47 for the averages). With φ the immersion angle (clockwise from +Y, feed along +X), the
//! force the workpiece exerts on the tool through an element of height dz cutting a chip h > 0:
//!
//! ```text
//! dF_t = (K_tc·h + K_te)·dz,  dF_r = (K_rc·h + K_re)·dz,  dF_a = (K_ac·h + K_ae)·dz     N
//! dF_x = -dF_t·cos φ - dF_r·sin φ
//! dF_y = +dF_t·sin φ - dF_r·cos φ
//! dF_z = +dF_a
//! ```
//!
//! No chip (h ≤ 0, the tooth is out of the material) means no force, edge force included.

use super::{CutGeometry, CuttingCoefficients, EndMill};

/// Force on the tool, N, along X, Y, Z, from an element of height `dz` (m) cutting a chip `h`
/// (m) at the immersion angle whose sine and cosine are given; zero when h ≤ 0.
#[inline]
pub fn element_force(
    k: &CuttingCoefficients,
    h: f64,
    dz: f64,
    sin_phi: f64,
    cos_phi: f64,
) -> [f64; 3] {
    if h <= 0.0 {
        return [0.0; 3];
    }
    let ft = (k.tangential * h + k.tangential_edge) * dz;
    let fr = (k.radial * h + k.radial_edge) * dz;
    let fa = (k.axial * h + k.axial_edge) * dz;
    [
        -ft * cos_phi - fr * sin_phi,
        ft * sin_phi - fr * cos_phi,
        fa,
    ]
}

/// Average force on the tool over one tooth period, N, along X, Y, Z, for the static chip
/// h = f_t·sin φ (no vibration, no run-out; the helix does not change the average). Altintas
/// eq. 2.47, evaluated between the entry and exit angles of `cut`:
///
/// ```text
/// F̄x = N·a·f_t/(8π)·[K_tc·cos 2φ - K_rc·(2φ - sin 2φ)] + N·a/(2π)·[-K_te·sin φ + K_re·cos φ]
/// F̄y = N·a·f_t/(8π)·[K_tc·(2φ - sin 2φ) + K_rc·cos 2φ] - N·a/(2π)·[K_te·cos φ + K_re·sin φ]
/// F̄z = N·a/(2π)·[-K_ac·f_t·cos φ + K_ae·φ]
/// ```
///
/// `feed_per_tooth` in m.
pub fn average_forces(
    k: &CuttingCoefficients,
    tool: &EndMill,
    cut: &CutGeometry,
    feed_per_tooth: f64,
) -> [f64; 3] {
    let (st, ex) = cut.engagement_angles(tool);
    let n = tool.teeth as f64;
    let a = cut.axial_depth;
    let c = n * a * feed_per_tooth / (8.0 * std::f64::consts::PI);
    let e = n * a / std::f64::consts::TAU;
    let fx = |p: f64| {
        c * (k.tangential * (2.0 * p).cos() - k.radial * (2.0 * p - (2.0 * p).sin()))
            + e * (-k.tangential_edge * p.sin() + k.radial_edge * p.cos())
    };
    let fy = |p: f64| {
        c * (k.tangential * (2.0 * p - (2.0 * p).sin()) + k.radial * (2.0 * p).cos())
            - e * (k.tangential_edge * p.cos() + k.radial_edge * p.sin())
    };
    let fz = |p: f64| e * (-k.axial * feed_per_tooth * p.cos() + k.axial_edge * p);
    [fx(ex) - fx(st), fy(ex) - fy(st), fz(ex) - fz(st)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutting::MillingDirection;

    #[test]
    fn slotting_average_matches_its_simplified_closed_form() {
        let k = CuttingCoefficients {
            tangential: 6e8,
            radial: 2e8,
            axial: 1e8,
            tangential_edge: 2e4,
            radial_edge: 1e4,
            axial_edge: 5e3,
        };
        let tool = EndMill {
            diameter: 0.01,
            teeth: 2,
            helix: 0.0,
            flute_length: 0.02,
            runout: 0.0,
            runout_angle: 0.0,
        };
        let cut = CutGeometry {
            axial_depth: 1e-3,
            radial_depth: 0.01,
            direction: MillingDirection::Down,
        };
        let (n, a, f) = (2.0, 1e-3, 1e-4);
        let pi = std::f64::consts::PI;
        // φ from 0 to π: F̄x = -N·a·(K_rc·f/4 + K_re/π), F̄y = N·a·(K_tc·f/4 + K_te/π),
        // F̄z = N·a·(K_ac·f/π + K_ae/2).
        let expected = [
            -n * a * (2e8 * f / 4.0 + 1e4 / pi),
            n * a * (6e8 * f / 4.0 + 2e4 / pi),
            n * a * (1e8 * f / pi + 5e3 / 2.0),
        ];
        let got = average_forces(&k, &tool, &cut, f);
        for (g, e) in got.iter().zip(expected) {
            assert!((g - e).abs() < 1e-9 * e.abs(), "{got:?} vs {expected:?}");
        }
    }

    #[test]
    fn an_element_out_of_the_chip_carries_no_edge_force() {
        let k = CuttingCoefficients {
            tangential: 6e8,
            radial: 2e8,
            axial: 0.0,
            tangential_edge: 2e4,
            radial_edge: 1e4,
            axial_edge: 0.0,
        };
        assert_eq!(element_force(&k, 0.0, 1e-3, 1.0, 0.0), [0.0; 3]);
        // At φ = 90° (the tooth on the +X side) the tangential force on the tool points along
        // +Y, against the tooth's motion, and the radial force along -X, towards the axis.
        let f = element_force(&k, 1e-4, 1e-3, 1.0, 0.0);
        assert!((f[0] + (2e8 * 1e-4 + 1e4) * 1e-3).abs() < 1e-12);
        assert!((f[1] - (6e8 * 1e-4 + 2e4) * 1e-3).abs() < 1e-12);
    }
}
