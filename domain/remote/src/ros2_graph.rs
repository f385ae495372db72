//! The robot as a ROS 2 node over rmw_zenoh (Jazzy and later): the key expressions its topics
//! are published on, the liveliness tokens by which `ros2 node list` / `ros2 topic list` learn
//! of the node and its publishers and subscriptions, and the attachment every sample carries.
//! Formats as rmw_zenoh's design documents and its `liveliness_utils` write them:
//!
//! - a topic's data: `<domain_id>/<fully qualified name without the leading slash>/<DDS type
//!   name>/<RIHS01 type hash>`, e.g. `0/r1/arm1/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13e...`;
//! - a liveliness token: `@ros2_lv/<domain_id>/<session id>/<node id>/<entity id>/<NN|MP|MS>/
//!   <enclave>/<namespace>/<node name>[/<topic>/<type>/<hash>/<qos>]`, every name with its `/`
//!   written `%` (so the empty namespace `/` is `%`);
//! - the attachment: the sample's sequence number (i64), its source timestamp (i64, ns since the
//!   epoch) and the publisher's 16-byte GID as a length-prefixed byte sequence: 33 bytes, little
//!   endian (Zenoh's serialization of `i64, i64, Vec<u8>`).
//!
//! The payload is the message's CDR with its 4-byte encapsulation header
//! ([`harvest_ros2::RosMessage::to_cdr`]). The GID is the first 16 bytes of the SHA-256 of the
//! entity's token (rmw_zenoh hashes the token with XXH3; a GID only has to be unique and
//! stable, and no peer recomputes ours).

use harvest_ros2::type_description::MessageType;
use sha2::Digest;

use crate::robot_name::RobotName;

/// Where ROS 2 liveliness tokens live.
pub const ADMIN_SPACE: &str = "@ros2_lv";
/// The node every robot's link appears as, in the robot's namespace (`/r1/harvest_remote`).
pub const NODE_NAME: &str = "harvest_remote";
/// The publishers' and subscriptions' QoS in a token: reliable (1), volatile (2), keep last (1)
/// 10 deep; deadline, lifespan and liveliness left at their defaults (empty).
pub const QOS: &str = "1:2:1,10:,:,:,,";
/// Bytes of an attachment.
pub const ATTACHMENT_BYTES: usize = 33;

/// A name with its slashes written `%`, as a key expression's chunk.
fn mangle(name: &str) -> String {
    name.replace('/', "%")
}

/// The robot's ROS 2 node on one session.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ros2Node {
    domain_id: u32,
    session_id: String,
    namespace: String,
    node_id: u32,
}

/// One topic of the node, with its data key.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ros2Topic {
    /// Fully qualified (`/r1/arm1/joint_states`).
    pub name: String,
    /// The DDS type name (`sensor_msgs::msg::dds_::JointState_`).
    pub type_name: String,
    /// `RIHS01_<sha-256>`.
    pub type_hash: String,
    /// Where its samples are put.
    pub key: String,
}

/// Publisher or subscription.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Endpoint {
    Publisher,
    Subscription,
}

impl Ros2Node {
    /// The node of `robot` (namespace `/<robot>`) in ROS domain `domain_id`, on the Zenoh
    /// session whose id is `session_id` (its text form).
    pub fn new(domain_id: u32, session_id: &str, robot: &RobotName) -> Self {
        Self {
            domain_id,
            session_id: session_id.to_owned(),
            namespace: format!("/{robot}"),
            node_id: 0,
        }
    }

    pub fn namespace(&self) -> &str {
        &self.namespace
    }

    fn token_prefix(&self, entity_id: u32, kind: &str) -> String {
        format!(
            "{ADMIN_SPACE}/{}/{}/{}/{entity_id}/{kind}/{}/{}/{NODE_NAME}",
            self.domain_id,
            self.session_id,
            self.node_id,
            mangle("/"),
            mangle(&self.namespace),
        )
    }

    /// The node's liveliness token (`NN`).
    pub fn node_token(&self) -> String {
        self.token_prefix(self.node_id, "NN")
    }

    /// `relative` (`arm1/joint_states`) in the robot's namespace, of type `message`.
    pub fn topic(&self, relative: &str, message: &MessageType) -> Ros2Topic {
        let name = format!("{}/{}", self.namespace, relative.trim_matches('/'));
        let type_name = message.dds_name();
        let type_hash = message.type_hash();
        let key = format!(
            "{}/{}/{type_name}/{type_hash}",
            self.domain_id,
            name.trim_matches('/')
        );
        Ros2Topic {
            name,
            type_name,
            type_hash,
            key,
        }
    }

    /// The liveliness token of a publisher (`MP`) or subscription (`MS`) of `topic`, entity
    /// `entity_id` (unique within the node, not the node's own id).
    pub fn endpoint_token(&self, topic: &Ros2Topic, endpoint: Endpoint, entity_id: u32) -> String {
        let kind = match endpoint {
            Endpoint::Publisher => "MP",
            Endpoint::Subscription => "MS",
        };
        format!(
            "{}/{}/{}/{}/{QOS}",
            self.token_prefix(entity_id, kind),
            mangle(&topic.name),
            mangle(&topic.type_name),
            mangle(&topic.type_hash),
        )
    }
}

impl Ros2Topic {
    /// The topic's key with any type hash: what a subscription of ours listens on, so that a
    /// peer built against another revision of the type is still heard (its CDR is checked).
    pub fn key_any_hash(&self) -> String {
        match self.key.rsplit_once('/') {
            Some((head, _)) => format!("{head}/*"),
            None => self.key.clone(),
        }
    }
}

/// An entity's GID: the first 16 bytes of the SHA-256 of its liveliness token.
pub fn gid(token: &str) -> [u8; 16] {
    let digest = sha2::Sha256::digest(token.as_bytes());
    let mut gid = [0u8; 16];
    gid.copy_from_slice(&digest[..16]);
    gid
}

/// A sample's attachment (module documentation).
pub fn attachment(
    sequence: i64,
    source_timestamp_ns: i64,
    gid: &[u8; 16],
) -> [u8; ATTACHMENT_BYTES] {
    let mut bytes = [0u8; ATTACHMENT_BYTES];
    bytes[..8].copy_from_slice(&sequence.to_le_bytes());
    bytes[8..16].copy_from_slice(&source_timestamp_ns.to_le_bytes());
    bytes[16] = 16;
    bytes[17..].copy_from_slice(gid);
    bytes
}

/// The sequence number, source timestamp and GID of an attachment, if it has the layout.
pub fn read_attachment(bytes: &[u8]) -> Option<(i64, i64, [u8; 16])> {
    if bytes.len() != ATTACHMENT_BYTES || bytes[16] != 16 {
        return None;
    }
    let sequence = i64::from_le_bytes(bytes[..8].try_into().ok()?);
    let stamp = i64::from_le_bytes(bytes[8..16].try_into().ok()?);
    Some((sequence, stamp, bytes[17..].try_into().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ros2::msgs::{sensor_msgs, std_msgs};

    fn node() -> Ros2Node {
        Ros2Node::new(0, "8f3a2c", &RobotName::parse("r1").expect("name"))
    }

    #[test]
    fn topic_keys_are_domain_name_type_and_hash() {
        let topic = node().topic("arm1/joint_states", &sensor_msgs::JOINT_STATE_TYPE);
        assert_eq!(topic.name, "/r1/arm1/joint_states");
        assert_eq!(
            topic.key,
            "0/r1/arm1/joint_states/sensor_msgs::msg::dds_::JointState_/\
             RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
        );
        assert_eq!(
            node()
                .topic("/emergency_stop", &std_msgs::BOOL_TYPE)
                .key_any_hash(),
            "0/r1/emergency_stop/std_msgs::msg::dds_::Bool_/*"
        );
    }

    #[test]
    fn tokens_name_the_node_and_its_endpoints_with_slashes_mangled() {
        let node = node();
        assert_eq!(
            node.node_token(),
            "@ros2_lv/0/8f3a2c/0/0/NN/%/%r1/harvest_remote"
        );
        let topic = node.topic("emergency_stop", &std_msgs::BOOL_TYPE);
        assert_eq!(
            node.endpoint_token(&topic, Endpoint::Subscription, 7),
            "@ros2_lv/0/8f3a2c/0/7/MS/%/%r1/harvest_remote/%r1%emergency_stop/\
             std_msgs::msg::dds_::Bool_/\
             RIHS01_feb91e995ff9ebd09c0cb3d2aed18b11077585839fb5db80193b62d74528f6c9/1:2:1,10:,:,:,,"
        );
        // Six QoS components, as rmw_zenoh's parser requires.
        assert_eq!(QOS.split(':').count(), 6);
    }

    #[test]
    fn the_attachment_is_33_bytes_and_reads_back() {
        let gid = gid("@ros2_lv/0/8f3a2c/0/1/MP");
        let bytes = attachment(42, 1_700_000_000_123_456_789, &gid);
        assert_eq!(bytes.len(), 33);
        assert_eq!(&bytes[..8], &42i64.to_le_bytes());
        assert_eq!(bytes[16], 16);
        assert_eq!(
            read_attachment(&bytes),
            Some((42, 1_700_000_000_123_456_789, gid))
        );
        assert_eq!(read_attachment(&bytes[..32]), None);
        assert_ne!(gid, super::gid("@ros2_lv/0/8f3a2c/0/2/MP"));
    }
}
