//! harvest-camera
