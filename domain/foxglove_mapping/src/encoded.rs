//! Mapping recorded (encoded) messages: the recorder's mapped channels and `rec export
//! --foxglove` decode each message of a mapped stack channel back into its payload
//! (`Payload::decode_into`) and map it like the live bridge does, camera images included.

use crate::camera::{CameraMapper, ImageSettings, JpegEncoder};
use crate::error::MapError;
use crate::stack_mapper::{Mounting, StackMapper};
use crate::stamps::TimeBase;
use crate::topics::MappedSink;
use harvest_ipc::payloads::{
    AppleDetections, ArmState, EmergencyStop, HarvestEvent, LaserScanResult, PointCloud, RgbdFrame,
    VacuumState,
};
use harvest_ipc::{ArmId, Channel, Payload, catalogue};

/// The stack channels the mapping reads, with their payload type and version.
pub fn mapped_channels() -> Vec<(&'static str, &'static str, u32)> {
    fn entry<T: Payload>(channel: Channel<T>) -> (&'static str, &'static str, u32) {
        (channel.spec.topic, T::TYPE_NAME, T::VERSION)
    }
    vec![
        entry(catalogue::CAMERA_RGBD),
        entry(catalogue::PERCEPTION_APPLES),
        entry(catalogue::ARM_STATE[0]),
        entry(catalogue::ARM_STATE[1]),
        entry(catalogue::VACUUM_STATE),
        entry(catalogue::HARVEST_EVENTS),
        entry(catalogue::EMERGENCY_STOP),
        entry(catalogue::LIDAR_POINTS),
        entry(catalogue::LASER_SCAN_RESULT),
    ]
}

/// True when `topic` is a stack channel the mapping reads.
pub fn is_mapped(topic: &str) -> bool {
    mapped_channels().iter().any(|(name, _, _)| *name == topic)
}

/// Decodes and maps recorded messages, reusing its buffers (frames are 6.8 MB).
pub struct EncodedMapper {
    camera: CameraMapper,
    jpeg: JpegEncoder,
    stack: StackMapper,
    frame: Box<RgbdFrame>,
    cloud: Box<PointCloud>,
}

impl std::fmt::Debug for EncodedMapper {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EncodedMapper")
            .field("camera", &self.camera)
            .finish_non_exhaustive()
    }
}

fn decode<T: Payload, E>(topic: &str, bytes: &[u8]) -> Result<Box<T>, MapError<E>> {
    let mut value: Box<T> = harvest_ipc::payload::boxed_zeroed();
    decode_into(topic, bytes, &mut *value)?;
    Ok(value)
}

fn decode_into<T: Payload, E>(topic: &str, bytes: &[u8], value: &mut T) -> Result<(), MapError<E>> {
    T::decode_into(bytes, value).map_err(|error| MapError::Decode {
        topic: topic.to_owned(),
        reason: error.to_string(),
    })
}

impl EncodedMapper {
    pub fn new(time: TimeBase, image: ImageSettings, mounting: Mounting) -> Self {
        Self {
            camera: CameraMapper::new(image, time, mounting.robot_from_camera),
            jpeg: JpegEncoder::new(image),
            stack: StackMapper::new(time, image, mounting),
            frame: harvest_ipc::payload::boxed_zeroed(),
            cloud: harvest_ipc::payload::boxed_zeroed(),
        }
    }

    /// Maps one recorded message of the stack channel `topic` (encoded with its payload's
    /// current version). Returns `false` when the mapping does not read that channel.
    pub fn map<S: MappedSink>(
        &mut self,
        topic: &str,
        bytes: &[u8],
        log_time_ns: u64,
        sink: &mut S,
    ) -> Result<bool, MapError<S::Error>> {
        if topic == catalogue::CAMERA_RGBD.spec.topic {
            decode_into(topic, bytes, &mut *self.frame)?;
            let jpeg = self
                .jpeg
                .encode(&self.frame)
                .map_err(|error| MapError::Image {
                    topic: topic.to_owned(),
                    reason: error.to_string(),
                })?;
            self.camera.write(&self.frame, jpeg, log_time_ns, sink)?;
        } else if topic == catalogue::PERCEPTION_APPLES.spec.topic {
            let detections = decode::<AppleDetections, _>(topic, bytes)?;
            self.stack.detections(&detections, log_time_ns, sink)?;
        } else if let Some(arm) = ArmId::ALL
            .into_iter()
            .find(|arm| catalogue::ARM_STATE[arm.index()].spec.topic == topic)
        {
            let state = decode::<ArmState, _>(topic, bytes)?;
            self.stack.arm_state(arm, &state, log_time_ns, sink)?;
        } else if topic == catalogue::VACUUM_STATE.spec.topic {
            let state = decode::<VacuumState, _>(topic, bytes)?;
            self.stack.vacuum(&state, log_time_ns, sink)?;
        } else if topic == catalogue::HARVEST_EVENTS.spec.topic {
            let event = decode::<HarvestEvent, _>(topic, bytes)?;
            self.stack.event(&event, log_time_ns, sink)?;
        } else if topic == catalogue::EMERGENCY_STOP.spec.topic {
            let stop = decode::<EmergencyStop, _>(topic, bytes)?;
            self.stack.emergency_stop(&stop, log_time_ns, sink)?;
        } else if topic == catalogue::LIDAR_POINTS.spec.topic {
            decode_into(topic, bytes, &mut *self.cloud)?;
            self.stack.lidar(&self.cloud, log_time_ns, sink)?;
        } else if topic == catalogue::LASER_SCAN_RESULT.spec.topic {
            let result = decode::<LaserScanResult, _>(topic, bytes)?;
            self.stack.laser_scan(&result, log_time_ns, sink)?;
        } else {
            return Ok(false);
        }
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topics::Topic;
    use foxglove::Encode;

    /// Collects (topic, log time, encoded bytes).
    #[derive(Default)]
    struct Collect(Vec<(&'static str, u64, Vec<u8>)>);

    impl MappedSink for Collect {
        type Error = std::convert::Infallible;
        fn write<M: Encode>(
            &mut self,
            topic: Topic<M>,
            log_time_ns: u64,
            message: &M,
        ) -> Result<(), Self::Error> {
            let mut bytes = Vec::new();
            crate::topics::encode_into(message, &mut bytes).ok();
            self.0.push((topic.name, log_time_ns, bytes));
            Ok(())
        }
    }

    fn encoded<T: Payload>(value: &T) -> Vec<u8> {
        let mut bytes = Vec::new();
        value.encode(&mut bytes).expect("encode");
        bytes
    }

    #[test]
    fn recorded_messages_map_to_their_topics() {
        let mut mapper = EncodedMapper::new(
            TimeBase::MONOTONIC,
            ImageSettings::VIEWING,
            Mounting::default(),
        );
        let mut sink = Collect::default();
        let state = ArmState {
            phase: harvest_ipc::payloads::ArmPhase::Approach.into(),
            ..ArmState::default()
        };
        assert!(
            mapper
                .map("arm1/state", &encoded(&state), 10, &mut sink)
                .expect("map")
        );
        let topics: Vec<&str> = sink.0.iter().map(|(topic, _, _)| *topic).collect();
        assert_eq!(topics, ["/tf", "/arm1/joints", "/robot_model"]);
        let frame: Box<RgbdFrame> = harvest_ipc::payload::boxed_zeroed();
        sink.0.clear();
        assert!(
            mapper
                .map("camera/rgbd", &encoded(&*frame), 20, &mut sink)
                .expect("map")
        );
        let topics: Vec<&str> = sink.0.iter().map(|(topic, _, _)| *topic).collect();
        assert_eq!(topics, ["/camera/image", "/camera/calibration", "/tf"]);
        assert!(
            !mapper
                .map("vacuum/valve_grant", &[], 0, &mut sink)
                .expect("map")
        );
        let error = mapper
            .map("vacuum/state", &[1, 2, 3], 0, &mut sink)
            .expect_err("truncated");
        assert!(error.to_string().contains("vacuum/state"), "{error}");
        assert!(is_mapped("camera/rgbd") && !is_mapped("hw/camera/rgbd"));
    }
}
