//! ALACS unit: red line laser on a 20 cm linear slide plus an RGB camera.
