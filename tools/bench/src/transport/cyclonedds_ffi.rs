//! The part of Eclipse Cyclone DDS's C API (`libddsc`, Debian's `cyclonedds-dev` 0.10.2) the
//! `cyclonedds` transport calls, declared by hand from `/usr/include/dds/dds.h` and
//! `dds/ddsc/dds_public_impl.h` of that version, with the one topic type it sends.
//!
//! The type is the IDL `module harvest_bench { struct Blob { sequence<octet> data; }; };`: its
//! marshalling ops are what Cyclone's `idlc -l c` generates for it, without the optional XTypes
//! type information (so `m_flagset` is 0).

use std::ffi::{c_char, c_void};

pub type DdsEntity = i32;
pub type DdsReturn = i32;
pub type DdsDuration = i64;

/// `DDS_DOMAIN_DEFAULT`: the domain of the configuration (`CYCLONEDDS_URI`), else 0.
pub const DOMAIN_DEFAULT: u32 = u32::MAX;
/// `DDS_ANY_STATE`: any sample, view and instance state.
pub const ANY_STATE: u32 = 3 | 12 | (16 | 32 | 64);
pub const RELIABILITY_RELIABLE: u32 = 1;
pub const HISTORY_KEEP_ALL: u32 = 1;

/// `dds_sequence_octet`.
#[repr(C)]
pub struct OctetSequence {
    pub maximum: u32,
    pub length: u32,
    pub buffer: *mut u8,
    pub release: bool,
}

/// `harvest_bench_Blob`, the sample type.
#[repr(C)]
pub struct Blob {
    pub data: OctetSequence,
}

#[repr(C)]
struct TypeMetaSer {
    data: *const u8,
    size: u32,
}

/// `dds_topic_descriptor_t`.
#[repr(C)]
pub struct TopicDescriptor {
    size: u32,
    align: u32,
    flagset: u32,
    key_count: u32,
    type_name: *const c_char,
    keys: *const c_void,
    op_count: u32,
    ops: *const u32,
    meta: *const c_char,
    type_information: TypeMetaSer,
    type_mapping: TypeMetaSer,
    restrict_data_representation: u32,
}

// SAFETY: the descriptor only points at 'static constants that are never written.
unsafe impl Sync for TopicDescriptor {}

const OP_RTS: u32 = 0;
const OP_ADR: u32 = 1 << 24;
const OP_TYPE_SEQ: u32 = 7 << 16;
const OP_SUBTYPE_1BY: u32 = 1 << 8;
static BLOB_OPS: [u32; 3] = [OP_ADR | OP_TYPE_SEQ | OP_SUBTYPE_1BY, 0, OP_RTS];

/// The descriptor of [`Blob`] (the `data` field is at offset 0, the second op).
pub static BLOB_DESCRIPTOR: TopicDescriptor = TopicDescriptor {
    size: std::mem::size_of::<Blob>() as u32,
    align: std::mem::align_of::<Blob>() as u32,
    flagset: 0,
    key_count: 0,
    type_name: c"harvest_bench::Blob".as_ptr(),
    keys: std::ptr::null(),
    op_count: 2,
    ops: BLOB_OPS.as_ptr(),
    meta: c"".as_ptr(),
    type_information: TypeMetaSer {
        data: std::ptr::null(),
        size: 0,
    },
    type_mapping: TypeMetaSer {
        data: std::ptr::null(),
        size: 0,
    },
    restrict_data_representation: 0,
};

/// `dds_sample_info_t`.
#[repr(C)]
#[derive(Default)]
pub struct SampleInfo {
    pub sample_state: u32,
    pub view_state: u32,
    pub instance_state: u32,
    pub valid_data: bool,
    pub source_timestamp: i64,
    pub instance_handle: u64,
    pub publication_handle: u64,
    pub disposed_generation_count: u32,
    pub no_writers_generation_count: u32,
    pub sample_rank: u32,
    pub generation_rank: u32,
    pub absolute_generation_rank: u32,
}

/// `dds_publication_matched_status_t`.
#[repr(C)]
#[derive(Default)]
pub struct PublicationMatchedStatus {
    pub total_count: u32,
    pub total_count_change: i32,
    pub current_count: u32,
    pub current_count_change: i32,
    pub last_subscription_handle: u64,
}

/// `dds_qos_t`, opaque.
#[repr(C)]
pub struct Qos {
    _private: [u8; 0],
}

#[link(name = "ddsc")]
unsafe extern "C" {
    pub fn dds_create_participant(
        domain: u32,
        qos: *const Qos,
        listener: *const c_void,
    ) -> DdsEntity;
    pub fn dds_create_topic(
        participant: DdsEntity,
        descriptor: *const TopicDescriptor,
        name: *const c_char,
        qos: *const Qos,
        listener: *const c_void,
    ) -> DdsEntity;
    pub fn dds_create_writer(
        participant: DdsEntity,
        topic: DdsEntity,
        qos: *const Qos,
        listener: *const c_void,
    ) -> DdsEntity;
    pub fn dds_create_reader(
        participant: DdsEntity,
        topic: DdsEntity,
        qos: *const Qos,
        listener: *const c_void,
    ) -> DdsEntity;
    pub fn dds_create_waitset(owner: DdsEntity) -> DdsEntity;
    pub fn dds_create_readcondition(reader: DdsEntity, mask: u32) -> DdsEntity;
    pub fn dds_waitset_attach(waitset: DdsEntity, entity: DdsEntity, token: isize) -> DdsReturn;
    pub fn dds_waitset_wait(
        waitset: DdsEntity,
        triggered: *mut isize,
        capacity: usize,
        timeout_ns: DdsDuration,
    ) -> DdsReturn;
    pub fn dds_write(writer: DdsEntity, sample: *const c_void) -> DdsReturn;
    pub fn dds_take(
        reader: DdsEntity,
        samples: *mut *mut c_void,
        infos: *mut SampleInfo,
        buffer_size: usize,
        max_samples: u32,
    ) -> DdsReturn;
    pub fn dds_return_loan(reader: DdsEntity, samples: *mut *mut c_void, count: i32) -> DdsReturn;
    pub fn dds_get_publication_matched_status(
        writer: DdsEntity,
        status: *mut PublicationMatchedStatus,
    ) -> DdsReturn;
    pub fn dds_delete(entity: DdsEntity) -> DdsReturn;
    pub fn dds_create_qos() -> *mut Qos;
    pub fn dds_delete_qos(qos: *mut Qos);
    pub fn dds_qset_reliability(qos: *mut Qos, kind: u32, max_blocking_time_ns: DdsDuration);
    pub fn dds_qset_history(qos: *mut Qos, kind: u32, depth: i32);
    pub fn dds_strretcode(code: DdsReturn) -> *const c_char;
}
