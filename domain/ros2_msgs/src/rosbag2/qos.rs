//! The QoS profile a topic was offered with, as rosbag2 stores it per topic.

/// The QoS profile of a recorded publisher. `ros2 bag play` offers it again; durations are
/// "infinite" (rmw's default) unless set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QosProfile {
    pub reliable: bool,
    pub transient_local: bool,
    /// `keep_last` depth.
    pub depth: u32,
}

impl QosProfile {
    /// Sensor data (`rclcpp::SensorDataQoS`): best effort, volatile, keep last 5.
    pub const SENSOR_DATA: Self = Self {
        reliable: false,
        transient_local: false,
        depth: 5,
    };
    /// The default of most publishers: reliable, volatile, keep last 10.
    pub const DEFAULT: Self = Self {
        reliable: true,
        transient_local: false,
        depth: 10,
    };

    /// The profile as the indented YAML list item of metadata format 9 (`indent` spaces in
    /// front of each line, `- ` on the first).
    pub fn yaml(&self, indent: usize) -> String {
        // rmw's "infinite" duration.
        const INFINITE: &str = "sec: 9223372036\n  nsec: 854775807";
        let pad = " ".repeat(indent);
        let lines = [
            "history: keep_last".to_owned(),
            format!("depth: {}", self.depth),
            format!(
                "reliability: {}",
                if self.reliable {
                    "reliable"
                } else {
                    "best_effort"
                }
            ),
            format!(
                "durability: {}",
                if self.transient_local {
                    "transient_local"
                } else {
                    "volatile"
                }
            ),
            format!("deadline:\n  {INFINITE}"),
            format!("lifespan:\n  {INFINITE}"),
            "liveliness: automatic".to_owned(),
            format!("liveliness_lease_duration:\n  {INFINITE}"),
            "avoid_ros_namespace_conventions: false".to_owned(),
        ];
        let mut text = String::new();
        for (index, line) in lines.iter().enumerate() {
            for (row, part) in line.split('\n').enumerate() {
                text.push_str(&pad);
                text.push_str(if index == 0 && row == 0 { "- " } else { "  " });
                text.push_str(part);
                text.push('\n');
            }
        }
        text
    }
}
