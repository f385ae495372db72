//! Borrowed, zero-copy views of one colour frame and one depth frame.
//!
//! The views only borrow the pixel buffers so the process wiring can hand in shared-memory
//! samples without copying. Every consumer validates a view with [`RgbView::validate`] /
//! [`DepthView::validate`] before indexing it, so a wrong buffer size never panics.

use thiserror::Error;

/// An RGB8 image, row-major, 3 bytes per pixel (R, G, B), no row padding.
#[derive(Debug, Clone, Copy)]
pub struct RgbView<'a> {
    pub width_px: u32,
    pub height_px: u32,
    /// `width_px * height_px * 3` bytes.
    pub data: &'a [u8],
}

/// A depth image in millimetres along the optical axis (z-depth), row-major; 0 = no return.
#[derive(Debug, Clone, Copy)]
pub struct DepthView<'a> {
    pub width_px: u32,
    pub height_px: u32,
    /// `width_px * height_px` samples, depth in mm.
    pub data: &'a [u16],
}

/// Why a frame cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum FrameError {
    /// The colour image has zero width or height.
    #[error("RGB frame has zero size ({width_px}x{height_px} px)")]
    RgbEmpty { width_px: u32, height_px: u32 },
    /// The colour buffer length does not match `width_px * height_px * 3`.
    #[error(
        "RGB frame {width_px}x{height_px} px: buffer holds {actual_bytes} bytes, expected {expected_bytes}"
    )]
    RgbBufferSize {
        width_px: u32,
        height_px: u32,
        expected_bytes: usize,
        actual_bytes: usize,
    },
    /// The colour image size differs from the calibrated colour camera.
    #[error(
        "RGB frame is {width_px}x{height_px} px but the colour camera is calibrated for {expected_width_px}x{expected_height_px} px"
    )]
    RgbSizeMismatch {
        width_px: u32,
        height_px: u32,
        expected_width_px: u32,
        expected_height_px: u32,
    },
    /// The depth image has zero width or height.
    #[error("depth frame has zero size ({width_px}x{height_px} px)")]
    DepthEmpty { width_px: u32, height_px: u32 },
    /// The depth buffer length does not match `width_px * height_px`.
    #[error(
        "depth frame {width_px}x{height_px} px: buffer holds {actual_samples} samples, expected {expected_samples}"
    )]
    DepthBufferSize {
        width_px: u32,
        height_px: u32,
        expected_samples: usize,
        actual_samples: usize,
    },
    /// The depth image size differs from the calibrated depth camera.
    #[error(
        "depth frame is {width_px}x{height_px} px but the depth camera is calibrated for {expected_width_px}x{expected_height_px} px"
    )]
    DepthSizeMismatch {
        width_px: u32,
        height_px: u32,
        expected_width_px: u32,
        expected_height_px: u32,
    },
    /// The detector failed on the frame (a learned detector's runtime error).
    #[error("detector {detector} failed: {reason}")]
    DetectorFailed {
        detector: &'static str,
        reason: String,
    },
}

impl RgbView<'_> {
    /// Checks that the buffer holds exactly `width_px * height_px` RGB8 pixels.
    pub fn validate(&self) -> Result<(), FrameError> {
        if self.width_px == 0 || self.height_px == 0 {
            return Err(FrameError::RgbEmpty {
                width_px: self.width_px,
                height_px: self.height_px,
            });
        }
        let expected_bytes = (self.width_px as usize)
            .checked_mul(self.height_px as usize)
            .and_then(|pixels| pixels.checked_mul(3))
            .unwrap_or(usize::MAX);
        if self.data.len() != expected_bytes {
            return Err(FrameError::RgbBufferSize {
                width_px: self.width_px,
                height_px: self.height_px,
                expected_bytes,
                actual_bytes: self.data.len(),
            });
        }
        Ok(())
    }

    /// Like [`Self::validate`], and also checks the size against the calibrated camera.
    pub fn validate_size(&self, width_px: u32, height_px: u32) -> Result<(), FrameError> {
        self.validate()?;
        if self.width_px != width_px || self.height_px != height_px {
            return Err(FrameError::RgbSizeMismatch {
                width_px: self.width_px,
                height_px: self.height_px,
                expected_width_px: width_px,
                expected_height_px: height_px,
            });
        }
        Ok(())
    }
}

impl DepthView<'_> {
    /// Checks that the buffer holds exactly `width_px * height_px` depth samples.
    pub fn validate(&self) -> Result<(), FrameError> {
        if self.width_px == 0 || self.height_px == 0 {
            return Err(FrameError::DepthEmpty {
                width_px: self.width_px,
                height_px: self.height_px,
            });
        }
        let expected_samples = (self.width_px as usize).saturating_mul(self.height_px as usize);
        if self.data.len() != expected_samples {
            return Err(FrameError::DepthBufferSize {
                width_px: self.width_px,
                height_px: self.height_px,
                expected_samples,
                actual_samples: self.data.len(),
            });
        }
        Ok(())
    }

    /// Like [`Self::validate`], and also checks the size against the calibrated camera.
    pub fn validate_size(&self, width_px: u32, height_px: u32) -> Result<(), FrameError> {
        self.validate()?;
        if self.width_px != width_px || self.height_px != height_px {
            return Err(FrameError::DepthSizeMismatch {
                width_px: self.width_px,
                height_px: self.height_px,
                expected_width_px: width_px,
                expected_height_px: height_px,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgb_buffer_size_is_checked() {
        let data = vec![0_u8; 4 * 3 * 3];
        let ok = RgbView {
            width_px: 4,
            height_px: 3,
            data: &data,
        };
        assert_eq!(ok.validate(), Ok(()));
        let short = RgbView {
            width_px: 4,
            height_px: 3,
            data: &data[1..],
        };
        assert_eq!(
            short.validate(),
            Err(FrameError::RgbBufferSize {
                width_px: 4,
                height_px: 3,
                expected_bytes: 36,
                actual_bytes: 35
            })
        );
        let empty = RgbView {
            width_px: 0,
            height_px: 3,
            data: &[],
        };
        assert!(matches!(empty.validate(), Err(FrameError::RgbEmpty { .. })));
        assert!(matches!(
            ok.validate_size(8, 3),
            Err(FrameError::RgbSizeMismatch { .. })
        ));
    }

    #[test]
    fn depth_buffer_size_is_checked_without_overflow() {
        let data = vec![0_u16; 12];
        let ok = DepthView {
            width_px: 4,
            height_px: 3,
            data: &data,
        };
        assert_eq!(ok.validate(), Ok(()));
        let huge = DepthView {
            width_px: u32::MAX,
            height_px: u32::MAX,
            data: &data,
        };
        assert!(matches!(
            huge.validate(),
            Err(FrameError::DepthBufferSize { .. })
        ));
        assert!(matches!(
            ok.validate_size(4, 4),
            Err(FrameError::DepthSizeMismatch { .. })
        ));
    }
}
