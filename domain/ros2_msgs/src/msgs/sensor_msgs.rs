//! `sensor_msgs`: images, camera calibration, point clouds, joint states.

use super::std_msgs::{HEADER_TYPE, Header};
use crate::cdr::{CdrError, CdrReader, CdrWriter};
use crate::message::RosMessage;
use crate::type_description::{BaseType, Constant, Field, MessageType, STRING};

/// `sensor_msgs/msg/Image`: an uncompressed image, rows `step` bytes apart.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Image {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    /// `rgb8`, `bgr8`, `mono8`, `16UC1`, `32FC1`, `bayer_rggb8`, ... (`sensor_msgs/image_encodings.hpp`).
    pub encoding: String,
    pub is_bigendian: u8,
    pub step: u32,
    pub data: Vec<u8>,
}

pub static IMAGE_TYPE: MessageType = MessageType {
    name: "sensor_msgs/msg/Image",
    constants: &[],
    fields: &[
        Field::new("header", BaseType::Nested(&HEADER_TYPE)),
        Field::new("height", BaseType::Uint32),
        Field::new("width", BaseType::Uint32),
        Field::new("encoding", STRING),
        Field::new("is_bigendian", BaseType::Uint8),
        Field::new("step", BaseType::Uint32),
        Field::sequence("data", BaseType::Uint8),
    ],
};

impl RosMessage for Image {
    const TYPE: &'static MessageType = &IMAGE_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.header.write_fields(w);
        w.write_u32(self.height);
        w.write_u32(self.width);
        w.write_string(&self.encoding);
        w.write_u8(self.is_bigendian);
        w.write_u32(self.step);
        w.write_byte_sequence(&self.data);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            height: r.read_u32()?,
            width: r.read_u32()?,
            encoding: r.read_string()?,
            is_bigendian: r.read_u8()?,
            step: r.read_u32()?,
            data: r.read_byte_sequence()?.to_vec(),
        })
    }
}

/// `sensor_msgs/msg/CompressedImage`: `format` is `jpeg`, `png`, or image_transport's
/// `rgb8; jpeg compressed bgr8` form.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CompressedImage {
    pub header: Header,
    pub format: String,
    pub data: Vec<u8>,
}

pub static COMPRESSED_IMAGE_TYPE: MessageType = MessageType {
    name: "sensor_msgs/msg/CompressedImage",
    constants: &[],
    fields: &[
        Field::new("header", BaseType::Nested(&HEADER_TYPE)),
        Field::new("format", STRING),
        Field::sequence("data", BaseType::Uint8),
    ],
};

impl RosMessage for CompressedImage {
    const TYPE: &'static MessageType = &COMPRESSED_IMAGE_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.header.write_fields(w);
        w.write_string(&self.format);
        w.write_byte_sequence(&self.data);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            format: r.read_string()?,
            data: r.read_byte_sequence()?.to_vec(),
        })
    }
}

/// `sensor_msgs/msg/RegionOfInterest`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RegionOfInterest {
    pub x_offset: u32,
    pub y_offset: u32,
    pub height: u32,
    pub width: u32,
    pub do_rectify: bool,
}

pub static REGION_OF_INTEREST_TYPE: MessageType = MessageType {
    name: "sensor_msgs/msg/RegionOfInterest",
    constants: &[],
    fields: &[
        Field::new("x_offset", BaseType::Uint32),
        Field::new("y_offset", BaseType::Uint32),
        Field::new("height", BaseType::Uint32),
        Field::new("width", BaseType::Uint32),
        Field::new("do_rectify", BaseType::Bool),
    ],
};

impl RosMessage for RegionOfInterest {
    const TYPE: &'static MessageType = &REGION_OF_INTEREST_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_u32(self.x_offset);
        w.write_u32(self.y_offset);
        w.write_u32(self.height);
        w.write_u32(self.width);
        w.write_bool(self.do_rectify);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            x_offset: r.read_u32()?,
            y_offset: r.read_u32()?,
            height: r.read_u32()?,
            width: r.read_u32()?,
            do_rectify: r.read_bool()?,
        })
    }
}

/// `sensor_msgs/msg/CameraInfo`: the pinhole model (`k`, row-major 3x3), distortion `d` in
/// the order of `distortion_model` (`plumb_bob`: k1, k2, t1, t2, k3), rectification `r` and
/// projection `p` (3x4).
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfo {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub distortion_model: String,
    pub d: Vec<f64>,
    pub k: [f64; 9],
    pub r: [f64; 9],
    pub p: [f64; 12],
    pub binning_x: u32,
    pub binning_y: u32,
    pub roi: RegionOfInterest,
}

impl Default for CameraInfo {
    fn default() -> Self {
        Self {
            header: Header::default(),
            height: 0,
            width: 0,
            distortion_model: String::new(),
            d: Vec::new(),
            k: [0.0; 9],
            r: [0.0; 9],
            p: [0.0; 12],
            binning_x: 0,
            binning_y: 0,
            roi: RegionOfInterest::default(),
        }
    }
}

pub static CAMERA_INFO_TYPE: MessageType = MessageType {
    name: "sensor_msgs/msg/CameraInfo",
    constants: &[],
    fields: &[
        Field::new("header", BaseType::Nested(&HEADER_TYPE)),
        Field::new("height", BaseType::Uint32),
        Field::new("width", BaseType::Uint32),
        Field::new("distortion_model", STRING),
        Field::sequence("d", BaseType::Float64),
        Field::array("k", BaseType::Float64, 9),
        Field::array("r", BaseType::Float64, 9),
        Field::array("p", BaseType::Float64, 12),
        Field::new("binning_x", BaseType::Uint32),
        Field::new("binning_y", BaseType::Uint32),
        Field::new("roi", BaseType::Nested(&REGION_OF_INTEREST_TYPE)),
    ],
};

impl RosMessage for CameraInfo {
    const TYPE: &'static MessageType = &CAMERA_INFO_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.header.write_fields(w);
        w.write_u32(self.height);
        w.write_u32(self.width);
        w.write_string(&self.distortion_model);
        w.write_f64_sequence(&self.d);
        w.write_f64_array(&self.k);
        w.write_f64_array(&self.r);
        w.write_f64_array(&self.p);
        w.write_u32(self.binning_x);
        w.write_u32(self.binning_y);
        self.roi.write_fields(w);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            height: r.read_u32()?,
            width: r.read_u32()?,
            distortion_model: r.read_string()?,
            d: r.read_f64_sequence()?,
            k: r.read_f64_array()?,
            r: r.read_f64_array()?,
            p: r.read_f64_array()?,
            binning_x: r.read_u32()?,
            binning_y: r.read_u32()?,
            roi: RegionOfInterest::read_fields(r)?,
        })
    }
}

/// `sensor_msgs/msg/PointField`: one field of a [`PointCloud2`] point.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PointField {
    pub name: String,
    /// Byte offset in the point.
    pub offset: u32,
    /// One of the `PointField::INT8` ... `FLOAT64` codes.
    pub datatype: u8,
    /// Elements in the field (1 for a scalar).
    pub count: u32,
}

impl PointField {
    pub const INT8: u8 = 1;
    pub const UINT8: u8 = 2;
    pub const INT16: u8 = 3;
    pub const UINT16: u8 = 4;
    pub const INT32: u8 = 5;
    pub const UINT32: u8 = 6;
    pub const FLOAT32: u8 = 7;
    pub const FLOAT64: u8 = 8;

    /// Bytes of one element of `datatype`; `None` for an unknown code.
    pub fn datatype_bytes(datatype: u8) -> Option<u32> {
        match datatype {
            Self::INT8 | Self::UINT8 => Some(1),
            Self::INT16 | Self::UINT16 => Some(2),
            Self::INT32 | Self::UINT32 | Self::FLOAT32 => Some(4),
            Self::FLOAT64 => Some(8),
            _ => None,
        }
    }

    /// A scalar field.
    pub fn scalar(name: &str, offset: u32, datatype: u8) -> Self {
        Self {
            name: name.to_owned(),
            offset,
            datatype,
            count: 1,
        }
    }
}

const fn datatype_constant(name: &'static str, value: &'static str) -> Constant {
    Constant {
        name,
        base: BaseType::Uint8,
        value,
    }
}

pub static POINT_FIELD_TYPE: MessageType = MessageType {
    name: "sensor_msgs/msg/PointField",
    constants: &[
        datatype_constant("INT8", "1"),
        datatype_constant("UINT8", "2"),
        datatype_constant("INT16", "3"),
        datatype_constant("UINT16", "4"),
        datatype_constant("INT32", "5"),
        datatype_constant("UINT32", "6"),
        datatype_constant("FLOAT32", "7"),
        datatype_constant("FLOAT64", "8"),
    ],
    fields: &[
        Field::new("name", STRING),
        Field::new("offset", BaseType::Uint32),
        Field::new("datatype", BaseType::Uint8),
        Field::new("count", BaseType::Uint32),
    ],
};

impl RosMessage for PointField {
    const TYPE: &'static MessageType = &POINT_FIELD_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_string(&self.name);
        w.write_u32(self.offset);
        w.write_u8(self.datatype);
        w.write_u32(self.count);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            name: r.read_string()?,
            offset: r.read_u32()?,
            datatype: r.read_u8()?,
            count: r.read_u32()?,
        })
    }
}

/// `sensor_msgs/msg/PointCloud2`: `height` x `width` points of `point_step` bytes laid out as
/// `fields` say.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PointCloud2 {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub fields: Vec<PointField>,
    pub is_bigendian: bool,
    pub point_step: u32,
    pub row_step: u32,
    pub data: Vec<u8>,
    pub is_dense: bool,
}

pub static POINT_CLOUD2_TYPE: MessageType = MessageType {
    name: "sensor_msgs/msg/PointCloud2",
    constants: &[],
    fields: &[
        Field::new("header", BaseType::Nested(&HEADER_TYPE)),
        Field::new("height", BaseType::Uint32),
        Field::new("width", BaseType::Uint32),
        Field::sequence("fields", BaseType::Nested(&POINT_FIELD_TYPE)),
        Field::new("is_bigendian", BaseType::Bool),
        Field::new("point_step", BaseType::Uint32),
        Field::new("row_step", BaseType::Uint32),
        Field::sequence("data", BaseType::Uint8),
        Field::new("is_dense", BaseType::Bool),
    ],
};

impl RosMessage for PointCloud2 {
    const TYPE: &'static MessageType = &POINT_CLOUD2_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.header.write_fields(w);
        w.write_u32(self.height);
        w.write_u32(self.width);
        w.write_sequence(&self.fields, |w, field| field.write_fields(w));
        w.write_bool(self.is_bigendian);
        w.write_u32(self.point_step);
        w.write_u32(self.row_step);
        w.write_byte_sequence(&self.data);
        w.write_bool(self.is_dense);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            height: r.read_u32()?,
            width: r.read_u32()?,
            fields: r.read_sequence("PointField[]", 13, PointField::read_fields)?,
            is_bigendian: r.read_bool()?,
            point_step: r.read_u32()?,
            row_step: r.read_u32()?,
            data: r.read_byte_sequence()?.to_vec(),
            is_dense: r.read_bool()?,
        })
    }
}

/// `sensor_msgs/msg/JointState`: per named joint, position (rad or m), velocity, effort; the
/// arrays may be empty.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointState {
    pub header: Header,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}

pub static JOINT_STATE_TYPE: MessageType = MessageType {
    name: "sensor_msgs/msg/JointState",
    constants: &[],
    fields: &[
        Field::new("header", BaseType::Nested(&HEADER_TYPE)),
        Field::sequence("name", STRING),
        Field::sequence("position", BaseType::Float64),
        Field::sequence("velocity", BaseType::Float64),
        Field::sequence("effort", BaseType::Float64),
    ],
};

impl RosMessage for JointState {
    const TYPE: &'static MessageType = &JOINT_STATE_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.header.write_fields(w);
        w.write_string_sequence(&self.name);
        w.write_f64_sequence(&self.position);
        w.write_f64_sequence(&self.velocity);
        w.write_f64_sequence(&self.effort);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            name: r.read_string_sequence()?,
            position: r.read_f64_sequence()?,
            velocity: r.read_f64_sequence()?,
            effort: r.read_f64_sequence()?,
        })
    }
}
