//! vmt-sim: executes a job in time. NC program -> interpolator -> controller -> plant -> error
//! chain -> instruments -> a run (channels and ground truth).
//!
//! - [`nc`]: NC programs: G-code parsing into SI motion blocks, and generators of test programs
//!   (ISO 230-4 circular tests, Kwon's seven-step ball-bar procedure).
//! - [`interpolator`]: path speed planning with acceleration and jerk limits, exact arcs, the
//!   interpolation period and fine interpolation down to the servo rate.
//! - [`plant`]: the moving assemblies and their drives, reduced or rapier3d multibody.
//! - [`simulate`]: runs a job through interpolator, controllers, plant, error chain and
//!   instruments ([`ballbar`], [`laser`]: the ISO 230-2 positioning test); [`truth`] writes its
//!   ground truth; [`replay`] reads the ball bar of a run again on a machine with other
//!   geometric errors or another bar set-up, without simulating the motion again.
//! - [`milling`]: time-domain milling with regenerative chatter: forces, tool modes, surface
//!   memory, spindle-housing accelerometers, the machined wall and the chatter truth;
//!   [`machining`] drives it from an NC program through the controller and feed drives, with a
//!   supervisor (chatter detection and compensation) in the loop.
//! - [`run`]: what a simulation produces: time-stamped streams, ball-bar traces, ground truth.

pub mod ballbar;
pub mod interpolator;
pub mod laser;
pub mod machining;
pub mod milling;
pub mod nc;
pub mod plant;
pub mod replay;
pub mod run;
pub mod simulate;
pub mod truth;

/// `x` to six significant digits without trailing zeros, for messages: `5400002`, not
/// `5400002.0980000001`; `0.0000166667`, not `1.6666666666666667e-5`.
pub(crate) fn short(x: f64) -> String {
    if !x.is_finite() || x == 0.0 {
        return x.to_string();
    }
    let decimals = (5 - x.abs().log10().floor() as i32).max(0) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::short;

    #[test]
    fn short_keeps_six_significant_digits_and_drops_trailing_zeros() {
        assert_eq!(short(600001.1140000001), "600001");
        assert_eq!(short(16777.216), "16777.2");
        assert_eq!(short(0.0001 / 60_000.0), "0.00000000166667");
        assert_eq!(short(-0.30000000000000004), "-0.3");
        assert_eq!(short(8000.0), "8000");
        assert_eq!(short(0.0), "0");
        assert_eq!(short(f64::NAN), "NaN");
    }
}
