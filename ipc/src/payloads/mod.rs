//! The message types of the stack, one concept per file.

pub mod alacs;
pub mod apple_detections;
pub mod arm;
pub mod emergency_stop;
pub mod hardware;
pub mod harvest_event;
pub mod laser_scan;
pub mod node_tick;
pub mod platform;
pub mod point_cloud;
pub mod process_health;
pub mod rgbd_frame;
pub mod safety_violation;
pub mod tractor;
pub mod vacuum;
// Operator channels: commands, acknowledgements, the mode, manual arm orders.
pub mod arm_manual;
pub mod operator;
pub mod operator_mark;

pub use alacs::{AlacsCommand, AlacsImage, AlacsStatus};
pub use apple_detections::{AppleDetection, AppleDetections, DepthSourceCode, LocalizationMethod};
pub use arm::{ArmCommand, ArmPhase, ArmState, ArmTarget, JOINT_COUNT, TargetStatus};
pub use arm_manual::{ArmManualCommand, ArmManualKind};
pub use emergency_stop::EmergencyStop;
pub use hardware::{
    EncoderFeedback, GroundTruth, ServoSetpoint, TrueApple, TrueAppleState, ValveBoardCommand,
    ValveBoardReadings,
};
pub use harvest_event::{
    HARVEST_EVENT_REASON_BYTES, HarvestCause, HarvestEvent, HarvestEventKind, HarvestEventSource,
};
pub use laser_scan::{LaserScanRequest, LaserScanResult, LaserScanStatus};
pub use node_tick::{
    DeviceRead, MODE_SLOT, NodeTickRecord, StopHeard, TICK_INPUTS, TICK_READINGS_BYTES, TickInput,
};
pub use operator::{
    OperatorAck, OperatorCommand, OperatorCommandCode, OperatorModeCode, OperatorModeState,
    OperatorRefusalCode,
};
pub use operator_mark::{MARK_SOURCE_BYTES, MARK_TEXT_BYTES, OperatorMark};
pub use platform::{PlatformCommand, PlatformFeedback, PlatformStatus};
pub use point_cloud::{LidarPoint, PointCloud, PointCloudMeta};
pub use process_health::{DeviceErrorCode, ProcessHealth, ProcessRunState};
pub use rgbd_frame::{RgbdFrame, RgbdFrameMeta};
pub use safety_violation::{SafetyViolation, VIOLATION_TEXT_BYTES, ViolationAction, ViolationRule};
pub use tractor::{TractorCommand, TractorFeedback, TractorStatus};
pub use vacuum::{
    ArmAttachment, VacuumPolicyCode, VacuumState, ValveGrant, ValveRequest, ValveRequestKind,
};
