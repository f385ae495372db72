//! harvest-vacuum
