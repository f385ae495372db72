//! harvest-arm
