//! The integration window of one `lidar/points` cloud: how many returns a window of a given
//! length holds, and the longest window one fixed-capacity cloud payload can carry.

use harvest_hw::lidar::LidarSpec;
use harvest_ipc::payloads::point_cloud::POINT_CLOUD_CAPACITY;

/// Longest window one cloud holds at `spec`'s point rate, seconds (1 s for the Mid-70).
pub fn max_window_s(spec: &LidarSpec) -> f64 {
    POINT_CLOUD_CAPACITY as f64 / spec.point_rate_hz
}

/// Returns of a window of `integration_s` at `spec`'s point rate; `None` when the window is not
/// positive or longer than one cloud holds.
pub fn window_returns(spec: &LidarSpec, integration_s: f64) -> Option<usize> {
    (integration_s > 0.0 && integration_s <= max_window_s(spec) + 1e-9)
        .then(|| ((integration_s * spec.point_rate_hz).round() as usize).min(POINT_CLOUD_CAPACITY))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_of_mid70_returns_fills_one_cloud() {
        let spec = LidarSpec::mid70();
        assert!((max_window_s(&spec) - 1.0).abs() < 1e-12);
        assert_eq!(window_returns(&spec, 1.0), Some(100_000));
        assert_eq!(window_returns(&spec, 0.25), Some(25_000));
        for bad in [0.0, -1.0, 1.5, f64::NAN, f64::INFINITY] {
            assert_eq!(window_returns(&spec, bad), None, "{bad}");
        }
    }
}
