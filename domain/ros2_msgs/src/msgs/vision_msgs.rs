//! `vision_msgs` (ros-perception/vision_msgs 4.x, the ROS 2 releases): 3D detections.
//!
//! Why this type for the stack's detections: `Detection3DArray` is the common ROS 2 output of
//! 3D object detectors (Isaac ROS, depthai-ros, the vision_msgs REP-style conventions) and
//! holds what an apple detection is: a class with a score (`ObjectHypothesis`), a centre
//! (`pose`, here in the colour camera's optical frame), a size (`bbox.size`: the sphere's
//! bounding cube) and an id that stays the same across messages (the apple's track id).

use super::geometry_msgs::{
    POSE_TYPE, POSE_WITH_COVARIANCE_TYPE, Pose, PoseWithCovariance, VECTOR3_TYPE, Vector3,
};
use super::std_msgs::{HEADER_TYPE, Header};
use crate::cdr::{CdrError, CdrReader, CdrWriter};
use crate::message::RosMessage;
use crate::type_description::{BaseType, Field, MessageType, STRING};

/// `vision_msgs/msg/ObjectHypothesis`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ObjectHypothesis {
    pub class_id: String,
    pub score: f64,
}

pub static OBJECT_HYPOTHESIS_TYPE: MessageType = MessageType {
    name: "vision_msgs/msg/ObjectHypothesis",
    constants: &[],
    fields: &[
        Field::new("class_id", STRING),
        Field::new("score", BaseType::Float64),
    ],
};

impl RosMessage for ObjectHypothesis {
    const TYPE: &'static MessageType = &OBJECT_HYPOTHESIS_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_string(&self.class_id);
        w.write_f64(self.score);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            class_id: r.read_string()?,
            score: r.read_f64()?,
        })
    }
}

/// `vision_msgs/msg/ObjectHypothesisWithPose`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ObjectHypothesisWithPose {
    pub hypothesis: ObjectHypothesis,
    pub pose: PoseWithCovariance,
}

pub static OBJECT_HYPOTHESIS_WITH_POSE_TYPE: MessageType = MessageType {
    name: "vision_msgs/msg/ObjectHypothesisWithPose",
    constants: &[],
    fields: &[
        Field::new("hypothesis", BaseType::Nested(&OBJECT_HYPOTHESIS_TYPE)),
        Field::new("pose", BaseType::Nested(&POSE_WITH_COVARIANCE_TYPE)),
    ],
};

impl RosMessage for ObjectHypothesisWithPose {
    const TYPE: &'static MessageType = &OBJECT_HYPOTHESIS_WITH_POSE_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.hypothesis.write_fields(w);
        self.pose.write_fields(w);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            hypothesis: ObjectHypothesis::read_fields(r)?,
            pose: PoseWithCovariance::read_fields(r)?,
        })
    }
}

/// `vision_msgs/msg/BoundingBox3D`: centre pose and full size, metres.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BoundingBox3D {
    pub center: Pose,
    pub size: Vector3,
}

pub static BOUNDING_BOX_3D_TYPE: MessageType = MessageType {
    name: "vision_msgs/msg/BoundingBox3D",
    constants: &[],
    fields: &[
        Field::new("center", BaseType::Nested(&POSE_TYPE)),
        Field::new("size", BaseType::Nested(&VECTOR3_TYPE)),
    ],
};

impl RosMessage for BoundingBox3D {
    const TYPE: &'static MessageType = &BOUNDING_BOX_3D_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.center.write_fields(w);
        self.size.write_fields(w);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            center: Pose::read_fields(r)?,
            size: Vector3::read_fields(r)?,
        })
    }
}

/// `vision_msgs/msg/Detection3D`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Detection3D {
    pub header: Header,
    pub results: Vec<ObjectHypothesisWithPose>,
    pub bbox: BoundingBox3D,
    /// Stays the same for one object across messages (may be empty).
    pub id: String,
}

pub static DETECTION_3D_TYPE: MessageType = MessageType {
    name: "vision_msgs/msg/Detection3D",
    constants: &[],
    fields: &[
        Field::new("header", BaseType::Nested(&HEADER_TYPE)),
        Field::sequence(
            "results",
            BaseType::Nested(&OBJECT_HYPOTHESIS_WITH_POSE_TYPE),
        ),
        Field::new("bbox", BaseType::Nested(&BOUNDING_BOX_3D_TYPE)),
        Field::new("id", STRING),
    ],
};

impl RosMessage for Detection3D {
    const TYPE: &'static MessageType = &DETECTION_3D_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.header.write_fields(w);
        w.write_sequence(&self.results, |w, result| result.write_fields(w));
        self.bbox.write_fields(w);
        w.write_string(&self.id);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            results: r.read_sequence(
                "ObjectHypothesisWithPose[]",
                8,
                ObjectHypothesisWithPose::read_fields,
            )?,
            bbox: BoundingBox3D::read_fields(r)?,
            id: r.read_string()?,
        })
    }
}

/// `vision_msgs/msg/Detection3DArray`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Detection3DArray {
    pub header: Header,
    pub detections: Vec<Detection3D>,
}

pub static DETECTION_3D_ARRAY_TYPE: MessageType = MessageType {
    name: "vision_msgs/msg/Detection3DArray",
    constants: &[],
    fields: &[
        Field::new("header", BaseType::Nested(&HEADER_TYPE)),
        Field::sequence("detections", BaseType::Nested(&DETECTION_3D_TYPE)),
    ],
};

impl RosMessage for Detection3DArray {
    const TYPE: &'static MessageType = &DETECTION_3D_ARRAY_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.header.write_fields(w);
        w.write_sequence(&self.detections, |w, detection| detection.write_fields(w));
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            detections: r.read_sequence("Detection3D[]", 8, Detection3D::read_fields)?,
        })
    }
}
