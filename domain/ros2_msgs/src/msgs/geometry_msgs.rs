//! `geometry_msgs`: the poses the detection types carry.

use crate::cdr::{CdrError, CdrReader, CdrWriter};
use crate::message::RosMessage;
use crate::type_description::{BaseType, Field, MessageType};

/// `geometry_msgs/msg/Point`, metres.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/msg/Vector3`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion` (identity by default, as in the `.msg` file).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pose {
    pub position: Point,
    pub orientation: Quaternion,
}

/// `geometry_msgs/msg/PoseWithCovariance`: row-major 6x6 covariance of (x, y, z, rot x, rot y,
/// rot z).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseWithCovariance {
    pub pose: Pose,
    pub covariance: [f64; 36],
}

impl Default for PoseWithCovariance {
    fn default() -> Self {
        Self {
            pose: Pose::default(),
            covariance: [0.0; 36],
        }
    }
}

const XYZ: &[Field] = &[
    Field::new("x", BaseType::Float64),
    Field::new("y", BaseType::Float64),
    Field::new("z", BaseType::Float64),
];

pub static POINT_TYPE: MessageType = MessageType {
    name: "geometry_msgs/msg/Point",
    constants: &[],
    fields: XYZ,
};

pub static VECTOR3_TYPE: MessageType = MessageType {
    name: "geometry_msgs/msg/Vector3",
    constants: &[],
    fields: XYZ,
};

pub static QUATERNION_TYPE: MessageType = MessageType {
    name: "geometry_msgs/msg/Quaternion",
    constants: &[],
    fields: &[
        Field::new("x", BaseType::Float64).with_default("0"),
        Field::new("y", BaseType::Float64).with_default("0"),
        Field::new("z", BaseType::Float64).with_default("0"),
        Field::new("w", BaseType::Float64).with_default("1"),
    ],
};

pub static POSE_TYPE: MessageType = MessageType {
    name: "geometry_msgs/msg/Pose",
    constants: &[],
    fields: &[
        Field::new("position", BaseType::Nested(&POINT_TYPE)),
        Field::new("orientation", BaseType::Nested(&QUATERNION_TYPE)),
    ],
};

pub static POSE_WITH_COVARIANCE_TYPE: MessageType = MessageType {
    name: "geometry_msgs/msg/PoseWithCovariance",
    constants: &[],
    fields: &[
        Field::new("pose", BaseType::Nested(&POSE_TYPE)),
        Field::array("covariance", BaseType::Float64, 36),
    ],
};

impl RosMessage for Point {
    const TYPE: &'static MessageType = &POINT_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_f64_array(&[self.x, self.y, self.z]);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let [x, y, z] = r.read_f64_array()?;
        Ok(Self { x, y, z })
    }
}

impl RosMessage for Vector3 {
    const TYPE: &'static MessageType = &VECTOR3_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_f64_array(&[self.x, self.y, self.z]);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let [x, y, z] = r.read_f64_array()?;
        Ok(Self { x, y, z })
    }
}

impl RosMessage for Quaternion {
    const TYPE: &'static MessageType = &QUATERNION_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_f64_array(&[self.x, self.y, self.z, self.w]);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let [x, y, z, w] = r.read_f64_array()?;
        Ok(Self { x, y, z, w })
    }
}

impl RosMessage for Pose {
    const TYPE: &'static MessageType = &POSE_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.position.write_fields(w);
        self.orientation.write_fields(w);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            position: Point::read_fields(r)?,
            orientation: Quaternion::read_fields(r)?,
        })
    }
}

impl RosMessage for PoseWithCovariance {
    const TYPE: &'static MessageType = &POSE_WITH_COVARIANCE_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.pose.write_fields(w);
        w.write_f64_array(&self.covariance);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            pose: Pose::read_fields(r)?,
            covariance: r.read_f64_array()?,
        })
    }
}
