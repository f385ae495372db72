//! `lidar/points` -> `/lidar/cloud` (lidar frame: x, y, z, intensity as float32, the payload's
//! own layout) and `laser/scan_result` -> `/laser/scan` (camera_color frame: the per-image
//! candidates and the final position, with a `kind` field: 0 candidate, 1 selected candidate,
//! 2 final position).

use crate::frames;
use crate::geometry::{IDENTITY, pose};
use crate::stamps::TimeBase;
use foxglove::bytes::Bytes;
use foxglove::messages::{PackedElementField, PointCloud, packed_element_field};
use harvest_ipc::payloads::{LaserScanResult, LaserScanStatus, PointCloud as LidarCloud};

fn float_field(name: &str, offset: u32) -> PackedElementField {
    PackedElementField {
        name: name.to_owned(),
        offset,
        r#type: packed_element_field::NumericType::Float32 as i32,
    }
}

/// The LiDAR cloud, valid points only.
pub fn lidar_cloud(cloud: &LidarCloud, time: &TimeBase) -> PointCloud {
    let points = cloud.valid_points();
    let mut data = Vec::with_capacity(points.len() * 16);
    for point in points {
        for value in [point.x_m, point.y_m, point.z_m, point.intensity] {
            data.extend_from_slice(&value.to_le_bytes());
        }
    }
    PointCloud {
        timestamp: Some(time.timestamp(cloud.header.capture_ns)),
        frame_id: frames::LIDAR.to_owned(),
        pose: Some(pose([0.0; 3], IDENTITY)),
        point_stride: 16,
        fields: vec![
            float_field("x", 0),
            float_field("y", 4),
            float_field("z", 8),
            float_field("intensity", 12),
        ],
        data: Bytes::from(data),
    }
}

/// The laser scan's candidates and final position (empty when the scan failed).
pub fn laser_scan(result: &LaserScanResult, time: &TimeBase) -> PointCloud {
    let count = usize::from(result.candidate_count).min(result.candidates_in_camera_m.len());
    let mut points: Vec<([f64; 3], f32)> = result.candidates_in_camera_m[..count]
        .iter()
        .enumerate()
        .map(|(index, point)| {
            let kind = if index == usize::from(result.selected) {
                1.0
            } else {
                0.0
            };
            (*point, kind)
        })
        .collect();
    if result.status == LaserScanStatus::Ok {
        points.push((result.position_in_camera_m, 2.0));
    }
    let mut data = Vec::with_capacity(points.len() * 16);
    for (point, kind) in points
        .iter()
        .filter(|(point, _)| point.iter().all(|v| v.is_finite()))
    {
        for value in [point[0] as f32, point[1] as f32, point[2] as f32, *kind] {
            data.extend_from_slice(&value.to_le_bytes());
        }
    }
    PointCloud {
        timestamp: Some(time.timestamp(result.header.capture_ns)),
        frame_id: frames::CAMERA_COLOR.to_owned(),
        pose: Some(pose([0.0; 3], IDENTITY)),
        point_stride: 16,
        fields: vec![
            float_field("x", 0),
            float_field("y", 4),
            float_field("z", 8),
            float_field("kind", 12),
        ],
        data: Bytes::from(data),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::payloads::LidarPoint;

    #[test]
    fn clouds_pack_their_points() {
        let mut cloud: Box<LidarCloud> = harvest_ipc::payload::boxed_zeroed();
        for k in 0..3 {
            cloud.push(LidarPoint {
                x_m: k as f32,
                y_m: 1.0,
                z_m: 2.0,
                intensity: 50.0,
            });
        }
        let mapped = lidar_cloud(&cloud, &TimeBase::MONOTONIC);
        assert_eq!(mapped.data.len(), 3 * 16);
        assert_eq!(&mapped.data[16..20], &1.0f32.to_le_bytes());
        assert_eq!(mapped.frame_id, "lidar");

        let result = LaserScanResult {
            status: LaserScanStatus::Ok.into(),
            candidate_count: 2,
            selected: 1,
            candidates_in_camera_m: [
                [0.1, 0.0, 1.0],
                [0.1, 0.0, 1.01],
                [0.0; 3],
                [0.0; 3],
                [0.0; 3],
            ],
            position_in_camera_m: [0.1, 0.0, 1.005],
            ..LaserScanResult::default()
        };
        let scan = laser_scan(&result, &TimeBase::MONOTONIC);
        assert_eq!(scan.data.len(), 3 * 16);
        assert_eq!(
            &scan.data[28..32],
            &1.0f32.to_le_bytes(),
            "second is selected"
        );
        assert_eq!(
            &scan.data[44..48],
            &2.0f32.to_le_bytes(),
            "then the final position"
        );
    }
}
