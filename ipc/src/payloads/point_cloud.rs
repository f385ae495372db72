//! One point cloud of the solid-state LiDAR (Livox Mid-70, [fusion Table II]): up to
//! [`POINT_CLOUD_CAPACITY`] returns in the LiDAR frame with their intensity. About 1.6 MB: always
//! loaned and written in place.
//!
//! LiDAR frame (Livox convention): x forward along the boresight, y left, z up, metres. The
//! device delivers short frames on the hardware channel; the `lidar` process integrates them
//! (the non-repetitive scan densifies with integration time) and publishes one cloud per
//! integration period. `header.capture_ns` is the end of the integration window.

use crate::codec::{self, CodecError};
use crate::header::Header;
use crate::payload::CustomCodec;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Points one cloud can hold: one second of the Mid-70 at 100,000 points/s.
pub const POINT_CLOUD_CAPACITY: usize = 100_000;

/// One return.
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Describe,
)]
pub struct LidarPoint {
    /// Position in the LiDAR frame, metres.
    pub x_m: f32,
    /// Position in the LiDAR frame, metres.
    pub y_m: f32,
    /// Position in the LiDAR frame, metres.
    pub z_m: f32,
    /// Reflectivity of the return, 0-255 (Livox scale: 0-150 diffuse, 151-255 retro-reflective).
    pub intensity: f32,
}

impl LidarPoint {
    /// The position as an `[x, y, z]` array, metres.
    pub fn position_m(&self) -> [f32; 3] {
        [self.x_m, self.y_m, self.z_m]
    }

    /// True when all three coordinates are finite (the device may report NaN for no return).
    pub fn is_finite(&self) -> bool {
        self.x_m.is_finite() && self.y_m.is_finite() && self.z_m.is_finite()
    }
}

/// Cloud metadata: everything but the point buffer.
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Describe,
)]
pub struct PointCloudMeta {
    /// Valid points at the start of `points`.
    pub point_count: u32,
    /// Bit 0: the integration window held more returns than [`POINT_CLOUD_CAPACITY`] (the
    /// excess was dropped).
    pub flags: u32,
    /// Length of the integration window, nanoseconds; it ends at `header.capture_ns`.
    pub integration_ns: u64,
}

impl PointCloudMeta {
    /// Bit of [`Self::flags`]: points beyond the capacity were dropped.
    pub const FLAG_TRUNCATED: u32 = 1;
}

/// One integrated LiDAR point cloud in the LiDAR frame (`lidar/points`, `hw/lidar/points`).
#[repr(C)]
#[derive(ZeroCopySend, crate::AnyBitPattern, crate::Payload)]
#[type_name("harvest.PointCloud.v1")]
#[payload(custom_codec)]
pub struct PointCloud {
    /// `capture_ns` is the end of the integration window; see [`Header`].
    pub header: Header,
    /// Point count, flags and integration window.
    pub meta: PointCloudMeta,
    /// The first `meta.point_count` entries are valid; the rest is stale memory (not encoded).
    #[schema(count = "meta.point_count")]
    pub points: [LidarPoint; POINT_CLOUD_CAPACITY],
}

impl std::fmt::Debug for PointCloud {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PointCloud")
            .field("header", &self.header)
            .field("meta", &self.meta)
            .finish_non_exhaustive()
    }
}

impl PointCloud {
    /// The valid points (`meta.point_count`, clamped to the capacity).
    pub fn valid_points(&self) -> &[LidarPoint] {
        let count = (self.meta.point_count as usize).min(POINT_CLOUD_CAPACITY);
        &self.points[..count]
    }

    /// Empties the cloud (metadata only; the point memory is left as it is).
    pub fn clear(&mut self) {
        self.meta.point_count = 0;
        self.meta.flags = 0;
        self.meta.integration_ns = 0;
    }

    /// Appends a point; when full, sets [`PointCloudMeta::FLAG_TRUNCATED`] and returns `false`.
    pub fn push(&mut self, point: LidarPoint) -> bool {
        let count = self.meta.point_count as usize;
        if count >= POINT_CLOUD_CAPACITY {
            self.meta.flags |= PointCloudMeta::FLAG_TRUNCATED;
            return false;
        }
        self.points[count] = point;
        self.meta.point_count += 1;
        true
    }

    /// Appends as many of `points` as fit; returns how many were appended.
    pub fn extend_from_slice(&mut self, points: &[LidarPoint]) -> usize {
        let count = (self.meta.point_count as usize).min(POINT_CLOUD_CAPACITY);
        let room = POINT_CLOUD_CAPACITY - count;
        let taken = points.len().min(room);
        self.points[count..count + taken].copy_from_slice(&points[..taken]);
        self.meta.point_count = (count + taken) as u32;
        if taken < points.len() {
            self.meta.flags |= PointCloudMeta::FLAG_TRUNCATED;
        }
        taken
    }
}

const POINT_BYTES: usize = 16;

impl CustomCodec for PointCloud {
    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError> {
        let points = self.valid_points();
        out.reserve(points.len() * POINT_BYTES + 64);
        let meta = PointCloudMeta {
            point_count: points.len() as u32,
            ..self.meta
        };
        codec::encode_into(&(self.header, meta), out)?;
        for point in points {
            for value in [point.x_m, point.y_m, point.z_m, point.intensity] {
                out.extend_from_slice(&value.to_le_bytes());
            }
        }
        Ok(())
    }

    fn decode_into(bytes: &[u8], dst: &mut Self) -> Result<(), CodecError> {
        let ((header, meta), used): ((Header, PointCloudMeta), usize) =
            codec::decode_prefix(bytes)?;
        let count = meta.point_count as usize;
        if count > POINT_CLOUD_CAPACITY {
            return Err(CodecError::Decode(format!(
                "point_count {count} exceeds the capacity {POINT_CLOUD_CAPACITY}"
            )));
        }
        let expected = used + count * POINT_BYTES;
        if bytes.len() != expected {
            return Err(CodecError::Length {
                expected,
                actual: bytes.len(),
            });
        }
        dst.header = header;
        dst.meta = meta;
        for (point, chunk) in dst
            .points
            .iter_mut()
            .zip(bytes[used..].chunks_exact(POINT_BYTES))
        {
            let value = |k: usize| {
                f32::from_le_bytes([
                    chunk[4 * k],
                    chunk[4 * k + 1],
                    chunk[4 * k + 2],
                    chunk[4 * k + 3],
                ])
            };
            *point = LidarPoint {
                x_m: value(0),
                y_m: value(1),
                z_m: value(2),
                intensity: value(3),
            };
        }
        Ok(())
    }

    fn to_json(&self) -> serde_json::Value {
        let points = self.valid_points();
        let finite = points.iter().filter(|p| p.is_finite()).count();
        serde_json::json!({
            "header": self.header,
            "meta": self.meta,
            "finite_points": finite,
            "first_point": points.first(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encode_decode_round_trip_keeps_only_valid_points() {
        let mut cloud: Box<PointCloud> = crate::payload::boxed_zeroed();
        cloud.header.msg_seq = 7;
        cloud.meta.integration_ns = 1_000_000_000;
        for k in 0..3 {
            assert!(cloud.push(LidarPoint {
                x_m: 1.0 + k as f32,
                y_m: -0.5,
                z_m: 0.25,
                intensity: 40.0,
            }));
        }
        let mut bytes = Vec::new();
        cloud.encode(&mut bytes).expect("encode");
        assert_eq!(bytes.len(), 24 + 16 + 3 * POINT_BYTES);
        let mut back: Box<PointCloud> = crate::payload::boxed_zeroed();
        PointCloud::decode_into(&bytes, &mut back).expect("decode");
        assert_eq!(back.header, cloud.header);
        assert_eq!(back.meta, cloud.meta);
        assert_eq!(back.valid_points(), cloud.valid_points());
        assert!(PointCloud::decode_into(&bytes[..bytes.len() - 1], &mut back).is_err());
    }

    #[test]
    fn a_full_cloud_flags_truncation() {
        let mut cloud: Box<PointCloud> = crate::payload::boxed_zeroed();
        let batch = vec![LidarPoint::default(); 60_000];
        assert_eq!(cloud.extend_from_slice(&batch), 60_000);
        assert_eq!(cloud.extend_from_slice(&batch), 40_000);
        assert_eq!(cloud.meta.flags & PointCloudMeta::FLAG_TRUNCATED, 1);
        assert!(!cloud.push(LidarPoint::default()));
        assert_eq!(cloud.valid_points().len(), POINT_CLOUD_CAPACITY);
    }
}
