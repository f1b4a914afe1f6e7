//! The robots shipped with tagk (the URDFs in `tagk-dynamics/robots/`), by name.
//!
//! `tagk diagnose LOG --robot ur5` reads them from here, so the installed binary needs no
//! file. Their licences are in `tagk-dynamics/robots/`.

/// The names of the shipped robots.
pub const SHIPPED_ROBOTS: [&str; 3] = ["ur5", "panda", "planar_2link"];

/// The URDF text of a shipped robot (`ur5`, `panda`, `planar_2link`), or `None`.
///
/// The planar 2-link arm's joints rotate about z: give its tree the gravity `(0, −9.81, 0)`
/// (see the file's header comment).
pub fn shipped_urdf(name: &str) -> Option<&'static str> {
    match name {
        "ur5" => Some(include_str!("../robots/ur5.urdf")),
        "panda" => Some(include_str!("../robots/panda.urdf")),
        "planar_2link" => Some(include_str!("../robots/planar_2link.urdf")),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_name_has_a_urdf_and_others_none() {
        for n in super::SHIPPED_ROBOTS {
            assert!(super::shipped_urdf(n).is_some_and(|u| u.contains("<robot")));
        }
        assert!(super::shipped_urdf("ur10").is_none());
    }
}
