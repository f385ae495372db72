//! harvest-sim
