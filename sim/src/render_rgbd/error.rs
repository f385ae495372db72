//! [`RenderError`]: why a frame could not be rendered.

use crate::scenario::CameraPoseError;

/// Why a frame could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The caller's buffer does not have the frame's size.
    #[error("{buffer} buffer holds {actual} elements; a {width}x{height} frame needs {expected}")]
    BufferSize {
        buffer: &'static str,
        expected: usize,
        actual: usize,
        width: u32,
        height: u32,
    },
    /// The camera pose in the scenario is degenerate.
    #[error("camera pose: {0}")]
    CameraPose(#[from] CameraPoseError),
}
