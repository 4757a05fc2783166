//! Values a user picks by name — on the command line, in the editor's menus — each with one
//! line of help: one definition per enumeration, which the CLI and the editor offer without
//! copying it.

/// An enumeration whose values users pick by name.
pub trait Named: Copy + PartialEq + 'static {
    /// Every value, in the order menus and help list them.
    const ALL: &'static [Self];

    /// The name a user types or picks.
    fn name(self) -> &'static str;

    /// One line on what it does.
    fn about(self) -> &'static str;

    /// The value called `name`; the error lists the names.
    fn named(name: &str) -> Result<Self, String> {
        Self::ALL.iter().copied().find(|v| v.name() == name).ok_or_else(|| {
            let names: Vec<&str> = Self::ALL.iter().map(|v| v.name()).collect();
            format!("unknown name '{name}' (one of: {})", names.join(", "))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::Named;

    /// Asserts that every value of `T` has its own name and help, and parses back from it.
    fn assert_round_trip<T: Named + std::fmt::Debug>() {
        for &v in T::ALL {
            assert_eq!(T::named(v.name()), Ok(v));
            assert!(!v.about().is_empty(), "{v:?} has no help");
        }
        let mut names: Vec<&str> = T::ALL.iter().map(|v| v.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), T::ALL.len(), "names are distinct");
        assert!(T::named("no-such-name").unwrap_err().contains(T::ALL[0].name()));
    }

    #[test]
    fn every_named_enumeration_round_trips() {
        assert_round_trip::<crate::shading::Method>();
        assert_round_trip::<crate::cache::Blend>();
        assert_round_trip::<crate::cache::record::GradientForm>();
        assert_round_trip::<crate::prt::lighting::Window>();
    }
}
