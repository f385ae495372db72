//! Livox Mid-70 parameters ([fusion Table II]) and the sensor configuration the
//! simulator and the driver share.

use serde::{Deserialize, Serialize};

/// Full cone angle of the circular field of view, degrees (Table II).
pub const MID70_FOV_DEG: f64 = 70.4;
/// Returns per second (Table II).
pub const MID70_POINT_RATE_HZ: f64 = 100_000.0;
/// Range error bound over the working range, metres (Table II: <= 2 cm over 0.2-20 m).
pub const MID70_RANGE_ERROR_M: f64 = 0.02;
/// Working range with the stated error, metres (Table II).
pub const MID70_RANGE_M: [f64; 2] = [0.2, 20.0];
/// Rate of the frames the device streams to its driver (Livox default), Hz.
pub const MID70_FRAME_RATE_HZ: f64 = 10.0;

/// A solid-state LiDAR's scan and error model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LidarSpec {
    /// Full cone angle of the circular field of view, degrees.
    pub fov_deg: f64,
    /// Returns per second.
    pub point_rate_hz: f64,
    /// One standard deviation of the Gaussian range noise, metres (the spec's bound taken as one
    /// sigma, as the ToF camera's spec is in the simulator: conservative).
    pub range_sigma_m: f64,
    /// One standard deviation of the beam direction noise, degrees.
    pub angular_sigma_deg: f64,
    /// Returns outside this range are not reported, metres `[min, max]`.
    pub range_m: [f64; 2],
    /// Rate of the device's frames on the hardware channel, Hz.
    pub frame_rate_hz: f64,
    /// Angular speeds of the two Risley prisms, revolutions per second (opposite signs give the
    /// rosette; an irrational ratio makes the pattern non-repetitive).
    pub prism_rev_per_s: [f64; 2],
}

impl Default for LidarSpec {
    fn default() -> Self {
        Self::mid70()
    }
}

impl LidarSpec {
    /// The Livox Mid-70 of Table II. The prism speeds are the ones commonly quoted for the
    /// Livox rosette scanners (7294 and -4664 rpm); they set the petal shape, not the rate.
    pub fn mid70() -> Self {
        Self {
            fov_deg: MID70_FOV_DEG,
            point_rate_hz: MID70_POINT_RATE_HZ,
            range_sigma_m: MID70_RANGE_ERROR_M,
            angular_sigma_deg: 0.05,
            range_m: MID70_RANGE_M,
            frame_rate_hz: MID70_FRAME_RATE_HZ,
            prism_rev_per_s: [7294.0 / 60.0, -4664.0 / 60.0],
        }
    }

    /// Half the cone angle, radians.
    pub fn half_fov_rad(&self) -> f64 {
        self.fov_deg.to_radians() / 2.0
    }

    /// Points in one device frame.
    pub fn points_per_frame(&self) -> usize {
        (self.point_rate_hz / self.frame_rate_hz).round() as usize
    }

    /// Checks every field; the error names the field and its value.
    pub fn validate(&self) -> Result<(), String> {
        let check = |key: &str, value: f64, min: f64, max: f64| {
            if value.is_finite() && value >= min && value <= max {
                Ok(())
            } else {
                Err(format!("lidar spec: {key} = {value} outside {min}..={max}"))
            }
        };
        check("fov_deg", self.fov_deg, 1.0, 170.0)?;
        check("point_rate_hz", self.point_rate_hz, 1.0, 1e7)?;
        check("range_sigma_m", self.range_sigma_m, 0.0, 1.0)?;
        check("angular_sigma_deg", self.angular_sigma_deg, 0.0, 5.0)?;
        check("range_m[0]", self.range_m[0], 0.0, 1000.0)?;
        check("range_m[1]", self.range_m[1], self.range_m[0], 1000.0)?;
        check("frame_rate_hz", self.frame_rate_hz, 0.1, 1000.0)?;
        for (k, rev) in self.prism_rev_per_s.iter().enumerate() {
            check(&format!("prism_rev_per_s[{k}]"), rev.abs(), 1e-3, 1e5)?;
        }
        Ok(())
    }
}
