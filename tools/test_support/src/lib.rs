//! Test support shared by the workspace's property tests; a dev-dependency only, never linked
//! into a binary.
//!
//! - [`toml_mutation`]: one generator of damaged TOML files for every reader of outside files.
//! - [`python`]: the independent Python checkers, installed with pip where missing.

#![forbid(unsafe_code)]

pub mod python;
pub mod toml_mutation;
