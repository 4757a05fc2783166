//! One module per subcommand.

pub mod bake;
pub mod db;
pub mod edit;
pub mod export;
pub mod info;
pub mod render;
pub mod report;
