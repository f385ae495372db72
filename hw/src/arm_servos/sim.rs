//! One arm's simulated servos as a device: set-points go out on `hw/armN/servo`, encoder
//! feedback comes back on `hw/armN/encoders`, served by the simulator at its servo rate.

use super::{ArmServos, JOINT_COUNT, JointFeedback};
use crate::error_kind::{DeviceError, ErrorKind};
use harvest_ipc::catalogue::{HW_ARM_ENCODERS, HW_ARM_SERVO};
use harvest_ipc::error::IpcError;
use harvest_ipc::payloads::{EncoderFeedback, ServoSetpoint};
use harvest_ipc::{ArmId, Context, MonotonicClock, Publisher, Subscriber};

/// Errors of the simulated servo link.
#[derive(Debug, thiserror::Error)]
pub enum SimServoError {
    /// A set-point was not finite or outside the joint's limits; nothing was sent.
    #[error("joint {joint} set-point {value} outside [{min}, {max}] or not finite")]
    OutOfLimits {
        /// Joint index 0-3 (D, theta, phi, twist).
        joint: usize,
        /// The set-point, m (joint 0) or rad.
        value: f64,
        /// The joint's lower limit, same unit.
        min: f64,
        /// The joint's upper limit, same unit.
        max: f64,
    },
    /// The hardware channels to the simulator failed (opening, sending or receiving).
    #[error("simulated servo link: {0}")]
    Link(#[from] IpcError),
}

impl DeviceError for SimServoError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::OutOfLimits { .. } => ErrorKind::InvalidRequest,
            Self::Link(_) => ErrorKind::Disconnected,
        }
    }
}

/// Driver for one arm's simulated servos.
pub struct SimArmServos {
    setpoints: Publisher<ServoSetpoint>,
    encoders: Subscriber<EncoderFeedback>,
    /// `[min, max]` per joint, as the servo controller enforces them.
    limits: [[f64; 2]; JOINT_COUNT],
    latest: Option<JointFeedback>,
}

impl SimArmServos {
    /// Opens arm `arm`'s servo and encoder channels; `limits` are the `[min, max]` per joint
    /// the driver refuses set-points outside of.
    pub fn connect(
        context: &Context,
        arm: ArmId,
        limits: [[f64; 2]; JOINT_COUNT],
    ) -> Result<Self, SimServoError> {
        let link = |error: harvest_ipc::error::OpenChannelError| SimServoError::Link(error.into());
        Ok(Self {
            setpoints: context.publisher(HW_ARM_SERVO[arm.index()]).map_err(link)?,
            encoders: context
                .subscriber(HW_ARM_ENCODERS[arm.index()])
                .map_err(link)?,
            limits,
            latest: None,
        })
    }

    fn send(
        &mut self,
        hold: bool,
        position: [f64; JOINT_COUNT],
        velocity: [f64; JOINT_COUNT],
    ) -> Result<(), SimServoError> {
        self.setpoints
            .publish_with(MonotonicClock::read_ns(), |setpoint| {
                setpoint.hold = u8::from(hold);
                setpoint._reserved = [0; 7];
                setpoint.joint_position = position;
                setpoint.joint_velocity = velocity;
            })
            .map_err(|error| SimServoError::Link(error.into()))?;
        Ok(())
    }
}

impl ArmServos for SimArmServos {
    type Error = SimServoError;

    fn command(
        &mut self,
        position: [f64; JOINT_COUNT],
        velocity: [f64; JOINT_COUNT],
    ) -> Result<(), Self::Error> {
        for (joint, (&value, [min, max])) in position.iter().zip(self.limits).enumerate() {
            if !value.is_finite() || value < min || value > max || !velocity[joint].is_finite() {
                return Err(SimServoError::OutOfLimits {
                    joint,
                    value,
                    min,
                    max,
                });
            }
        }
        self.send(false, position, velocity)
    }

    fn hold(&mut self) -> Result<(), Self::Error> {
        let position = self
            .latest
            .map(|feedback| feedback.position)
            .unwrap_or_default();
        self.send(true, position, [0.0; JOINT_COUNT])
    }

    fn feedback(&mut self) -> Result<Option<JointFeedback>, Self::Error> {
        let newest = self
            .encoders
            .receive_latest()
            .map_err(|error| SimServoError::Link(error.into()))?;
        if let Some(sample) = newest {
            self.latest = Some(JointFeedback {
                capture_ns: sample.header.capture_ns,
                position: sample.joint_position,
                velocity: sample.joint_velocity,
                fault_bits: sample.fault_bits,
            });
        }
        Ok(self.latest)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_kind::lost_link;

    #[test]
    fn every_error_maps_to_its_kind() {
        let refused = SimServoError::OutOfLimits {
            joint: 1,
            value: 4.0,
            min: -1.0,
            max: 1.0,
        };
        assert_eq!(refused.kind(), ErrorKind::InvalidRequest);
        assert_eq!(
            SimServoError::from(lost_link()).kind(),
            ErrorKind::Disconnected
        );
    }
}
