//! The map file of `harvest replay --ros2 --map MAP.toml`: which topics of a bag feed which
//! channel of the stack, and what the messages do not say (the depth-to-colour registration,
//! the LiDAR's integration window).
//!
//! ```toml
//! [camera]                                   # -> camera/rgbd
//! color = "/camera/color/image_raw"          # sensor_msgs/Image or CompressedImage
//! color_info = "/camera/color/camera_info"   # sensor_msgs/CameraInfo
//! depth = "/camera/depth/image_raw"          # sensor_msgs/Image, 16UC1 (mm) or 32FC1 (m)
//! depth_info = "/camera/depth/camera_info"
//! max_stamp_difference_ms = 20.0             # colour and depth paired within this
//! [camera.color_from_depth]                  # default: identity (depth registered to colour)
//! rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
//! translation_m = [0.025, 0.0, 0.0]
//!
//! [lidar]                                    # -> lidar/points
//! points = "/livox/lidar"                    # sensor_msgs/PointCloud2
//! intensity_field = "intensity"              # "" for none
//! integration_ms = 100.0
//! ```

use harvest_ipc::camera_model::RigidTransform;
use harvest_ipc::config_file::{ConfigFileError, parse_toml, read_toml};
use serde::Deserialize;
use std::path::Path;

/// What a map file says.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapFile {
    pub camera: Option<CameraMap>,
    pub lidar: Option<LidarMap>,
}

/// The camera's topics.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraMap {
    pub color: String,
    pub color_info: String,
    pub depth: String,
    pub depth_info: String,
    #[serde(default = "default_max_stamp_difference_ms")]
    pub max_stamp_difference_ms: f64,
    #[serde(default)]
    pub color_from_depth: RigidTransform,
}

fn default_max_stamp_difference_ms() -> f64 {
    20.0
}

/// The LiDAR's topic.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LidarMap {
    pub points: String,
    #[serde(default = "default_intensity_field")]
    pub intensity_field: String,
    #[serde(default)]
    pub integration_ms: f64,
}

fn default_intensity_field() -> String {
    "intensity".to_owned()
}

/// What a mapped topic is used for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    Color,
    ColorInfo,
    Depth,
    DepthInfo,
    LidarPoints,
}

impl Role {
    /// The map key naming the topic of this role.
    pub fn key(self) -> &'static str {
        match self {
            Self::Color => "camera.color",
            Self::ColorInfo => "camera.color_info",
            Self::Depth => "camera.depth",
            Self::DepthInfo => "camera.depth_info",
            Self::LidarPoints => "lidar.points",
        }
    }

    /// The message types this role takes.
    pub fn accepted_types(self) -> &'static [&'static str] {
        match self {
            Self::Color => &["sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"],
            Self::Depth => &["sensor_msgs/msg/Image"],
            Self::ColorInfo | Self::DepthInfo => &["sensor_msgs/msg/CameraInfo"],
            Self::LidarPoints => &["sensor_msgs/msg/PointCloud2"],
        }
    }

    /// [`Self::accepted_types`] as words.
    pub fn accepted_text(self) -> &'static str {
        match self {
            Self::Color => "sensor_msgs/msg/Image or sensor_msgs/msg/CompressedImage",
            Self::Depth => "sensor_msgs/msg/Image",
            Self::ColorInfo | Self::DepthInfo => "sensor_msgs/msg/CameraInfo",
            Self::LidarPoints => "sensor_msgs/msg/PointCloud2",
        }
    }
}

/// A map file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum MapFileError {
    #[error(transparent)]
    File(#[from] ConfigFileError),
    /// A value out of range or a missing section, naming the key.
    #[error("ROS 2 bag map {origin}: {key}: {problem}")]
    Value {
        origin: String,
        key: &'static str,
        problem: String,
    },
}

impl MapFile {
    /// Reads and checks the map file at `path`.
    pub fn read(path: &Path) -> Result<Self, MapFileError> {
        let map: Self = read_toml(path, "ROS 2 bag map")?;
        map.checked(&path.display().to_string())
    }

    /// Parses and checks a map's text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, MapFileError> {
        let map: Self = parse_toml(text, origin, "ROS 2 bag map")?;
        map.checked(origin)
    }

    fn checked(self, origin: &str) -> Result<Self, MapFileError> {
        let problem = |key: &'static str, problem: String| MapFileError::Value {
            origin: origin.to_owned(),
            key,
            problem,
        };
        if self.camera.is_none() && self.lidar.is_none() {
            return Err(problem(
                "camera",
                "the map has neither a [camera] nor a [lidar] section: nothing to replay".into(),
            ));
        }
        if let Some(camera) = &self.camera {
            let tolerance = camera.max_stamp_difference_ms;
            if !(tolerance.is_finite() && tolerance >= 0.0) {
                return Err(problem(
                    "camera.max_stamp_difference_ms",
                    format!("{tolerance} is not a non-negative number"),
                ));
            }
            if !camera.color_from_depth.is_rigid() {
                return Err(problem(
                    "camera.color_from_depth",
                    "not a rigid transform (orthonormal rotation, finite translation)".into(),
                ));
            }
        }
        if let Some(lidar) = &self.lidar {
            let integration = lidar.integration_ms;
            if !(integration.is_finite() && integration >= 0.0) {
                return Err(problem(
                    "lidar.integration_ms",
                    format!("{integration} is not a non-negative number"),
                ));
            }
        }
        let topics = self.topics();
        for (index, (topic, role)) in topics.iter().enumerate() {
            if topic.is_empty() {
                return Err(problem(role.key(), "empty topic name".into()));
            }
            if let Some((_, other)) = topics[..index].iter().find(|(t, _)| t == topic) {
                return Err(problem(
                    role.key(),
                    format!("topic {topic} is also {}", other.key()),
                ));
            }
        }
        Ok(self)
    }

    /// Every mapped topic with its role.
    pub fn topics(&self) -> Vec<(String, Role)> {
        let mut topics = Vec::new();
        if let Some(camera) = &self.camera {
            topics.push((camera.color.clone(), Role::Color));
            topics.push((camera.color_info.clone(), Role::ColorInfo));
            topics.push((camera.depth.clone(), Role::Depth));
            topics.push((camera.depth_info.clone(), Role::DepthInfo));
        }
        if let Some(lidar) = &self.lidar {
            topics.push((lidar.points.clone(), Role::LidarPoints));
        }
        topics
    }

    /// The role of `topic`, if the map uses it.
    pub fn role_of(&self, topic: &str) -> Option<Role> {
        self.topics()
            .into_iter()
            .find(|(name, _)| name == topic)
            .map(|(_, role)| role)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_committed_example_reads() {
        let text = include_str!("../../../docs/ros2/map.example.toml");
        let map = MapFile::parse(text, "map.example.toml").unwrap();
        assert_eq!(map.role_of("/camera/color/image_raw"), Some(Role::Color));
        assert_eq!(map.topics().len(), 5);
    }

    #[test]
    fn errors_name_the_key() {
        let error = MapFile::parse("[camera]\ncolour = \"/c\"\n", "m.toml").unwrap_err();
        assert!(error.to_string().contains("colour"), "{error}");
        let error = MapFile::parse("", "m.toml").unwrap_err();
        assert!(error.to_string().contains("nothing to replay"), "{error}");
        let error = MapFile::parse(
            "[camera]\ncolor = \"/a\"\ncolor_info = \"/a\"\ndepth = \"/d\"\ndepth_info = \"/e\"\n",
            "m.toml",
        )
        .unwrap_err();
        assert!(error.to_string().contains("camera.color_info"), "{error}");
    }
}
