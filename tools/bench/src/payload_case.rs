//! The payloads a run can measure: fixed-size benchmark payloads for the sweep, and the
//! catalogue types our layer can carry.

use crate::error::BenchError;

/// One payload type of the benchmark. The sweep sizes are total message sizes (header
/// included); the catalogue cases are the stack's real message types.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PayloadCase {
    Bytes64,
    Bytes256,
    KiB1,
    KiB4,
    KiB16,
    KiB64,
    KiB256,
    MiB1,
    MiB2,
    MiB4,
    MiB8,
    MiB16,
    /// `LaserScanRequest` on `laser/scan_request` (64 B).
    ScanRequest,
    /// `AppleDetections` on `perception/apples` (about 5.7 kB).
    Detections,
    /// `RgbdFrame` on `camera/rgbd` (about 6.8 MB).
    Rgbd,
}

/// Runs `$body` with `$t` bound to the Rust type of `$case`.
macro_rules! with_payload_type {
    ($case:expr, $t:ident => $body:expr) => {{
        use $crate::bench_payload::{BENCH_PAYLOAD_OVERHEAD as O, BenchPayload as P};
        use $crate::payload_case::PayloadCase as C;
        // One arm per case: `$t` is bound to the case's type, then `$body` runs.
        macro_rules! with_type {
            ($ty:ty) => {{
                type $t = $ty;
                $body
            }};
        }
        match $case {
            C::Bytes64 => with_type!(P<{ 64 - O }>),
            C::Bytes256 => with_type!(P<{ 256 - O }>),
            C::KiB1 => with_type!(P<{ 1024 - O }>),
            C::KiB4 => with_type!(P<{ 4 * 1024 - O }>),
            C::KiB16 => with_type!(P<{ 16 * 1024 - O }>),
            C::KiB64 => with_type!(P<{ 64 * 1024 - O }>),
            C::KiB256 => with_type!(P<{ 256 * 1024 - O }>),
            C::MiB1 => with_type!(P<{ (1 << 20) - O }>),
            C::MiB2 => with_type!(P<{ (2 << 20) - O }>),
            C::MiB4 => with_type!(P<{ (4 << 20) - O }>),
            C::MiB8 => with_type!(P<{ (8 << 20) - O }>),
            C::MiB16 => with_type!(P<{ (16 << 20) - O }>),
            C::ScanRequest => with_type!(harvest_ipc::payloads::LaserScanRequest),
            C::Detections => with_type!(harvest_ipc::payloads::AppleDetections),
            C::Rgbd => with_type!(harvest_ipc::payloads::RgbdFrame),
        }
    }};
}
pub(crate) use with_payload_type;

impl PayloadCase {
    pub const ALL: [PayloadCase; 15] = [
        Self::Bytes64,
        Self::Bytes256,
        Self::KiB1,
        Self::KiB4,
        Self::KiB16,
        Self::KiB64,
        Self::KiB256,
        Self::MiB1,
        Self::MiB2,
        Self::MiB4,
        Self::MiB8,
        Self::MiB16,
        Self::ScanRequest,
        Self::Detections,
        Self::Rgbd,
    ];

    /// Measured when `--sizes` is not given: 64 B to 16 MiB in steps of 4-16x, plus the three
    /// catalogue types.
    pub const DEFAULT: [PayloadCase; 11] = [
        Self::Bytes64,
        Self::KiB1,
        Self::KiB16,
        Self::KiB256,
        Self::MiB1,
        Self::MiB4,
        Self::MiB8,
        Self::MiB16,
        Self::ScanRequest,
        Self::Detections,
        Self::Rgbd,
    ];

    /// The name used by `--sizes`, `bench-peer --payload` and the reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Bytes64 => "64B",
            Self::Bytes256 => "256B",
            Self::KiB1 => "1KiB",
            Self::KiB4 => "4KiB",
            Self::KiB16 => "16KiB",
            Self::KiB64 => "64KiB",
            Self::KiB256 => "256KiB",
            Self::MiB1 => "1MiB",
            Self::MiB2 => "2MiB",
            Self::MiB4 => "4MiB",
            Self::MiB8 => "8MiB",
            Self::MiB16 => "16MiB",
            Self::ScanRequest => "scan-request",
            Self::Detections => "detections",
            Self::Rgbd => "rgbd",
        }
    }

    /// The Rust type carried, for the report.
    pub fn type_name(self) -> &'static str {
        match self {
            Self::ScanRequest => "LaserScanRequest",
            Self::Detections => "AppleDetections",
            Self::Rgbd => "RgbdFrame",
            _ => "BenchPayload",
        }
    }

    /// Size of one message in bytes (`size_of` of the type).
    pub fn size_bytes(self) -> usize {
        with_payload_type!(self, T => std::mem::size_of::<T>())
    }

    /// Whether it is one of the stack's catalogue types (carried on its catalogue channel);
    /// the sweep sizes travel on ad-hoc channels ([`Self::topic`]).
    pub fn has_catalogue_channel(self) -> bool {
        matches!(self, Self::ScanRequest | Self::Detections | Self::Rgbd)
    }

    /// Topic of the channel our layer uses for this payload: the catalogue topic for the
    /// catalogue types, else an ad-hoc `bench/<name>` channel
    /// (`harvest_ipc::Channel::ad_hoc`, not part of the stack catalogue).
    pub fn topic(self) -> &'static str {
        match self {
            Self::Bytes64 => "bench/64b",
            Self::Bytes256 => "bench/256b",
            Self::KiB1 => "bench/1kib",
            Self::KiB4 => "bench/4kib",
            Self::KiB16 => "bench/16kib",
            Self::KiB64 => "bench/64kib",
            Self::KiB256 => "bench/256kib",
            Self::MiB1 => "bench/1mib",
            Self::MiB2 => "bench/2mib",
            Self::MiB4 => "bench/4mib",
            Self::MiB8 => "bench/8mib",
            Self::MiB16 => "bench/16mib",
            Self::ScanRequest => harvest_ipc::catalogue::LASER_SCAN_REQUEST.spec.topic,
            Self::Detections => harvest_ipc::catalogue::PERCEPTION_APPLES.spec.topic,
            Self::Rgbd => harvest_ipc::catalogue::CAMERA_RGBD.spec.topic,
        }
    }

    /// Parses one `--sizes` entry: a name (`rgbd`), or a size with an optional `K`/`M` suffix
    /// and optional `B`/`iB` (`64`, `64B`, `1K`, `16KiB`, `8M`).
    pub fn parse(value: &str) -> Result<Self, BenchError> {
        let unknown = || BenchError::UnknownPayload {
            value: value.to_owned(),
            supported: Self::ALL
                .iter()
                .map(|case| case.name())
                .collect::<Vec<_>>()
                .join(", "),
        };
        let lower = value.trim().to_ascii_lowercase();
        if let Some(case) = Self::ALL
            .iter()
            .find(|case| case.name().to_ascii_lowercase() == lower)
        {
            return Ok(*case);
        }
        let digits_end = lower
            .find(|c: char| !c.is_ascii_digit())
            .unwrap_or(lower.len());
        let number: usize = lower[..digits_end].parse().map_err(|_| unknown())?;
        let multiplier = match &lower[digits_end..] {
            "" | "b" => 1,
            "k" | "kb" | "kib" => 1024,
            "m" | "mb" | "mib" => 1 << 20,
            _ => return Err(unknown()),
        };
        let bytes = number.checked_mul(multiplier).ok_or_else(unknown)?;
        Self::ALL
            .iter()
            .find(|case| !case.has_catalogue_channel() && case.size_bytes() == bytes)
            .copied()
            .ok_or_else(unknown)
    }
}

impl std::fmt::Display for PayloadCase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_sizes_match() {
        for case in PayloadCase::ALL {
            assert_eq!(
                PayloadCase::parse(case.name()).expect("own name parses"),
                case
            );
        }
        assert_eq!(PayloadCase::Bytes64.size_bytes(), 64);
        assert_eq!(PayloadCase::MiB16.size_bytes(), 16 << 20);
        assert_eq!(PayloadCase::ScanRequest.size_bytes(), 64);
        let rgbd = PayloadCase::Rgbd.size_bytes();
        assert!(
            (6_500_000..7_000_000).contains(&rgbd),
            "rgbd is {rgbd} bytes"
        );
    }

    #[test]
    fn topics_are_unique_and_catalogue_types_keep_theirs() {
        let mut topics: Vec<_> = PayloadCase::ALL.iter().map(|case| case.topic()).collect();
        topics.sort_unstable();
        topics.dedup();
        assert_eq!(topics.len(), PayloadCase::ALL.len());
        assert_eq!(PayloadCase::Rgbd.topic(), "camera/rgbd");
        let catalogue: Vec<_> = harvest_ipc::catalogue::all_specs()
            .iter()
            .map(|spec| spec.topic)
            .collect();
        for case in PayloadCase::ALL {
            assert_eq!(
                catalogue.contains(&case.topic()),
                case.has_catalogue_channel(),
                "{case}"
            );
        }
    }

    #[test]
    fn sizes_parse_with_suffixes() {
        assert_eq!(PayloadCase::parse("64").expect("64"), PayloadCase::Bytes64);
        assert_eq!(PayloadCase::parse("1k").expect("1k"), PayloadCase::KiB1);
        assert_eq!(PayloadCase::parse("8M").expect("8M"), PayloadCase::MiB8);
        assert_eq!(PayloadCase::parse("RGBD").expect("RGBD"), PayloadCase::Rgbd);
        assert!(matches!(
            PayloadCase::parse("3K"),
            Err(BenchError::UnknownPayload { .. })
        ));
        assert!(matches!(
            PayloadCase::parse("big"),
            Err(BenchError::UnknownPayload { .. })
        ));
    }
}
