//! vmt-tools: the pieces behind the `vmt` command line — input files, maps, reports and plots.
//! The binary in `main.rs` only parses arguments, calls these and the library crates, and prints.

pub mod accuracy;
pub mod chatter;
pub mod chatter_bench;
pub mod dataset;
pub mod diagnose;
pub mod error;
pub mod gap;
pub mod import;
pub mod job;
pub mod lobes;
pub mod map;
pub mod out;
pub mod outputs;
pub mod plane;
pub mod plot;
pub mod points;
pub mod positioning;
pub mod program;
pub mod thermal;
pub mod traces;
pub mod vibration_gap;

pub use error::CliError;
