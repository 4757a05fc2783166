//! Options whose values are the engine's (or the editor's) named enumerations
//! ([`kage_engine::named::Named`]): clap offers their names and help, and parses them into the
//! type itself, so no enumeration is copied for the command line.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use kage_engine::named::Named;

/// A parser of `T`'s names, listing each with its help.
pub fn named<T: Named + Send + Sync>() -> impl TypedValueParser<Value = T> {
    let names = T::ALL.iter().map(|v| PossibleValue::new(v.name()).help(v.about()));
    PossibleValuesParser::new(names).map(|name| T::named(&name).expect("clap checked the name"))
}
