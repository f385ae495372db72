//! `harvest replay BAG --ros2 --map MAP.toml`: the messages of a ROS 2 bag (rosbag2, MCAP
//! storage, CDR) into the stack's channels, as the map file says: colour and depth images and
//! their camera models become `camera/rgbd` frames (paired by stamp), point clouds become
//! `lidar/points`. Frames are assembled straight into samples loaned from the channel's shared
//! memory. A message the stack cannot take (an encoding, a size, a missing field, another type)
//! ends the replay with an error naming its topic and field: a bag that half works would
//! mislead whoever replays it.
//!
//! Stamps: `capture_ns` is the message's `header.stamp` as it is (ROS system time for a bag
//! recorded on a robot), as a native replay keeps the recorded stamps.

use harvest_ipc::catalogue::{CAMERA_RGBD, LIDAR_POINTS};
use harvest_ipc::payloads::rgbd_frame::{
    DEPTH_HEIGHT_PX, DEPTH_WIDTH_PX, RGB_HEIGHT_PX, RGB_WIDTH_PX,
};
use harvest_ipc::payloads::{PointCloud, RgbdFrame};
use harvest_ipc::{Context, Publisher};
use harvest_recording::recording_file::read_summary;
use harvest_ros2::RosMessage;
use harvest_ros2::msgs::sensor_msgs::{CameraInfo, CompressedImage, Image, PointCloud2};
use harvest_ros2_mapping::camera_info::intrinsics;
use harvest_ros2_mapping::frame_assembler::{AssemblyCounts, FrameAssembler};
use harvest_ros2_mapping::from_ros::{
    color_image_into, compressed_color_into, depth_image_into, point_cloud_into,
};
use harvest_ros2_mapping::map_file::{MapFile, Role};
use harvest_ros2_mapping::{FieldError, ImportError};
use std::path::{Path, PathBuf};

/// A bag's messages, mapped into the stack's channels.
pub struct Ros2Input {
    map: MapFile,
    assembler: Option<FrameAssembler>,
    frames: Option<Publisher<RgbdFrame>>,
    clouds: Option<Publisher<PointCloud>>,
    intensity_field: Option<String>,
    integration_ns: u64,
    /// Clouds published on `lidar/points`.
    pub clouds_published: u64,
}

/// What went wrong with a mapped message.
#[derive(Debug, thiserror::Error)]
pub enum Ros2InputError {
    #[error(transparent)]
    Import(#[from] ImportError),
    /// The stack's channel refused the sample.
    #[error("publishing on {topic}: {reason}")]
    Publish { topic: &'static str, reason: String },
}

/// The MCAP files of a bag: a rosbag2 directory's `*.mcap` files in name order, or the file.
pub fn bag_files(paths: &[PathBuf]) -> Result<Vec<PathBuf>, String> {
    let mut files = Vec::new();
    for path in paths {
        if path.is_dir() {
            let mut found: Vec<PathBuf> = std::fs::read_dir(path)
                .map_err(|error| format!("{}: {error}", path.display()))?
                .flatten()
                .map(|entry| entry.path())
                .filter(|file| file.extension().is_some_and(|ext| ext == "mcap"))
                .collect();
            found.sort();
            if found.is_empty() {
                return Err(format!(
                    "{}: a directory without .mcap files (a rosbag2 bag in MCAP storage has one)",
                    path.display()
                ));
            }
            files.extend(found);
        } else {
            files.push(path.clone());
        }
    }
    Ok(files)
}

/// Checks that every topic the map names is in the bag with a type its role takes (when the
/// files have a summary to tell).
pub fn check_bag_topics(map: &MapFile, files: &[PathBuf]) -> Result<(), String> {
    let mut channels: Vec<(String, String)> = Vec::new();
    for file in files {
        let Ok(Some(summary)) = read_summary(file) else {
            return Ok(());
        };
        for channel in summary.channels.values() {
            let schema = channel
                .schema
                .as_ref()
                .map(|schema| schema.name.clone())
                .unwrap_or_default();
            channels.push((channel.topic.clone(), schema));
        }
    }
    for (topic, role) in map.topics() {
        let found: Vec<&(String, String)> = channels.iter().filter(|(t, _)| *t == topic).collect();
        if found.is_empty() {
            let mut names: Vec<&str> = channels.iter().map(|(t, _)| t.as_str()).collect();
            names.sort_unstable();
            names.dedup();
            return Err(format!(
                "the map's {} is {topic}, which the bag does not have (its topics: {})",
                role.key(),
                names.join(", ")
            ));
        }
        for (_, schema) in found {
            if !role.accepted_types().contains(&schema.as_str()) {
                return Err(ImportError::Type {
                    topic: topic.clone(),
                    found: schema.clone(),
                    role: role.key(),
                    expected: role.accepted_text(),
                }
                .to_string());
            }
        }
    }
    Ok(())
}

fn field_error(topic: &str, type_name: &str, source: FieldError) -> ImportError {
    ImportError::Field {
        topic: topic.to_owned(),
        type_name: type_name.to_owned(),
        source,
    }
}

fn decode<T: RosMessage>(topic: &str, data: &[u8]) -> Result<T, ImportError> {
    T::from_cdr(data).map_err(|source| ImportError::Decode {
        topic: topic.to_owned(),
        source,
    })
}

/// The camera model of a `CameraInfo`, which must describe an image of the stack's size.
fn camera_model(
    topic: &str,
    info: &CameraInfo,
    size: (usize, usize),
) -> Result<harvest_ipc::camera_model::CameraIntrinsics, ImportError> {
    let type_name = "sensor_msgs/msg/CameraInfo";
    let model = intrinsics(info).map_err(|error| field_error(topic, type_name, error))?;
    if (model.width_px as usize, model.height_px as usize) != size {
        return Err(field_error(
            topic,
            type_name,
            FieldError::new(
                "width",
                format!(
                    "{} x {} px: the stack's image is {} x {} px",
                    model.width_px, model.height_px, size.0, size.1
                ),
            ),
        ));
    }
    Ok(model)
}

impl Ros2Input {
    /// Opens the publishers of the channels the map feeds.
    pub fn open(
        map: MapFile,
        context: &Context,
    ) -> Result<Self, harvest_ipc::error::OpenChannelError> {
        let (assembler, frames) = match &map.camera {
            Some(camera) => (
                Some(FrameAssembler::new(
                    (camera.max_stamp_difference_ms * 1e6).round() as u64,
                    camera.color_from_depth,
                )),
                Some(context.publisher(CAMERA_RGBD)?),
            ),
            None => (None, None),
        };
        let (clouds, intensity_field, integration_ns) = match &map.lidar {
            Some(lidar) => (
                Some(context.publisher(LIDAR_POINTS)?),
                Some(lidar.intensity_field.clone()).filter(|name| !name.is_empty()),
                (lidar.integration_ms * 1e6).round() as u64,
            ),
            None => (None, None, 0),
        };
        Ok(Self {
            map,
            assembler,
            frames,
            clouds,
            intensity_field,
            integration_ns,
            clouds_published: 0,
        })
    }

    /// How colour and depth were paired so far.
    pub fn frame_counts(&self) -> Option<AssemblyCounts> {
        self.assembler.as_ref().map(FrameAssembler::counts)
    }

    /// True when the map uses `topic`.
    pub fn uses(&self, topic: &str) -> bool {
        self.map.role_of(topic).is_some()
    }

    /// Takes one bag message of a mapped topic; publishes whatever it completes.
    pub fn handle(
        &mut self,
        topic: &str,
        type_name: &str,
        message_encoding: &str,
        data: &[u8],
    ) -> Result<(), Ros2InputError> {
        let Some(role) = self.map.role_of(topic) else {
            return Ok(());
        };
        if message_encoding != "cdr" {
            return Err(ImportError::Encoding {
                topic: topic.to_owned(),
                encoding: message_encoding.to_owned(),
            }
            .into());
        }
        if !role.accepted_types().contains(&type_name) {
            return Err(ImportError::Type {
                topic: topic.to_owned(),
                found: type_name.to_owned(),
                role: role.key(),
                expected: role.accepted_text(),
            }
            .into());
        }
        match role {
            Role::LidarPoints => return self.cloud(topic, data),
            Role::ColorInfo | Role::DepthInfo => {
                let info: CameraInfo = decode(topic, data)?;
                let Some(assembler) = self.assembler.as_mut() else {
                    return Ok(());
                };
                if role == Role::ColorInfo {
                    assembler.set_color_info(camera_model(
                        topic,
                        &info,
                        (RGB_WIDTH_PX, RGB_HEIGHT_PX),
                    )?);
                } else {
                    assembler.set_depth_info(camera_model(
                        topic,
                        &info,
                        (DEPTH_WIDTH_PX, DEPTH_HEIGHT_PX),
                    )?);
                }
                return Ok(());
            }
            Role::Color | Role::Depth => {}
        }
        let Some(assembler) = self.assembler.as_mut() else {
            return Ok(());
        };
        if role == Role::Color {
            let mut rgb = assembler.color_buffer();
            let stamp_ns = if type_name == "sensor_msgs/msg/CompressedImage" {
                let image: CompressedImage = decode(topic, data)?;
                compressed_color_into(&image, &mut rgb)
                    .map_err(|error| field_error(topic, type_name, error))?;
                image.header.stamp.to_ns()
            } else {
                let image: Image = decode(topic, data)?;
                color_image_into(&image, &mut rgb)
                    .map_err(|error| field_error(topic, type_name, error))?;
                image.header.stamp.to_ns()
            };
            assembler.push_color(stamp_ns, rgb);
        } else {
            let image: Image = decode(topic, data)?;
            let mut depth = assembler.depth_buffer();
            depth_image_into(&image, &mut depth)
                .map_err(|error| field_error(topic, type_name, error))?;
            assembler.push_depth(image.header.stamp.to_ns(), depth);
        }
        self.publish_frames()
    }

    fn publish_frames(&mut self) -> Result<(), Ros2InputError> {
        let (Some(assembler), Some(publisher)) = (self.assembler.as_mut(), self.frames.as_mut())
        else {
            return Ok(());
        };
        let topic = CAMERA_RGBD.spec.topic;
        let publish_error = |error: harvest_ipc::error::SendError| Ros2InputError::Publish {
            topic,
            reason: error.to_string(),
        };
        loop {
            let mut loan = publisher.loan().map_err(publish_error)?;
            if !assembler.next_frame(&mut loan) {
                return Ok(());
            }
            publisher.send(loan).map_err(publish_error)?;
        }
    }

    fn cloud(&mut self, topic: &str, data: &[u8]) -> Result<(), Ros2InputError> {
        let Some(publisher) = self.clouds.as_mut() else {
            return Ok(());
        };
        let message: PointCloud2 = decode(topic, data)?;
        let channel = LIDAR_POINTS.spec.topic;
        let publish_error = |error: harvest_ipc::error::SendError| Ros2InputError::Publish {
            topic: channel,
            reason: error.to_string(),
        };
        let mut loan = publisher.loan().map_err(publish_error)?;
        loan.meta.integration_ns = self.integration_ns;
        point_cloud_into(&message, self.intensity_field.as_deref(), &mut loan)
            .map_err(|error| field_error(topic, "sensor_msgs/msg/PointCloud2", error))?;
        loan.header.capture_ns = message.header.stamp.to_ns();
        publisher.send(loan).map_err(publish_error)?;
        self.clouds_published += 1;
        Ok(())
    }
}

/// Reads the map file given with `--map`.
pub fn read_map(path: &Path) -> Result<MapFile, String> {
    MapFile::read(path).map_err(|error| error.to_string())
}
