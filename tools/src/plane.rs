//! The one parser of every `--plane` option (diagnose, gap, gap-bench, program ballbar,
//! volumetric): XY, ZX or YZ in any case and either order (xz = zx), or the G-code plane
//! selections G17, G18, G19.

pub use vmt_ballbar::Plane;

/// The accepted spellings, for messages and help.
pub const ACCEPTED: &str = "XY, ZX (or XZ) or YZ, in any case and either order, or G17, G18, G19";

/// Parses a plane name.
pub fn parse(s: &str) -> Result<Plane, String> {
    match s.trim().to_ascii_uppercase().as_str() {
        "G17" => Ok(Plane::Xy),
        "G18" => Ok(Plane::Zx),
        "G19" => Ok(Plane::Yz),
        name => Plane::parse(name).ok_or_else(|| format!("`{s}`: the plane is {ACCEPTED}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_spelling_of_each_plane() {
        for (names, plane) in [
            (["xy", "YX", "G17"], Plane::Xy),
            (["zx", "XZ", "g18"], Plane::Zx),
            (["yz", "Zy", "G19"], Plane::Yz),
        ] {
            for n in names {
                assert_eq!(parse(n), Ok(plane), "{n}");
            }
        }
        assert!(
            parse("xx")
                .unwrap_err()
                .contains("the plane is XY, ZX (or XZ) or YZ")
        );
    }
}
