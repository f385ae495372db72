//! harvest-recorder
