//! harvest-laser
