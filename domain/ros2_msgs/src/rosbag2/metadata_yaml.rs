//! The bag's metadata (`metadata.yaml`, and the `rosbag2` record inside the MCAP file).

use super::METADATA_VERSION;
use super::qos::QosProfile;

/// One topic of the bag and its message count.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicSummary {
    pub name: String,
    /// `package/msg/Type`.
    pub type_name: String,
    /// `RIHS01_...`.
    pub type_hash: String,
    pub qos: QosProfile,
    pub message_count: u64,
}

/// What `metadata.yaml` says about a bag of one MCAP file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagMetadata {
    /// The storage file's name, relative to the bag directory.
    pub file_name: String,
    pub starting_time_ns: u64,
    pub duration_ns: u64,
    pub topics: Vec<TopicSummary>,
    /// Free key-value pairs (`custom_data`).
    pub custom_data: Vec<(String, String)>,
    /// `ros_distro` field: who wrote the bag.
    pub ros_distro: String,
}

/// A YAML double-quoted scalar.
fn quoted(text: &str) -> String {
    let mut out = String::from("\"");
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\x{:02x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

impl BagMetadata {
    pub fn message_count(&self) -> u64 {
        self.topics.iter().map(|topic| topic.message_count).sum()
    }

    /// The `rosbag2_bagfile_information` mapping's body, indented by `indent` spaces.
    fn body(&self, indent: usize) -> String {
        let pad = " ".repeat(indent);
        let mut y = String::new();
        let mut line = |depth: usize, text: &str| {
            y.push_str(&pad);
            y.push_str(&" ".repeat(depth));
            y.push_str(text);
            y.push('\n');
        };
        line(0, &format!("version: {METADATA_VERSION}"));
        line(0, "storage_identifier: mcap");
        line(0, "duration:");
        line(2, &format!("nanoseconds: {}", self.duration_ns));
        line(0, "starting_time:");
        line(
            2,
            &format!("nanoseconds_since_epoch: {}", self.starting_time_ns),
        );
        line(0, &format!("message_count: {}", self.message_count()));
        line(0, "topics_with_message_count:");
        for topic in &self.topics {
            line(2, "- topic_metadata:");
            line(6, &format!("name: {}", quoted(&topic.name)));
            line(6, &format!("type: {}", quoted(&topic.type_name)));
            line(6, "serialization_format: cdr");
            line(6, "offered_qos_profiles:");
            for qos_line in topic.qos.yaml(8).lines() {
                line(0, qos_line);
            }
            line(6, &format!("type_description_hash: {}", topic.type_hash));
            line(4, &format!("message_count: {}", topic.message_count));
        }
        line(0, "compression_format: \"\"");
        line(0, "compression_mode: \"\"");
        line(0, "relative_file_paths:");
        line(2, &format!("- {}", quoted(&self.file_name)));
        line(0, "files:");
        line(2, &format!("- path: {}", quoted(&self.file_name)));
        line(4, "starting_time:");
        line(
            6,
            &format!("nanoseconds_since_epoch: {}", self.starting_time_ns),
        );
        line(4, "duration:");
        line(6, &format!("nanoseconds: {}", self.duration_ns));
        line(4, &format!("message_count: {}", self.message_count()));
        if self.custom_data.is_empty() {
            line(0, "custom_data: ~");
        } else {
            line(0, "custom_data:");
            for (key, value) in &self.custom_data {
                line(2, &format!("{}: {}", quoted(key), quoted(value)));
            }
        }
        line(0, &format!("ros_distro: {}", quoted(&self.ros_distro)));
        y
    }

    /// `metadata.yaml`.
    pub fn metadata_yaml(&self) -> String {
        format!("rosbag2_bagfile_information:\n{}", self.body(2))
    }

    /// The `serialized_metadata` value of the MCAP file's `rosbag2` record (the same mapping
    /// without the top-level key).
    pub fn serialized_metadata(&self) -> String {
        self.body(0)
    }
}
