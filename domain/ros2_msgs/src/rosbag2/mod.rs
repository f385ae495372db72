//! rosbag2 bags in MCAP storage, as `ros2 bag record -s mcap` writes them: a directory holding
//! `metadata.yaml` and `<name>_0.mcap` (profile `ros2`; per topic a schema named
//! `package/msg/Type`, encoding `ros2msg`, the full definition text as data; a channel with
//! message encoding `cdr` and the metadata `offered_qos_profiles` and `topic_type_hash`; a
//! `rosbag2` metadata record holding the bag's metadata as YAML in `serialized_metadata`).

mod metadata_yaml;
mod qos;
mod writer;

pub use metadata_yaml::{BagMetadata, TopicSummary};
pub use qos::QosProfile;
pub use writer::{BagWriter, BagWriterError, TopicId};

/// Version of the rosbag2 metadata format written (Jazzy's).
pub const METADATA_VERSION: u32 = 9;
