//! The two checksums of the Livox SDK 1 control frame, with the seeds the SDK uses
//! (`comm_port.cpp`: `SdkProtocol(0x4c49, 0x564f580a)`; `FastCRCsw.cpp`).
//!
//! - CRC-16/MCRF4XX (polynomial 0x1021 reflected, no final XOR) started from the seed 0x4c49,
//!   over the first 7 bytes of the frame (the preamble), stored little-endian. Because the
//!   algorithm has no final XOR, the CRC over the whole 9-byte preamble is 0 when it is intact
//!   (the SDK's `CheckPreamble`).
//! - CRC-32 (polynomial 0x04C11DB7 reflected, final XOR 0xFFFFFFFF) whose register starts at
//!   `seed ^ 0xFFFFFFFF` with the seed 0x564f580a, over every byte before it, stored
//!   little-endian.

/// Seed of the preamble CRC-16 (`comm_port.cpp`).
pub const CRC16_SEED: u16 = 0x4c49;
/// Seed of the frame CRC-32 (`comm_port.cpp`).
pub const CRC32_SEED: u32 = 0x564f_580a;

/// Reflected CRC-16 polynomial 0x1021 (its values stay within 16 bits).
const CRC16_TABLE: [u32; 256] = reflected_table(0x8408);
/// Reflected CRC-32 polynomial 0x04C11DB7.
const CRC32_TABLE: [u32; 256] = reflected_table(0xEDB8_8320);

/// The byte table of a reflected CRC of polynomial `reflected_polynomial`.
const fn reflected_table(reflected_polynomial: u32) -> [u32; 256] {
    let mut table = [0u32; 256];
    let mut index = 0;
    while index < 256 {
        let mut crc = index as u32;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ reflected_polynomial
            } else {
                crc >> 1
            };
            bit += 1;
        }
        table[index] = crc;
        index += 1;
    }
    table
}

/// CRC-16/MCRF4XX of `bytes` from the SDK's seed.
pub fn crc16(bytes: &[u8]) -> u16 {
    bytes.iter().fold(CRC16_SEED, |crc, &byte| {
        (crc >> 8) ^ CRC16_TABLE[usize::from((crc as u8) ^ byte)] as u16
    })
}

/// CRC-32 of `bytes` from the SDK's seed.
pub fn crc32(bytes: &[u8]) -> u32 {
    let register = bytes.iter().fold(CRC32_SEED ^ 0xFFFF_FFFF, |crc, &byte| {
        (crc >> 8) ^ CRC32_TABLE[usize::from((crc as u8) ^ byte)]
    });
    register ^ 0xFFFF_FFFF
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit-by-bit forms of both algorithms, written from their definitions, against the tables.
    fn crc16_bitwise(bytes: &[u8]) -> u16 {
        let mut crc = CRC16_SEED;
        for &byte in bytes {
            crc ^= u16::from(byte);
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0x8408
                } else {
                    crc >> 1
                };
            }
        }
        crc
    }

    fn crc32_bitwise(bytes: &[u8]) -> u32 {
        let mut crc = !CRC32_SEED;
        for &byte in bytes {
            crc ^= u32::from(byte);
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }

    #[test]
    fn tables_match_the_bitwise_definitions() {
        let bytes: Vec<u8> = (0..=255u8).chain((0..=255u8).rev()).collect();
        for end in [0, 1, 7, 9, 100, bytes.len()] {
            assert_eq!(crc16(&bytes[..end]), crc16_bitwise(&bytes[..end]));
            assert_eq!(crc32(&bytes[..end]), crc32_bitwise(&bytes[..end]));
        }
    }

    #[test]
    fn the_standard_check_values_follow_with_the_standard_seeds() {
        // With the catalogue's initial values the same code gives the catalogue's check values
        // of "123456789": CRC-16/MCRF4XX 0x6F91 (init 0xFFFF), CRC-32 0xCBF43926 (init 0).
        let check = b"123456789";
        let crc16_std = check.iter().fold(0xFFFFu16, |crc, &byte| {
            (crc >> 8) ^ CRC16_TABLE[usize::from((crc as u8) ^ byte)] as u16
        });
        assert_eq!(crc16_std, 0x6F91);
        let crc32_std = check.iter().fold(0xFFFF_FFFFu32, |crc, &byte| {
            (crc >> 8) ^ CRC32_TABLE[usize::from((crc as u8) ^ byte)]
        }) ^ 0xFFFF_FFFF;
        assert_eq!(crc32_std, 0xCBF4_3926);
    }

    #[test]
    fn an_intact_preamble_checks_to_zero() {
        let mut preamble = [0xAA, 1, 15, 0, 0, 1, 0, 0, 0];
        let crc = crc16(&preamble[..7]).to_le_bytes();
        preamble[7..].copy_from_slice(&crc);
        assert_eq!(crc16(&preamble), 0);
    }
}
