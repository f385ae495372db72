//! Test support shared by the workspace's property tests; a dev-dependency only, never linked
//! into a binary.
//!
//! - [`toml_mutation`]: one generator of damaged TOML files for every reader of outside files.

#![forbid(unsafe_code)]

pub mod toml_mutation;
