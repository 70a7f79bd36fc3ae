//! The one parser of every `--plane` option (diagnose, gap, gap-bench, program ballbar,
//! volumetric): XY, ZX or YZ in any case and either order (xz = zx), or the G-code plane
//! selections G17, G18, G19.

pub use vmt_ballbar::Plane;

/// The accepted spellings, for messages and help.
pub const ACCEPTED: &str = "XY, ZX (or XZ) or YZ, in any case and either order, or G17, G18, G19";

/// Parses a plane name. A name in the other order (YX, XZ, ZY) is the same plane, whose
/// angles are still measured from its first axis (ISO 230-4's XY, ZX, YZ): a note says so,
/// since a trace whose angles were measured from the other axis would be read turned by 90°.
pub fn parse(s: &str) -> Result<Plane, String> {
    let name = s.trim().to_ascii_uppercase();
    let plane = match name.as_str() {
        "G17" => Plane::Xy,
        "G18" => Plane::Zx,
        "G19" => Plane::Yz,
        name => Plane::parse(name).ok_or_else(|| format!("`{s}`: the plane is {ACCEPTED}"))?,
    };
    if let Some(note) = reversed_note(&name, plane) {
        crate::errln!("{note}");
    }
    Ok(plane)
}

/// The note for a plane named in the other order than its own.
fn reversed_note(name: &str, plane: Plane) -> Option<String> {
    let (p, q) = plane.axes();
    (name == format!("{q}{p}")).then(|| {
        format!(
            "note: --plane {name} is the {plane} plane: angles are measured from +{p} towards +{q} (ISO 230-4)"
        )
    })
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
        assert_eq!(
            reversed_note("XZ", Plane::Zx).as_deref(),
            Some(
                "note: --plane XZ is the ZX plane: angles are measured from +Z towards +X (ISO 230-4)"
            )
        );
        assert_eq!(reversed_note("ZX", Plane::Zx), None);
        assert_eq!(reversed_note("G18", Plane::Zx), None);
        assert!(
            parse("xx")
                .unwrap_err()
                .contains("the plane is XY, ZX (or XZ) or YZ")
        );
    }
}
