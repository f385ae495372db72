//! Writing a rosbag2 bag (MCAP storage).

use super::metadata_yaml::{BagMetadata, TopicSummary};
use super::qos::QosProfile;
use crate::type_description::MessageType;
use mcap::records::{MessageHeader, Metadata};
use mcap::{McapError, WriteOptions, Writer};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// A topic of the bag being written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TopicId(usize);

/// The bag could not be written.
#[derive(Debug, thiserror::Error)]
pub enum BagWriterError {
    /// The bag directory exists already (rosbag2 never writes into an existing bag).
    #[error("{0} exists already: a bag is a new directory")]
    Exists(PathBuf),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: MCAP: {source}")]
    Mcap { path: PathBuf, source: McapError },
    /// The same topic name was added twice.
    #[error("topic {0} added twice")]
    DuplicateTopic(String),
}

struct Topic {
    summary: TopicSummary,
    channel_id: u16,
}

/// Writes one bag directory: `<dir>/metadata.yaml` and `<dir>/<dir name>_0.mcap`.
pub struct BagWriter {
    dir: PathBuf,
    mcap_path: PathBuf,
    file_name: String,
    writer: Writer<BufWriter<File>>,
    topics: Vec<Topic>,
    schemas: BTreeMap<&'static str, u16>,
    first_ns: Option<u64>,
    last_ns: u64,
    custom_data: Vec<(String, String)>,
    ros_distro: String,
}

impl BagWriter {
    /// Creates the bag directory `dir` (which must not exist) and its MCAP file; `library`
    /// names the writing software in the MCAP header and the metadata's `ros_distro`.
    pub fn create(dir: &Path, library: &str) -> Result<Self, BagWriterError> {
        if dir.exists() {
            return Err(BagWriterError::Exists(dir.to_owned()));
        }
        let io = |source| BagWriterError::Io {
            path: dir.to_owned(),
            source,
        };
        std::fs::create_dir_all(dir).map_err(io)?;
        let stem = dir
            .file_name()
            .map(|name| name.to_string_lossy().into_owned())
            .unwrap_or_else(|| "bag".to_owned());
        let file_name = format!("{stem}_0.mcap");
        let mcap_path = dir.join(&file_name);
        let file = File::create(&mcap_path).map_err(|source| BagWriterError::Io {
            path: mcap_path.clone(),
            source,
        })?;
        let options = WriteOptions::new()
            .profile("ros2")
            .library(library)
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(1)
            .compression_threads(0)
            .chunk_size(Some(4 << 20));
        let writer = Writer::with_options(BufWriter::with_capacity(1 << 20, file), options)
            .map_err(|source| BagWriterError::Mcap {
                path: mcap_path.clone(),
                source,
            })?;
        Ok(Self {
            dir: dir.to_owned(),
            mcap_path,
            file_name,
            writer,
            topics: Vec::new(),
            schemas: BTreeMap::new(),
            first_ns: None,
            last_ns: 0,
            custom_data: Vec::new(),
            ros_distro: library.to_owned(),
        })
    }

    fn mcap_error(&self, source: McapError) -> BagWriterError {
        BagWriterError::Mcap {
            path: self.mcap_path.clone(),
            source,
        }
    }

    /// Adds a topic of messages of `ty`, offered with `qos`.
    pub fn add_topic(
        &mut self,
        name: &str,
        ty: &'static MessageType,
        qos: QosProfile,
    ) -> Result<TopicId, BagWriterError> {
        if self.topics.iter().any(|topic| topic.summary.name == name) {
            return Err(BagWriterError::DuplicateTopic(name.to_owned()));
        }
        let schema_id = match self.schemas.get(ty.name) {
            Some(id) => *id,
            None => {
                let id = self
                    .writer
                    .add_schema(ty.name, "ros2msg", ty.definition().as_bytes())
                    .map_err(|error| self.mcap_error(error))?;
                self.schemas.insert(ty.name, id);
                id
            }
        };
        let type_hash = ty.type_hash();
        let metadata = BTreeMap::from([
            ("offered_qos_profiles".to_owned(), qos.yaml(0)),
            ("topic_type_hash".to_owned(), type_hash.clone()),
        ]);
        let channel_id = self
            .writer
            .add_channel(schema_id, name, "cdr", &metadata)
            .map_err(|error| self.mcap_error(error))?;
        self.topics.push(Topic {
            summary: TopicSummary {
                name: name.to_owned(),
                type_name: ty.name.to_owned(),
                type_hash,
                qos,
                message_count: 0,
            },
            channel_id,
        });
        Ok(TopicId(self.topics.len() - 1))
    }

    /// Writes one serialized message received at `log_time_ns` (Unix-epoch ns, as rosbag2's
    /// receive time).
    pub fn write(
        &mut self,
        topic: TopicId,
        log_time_ns: u64,
        cdr: &[u8],
    ) -> Result<(), BagWriterError> {
        let Some(entry) = self.topics.get_mut(topic.0) else {
            return Err(BagWriterError::DuplicateTopic(format!("#{}", topic.0)));
        };
        let sequence = u32::try_from(entry.summary.message_count).unwrap_or(u32::MAX);
        entry.summary.message_count += 1;
        let header = MessageHeader {
            channel_id: entry.channel_id,
            sequence,
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        self.writer
            .write_to_known_channel(&header, cdr)
            .map_err(|error| self.mcap_error(error))?;
        self.first_ns = Some(self.first_ns.map_or(log_time_ns, |ns| ns.min(log_time_ns)));
        self.last_ns = self.last_ns.max(log_time_ns);
        Ok(())
    }

    /// Adds a `custom_data` entry to the metadata.
    pub fn add_custom_data(&mut self, key: &str, value: &str) {
        self.custom_data.push((key.to_owned(), value.to_owned()));
    }

    /// The metadata as it stands.
    pub fn metadata(&self) -> BagMetadata {
        let start = self.first_ns.unwrap_or(0);
        BagMetadata {
            file_name: self.file_name.clone(),
            starting_time_ns: start,
            duration_ns: self.last_ns.saturating_sub(start),
            topics: self
                .topics
                .iter()
                .map(|topic| topic.summary.clone())
                .collect(),
            custom_data: self.custom_data.clone(),
            ros_distro: self.ros_distro.clone(),
        }
    }

    /// Writes the `rosbag2` record, ends the MCAP file and writes `metadata.yaml`.
    pub fn finish(mut self) -> Result<BagMetadata, BagWriterError> {
        let metadata = self.metadata();
        let record = Metadata {
            name: "rosbag2".to_owned(),
            metadata: BTreeMap::from([(
                "serialized_metadata".to_owned(),
                metadata.serialized_metadata(),
            )]),
        };
        self.writer
            .write_metadata(&record)
            .map_err(|error| self.mcap_error(error))?;
        self.writer
            .finish()
            .map_err(|error| self.mcap_error(error))?;
        let yaml_path = self.dir.join("metadata.yaml");
        std::fs::write(&yaml_path, metadata.metadata_yaml()).map_err(|source| {
            BagWriterError::Io {
                path: yaml_path,
                source,
            }
        })?;
        Ok(metadata)
    }
}
