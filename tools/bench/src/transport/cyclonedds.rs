//! Eclipse Cyclone DDS (the DDS a ROS 2 user would run, from Debian's `cyclonedds-dev`) through
//! its C API: one participant per process in the default domain, a reliable keep-all topic of
//! its own per case, and Cyclone's default configuration (its network stack over the host's
//! default interface: no shared memory, which Debian's build does not have).
//!
//! The same rule as `zenoh-tcp`: the sender writes the message in place into its own copy,
//! encodes it with the stack's codec (`Payload::encode`) into a reused buffer that the sample's
//! `sequence<octet>` points at (DDS serializes from it; nothing else is copied on our side),
//! and the receiver takes the sample on loan and decodes it into its own copy
//! (`Payload::decode_into`). `publish_ns` is stamped before encoding, so encode and decode are
//! in the latency. Event mode waits in a DDS wait set on a read condition; poll mode spins on
//! `dds_take`.

use super::cyclonedds_ffi as ffi;
use super::{OnMessage, ReceivePort, SendPort};
use crate::bench_payload::zeroed_box;
use crate::error::BenchError;
use crate::message::{BenchMessage, Phase};
use crate::options::{Transport, WakeMode};
use crate::sender_write::PayloadWriter;
use crate::watchdog::{WATCH_PERIOD, Watchdog};
use harvest_ipc::{Flow, MonotonicClock};
use std::ffi::{CStr, CString, c_void};
use std::path::Path;
use std::time::{Duration, Instant};

const TRANSPORT: Transport = Transport::CycloneDds;
/// How long the sender waits for the receiver's reader to be discovered.
const MATCH_LIMIT: Duration = Duration::from_secs(20);
/// How long a write may block while the receiver has not acknowledged earlier samples.
const WRITE_BLOCKING_NS: i64 = 10_000_000_000;

/// The topic of one case: named after the case's control socket (unique per run and case) so
/// that concurrent runs and earlier cases never meet.
pub fn topic_name(control: &Path, payload: &str) -> String {
    let stem = control
        .file_stem()
        .map(|stem| {
            stem.to_string_lossy()
                .replace(|c: char| !c.is_ascii_alphanumeric(), "_")
        })
        .unwrap_or_default();
    format!("harvest_bench_{payload}_{stem}")
}

fn dds_error(operation: &'static str, topic: &str, code: ffi::DdsReturn) -> BenchError {
    // SAFETY: dds_strretcode returns a pointer to a static NUL-terminated string for any code.
    let reason = unsafe { CStr::from_ptr(ffi::dds_strretcode(code)) }
        .to_string_lossy()
        .into_owned();
    BenchError::PeerTransport {
        transport: TRANSPORT.name(),
        operation,
        key: topic.to_owned(),
        reason: format!("{reason} ({code})"),
    }
}

/// A DDS entity handle: negative values are error codes.
fn entity(operation: &'static str, topic: &str, handle: ffi::DdsEntity) -> Result<i32, BenchError> {
    if handle < 0 {
        Err(dds_error(operation, topic, handle))
    } else {
        Ok(handle)
    }
}

/// A participant with the case's topic; deleting the participant deletes everything in it.
struct Participant {
    participant: ffi::DdsEntity,
    topic: ffi::DdsEntity,
    topic_name: String,
}

impl Participant {
    fn open(topic_name: String) -> Result<Self, BenchError> {
        let name = CString::new(topic_name.clone()).map_err(|_| BenchError::InvalidOption {
            option: "transports",
            value: topic_name.clone(),
            reason: "a DDS topic name cannot hold a NUL byte".to_owned(),
        })?;
        // SAFETY: null QoS and listener select the defaults.
        let participant = entity("create participant", &topic_name, unsafe {
            ffi::dds_create_participant(ffi::DOMAIN_DEFAULT, std::ptr::null(), std::ptr::null())
        })?;
        let mut opened = Self {
            participant,
            topic: 0,
            topic_name,
        };
        // SAFETY: the descriptor and the name outlive the call (the descriptor is 'static); the
        // participant is a live entity.
        opened.topic = entity("create topic", &opened.topic_name, unsafe {
            ffi::dds_create_topic(
                participant,
                &ffi::BLOB_DESCRIPTOR,
                name.as_ptr(),
                std::ptr::null(),
                std::ptr::null(),
            )
        })?;
        Ok(opened)
    }

    /// Reliable, keep-all: no sample is replaced before the receiver has it (the stream phase
    /// keeps a window of messages in flight).
    fn create_endpoint(
        &self,
        operation: &'static str,
        create: unsafe extern "C" fn(i32, i32, *const ffi::Qos, *const c_void) -> i32,
    ) -> Result<ffi::DdsEntity, BenchError> {
        // SAFETY: a fresh QoS object, set and deleted here; the participant and topic are live.
        unsafe {
            let qos = ffi::dds_create_qos();
            ffi::dds_qset_reliability(qos, ffi::RELIABILITY_RELIABLE, WRITE_BLOCKING_NS);
            ffi::dds_qset_history(qos, ffi::HISTORY_KEEP_ALL, 0);
            let handle = create(self.participant, self.topic, qos, std::ptr::null());
            ffi::dds_delete_qos(qos);
            entity(operation, &self.topic_name, handle)
        }
    }
}

impl Drop for Participant {
    fn drop(&mut self) {
        // SAFETY: deletes the participant and every entity created in it; none is used after.
        let code = unsafe { ffi::dds_delete(self.participant) };
        if code < 0 {
            tracing::debug!(
                code,
                topic = self.topic_name,
                "deleting the DDS participant failed"
            );
        }
    }
}

/// Writes into its own copy, encodes into a reused buffer, writes the sample.
pub struct CycloneDdsSender<T: BenchMessage> {
    writer: ffi::DdsEntity,
    message: Box<T>,
    encoded: Vec<u8>,
    payload: &'static str,
    next_seq: u64,
    participant: Participant,
}

impl<T: BenchMessage> CycloneDdsSender<T> {
    /// Creates the writer on the case's topic and waits until the receiver's reader matched.
    pub fn connect(control: &Path, payload: &'static str) -> Result<Self, BenchError> {
        let participant = Participant::open(topic_name(control, payload))?;
        let writer = participant.create_endpoint("create writer", ffi::dds_create_writer)?;
        let started = Instant::now();
        loop {
            let mut status = ffi::PublicationMatchedStatus::default();
            // SAFETY: the writer is live and `status` is a valid place for the result.
            let code = unsafe { ffi::dds_get_publication_matched_status(writer, &mut status) };
            if code < 0 {
                return Err(dds_error(
                    "publication matched status",
                    &participant.topic_name,
                    code,
                ));
            }
            if status.current_count > 0 {
                break;
            }
            if started.elapsed() > MATCH_LIMIT {
                return Err(BenchError::PeerTransport {
                    transport: TRANSPORT.name(),
                    operation: "discover the reader",
                    key: participant.topic_name.clone(),
                    reason: format!("no reader matched within {MATCH_LIMIT:?}"),
                });
            }
            // Discovery is set-up, not the measured path.
            std::thread::sleep(Duration::from_millis(5));
        }
        Ok(Self {
            writer,
            message: zeroed_box(),
            encoded: Vec::with_capacity(2 * std::mem::size_of::<T>()),
            payload,
            next_seq: 1,
            participant,
        })
    }
}

impl<T: BenchMessage> SendPort<T> for CycloneDdsSender<T> {
    fn send(&mut self, phase: Phase, writer: &mut PayloadWriter) -> Result<u64, BenchError> {
        let msg_seq = self.next_seq;
        let publish_ns = writer.write_stamped(&mut *self.message, msg_seq, phase);
        self.encoded.clear();
        self.message
            .encode(&mut self.encoded)
            .map_err(|source| BenchError::Codec {
                operation: "encode",
                payload: self.payload,
                source,
            })?;
        let length = u32::try_from(self.encoded.len()).map_err(|_| BenchError::InvalidOption {
            option: "sizes",
            value: self.payload.to_owned(),
            reason: "an encoded message over 4 GiB does not fit a DDS sequence".to_owned(),
        })?;
        let sample = ffi::Blob {
            data: ffi::OctetSequence {
                maximum: length,
                length,
                buffer: self.encoded.as_mut_ptr(),
                release: false,
            },
        };
        // SAFETY: the sample points at `encoded`, alive and unchanged during the call; DDS
        // serializes it before returning and keeps no pointer to it (`release` false).
        let code = unsafe { ffi::dds_write(self.writer, std::ptr::from_ref(&sample).cast()) };
        if code < 0 {
            return Err(dds_error("write", &self.participant.topic_name, code));
        }
        self.next_seq += 1;
        Ok(MonotonicClock::read_ns().saturating_sub(publish_ns))
    }
}

/// Takes each sample on loan and decodes it into its own copy.
pub struct CycloneDdsReceiver<T: BenchMessage> {
    reader: ffi::DdsEntity,
    waitset: ffi::DdsEntity,
    mode: WakeMode,
    message: Box<T>,
    payload: &'static str,
    participant: Participant,
}

impl<T: BenchMessage> CycloneDdsReceiver<T> {
    /// Creates the reader (and, for event mode, a wait set on its read condition).
    pub fn open(control: &Path, mode: WakeMode, payload: &'static str) -> Result<Self, BenchError> {
        let participant = Participant::open(topic_name(control, payload))?;
        let reader = participant.create_endpoint("create reader", ffi::dds_create_reader)?;
        let topic = participant.topic_name.clone();
        // SAFETY: the participant and reader are live entities.
        let waitset = entity("create wait set", &topic, unsafe {
            ffi::dds_create_waitset(participant.participant)
        })?;
        // SAFETY: as above.
        let condition = entity("create read condition", &topic, unsafe {
            ffi::dds_create_readcondition(reader, ffi::ANY_STATE)
        })?;
        // SAFETY: as above.
        let code = unsafe { ffi::dds_waitset_attach(waitset, condition, 0) };
        if code < 0 {
            return Err(dds_error("attach the read condition", &topic, code));
        }
        Ok(Self {
            reader,
            waitset,
            mode,
            message: zeroed_box(),
            payload,
            participant,
        })
    }

    /// Takes one sample, decodes it and returns the loan; `None` if none was there.
    fn take_one(&mut self) -> Result<Option<u64>, BenchError> {
        let mut samples: [*mut c_void; 1] = [std::ptr::null_mut()];
        let mut infos = [ffi::SampleInfo::default()];
        // SAFETY: a null first pointer asks DDS to lend its own sample memory; one slot each.
        let taken =
            unsafe { ffi::dds_take(self.reader, samples.as_mut_ptr(), infos.as_mut_ptr(), 1, 1) };
        if taken < 0 {
            return Err(dds_error("take", &self.participant.topic_name, taken));
        }
        if taken == 0 {
            return Ok(None);
        }
        let decoded = if infos[0].valid_data {
            // SAFETY: DDS lent one sample of the topic's type, `Blob`, valid until the loan is
            // returned below; its sequence holds `length` initialized bytes.
            let bytes = unsafe {
                let blob = &*samples[0].cast::<ffi::Blob>();
                if blob.data.buffer.is_null() {
                    &[][..]
                } else {
                    std::slice::from_raw_parts(blob.data.buffer, blob.data.length as usize)
                }
            };
            Some(T::decode_into(bytes, &mut self.message))
        } else {
            None
        };
        let recv_ns = MonotonicClock::read_ns();
        // SAFETY: returns the loan taken above; the slice into it is no longer used.
        let code = unsafe { ffi::dds_return_loan(self.reader, samples.as_mut_ptr(), taken) };
        if code < 0 {
            return Err(dds_error("return loan", &self.participant.topic_name, code));
        }
        match decoded {
            Some(Ok(())) => Ok(Some(recv_ns)),
            Some(Err(source)) => Err(BenchError::Codec {
                operation: "decode",
                payload: self.payload,
                source,
            }),
            // An instance-state change without data: nothing to deliver.
            None => Ok(None),
        }
    }

    fn wait(&self) -> Result<(), BenchError> {
        let mut triggered = [0_isize; 1];
        let timeout_ns = i64::try_from(WATCH_PERIOD.as_nanos()).unwrap_or(i64::MAX);
        // SAFETY: the wait set is live; one slot for the triggered attachment.
        let code =
            unsafe { ffi::dds_waitset_wait(self.waitset, triggered.as_mut_ptr(), 1, timeout_ns) };
        if code < 0 {
            return Err(dds_error("wait", &self.participant.topic_name, code));
        }
        Ok(())
    }
}

impl<T: BenchMessage> ReceivePort<T> for CycloneDdsReceiver<T> {
    fn run_phase(
        &mut self,
        watchdog: &mut Watchdog,
        on_message: &mut OnMessage<'_, T>,
    ) -> Result<(), BenchError> {
        loop {
            match self.take_one()? {
                Some(recv_ns) => {
                    if on_message(&self.message, recv_ns)? == Flow::Stop {
                        return Ok(());
                    }
                }
                None => match self.mode {
                    WakeMode::Event => {
                        watchdog.check()?;
                        self.wait()?;
                    }
                    WakeMode::Poll => {
                        watchdog.poll_check()?;
                        std::hint::spin_loop();
                    }
                },
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topic_names_are_per_case_and_plain() {
        let name = topic_name(Path::new("/tmp/harvest-bench-123-4.sock"), "64B");
        assert_eq!(name, "harvest_bench_64B_harvest_bench_123_4");
        assert_ne!(
            name,
            topic_name(Path::new("/tmp/harvest-bench-123-5.sock"), "64B")
        );
    }

    #[test]
    fn the_blob_type_has_the_layout_of_the_generated_c() {
        // idlc's harvest_bench_Blob: a dds_sequence_octet {u32, u32, u8*, bool}.
        assert_eq!(std::mem::size_of::<ffi::Blob>(), 24);
        assert_eq!(std::mem::align_of::<ffi::Blob>(), 8);
        assert_eq!(std::mem::size_of::<ffi::SampleInfo>(), 64);
    }
}
